"""Edge cases found by using the Python API as a researcher would (short recordings, parameters
an estimator silently ignored): each test failed before its fix."""

from __future__ import annotations

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import aided
from vibrospeed.signal import mount


@pytest.fixture(scope="module")
def car():
    return sim.simulate("car", seed=1, duration=3.0)


@pytest.mark.parametrize("n", [3, 40])
def test_moving_average_of_a_record_shorter_than_its_window(n):
    """A centred window longer than the record: every sample averages the finite samples
    within ``(k - 1) // 2`` before and ``k // 2`` after it (brute force), as long as the
    record (was: ``k`` long, numpy's "same" convolution)."""
    k = 100
    rng = np.random.default_rng(3)
    x = rng.normal(size=(n, 2))
    x[1, 0] = np.nan
    got = mount._moving_average(x, k)
    assert got.shape == x.shape
    a, b = (k - 1) // 2, k // 2
    for i in range(n):
        w = x[max(0, i - a):i + b + 1]
        for j in range(2):
            np.testing.assert_allclose(got[i, j], np.nanmean(w[:, j]), rtol=1e-12)


def test_moving_average_unchanged_for_a_long_record():
    """For a record at least as long as the window: the numbers of numpy's "same"
    convolution, bitwise (the mount's numbers on normal drives stay as they were)."""
    rng = np.random.default_rng(4)
    x = rng.normal(size=500)
    k = 100
    ker = np.ones(k)
    ref = np.convolve(x, ker, "same") / np.convolve(np.ones_like(x), ker, "same")
    np.testing.assert_array_equal(mount._moving_average(x, k), ref)


@pytest.mark.parametrize("n", [2, 50, 99])
def test_aided_estimates_a_recording_shorter_than_a_second(car, n):
    """``aided.estimate`` on less than the mount's 1 s smoothing window gives one finite
    estimate per sample (was: ValueError, operands could not be broadcast together)."""
    rec = car.slice_time(0.0, car.t[n - 1] + 1e-6)
    tr = aided.estimate(rec, wheel_radius=0.31)
    assert len(tr) == n
    assert np.all(np.isfinite(tr.omega))


@pytest.mark.parametrize("params", [{"smooth": "none"}, {"smooth": "bogus"}, {"lag": "2"},
                                    {"smooth": "lag", "lag": 2.0, "causal": "true"}])
def test_aided_refuses_the_grid_smoothing_it_would_ignore(car, params):
    """``-m aided`` sets the grid's ``smooth`` itself (offline: smoothed; ``causal=true``:
    the causal filter); a ``smooth`` or ``lag`` given was dropped silently (``smooth=none``
    gave the smoothed estimate, ``smooth=bogus`` passed). Now one line pointing to
    ``causal=true``."""
    with pytest.raises(ParameterError, match=r"^(smooth|lag): .*causal=true") as err:
        aided.estimate(car, wheel_radius=0.31, params=params)
    assert "\n" not in str(err.value)


def test_aided_causal_is_still_the_way_to_the_causal_filter(car):
    """The documented switch differs from the offline default (so the refusal above points
    to something that does what ``smooth=none`` was meant to)."""
    off = aided.estimate(car, wheel_radius=0.31)
    on = aided.estimate(car, wheel_radius=0.31, params={"causal": "true"})
    assert on.params["causal"] is True and off.params["causal"] is False


def _gps_riss_sample():
    from vibrospeed.estimators import gps_riss

    n = 600
    t = np.arange(n) * 0.01
    rng = np.random.default_rng(1)
    accel = 0.5 * np.cos(0.5 * t) + 0.05 * rng.normal(size=n)
    gps = np.full(n, np.nan)
    gps[::10] = 10.0 + np.sin(0.5 * t[::10]) + 0.1 * rng.normal(size=gps[::10].size)
    return gps_riss, gps_riss.Sample(t, accel, gps, np.full(n, 9.0))


@pytest.mark.parametrize("field", ["accel", "gps_speed"])
def test_gps_riss_takes_an_infinite_sample_as_a_missing_one(field):
    """An inf accelerometer sample or GPS fix is no measurement, as NaN is: the same numbers
    as with NaN there, bitwise, and finite (was: every sample after an inf in ``accel`` NaN)."""
    gps_riss, s = _gps_riss_sample()
    cfg = gps_riss.Config()
    runs = []
    for bad in (np.inf, -np.inf, np.nan):
        x = np.array(getattr(s, field))
        x[[100, 250]] = bad
        runs.append(gps_riss.run(cfg, s._replace(**{field: x})))
    assert np.all(np.isfinite(runs[2].speed)) and np.all(np.isfinite(runs[2].speed_std))
    for r in runs[:2]:
        np.testing.assert_array_equal(r.speed, runs[2].speed)
        np.testing.assert_array_equal(r.speed_std, runs[2].speed_std)


def test_fuse_takes_an_infinite_gps_speed_as_no_fix():
    """``fuse.estimate`` with one GPS speed inf: the numbers of that fix NaN, bitwise (was:
    LinAlgError in the smoother, "Array must not contain infs or NaNs")."""
    from vibrospeed.estimators import fuse

    rec = sim.simulate("car", seed=1, duration=10.0)
    k = int(np.flatnonzero(np.isfinite(rec["gps_speed"]))[8])
    tracks = []
    for bad in (np.inf, np.nan):
        g = rec["gps_speed"].copy()
        g[k] = bad
        tracks.append(fuse.estimate(rec.with_channels(gps_speed=g), wheel_radius=0.31))
    assert np.all(np.isfinite(tracks[1].speed))
    np.testing.assert_array_equal(tracks[0].speed, tracks[1].speed)
    np.testing.assert_array_equal(tracks[0].speed_std, tracks[1].speed_std)


def test_grid_step_takes_an_infinite_sample_as_a_missing_one():
    """``grid.run`` (the numbers of ``step``) with an inf sample: those of a NaN there, bitwise,
    and a finite band throughout (was: the comb frames holding it read the inf as 1.8e308, an
    overflow, and omega_std NaN from then on)."""
    import dataclasses

    from vibrospeed.estimators import grid

    tr = dataclasses.replace(grid._default_tracker(0.01), n_grid=60, omega_min=10.0,
                             omega_max=60.0, smooth="none")
    cfg = grid.Config(tracker=tr)
    t = np.arange(600) * 0.01
    rng = np.random.default_rng(0)
    y = np.sin(30 * t) + 0.5 * np.sin(60 * t + 1.0) + 0.3 * rng.normal(size=t.size)
    runs = []
    for bad in (np.inf, -np.inf, np.nan):
        x = y.copy()
        x[50] = bad
        runs.append(grid.run(cfg, x))
    assert np.all(np.isfinite(runs[2].omega_std)) and np.all(np.isfinite(runs[2].omega_lo))
    for r in runs[:2]:
        for name in ("omega", "omega_std", "omega_lo", "omega_hi"):
            np.testing.assert_array_equal(getattr(r, name), getattr(runs[2], name))


@pytest.mark.parametrize("method", ["aided", "fuse", "algebraic"])
def test_a_wheel_radius_that_is_not_a_number_is_a_parameter_error(car, method):
    """As every other method (``types.check_wheel_radius``): one line naming wheel_radius
    (was: ValueError, "could not convert string to float: 'abc'")."""
    from vibrospeed import estimators

    with pytest.raises(ParameterError, match=r"^wheel_radius must be a number in m, got 'abc'$"):
        estimators.get(method).estimate(car, wheel_radius="abc", params={"L1": 1.2}
                                        if method == "algebraic" else {})


@pytest.mark.parametrize("params", [{"L1": "abc"}, {"L1": 1.2, "r": "abc"}])
def test_algebraic_text_l1_or_r_that_is_not_a_number_is_a_parameter_error(car, params):
    from vibrospeed.estimators import algebraic

    name = "r" if "r" in params else "L1"
    with pytest.raises(ParameterError, match=rf"^parameter '{name}': cannot read 'abc'"):
        algebraic.estimate(car, params=params)


def test_algebraic_reads_l1_and_r_as_text_as_numbers(car):
    """Text values (as ``-p`` gives them) are the numbers they say: the same Track."""
    from vibrospeed.estimators import algebraic

    a = algebraic.estimate(car, params={"L1": "1.2", "r": "0.31"})
    b = algebraic.estimate(car, params={"L1": 1.2}, wheel_radius=0.31)
    np.testing.assert_array_equal(a.speed, b.speed)


def _retimed(car, how: str):
    from vibrospeed.types import Recording

    t = car.t.copy()
    if how == "nan":
        t[100] = np.nan
    elif how == "repeated":
        t[100] = t[99]
    elif how == "swapped":
        t[100], t[101] = t[101], t[100]
    return Recording(t, dict(car.channels), source="api", wheel_radius=0.31)


@pytest.mark.parametrize("method", ["ekf", "grid", "shs", "aided", "fuse", "algebraic"])
@pytest.mark.parametrize("how", ["nan", "repeated", "swapped"])
def test_a_time_line_that_is_not_strictly_increasing_is_one_line_naming_the_sample(
        car, method, how):
    """A Recording built through the API with a NaN, a repeated or a swapped time: one
    InputError naming the sample (was: ValueError inside NumPy, "attempt to get argmin of an
    empty sequence" / "cannot convert float NaN to integer", or, for a repeated or swapped
    time, an estimate as if the time line were uniform)."""
    from vibrospeed import estimators
    from vibrospeed.errors import InputError

    rec = _retimed(car, how)
    want = 100 if how != "swapped" else 101
    with pytest.raises(InputError,
                       match=rf"^api, sample {want}: time .*; vibrospeed\.io\.sort_dedup ") as err:
        estimators.get(method).estimate(rec, params={"L1": 1.2} if method == "algebraic"
                                        else {})
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("method", ["gps-riss", "algebraic"])
def test_the_two_methods_that_take_a_time_line_with_a_gap(car, method):
    """docs/architecture.md: gps-riss filters on the time stamps and algebraic resamples, so
    a gap is no error for them (every other method refuses it, tests/test_gaps.py)."""
    from vibrospeed import estimators
    from vibrospeed.types import Recording

    keep = (car.t < 1.0) | (car.t >= 1.5)
    rec = Recording(car.t[keep], {k: v[keep] for k, v in car.channels.items()}, source="api")
    tr = estimators.get(method).estimate(rec, wheel_radius=0.31, axis="x" if
                                         method == "gps-riss" else None,
                                         params={"L1": 1.2} if method == "algebraic" else {})
    assert len(tr) == keep.sum() and np.isfinite(tr.speed[-100:]).all()
