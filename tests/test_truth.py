"""Cog-wheel ticks -> ground-truth omega (thesis appendix B.4) and the ticks CSV reader."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.errors import InputError, ParameterError, ReaderError
from vibrospeed.eval.truth import read_ticks, remove_spikes, ticks_to_truth

N_COGS, R_S, R_W = 12, 0.0625, 0.08


def _accelerating_wheel(w0, a, n_ticks, n_cogs=N_COGS):
    """Exact tick times of a sensor wheel with angle w0 t + a t^2 / 2 crossing 2 pi k / n_cogs."""
    theta = 2 * np.pi * np.arange(n_ticks) / n_cogs
    if a == 0:
        return theta / w0
    return (-w0 + np.sqrt(w0**2 + 2 * a * theta)) / a


def test_constant_speed_exact():
    w_sensor = 12.8
    rec = ticks_to_truth(_accelerating_wheel(w_sensor, 0.0, 60))
    np.testing.assert_allclose(rec["omega_true"], w_sensor * R_S / R_W, rtol=1e-12)
    np.testing.assert_allclose(rec["speed_true"], w_sensor * R_S, rtol=1e-12)
    assert rec.wheel_radius == R_W and rec.meta["n_spikes"] == 0


def test_uniform_acceleration_exact_at_midpoints():
    # mean angular speed over an interval = speed at its middle when the acceleration is constant
    w0, a = 5.0, 1.7
    ticks = _accelerating_wheel(w0, a, 300)
    rec = ticks_to_truth(ticks)
    tm = 0.5 * (ticks[1:] + ticks[:-1])
    np.testing.assert_allclose(rec.t, tm, rtol=1e-13)
    np.testing.assert_allclose(rec["omega_true"], (w0 + a * tm) * R_S / R_W, rtol=1e-9)


def test_missed_cogs_are_single_sample_spikes():
    w0, a = 8.0, 0.5
    ticks = _accelerating_wheel(w0, a, 200)
    missed = [40, 97, 150]
    rec = ticks_to_truth(np.delete(ticks, missed))
    assert rec.meta["n_spikes"] == 3
    truth = (w0 + a * rec.t) * R_S / R_W
    err = np.abs(rec["omega_true"] - truth)
    spike_pos = [m - 1 - i for i, m in enumerate(missed)]  # merged interval's index
    ok = np.ones(rec.t.size, bool)
    ok[spike_pos] = False
    np.testing.assert_allclose(rec["omega_true"][ok], truth[ok], rtol=1e-9)
    # replaced values: mean of neighbours, within the curvature of the interpolation
    assert np.all(err[spike_pos] < 0.01 * truth[spike_pos])
    # without spike removal the merged interval reads about half the speed
    raw = ticks_to_truth(np.delete(ticks, missed), spike_rel=0)
    assert raw["omega_true"][spike_pos[0]] == pytest.approx(truth[spike_pos[0]] / 2, rel=0.01)


def test_remove_spikes_definition():
    w = np.array([10.0, 10.0, 30.0, 10.0, 10.0, 5.0, 10.0, 12.0, 14.0])
    out, mask = remove_spikes(w, 0.3)
    np.testing.assert_array_equal(mask, [0, 0, 1, 0, 0, 1, 0, 0, 0])
    np.testing.assert_allclose(out, [10, 10, 10, 10, 10, 10, 10, 12, 14])


def test_stop_gap_gives_zero():
    ticks = np.concatenate([np.arange(30) * 0.04, 5.0 + np.arange(30) * 0.04])
    rec = ticks_to_truth(ticks, max_gap=0.5)
    w = np.interp([2.0, 3.0, 4.0], rec.t, rec["omega_true"])
    np.testing.assert_array_equal(w, 0.0)
    assert np.all(np.diff(rec.t) > 0)


def test_simulated_cart_ticks_match_truth():
    from vibrospeed.sim import simulate

    sim = simulate("cart", seed=4, duration=40)
    rec = ticks_to_truth(sim.events["wss_ticks"], n_cogs=sim.meta["ticks_n_cogs"],
                         r_sensor=sim.meta["ticks_radius"], r_wheel=sim.wheel_radius)
    w = np.interp(rec.t, sim.t, sim["omega_true"])
    moving = rec["omega_true"] > 2.0
    assert moving.sum() > 300
    assert np.max(np.abs(rec["omega_true"][moving] - w[moving])) < 0.1


def test_bad_ticks():
    with pytest.raises(InputError, match="back in time"):
        ticks_to_truth(np.array([0.0, 0.1, 0.05, 0.2]))
    with pytest.raises(ParameterError):
        ticks_to_truth(np.arange(5.0), n_cogs=0)
    with pytest.raises(InputError):
        ticks_to_truth(np.array([1.0]))


def test_read_ticks(tmp_path):
    p = tmp_path / "ticks.csv"
    p.write_text("time_s\n0.0\n0.04\n\n0.08\n")
    np.testing.assert_array_equal(read_ticks(p), [0.0, 0.04, 0.08])
    p.write_text("0\n40\n80\n")
    np.testing.assert_allclose(read_ticks(p, scale=1e-3), [0.0, 0.04, 0.08])
    p.write_text("t\n0.0\nabc\n")
    with pytest.raises(ReaderError, match="line 3"):
        read_ticks(p)
    p.write_text("0.0\n0.5\n0.2\n")
    with pytest.raises(ReaderError, match="line 3.*backwards"):
        read_ticks(p)
    p.write_text("0.0,1\n")
    with pytest.raises(ReaderError, match="one column"):
        read_ticks(p)
    with pytest.raises(ReaderError, match="not found"):
        read_ticks(tmp_path / "missing.csv")


@given(st.lists(st.floats(1e-3, 10.0), min_size=2, max_size=50))
@settings(max_examples=50, deadline=None)
def test_read_ticks_round_trip(tmp_path_factory, gaps):
    ticks = np.cumsum(gaps)
    p = tmp_path_factory.mktemp("t") / "ticks.csv"
    p.write_text("t\n" + "\n".join(repr(float(v)) for v in ticks) + "\n")
    np.testing.assert_array_equal(read_ticks(p), ticks)
