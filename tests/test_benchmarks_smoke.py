"""Cheap checks of the benchmark helpers (benchmarks/peers.py, benchmarks/real_recordings.py):
metrics against hand-computed values, the plain spectrogram-peak peer on a pure tone, the
audio time/frequency mapping, and the k fit on an exact line. No trackers, no peers run."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
peers = pytest.importorskip("peers")
real = pytest.importorskip("real_recordings")


def test_metrics_hand_computed():
    truth = np.array([0.0, 10.0, 20.0, 40.0, 40.0, 50.0])  # first sample not moving
    est = np.array([99.0, 11.0, 10.0, 20.5, np.nan, 50.0])
    m = peers.metrics(est, truth)
    e = np.array([1.0, -10.0, -19.5, 0.0])  # errors of the moving samples with an estimate
    assert m["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)))
    assert m["medae"] == pytest.approx(np.median(np.abs(e)))
    # within max(2, 10 %): samples 1 (|1| < 2) and 5 (0 < 5) of 5 moving
    assert m["within"] == pytest.approx(2 / 5)
    # omega/2: sample 2 (10 vs 10) and sample 3 (20.5 vs 20, tol 4); the NaN is a miss
    assert m["harm"] == pytest.approx(2 / 5)
    assert m["avail"] == pytest.approx(4 / 5)


def test_spectrogram_peak_finds_tone_between_bins():
    fs = 100.0
    t = np.arange(0, 30, 1 / fs)
    w0 = 47.3  # rad/s, not on an FFT bin (bin spacing 0.153 rad/s)
    y = np.cos(w0 * t) + 0.5 * np.cos(2 * w0 * t)
    tf, wf = peers.spectrogram_peak(y, fs, 10.0, 120.0)
    assert np.all(np.abs(wf - w0) < 0.03)
    assert tf[0] == pytest.approx((200 - 1) / 2 / fs)  # centre of the first 2 s window


def test_audio_view_mapping_round_trip():
    fs = 100.0
    y = np.random.default_rng(0).normal(size=1000)
    av = peers.AudioView(y, fs, 10.0, 120.0)
    assert av.U == 4  # 16 samples per period at 120 rad/s needs 305.6 Hz
    assert av.x.size == 4000
    assert av.S == pytest.approx(peers.AUDIO_SR / 400.0)
    assert av.omega(av.hz(37.0)) == pytest.approx(37.0)
    # one real second is 1 / S audio seconds
    assert av.t_real(1.0 / av.S) == pytest.approx(1.0)
    assert av.hop == 40


def test_kfit_exact_line_and_two_fold():
    v = np.linspace(4, 20, 400)
    w = 11.2 * v
    k, s, s2 = real._kfit(w, v)
    assert k == pytest.approx(11.2)
    assert s == 1.0 and s2 == 1.0
    w2 = w.copy()
    w2[::4] *= 0.5  # a quarter on omega/2: missed, k unchanged (median)
    k, s, s2 = real._kfit(w2, v)
    assert k == pytest.approx(11.2)
    assert s == pytest.approx(0.75)


def test_band_stats_confident_miss():
    truth = np.full(4, 50.0)
    omega = np.array([50.0, 30.0, 30.0, 5.0])
    lo = np.array([45.0, 28.0, 10.0, 0.0])
    hi = np.array([55.0, 32.0, 60.0, 9.0])  # last: truth outside, width 9 < 0.2 * 50
    st = real._band_stats(omega, lo, hi, truth, np.ones(4, bool))
    assert st["cover"] == pytest.approx(2 / 4)
    assert st["conf_miss"] == pytest.approx(2 / 4)
    assert st["within"] == pytest.approx(1 / 4)


trackers = pytest.importorskip("trackers")


def test_metrics_band_and_claims_hand_computed():
    truth = np.array([0.0, 10.0, 20.0, 40.0, 40.0, 50.0])
    est = np.array([99.0, 11.0, 10.0, 20.5, np.nan, 50.0])
    lo = est - 2.0
    hi = est + 2.0
    claim = np.array([True, True, False, True, True, True])
    m = peers.metrics(est, truth, lo, hi, claim)
    # band: samples 1 (9..13 holds 10) and 5 (48..52 holds 50) of 5 moving; the NaN band misses
    assert m["cover"] == pytest.approx(2 / 5)
    # claimed moving samples: 1, 3, 4, 5 (4 of 5)
    assert m["claimed"] == pytest.approx(4 / 5)
    assert m["within_c"] == pytest.approx(2 / 4)  # 1 and 5 within; 3 on omega/2; 4 no estimate
    assert m["rmse_c"] == pytest.approx(np.sqrt((1.0 + 19.5**2 + 0.0) / 3))
    assert m["cover_c"] == pytest.approx(2 / 4)


def test_voiced_on_samples():
    t = np.array([0.1, 0.25, 0.35, 0.45, 0.55, 0.6, 0.7])
    v = peers.voiced_on_samples(t, np.array([0.2, 0.4, 0.6]), np.array([True, False, True]))
    # outside the frames: not voiced; between frames: the nearer frame's decision
    assert v.tolist() == [False, True, False, False, True, True, False]


def test_cruise_starts_rule():
    t = np.arange(0, 100, 0.01)
    # 0-20 s ramp 0 -> 60 rad/s (3 rad/s^2), 20-50 s cruise at 60, 50-55 s brake to 40 (4 rad/s^2),
    # 55-61 s cruise at 40 (too short), 61-81 s ramp down to 20 (1 rad/s^2, but partly < 30)
    w = np.interp(t, [0, 20, 50, 55, 61, 81, 100], [0, 60, 60, 40, 40, 20, 20])
    starts = trackers.cruise_starts(t, w)
    assert len(starts) == 2
    (a0, e0), (a1, e1) = starts
    assert e0 == pytest.approx(50.0, abs=0.02) and a0 == pytest.approx(35.0, abs=0.02)
    # the slow descent counts while above 30 rad/s (|dw/dt| = 1 < 2): from 55 to 71 s
    assert e1 == pytest.approx(71.0, abs=0.02) and a1 == pytest.approx(63.0, abs=0.02)


def test_lock_after_hand_computed():
    t = np.arange(0, 10, 0.01)
    truth = np.full(t.size, 50.0)
    est = truth.copy()
    est[:150] = 25.0  # omega/2 for 1.5 s, then locked
    est[400] = 53.0  # one excursion at 4 s: the strict lock moves to 4.01 s
    r = trackers.lock_after(t, est, truth)
    assert r["lock_s"] == pytest.approx(4.01)
    assert r["lock95_s"] == pytest.approx(1.5)
    assert r["half"] == 0.0 and not r["ends_half"]
    est2 = np.where(t < 6, 50.0, 25.0)  # falls to omega/2 at 6 s and stays
    r2 = trackers.lock_after(t, est2, truth)
    assert np.isnan(r2["lock_s"]) and r2["ends_half"]
    assert r2["half"] == pytest.approx(400 / 800)
    est3 = truth.copy()
    est3[-30:] = np.nan  # an unfinished last batch is dropped
    assert trackers.lock_after(t, est3, truth)["lock_s"] == 0.0


def test_real_recordings_rerun_keeps_the_hand_written_reading(tmp_path, monkeypatch):
    doc = tmp_path / "real.md"
    monkeypatch.setattr(real, "DOC", doc)
    assert real._reading() == real.READING  # first run: the template
    doc.write_text("# tables\n\n| a |\n\n## Reading\n\nhand-written text\n")
    assert real._reading() == "## Reading\n\nhand-written text\n"
