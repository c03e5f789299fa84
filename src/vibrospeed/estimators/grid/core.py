"""The compiled core of the grid tracker: one filter iteration (:func:`_iterate`, steps 1-5 of
:mod:`vibrospeed.estimators.grid.filter`), the loop over a signal (:func:`_run`) and one step
from a state left as it is (:func:`_step_from`)."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

# numba's cache keys this file's compiled functions on this file alone: _summary and the row
# layout (N_OUT_FIXED: 14 columns, the within-mode spread the last) are compiled in, so a
# change of summary.py must come with a change here and in smoother.py (stale caches are then
# rebuilt; last: the band widened to hold the reported mode)
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



#: positions in :func:`pack_scalars`'s array (in :func:`step_constants`, after its head)
_SC_FIELDS = ("r", "qd", "B", "log_floor", "q_lo", "q_hi", "eps", "p_off", "p_on", "null_var",
              "p0", "amb_rel", "amb_abs", "temper", "null_mix", "hold")


def pack_scalars(tb: Tables) -> np.ndarray:
    """The scalar fields of ``tb`` in one float64 array (:data:`_SC_FIELDS` order; ``B`` and
    ``null_mix`` as exact small numbers): a compiled call per sample then unpacks six arrays
    instead of a record of 21 fields."""
    return np.array([float(getattr(tb, f)) for f in _SC_FIELDS], dtype=np.float64)


# ------------------------------------------------------------------------------------------
# Layout inside the compiled loop: structure of arrays, the grid index innermost, so that the
# elementwise parts of an iteration (measurement update, rotation, packing, merge) are loops
# over j that the compiler turns into SIMD instructions. The state of grid point j is the
# column Z[:, j] of Z (L, N), L = n + n (n + 1) / 2: rows 0..n-1 the mean, rows n..L-1 the
# covariance's upper triangle row by row (P[a, b], b >= a, at row pidx[a, b]). Callers see
# the (N, n) means and (N, n, n) covariances: :func:`_run` converts at entry and exit;
# :func:`_step_from` converts a state of plain arrays at entry and leaves its result in Z
# (the filter's State builds the plain arrays when they are read, :func:`soa_to_state`).
# Every sum is taken in the order of the per-point form, so the numbers are those of the
# per-point loop.
# ------------------------------------------------------------------------------------------


@njit(cache=True)
def _layout(n):
    """(n, n) row of Z holding the covariance entry P[a, b] (either order)."""
    pidx = np.empty((n, n), dtype=np.int64)
    c = n
    for a in range(n):
        for b in range(a, n):
            pidx[a, b] = c
            pidx[b, a] = c
            c += 1
    return pidx


@njit(cache=True)
def _to_soa(mean, cov, Z):
    """Z (L, N) from the means (N, n) and the covariances' upper triangles (N, n, n) (a state's
    covariances are symmetric: every update writes both triangles, and the lower one is not
    read)."""
    N, n = mean.shape
    for a in range(n):
        for j in range(N):
            Z[a, j] = mean[j, a]
    c = n
    for a in range(n):
        for b in range(a, n):
            for j in range(N):
                Z[c, j] = cov[j, a, b]
            c += 1


@njit(cache=True)
def _from_soa(Z, mean, cov):
    """The means (N, n) and symmetric covariances (N, n, n) held in Z (L, N)."""
    N, n = mean.shape
    for a in range(n):
        zr = Z[a]
        for j in range(N):
            mean[j, a] = zr[j]
    c = n
    for a in range(n):
        for b in range(a, n):
            zr = Z[c]
            for j in range(N):
                cov[j, a, b] = zr[j]
            if b != a:
                for j in range(N):
                    cov[j, b, a] = zr[j]
            c += 1


@njit(cache=True)
def _tables_soa(cs, kb):
    """(cos, sin)(m omega_j T) as (M, N) each, and the band kernel by offset kbT (2B+1, N):
    ``kbT[e, j] = kb[j, e]``."""
    N, M = cs.shape[0], cs.shape[1]
    ct = np.empty((M, N))
    st = np.empty((M, N))
    for a in range(M):
        for j in range(N):
            ct[a, j] = cs[j, a, 0]
            st[a, j] = cs[j, a, 1]
    E = kb.shape[1]
    kbT = np.empty((E, N))
    for e in range(E):
        for j in range(N):
            kbT[e, j] = kb[j, e]
    return ct, st, kbT


@njit(cache=True, inline="always")
def _innovation(Z, pidx, M, y, r, ph, rows):
    """The measurement update's terms for every grid point of the state ``Z``: ``P h'`` into
    ``ph``, the predicted ``h m`` then the innovation ``nu`` into ``rows[1]``, ``S = h P h' +
    r`` into ``rows[2]``, the gain factor ``nu / S`` into ``rows[3]`` and ``1 / S`` into
    ``rows[4]`` (inlined into :func:`_update` and :func:`_update_from`)."""
    n = 2 * M
    N = Z.shape[1]
    yh = rows[1]
    S = rows[2]
    g = rows[3]
    iv = rows[4]
    for j in range(N):
        yh[j] = 0.0
    for a in range(M):
        zr = Z[2 * a]
        for j in range(N):
            yh[j] += zr[j]
    for i in range(n):
        pr = ph[i]
        for j in range(N):
            pr[j] = 0.0
        for a in range(M):
            zr = Z[pidx[i, 2 * a]]
            for j in range(N):
                pr[j] += zr[j]
    for j in range(N):
        S[j] = r
    for a in range(M):
        pr = ph[2 * a]
        for j in range(N):
            S[j] += pr[j]
    for j in range(N):
        iv[j] = 1.0 / S[j]
        yh[j] = y - yh[j]  # the innovation nu
        g[j] = yh[j] * iv[j]


@njit(cache=True)
def _update(Z, pidx, M, y, r, temper, ph, rows):
    """Step 1 for every grid point: the Kalman measurement update of (m_j, P_j) with
    ``h = [1, 0, 1, 0, ...]`` (``P h' = sum of the even columns``) in place on Z; the tempered
    predictive log-likelihood ``temper log N(y; h m_j, S_j)`` into ``rows[0]``."""
    n = 2 * M
    N = Z.shape[1]
    yh = rows[1]
    S = rows[2]
    g = rows[3]
    iv = rows[4]
    t = rows[5]
    ll = rows[0]
    _innovation(Z, pidx, M, y, r, ph, rows)
    for i in range(n):
        zr = Z[i]
        pr = ph[i]
        for j in range(N):
            zr[j] += pr[j] * g[j]
    for i in range(n):
        pr = ph[i]
        for j in range(N):
            t[j] = pr[j] * iv[j]
        for k in range(i, n):
            zr = Z[pidx[i, k]]
            pk = ph[k]
            for j in range(N):
                zr[j] = zr[j] - t[j] * pk[j]
    for j in range(N):
        nu = yh[j]
        ll[j] = -0.5 * (LOG_2PI + np.log(S[j]) + nu * nu * iv[j]) * temper


@njit(cache=True)
def _update_from(Zi, Z, pidx, M, y, r, temper, ph, rows):
    """:func:`_update` of the state ``Zi`` written to ``Z`` (every row of Z is written once,
    from the same row of Zi and terms read before any write; the same operations, so the same
    numbers): a step from a state left as it is needs no copy of it first. ``Zi`` must not
    be ``Z`` (in place, :func:`_update`: the compiled loops' overlap check would then take
    their scalar form)."""
    n = 2 * M
    N = Zi.shape[1]
    yh = rows[1]
    S = rows[2]
    g = rows[3]
    iv = rows[4]
    t = rows[5]
    ll = rows[0]
    _innovation(Zi, pidx, M, y, r, ph, rows)
    for i in range(n):
        zi = Zi[i]
        zr = Z[i]
        pr = ph[i]
        for j in range(N):
            zr[j] = zi[j] + pr[j] * g[j]
    for i in range(n):
        pr = ph[i]
        for j in range(N):
            t[j] = pr[j] * iv[j]
        for k in range(i, n):
            zi = Zi[pidx[i, k]]
            zr = Z[pidx[i, k]]
            pk = ph[k]
            for j in range(N):
                zr[j] = zi[j] - t[j] * pk[j]
    for j in range(N):
        nu = yh[j]
        ll[j] = -0.5 * (LOG_2PI + np.log(S[j]) + nu * nu * iv[j]) * temper


@njit(cache=True)
def _time_update(Z, X, ct, st, qd, M, B):
    """Step 3 for every source point: m = F m, P = F P F' + Q in place on Z (F block diagonal
    with the rotations ``[[c, s], [-s, c]]`` of ``(c, s) = (cos, sin)(m omega_j T)``,
    Q = qd I), packed into X: ``X[:, j] = [m_j, upper(P_j + m_j m_j')]`` (Z's row order)."""
    n = 2 * M
    N = Z.shape[1]
    for a in range(M):
        c = ct[a]
        sn = st[a]
        z0 = Z[2 * a]
        z1 = Z[2 * a + 1]
        for j in range(N):
            x0 = z0[j]
            x1 = z1[j]
            z0[j] = c[j] * x0 + sn[j] * x1
            z1[j] = -sn[j] * x0 + c[j] * x1
    # the 2 x 2 block (a, b) of P, b >= a: R_a P_ab R_b'; its rows in Z
    c = n
    for a in range(M):
        ca = ct[a]
        sa = st[a]
        # row of P[2a, 2b] is c; P[2a, 2b+1] c + 1; P[2a+1, 2b] and P[2a+1, 2b+1] follow in
        # row 2a + 1 of the upper triangle
        row0 = c  # start of P's row 2a at column 2a
        row1 = c + (n - 2 * a)  # start of P's row 2a + 1 at column 2a + 1
        for b in range(a, M):
            cb = ct[b]
            sb = st[b]
            o = 2 * (b - a)
            i00 = row0 + o
            i01 = row0 + o + 1
            if b == a:
                i10 = i01
                i11 = row1
            else:
                i10 = row1 + o - 1
                i11 = row1 + o
            q00 = Z[i00]
            q01 = Z[i01]
            q10 = Z[i10]
            q11 = Z[i11]
            if b == a:
                for j in range(N):
                    p00 = q00[j]
                    p01 = q01[j]
                    p10 = q10[j]
                    p11 = q11[j]
                    t00 = ca[j] * p00 + sa[j] * p10
                    t01 = ca[j] * p01 + sa[j] * p11
                    t10 = -sa[j] * p00 + ca[j] * p10
                    t11 = -sa[j] * p01 + ca[j] * p11
                    r00 = t00 * cb[j] + t01 * sb[j]
                    r01 = -t00 * sb[j] + t01 * cb[j]
                    r10 = t10 * cb[j] + t11 * sb[j]
                    r11 = -t10 * sb[j] + t11 * cb[j]
                    q00[j] = r00 + qd
                    q01[j] = 0.5 * (r01 + r10)
                    q11[j] = r11 + qd
            else:
                for j in range(N):
                    p00 = q00[j]
                    p01 = q01[j]
                    p10 = q10[j]
                    p11 = q11[j]
                    t00 = ca[j] * p00 + sa[j] * p10
                    t01 = ca[j] * p01 + sa[j] * p11
                    t10 = -sa[j] * p00 + ca[j] * p10
                    t11 = -sa[j] * p01 + ca[j] * p11
                    q00[j] = t00 * cb[j] + t01 * sb[j]
                    q01[j] = -t00 * sb[j] + t01 * cb[j]
                    q10[j] = t10 * cb[j] + t11 * sb[j]
                    q11[j] = -t10 * sb[j] + t11 * cb[j]
        c += (n - 2 * a) + (n - 2 * a - 1)
    for a in range(n):
        zr = Z[a]
        xr = X[a, B:B + N]
        for j in range(N):
            xr[j] = zr[j]
    c = n
    for a in range(n):
        ma = Z[a]
        for b in range(a, n):
            mb = Z[b]
            zr = Z[c]
            xr = X[c, B:B + N]
            for j in range(N):
                xr[j] = zr[j] + ma[j] * mb[j]
            c += 1


@njit(cache=True)
def _merge(Z, X, w, kbT, B, rw, J, u, p0, n, lw, lamT, W, iv, Jp):
    """Steps 4-5 for every target point j: the banded transition's weights
    ``lam_ij = w_i kb[j, i - j + B]`` (i = j + d, d = -B..B), the moments
    ``sum_i lam_ij X[:, i]`` (summed in the order of i), the random-walk share ``rw``, the
    uniform jump mass ``J u_j`` with the prior's moments (mean 0, second moment p0 I), and the
    moment-matched Gaussian written to Z; ``lw[j] = log W_j``. ``W``, ``iv``, ``Jp`` (N,):
    work space."""
    N = Z.shape[1]
    E = 2 * B + 1
    # lamT[e, j] = lam_(j+e-B),j, zero where j + e - B is off the grid: every offset then
    # runs over all j against X's zero padding (adding 0 is exact)
    for e in range(E):
        d = e - B
        lo = max(0, -d)
        hi = min(N, N - d)
        lr = lamT[e]
        for j in range(lo):
            lr[j] = 0.0
        for j in range(hi, N):
            lr[j] = 0.0
        k_ = kbT[e, lo:hi]
        l_ = lamT[e, lo:hi]
        w_ = w[lo + d:hi + d]
        for k in range(hi - lo):
            l_[k] = w_[k] * k_[k]
    # W_j = rw sum_i lam_ij + J u_j, the jump mass only where it is positive (adding 0 is
    # exact, so every point takes the same branch-free loop)
    for j in range(N):
        W[j] = 0.0
    for e in range(E):
        lr = lamT[e]
        for j in range(N):
            W[j] += lr[j]
    for j in range(N):
        x = J * u[j]
        Jp[j] = x * p0 if x > 0.0 else 0.0
        W[j] = W[j] * rw + (x if x > 0.0 else 0.0)
        iv[j] = 1.0 / W[j]
    # each moment summed over the band (:func:`_band_sum`), times rw (exact where rw = 1),
    # the jumped mass's prior second moment added on the diagonal, divided by W: the means
    # first, then the covariances P = E[x x'] - m m', each row while it is in the cache
    for a in range(n):
        zr = Z[a]
        _band_sum(zr, X[a], lamT, N)
        for j in range(N):
            zr[j] = zr[j] * rw * iv[j]
    c = n
    for a in range(n):
        ma = Z[a]
        for b in range(a, n):
            mb = Z[b]
            zr = Z[c]
            _band_sum(zr, X[c], lamT, N)
            if b == a:
                for j in range(N):
                    zr[j] = (zr[j] * rw + Jp[j]) * iv[j] - ma[j] * mb[j]
            else:
                for j in range(N):
                    zr[j] = zr[j] * rw * iv[j] - ma[j] * mb[j]
            c += 1
    for j in range(N):
        lw[j] = np.log(W[j])


@njit(cache=True, inline="always")
def _band_sum(ar, xr, lamT, N):
    """``ar[j] = sum_e lamT[e, j] xr[j + e]`` (xr zero-padded by B either side), summed in the
    order of e, four offsets per pass."""
    E = lamT.shape[0]
    e = 0
    for j in range(N):
        ar[j] = 0.0
    while e + 4 <= E:
        l0 = lamT[e]
        l1 = lamT[e + 1]
        l2 = lamT[e + 2]
        l3 = lamT[e + 3]
        x0 = xr[e:e + N]
        x1 = xr[e + 1:e + 1 + N]
        x2 = xr[e + 2:e + 2 + N]
        x3 = xr[e + 3:e + 3 + N]
        for j in range(N):
            ar[j] = ar[j] + l0[j] * x0[j] + l1[j] * x1[j] + l2[j] * x2[j] + l3[j] * x3[j]
        e += 4
    while e < E:
        l0 = lamT[e]
        x0 = xr[e:e + N]
        for j in range(N):
            ar[j] = ar[j] + l0[j] * x0[j]
        e += 1


@njit(cache=True)
def _work(N, n, B):
    """Work space of :func:`_iterate`: w, v (N,), X (L, N + 2B) (the packed moments, point
    i at column i + B, B zero columns either side), ph (n, N), rows (6, N), lamT (2B+1, N)."""
    L = n + n * (n + 1) // 2
    return (np.empty(N), np.empty(N), np.zeros((L, N + 2 * B)), np.empty((n, N)),
            np.empty((6, N)), np.empty((2 * B + 1, N)))


@njit(cache=True)
def _iterate(lw, lw0, Zi, Z, y, r, ct, st, qd, kbT, B, pidx, grid, edges, u, log_floor, q_lo,
             q_hi, eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold,
             cur, ex, w, v, X, ph, rows, lamT, out, post, gll):
    """One iteration in place on (lw, lw0[0], Z (the means and covariances, :func:`_layout`));
    with a finite ``y`` and ``Zi`` sized, the means and covariances are read from ``Zi``
    (:func:`_update_from`), else Z holds them;
    the constants are the fields of :class:`Tables` (passed one by one: the loop of
    :func:`_run` calls this per sample, and numba passes scalars and array structs here
    without packing a record per call), the rotations as ``ct``, ``st`` (M, N) and the band
    kernel by offset ``kbT`` (2B+1, N) (:func:`_tables_soa`). Writes ``out``, ``post`` (N,)
    and ``gll`` (N + 1,) per-point log-emissions (if sized): ``temper`` times the predictive
    log-likelihood plus ``ex`` (N + 1,) extra log-evidence for this sample (if sized; last
    entry for the "no line" state). ``null_mix``: the "no line" state's time-domain emission
    is the signal part's predictive mixture (Config.null_model "mixture") instead of
    N(0, null_var). ``w``, ``v``, ``X``, ``ph``, ``rows``, ``lamT``: work space
    (:func:`_work`).

    Specialised to the harmonic model: ``h = [1, 0, 1, 0, ...]`` (rank-1 update with
    ``P h' = sum of the even columns``), ``F`` block diagonal with rotations ``(cos, sin)(m
    omega_i T)`` precomputed per grid point, ``Q = qd I``.
    """
    N = grid.size
    M = ct.shape[0]
    n = 2 * M
    has_null = p_off > 0.0
    finite = np.isfinite(y)
    # the signal part's mixture exponentials exp(lw_j + ll_j - max), kept (rows[4]) for the
    # normalisation below, which takes the same exponentials when no extra evidence came and
    # the best state is a grid point (the same arguments, so the same values)
    ea = rows[4]
    reuse = False
    ma = -np.inf
    # ---- 1. measurement update per grid point: log w_j += log N(y; h m_j, S_j) ----------
    if finite:
        if Zi.shape[0] > 0:
            _update_from(Zi, Z, pidx, M, y, r, temper, ph, rows)
        else:
            _update(Z, pidx, M, y, r, temper, ph, rows)
        lls = rows[0]
        for j in range(N):
            ll = lls[j]
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
                    ea[j] = np.exp(w[j] - ma)
                    sa += ea[j]
                    sb += np.exp(v[j] - mb)
                ll0 = ma + np.log(sa) - mb - np.log(sb)
                reuse = ex.size == 0
            else:
                ll0 = -0.5 * (LOG_2PI + np.log(null_var) + y * y / null_var) * temper
            if ex.size > 0:
                ll0 += ex[N]
            lw0[0] += ll0
            if gll.size > 0:
                gll[N] = ll0
        elif gll.size > 0:
            gll[N] = ex[N] if ex.size > 0 else 0.0  # as for a NaN sample
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
    # floor at log_floor nats below the best state, then normalise (one exp per point; with
    # no extra evidence lw_j = w_j of the mixture above, so where its maximum ma is mx the
    # exponential exp(lw_j - mx) is ea_j)
    s = 0.0
    if reuse and mx == ma:
        e_floor = np.exp(-log_floor)
        for j in range(N):
            w[j] = e_floor if lw[j] - mx < -log_floor else ea[j]
            s += w[j]
    else:
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
        al = Z[2 * a, jmap]
        be = Z[2 * a + 1, jmap]
        out[N_OUT_FIXED + a] = np.sqrt(al * al + be * be)
    if post.size == N:
        for j in range(N):
            post[j] = w[j]
    # ---- 3. linear time update per source point (m = F m, P = F P F' + Q), packed into
    #         X[:, i] = [m_i-, upper(P_i- + m_i- m_i-')] ---------------------------------
    _time_update(Z, X, ct, st, qd, M, B)
    # ---- 4.-5. transition (random walk, jumps, null) and moment-matching merge ----------
    rw = 1.0 - eps - p_off
    J = eps * (1.0 - w0) + p_on * w0  # mass redistributed uniformly with the prior
    _merge(Z, X, w, kbT, B, rw, J, u, p0, n, lw, lamT, rows[1], rows[2], rows[3])
    if has_null:
        lw0[0] = np.log(p_off * (1.0 - w0) + (1.0 - p_on) * w0)


def step_table(cs: np.ndarray, kb: np.ndarray) -> np.ndarray:
    """The rotations and the band kernel in the loop's layout, stacked as one (2M + 2B + 1, N)
    array: rows 0..M-1 ``cos(m omega_j T)``, M..2M-1 the sines, then ``kbT``
    (:func:`_tables_soa`); built once per config, so that a step transposes nothing."""
    ct, st, kbT = _tables_soa(cs, kb)
    return np.ascontiguousarray(np.concatenate([ct, st, kbT]))


#: entries of :func:`step_constants`' array before the scalars: N, M
_CST_HEAD = 2


def step_constants(tb: Tables) -> np.ndarray:
    """Everything :func:`_step_from` reads of the config, packed once as one float64 array
    (one argument to unbox per call instead of five): ``N``, ``M``, the scalars
    (:func:`pack_scalars`), ``grid`` (N,), ``edges`` (N + 1,), ``u`` (N,) and the rotations
    and band kernel in the loop's layout (:func:`step_table`, flattened). Sizes and flags are
    small integers, exact in float64."""
    N = tb.grid.size
    M = tb.cs.shape[1]
    return np.concatenate([[float(N), float(M)], pack_scalars(tb), tb.grid, tb.edges, tb.u,
                           step_table(tb.cs, tb.kb).ravel()]).astype(np.float64)


def step_work(tb: Tables) -> np.ndarray:
    """The work space of :func:`_step_from` for ``tb``'s sizes as one float64 array, zeros
    (the moments' padding columns must stay 0; nothing writes them): kept with the config and
    reused by every step, which needs no state from it. :func:`_step_from` runs holding the
    GIL (no ``nogil``), so two threads never use it at once."""
    N = tb.grid.size
    n = 2 * tb.cs.shape[1]
    B = int(tb.B)
    L = n + n * (n + 1) // 2
    return np.zeros(2 * N + L * (N + 2 * B) + n * N + 6 * N + (2 * B + 1) * N)


@njit(cache=True)
def soa_to_state(Z, mean, cov):
    """The means (N, n) and symmetric covariances (N, n, n) of a state held in the loop's
    layout Z (L, N) (:func:`_from_soa`, for a :class:`~vibrospeed.estimators.grid.filter.State`
    read after :func:`_step_from`)."""
    _from_soa(Z, mean, cov)


@njit(cache=True)
def _step_from(cst, ws, lw_in, z_in, mean_in, cov_in, lw0_in, cur_in, y, ex, lw, Z, out, post,
               gll):
    """One iteration from a state that is left as it is: (``lw_in``, the means and covariances,
    ``lw0_in``, ``cur_in``) is iterated into the next state's storage ``lw`` (N,) and ``Z``
    (L, N) (the loop's layout, :func:`_layout`; a finite sample's measurement update reads
    ``z_in`` and writes Z, else it is copied first) (:func:`_iterate`, the
    constants of :class:`Tables` from ``cst`` (:func:`step_constants`), its work space in
    ``ws`` (:func:`step_work`)). The means and covariances come from ``z_in`` (L, N) in the
    loop's layout when it is sized (a state this function made, copied as it is), else from
    ``mean_in`` (N, 2M) and ``cov_in`` (N, 2M, 2M) (their upper triangles). Writes ``out``,
    ``post`` (N,) and ``gll`` (N + 1,) the per-state log-emissions (if sized: :func:`_iterate`)
    and returns the next state's ``(log_w_null, mode_j)``."""
    h = _CST_HEAD
    N = int(cst[0])
    M = int(cst[1])
    n = 2 * M
    nsc = len(_SC_FIELDS)
    sc = cst[h : h + nsc]
    B = int(sc[2])
    E = 2 * B + 1
    o = h + nsc
    grid = cst[o : o + N]
    edges = cst[o + N : o + 2 * N + 1]
    u = cst[o + 2 * N + 1 : o + 3 * N + 1]
    o += 3 * N + 1
    tab = cst[o : o + (n + E) * N].reshape((n + E, N))
    L = Z.shape[0]
    if (lw_in.shape[0] != N or lw.shape[0] != N or Z.shape[1] != N
            or L != n + n * (n + 1) // 2 or cur_in < -1 or cur_in >= N):
        raise ValueError("grid state: log_w, mean, cov, mode_j do not match the config's "
                         "grid and model (N, 2M)")
    Zi = np.empty((0, N))  # empty: in place on Z
    if z_in.shape[0] > 0:
        if z_in.shape[0] != L or z_in.shape[1] != N:
            raise ValueError("grid state: log_w, mean, cov do not match the config's grid "
                             "and model (N, 2M)")
        if np.isfinite(y):  # the measurement update reads z_in and writes Z
            Zi = z_in
        else:
            for c in range(L):
                zi = z_in[c]
                zo = Z[c]
                for j in range(N):
                    zo[j] = zi[j]
    else:
        if (mean_in.shape[0] != N or mean_in.shape[1] != n or cov_in.shape[0] != N
                or cov_in.shape[1] != n or cov_in.shape[2] != n):
            raise ValueError("grid state: log_w, mean, cov do not match the config's grid "
                             "and model (N, 2M)")
        _to_soa(mean_in, cov_in, Z)
    for j in range(N):
        lw[j] = lw_in[j]
    # the work space of _work, in its order
    w = ws[:N]
    v = ws[N : 2 * N]
    o = 2 * N
    X = ws[o : o + L * (N + 2 * B)].reshape((L, N + 2 * B))
    o += L * (N + 2 * B)
    ph = ws[o : o + n * N].reshape((n, N))
    o += n * N
    rows = ws[o : o + 6 * N].reshape((6, N))
    o += 6 * N
    lamT = ws[o : o + E * N].reshape((E, N))
    lw0 = np.empty(1)
    lw0[0] = lw0_in
    cur = np.empty(1, dtype=np.int64)
    cur[0] = cur_in
    _iterate(lw, lw0, Zi, Z, y, sc[0], tab[:M], tab[M:n], sc[1], tab[n:], B, _layout(n), grid,
             edges, u, sc[3], sc[4], sc[5], sc[6], sc[7], sc[8], sc[9], sc[10], sc[11], sc[12],
             sc[13], sc[14] != 0.0, sc[15], cur, ex, w, v, X, ph, rows, lamT, out, post, gll)
    return lw0[0], cur[0]


@njit(cache=True)
def _run(tb, lw, lw0, mean, cov, cur, ys, ex_idx, ex_val, post_slot, want_gll):
    """:func:`_iterate` over ``ys`` with the extra evidence rows ``ex_val[f]`` at the samples
    ``ex_idx[f]``, in place on the state (lw, lw0[0], mean (N, 2M), cov (N, 2M, 2M), cur[0]);
    returns the summary rows (n, N_OUT_FIXED + M), the posteriors as float32 rows (sample k's
    in row ``post_slot[k]`` where that is >= 0; ``post_slot`` empty: none) and, if wanted, the
    per-state log-emissions (n, N + 1) as float32."""
    r, qd, B = tb.r, tb.qd, tb.B
    grid, edges, u, log_floor = tb.grid, tb.edges, tb.u, tb.log_floor
    q_lo, q_hi, eps, p_off, p_on = tb.q_lo, tb.q_hi, tb.eps, tb.p_off, tb.p_on
    null_var, p0, amb_rel, amb_abs = tb.null_var, tb.p0, tb.amb_rel, tb.amb_abs
    temper, null_mix, hold = tb.temper, tb.null_mix, tb.hold
    n_s = ys.size
    N = grid.size
    n = mean.shape[1]
    M = n // 2
    outs = np.empty((n_s, N_OUT_FIXED + M))
    want_post = post_slot.size > 0
    n_post = 0
    for k in range(post_slot.size):
        n_post = max(n_post, post_slot[k] + 1)
    posts = np.empty((n_post, N), dtype=np.float32)
    glls = np.empty((n_s if want_gll else 0, N + 1), dtype=np.float32)
    post = np.empty(N if want_post else 0)
    gll = np.empty(N + 1 if want_gll else 0)
    L = n + n * (n + 1) // 2
    Z = np.empty((L, N))
    _to_soa(mean, cov, Z)
    ct, st, kbT = _tables_soa(tb.cs, tb.kb)
    pidx = _layout(n)
    w, v, X, ph, rows, lamT = _work(N, n, B)
    no_ex = np.empty(0)
    no_z = np.empty((0, N))  # Z is updated in place
    f = 0
    n_ex = ex_idx.size
    for k in range(n_s):
        while f < n_ex and ex_idx[f] < k:
            f += 1
        ex = ex_val[f] if (f < n_ex and ex_idx[f] == k) else no_ex
        _iterate(lw, lw0, no_z, Z, ys[k], r, ct, st, qd, kbT, B, pidx, grid, edges, u, log_floor,
                 q_lo, q_hi, eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper,
                 null_mix, hold, cur, ex, w, v, X, ph, rows, lamT, outs[k], post, gll)
        if want_post and post_slot[k] >= 0:
            row = posts[post_slot[k]]
            for j in range(N):
                row[j] = post[j]
        if want_gll:
            for j in range(N + 1):
                glls[k, j] = gll[j]
    _from_soa(Z, mean, cov)
    return outs, posts, glls
