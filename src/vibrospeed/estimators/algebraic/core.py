"""The compiled core of the algebraic estimator (numba): one sample in place (:func:`_core`:
algebraic filters, disturbance system with resets, slip detection with backtracking, yaw
detection, Vx / Vy updates and their standard deviations; package docstring, steps 1-4) and
the loop over a signal (:func:`_run`). The scalar state is one packed array; its layout (the
``_*`` indices below) is defined here, next to the code that reads it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from vibrospeed.models.kinematics import disturbance_rhs

# packed scalar state: indices into State.s
_GX, _GY, _VX, _VY, _NX, _NY, _NRESET, _POS, _STARTED = 0, 1, 2, 3, 4, 5, 6, 7, 8
_LAST = 9  # 4 values: last finite input per channel (zero-order hold)
_LAST2 = 13  # 4 values: the finite input before it
_NSEEN = 17  # 4 values: finite samples seen per channel
_ND2 = 21  # 4 values: second differences averaged per channel
_MSQ = 25  # 4 values: running mean of the squared second differences
_VX0, _VXRW, _TX, _VY0, _VYRW, _TY = 29, 30, 31, 32, 33, 34  # integration-mode variances
_HX, _HY = 35, 36  # hand-over allowances (variances, decaying)
_HPOS, _NSTEP, _VARX, _VARY = 37, 38, 39, 40
_SLIP = 41  # window detection: 1 while integrating
_NS = 42


@njit(cache=True)
def _noise_update(s, j, x, w_min, update):
    """Second-difference noise statistic of channel ``j``: for white noise of sd sigma,
    ``E[(x_i - 2 x_{i-1} + x_{i-2})^2] = 6 sigma^2``; running mean, memory ``noise_tau``."""
    if s[_NSEEN + j] >= 2.0 and update:
        d2 = x - 2.0 * s[_LAST + j] + s[_LAST2 + j]
        s[_ND2 + j] += 1.0
        w = max(1.0 / s[_ND2 + j], w_min)
        s[_MSQ + j] += w * (d2 * d2 - s[_MSQ + j])
    s[_LAST2 + j] = s[_LAST + j]
    s[_LAST + j] = x
    s[_NSEEN + j] += 1.0


@njit(cache=True)
def _core(b0, b1, p, buf, hist, s, z, out):
    """One sample of Algorithms 1 and 2 in place on ``buf``, ``hist``, ``s``; outputs to
    ``out`` (:data:`OUTPUTS`)."""
    r, L1, dt, eps1, alpha, eps2, beta = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    rex, rey, rhold, vy0 = p[7], p[8], p[9], p[10]
    nback, eps_k, slip_sd, b_acc, b_gyro, h_tau, n_tau = (
        int(p[11]), p[12], p[13], p[14], p[15], p[16], p[17])
    g0, g1, max_int = p[18], p[19], p[20]
    win, tol, kwin = p[21] > 0.5, p[22], int(p[23])
    L = b0.size
    K = hist.shape[1]
    first = s[_STARTED] == 0.0
    # all channels known at least once (zero-order hold of NaN inputs)
    ok = True
    for j in range(4):
        if not (np.isfinite(z[j]) or np.isfinite(s[_LAST + j])):
            ok = False
    if not ok:
        out[:] = np.nan
        return
    # on-line noise statistics; the wheel-speed noise only in wheel mode (ABS cycles are no
    # noise) once 50 differences are known
    w_min = dt / n_tau
    if win:
        wheel_upd = s[_SLIP] == 0.0 or s[_ND2 + 3] < 50.0
    else:
        wheel_upd = s[_NX] >= alpha + 1.0 or s[_ND2 + 3] < 50.0
    for j in range(4):
        if np.isfinite(z[j]):
            _noise_update(s, j, z[j], w_min, j < 3 or wheel_upd)
    sig2_gz = s[_MSQ] / 6.0
    sig2_ax = s[_MSQ + 1] / 6.0
    sig2_ay = s[_MSQ + 2] / 6.0
    sig2_wm = s[_MSQ + 3] / 6.0
    pos = int(s[_POS])
    if first:  # steady-state buffers, wheels roll, Vy = vy0
        for j in range(4):
            buf[j, :] = s[_LAST + j]
        s[_GX] = 0.0
        s[_GY] = 0.0
        s[_VX] = r * s[_LAST + 3]
        s[_VY] = vy0
        s[_NX] = alpha + 1.0
        s[_NY] = 0.0
        s[_NRESET] = 0.0
        s[_SLIP] = 0.0
        s[_STARTED] = 1.0
    # algebraic filters (Algorithm 1, line 1)
    f0 = np.zeros(4)
    f1 = np.zeros(4)
    for j in range(4):
        buf[j, pos] = s[_LAST + j]
        a0 = 0.0
        a1 = 0.0
        for k in range(L):
            q = pos - k
            if q < 0:
                q += L
            a0 += b0[k] * buf[j, q]
            a1 += b1[k] * buf[j, q]
        f0[j] = a0
        f1[j] = a1
    pos += 1
    if pos == L:
        pos = 0
    s[_POS] = pos
    wz, ax, ay, wm = f0[0], f0[1], f0[2], f0[3]
    wz_dot, wm_dot = f1[0], f1[3]
    # disturbance system (seed eq. 7), explicit Euler (line 2)
    dgx, dgy = disturbance_rhs(s[_GX], s[_GY], wz, wz_dot, wm, wm_dot, ax, ay, r, L1)
    s[_GX] += dt * dgx
    s[_GY] += dt * dgy
    # remark 4: reset G when the residual derivatives stay near zero
    if rhold > 0:
        if abs(r * wm_dot) < rex and abs(L1 * wz_dot) < rey:
            s[_NRESET] += 1.0
        else:
            s[_NRESET] = 0.0
        if s[_NRESET] >= rhold:
            s[_GX] = 0.0
            s[_GY] = 0.0
    # thresholds, optionally scaled to the measured noise of dGx/dt and of psi_dot
    e1 = eps1
    e2 = eps2
    if eps_k > 0.0:
        e1 = max(eps1, eps_k * np.sqrt(g0 * g0 * sig2_ax + r * r * g1 * g1 * sig2_wm))
        e2 = max(eps2, eps_k * g0 * np.sqrt(sig2_gz))
        # window residual: two filtered wheel speeds and kwin filtered accelerations
        tol = max(tol, eps_k * g0 * np.sqrt(2.0 * r * r * sig2_wm + kwin * dt * dt * sig2_ax))
    # no longitudinal force below the acceleration that moves the speed by tol in a window
    a_free = tol / (kwin * dt)
    # window-held switching conditions (line 3 of Algorithms 1 and 2)
    nx_prev = s[_NX]
    was_turn = s[_NY] < beta + 1.0
    s[_NY] = s[_NY] + 1.0 if abs(wz) < e2 else 0.0
    vx_prev = s[_VX]
    vy_prev = s[_VY]
    varx_prev = s[_VARX]
    vary_prev = s[_VARY]
    turn = s[_NY] < beta + 1.0
    # history of Vx and of the increments Ts (gamma_x + psi_dot Vy) for the backtracking
    hpos = int(s[_HPOS])
    inc = dt * (ax + wz * vy_prev)
    hist[2, hpos] = inc
    if win:
        # window detection: res = change of r omega_mean over the last kwin samples minus the
        # dead-reckoned change (the increments); the wheels start to slip when |res| >= tol.
        # Integrating, they are trusted again after kwin samples in which they agree with the
        # integrated speed, or in which there is no longitudinal force (|a_x| < a_free: no
        # force, no slip) and |res| < tol (the integrated speed has drifted, the wheels roll)
        was_slip = s[_SLIP] == 1.0
        vw = r * wm
        nb0 = min(kwin, int(s[_NSTEP]))
        res = 0.0
        if nb0 > 0:
            q = hpos - nb0
            if q < 0:
                q += K
            res = vw - hist[3, q]
            for _m in range(nb0):
                q += 1
                if q == K:
                    q = 0
                res -= hist[2, q]
        if was_slip:
            agree = abs(vw - (vx_prev + inc)) < tol or (abs(ax) < a_free and abs(res) < tol)
            s[_NX] = s[_NX] + 1.0 if agree else 0.0
            slip = s[_NX] < kwin
        elif s[_NX] < 0.0:  # wheels trusted for a window after a capped episode
            slip = False
            s[_NX] += 1.0
        else:
            slip = nb0 > 0 and abs(res) >= tol
            s[_NX] = 0.0
        if slip and was_slip and s[_TX] + dt > max_int:  # integration episode too long
            slip = False
            s[_NX] = -float(kwin)
        s[_SLIP] = 1.0 if slip else 0.0
    else:
        was_slip = nx_prev < alpha + 1.0
        s[_NX] = s[_NX] + 1.0 if abs(dgx) < e1 else 0.0
        slip = s[_NX] < alpha + 1.0
        if slip and was_slip and s[_TX] + dt > max_int:  # integration episode too long
            s[_NX] = alpha + 1.0
            slip = False
    decay = np.exp(-2.0 * dt / h_tau)
    # Vx: Algorithm 1 with its standard deviation
    qx = dt * dt * (sig2_ax + vy_prev * vy_prev * sig2_gz + wz * wz * vary_prev)
    if slip:
        # never back into the previous integration episode (nx_prev - alpha samples of wheel
        # mode precede this one)
        if win:
            nb = -1
        else:
            nb = min(nback, int(s[_NSTEP]) - 1, int(nx_prev - alpha) - 1)
        if win and not was_slip:
            # slip onset: restart from the wheel speed kwin samples back plus the increments
            q = hpos - nb0
            if q < 0:
                q += K
            vx0 = hist[0, q]
            for _m in range(nb0):
                q += 1
                if q == K:
                    q = 0
                vx0 += hist[2, q]
            s[_VX] = vx0
            q = hpos - nb0
            if q < 0:
                q += K
            s[_VX0] = hist[1, q]
            s[_VXRW] = nb0 * qx
            s[_TX] = nb0 * dt
        elif not was_slip and nb >= 0:
            # slip onset: restart from Vx(t_i - (nb + 1) Ts), re-integrate the nb + 1 increments
            q = hpos - nb - 1
            if q < 0:
                q += K
            vx = hist[0, q]
            s[_VX0] = hist[1, q]
            for _m in range(nb + 1):
                q += 1
                if q == K:
                    q = 0
                vx += hist[2, q]
            s[_VX] = vx
            s[_VXRW] = (nb + 1) * qx
            s[_TX] = (nb + 1) * dt
        else:
            if not was_slip:  # slip from the first sample on
                s[_VX0] = varx_prev
                s[_VXRW] = 0.0
                s[_TX] = 0.0
            s[_VX] = vx_prev + inc
            s[_VXRW] += qx
            s[_TX] += dt
        bx = s[_TX] * b_acc
        varx = s[_VX0] + s[_VXRW] + bx * bx
    else:
        s[_VX] = r * wm
        if was_slip and not first:
            d = vx_prev - s[_VX]  # disagreement at the hand-over: one of the two is wrong
            s[_HX] = max(s[_HX] * decay, d * d)
        else:
            s[_HX] *= decay
        sx = slip_sd * s[_VX]
        varx = r * r * g0 * g0 * sig2_wm + sx * sx + s[_HX]
    # Vy: Algorithm 2 with its standard deviation
    if turn:
        qy = dt * dt * (sig2_ay + vx_prev * vx_prev * sig2_gz + wz * wz * varx_prev)
        if not was_turn:
            s[_VY0] = vary_prev
            s[_VYRW] = qy
            s[_TY] = dt
        else:
            s[_VYRW] += qy
            s[_TY] += dt
        s[_VY] = vy_prev + dt * (ay - wz * vx_prev)
        by2 = (b_acc * b_acc + vx_prev * vx_prev * b_gyro * b_gyro) * s[_TY] * s[_TY]
        vary = s[_VY0] + s[_VYRW] + by2
    else:
        s[_VY] = 0.0
        sy = L1 * e2  # kinematic side-slip bound while |psi_dot| < eps2
        vary = sy * sy
    if first:
        vary = (L1 * e2) ** 2
    s[_VARX] = varx
    s[_VARY] = vary
    hist[0, hpos] = s[_VX]
    hist[1, hpos] = varx
    hist[3, hpos] = r * wm
    hpos += 1
    if hpos == K:
        hpos = 0
    s[_HPOS] = hpos
    s[_NSTEP] += 1.0
    out[0] = s[_VX]
    out[1] = s[_VY]
    out[2] = s[_GX]
    out[3] = s[_GY]
    out[4] = dgx
    out[5] = dgy
    out[6] = 1.0 if slip else 0.0
    out[7] = 1.0 if turn else 0.0
    out[8] = wz
    out[9] = wz_dot
    out[10] = ax
    out[11] = ay
    out[12] = wm
    out[13] = wm_dot
    out[14] = np.sqrt(varx)
    out[15] = np.sqrt(vary)
    out[16] = np.sqrt(sig2_gz)
    out[17] = np.sqrt(sig2_ax)
    out[18] = np.sqrt(sig2_ay)
    out[19] = np.sqrt(sig2_wm)


@njit(cache=True)
def _run(b0, b1, p, buf, hist, s, Z, outs):
    for i in range(Z.shape[0]):
        _core(b0, b1, p, buf, hist, s, Z[i], outs[i])
