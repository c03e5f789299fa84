"""Posterior summaries of grid weights, shared by the filter and the smoother: mean, std,
MAP, credible band (piecewise-uniform cells), mode window, its basin and the spread of omega
within it, masses near MAP/2, 2 MAP, MAP/3, 3 MAP. The columns of a summary row are named
here (``COL_*``)."""

from __future__ import annotations

import numpy as np
from numba import njit

#: columns of a summary row: posterior mean given a line (rad/s), std and band of the mixture
#: (the "no line" mass spread over the grid), MAP grid point, predictive log-likelihood (filter
#: only), "no line" mass, masses near MAP/2, 2 MAP, MAP/3, 3 MAP (shares of the signal mass),
#: mean of the mode window (rad/s), its basin's share of the signal mass, and the spread of
#: omega within that basin about the mode's mean (rad/s; the mixture's std covers all modes)
COL_MEAN, COL_STD, COL_MAP, COL_LO, COL_HI, COL_LOGLIK = 0, 1, 2, 3, 4, 5
COL_P_NULL, COL_P_HALF, COL_P_DOUBLE, COL_P_THIRD, COL_P_TRIPLE = 6, 7, 8, 9, 10
COL_MODE, COL_P_MODE, COL_MODE_STD = 11, 12, 13
#: fixed columns per row; the filter appends the M amplitudes at the MAP point after them
N_OUT_FIXED = 14
#: window excesses within TIE x the signal mass of each other are tied (the running sums'
#: round-off)
TIE = 1e-9


@njit(cache=True)
def _quantile(w, edges, q):
    """Quantile of the piecewise-uniform density with mass w_j on cell [edges_j, edges_j+1]."""
    acc = 0.0
    N = w.size
    for j in range(N):
        if acc + w[j] >= q and w[j] > 0.0:
            f = (q - acc) / w[j]
            if f < 0.0:
                f = 0.0
            if f > 1.0:
                f = 1.0
            return edges[j] + f * (edges[j + 1] - edges[j])
        acc += w[j]
    return edges[N]


@njit(cache=True)
def _near(grid, x, hw):
    """``(a, b)``: the grid points with ``|grid_j - x| <= hw`` are ``a <= j < b`` (``grid``
    increasing: ``|grid_j - x|`` rounds monotonically on each side of x, so they are
    contiguous); found by bisection for x and a walk out over the window, the same test
    per point as a scan of the whole grid."""
    N = grid.size
    lo = 0
    hi = N
    while lo < hi:  # first point >= x
        mid = (lo + hi) // 2
        if grid[mid] < x:
            lo = mid + 1
        else:
            hi = mid
    a = lo
    while a > 0 and abs(grid[a - 1] - x) <= hw:
        a -= 1
    b = lo
    while b < N and abs(grid[b] - x) <= hw:
        b += 1
    return a, b


@njit(cache=True)
def _mass_near(w, grid, x, rel, ab):
    """Mass of ``w`` on grid points within max(ab, rel x) of x (summed in grid order)."""
    a, b = _near(grid, x, max(ab, rel * x))
    s = 0.0
    for j in range(a, b):
        s += w[j]
    return s


@njit(cache=True)
def _summary(w, w0, u, grid, edges, q_lo, q_hi, amb_rel, amb_abs, v, out, hold, cur):
    """The summary row ``out`` (every ``COL_*`` but ``COL_LOGLIK``) from grid weights ``w``
    (signal, sum 1 - w0) and null mass ``w0``:
    omega is the mean given a line (grid part renormalised); std and band are of the mixture
    ``v_j = w_j + w0 u_j`` (the null's omega is unknown: uniform on the grid), the band the
    equal-tailed one widened to hold the mode's mean (``COL_MODE``, the reported omega);
    MAP and ambiguity masses are of the signal part."""
    N = grid.size
    mu = 0.0
    mc = 0.0
    jmap = 0
    for j in range(N):
        v[j] = w[j] + w0 * u[j]
        mu += v[j] * grid[j]
        mc += w[j] * grid[j]
        if w[j] > w[jmap]:
            jmap = j
    var = 0.0
    for j in range(N):
        d = grid[j] - mu
        var += v[j] * d * d
    # reported omega: the mean given that a line is present (= mu without a null state)
    out[COL_MEAN] = mc / (1.0 - w0) if w0 > 0.0 and w0 < 1.0 else mu
    out[COL_STD] = np.sqrt(var)
    out[COL_MAP] = grid[jmap]
    out[COL_LO] = _quantile(v, edges, q_lo)
    out[COL_HI] = _quantile(v, edges, q_hi)
    out[COL_P_NULL] = w0
    # the mode: the window of half-width max(amb_abs, amb_rel x) around a grid point x whose
    # signal mass most exceeds that of a flat posterior, sum_window (w_j - (1 - w0) u_j) (two
    # pointers; v is free after the quantiles), reported as the window's conditional mean. A
    # window, not the single highest point, so a spiky posterior (fine grid, tempered data)
    # does not hop between neighbouring peaks; the excess, not the mass, because the windows
    # widen with x while the prior u is uniform in omega: where the data say little, the
    # widest window (the top of the range) would otherwise win
    sig = 1.0 - w0
    lo = 0
    hi = 0
    s = 0.0
    top = -np.inf
    for j in range(N):
        hw = max(amb_abs, amb_rel * grid[j])
        while hi < N and grid[hi] <= grid[j] + hw:
            s += w[hi] - sig * u[hi]
            hi += 1
        while grid[lo] < grid[j] - hw:
            s -= w[lo] - sig * u[lo]
            lo += 1
        v[j] = s
        top = max(top, s)
    # windows within the sums' round-off of the best (a flat posterior: all of them) are
    # tied; the one nearest the posterior mean given a line wins, so ties do not go to an end
    tie = top - TIE * sig
    mean = out[COL_MEAN]
    jb = -1
    for j in range(N):
        if v[j] >= tie and (jb < 0 or abs(grid[j] - mean) < abs(grid[jb] - mean)):
            jb = j
    # hysteresis (mode_hold > 1): keep the current window, re-centred on its best window
    # within its half-width, unless the best window holds more than hold x its mass (plain
    # masses throughout: a ratio of excesses, which may be negative, means nothing)
    if hold > 1.0 and cur[0] >= 0:
        c = cur[0]
        hwc = max(amb_abs, amb_rel * grid[c])
        jc = c
        mcur = _mass_near(w, grid, grid[c], amb_rel, amb_abs)
        a, b = _near(grid, grid[c], hwc)
        for j in range(a, b):
            mj = _mass_near(w, grid, grid[j], amb_rel, amb_abs)
            if mj > mcur:
                jc = j
                mcur = mj
        if not _mass_near(w, grid, grid[jb], amb_rel, amb_abs) > hold * mcur:
            jb = jc
    cur[0] = jb
    hw = max(amb_abs, amb_rel * grid[jb])
    sb = 0.0
    mb = 0.0
    a, b = _near(grid, grid[jb], hw)
    for j in range(a, b):
        sb += w[j]
        mb += w[j] * grid[j]
    out[COL_MODE] = mb / sb if sb > 0.0 else grid[jb]
    # the band is widened to hold the mode's mean, the reported omega (point="mode"): the
    # equal-tailed band is of the mixture, the mode of the signal part, and a mode at an end of
    # the grid (signal mass piled on the floor, or a window held by mode_hold there) lies
    # outside the band's 1 % tail when "no line" carries the mass (p_null 0.9 on 10-120 rad/s
    # puts the 1 % quantile 1.2 rad/s above the floor). [min(lo, mode), max(hi, mode)] holds at
    # least the band's mass, so it is still a credible band at its level, and it is the
    # equal-tailed band, bit for bit, wherever that already holds the mode
    if out[COL_MODE] < out[COL_LO]:
        out[COL_LO] = out[COL_MODE]
    if out[COL_MODE] > out[COL_HI]:
        out[COL_HI] = out[COL_MODE]
    # its basin: the windows reached from jb by non-increasing window excess (within TIE:
    # the running sums' round-off, so a flat posterior is one basin); p_mode is the signal
    # mass they cover; the within-mode spread is the root-mean-square distance of omega from the
    # mode's mean over the basin, sqrt(sum_basin w_j (g_j - mode)^2 / sum_basin w_j): the
    # spread of the posterior given the mode, about the point the mode reports
    mode = out[COL_MODE]
    a = jb
    while a > 0 and v[a - 1] <= v[a] + TIE * sig:
        a -= 1
    b = jb
    while b < N - 1 and v[b + 1] <= v[b] + TIE * sig:
        b += 1
    x_lo = grid[a] - max(amb_abs, amb_rel * grid[a])
    x_hi = grid[b] + max(amb_abs, amb_rel * grid[b])
    # the grid points in [x_lo, x_hi]: from a (x_lo <= grid[a]) out to both sides
    while a > 0 and grid[a - 1] >= x_lo:
        a -= 1
    while b < N - 1 and grid[b + 1] <= x_hi:
        b += 1
    sb = 0.0
    ss = 0.0
    for j in range(a, b + 1):
        sb += w[j]
        d = grid[j] - mode
        ss += w[j] * d * d
    out[COL_P_MODE] = min(1.0, sb / sig) if sig > 1e-300 else 1.0
    out[COL_MODE_STD] = np.sqrt(ss / sb) if sb > 0.0 else 0.0
    if sig > 1e-300:
        x = grid[jmap]
        out[COL_P_HALF] = _mass_near(w, grid, x / 2.0, amb_rel, amb_abs) / sig
        out[COL_P_DOUBLE] = _mass_near(w, grid, 2.0 * x, amb_rel, amb_abs) / sig
        out[COL_P_THIRD] = _mass_near(w, grid, x / 3.0, amb_rel, amb_abs) / sig
        out[COL_P_TRIPLE] = _mass_near(w, grid, 3.0 * x, amb_rel, amb_abs) / sig
    else:
        out[COL_P_HALF] = 0.0
        out[COL_P_DOUBLE] = 0.0
        out[COL_P_THIRD] = 0.0
        out[COL_P_TRIPLE] = 0.0
    return jmap

