"""Translation of the grid posterior along omega, the aiding's acceleration integration on a grid
(thesis eq. 3.10; package docstring): :func:`_shift` moves every point's mass by a (fractional)
number of cells, split linearly between the two neighbours and with the phasor filters arriving
at a point merged by moment matching (METHODS 1.3 step 4), compiled with numba.
:func:`_move` makes whole-cell moves exactly and returns the sub-cell remainder (the state's
``offset``); :func:`_resolve` applies a remainder with one linear split, so the diffusion
``f (1 - f) dx^2`` of a split is paid only where the filter needs the posterior on the grid."""

from __future__ import annotations

import numpy as np
from numba import njit

from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.aided_grid.config import Config


@njit(cache=True)
def _shift(lw, mean, cov, s, p0):
    """Move every grid point's mass by ``s`` cells (float) in place: point ``i`` goes to
    ``i + s``, split linearly between the two neighbouring points, clamped to the grid ends;
    phasor filters merged by moment matching; empty points get the prior N(0, p0 I)."""
    N, n = mean.shape
    mx = -np.inf
    for i in range(N):
        if lw[i] > mx:
            mx = lw[i]
    k = int(np.floor(s))
    f = s - k
    W = np.zeros(N)
    M1 = np.zeros((N, n))
    M2 = np.zeros((N, n, n))
    for i in range(N):
        wi = np.exp(lw[i] - mx)
        if wi == 0.0:
            continue
        for part in range(2):
            a = (1.0 - f) if part == 0 else f
            if a == 0.0:
                continue
            j = i + k + part
            if j < 0:
                j = 0
            elif j > N - 1:
                j = N - 1
            lam = wi * a
            W[j] += lam
            mi = mean[i]
            Pi = cov[i]
            for p in range(n):
                M1[j, p] += lam * mi[p]
                for q in range(n):
                    M2[j, p, q] += lam * (Pi[p, q] + mi[p] * mi[q])
    for j in range(N):
        if W[j] > 0.0:
            inv = 1.0 / W[j]
            for p in range(n):
                mean[j, p] = M1[j, p] * inv
            for p in range(n):
                for q in range(p, n):
                    v = M2[j, p, q] * inv - mean[j, p] * mean[j, q]
                    cov[j, p, q] = v
                    cov[j, q, p] = v
            lw[j] = np.log(W[j]) + mx
        else:
            lw[j] = -np.inf
            for p in range(n):
                mean[j, p] = 0.0
                for q in range(n):
                    cov[j, p, q] = p0 if p == q else 0.0


def _copy_grid(g: rbpmf.State) -> rbpmf.State:
    return rbpmf.State(np.array(g.log_w, dtype=np.float64), np.array(g.mean, dtype=np.float64),
                       np.array(g.cov, dtype=np.float64), float(g.log_w_null), int(g.mode_j))


def _move(config: Config, g: rbpmf.State, offset: float, delta: float) -> float:
    """Add ``delta`` rad/s: whole cells moved exactly (in place on ``g``), remainder returned."""
    dx = config.dx
    tot = offset + delta
    k = int(np.round(tot / dx))
    if k != 0:
        _shift(g.log_w, g.mean, g.cov, float(k), config.tracker.model.p0_amp)
    return tot - k * dx


def _resolve(config: Config, g: rbpmf.State, offset: float) -> float:
    """Apply the sub-cell offset by one linear split; returns the new offset 0."""
    if offset != 0.0:
        _shift(g.log_w, g.mean, g.cov, offset / config.dx, config.tracker.model.p0_amp)
    return 0.0
