"""The grid smoother's compiled loops: the band sums offset by offset, the Viterbi scan over the
grid, the summary's window sums over index ranges and the first pass's kept tail, each checked
bitwise against a plain-Python loop over grid points or the whole-log pass."""

import numpy as np
import pytest

from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.grid import smoother as gs
from vibrospeed.estimators.grid import summary
from vibrospeed.estimators.grid import viterbi as gv
from vibrospeed.models.harmonic import HarmonicModel

FIELDS = ("omega", "omega_std", "omega_map", "omega_lo", "omega_hi", "p_null", "p_half",
          "p_double", "p_third", "p_triple", "omega_mode", "p_mode", "omega_mode_std",
          "posterior")


def _emissions(n=900, seed=0, null=True):
    """RBPMF emissions of a two-harmonic line stepping 30 -> 38 rad/s with a gap; jumps, and
    the "no line" state when ``null``."""
    model = HarmonicModel(M=2, dt=0.01, q_omega=4.0, q_amp=0.001, r=0.05, p0_amp=0.1)
    om = np.where(np.arange(n) < n // 2, 30.0, 38.0)
    y, _ = model.simulate(om, np.random.default_rng(seed), x0=np.tile([0.6, 0.0], 2))
    y[200:230] = np.nan
    kw = {"off_rate": 0.2, "on_rate": 1.0} if null else {"off_rate": 0.0}
    cfg = rbpmf.Config(model=model, n_grid=30, omega_min=20.0, omega_max=50.0,
                       jump_rate=0.5, **kw)
    return cfg, rbpmf.run(cfg, y, return_grid_loglik=True).grid_loglik


def _same(a, b):
    if a is None or b is None:
        assert a is None and b is None
        return
    assert a.dtype == b.dtype and a.shape == b.shape
    assert np.array_equal(a, b, equal_nan=True)


def test_band_tables_against_the_kernel():
    rng = np.random.default_rng(1)
    N, B = 11, 3
    kb = rng.random((N, 2 * B + 1))
    kf, kr = gs.band_tables(kb, B)
    for j in range(N):
        for i in range(N):
            d = i - j + B  # K(i -> j) = kb[j, i - j + B] inside the band
            k = kb[j, d] if 0 <= d <= 2 * B else None
            if k is None:
                continue
            assert kf[i - j + B, j] == k  # forward: target j, source offset
            assert kr[j - i + B, i] == k  # backward: source i, target offset
    # off the grid: zeros
    assert np.all(kf[:B, 0] == 0) and np.all(kr[B + 1 :, N - 1] == 0)


def _predict_loop(a, kb, B, u, eps, p_off, p_on, has_null):
    """The transition a T as a plain loop over targets and their band sources."""
    N = u.size
    out = np.zeros(N + 1)
    a0 = a[N] if has_null else 0.0
    rw = 1.0 - eps - p_off
    J = eps * (1.0 - a0) + p_on * a0
    for j in range(N):
        s = 0.0
        for i in range(max(0, j - B), min(N - 1, j + B) + 1):
            s += a[i] * kb[j, i - j + B]
        out[j] = rw * s + J * u[j]
    out[N] = p_off * (1.0 - a0) + (1.0 - p_on) * a0 if has_null else 0.0
    return out


@pytest.mark.parametrize("has_null", [True, False])
def test_predict_equals_the_plain_loop(has_null):
    rng = np.random.default_rng(2)
    N, B = 40, 4
    kb = rng.random((N, 2 * B + 1))
    kf, _ = gs.band_tables(kb, B)
    u = rng.random(N)
    u /= u.sum()
    a = rng.random(N + 1)
    a /= a.sum()
    out = np.empty(N + 1)
    gs._predict(a, kf, B, u, 0.01, 0.002, 0.3, has_null, np.zeros(N + 2 * B), np.empty(N),
                out)
    np.testing.assert_array_equal(out, _predict_loop(a, kb, B, u, 0.01, 0.002, 0.3, has_null))


def _viterbi_loop(gll, lw, kb, B, u, eps, p_off, p_on, has_null):
    """The Viterbi path by a plain loop over targets and sources (first maximum wins)."""
    lt, lju, lon, loff, lstay0 = gv._viterbi_tables(kb, B, u, eps, p_off, p_on, has_null)
    n, N1 = gll.shape
    N = N1 - 1
    delta = np.array([lw[j] + gll[0, j] if (j < N or has_null) else -np.inf
                      for j in range(N1)])
    back = np.zeros((n, N1), dtype=np.int64)
    back[0] = np.arange(N1)
    for t in range(1, n):
        best = int(np.argmax(delta[:N]))
        nd = np.empty(N1)
        for j in range(N):
            bv, bi = -np.inf, j
            for i in range(max(0, j - B), min(N - 1, j + B) + 1):
                val = delta[i] + lt[i - j + B, j]
                if val > bv:
                    bv, bi = val, i
            for val, src in ((delta[best] + lju[j], best),
                             (delta[N] + lon[j] if has_null else -np.inf, N)):
                if val > bv:
                    bv, bi = val, src
            nd[j] = bv + gll[t, j]
            back[t, j] = bi
        if has_null:
            stay, leave = delta[N] + lstay0, delta[best] + loff
            nd[N] = (stay if stay >= leave else leave) + gll[t, N]
            back[t, N] = N if stay >= leave else best
        else:
            nd[N], back[t, N] = -np.inf, N
        delta = nd
    path = np.empty(n, dtype=np.int64)
    path[-1] = int(np.argmax(delta))
    for t in range(n - 1, 0, -1):
        path[t - 1] = back[t, path[t]]
    return path


@pytest.mark.parametrize("null", [True, False])
def test_viterbi_equals_the_plain_loop(null):
    cfg, gll = _emissions(n=300, null=null)
    lw, kb, B, grid, edges, u, eps, p_off, p_on, q = gs._setup(cfg)
    ref = _viterbi_loop(gll.astype(np.float64), lw, kb, B, u, eps, p_off, p_on, cfg.has_null)
    np.testing.assert_array_equal(gv.viterbi(cfg, gll).state, ref)


@pytest.mark.parametrize("keep", [0, 1, 250, 299, 300, 450, 899, 900, None])
def test_kept_tail_equals_whole_log(keep):
    cfg, gll = _emissions()
    whole = gs.smooth(cfg, gll, return_posterior=True, checkpoint=None)
    part = gs.smooth(cfg, gll, return_posterior=True, checkpoint=150, keep=keep)
    for f in FIELDS:
        _same(getattr(part, f), getattr(whole, f))


def _mass_near_loop(w, grid, x, rel, ab):
    hw = max(ab, rel * x)
    return sum((w[j] for j in range(grid.size) if abs(grid[j] - x) <= hw), 0.0)


def test_window_sums_over_index_ranges_equal_the_scan():
    rng = np.random.default_rng(3)
    grid = np.cumsum(rng.uniform(0.2, 1.5, 120)) + 5.0
    w = rng.random(120)
    for x in np.r_[grid[::7], grid[::5] / 2, grid[::3] * 3, 0.1, 1e3, grid[0] - 0.01]:
        for rel, ab in ((0.05, 1.5), (0.0, 0.0), (0.2, 0.1), (0.01, 30.0)):
            assert summary._mass_near(w, grid, x, rel, ab) == _mass_near_loop(w, grid, x, rel,
                                                                                ab)
            a, b = summary._near(grid, x, max(ab, rel * x))
            inside = np.flatnonzero(np.abs(grid - x) <= max(ab, rel * x))
            np.testing.assert_array_equal(np.arange(a, b), inside)


@pytest.mark.parametrize("keep", [0, 1, 250, 299, 300, 450, 899, 900, None])
def test_viterbi_kept_tail_equals_whole_log(keep):
    cfg, gll = _emissions()
    whole = gv.viterbi(cfg, gll, checkpoint=None)
    part = gv.viterbi(cfg, gll, checkpoint=150, keep=keep)
    np.testing.assert_array_equal(part.state, whole.state)
    np.testing.assert_array_equal(part.omega, whole.omega)
    assert part.log_joint == whole.log_joint
