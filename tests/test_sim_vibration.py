"""Vibration building blocks: OU amplitudes, fades, gears, resonators, anti-alias response."""

from __future__ import annotations

import numpy as np
import pytest

from vibrospeed.sim import EngineConfig, VibrationConfig, simulate
from vibrospeed.sim.vibration import (
    _resonator_noise,
    aa_gain,
    fade_gain,
    ou_process,
    select_gears,
)


def test_ou_stationary_statistics():
    dt, tau, std = 0.01, 0.5, 0.3
    u = ou_process(100_000, dt, tau, std, np.random.default_rng(0), (4,))
    assert u.shape == (4, 100_000)
    assert u.std() == pytest.approx(std, rel=0.05)
    phi = np.exp(-dt / tau)
    r1 = np.mean(u[:, 1:] * u[:, :-1]) / np.mean(u * u)
    assert r1 == pytest.approx(phi, abs=2e-3)


def test_fade_gain_shape():
    cfg = VibrationConfig(fade_duration=(4.0, 4.0), fade_ramp=0.5, fade_depth=0.2)
    t = np.arange(0, 600, 0.01)
    g, events = fade_gain(t, 600.0, 2.0, cfg, np.random.default_rng(1))
    assert len(events) > 5
    assert g.min() == pytest.approx(0.2) and g.max() == 1.0
    for e in events:
        mid = np.abs(t - (e["t_start"] + 2.0)) < 1.0
        assert np.all(g[mid] == pytest.approx(0.2))


def test_gears_hysteresis_on_ramp():
    eng = EngineConfig()
    omega = np.concatenate([np.linspace(5, 110, 5000), np.linspace(110, 5, 5000)])
    gear = select_gears(omega, eng)
    shifts = np.flatnonzero(np.diff(gear))
    G = len(eng.gear_ratios)
    assert shifts.size == 2 * (G - 1)  # up through every gear and down again, no chatter
    rpm = omega * np.asarray(eng.gear_ratios)[gear] * eng.final_drive * 60 / (2 * np.pi)
    up = shifts[: G - 1]
    down = shifts[G - 1:]
    # up-shifts happen as the engine crosses upshift_rpm, down-shifts at downshift_rpm
    assert np.all(np.abs(rpm[up] - eng.upshift_rpm) < 30)
    assert np.all(np.abs(rpm[down] - eng.downshift_rpm) < 30)
    inner = (gear > 0) & (gear < G - 1)
    assert np.all((rpm[inner] >= eng.downshift_rpm - 30) & (rpm[inner] <= eng.upshift_rpm + 30))


def test_resonator_unit_variance_and_peak():
    fs, f0 = 100.0, 14.0
    x = _resonator_noise(60_000, fs, f0, 15.0, np.random.default_rng(2), 2)
    assert x.std() == pytest.approx(1.0, rel=0.05)
    spec = np.abs(np.fft.rfft(x[0])) ** 2
    f = np.fft.rfftfreq(x.shape[1], 1 / fs)
    smooth = np.convolve(spec, np.ones(200) / 200, mode="same")
    assert f[np.argmax(smooth)] == pytest.approx(f0, abs=0.3)


def test_aa_gain():
    cfg = VibrationConfig(aa_cutoff=0.4, aa_order=4)
    g = aa_gain(np.array([0.0, 40.0, 80.0]), 100.0, cfg)
    np.testing.assert_allclose(g, [1.0, 2**-0.5, 1 / np.sqrt(1 + 2.0**8)])
    assert np.all(aa_gain(np.array([100.0]), 100.0, VibrationConfig(aa_order=0)) == 1.0)


def test_cart_standstill_is_sensor_noise_only():
    """No rotation, no vibration: at rest the cart's y axis is bias + white noise."""
    rec = simulate("cart", seed=9, duration=60.0)
    still = rec["omega_true"] == 0
    still &= np.roll(still, 50) & np.roll(still, -50)
    assert still.sum() > 200
    assert rec["ay"][still].std() == pytest.approx(0.02, rel=0.15)
    moving = rec["omega_true"] > 5
    assert rec["ay"][moving].std() > 5 * 0.02
