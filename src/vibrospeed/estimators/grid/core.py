"""The compiled core of the grid tracker: one filter iteration (:func:`_step`, steps 1-5 of
:mod:`vibrospeed.estimators.grid.filter`) and the loop over a signal (:func:`_run`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

# numba's cache keys this file's compiled functions on this file alone: _summary and the row
# layout (N_OUT_FIXED: 14 columns, the within-mode spread the last) are compiled in, so a
# change of summary.py's columns must come with a change here (stale caches are then rebuilt)
from vibrospeed.estimators.grid.summary import COL_LOGLIK, N_OUT_FIXED, _summary

LOG_2PI = float(np.log(2.0 * np.pi))


class Tables(NamedTuple):
    """The tracker's constants for the compiled core, built once per config
    (:func:`vibrospeed.estimators.grid.filter.tables`).

    r : measurement noise variance; cs (N, M, 2): ``(cos, sin)(m omega_i T)`` per grid point;
    qd : ``T var(v^a,b)``, the phasors' process noise per step; kb (N, 2B+1), B: the banded
    kernel (:class:`vibrospeed.estimators.grid.kernel.Kernel`); grid, edges (N + 1,); u (N,)
    cell widths normalised to sum 1 (where a jump lands); log_floor : nats; q_lo, q_hi : band
    quantiles; eps, p_off, p_on : per-step jump, "line -> none", "none -> line" probabilities;
    null_var : the "no line" state's white-noise variance; p0 : ``var(alpha_0)``; amb_rel,
    amb_abs : mode / ambiguity window; temper : power on the predictive likelihood; null_mix :
    "no line" emission is the signal part's predictive mixture; hold : mode hysteresis.
    """

    r: float
    cs: np.ndarray
    qd: float
    kb: np.ndarray
    B: int
    grid: np.ndarray
    edges: np.ndarray
    u: np.ndarray
    log_floor: float
    q_lo: float
    q_hi: float
    eps: float
    p_off: float
    p_on: float
    null_var: float
    p0: float
    amb_rel: float
    amb_abs: float
    temper: float
    null_mix: bool
    hold: float



@njit(cache=True)
def _step(tb, lw, lw0, mean, cov, cur, y, ex, w, v, X, acc, out, post, gll):
    """One iteration with the constants ``tb`` (:class:`Tables`) in place on the state (lw,
    lw0[0], mean, cov, cur[0] the mode window); ``w``, ``v`` (N,), ``X`` (N, L), ``acc`` (L,)
    are work space (L = 2M + M(2M + 1)). See :func:`_iterate`."""
    _iterate(lw, lw0, mean, cov, y, tb.r, tb.cs, tb.qd, tb.kb, tb.B, tb.grid, tb.edges, tb.u,
             tb.log_floor, tb.q_lo, tb.q_hi, tb.eps, tb.p_off, tb.p_on, tb.null_var, tb.p0,
             tb.amb_rel, tb.amb_abs, tb.temper, tb.null_mix, tb.hold, cur, ex, w, v, X, acc, out,
             post, gll)


#: positions in :func:`pack_scalars`'s array (``_step_from``'s ``sc``)
_SC_FIELDS = ("r", "qd", "B", "log_floor", "q_lo", "q_hi", "eps", "p_off", "p_on", "null_var",
              "p0", "amb_rel", "amb_abs", "temper", "null_mix", "hold")


def pack_scalars(tb: Tables) -> np.ndarray:
    """The scalar fields of ``tb`` in one float64 array (:data:`_SC_FIELDS` order; ``B`` and
    ``null_mix`` as exact small numbers): a compiled call per sample then unpacks six arrays
    instead of a record of 21 fields."""
    return np.array([float(getattr(tb, f)) for f in _SC_FIELDS], dtype=np.float64)


@njit(cache=True)
def _step_from(sc, cs, kb, grid, edges, u, lw_in, mean_in, cov_in, lw0_in, cur_in, y, ex, lw,
               mean, cov, out, post):
    """One iteration from a state that is left as it is: (``lw_in``, ``mean_in``, ``cov_in``,
    ``lw0_in``, ``cur_in``) is copied into the next state's storage ``lw`` (N,), ``mean``
    (N, 2M), ``cov`` (N, 2M, 2M) and iterated there (:func:`_iterate`, the constants of
    :class:`Tables` from ``sc`` (:func:`pack_scalars`) and the arrays); writes ``out`` and
    ``post`` (N,) and returns the next state's ``(log_w_null, mode_j)``."""
    N = grid.size
    n = mean.shape[1]
    if (lw_in.shape[0] != N or mean_in.shape[0] != N or mean_in.shape[1] != n
            or cov_in.shape[0] != N or cov_in.shape[1] != n or cov_in.shape[2] != n
            or lw.shape[0] != N or mean.shape[0] != N or cov.shape[0] != N
            or cov.shape[1] != n or cov.shape[2] != n):
        raise ValueError("grid state: log_w, mean, cov do not match the config's grid and "
                         "model (N, 2M)")
    for j in range(N):
        lw[j] = lw_in[j]
        for a in range(n):
            mean[j, a] = mean_in[j, a]
            for b in range(n):
                cov[j, a, b] = cov_in[j, a, b]
    lw0 = np.empty(1)
    lw0[0] = lw0_in
    cur = np.empty(1, dtype=np.int64)
    cur[0] = cur_in
    L = n + n * (n + 1) // 2
    _iterate(lw, lw0, mean, cov, y, sc[0], cs, sc[1], kb, int(sc[2]), grid, edges, u, sc[3],
             sc[4], sc[5], sc[6], sc[7], sc[8], sc[9], sc[10], sc[11], sc[12], sc[13],
             sc[14] != 0.0, sc[15], cur, ex, np.empty(N), np.empty(N), np.empty((N, L)),
             np.empty(L), out, post, np.empty(0))
    return lw0[0], cur[0]


@njit(cache=True)
def _iterate(lw, lw0, mean, cov, y, r, cs, qd, kb, B, grid, edges, u, log_floor, q_lo, q_hi,
             eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold, cur, ex,
             w, v, X, acc, out, post, gll):
    """One iteration in place on (lw, lw0[0], mean, cov); the constants are the fields of
    :class:`Tables` (passed one by one: the loop of :func:`_run` calls this per sample, and
    numba passes scalars and array structs here without packing a record per call). Writes
    ``out``, ``post`` (N,) and ``gll`` (N + 1,) per-point log-emissions (if sized):
    ``temper`` times the predictive log-likelihood plus ``ex`` (N + 1,) extra log-evidence
    for this sample (if sized; last entry for the "no line" state). ``null_mix``: the "no
    line" state's time-domain emission is the signal part's predictive mixture
    (Config.null_model "mixture") instead of N(0, null_var).

    Specialised to the harmonic model: ``h = [1, 0, 1, 0, ...]`` (rank-1 update with
    ``P h' = sum of the even columns``), ``F`` block diagonal with rotations ``cs[i, m] =
    (cos, sin)(m omega_i T)`` precomputed per grid point, ``Q = qd I``.
    """
    N = grid.size
    n = mean.shape[1]
    M = n // 2
    has_null = p_off > 0.0
    finite = np.isfinite(y)
    ph = acc[:n]
    # ---- 1. measurement update per grid point: log w_j += log N(y; h m_j, S_j) ----------
    if finite:
        for j in range(N):
            mj = mean[j]
            Pj = cov[j]
            yhat = 0.0
            for a in range(M):
                yhat += mj[2 * a]
            for i in range(n):
                s_ = 0.0
                for a in range(M):
                    s_ += Pj[i, 2 * a]
                ph[i] = s_
            S = r
            for a in range(M):
                S += ph[2 * a]
            nu = y - yhat
            inv = 1.0 / S
            g = nu * inv
            for i in range(n):
                mj[i] += ph[i] * g
            for i in range(n):
                pi = ph[i] * inv
                for k in range(i, n):
                    val = Pj[i, k] - pi * ph[k]
                    Pj[i, k] = val
                    Pj[k, i] = val
            ll = -0.5 * (LOG_2PI + np.log(S) + nu * nu * inv) * temper
            if null_mix:
                v[j] = lw[j]  # prior log-weight
                w[j] = lw[j] + ll  # prior times (tempered) predictive
            if ex.size > 0:
                ll += ex[j]
            lw[j] += ll
            if gll.size > 0:
                gll[j] = ll
        if has_null:
            if null_mix:
                # log sum_j p_j l_j - log sum_j p_j (signal part's predictive mixture)
                ma = -np.inf
                mb = -np.inf
                for j in range(N):
                    if w[j] > ma:
                        ma = w[j]
                    if v[j] > mb:
                        mb = v[j]
                sa = 0.0
                sb = 0.0
                for j in range(N):
                    sa += np.exp(w[j] - ma)
                    sb += np.exp(v[j] - mb)
                ll0 = ma + np.log(sa) - mb - np.log(sb)
            else:
                ll0 = -0.5 * (LOG_2PI + np.log(null_var) + y * y / null_var) * temper
            if ex.size > 0:
                ll0 += ex[N]
            lw0[0] += ll0
            if gll.size > 0:
                gll[N] = ll0
    else:
        if ex.size > 0:
            for j in range(N):
                lw[j] += ex[j]
            if has_null:
                lw0[0] += ex[N]
        if gll.size > 0:
            for j in range(N + 1):
                gll[j] = ex[j] if ex.size > 0 else 0.0
    mx = lw0[0] if has_null else -np.inf
    for j in range(N):
        if lw[j] > mx:
            mx = lw[j]
    # floor at log_floor nats below the best state, then normalise (one exp per point)
    s = 0.0
    for j in range(N):
        d = lw[j] - mx
        if d < -log_floor:
            d = -log_floor
        w[j] = np.exp(d)
        s += w[j]
    w0 = 0.0
    if has_null:
        d = lw0[0] - mx
        if d < -log_floor:
            d = -log_floor
        w0 = np.exp(d)
        s += w0
    pred_ll = mx + np.log(s)
    inv_s = 1.0 / s
    for j in range(N):
        w[j] *= inv_s
    w0 *= inv_s
    # ---- 2. outputs ---------------------------------------------------------------------
    jmap = _summary(w, w0, u, grid, edges, q_lo, q_hi, amb_rel, amb_abs, v, out, hold, cur)
    out[COL_LOGLIK] = pred_ll if finite else 0.0
    for a in range(M):
        al = mean[jmap, 2 * a]
        be = mean[jmap, 2 * a + 1]
        out[N_OUT_FIXED + a] = np.sqrt(al * al + be * be)
    if post.size == N:
        for j in range(N):
            post[j] = w[j]
    # ---- 3. linear time update per source point i (in place: m = F m, P = F P F' + Q),
    #         packed into X[i] = [m_i-, upper(P_i- + m_i- m_i-')] -------------------------
    for i in range(N):
        m = mean[i]
        P = cov[i]
        for a in range(M):
            c = cs[i, a, 0]
            sn = cs[i, a, 1]
            x0 = m[2 * a]
            x1 = m[2 * a + 1]
            m[2 * a] = c * x0 + sn * x1
            m[2 * a + 1] = -sn * x0 + c * x1
        for a in range(M):
            a0 = 2 * a
            ca = cs[i, a, 0]
            sa = cs[i, a, 1]
            for b in range(a, M):
                c0 = 2 * b
                cb = cs[i, b, 0]
                sb = cs[i, b, 1]
                p00 = P[a0, c0]
                p01 = P[a0, c0 + 1]
                p10 = P[a0 + 1, c0]
                p11 = P[a0 + 1, c0 + 1]
                # R_a P_ab, R = [[c, s], [-s, c]]
                t00 = ca * p00 + sa * p10
                t01 = ca * p01 + sa * p11
                t10 = -sa * p00 + ca * p10
                t11 = -sa * p01 + ca * p11
                # (R_a P_ab) R_b'
                r00 = t00 * cb + t01 * sb
                r01 = -t00 * sb + t01 * cb
                r10 = t10 * cb + t11 * sb
                r11 = -t10 * sb + t11 * cb
                if b == a:
                    r01 = 0.5 * (r01 + r10)
                    r10 = r01
                    r00 += qd
                    r11 += qd
                P[a0, c0] = r00
                P[a0, c0 + 1] = r01
                P[a0 + 1, c0] = r10
                P[a0 + 1, c0 + 1] = r11
        Xi = X[i]
        c = n
        for a in range(n):
            ma = m[a]
            Xi[a] = ma
            for b in range(a, n):
                Xi[c] = P[a, b] + ma * m[b]
                c += 1
    # ---- 4.-5. transition (random walk, jumps, null) and moment-matching merge ----------
    L = X.shape[1]
    rw = 1.0 - eps - p_off
    J = eps * (1.0 - w0) + p_on * w0  # mass redistributed uniformly with the prior
    for j in range(N):
        lo = max(0, j - B)
        hi = min(N - 1, j + B)
        for c in range(L):
            acc[c] = 0.0
        W = 0.0
        for i in range(lo, hi + 1):
            lam = w[i] * kb[j, i - j + B]
            W += lam
            Xi = X[i]
            for c in range(L):
                acc[c] += lam * Xi[c]
        if rw != 1.0:
            W *= rw
            for c in range(L):
                acc[c] *= rw
        Ju = J * u[j]
        if Ju > 0.0:
            W += Ju
            # prior: mean 0, second moment p0 I
            c = n
            for a in range(n):
                acc[c] += Ju * p0
                c += n - a
        inv = 1.0 / W
        # m_j = sum lam m_i- / W ;  P_j = sum lam (P_i- + m_i- m_i-') / W - m_j m_j'
        mj = mean[j]
        Pj = cov[j]
        for a in range(n):
            mj[a] = acc[a] * inv
        c = n
        for a in range(n):
            for b in range(a, n):
                val = acc[c] * inv - mj[a] * mj[b]
                Pj[a, b] = val
                Pj[b, a] = val
                c += 1
        lw[j] = np.log(W)
    if has_null:
        lw0[0] = np.log(p_off * (1.0 - w0) + (1.0 - p_on) * w0)


@njit(cache=True)
def _run(tb, lw, lw0, mean, cov, cur, ys, ex_idx, ex_val, want_post, want_gll):
    """:func:`_step` over ``ys`` with the extra evidence rows ``ex_val[f]`` at the samples
    ``ex_idx[f]``; returns the summary rows (n, N_OUT_FIXED + M) and, if wanted, the
    posteriors (n, N) and per-state log-emissions (n, N + 1) as float32."""
    r, cs, qd, kb, B = tb.r, tb.cs, tb.qd, tb.kb, tb.B
    grid, edges, u, log_floor = tb.grid, tb.edges, tb.u, tb.log_floor
    q_lo, q_hi, eps, p_off, p_on = tb.q_lo, tb.q_hi, tb.eps, tb.p_off, tb.p_on
    null_var, p0, amb_rel, amb_abs = tb.null_var, tb.p0, tb.amb_rel, tb.amb_abs
    temper, null_mix, hold = tb.temper, tb.null_mix, tb.hold
    n_s = ys.size
    N = grid.size
    n = mean.shape[1]
    M = n // 2
    outs = np.empty((n_s, N_OUT_FIXED + M))
    posts = np.empty((n_s if want_post else 0, N), dtype=np.float32)
    glls = np.empty((n_s if want_gll else 0, N + 1), dtype=np.float32)
    post = np.empty(N if want_post else 0)
    gll = np.empty(N + 1 if want_gll else 0)
    w = np.empty(N)
    v = np.empty(N)
    L = n + n * (n + 1) // 2
    X = np.empty((N, L))
    acc = np.empty(L)
    no_ex = np.empty(0)
    f = 0
    n_ex = ex_idx.size
    for k in range(n_s):
        while f < n_ex and ex_idx[f] < k:
            f += 1
        ex = ex_val[f] if (f < n_ex and ex_idx[f] == k) else no_ex
        _iterate(lw, lw0, mean, cov, ys[k], r, cs, qd, kb, B, grid, edges, u, log_floor, q_lo,
                 q_hi, eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold,
                 cur, ex, w, v, X, acc, outs[k], post, gll)
        if want_post:
            for j in range(N):
                posts[k, j] = post[j]
        if want_gll:
            for j in range(N + 1):
                glls[k, j] = gll[j]
    return outs, posts, glls
