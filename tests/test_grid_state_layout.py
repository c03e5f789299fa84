"""The grid filter's State as :func:`vibrospeed.estimators.grid.filter.step` makes it: the means
and covariances kept in the compiled loop's layout and built when read. Its fields, its tuple
protocol and its next steps are those of the same state held as plain arrays, and of
``filter.run`` (the reference: the batch loop, which hands back plain arrays)."""

import pickle

import numpy as np

from vibrospeed.estimators import grid
from vibrospeed.estimators.grid import filter as gf
from vibrospeed.types import Recording


def _cfg():
    return grid.config_for(Recording(np.arange(200) / 100.0, {"ay": np.zeros(200)}), axis="y",
                           params={"n_grid": 40, "smooth": "none"}).tracker


def _signal(n=300, seed=3):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    y = np.cos(25.0 * t) + 0.4 * np.cos(50.0 * t) + 0.3 * rng.normal(size=n)
    y[40:44] = np.nan
    return y


def _stepped(cfg, y):
    st = gf.init(cfg)
    for v in y:
        st, _ = gf.step(cfg, st, float(v))
    return st


def _plain(st):
    return gf.State(st.log_w.copy(), st.mean.copy(), st.cov.copy(), st.log_w_null, st.mode_j)


def _bits(a):
    return np.asarray(a, dtype=np.float64).view(np.int64)


def test_fields_equal_the_run_final_state():
    cfg = _cfg()
    y = _signal()
    st = _stepped(cfg, y)
    assert st._z is not None  # held in the loop's layout until read
    ref = gf.run(cfg, y).final
    for name in ("log_w", "mean", "cov"):
        np.testing.assert_array_equal(_bits(getattr(st, name)), _bits(getattr(ref, name)))
    assert st.log_w_null == ref.log_w_null and st.mode_j == ref.mode_j
    assert st.mean.shape == (40, cfg.model.n_lin)
    np.testing.assert_array_equal(st.cov, np.swapaxes(st.cov, 1, 2))  # both triangles


def test_tuple_protocol():
    cfg = _cfg()
    st = _stepped(cfg, _signal(120))
    assert isinstance(st, tuple) and len(st) == 5
    lw, mean, cov, lw0, mode = st
    assert mean is st.mean and cov is st.cov and lw is st.log_w
    assert st[1] is st.mean and st[-1] == mode and lw0 == st.log_w_null
    assert list(st._asdict()) == list(gf.State._fields)
    other = _stepped(cfg, _signal(120))
    moved = other._replace(log_w_null=-5.0)
    assert moved.log_w_null == -5.0 and moved.log_w is other.log_w
    np.testing.assert_array_equal(moved.mean, st.mean)
    assert "State(log_w=" in repr(st)


def test_next_steps_equal_the_plain_state_and_leave_it():
    cfg = _cfg()
    y = _signal()
    st = _stepped(cfg, y[:200])
    z0 = st._z.copy()
    plain = _plain(_stepped(cfg, y[:200]))
    a, b = st, plain
    for v in y[200:]:
        a, ea = gf.step(cfg, a, float(v))
        b, eb = gf.step(cfg, b, float(v))
        assert _bits(ea.omega) == _bits(eb.omega) and _bits(ea.omega_std) == _bits(eb.omega_std)
    for name in ("log_w", "mean", "cov"):
        np.testing.assert_array_equal(_bits(getattr(a, name)), _bits(getattr(b, name)))
    np.testing.assert_array_equal(_bits(st._z), _bits(z0))  # the state stepped from is kept


def test_arrays_changed_in_place_after_a_read_count():
    cfg = _cfg()
    y = _signal()
    st = _stepped(cfg, y[:150])
    st.mean[:, :] *= 0.5  # read (built), then changed in place, as aided_grid's shift does
    st.cov[:, :, :] *= 2.0
    ref = gf.State(st.log_w.copy(), st.mean.copy(), st.cov.copy(), st.log_w_null, st.mode_j)
    a, ea = gf.step(cfg, st, float(y[150]))
    b, eb = gf.step(cfg, ref, float(y[150]))
    assert _bits(ea.omega) == _bits(eb.omega)
    np.testing.assert_array_equal(_bits(a.cov), _bits(b.cov))
    untouched, eu = gf.step(cfg, _stepped(cfg, y[:150]), float(y[150]))
    assert not np.array_equal(untouched.cov, a.cov)  # the change did reach the step


def test_pickle_round_trip_continues_bitwise():
    cfg = _cfg()
    y = _signal()
    st = _stepped(cfg, y[:180])
    back = pickle.loads(pickle.dumps(st))
    assert type(back) is gf.State
    r1 = gf.run(cfg, y[180:], state=st)
    r2 = gf.run(cfg, y[180:], state=back)
    np.testing.assert_array_equal(_bits(r1.omega), _bits(r2.omega))


def test_a_state_of_another_config_is_refused_before_the_compiled_loop():
    import pytest

    from vibrospeed.errors import ParameterError

    cfg = _cfg()
    other = grid.config_for(Recording(np.arange(200) / 100.0, {"ay": np.zeros(200)}), axis="y",
                            params={"n_grid": 30, "smooth": "none"}).tracker
    y = _signal(20)
    for st in (gf.init(other), gf.init(cfg)._replace(mode_j=cfg.n_grid + 5),
               gf.init(cfg)._replace(mode_j=-2)):
        # run: the compiled loop would index past the arrays (a segfault, or NaN then one)
        with pytest.raises(ParameterError, match="grid state"):
            gf.run(cfg, y, st)
        with pytest.raises(ValueError, match="grid state"):
            gf.step(cfg, st, 0.1)
    gf.run(cfg, y, gf.init(cfg)._replace(mode_j=-1))  # -1: no mode window yet, valid
