"""Simulated GPS/accelerometer scenarios (sim/gps.py): channels, reproducibility, and that each
scenario contains what it claims (lag model, tunnel, slope offset, jumps, pitch)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from vibrospeed import ParameterError
from vibrospeed.models.gps_riss import GpsLagModel, simulate_receiver
from vibrospeed.sim import gps as sg


@pytest.mark.parametrize("name", list(sg.SCENARIOS))
def test_scenario_channels_and_seeding(name):
    rec = sg.scenario(name, np.random.default_rng(0), fs=100.0)
    assert set(rec.channels) == {"ax", "gps_speed", "gps_sats", "speed_true"}
    assert rec.units["gps_speed"] == "m/s" and rec.units["ax"] == "m/s^2"
    assert rec.is_uniform() and rec.fs == pytest.approx(100.0)
    assert np.all(np.isfinite(rec["ax"])) and np.all(rec["speed_true"] >= 0)
    fix = np.isfinite(rec["gps_speed"])
    assert fix.sum() / rec.duration == pytest.approx(12.5, rel=0.03)
    again = sg.scenario(name, np.random.default_rng(0), fs=100.0)
    other = sg.scenario(name, np.random.default_rng(1), fs=100.0)
    np.testing.assert_array_equal(rec["ax"], again["ax"])
    assert not np.array_equal(rec["ax"], other["ax"])


def test_accelerometer_model():
    rec = sg.hilly(np.random.default_rng(4), fs=200.0)
    resid = rec["ax"] - rec.meta["accel_true"] - rec.meta["offset_true"]
    assert abs(resid.mean()) < 0.01
    assert resid.std() == pytest.approx(rec.meta["acc_noise"], rel=0.03)
    off = 0.5 + 9.80665 * np.sin(rec.meta["slope_rad"])
    np.testing.assert_allclose(rec.meta["offset_true"], off)
    assert np.ptp(rec.meta["slope_rad"]) > 0.01
    # speed is the integral of the acceleration
    v = rec["speed_true"]
    dv = np.diff(v) * rec.fs
    np.testing.assert_allclose(dv, 0.5 * (rec.meta["accel_true"][1:] + rec.meta["accel_true"][:-1]))


def test_gps_is_the_lag_model_plus_noise():
    lag = GpsLagModel.from_wn_zeta(6.0, 0.5)
    rec = sg.braking(np.random.default_rng(2), fs=100.0, lag=lag)
    fix = np.isfinite(rec["gps_speed"])
    rx = simulate_receiver(rec.t, rec["speed_true"], lag)
    d = rec["gps_speed"][fix] - rx[fix]
    assert abs(d.mean()) < 0.03 and d.std() == pytest.approx(0.1, rel=0.15)
    # the raw GPS overshoots after braking: rx exceeds the true speed somewhere by > 0.3 m/s
    assert np.max(rx - rec["speed_true"]) > 0.3


def test_tunnel_drops_satellites_and_reports_zero():
    rec = sg.tunnel(np.random.default_rng(0), fs=100.0)
    t0, t1 = rec.meta["tunnel"]
    assert t1 - t0 == pytest.approx(5.0)
    inside = (rec.t >= t0) & (rec.t < t1)
    assert np.all(rec["gps_sats"][inside] == 0) and np.all(rec["gps_sats"][~inside] == 9)
    g = rec["gps_speed"][inside]
    assert np.all(g[np.isfinite(g)] == 0.0) and np.isfinite(g).sum() >= 60


def test_jumps_and_pitch():
    rec = sg.gps_jump(np.random.default_rng(0), fs=100.0)
    err = rec.meta["gps_error"]
    assert 2.0 < np.max(np.abs(err)) < 4.0
    assert 0.01 < np.mean(err != 0) < 0.1
    moto = sg.motorcycle(np.random.default_rng(0), fs=100.0)
    a = moto.meta["accel_true"]
    assert a.max() > 3.0 and a.min() < -4.0
    p = np.polyval(sg.PAPER_PITCH_POLY, a)
    assert np.std(moto.meta["pitch_deg"] - p) == pytest.approx(0.1, rel=0.05)


def test_unknown_scenario():
    with pytest.raises(ParameterError, match="unknown GPS scenario 'x'"):
        sg.scenario("x", np.random.default_rng(0))


@pytest.mark.parametrize("name", list(sg.SCENARIOS))
def test_duration_knob(name):
    rec = sg.scenario(name, np.random.default_rng(0), fs=50.0, duration=40.0)
    assert rec.duration == pytest.approx(40.0, abs=0.05)
    assert np.all(rec["speed_true"] >= 0)
    default = sg.scenario(name, np.random.default_rng(0), fs=50.0)
    assert default.duration == pytest.approx(180.0 if name == "gps_hilly" else 60.0, abs=0.05)
    if name == "gps_tunnel":
        t0, t1 = rec.meta["tunnel"]
        assert 0 < t0 < t1 < 40.0
    with pytest.raises(ParameterError, match="duration"):
        sg.scenario(name, np.random.default_rng(0), fs=50.0, duration=5.0)


def test_gps_delay_is_an_exact_shift():
    lag = GpsLagModel.from_wn_zeta(6.0, 0.5)
    rec = sg.braking(np.random.default_rng(2), fs=100.0, lag=lag, gps_delay=0.37,
                     gps_noise=0.0)
    fix = np.isfinite(rec["gps_speed"])
    rx = simulate_receiver(rec.t, rec["speed_true"], lag)
    shifted = np.interp(rec.t - 0.37, rec.t, rx)
    late = fix & (rec.t > 1.0)
    np.testing.assert_allclose(rec["gps_speed"][late], np.maximum(shifted[late], 0), atol=1e-9)
    assert rec.meta["gps_lag"]["delay"] == 0.37
    with pytest.raises(ParameterError, match="gps_delay"):
        sg.braking(np.random.default_rng(2), fs=100.0, gps_delay=-1.0)


def test_outage_gps_adds_gps_without_changing_the_drive():
    from vibrospeed.sim import simulate

    base = simulate("random", seed=11, duration=300.0, vehicle="car")
    model = sg.outage_gps(tunnel_duration=(40.0, 60.0), jumps=2, low_sats=1)
    rec = simulate("random", seed=11, duration=300.0, vehicle="car", gps_model=model)
    for name, x in base.channels.items():
        np.testing.assert_array_equal(rec[name], x)  # the other streams are untouched
    sats, g, t = rec["gps_sats"], rec["gps_speed"], rec.t
    tun = sats == 0
    assert np.isfinite(sats).all()
    spans = np.flatnonzero(np.diff(tun.astype(int)))
    assert spans.size in (1, 2)  # one tunnel (it may run to the end)
    length = tun.sum() / rec.fs
    assert 40.0 - 0.05 <= length <= 60.0 + 0.05
    assert not np.isfinite(g[tun]).any()
    t_in = t[np.flatnonzero(tun)[0]]
    assert t_in >= 60.0
    assert 10.0 <= rec["speed_true"][np.flatnonzero(tun)[0]] <= 30.0
    # fixes at ~10 Hz outside, weak sky 4-6 satellites somewhere, clear sky 6..14
    rate = np.isfinite(g[~tun]).sum() / ((~tun).sum() / rec.fs)
    assert 9.0 < rate < 10.5
    assert np.any((sats >= 4) & (sats <= 6))
    clear = ~tun & ~((sats >= 4) & (sats <= 6))
    assert sats[clear].min() >= 6 and sats[clear].max() <= 14
    # away from jumps and weak sky the fixes follow the paper receiver within the noise
    fix = np.isfinite(g) & clear
    rx = simulate_receiver(t, rec["speed_true"], GpsLagModel.paper())
    err = g[fix] - rx[fix]
    assert np.median(np.abs(err)) < 0.15
    assert np.sum(np.abs(err) > 1.5) > 0  # the receiver jumps
    again = simulate("random", seed=11, duration=300.0, vehicle="car", gps_model=model)
    np.testing.assert_array_equal(again["gps_speed"], g)


def test_fs_and_duration_given_as_text_are_read_as_numbers(tmp_path):
    # `vibrospeed simulate --scenario gps_braking --set fs=200` passes fs="200" (simulate's own
    # argument); it reached the builder as text and failed in np.isfinite (an internal error)
    from typer.testing import CliRunner

    from vibrospeed.cli.app import app
    from vibrospeed.sim import simulate

    a = simulate("gps_braking", seed=1, fs="200", duration="12")
    b = simulate("gps_braking", seed=1, fs=200.0, duration=12.0)
    assert a.fs == pytest.approx(200.0) and len(a) == 2400
    np.testing.assert_array_equal(a["ax"], b["ax"])
    with pytest.raises(ParameterError, match="parameter 'fs': cannot read 'abc' as float"):
        simulate("gps_braking", seed=1, fs="abc")
    out = tmp_path / "b.csv"
    res = CliRunner().invoke(app, ["simulate", "--scenario", "gps_braking", "--set", "fs=200",
                                   "--duration", "12", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "at 200 Hz" in res.stderr


@pytest.mark.parametrize(("knob", "value", "says"), [
    ("gps_rate", 0.0, "gps_rate must be > 0, got 0.0"),
    ("gps_rate", -1.0, "gps_rate must be > 0, got -1.0"),
    ("gps_noise", -1.0, "gps_noise must be finite and >= 0, got -1.0"),
    ("gps_jitter", -0.1, "gps_jitter must be finite and >= 0, got -0.1"),
    ("acc_noise", float("nan"), "acc_noise must be finite and >= 0, got nan"),
    ("acc_bias", float("inf"), "acc_bias must be finite, got inf"),
    ("lag", "abc", "lag must be a GpsLagModel (Python API; the command line sets gps_delay), "
                   "got 'abc'"),
])
def test_knobs_out_of_range_are_refused_naming_them(knob, value, says):
    # each was an internal error (ZeroDivisionError, NumPy's "scale < 0" / "high - low < 0",
    # "'str' object has no attribute 'delay'") or, acc_bias=inf, a recording of inf
    from vibrospeed.sim import simulate

    for name in ("gps_braking", "gps_tunnel"):
        with pytest.raises(ParameterError, match=re.escape(says) + "$"):
            simulate(name, seed=1, duration=30.0, **{knob: value})
    rec = simulate("gps_braking", seed=1, duration=30.0, gps_noise=0.0, acc_bias=-0.5)
    assert np.isfinite(rec["ax"]).all()  # the edges allowed
