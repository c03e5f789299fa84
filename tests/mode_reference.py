"""Brute-force reference of the grid trackers' mode (``point="mode"``), shared by tests."""

import numpy as np


def window_masses(w, g, rel, ab, u=None):
    """Mass of ``w`` within max(ab, rel g_j) of every grid point g_j (plain loops); with the
    prior ``u``, the mass in excess of a flat posterior's, ``sum_window (w_i - W u_i)``,
    ``W = sum(w)``."""
    hw = np.maximum(ab, rel * g)
    d = w if u is None else w - w.sum() * np.asarray(u, np.float64)
    return np.array([d[np.abs(g - g[j]) <= hw[j]].sum() for j in range(g.size)]), hw


def check_mode(w, g, rel, ab, omega_mode, p_mode, u, tol=1e-9):
    """The reported mode is the mean of a window holding the most mass in excess of a flat
    posterior's (prior ``u``; ties within 1e-9 of the mass), and p_mode the mass covered by that
    window's basin of non-increasing window excesses."""
    w = np.asarray(w, np.float64)
    m, hw = window_masses(w, g, rel, ab, u)
    eps = 1e-9 * w.sum()
    cands = np.flatnonzero(m >= m.max() - eps)
    means = []
    for j in cands:
        inw = np.abs(g - g[j]) <= hw[j]
        means.append(w[inw] @ g[inw] / w[inw].sum())
    k = int(np.argmin(np.abs(np.array(means) - omega_mode)))
    assert abs(means[k] - omega_mode) <= tol * max(1.0, abs(omega_mode))
    j = int(cands[k])
    a, b = j, j
    while a > 0 and m[a - 1] <= m[a] + eps:
        a -= 1
    while b < g.size - 1 and m[b + 1] <= m[b] + eps:
        b += 1
    cover = (g >= g[a] - hw[a]) & (g <= g[b] + hw[b])
    assert abs(w[cover].sum() / w.sum() - p_mode) < tol


def held_modes(posts, g, rel, ab, hold, u):
    """Mode with hysteresis (``mode_hold``), brute force over stored posteriors (n, N): the
    window with the most mass in excess of a flat posterior's (prior ``u``; ties: the nearest
    the posterior mean); keep the current window, re-centred on its best window within its
    half-width, unless the best window holds more than ``hold`` times its mass (plain masses
    in the hold);
    returns the windows' means."""
    out, cur = [], -1
    for w in np.asarray(posts, np.float64):
        m, hw = window_masses(w, g, rel, ab)
        e, _ = window_masses(w, g, rel, ab, u)
        tied = np.flatnonzero(e >= e.max() - 1e-9 * w.sum())
        jb = int(tied[np.argmin(np.abs(g[tied] - w @ g / w.sum()))])
        if cur >= 0:
            near = np.flatnonzero(np.abs(g - g[cur]) <= hw[cur])
            jc = int(near[np.argmax(m[near])]) if m[near].max() > m[cur] else cur
            if not m[jb] > hold * m[jc]:
                jb = jc
        cur = jb
        inw = np.abs(g - g[jb]) <= hw[jb]
        out.append(w[inw] @ g[inw] / m[jb])
    return np.array(out)
