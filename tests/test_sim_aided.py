"""Aided-tracking simulator scenarios: truth consistency, stops, bumps, turns, reproducibility."""

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.sim.aided import SCENARIOS, bump_response


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_scenario_channels_and_truth(name):
    rec = SCENARIOS[name](seed=3, duration=60)
    for ch in ("ax", "ay", "az", "gz", "omega_true", "speed_true"):
        assert rec[ch].shape == rec.t.shape and np.all(np.isfinite(rec[ch]))
    np.testing.assert_allclose(rec["speed_true"], rec["omega_true"] * rec.wheel_radius)
    assert rec.wheel_radius == 0.08 and round(rec.fs) == 100
    # the speed integrates the truth acceleration
    v = rec["speed_true"]
    dv = np.cumsum(rec["accel_true"]) * rec.dt
    assert np.max(np.abs(v - v[0] - (dv - dv[0]))) < 0.02
    # standstill at the start; stops listed where the truth is 0
    a, b = rec.meta["stops"][0]
    assert a == rec.t[0] and b >= 2.9
    for a, b in rec.meta["stops"]:
        i = (rec.t >= a) & (rec.t <= b)
        assert np.all(rec["omega_true"][i] == 0)
    # same seed, same data; another seed differs
    again = SCENARIOS[name](seed=3, duration=60)
    np.testing.assert_array_equal(again["ay"], rec["ay"])
    assert not np.array_equal(SCENARIOS[name](seed=4, duration=60)["ay"], rec["ay"])


def test_stop_and_go_has_several_stops():
    rec = SCENARIOS["stop_and_go"](seed=0)
    assert len(rec.meta["stops"]) >= 4
    # the cart pushes harder than the mode detector's threshold
    assert np.max(np.abs(rec["accel_true"])) >= 0.4


def test_sudden_change_size():
    rec = SCENARIOS["sudden_change"](seed=1, omega_change=5.0)
    w = rec["omega_true"]
    assert w.max() - np.median(w[w > 1]) == pytest.approx(5.0, abs=1.6)


def test_bumps_front_then_rear():
    rec = SCENARIOS["bumpy_floor"](seed=2)
    bumps = np.array(rec.meta["bumps"])
    assert len(bumps) >= 5
    L = rec.meta["wheelbase"]
    # dT = L / v at cruise (exact distances): v * dT ~ L
    dT = bumps[:, 1] - bumps[:, 0]
    np.testing.assert_allclose(bumps[:, 2] * dT, L, rtol=0.02)
    # the az shock is there: |az - g| peaks near each front hit
    k = np.searchsorted(rec.t, bumps[0, 0])
    assert np.abs(rec["az"][k : k + 3] - 9.80665).max() > 0.5 * 1.5


def test_bump_response_shape():
    t = np.arange(100) * 0.01
    x = bump_response(t, np.array([0.2]), 2.0, 18.0, 0.03)
    assert x[:20].max() == 0 and x[20] == pytest.approx(2.0)
    assert np.abs(x[40:]).max() < 2.0 * np.exp(-0.2 / 0.03) * 1.01


def test_turns_kinematics():
    rec = SCENARIOS["turns"](seed=5)
    assert len(rec.meta["turns"]) >= 3
    yaw = rec["yaw_rate_true"]
    assert np.abs(yaw).max() > 0.2
    # ay carries v * yaw rate (low-passed ay vs truth, vibrations average out over 1 s)
    n = 100
    k = np.ones(n) / n
    a = np.convolve(rec["ay"], k, mode="valid")
    c = np.convolve(rec["speed_true"] * yaw, k, mode="valid")
    slope, offset = np.polyfit(c, a, 1)
    assert slope == pytest.approx(1.0, abs=0.05)


def test_overrides_and_errors():
    rec = SCENARIOS["start_from_rest"](seed=0, duration=20, omega_cruise=6.0, omega_spread=0.5)
    assert 5.4 < rec["omega_true"].max() < 6.6
    with pytest.raises(ParameterError):
        SCENARIOS["stop_and_go"](seed=0, bogus=1)
    with pytest.raises(ParameterError):
        SCENARIOS["sudden_change"](seed=0, duration=12)
