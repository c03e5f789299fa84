"""A vehicle tester's walkthrough: evaluation against references with gaps and other radii,
``fuse``'s radius carried between drives (``radius_from``): numbers against hand-computed ones."""

import json
import re

import numpy as np
import pytest

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import fuse
from vibrospeed.estimators.fuse import method as fuse_method
from vibrospeed.eval.metrics import evaluate
from vibrospeed.types import Recording, Track

# -- evaluate ------------------------------------------------------------------------------------


def test_a_dropped_reference_is_no_truth_not_a_straight_line():
    """A 10 s stretch of NaN in a 10 Hz reference (10 m/s before, 30 m/s after) is not bridged:
    the estimate there (held at 10 m/s) is not scored against a made-up 10 -> 30 ramp."""
    t = np.arange(0.0, 30.0, 0.1)
    v = np.where(t < 20.0, 10.0, 30.0)
    ref = np.where((t >= 10.0) & (t < 20.0), np.nan, v)
    truth = Recording(t, {"speed_true": ref}, source="ref.csv")
    est = Track.from_speed(t, np.where(t < 20.0, 10.0, 30.0) + 0.2, np.full(t.size, 0.1))
    m = evaluate(est, truth)
    assert m.unit == "m/s"
    assert m.n == 200  # the 100 samples of the gap are not scored (before: all 300)
    assert m.rmse == pytest.approx(0.2)
    assert m.bias == pytest.approx(0.2)


def test_a_short_nan_run_in_the_reference_is_still_bridged():
    """Two NaN samples in a 100 Hz reference (3 periods < 5) are interpolated as before."""
    t = np.arange(0.0, 2.0, 0.01)
    ref = 5.0 + t
    ref[50:52] = np.nan
    truth = Recording(t, {"speed_true": ref})
    m = evaluate(Track.from_speed(t, 5.0 + t, np.full(t.size, 0.1)), truth)
    assert m.n == t.size and m.rmse == pytest.approx(0.0, abs=1e-12)


def test_rmse_speed_is_the_speed_error_when_the_track_has_another_radius():
    """A fuse track whose learned radius (0.1 m) is not the truth's wheel (0.3 m): its speed is
    0.5 m/s high throughout, so the speed RMSE is 0.5 m/s, whatever its omega column says
    (before: the omega error times 0.1 m, 2.2 m/s here)."""
    t = np.arange(0.0, 10.0, 0.1)
    v = 10.0 + t
    truth = Recording(t, {"omega_true": v / 0.3, "speed_true": v}, wheel_radius=0.3)
    est = Track.from_speed(t, v + 0.5, np.full(t.size, 0.2), wheel_radius=0.1)
    m = evaluate(est, truth)
    assert m.unit == "rad/s"  # scored as wheel speeds (the truth has omega_true)
    assert m.rmse_speed == pytest.approx(0.5)
    # omega_true with the truth's radius, no speed_true: the same
    truth2 = Recording(t, {"omega_true": v / 0.3}, wheel_radius=0.3)
    assert evaluate(est, truth2).rmse_speed == pytest.approx(0.5)



def test_a_speed_only_estimate_against_omega_truth_with_its_radius():
    """A GPS/accelerometer estimate (speed only, no radius) against a truth of omega_true and
    the truth's wheel radius (0.3 m) is scored as speeds (was: "nothing to compare"); without
    that radius it is one line saying what is missing."""
    t = np.arange(0.0, 10.0, 0.1)
    v = 10.0 + t
    est = Track.from_speed(t, v - 0.3, np.full(t.size, 0.2))
    m = evaluate(est, Recording(t, {"omega_true": v / 0.3}, wheel_radius=0.3))
    assert m.unit == "m/s" and m.n == t.size
    assert m.rmse == pytest.approx(0.3) and m.bias == pytest.approx(-0.3)
    with pytest.raises(InputError, match="speeds only.*omega_true without a wheel radius"):
        evaluate(est, Recording(t, {"omega_true": v / 0.3}, source="ref.csv"))


@pytest.mark.parametrize(("channel", "unit"), [("gps_sats", "1"), ("ax", "m/s^2")])
def test_a_truth_channel_that_is_not_a_speed_is_refused(channel, unit):
    """--truth-channel takes a speed in m/s: a satellite count or an acceleration was scored as
    one (RMSE in 'm/s' of a count)."""
    t = np.arange(0.0, 10.0, 0.1)
    truth = Recording(t, {"speed_true": np.full(t.size, 10.0), "gps_sats": np.full(t.size, 9.0),
                          "ax": np.zeros(t.size)}, source="drive.csv")
    est = Track.from_speed(t, np.full(t.size, 10.0), np.full(t.size, 0.2))
    with pytest.raises(InputError, match=re.escape(f"'{channel}' is in {unit}, not a speed")):
        evaluate(est, truth, truth_channel=channel)
    assert evaluate(est, truth, truth_channel="speed_true").rmse == 0.0

# -- fuse: the radius of an earlier drive (radius_from) ------------------------------------------

def _sidecar(tmp_path, name, obj):
    p = tmp_path / name
    p.write_text(json.dumps(obj))
    return p


def _drive(T=30.0, fs=200.0, r=0.3, gps=True, seed=0):
    """A drive with a 3-harmonic wheel line of radius ``r`` on ay, the acceleration on ax and,
    with ``gps``, 10 Hz GPS speed (the speed itself, 9 satellites)."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    v = 12.0 + 3.0 * np.sin(2 * np.pi * t / 20.0)
    phase = np.cumsum(v / r) / fs
    ay = np.sin(phase) + 0.5 * np.sin(2 * phase) + 0.3 * np.sin(3 * phase)
    ch = {"ax": np.gradient(v, t) + 0.1 * rng.normal(size=t.size),
          "ay": ay + 0.3 * rng.normal(size=t.size), "az": 9.81 + 0.1 * rng.normal(size=t.size)}
    if gps:
        g = np.full(t.size, np.nan)
        g[::20] = v[::20]
        ch.update(gps_speed=g, gps_sats=np.full(t.size, 9.0))
    return Recording(t, ch, source="drive.csv")


def test_radius_file_of_another_method_or_never_learned(tmp_path):
    """Another method's sidecar: its given wheel radius (said so), or one line where it has
    none; a fuse sidecar whose radius was never learned (the 0.3 +- 0.15 m prior) is refused
    for a drive without GPS instead of integrating the accelerometer for the whole drive."""
    gr = _sidecar(tmp_path, "gr.csv.json", {"kind": "track", "method": "gps-riss",
                                            "wheel_radius": None, "params": {}})
    with pytest.raises(InputError, match="gps-riss estimate's sidecar holds no learned radius"):
        fuse.radius_from_json(gr)
    alg = _sidecar(tmp_path, "alg.csv.json", {"kind": "track", "method": "algebraic",
                                              "wheel_radius": 0.31, "params": {"L1": 1.2}})
    assert fuse_method._read_radius(alg) == (0.31, pytest.approx(0.0031), "algebraic")
    unlearned = _sidecar(tmp_path, "h.csv.json", {
        "kind": "track", "method": "fuse", "wheel_radius": None,
        "params": {"learned_radius": 0.3, "learned_radius_std": 0.15}})
    with pytest.raises(ParameterError, match="no learned radius.*needs a radius"):
        fuse.estimate(_drive(T=2.0, gps=False), radius_from=unlearned)


def test_radius_prior_outside_the_range_fuse_reads_lines_in_is_refused(tmp_path):
    """A 2.5 m radius (outside radius_min..radius_max, 0.03-1 m) rejected every wheel line in
    silence; now one line, from a file or --wheel-radius; -p radius_max= accepts it."""
    big = _sidecar(tmp_path, "big.json", {"wheel_radius": 2.5})
    with pytest.raises(ParameterError, match="2.5 m is outside radius_min..radius_max"):
        fuse.estimate(_drive(T=2.0, gps=False), radius_from=big)
    with pytest.raises(ParameterError, match="outside radius_min"):
        fuse.estimate(_drive(T=2.0), wheel_radius=1.5)


def test_a_prior_the_lines_seen_with_gps_contradict_gets_a_note():
    """The lines with good fixes put the radius at GPS speed / line (0.3 m here, at any of the
    octaves 1/2, 1, 2): a prior of 0.089 m (a kart's, on a car) gets the note, 0.3 m or its
    octave 0.15 m do not, nor fewer than 1 s of lines."""
    t = np.arange(0.0, 10.0, 0.04)
    v = 10.0 + t
    arrays = {"t": t, "gps_speed": v, "omega": v / 0.3, "line": np.ones(t.size, bool)}
    fixes = np.ones(t.size, bool)
    note = fuse_method._prior_mismatch(arrays, fixes, 0.089, 0.0005)
    assert len(note) == 1 and "radius at 0.3000 m" in note[0] and "0.0890" in note[0]
    assert fuse_method._prior_mismatch(arrays, fixes, 0.3, 0.003) == []
    assert fuse_method._prior_mismatch(arrays, fixes, 0.15, 0.0015) == []
    assert fuse_method._prior_mismatch(arrays, fixes & (t < 0.9), 0.089, 0.0005) == []


@pytest.mark.slow
def test_another_vehicles_radius_on_a_drive_with_gps_is_named():
    """End to end: a 0.089 m prior on a 0.3 m car keeps the prior (the lines disagree) and
    says so; the car's own radius gives no such note."""
    rec = _drive()
    rng = {"omega_min": 10.0, "omega_max": 120.0}
    tr = fuse.estimate(rec, params=rng, wheel_radius=0.089)
    assert any("put the radius at 0.30" in n for n in tr.notes)
    assert tr.params["learned_radius"] == pytest.approx(0.089, rel=0.02)
    tr = fuse.estimate(rec, params=rng, wheel_radius=0.3)
    assert not any("put the radius at" in n for n in tr.notes)



@pytest.mark.slow
def test_another_vehicles_radius_without_gps_leaves_every_line_unused_and_says_so():
    """The simulated car (0.31 m) without GPS: with a kart's 0.089 m no line is used and a note
    says why the speed is the accelerometer's; with its own radius most samples use one."""
    from vibrospeed import sim

    car = sim.simulate("car", seed=1, duration=90.0)
    nogps = Recording(car.t, {k: car[k] for k in ("ax", "ay", "az")}, source="car.csv")
    tr = fuse.estimate(nogps, wheel_radius=0.089)
    assert np.all(tr.extras["source"] != fuse.SRC_VIBRATION)
    assert any("none fits the radius 0.0890 m" in n for n in tr.notes)
    tr = fuse.estimate(nogps, wheel_radius=0.31)
    assert np.mean(tr.extras["source"] == fuse.SRC_VIBRATION) > 0.5
    assert not any("none fits the radius" in n for n in tr.notes)


# -- plot / report ---------------------------------------------------------------------------------

@pytest.mark.parametrize("rows", [0, 1])
def test_plot_and_report_of_an_estimate_without_a_value_are_refused(tmp_path, rows):
    """A header-only estimate (or one row of NaN) gave a page with 'method ?' and empty numbers
    and a figure without an estimate, exit status 0; now one line, and nothing is written."""
    from vibrospeed.eval.plot import plot_track
    from vibrospeed.eval.report import write_report

    t = np.arange(0.0, 5.0, 0.01)
    rec = Recording(t, {"ay": np.sin(60.0 * t)}, source="drive.csv")
    est = Track.from_omega(np.arange(float(rows)), np.full(rows, np.nan))
    with pytest.raises(InputError, match="est.csv: no finite omega or speed in its"):
        write_report(tmp_path / "r.html", rec, est, axis="ay", estimate_path="est.csv")
    with pytest.raises(InputError, match="nothing to draw"):
        plot_track(tmp_path / "p.png", rec, est, axis="ay")
    assert list(tmp_path.iterdir()) == []


def test_report_says_why_the_truth_was_not_compared():
    """A truth that does not overlap the estimate (a reference 1000 s later) gave the rows
    'RMSE against the truth –' as if a number were missing; now one row says why."""
    from vibrospeed.eval.report import render_report

    t = np.arange(0.0, 5.0, 0.01)
    rec = Recording(t, {"ay": np.sin(60.0 * t)}, source="drive.csv")
    est = Track.from_speed(t, np.full(t.size, 10.0), np.full(t.size, 0.1))
    late = Recording(t + 1000.0, {"speed_true": np.full(t.size, 10.0)}, source="ref.csv")
    page = render_report(rec, est, axis="ay", truth=late)
    assert "not compared: no moving truth sample (1000-1004.99 s)" in page
    assert "RMSE against the truth" not in page
    same = Recording(t, {"speed_true": np.full(t.size, 10.0)})
    page = render_report(rec, est, axis="ay", truth=same)
    assert "RMSE against the truth" in page and "not compared" not in page
