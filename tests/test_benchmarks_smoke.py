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
