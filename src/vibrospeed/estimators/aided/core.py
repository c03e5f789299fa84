"""The compiled core of the aided EKF (numba): one sample's update in place
(:func:`_aided_step`: detectors, boost, vibration update with the line gate, CUSUM, standstill
measurement, comb check, reference fix, clip, time update; thesis eq. 3.4-3.15) and the loop
over a signal (:func:`_aided_run`). The state arrives as flat arrays and the parameters as one
float vector (:func:`vibrospeed.estimators.aided.filter._args` packs them), so ``step`` and
``run`` are this same code.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from vibrospeed.estimators.ekf import harmonic_update, rotate_phasors, symmetrize_into
from vibrospeed.estimators.kalman import joseph_update
from vibrospeed.signal.comb import comb_vote, restart_phasors
from vibrospeed.signal.detectors import _cusum_core, _mode_core, _window_core

N_OUT = 11  # omega, std, bias, ss, acc, boost, ubar, innov, innov var, share, locked; then amps


@njit(cache=True)
def _scalar_update(x, P, j, z, r):
    """Update with the scalar measurement ``z = x[j] + e``, var(e) = r (Joseph form)."""
    s = P[j, j] + r
    k = P[:, j] / s
    joseph_update(x, P, k, z - x[j], r, j, 1, 1)


@njit(cache=True)
def _vib_update(x, P, y, M, r, lock):
    """Vibration update ``y = sum_m alpha_m + e`` (thesis eq. 2.23, 2.26); -> (innov, S).
    ``lock`` False: the gains on omega (index 0) and b (last) are 0 (line gate)."""
    return harmonic_update(x, P, y, M, r, not lock, not lock)


@njit(cache=True)
def _aided_step(x, P, y, u, gain, ref, ref_var, still, comb, wbuf, wpc, wflag, cgs, mbuf, mpc,
                mflag, line, M, ss_kind, boost_n, flags, fp, out):
    """One sample in place. ``still``: the external standstill flag (> 0.5 standing; read with
    ``ss_kind`` 3); ``comb``: the comb's omega candidate (NaN: none this sample), a fix when
    omega has disagreed with it by more than ``fp[18]`` (relative) ``fp[17]`` candidates in a
    row. ``flags`` int: [boost_on, aid_always, cusum_hold, release_on_accel];
    ``fp``: [T, q_om, q_om_acc, q_amp, r, r_wheel, q_b, om_max, ss_mu, r_ss, c_sigma, c_nu,
    c_h, mode_mu, line_min, line_tau, line_omega_min]; ``line`` [power, count, known]."""
    T = fp[0]
    q_om = fp[1]
    q_om_acc = fp[2]
    q_amp = fp[3]
    r = fp[4]
    rw = fp[5]
    q_b = fp[6]
    om_max = fp[7]
    n = x.size
    nb = n - 1
    # ---- detectors -----------------------------------------------------------------------
    acc, boost, ubar = _mode_core(mbuf, mpc, mflag, u, fp[13])
    ss = False
    if ss_kind == 1:
        ss = _window_core(wbuf, wpc, wflag, y, fp[8])
    ext = ss_kind == 3 and still > 0.5  # NaN: no decision, moving
    if ext and acc and flags[3] == 1:
        # release_on_accel: the stop flag reaches into the start (the causal detector lets go
        # 1-1.7 s after the vehicle moves off); a speed change read by the mode detector
        # (a_x less its offset while standing) ends the stop, and the start is integrated
        ext = False
    if ext:
        # a vehicle whose broadband vibration sits at its floor stands: what the mode detector
        # reads then is the accelerometer's offset, not a speed change
        ss = True
        acc = False
        boost = False
    # ---- boost (thesis eq. 3.15) -------------------------------------------------------------
    if boost and flags[0] == 1:
        x[0] += boost_n * T * ubar / rw
    # ---- vibration measurement update (only in vibration mode) -----------------------------
    innov = np.nan
    s_var = np.nan
    share = np.nan
    lock = False
    if np.isfinite(y) and np.isfinite(gain):
        yg = y * gain
        line[1] += 1.0
        a_pw = max(T / fp[15], 1.0 / line[1])
        line[0] += a_pw * (yg * yg - line[0])
        expl = 0.0
        for m in range(M):
            expl += 0.5 * (x[1 + 2 * m] ** 2 + x[2 + 2 * m] ** 2)
        inst = expl / line[0] if line[0] > 0.0 else 0.0
        line[3] += a_pw * (inst - line[3])
        share = line[3]
        lock = line[2] > 0.5 and (fp[14] <= 0.0 or (share >= fp[14] and x[0] >= fp[16]
                                                     and line[1] * T >= fp[15]))
        if not acc:
            innov, s_var = _vib_update(x, P, yg, M, r, lock)
    if not lock and fp[14] > 0.0:
        # gate closed: the phasors are a plain Kalman filter at the current omega (no cross
        # covariance with omega, and omega's growing variance is not fed into their phase in
        # the time update); otherwise their bandwidth widens with var(omega) and they would
        # "explain" any noise, opening the gate
        for i in range(1, n - 1):
            P[0, i] = 0.0
            P[i, 0] = 0.0
            P[n - 1, i] = 0.0
            P[i, n - 1] = 0.0
    if ss_kind == 2:
        eps = np.nan
        if np.isfinite(innov) and gain > 0.0:
            e = innov / gain / fp[10]
            eps = 1.0 - e * e
        _cusum_core(cgs, eps, fp[11], fp[12])
        ss = cgs[1] <= flags[2]
    # ---- virtual standstill measurement omega = 0 (thesis eq. 3.4-3.6) ----------------------
    ss = ss and not acc  # a vehicle in acceleration mode is not standing still (thesis tests)
    if ss:
        _scalar_update(x, P, 0, 0.0, fp[9])
        line[2] = 1.0
    # ---- comb check: re-lock where omega has left the wheel's comb ---------------------------
    if np.isfinite(comb) and comb > 0.0 and not ss:
        # a candidate counts when it is steady (agrees with the previous one) and the vehicle
        # is not in acceleration mode (a 3 s frame lags a speed change)
        _, reset = comb_vote(line[4:6], comb, x[0], fp[18], fp[17], not acc)
        if reset:
            # the phasors belong to the old rotation (at half the wheel speed the line sits
            # in phasor 2 and would pull omega back): they restart, uncorrelated
            restart_phasors(x, P, 1, n - 1, fp[19])
            _scalar_update(x, P, 0, comb, (0.5 * fp[18] * comb) ** 2)
            line[2] = 1.0
    # ---- reference-speed fix (thesis 4.2.4) ------------------------------------------------
    if np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0.0:
        _scalar_update(x, P, 0, ref, ref_var)
        line[2] = 1.0
    # omega >= 0: clipped at 0 (with a_x aiding the direction is known; the EKF's mirror
    # symmetry (omega, beta) -> (-omega, -beta) would turn an overshoot below 0 into a speed)
    if x[0] < 0.0:
        x[0] = 0.0
    if x[0] > om_max:
        x[0] = om_max
    # ---- outputs -----------------------------------------------------------------------------
    out[0] = x[0]
    out[1] = np.sqrt(max(P[0, 0], 0.0))
    out[2] = x[nb]
    out[3] = 1.0 if ss else 0.0
    out[4] = 1.0 if acc else 0.0
    out[5] = 1.0 if (boost and flags[0] == 1) else 0.0
    out[6] = ubar
    out[7] = innov
    out[8] = s_var
    out[9] = share
    out[10] = 1.0 if (lock and not acc and np.isfinite(innov)) else 0.0
    for m in range(M):
        a = x[1 + 2 * m]
        b = x[2 + 2 * m]
        out[N_OUT + m] = np.sqrt(a * a + b * b)
    # ---- time update (thesis eq. 3.10-3.12) --------------------------------------------------
    ue = 0.0
    if (acc or flags[1] == 1) and np.isfinite(u):
        ue = u
    om = x[0]
    F = np.eye(n)
    xn = x.copy()
    rotate_phasors(x, xn, F, M, T, lock or fp[14] <= 0.0)
    xn[0] = om + T * (x[nb] + ue) / rw
    F[0, nb] = T / rw
    for i in range(n):
        x[i] = xn[i]
    Pn = F @ P @ F.T
    Pn[0, 0] += T * (q_om_acc if acc else q_om)
    for i in range(1, nb):
        Pn[i, i] += T * q_amp
    Pn[nb, nb] += T * q_b
    symmetrize_into(Pn, P)


@njit(cache=True)
def _aided_run(ys, us, gains, refs, ref_vars, stills, combs, x, P, wbuf, wpc, wflag, cgs, mbuf,
               mpc, mflag, line, M, ss_kind, boost_n, flags, fp):
    n_s = ys.size
    outs = np.empty((n_s, N_OUT + M))
    out = np.empty(N_OUT + M)
    for k in range(n_s):
        _aided_step(x, P, ys[k], us[k], gains[k], refs[k], ref_vars[k], stills[k], combs[k],
                    wbuf, wpc,
                    wflag, cgs, mbuf, mpc, mflag, line, M, ss_kind, boost_n, flags, fp, out)
        outs[k] = out
    return outs
