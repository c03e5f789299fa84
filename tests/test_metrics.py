"""Evaluation metrics against hand-computed values."""

import numpy as np
import pytest

from vibrospeed.eval.metrics import compare, interp_truth, time_to_lock
from vibrospeed.types import Track


def _track(t, om, std=None, r=None):
    return Track.from_omega(t, om, std, wheel_radius=r, method="x")


def test_rmse_bias_against_linear_interpolated_truth():
    t_truth = np.array([0.0, 10.0])
    w_truth = np.array([10.0, 20.0])  # linear ramp: truth(t) = 10 + t
    t = np.arange(0.0, 10.0, 0.5)
    est = 10 + t + np.where(np.arange(t.size) % 2 == 0, 1.0, -3.0)  # errors +1, -3
    m = compare(_track(t, est, np.full(t.size, 1.0), r=0.5), t_truth, w_truth)
    assert m.n == t.size
    assert m.bias == pytest.approx(-1.0)
    assert m.rmse == pytest.approx(np.sqrt((1 + 9) / 2))
    assert m.mae == pytest.approx(2.0)
    assert m.rmse_speed == pytest.approx(0.5 * np.sqrt(5))
    # band +-2.326 std: the +1 errors are covered, the -3 are not
    assert m.coverage == pytest.approx(0.5)
    rel = np.where(np.arange(t.size) % 2 == 0, 1.0, 3.0) / (10 + t)
    assert m.rel_error == pytest.approx(rel.mean())
    assert m.rel_error_median == pytest.approx(np.median(rel))


def test_median_relative_error_is_not_ruled_by_the_slow_samples():
    # 95 samples within 1 % at 20 rad/s, 5 at 1.5 rad/s guessed at 15: the mean relative error
    # is 45.9 %, the typical one 1 %
    t = np.arange(100.0)
    truth = np.where(t < 95, 20.0, 1.5)
    est = np.where(t < 95, 20.2, 15.0)
    m = compare(_track(t, est), t, truth)
    assert m.rel_error == pytest.approx((95 * 0.01 + 5 * 9.0) / 100)
    assert m.rel_error_median == pytest.approx(0.01)


def test_standstill_and_warmup_excluded():
    t = np.arange(0, 10, 0.1)
    truth = np.where(t < 5, 0.0, 10.0)
    est = np.where(t < 5, 7.0, 10.0)  # wrong while standing: must not count
    m = compare(_track(t, est), t, truth, warmup=1.0)
    assert m.rmse == 0.0
    assert m.moving_share == pytest.approx(50 / 90)


def test_harmonic_shares():
    t = np.arange(100.0)
    truth = np.full(100, 20.0)
    est = np.r_[np.full(30, 10.0), np.full(20, 40.0), np.full(50, 20.0)]
    m = compare(_track(t, est), t, truth)
    assert m.half_share == pytest.approx(0.3)
    assert m.double_share == pytest.approx(0.2)


def test_interp_outside_span_is_nan_and_time_to_lock():
    out = interp_truth(np.array([1.0, 2.0]), np.array([1.0, 3.0]), np.array([0.0, 1.5, 3.0]))
    assert np.isnan(out[0]) and out[1] == 2.0 and np.isnan(out[2])
    t = np.arange(10.0)
    est = np.array([0, 0, 5, 5, 9, 10, 10, 10, 10, 10.0])
    assert time_to_lock(t, est, np.full(10, 10.0)) == 4.0
    assert time_to_lock(t, np.zeros(10), np.full(10, 10.0)) == np.inf


def test_ok_share_and_claimed_scores():
    t = np.arange(10.0)
    truth = np.full(10, 50.0)
    est = np.array([50, 54, 56, 50, 50, 80, 80, 50, 50, 50.0])  # ok within 5 rad/s (10 %)
    tr = Track.from_omega(t, est, np.full(10, 1.0), method="x",
                          extras={"has_signal": np.r_[np.ones(5), np.zeros(2), np.ones(3)]})
    m = compare(tr, t, truth)
    assert m.ok_share == pytest.approx(0.7)
    assert m.claimed_share == pytest.approx(0.8)
    assert m.ok_claimed == pytest.approx(7 / 8)
    assert m.rmse_claimed == pytest.approx(np.sqrt((16 + 36) / 8))



def test_no_evidence_note_names_no_gps():
    """A track with nothing measured while moving: the note says no wheel line was claimed;
    "no GPS seen" was false for grid (which reads no GPS) on a recording with GPS. The same
    note for fuse, whose summary gives its source shares, and in batch's rows."""
    import math

    from vibrospeed.batch import task
    from vibrospeed.eval.metrics import NO_EVIDENCE_NOTE, track_summary

    assert NO_EVIDENCE_NOTE.startswith("no wheel line claimed while moving") \
        and "GPS" not in NO_EVIDENCE_NOTE
    t = np.arange(100) * 0.1
    tr = _track(t, np.full(100, 40.0), r=0.3)
    tr.extras["has_signal"] = np.zeros(100)
    got = track_summary(tr)
    assert got["note"] == NO_EVIDENCE_NOTE and math.isnan(got["distance_m"])
    tr.extras["source"] = np.zeros(100)  # fuse: the accelerometer alone on every sample
    got = track_summary(tr)
    assert got["note"] == NO_EVIDENCE_NOTE and math.isnan(got["median_speed"])
    assert got["source_shares"]["accelerometer"] == 1.0
    assert task.NO_EVIDENCE_NOTE == NO_EVIDENCE_NOTE


def test_interp_truth_leaves_gaps_over_max_gap_empty():
    tt = np.array([0.0, 1.0, 2.0, 10.0, 11.0])
    x = np.array([0.0, 1.0, 2.0, 10.0, 11.0])
    t = np.array([0.5, 2.0, 3.0, 9.5, 10.0, 10.5, 12.0])
    np.testing.assert_array_equal(interp_truth(tt, x, t), [0.5, 2.0, 3.0, 9.5, 10.0, 10.5, np.nan])
    np.testing.assert_array_equal(interp_truth(tt, x, t, max_gap=2.0),
                                  [0.5, 2.0, np.nan, np.nan, 10.0, 10.5, np.nan])


def test_evaluate_against_a_gps_channel_scores_at_the_fixes_only(tmp_path):
    """``--truth-channel gps_speed``: the speed estimate against the recording's own GPS, in
    m/s, the numbers those of numpy on the fixes' interpolation, nothing scored inside an
    outage; the CLI prints the same numbers."""
    import json

    from typer.testing import CliRunner

    from vibrospeed import io, sim
    from vibrospeed.cli.app import app
    from vibrospeed.errors import InputError
    from vibrospeed.eval.metrics import evaluate

    rec = sim.simulate("car", seed=1, duration=60)
    g = rec["gps_speed"].copy()
    g[(rec.t > 20) & (rec.t < 40)] = np.nan  # a 20 s outage: no truth there
    rec = rec.with_channels(gps_speed=g)
    io.write(rec, tmp_path / "drive.csv")
    run = CliRunner().invoke
    res = run(app, ["estimate", str(tmp_path / "drive.csv"), "-m", "gps-riss", "--axis", "x",
                    "-o", str(tmp_path / "est.csv")])
    assert res.exit_code == 0, res.output
    tr = io.read_track(tmp_path / "est.csv")
    rec = io.read(tmp_path / "drive.csv")
    m = evaluate(tr, rec, truth_channel="gps_speed")
    assert m.unit == "m/s"
    g = rec["gps_speed"]
    fix = np.isfinite(g)
    tf = rec.t[fix]
    w = np.interp(tr.t, tf, g[fix])
    j = np.clip(np.searchsorted(tf, tr.t), 1, tf.size - 1)
    inside = (tr.t >= tf[0]) & (tr.t <= tf[-1]) & ((tf[j] - tf[j - 1] <= 2.0) | (tr.t == tf[j]))
    assert not inside[(tr.t > 21) & (tr.t < 39)].any()
    moving = inside & (w > 0.3) & np.isfinite(tr.speed)
    assert m.n == int(moving.sum()) > 1000
    e = tr.speed[moving] - w[moving]
    assert m.rmse == pytest.approx(np.sqrt(np.mean(e ** 2)))
    assert m.bias == pytest.approx(np.mean(e))
    res = run(app, ["evaluate", str(tmp_path / "est.csv"), "--truth", str(tmp_path / "drive.csv"),
                    "--truth-channel", "gps_speed", "--json", str(tmp_path / "m.json")])
    assert res.exit_code == 0, res.output
    got = json.loads((tmp_path / "m.json").read_text())
    assert got["n"] == m.n and got["rmse"] == pytest.approx(m.rmse)
    with pytest.raises(InputError, match="gps_fix"):
        evaluate(tr, rec, truth_channel="gps_fix")
    res = run(app, ["evaluate", str(tmp_path / "est.csv"), "--truth", str(tmp_path / "drive.csv"),
                    "--truth-channel", "gps_fix"])
    assert res.exit_code == 2 and "gps_fix" in res.output
