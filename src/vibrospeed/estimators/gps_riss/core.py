"""The compiled core of GPS/RISS (numba): one accelerometer sample in place (:func:`_step_core`:
pre-processing, KF1 / KF INS, the GPS error E of the chosen error mode and KF2, the integrator
offset filter; package notes items 1-5) and the loop over a signal (:func:`_run_core`), with
the small dense Kalman steps of :mod:`vibrospeed.estimators.kalman` (the Joseph-form
``row_update``, ``dense_predict``). The state arrives as flat arrays and the parameters as
one float vector (``Config._arrays``), so ``step`` and ``run`` are this same code.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from vibrospeed.estimators.gps_riss.config import G
from vibrospeed.estimators.kalman import dense_predict, quad_form, row_update
from vibrospeed.models.gps_riss import transition


@njit(cache=True)
def _lag_row(Ac, x, ig, h):
    """The GPS row linearised at ``x`` (extended Kalman filter): the fix reads the receiver
    model's output ``x3 = x[ig]`` an extra lag ``dl = x[-1]`` earlier, ``g ~ x3 - dl x3'`` with
    ``x3' = Ac[ig] x``. ``h`` receives ``d g / d x`` and the return value is
    ``h x - g(x) = -dl x3'``, so that ``(z + that) - h x`` is the innovation of a fix ``z``."""
    n = x.size
    dl = x[n - 1]
    d3 = 0.0
    for i in range(n):
        d3 += Ac[ig, i] * x[i]
    for i in range(n):
        h[i] = -dl * Ac[ig, i]
    h[ig] += 1.0
    h[n - 1] = -d3
    return -dl * d3


@njit(cache=True)
def _step_core(Ac, qc, ha, hg, p, poly, x, P, x2, P2, lz, od, Pod, sc, t, a_raw, gps, sats,
               Fc, out):
    """One sample in place. ``sc = [t_prev, E, v_int, dt of Fc]``; ``Fc`` caches the transition
    of the last step length; ``out`` (8,) receives the results. Returns the mode."""
    dt = 0.0 if math.isnan(sc[0]) else t - sc[0]
    sc[0] = t
    integ = p[10] > 0.5
    emode = int(p[14])
    use_kf2 = emode > 0
    # 1. accelerometer pre-processing: gain, pitch (paper eq. 14, degrees)
    has_a = math.isfinite(a_raw)  # NaN or inf: no sample (an inf made every later one NaN)
    a = p[8] * a_raw
    if has_a and p[9] > 0.5:
        pitch = 0.0
        for c in poly:
            pitch = pitch * a + c
        pr = pitch * math.pi / 180.0
        a = (a - G * math.sin(pr)) / math.cos(pr)
    # integrator drift filter predict (eq. 16) and integral of the pre-processed accelerometer
    if dt > 0.0:
        if has_a:
            sc[2] += dt * a
        else:
            sc[2] += dt * (x[1] + x[2] + od[1])
        if integ:
            od[0] += dt * od[1]
            p00 = Pod[0, 0] + dt * (Pod[0, 1] + Pod[1, 0]) + dt * dt * Pod[1, 1] + p[11] * dt
            p01 = Pod[0, 1] + dt * Pod[1, 1]
            Pod[0, 0] = p00
            Pod[0, 1] = p01
            Pod[1, 0] = p01
            Pod[1, 1] += p[12] * dt
    a_c = a - od[1] if integ else a
    # 2. predict with the exact transition
    if dt > 0.0:
        if dt != sc[3]:
            Fc[:, :] = transition(Ac, dt)
            sc[3] = dt
        qd = qc * dt
        dense_predict(x, P, Fc, qd)
        if use_kf2:
            # the receiver chain (states 3 .. n - 2; the extra lag last is not in it) driven by
            # KF2's speed and acceleration: the prediction of the fix
            lzn = np.empty(lz.size)
            for i in range(lz.size):
                v = Fc[3 + i, 0] * x2[0] + Fc[3 + i, 1] * x2[1]
                for j in range(lz.size):
                    v += Fc[3 + i, 3 + j] * lz[j]
                lzn[i] = v
            for i in range(lz.size):
                lz[i] = lzn[i]
            dense_predict(x2, P2, Fc, qd)
    # 3. gating
    has_fix = math.isfinite(gps)
    valid = has_fix and (math.isnan(sats) or sats >= p[7])
    r22 = math.nan
    r_acc = p[1] if valid else p[0]
    if p[15] > 0.0:
        # a noise density: a sample of dt s weighs dt / acc_psd; one of no duration nothing
        r_acc = p[15] / dt if dt > 0.0 else math.inf
    if has_a and r_acc < math.inf:
        row_update(x, P, ha, a_c, r_acc)
        if use_kf2:
            row_update(x2, P2, ha, a_c, r_acc)
    if valid:
        # 4. GPS error E and R22 (eq. 13); the main filter's row with the receiver's extra lag
        hl = np.empty(x.size)
        zl = gps + _lag_row(Ac, x, 3, hl)
        if emode == 0:  # main filter's innovation beyond its predicted spread
            nu = zl
            for i in range(x.size):
                nu -= hl[i] * x[i]
            s0 = quad_form(hl, P) + p[2]
            e = math.sqrt(max(nu * nu - s0, 0.0))
        elif emode == 1:  # KF2's prediction of the fix, before KF2's update
            e = abs(gps - lz[0])
            row_update(x2, P2, hg, gps, p[2])
        else:  # "states" (paper VI-c): KF2's x3 against its speed through the lag model
            row_update(x2, P2, hg, gps, p[2])
            e = abs(x2[3] - lz[0])
        e = min(max(e, 0.0), p[5])
        sc[1] = e
        r22 = p[2] + p[3] * e + p[4] * e * e if p[6] > 0.5 else p[2]
        row_update(x, P, hl, zl, r22)
        # 5. integrator drift filter update (eq. 17): observes integral(a) - v
        if integ:
            s = Pod[0, 0] + p[13] * (r22 / p[2])  # weighted down like the GPS itself
            k0 = Pod[0, 0] / s
            k1 = Pod[1, 0] / s
            innov = (sc[2] - x[0]) - od[0]
            od[0] += k0 * innov
            od[1] += k1 * innov
            p00 = (1.0 - k0) * Pod[0, 0]
            p01 = (1.0 - k0) * Pod[0, 1]
            p11 = Pod[1, 1] - k1 * Pod[0, 1]
            Pod[0, 0] = p00
            Pod[0, 1] = p01
            Pod[1, 0] = p01
            Pod[1, 1] = p11
    out[0] = x[0]
    out[1] = math.sqrt(max(P[0, 0], 0.0))
    out[2] = x[1]
    out[3] = x[3]
    if integ:
        out[4] = od[1]
        out[5] = math.sqrt(max(Pod[1, 1], 0.0))
    else:
        out[4] = x[2]
        out[5] = math.sqrt(max(P[2, 2], 0.0))
    out[6] = sc[1]
    out[7] = r22
    if valid:
        return 1
    if has_fix:
        return 2
    return 0


@njit(cache=True)
def _run_core(Ac, qc, ha, hg, p, poly, x, P, x2, P2, lz, od, Pod, sc, t, a, gps, sats, out, mode):
    Fc = np.eye(x.size)
    for k in range(t.size):
        mode[k] = _step_core(Ac, qc, ha, hg, p, poly, x, P, x2, P2, lz, od, Pod, sc, t[k], a[k],
                             gps[k], sats[k], Fc, out[k])
