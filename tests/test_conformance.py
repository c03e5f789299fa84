"""Every method of :data:`vibrospeed.estimators.METHODS` holds the estimator protocol.

The protocol (the docstring of :mod:`vibrospeed.estimators`): a frozen ``Config`` (unknown
fields are a :class:`ParameterError`), a small ``State``, ``init(config) -> State``,
``step(config, state, sample) -> (State, Estimate)`` with the shared
:class:`vibrospeed.types.Estimate`, ``run(config, samples, state=None) -> Result`` holding the
same per-sample columns and ``final`` (the state after the last sample), and
``estimate(recording, *, axis, wheel_radius, params, progress, return_posterior) -> Track``.

Checked here for each method on a short synthetic signal: step == run bitwise (every column
that the Estimate and the run result share, by name), a run in two chunks == one run,
NaN input samples give finite output, Config and State survive a pickle round trip (the
unpickled state continues with the same numbers), and an unknown parameter is a
ParameterError both in the Config and in ``estimate``.
"""

from __future__ import annotations

import dataclasses
import inspect
import pickle

import numpy as np
import pytest

from vibrospeed import estimators, sim
from vibrospeed.config import config_from_params
from vibrospeed.errors import ParameterError
from vibrospeed.types import Estimate

DT = 0.01
N = 600  # 6 s at 100 Hz: growing and full comb frames, five SHS batches


def _vibration(n: int = N, seed: int = 0) -> np.ndarray:
    """A wheel comb at 30 rad/s (M = 3) in white noise, roughly unit RMS."""
    t = np.arange(n) * DT
    rng = np.random.default_rng(seed)
    return (np.sin(30 * t) + 0.5 * np.sin(60 * t + 1.0) + 0.3 * np.sin(90 * t + 2.0)
            + 0.3 * rng.normal(size=n))


def _case(method: str):
    """``(module, config, samples)`` for a method that follows the protocol."""
    from vibrospeed.estimators import aided, ekf, grid, rbpf, rbpmf, shs
    from vibrospeed.estimators.aiding import Sample

    y = _vibration()
    if method == "ekf":
        return ekf, ekf.Config(omega0=28.0), y
    if method == "rbpmf":
        return rbpmf, rbpmf.Config(n_grid=60, omega_min=10.0, omega_max=60.0), y
    if method == "grid":
        tr = dataclasses.replace(grid._default_tracker(DT), n_grid=60, omega_min=10.0,
                                 omega_max=60.0, smooth="none")
        return grid, grid.Config(tracker=tr), y
    if method == "rbpf":
        return rbpf, rbpf.Config(n_particles=100, omega_min=10.0, omega_max=60.0, seed=3), y
    if method == "shs":
        return shs, shs.Config(dt=DT, batch=100), y
    if method == "aided":
        u = 0.3 * np.sin(np.arange(N) * DT)
        return aided, aided.Config(wheel_radius=0.3), Sample(0.2 * y, u)
    if method == "aided_grid":  # ``aided`` with ``tracker=rbpmf`` or ``grid``
        from vibrospeed.estimators import aided_grid

        u = 0.3 * np.sin(np.arange(N) * DT)
        tr = dataclasses.replace(aided_grid._cart_tracker(DT), n_grid=81)
        return aided_grid, aided_grid.Config(tracker=tr, wheel_radius=0.3), Sample(0.2 * y, u)
    if method == "gps-riss":
        from vibrospeed.estimators import gps_riss

        t = np.arange(N) * DT
        rng = np.random.default_rng(1)
        accel = 0.5 * np.cos(0.5 * t) + 0.05 * rng.normal(size=N)
        gps = np.full(N, np.nan)
        gps[::10] = 10.0 + np.sin(0.5 * t[::10]) + 0.1 * rng.normal(size=gps[::10].size)
        return gps_riss, gps_riss.Config(), gps_riss.Sample(t, accel, gps, np.full(N, 9.0))
    if method == "algebraic":
        from vibrospeed.estimators import algebraic

        t = np.arange(N) * DT
        rng = np.random.default_rng(2)
        vx = 15.0 + 2.0 * np.sin(0.4 * t)
        gz = np.where((t > 2.0) & (t < 4.0), 0.1, 0.0)
        Z = np.stack([gz, 0.8 * np.cos(0.4 * t), gz * vx, vx / 0.31], axis=1)
        return algebraic, algebraic.Config(dt=DT), Z + 0.02 * rng.normal(size=Z.shape)
    if method == "fuse":
        from vibrospeed.estimators import fuse

        t = np.arange(N) * DT
        rng = np.random.default_rng(4)
        v = 12.0 + 2.0 * np.sin(0.5 * t)
        gps = np.full(N, np.nan)
        gps[::10] = v[::10] + 0.1 * rng.normal(size=gps[::10].size)
        gps[300:450] = np.nan  # an outage
        omega = v / 0.3 + 0.5 * rng.normal(size=N)
        return fuse, fuse.Config(), fuse.Sample(
            t, np.cos(0.5 * t) + 0.05 * rng.normal(size=N), gps, np.full(N, 9.0), omega,
            np.full(N, 0.5), (np.arange(N) % 50) < 40, np.zeros(N, bool))
    raise AssertionError(method)


#: the methods, and method variants whose state and step are their own (``method:variant``)
ALL = list(estimators.METHODS) + ["aided_grid"]


def _protocol(method: str):
    return _case(method)


def _n(samples) -> int:
    return len(samples[0]) if hasattr(samples, "_fields") else len(samples)


def _primary(res) -> np.ndarray:
    """The quantity a method estimates: omega, or speed for the speed estimators."""
    om = getattr(res, "omega", None)
    return np.asarray(res.speed if om is None else om)


def _take(samples, sl):
    """Samples ``sl`` (an index or a slice) of an array or of a NamedTuple of arrays."""
    if hasattr(samples, "_fields"):
        return type(samples)(*(v[sl] if np.ndim(v) else v for v in samples))
    return samples[sl]


def _with_nan(samples):
    """Copies with every 7th sample and a run of 25 samples NaN in the vibration."""
    idx = np.r_[np.arange(3, N, 7), np.arange(200, 225)]
    if hasattr(samples, "_fields"):  # the vibration, else the first measured input
        name = "y" if "y" in samples._fields else samples._fields[1]
        y = getattr(samples, name).copy()
        y[idx] = np.nan
        return samples._replace(**{name: y})
    y = samples.copy()
    y[idx] = np.nan
    return y


def _bits(x) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(x, dtype=np.float64)).view(np.uint64)


def _columns(est: Estimate, res) -> dict[str, np.ndarray]:
    """The run result's columns that the Estimate also has (fields and extras), per sample."""
    names = [f for f in Estimate._fields if f != "extras"] + list(est.extras)
    out = {}
    for name in names:
        try:
            col = getattr(res, name)
        except AttributeError:
            continue
        if col is not None:
            out[name] = np.asarray(col)
    return out


def _per_batch(res, n: int) -> bool:
    return len(np.atleast_1d(_primary(res))) != n


@pytest.mark.parametrize("method", list(estimators.METHODS))
def test_module_has_the_protocol(method):
    mod = estimators.get(method)
    assert dataclasses.is_dataclass(mod.Config) and mod.Config.__dataclass_params__.frozen
    assert issubclass(mod.State, tuple)
    for fn in ("init", "step", "run", "estimate"):
        assert callable(getattr(mod, fn))
    assert list(inspect.signature(mod.step).parameters)[:3] == ["config", "state", "y"]
    run_params = list(inspect.signature(mod.run).parameters)
    assert run_params[:2] == ["config", "y"] and "state" in run_params
    est_params = inspect.signature(mod.estimate).parameters
    for kw in ("axis", "wheel_radius", "params", "progress", "return_posterior"):
        assert kw in est_params, f"{method}.estimate has no '{kw}'"


@pytest.mark.parametrize("method", ALL)
def test_step_equals_run_bitwise(method):
    mod, cfg, s = _protocol(method)
    res = mod.run(cfg, s, state=mod.init(cfg))
    st = mod.init(cfg)
    ests = []
    for k in range(_n(s)):
        st, est = mod.step(cfg, st, _take(s, k))
        assert isinstance(est, Estimate)
        ests.append(est)
    if _per_batch(res, _n(s)):  # one estimate per batch, at the sample that completes it
        got = [e.omega for e in ests if np.isfinite(e.omega)]
        assert len(got) == len(res.omega) > 0
        np.testing.assert_array_equal(_bits(got), _bits(res.omega))
        return
    cols = _columns(ests[0], res)
    assert ("omega" in cols or "speed" in cols) and len(cols) >= 2
    for name, col in cols.items():
        stepped = np.array([getattr(e, name) for e in ests], dtype=np.float64)
        assert np.array_equal(_bits(stepped), _bits(col)), f"{method}: column '{name}'"
    # the states agree too: one more sample from each gives the same estimate
    nxt = _take(s, slice(0, 1))
    a = mod.run(cfg, nxt, state=st)
    b = mod.run(cfg, nxt, state=res.final)
    assert np.array_equal(_bits(_primary(a)), _bits(_primary(b)))


@pytest.mark.parametrize("method", ALL)
def test_chunked_run_equals_whole_run(method):
    mod, cfg, s = _protocol(method)
    whole = mod.run(cfg, s)
    first = mod.run(cfg, _take(s, slice(0, 237)))
    second = mod.run(cfg, _take(s, slice(237, None)), state=first.final)
    names = ["omega"] if _per_batch(whole, _n(s)) else list(
        _columns(mod.step(cfg, mod.init(cfg), _take(s, 0))[1], whole))
    for name in names:
        joined = np.concatenate([np.asarray(getattr(first, name)),
                                 np.asarray(getattr(second, name))])
        assert np.array_equal(_bits(joined), _bits(getattr(whole, name))), name


@pytest.mark.parametrize("method", ALL)
def test_nan_samples_give_finite_output(method):
    mod, cfg, s = _protocol(method)
    res = mod.run(cfg, _with_nan(s))
    assert np.all(np.isfinite(_primary(res)))
    std = getattr(res, "omega_std", getattr(res, "speed_std", None))
    if not _per_batch(res, _n(s)) and std is not None:
        assert np.all(np.isfinite(std))


@pytest.mark.parametrize("method", ALL)
def test_config_and_state_pickle(method):
    mod, cfg, s = _protocol(method)
    cfg2 = pickle.loads(pickle.dumps(cfg))
    assert cfg2 == cfg
    st = mod.run(cfg, _take(s, slice(0, 300))).final
    st2 = pickle.loads(pickle.dumps(st))
    rest = _take(s, slice(300, None))
    a = mod.run(cfg, rest, state=st)
    b = mod.run(cfg2, rest, state=st2)
    assert np.array_equal(_bits(_primary(a)), _bits(_primary(b)))
    init = mod.init(cfg)
    init2 = pickle.loads(pickle.dumps(init))
    assert np.array_equal(_bits(_primary(mod.run(cfg, rest, state=init2))),
                          _bits(_primary(mod.run(cfg, rest, state=init))))


@pytest.mark.parametrize("method", list(estimators.METHODS))
def test_unknown_config_field_is_a_parameter_error(method):
    mod = estimators.get(method)
    with pytest.raises(ParameterError, match="no_such_parameter"):
        config_from_params(mod.Config, {"no_such_parameter": 1.0})


@pytest.fixture(scope="module")
def car():
    return sim.simulate("car", seed=1, duration=8.0)


@pytest.mark.parametrize("method", list(estimators.METHODS))
def test_estimate_rejects_an_unknown_parameter(method, car):
    mod = estimators.get(method)
    kw = {"axis": "x"} if method == "gps-riss" else {}
    params = {"L1": "1.2"} if method == "algebraic" else {}  # the one it cannot default
    with pytest.raises(ParameterError, match="no_such_parameter"):
        mod.estimate(car, params={**params, "no_such_parameter": "1"}, **kw)
