"""The causal grid tracker's per-sample fast paths give the batch numbers bitwise: one comb
frame of one axis read from the ring buffer (``comb.ring_evidence``) against the batch's array
form, the method's step against its run (one and three comb axes, 100 Hz and an odd rate, NaN
samples), and the filter step that updates a state into new storage against ``filter.run``."""

import dataclasses

import numpy as np
import pytest

from vibrospeed.estimators import grid
from vibrospeed.estimators.grid import comb
from vibrospeed.estimators.grid import filter as gf
from vibrospeed.estimators.grid import method as gm
from vibrospeed.types import Recording


def _cfg(fs, axes=()):
    n = int(2 * fs)
    rec = Recording(np.arange(n) / fs, {"ax": np.zeros(n), "ay": np.zeros(n), "az": np.zeros(n)})
    tr = grid.config_for(rec, axis="y", params={"n_grid": 40, "smooth": "none"}).tracker
    return grid.Config(tracker=tr, comb_window=1.0, comb_axes=axes)


def _drive(n, fs, A, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    y = (np.cos(30.0 * t) + 0.5 * np.cos(60.0 * t))[:, None] + 0.3 * rng.normal(size=(n, A))
    y[40:45] = np.nan  # inside the first growing frames
    y[rng.integers(0, n, 12)] = np.nan
    y[rng.integers(0, n, 2), 0] = np.inf
    return y[:, 0] if A == 1 else y


def test_pairwise_sum_is_numpys():
    rng = np.random.default_rng(1)
    for n in [*range(1, 300), 1000, 4099]:
        x = rng.normal(size=n) * np.exp(rng.uniform(-8, 8, n))
        assert (0.0 + comb._pairwise_sum(x, 0, n)) / n == x[None, None, :].mean(axis=2)[0, 0]


@pytest.mark.parametrize("fs", [100.0, 173.0])
def test_one_frame_is_the_batch_row_bitwise(fs):
    cfg = _cfg(fs)
    L = cfg.frame_len
    rng = np.random.default_rng(2)
    for n in (L, cfg.min_frame_len, (L + cfg.min_frame_len) // 2 + 1):
        for case in range(4):
            x = np.cos(30.0 * np.arange(n) / fs) + 0.3 * rng.normal(size=n)
            if case == 1:
                x[rng.integers(0, n, 5)] = np.nan
                x[3] = -np.inf
            elif case == 2:
                x[: n // 2 + 1] = np.nan  # more than half missing: no evidence
            elif case == 3:
                x[:] = 0.0
            frames = np.stack([x, rng.normal(size=n)])[None]  # (1, 2, n): the batch form
            for centre in (False, True):
                for raw in (False, True):
                    want = comb.frame_evidence(cfg, frames, centre, raw=raw)[0]
                    # the frame at an offset in a ring, wrapping
                    ring = np.empty(n + 7)
                    s = 11
                    idx = (s + np.arange(n - 1)) % ring.size
                    ring[idx] = x[:-1]
                    got = comb.ring_evidence(cfg, ring, s, n - 1, float(x[-1]), centre, raw)
                    assert got.tobytes() == want.tobytes()
                    one = comb.frame_evidence(cfg, x[None, :], centre, raw=raw)[0]
                    assert one.tobytes() == want.tobytes()
            if case == 2:
                assert not np.any(want)


@pytest.mark.parametrize(("fs", "axes"), [(100.0, ()), (173.0, ()), (100.0, ("y", "x", "z"))])
def test_method_steps_are_its_run_bitwise(fs, axes):
    cfg = _cfg(fs, axes)
    A = max(1, len(axes))
    y = _drive(int(2.6 * fs), fs, A)
    res = gm.run(cfg, y)
    st = gm.init(cfg, n_axes=A)
    om, std, pn = [], [], []
    for k in range(y.shape[0]):
        buf = st.buf.copy()
        st, est = gm.step(cfg, st, float(y[k]) if A == 1 else y[k])
        om.append(est.omega)
        std.append(est.omega_std)
        pn.append(est.extras["p_null"])
    assert buf.tobytes() != st.buf.tobytes()  # the step made a new buffer
    filt = res.filt
    assert np.array(om).tobytes() == filt.omega.tobytes()
    assert np.array(std).tobytes() == filt.omega_std.tobytes()
    assert np.array(pn).tobytes() == filt.p_null.tobytes()


def test_filter_step_updates_into_new_storage_bitwise():
    cfg = _cfg(100.0).tracker
    y = _drive(300, 100.0, 1, seed=3)
    ex_at = {60: np.linspace(-1.0, 1.0, cfg.n_grid + 1), 61: np.linspace(1.0, 0.0, cfg.n_grid)}
    ex_idx = np.array(sorted(ex_at))
    ex_val = np.stack([np.append(v, 0.0) if v.size == cfg.n_grid else v
                       for v in (ex_at[i] for i in ex_idx)])
    res = gf.run(cfg, y, extra=(ex_idx, ex_val))
    st = gf.init(cfg)  # plain arrays
    om = []
    for k, v in enumerate(y):
        st, est = gf.step(cfg, st, float(v), extra=ex_at.get(k))
        om.append(est.omega)
        if k == 150:  # a state in the loop's layout is left as it is (finite and NaN samples)
            kept = st._z.copy()
            a, _ = gf.step(cfg, st, 0.25)
            b, _ = gf.step(cfg, st, np.nan)
            assert st._z.tobytes() == kept.tobytes()
            assert a._z is not st._z and b._z is not st._z
    assert np.array(om).tobytes() == res.omega.tobytes()
    for f in ("log_w", "mean", "cov"):
        assert getattr(st, f).tobytes() == getattr(res.final, f).tobytes()
    assert (st.log_w_null, st.mode_j) == (res.final.log_w_null, res.final.mode_j)


def test_a_config_keeps_one_work_space_and_steps_of_two_configs_do_not_mix():
    c1 = _cfg(100.0).tracker
    c2 = dataclasses.replace(c1)  # another instance: its own plan
    y = _drive(120, 100.0, 1, seed=4)
    s1, s2 = gf.init(c1), gf.init(c2)
    for v in y:
        s1, e1 = gf.step(c1, s1, float(v))
        s2, e2 = gf.step(c2, s2, float(v))
        assert e1.omega == e2.omega
    assert gf._plan(c1).ws is gf._plan(c1).ws and gf._plan(c1).ws is not gf._plan(c2).ws
