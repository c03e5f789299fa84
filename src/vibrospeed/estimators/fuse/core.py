"""The compiled core of the fusion filter (numba): one fusion sample in place
(:func:`_step_core`: exact prediction, then the measurement updates of the package notes --
accelerometer, GPS with its adaptive variance, wheel frequency with octave choice,
acquisition and re-lock, standstill, the ``v >= 0`` projection) and the loop over samples
(:func:`_run_core`, which also stores the predictions and posteriors the smoother reads), and
the product of the tracker's grid posterior with the prediction (:func:`_post_product`).
The state arrives as flat arrays and the parameters as one float vector
(:meth:`~vibrospeed.estimators.fuse.config.Config._arrays`), so ``step`` and ``run`` are this
same code. The measurement updates are :func:`vibrospeed.estimators.kalman.row_update`
(Joseph form) with consider states where a row must not teach some (item 3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from vibrospeed.estimators.fuse.config import IA, IB, IG, IR, IV
from vibrospeed.estimators.gps_riss.core import _lag_row
from vibrospeed.estimators.kalman import dense_predict, joseph, matvec, quad_form, row_update
from vibrospeed.models.gps_riss import transition

#: fixes on the same side of the filter's speed, beyond the innovation's spread, before a
#: disagreement may be taken as the filter's drift (besides lasting ``gps_persist`` s): by
#: chance, with white receiver errors, 2^-7 < 1 %
PERSIST_FIXES = 8


@njit(cache=True)
def _post_product(q, grid, m, s, width):
    """``(bf, mean, var)`` of the product of the tracker's line-conditional posterior ``q`` (N,)
    on the uniform ``grid`` (N,) with the Gaussian ``N(omega; m, s^2)``, over the grid points
    within ``width s`` of ``m``: ``bf = sum q_j g_j / sum g_j / N`` (the posterior's mass there
    against a flat posterior's, ``g_j = exp(-(grid_j - m)^2 / 2 s^2)``), the product's
    moment-matched mean and variance (the cells' own ``dg^2 / 12`` added). ``bf = 0``: no grid
    point in the window or no posterior mass there."""
    N = grid.size
    num = 0.0
    flat = 0.0
    s1 = 0.0
    for j in range(N):
        d = (grid[j] - m) / s
        if abs(d) <= width:
            gj = math.exp(-0.5 * d * d)
            w = q[j] * gj
            num += w
            flat += gj
            s1 += w * grid[j]
    if not (num > 0.0 and flat > 0.0):
        return 0.0, math.nan, math.nan
    mean = s1 / num
    s2 = 0.0
    for j in range(N):
        d = (grid[j] - m) / s
        if abs(d) <= width:
            e = grid[j] - mean
            s2 += q[j] * math.exp(-0.5 * d * d) * e * e
    dg = (grid[N - 1] - grid[0]) / (N - 1) if N > 1 else 0.0
    return num / (flat / N), mean, s2 / num + dg * dg / 12.0


@njit(cache=True)
def _band_update(P, Pb, J, h, r, rb, keep=-1, keep2=-1):
    """The band's covariance ``Pb`` through the scalar update that :func:`row_update` is about
    to make with ``P`` (call it first): the filter's gain ``k = P h' / (h P h' + r)`` (its
    consider states' entries 0) and the measurement's variance ``rb``, Joseph form
    ``Pb = (I - k h) Pb (I - k h)' + rb k k'`` (symmetrised): the error covariance of an
    estimate made with another filter's gains (a suboptimal filter's), here the speed band of
    an accelerometer noisier than the gains assume (``Config.band_psd``). With ``Pb = P`` and
    ``rb = r`` it is ``row_update``'s own arithmetic. ``J = (I - k h) J``: the sample's error
    transition through its updates so far (the smoother's band, :func:`smooth_band`)."""
    n = h.size
    Ph = np.empty(n)
    matvec(P, h, Ph)
    S = r
    for i in range(n):
        S += h[i] * Ph[i]
    k = Ph / S
    if keep >= 0:
        k[keep] = 0.0
    if keep2 >= 0:
        k[keep2] = 0.0
    for j in range(n):
        hJ = 0.0
        for i in range(n):
            hJ += h[i] * J[i, j]
        for i in range(n):
            J[i, j] -= k[i] * hJ
    Pbh = np.empty(n)
    matvec(Pb, h, Pbh)
    joseph(Pb, Pbh, k, h, rb)


@njit(cache=True)
def _update(x, P, Pb, J, h, z, r, rb, keep=-1, keep2=-1):
    """:func:`row_update` of the filter, and the band's covariance with the same gain
    (:func:`_band_update`, measurement variance ``rb``) where it is kept (``Pb`` not empty)."""
    if Pb.shape[0] > 0:
        _band_update(P, Pb, J, h, r, rb, keep, keep2)
    return row_update(x, P, h, z, r, keep, keep2)


@njit(cache=True)
def _step_core(Ac, qc, p, x, P, sc, Fc, t, am, g, sats, om, om_std, line, still, soft, post,
               grid, out, xp, Pp, Pb, band, Pbp, J):
    """One fusion sample in place. ``sc = [t_prev, t_gps, t_fix, v_fix, dt of Fc, octave,
    t_run, t_still, t_acq, z_acq, d_run, u_run, d0_run, t_last, om_last, k_last, t_dis,
    s_dis]`` (the
    last wheel-frequency update's time, omega and k; it was at the previous fusion sample if
    ``t_last`` is that sample's time: a sample with ``dt = 0`` uses no line); ``post`` (N,)
    the tracker's grid posterior of the signal part on ``grid`` (N,) (empty: none; read with
    ``vib_measure="posterior"``);
    ``out`` (7,) receives speed, std, radius, radius std, offset, source, k; ``xp, Pp`` the
    prediction (for the smoother). ``Pb`` (n, n): the band's covariance (0 x 0: none kept),
    propagated beside ``P`` with the filter's gains and the accelerometer's density ``band``
    ((m/s^2)^2 s; ``Config.band_psd``), its prediction into ``Pbp``; the std in ``out`` is then
    the band's; ``J`` receives the product of the sample's ``I - k h`` (its updates' error
    transition). The filter's ``x`` and ``P`` never read them. Returns dt."""
    n = x.size
    kb = Pb.shape[0] > 0
    t_prev = sc[0]
    dt = 0.0 if math.isnan(t_prev) else t - t_prev
    sc[0] = t
    if dt > 0.0:
        if dt != sc[4]:
            Fc[:, :] = transition(Ac, dt)
            sc[4] = dt
        qd = qc * dt
        dense_predict(x, P, Fc, qd)
        if kb:
            dense_predict(np.zeros(n), Pb, Fc, qd)
    for i in range(n):
        xp[i] = x[i]
        for j in range(n):
            Pp[i, j] = P[i, j]
            if kb:
                Pbp[i, j] = Pb[i, j]
                J[i, j] = 1.0 if i == j else 0.0
    h = np.zeros(n)
    # 1. accelerometer (mean over the interval): a_m = a + b
    if dt > 0.0 and math.isfinite(am):  # NaN or inf: no sample
        h[IA] = 1.0
        h[IB] = 1.0
        _update(x, P, Pb, J, h, am, p[0] / dt, band / dt)
        h[IA] = 0.0
        h[IB] = 0.0
    # 2. GPS, gated by satellites, weighted by the unexplained innovation
    if math.isfinite(g):  # an inf speed is no fix (it made the smoother fail)
        valid = math.isnan(sats) or sats >= p[4]
        if valid:
            sc[2] = t
            sc[3] = g
            # the row linearised at x: the fix is the receiver model's output an extra lag
            # (the last state) earlier
            hg = np.empty(n)
            zg = g + _lag_row(Ac, x, IG, hg)
            nu = zg
            for i in range(n):
                nu -= hg[i] * x[i]
            s0 = quad_form(hg, P) + p[1]
            e2 = min(max(nu * nu - s0, 0.0), p[3] * p[3])
            # a disagreement beyond the innovation's spread, on the same side at every valid
            # fix for gps_persist s (longer than a receiver jump) and PERSIST_FIXES fixes (sc[17]
            # counts them, signed by the side), is the filter's: its speed
            # drifted on the accelerometer. Weighting such fixes down (R grows with E^2) would
            # leave it there (the pull per fix shrinks as 1 / |nu|), so the speed's variance
            # grows by E^2 instead, along a speed offset that has passed through the receiver
            # (v and the receiver states at their steady state), and the fix is taken at its
            # own variance
            if e2 > 0.0:
                sg = 1.0 if nu > 0.0 else -1.0
                if math.isnan(sc[16]) or sg * sc[17] <= 0.0:
                    sc[16] = t
                    sc[17] = sg
                else:
                    sc[17] += sg
                if t - sc[16] >= p[39] and abs(sc[17]) >= PERSIST_FIXES:
                    u = np.zeros(n)
                    u[IV] = 1.0
                    ar = np.ascontiguousarray(Ac[IG:n - 1, IG:n - 1])
                    br = np.ascontiguousarray(Ac[IG:n - 1, IV])
                    u[IG:n - 1] = -np.linalg.solve(ar, br)
                    hu = 0.0
                    for i in range(n):
                        hu += hg[i] * u[i]
                    # hu: the fix's response to that offset, the receiver's steady-state gain
                    # (1 for the paper's lag model); a degenerate receiver model reads ~0
                    if hu > 0.1:
                        f = e2 / (hu * hu)
                        for i in range(n):
                            for j in range(n):
                                P[i, j] += f * u[i] * u[j]
                                if kb:
                                    Pb[i, j] += f * u[i] * u[j]
                        s0 = quad_form(hg, P) + p[1]
                        e2 = min(max(nu * nu - s0, 0.0), p[3] * p[3])
            else:
                sc[16] = math.nan
            # the extra lag is seen only against the accelerometer (GPS alone cannot tell a
            # late fix from another speed history): a sample without one leaves it alone
            # (consider state), else the loose acceleration state lets it drift
            keep = n - 1 if not math.isfinite(am) else -1
            rg = p[1] + p[2] * e2
            _update(x, P, Pb, J, hg, zg, rg, rg, keep)
            sc[1] = t
    # 3. wheel frequency, octave chosen by the speed prior
    kk = math.nan
    moving = x[IV] + 3.0 * math.sqrt(max(P[IV, IV], 0.0)) >= p[18]
    fresh = t - sc[1] <= p[24]  # GPS pins the speed: the radius may learn
    known = math.sqrt(max(P[IR, IR], 0.0)) < p[19] * abs(x[IR])
    if not (fresh and x[IV] >= p[18]):
        sc[8] = math.nan  # an acquisition run needs the GPS speed
    # the tracker's lag behind the speed: a causal tracker follows a hard acceleration late
    # while its mode stays narrow. The acceleration is the larger of the filter's and the
    # accelerometer's (less the offset): a lagging line accepted at the onset of a braking
    # pulls the filter's own acceleration towards 0
    a_lag = x[IA]
    if math.isfinite(am) and abs(am - x[IB]) > abs(a_lag):
        a_lag = am - x[IB]
    # beyond vib_amax the causal tracker's line trails the speed by more than its spread or
    # has jumped an octave: no line is used
    hard = abs(a_lag) > p[32]
    offered = (line and moving and dt > 0.0 and om > 0.0 and not math.isnan(om)
               and not math.isnan(om_std))
    if soft:
        # a line the tracker does not claim: only for the re-lock's band, away from GPS, with
        # r known
        sc[8] = math.nan
        offered = offered and known and not fresh
    if dt > 0.0 and not offered:
        # a consistency run (acquisition, re-lock) needs a line at every sample: a line
        # claimed now and then (a resonance, an engine order between the wheel's claims)
        # must not add up to a run
        sc[6] = math.nan
        sc[8] = math.nan
    if offered:
        ready = known
        if not known and fresh and x[IV] >= p[18]:
            # acquisition: the ratio v / omega must hold for acq_time s (a wheel line scales
            # with the speed; an idling engine's or a resonance's does not)
            z = math.log(x[IV] / om)
            if math.isnan(sc[8]) or abs(z - sc[9]) > p[26]:
                sc[8] = t
                sc[9] = z
            else:
                sc[9] += (z - sc[9]) * min(1.0, dt / p[25])
            ready = t - sc[8] >= p[25]
        best = math.inf
        r_hat = max(x[IR], 1e-3)
        var_om = om_std * om_std + (p[5] * om) ** 2
        var_lag = (p[29] * a_lag) ** 2
        infl = p[6] / dt
        sv3 = 3.0 * math.sqrt(max(P[IV, IV], 0.0))
        # octaves: the speed prior decides (GPS or the filter's own speed, with the decisive
        # gate away from GPS) and, while r is not known yet, the radius prior
        # an unclaimed line is a hypothesis only where it continues the last line used (at
        # most vib_soft_hold s before the previous fusion sample, within half an octave of
        # its omega), and only at that line's octave
        soft_cont = (soft and p[35] > 0.0 and not math.isnan(sc[14])
                     and t - sc[13] <= dt + p[34] and abs(math.log2(om / sc[14])) <= 0.5)
        # the tracker's posterior as the measurement (vib_measure="posterior", r known): per
        # octave the product of its line-conditional posterior with the prediction's Gaussian
        # on the line, N(v / (r k), S_k), read as the likelihood that product implies
        pm = p[36] > 0.5 and post.size > 0 and known
        p_line = 0.0
        if pm:
            for j in range(post.size):
                p_line += post[j]
            pm = p_line > 0.0
        zu = om
        vu = var_om
        bfu = 0.0
        beta = 1.0
        # (read through the posterior, an unclaimed line is weighed by its line probability
        # like a claimed one, so it need not continue the last line used)
        for j in range(3 if ready and not hard and (soft_cont or not soft or pm) else 0):
            k = 1.0 if j == 0 else (0.5 if j == 1 else 2.0)
            if soft and not pm and k != sc[15]:
                continue
            if (x[IV] + sv3) < p[21] * k * om or (x[IV] - sv3) > p[22] * k * om:
                continue  # no physical radius explains this line at this speed
            if known and not (x[IV] > 0.0 and abs(math.log2(k * x[IR] * om / x[IV])) <= 0.5):
                continue  # nearer another octave of the filter's speed than this one
            if pm:
                # the prediction of the line: omega = v / (r k), linearised in v and r, with
                # the tracker's lag and one grid cell (the posterior's resolution)
                rk = r_hat * k
                m = x[IV] / rk
                sp = ((P[IV, IV] - 2.0 * m * k * P[IV, IR] + (m * k) ** 2 * P[IR, IR]
                       + var_lag) / (rk * rk) + (grid[1] - grid[0]) ** 2)
                bf, mu, vp = _post_product(post, grid, m, math.sqrt(sp), p[37])
                if not (bf > 0.0 and vp < sp):
                    continue  # no posterior mass near the prediction, or none that narrows it
                rz = 1.0 / (1.0 / vp - 1.0 / sp)  # the likelihood: the product / the prior
                z = rz * (mu / vp - m / sp)
                if not z > 0.0:
                    continue
                cost = -2.0 * math.log(bf / p_line) + (0.0 if j == 0 else p[8])
                if cost < best:
                    best = cost
                    kk = k
                    zu = z
                    vu = rz + (p[5] * z) ** 2
                    bfu = bf / p_line
                continue
            hr = -k * om
            nu = -(x[IV] + hr * x[IR])
            s = (P[IV, IV] + 2.0 * hr * P[IV, IR] + hr * hr * P[IR, IR]
                 + (r_hat * k) ** 2 * var_om + var_lag)  # one sample's: the gate
            cost = nu * nu / s + (0.0 if j == 0 else p[8])
            if cost < best:
                best = cost
                kk = k
        # direct use needs a decisive gate: the band narrow against the octaves' spacing
        # or the tracker claims a line that continues the one used at the previous fusion
        # sample (at the same octave, within half an octave of its omega): the octave was
        # decided when the line was first taken, and a claimed line that moves by less than
        # half an octave from one sample to the next has not changed harmonic (with
        # vib_use=all the omegas offered are not claims: no continuation)
        cont = (p[33] > 0.5 and not math.isnan(kk) and kk == sc[15] and sc[13] == t_prev
                and abs(math.log2(zu / sc[14])) <= 0.5) or (
                    soft_cont and p[33] > 0.5)
        decisive = not math.isnan(kk) and (fresh or cont or 3.0 * math.sqrt(
            P[IV, IV] + (r_hat * kk) ** 2 * vu) <= p[28] * r_hat * kk * zu)
        glim = p[35] if soft else p[7]
        if pm:
            # the posterior's line is there with probability beta (its line probability and
            # its mass near the prediction against a flat posterior's: the "no line" state
            # explains the data as well as a flat posterior does)
            if not math.isnan(kk):
                beta = p_line * bfu / (p_line * bfu + 1.0 - p_line)
            ok = not math.isnan(kk) and beta >= p[38] and decisive
            best = 0.0 if ok else math.inf
            glim = 0.0
            vu = vu / max(beta, 1e-12)
        if ready and known and not hard and not (best <= glim and decisive or pm and best <= glim):
            # re-lock run on the line at k = 1 (the octave that taught r): the gap
            # d = r omega - v between the line's speed and the filter's must hold for
            # vib_relock s (no GPS in that time), and the line must have moved with the speed
            # (by acq_change) or lie inside the 3-sigma band (a constant line far outside it
            # may be an idling engine at a stop)
            best = math.inf
            kk = math.nan
            u = x[IR] * om
            d = u - x[IV]
            if math.isnan(sc[6]) or t - sc[1] <= p[20] or abs(d - sc[10]) > p[26] * u:
                sc[6] = t
                sc[10] = d
                sc[11] = u
                sc[12] = d
            else:
                sc[10] += (d - sc[10]) * min(1.0, dt / p[25])
                # moved with the speed: the line's speed changed by acq_change while the
                # mean gap changed by less than 0.4 of that (a line at another octave of the
                # one that taught r, v = c r omega with c = 2 or 1/2, changes the gap by
                # |1 - c| >= 1/2 of its own change; a running mean alone would follow a gap
                # that drifts with the speed)
                du = abs(u - sc[11])
                moved = du >= p[27] * u and abs(sc[10] - sc[12]) <= 0.4 * du
                # inside the band only a line within a factor sqrt 2 of the filter's speed:
                # nearer another octave of it (2 u, u / 2), a band that wide cannot tell
                # which octave the line is, and a re-lock never moves the speed by a factor 2
                inside = abs(d) <= sv3 and x[IV] > 0.0 and abs(math.log2(u / x[IV])) <= 0.5
                if t - sc[6] >= p[20] and (moved or inside):
                    # an unclaimed line widens the band to its gap (one sigma), a claimed
                    # one by its gap; Pp gets the same, the process noise of this step for
                    # the smoother
                    dpv = max(d * d - P[IV, IV], 0.0) if soft else d * d
                    P[IV, IV] += dpv
                    Pp[IV, IV] += dpv
                    if kb:
                        Pb[IV, IV] += dpv
                        Pbp[IV, IV] += dpv
                    sc[6] = math.nan
                    if not soft:
                        best = 0.0
                        kk = 1.0
                        zu = om
                        vu = var_om
                    # an unclaimed line widens the band by its gap but is not taken: a
                    # claimed line at that gap then lies inside the band and re-locks
        if best <= glim:
            sc[13] = t
            sc[14] = zu
            sc[15] = kk
            h[IV] = 1.0
            h[IR] = -kk * zu
            # away from GPS the radius and the offset are consider states: a line there
            # carries the speed but teaches neither (a wrong or lagging line accepted in an
            # outage would corrupt the radius and the offset the inertial stretches rest on)
            rv = ((r_hat * kk) ** 2 * vu + var_lag) * infl
            _update(x, P, Pb, J, h, 0.0, rv, rv, -1 if fresh else IR, -1 if fresh else IB)
            h[IV] = 0.0
            h[IR] = 0.0
            # the radius follows the octave most updates use (where GPS confirms them), as
            # far as the radius prior allows it: within 3 sigma of the prior (a car's prior
            # of a few cm keeps r where a tracker on the 2nd harmonic would teach r / 2)
            if fresh:
                sc[5] += (math.log2(kk) - sc[5]) * min(1.0, dt / p[16])
            if abs(sc[5]) > 0.5 and known:
                c = 2.0 if sc[5] > 0.0 else 0.5
                if abs(c * x[IR] - p[30]) <= 3.0 * p[31]:
                    x[IR] *= c
                    for i in range(n):
                        P[IR, i] *= c
                        P[i, IR] *= c
                        if kb:
                            Pb[IR, i] *= c
                            Pb[i, IR] *= c
                sc[5] = 0.0
        else:
            kk = math.nan
    # 4. standstill from all evidence
    stopped = False
    if not still:
        sc[7] = math.nan
    else:
        gps_ok = math.isnan(sc[3]) or (t - sc[2]) > p[14] or sc[3] <= p[13]
        consistent = (x[IV] * x[IV] / (P[IV, IV] + p[9]) <= p[11]) or abs(x[IV]) <= p[12]
        if gps_ok and not consistent:
            if math.isnan(sc[7]):
                sc[7] = t
            elif t - sc[7] >= p[23] and t - sc[1] > p[23]:
                # re-lock: the integrated speed, not the stop, is wrong
                Pp[IV, IV] += x[IV] * x[IV]  # process noise of this step, for the smoother
                P[IV, IV] += x[IV] * x[IV]
                if kb:
                    Pbp[IV, IV] += x[IV] * x[IV]
                    Pb[IV, IV] += x[IV] * x[IV]
                consistent = True
        if gps_ok and consistent:
            sc[7] = math.nan
            h[IV] = 1.0
            _update(x, P, Pb, J, h, 0.0, p[9], p[9])
            h[IV] = 0.0
            h[IA] = 1.0
            _update(x, P, Pb, J, h, 0.0, p[10], p[10])
            h[IA] = 0.0
            stopped = True
    # 5. speed >= 0: project onto the constraint surface
    if p[17] > 0.5 and x[IV] < 0.0 and P[IV, IV] > 0.0:
        f = x[IV] / P[IV, IV]
        for i in range(n):
            x[i] -= P[i, IV] * f
        x[IV] = 0.0
    if stopped:
        src = 3
    elif t - sc[1] <= p[15]:
        src = 1
    elif not math.isnan(kk):
        src = 2
    else:
        src = 0
    out[0] = x[IV]
    out[1] = math.sqrt(max(Pb[IV, IV] if kb else P[IV, IV], 0.0))
    out[2] = x[IR]
    out[3] = math.sqrt(max(P[IR, IR], 0.0))
    out[4] = x[IB]
    out[5] = src
    out[6] = kk
    return dt


@njit(cache=True)
def _run_core(Ac, qc, p, x, P, sc, t, am, g, sats, om, om_std, line, still, soft, posts, grid,
              out, xp, Pp, xf, Pf, dts, Pb, bands, Pbp, Pbf, Js):
    """:func:`_step_core` over the samples; ``Pb`` (n, n) and ``bands`` (one density per
    sample) keep the band's covariance (0 x 0 / empty: none), its predictions and posteriors
    into ``Pbp``, ``Pbf`` and the samples' update transitions into ``Js``."""
    Fc = np.eye(x.size)
    none = np.empty(0)
    have = posts.shape[0] == t.size
    kb = Pb.shape[0] > 0
    scratch = np.empty((x.size, x.size))
    for k in range(t.size):
        dts[k] = _step_core(Ac, qc, p, x, P, sc, Fc, t[k], am[k], g[k], sats[k], om[k],
                            om_std[k], line[k], still[k], soft[k], posts[k] if have else none,
                            grid, out[k], xp[k], Pp[k], Pb, bands[k] if kb else 0.0,
                            Pbp[k] if kb else scratch, Js[k] if kb else scratch)
        xf[k, :] = x
        Pf[k, :, :] = P
        if kb:
            Pbf[k, :, :] = Pb

