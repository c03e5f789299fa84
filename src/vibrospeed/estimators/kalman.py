"""Kalman predict / update primitives stacked over a leading axis (METHODS.md 1.2-1.3).

One code path serves a single filter (``N = 1``), the RBPF (``N`` particles) and the RBPMF
(``N`` grid points). Shapes: means ``m`` (N, n), covariances ``P`` (N, n, n), ``n = 2M``.

* :func:`predict` / :func:`update` are plain NumPy references for any dense ``F`` and row ``h``.
* :func:`predict_blocks` / :func:`update_scalar` are the compiled in-place kernels used in hot
  loops. ``predict_blocks`` exploits that the harmonic transition ``F(omega)`` of
  :class:`vibrospeed.models.harmonic.HarmonicModel` is block diagonal with 2x2 blocks; the blocks
  are *taken from* ``HarmonicModel.F`` (:func:`blocks_from_F`) or computed by
  :func:`rotation_blocks`, which a test checks against ``HarmonicModel.F`` element by element.

Equations (scalar measurement ``y = h x + e``, ``var(e) = r``)::

    m- = F m,  P- = F P F' + Q                               (time update)
    S = h P- h' + r,  K = P- h' / S,  nu = y - h m-              (innovation)
    m+ = m- + K nu,  P+ = P- - K S K'  (= P- - (P- h')(P- h')' / S, symmetric by construction)
    log p(y) = -0.5 (log(2 pi S) + nu^2 / S)

A NaN ``y`` skips the update (log-likelihood 0): gaps are prediction only.

:func:`joseph_update` is the Joseph-form update ``P+ = (I - K h) P- (I - K h)' + r K K'`` of the
EKFs (:mod:`.ekf`, :mod:`.aided`), for an ``h`` of ones at evenly spaced columns: it stays
positive semi-definite with the gains the aided tracker's gate sets to zero, which the short
form above does not.
"""

from __future__ import annotations

import numpy as np
from numba import njit

LOG_2PI = float(np.log(2.0 * np.pi))


# ------------------------------------------------------------------------------------------
# NumPy references (any F, any h)
# ------------------------------------------------------------------------------------------
def predict(m: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray):
    """Stacked time update ``m- = F m``, ``P- = F P F' + Q``.

    m : (N, n); P : (N, n, n); F : (n, n) shared or (N, n, n) per filter; Q : (n, n).
    Returns new ``(m, P)`` arrays.
    """
    m = np.asarray(m, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    F = np.broadcast_to(np.asarray(F, dtype=np.float64), P.shape)
    mn = np.einsum("kij,kj->ki", F, m)
    Pn = np.einsum("kij,kjl,kml->kim", F, P, F) + Q
    return mn, 0.5 * (Pn + np.swapaxes(Pn, 1, 2))


def update(m: np.ndarray, P: np.ndarray, h: np.ndarray, r: float, y: float):
    """Stacked scalar measurement update; returns ``(m, P, loglik (N,), nu (N,), S (N,))``.

    A NaN ``y`` returns the inputs unchanged and zero log-likelihood.
    """
    m = np.asarray(m, dtype=np.float64)
    P = np.asarray(P, dtype=np.float64)
    N = m.shape[0]
    if not np.isfinite(y):
        nan = np.full(N, np.nan)
        return m.copy(), P.copy(), np.zeros(N), nan, nan
    ph = P @ h  # (N, n)      P h'
    S = ph @ h + r  # (N,)     S = h P h' + r
    nu = y - m @ h  # (N,)     innovation
    K = ph / S[:, None]
    mn = m + K * nu[:, None]
    Pn = P - ph[:, :, None] * ph[:, None, :] / S[:, None, None]
    ll = -0.5 * (LOG_2PI + np.log(S) + nu * nu / S)
    return mn, Pn, ll, nu, S


# ------------------------------------------------------------------------------------------
# compiled kernels (in place)
# ------------------------------------------------------------------------------------------
def blocks_from_F(F: np.ndarray) -> np.ndarray:
    """The 2x2 diagonal blocks of block-diagonal ``F`` (..., 2M, 2M) as (..., M, 2, 2)."""
    F = np.asarray(F, dtype=np.float64)
    M = F.shape[-1] // 2
    out = np.empty(F.shape[:-2] + (M, 2, 2))
    for a in range(M):
        out[..., a, :, :] = F[..., 2 * a : 2 * a + 2, 2 * a : 2 * a + 2]
    return out


@njit(cache=True)
def rotation_blocks(omega, M, T, out):
    """Fill ``out`` (N, M, 2, 2) with ``R(m omega_i T)`` (thesis eq. 2.22), as HarmonicModel.F."""
    for i in range(omega.size):
        for a in range(M):
            psi = (a + 1.0) * omega[i] * T
            c = np.cos(psi)
            s = np.sin(psi)
            out[i, a, 0, 0] = c
            out[i, a, 0, 1] = s
            out[i, a, 1, 0] = -s
            out[i, a, 1, 1] = c


@njit(cache=True)
def predict_one(m, P, B, Q):
    """In place for one filter: ``m = F m``, ``P = F P F' + Q`` with ``F = blockdiag(B)``.

    m : (n,); P : (n, n); B : (M, 2, 2) blocks of F; Q : (n, n).
    """
    M = B.shape[0]
    n = 2 * M
    # m- = F m
    for a in range(M):
        x0 = m[2 * a]
        x1 = m[2 * a + 1]
        m[2 * a] = B[a, 0, 0] * x0 + B[a, 0, 1] * x1
        m[2 * a + 1] = B[a, 1, 0] * x0 + B[a, 1, 1] * x1
    # P- = F P F': block (a, b) -> B_a P_ab B_b'; blocks with a <= b, mirrored
    for a in range(M):
        a0 = 2 * a
        b00 = B[a, 0, 0]
        b01 = B[a, 0, 1]
        b10 = B[a, 1, 0]
        b11 = B[a, 1, 1]
        for b in range(a, M):
            c0 = 2 * b
            # T = B_a P_ab
            p00 = P[a0, c0]
            p01 = P[a0, c0 + 1]
            p10 = P[a0 + 1, c0]
            p11 = P[a0 + 1, c0 + 1]
            t00 = b00 * p00 + b01 * p10
            t01 = b00 * p01 + b01 * p11
            t10 = b10 * p00 + b11 * p10
            t11 = b10 * p01 + b11 * p11
            # T B_b'
            e00 = B[b, 0, 0]
            e01 = B[b, 0, 1]
            e10 = B[b, 1, 0]
            e11 = B[b, 1, 1]
            r00 = t00 * e00 + t01 * e01
            r01 = t00 * e10 + t01 * e11
            r10 = t10 * e00 + t11 * e01
            r11 = t10 * e10 + t11 * e11
            P[a0, c0] = r00
            P[a0, c0 + 1] = r01
            P[a0 + 1, c0] = r10
            P[a0 + 1, c0 + 1] = r11
            if b != a:
                P[c0, a0] = r00
                P[c0 + 1, a0] = r01
                P[c0, a0 + 1] = r10
                P[c0 + 1, a0 + 1] = r11
    for i in range(n):
        for j in range(n):
            P[i, j] += Q[i, j]
    # the diagonal blocks are symmetric up to rounding: enforce exactly
    for a in range(M):
        v = 0.5 * (P[2 * a, 2 * a + 1] + P[2 * a + 1, 2 * a])
        P[2 * a, 2 * a + 1] = v
        P[2 * a + 1, 2 * a] = v


@njit(cache=True)
def predict_blocks(m, P, B, Q):
    """Stacked in-place time update. m (N, n), P (N, n, n), B (N, M, 2, 2) or (1, M, 2, 2)."""
    shared = B.shape[0] == 1
    for k in range(m.shape[0]):
        predict_one(m[k], P[k], B[0] if shared else B[k], Q)


@njit(cache=True)
def update_one(m, P, h, r, y, ph):
    """In place scalar update of one filter; returns ``(loglik, nu, S)``. ``ph`` (n,) scratch.

    NaN ``y``: no change, returns ``(0, nan, nan)``.
    """
    if not np.isfinite(y):
        return 0.0, np.nan, np.nan
    n = m.size
    # ph = P h' ; S = h P h' + r ; nu = y - h m   (zero entries of h skipped)
    S = r
    yhat = 0.0
    for i in range(n):
        ph[i] = 0.0
    for j in range(n):
        hj = h[j]
        if hj != 0.0:
            for i in range(n):
                ph[i] += P[i, j] * hj
            yhat += hj * m[j]
    for i in range(n):
        S += h[i] * ph[i]
    nu = y - yhat
    # m += K nu,  K = ph / S ;  P -= ph ph' / S
    g = nu / S
    for i in range(n):
        m[i] += ph[i] * g
    inv = 1.0 / S
    for i in range(n):
        pi = ph[i] * inv
        for j in range(i, n):
            v = P[i, j] - pi * ph[j]
            P[i, j] = v
            P[j, i] = v
    return -0.5 * (LOG_2PI + np.log(S) + nu * nu / S), nu, S


@njit(cache=True)
def update_scalar(m, P, h, r, y, loglik):
    """Stacked in-place scalar update; per-filter log-likelihood written into ``loglik`` (N,)."""
    ph = np.empty(m.shape[1])
    for k in range(m.shape[0]):
        ll, _, _ = update_one(m[k], P[k], h, r, y, ph)
        loglik[k] = ll


@njit(cache=True)
def joseph_update(x, P, k, innov, r, first, stride, count):
    """In place ``x += k innov`` and ``P = A P A' + r k k'`` (symmetrised), ``A = I - k h``, for
    a scalar measurement whose ``h`` is 1 at the columns ``first + stride c``, ``c < count``, and
    0 elsewhere; ``k`` the gain actually applied (not necessarily ``P h' / S``)."""
    n = x.size
    for i in range(n):
        x[i] += k[i] * innov
    A = np.eye(n)
    for i in range(n):
        for c in range(count):
            A[i, first + stride * c] -= k[i]
    Pn = A @ P @ A.T
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (Pn[i, j] + Pn[j, i]) + r * k[i] * k[j]
            P[i, j] = v
            P[j, i] = v


# ------------------------------------------------------------------------------------------
# small dense filters (gps-riss, fuse): plain loops, no BLAS call per sample
# ------------------------------------------------------------------------------------------
@njit(cache=True)
def matvec(A, v, out):
    """``out = A v`` for a small dense ``A`` (n, m), summed in index order."""
    for i in range(A.shape[0]):
        s = 0.0
        for j in range(A.shape[1]):
            s += A[i, j] * v[j]
        out[i] = s


@njit(cache=True)
def dense_predict(x, P, F, qd):
    """In place ``x = F x``, ``P = F P F' + diag(qd)`` (symmetric by construction) for a
    small dense ``F`` (n, n): loops over n^3 terms instead of numba's BLAS-backed ``@``,
    which for n ~ 6 costs more in call overhead (and in compile time) than in arithmetic."""
    n = x.size
    xn = np.empty(n)
    matvec(F, x, xn)
    FP = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            s = 0.0
            for k in range(n):
                s += F[i, k] * P[k, j]
            FP[i, j] = s
    for i in range(n):
        x[i] = xn[i]
        for j in range(i, n):
            s = 0.0
            for k in range(n):
                s += FP[i, k] * F[j, k]
            if i == j:
                s += qd[i]
            P[i, j] = s
            P[j, i] = s


@njit(cache=True)
def quad_form(h, P):
    """``h P h'`` for a row ``h`` (n,)."""
    n = h.size
    s = 0.0
    for i in range(n):
        if h[i] != 0.0:
            t = 0.0
            for j in range(n):
                t += P[i, j] * h[j]
            s += h[i] * t
    return s


@njit(cache=True)
def innovation(x, P, h, z, r):
    """``(P h', S, nu)`` of the scalar measurement ``z = h x + e``, ``var(e) = r``:
    ``S = h P h' + r`` and ``nu = z - h x`` (P symmetric)."""
    n = x.size
    Ph = np.empty(n)
    matvec(P, h, Ph)
    S = r
    nu = z
    for i in range(n):
        S += h[i] * Ph[i]
        nu -= h[i] * x[i]
    return Ph, S, nu


@njit(cache=True)
def row_update(x, P, h, z, r, keep=-1, keep2=-1, keep3=-1):
    """Scalar update ``z = h x + e``, ``var(e) = r``, in place, Joseph form::

        S = h P h' + r,  k = P h' / S,  x += k (z - h x),
        P = (I - k h) P (I - k h)' + r k k'

    (symmetrised), which keeps P the covariance of the estimate for *any* gain: ``keep``,
    ``keep2``, ``keep3 >= 0`` are "consider" states (Schmidt) whose gain is set to 0, so the
    update leaves their means and variances unchanged. Returns the innovation ``z - h x``."""
    n = x.size
    Ph, S, nu = innovation(x, P, h, z, r)
    k = Ph / S
    if keep >= 0:
        k[keep] = 0.0
    if keep2 >= 0:
        k[keep2] = 0.0
    if keep3 >= 0:
        k[keep3] = 0.0
    for i in range(n):
        x[i] += k[i] * nu
    joseph(P, Ph, k, h, r)
    return nu


@njit(cache=True)
def joseph(C, Ch, k, h, r):
    """``C = (I - k h) C (I - k h)' + r k k'`` in place (symmetrised), ``Ch = C h'`` given: the
    covariance of an estimate updated with the gain ``k`` whatever ``k`` is (the filter's own
    in :func:`row_update`; another filter's for a suboptimal estimate's error)."""
    n = h.size
    # A = I - k h; A C = C - k (h C) with h C = Ch' (C symmetric); then (A C) A' + r k k'
    AC = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            AC[i, j] = C[i, j] - k[i] * Ch[j]
    ACh = np.empty(n)
    matvec(AC, h, ACh)
    for i in range(n):
        for j in range(i, n):
            v = (0.5 * (AC[i, j] - ACh[i] * k[j] + AC[j, i] - ACh[j] * k[i])
                 + r * k[i] * k[j])
            C[i, j] = v
            C[j, i] = v
