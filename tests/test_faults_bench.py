"""The fault injections of benchmarks/faults.py do what its docstring says, and its accuracy
maps output rows back to true time (a fault that moves the stamps must not move the truth)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from vibrospeed.types import Recording, Track

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
faults = pytest.importorskip("faults")

FS = 100.0


def drive(seconds=600.0):
    t = np.arange(int(seconds * FS)) / FS
    rng = np.random.default_rng(0)
    ch = {k: rng.normal(size=t.size) for k in faults.IMU}
    ch["az"] = ch["az"] + 9.81
    omega = 30.0 + 10.0 * np.sin(2 * np.pi * t / 20.0)
    return Recording(t, {**ch, "omega_true": omega})


def f(name):
    return faults.fault(name, drive(), np.random.default_rng(1))


def test_time_faults():
    gap = f("time_gap")
    assert not ((gap.t >= 240) & (gap.t < 270)).any() and gap.t.size == 60000 - 3000
    dup = f("dup_stamps")
    assert dup.t.size == 60100 and np.count_nonzero(np.diff(dup.t) == 0) == 100
    back = f("backward")
    assert np.count_nonzero(np.diff(back.t) < 0) == 20
    assert np.array_equal(np.sort(back.t), drive().t)
    rate = f("rate_change")
    d = np.diff(rate.t)
    np.testing.assert_allclose(d[rate.t[1:] < 300], 0.01, atol=1e-9)
    np.testing.assert_allclose(d[rate.t[:-1] > 300.5], 0.02, atol=1e-9)
    jump = f("clock_jump")
    assert np.count_nonzero(np.diff(jump.t) > 5.0) == 1
    np.testing.assert_array_equal(jump.true_t, drive().t)
    drift = f("rate_drift")
    d = np.diff(drift.t)
    assert d[0] == pytest.approx(0.01, rel=1e-3) and d[-1] == pytest.approx(0.0102, rel=1e-3)


def test_signal_faults():
    rec = drive()
    win = (rec.t >= 240) & (rec.t < 300)
    nan = f("nan_bursts")
    assert np.isnan(nan.ch["ay"]).sum() == 600 and not np.isnan(nan.ch["ay"][~win]).any()
    stuck = f("stuck")
    m = (rec.t >= 250) & (rec.t < 270)
    assert np.unique(stuck.ch["ay"][m]).size == 1
    spikes = f("spikes")
    hit = spikes.ch["ay"] != rec["ay"]
    assert hit.sum() == 60 and hit[win].sum() == 60  # 1 % of the window
    sat = f("saturation")
    assert sat.ch["az"].max() == pytest.approx(faults.G0)
    flipped = f("flipped")
    late = rec.t >= 300
    np.testing.assert_array_equal(flipped.ch["ay"][late], -rec["ay"][late])
    np.testing.assert_array_equal(flipped.ch["ax"], rec["ax"])
    q = f("quant8")
    step = 4 * faults.G0 / 256
    np.testing.assert_allclose(np.round(q.ch["ay"] / step) * step, q.ch["ay"], atol=1e-12)


def test_accuracy_maps_stamps_back_to_true_time():
    rec = drive()
    jump = f("clock_jump")
    w = rec["omega_true"]
    # an estimator that is exactly right at every row, rows stamped as the file says
    tr = Track.from_omega(jump.t, w.copy())
    nan, out, inside = faults.accuracy(tr, jump, rec.t, w)
    assert (nan, out, inside) == (0.0, 1.0, 1.0)
    # the same values read against the stamps as if they were true time: mostly wrong
    naive = faults.Faulted(jump.t, jump.t, {}, jump.window)
    assert faults.accuracy(tr, naive, rec.t, w)[1] < 0.9
