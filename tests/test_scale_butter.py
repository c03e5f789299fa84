"""``vibrospeed.signal.dsp`` against the ``scipy.signal`` (and ``scipy.ndimage``) calls it
reproduces, bit for bit, and the default estimate path without them.

The Butterworth design, the steady state, the filter loop, the response at a frequency and the
Hann window must be the installed scipy's numbers exactly (``np.array_equal``), so that no
estimate changes when the pre-filter and the whitener stop importing ``scipy.signal`` (~1 s of
start-up). Besides scipy: the design's gain at its corners (-3 dB, analytic), the steady state
held by a constant input, and the filter against a plain-Python loop of its difference
equations.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.signal as ss

from vibrospeed.signal import dsp
from vibrospeed.signal import prefilter as pf

SRC = Path(__file__).resolve().parents[1] / "src"

#: sample rates (Hz) of phones, loggers and karts, and the one the CLI's resampling gives
RATES = (20.0, 25.0, 50.0, 60.0, 99.7, 100.0, 100.00000000000213, 198.4, 200.0, 400.0, 500.0,
         1000.0)


def _cases(rng, n_cut=6):
    """(order, corner(s) in Hz, btype, fs): orders 1-8, corners over the whole open band
    (log-uniform, 0.2 % to 99 % of Nyquist) plus the presets' corners."""
    for fs in RATES:
        nyq = fs / 2
        cuts = list(nyq * 10 ** rng.uniform(np.log10(0.002), np.log10(0.99), n_cut))
        cuts += [4.0 / (2 * np.pi), 25.0 / (2 * np.pi), 8.0, 0.7 * 10 / (2 * np.pi)]
        cuts = [c for c in cuts if 0 < c < nyq]
        for N in (1, 2, 3, 4, 5, 6, 8):
            for c in cuts:
                yield N, c, "lowpass", fs
                yield N, c, "highpass", fs
            for _ in range(n_cut):
                lo, hi = np.sort(nyq * 10 ** rng.uniform(np.log10(0.002), np.log10(0.99), 2))
                if lo < hi:
                    yield N, (lo, hi), "bandpass", fs
        yield 2, (4.0 / (2 * np.pi), 50.0 / (2 * np.pi)), "bandpass", fs  # thesis-bp


def test_butter_equals_scipy_bitwise():
    rng = np.random.default_rng(15)
    n = 0
    for N, wn, btype, fs in _cases(rng):
        ref = ss.butter(N, wn, btype=btype, fs=fs, output="sos")
        got = dsp.butter_sos(N, wn, btype, fs)
        assert got.shape == ref.shape and got.dtype == ref.dtype, (N, wn, btype, fs)
        assert np.array_equal(got, ref), (N, wn, btype, fs, np.abs(got - ref).max())
        n += 1
    assert n > 1000


def test_butter_gain_at_the_corner_is_minus_3_db():
    """|H| = 1/sqrt(2) at a low/high-pass corner and at both band-pass corners (the
    Butterworth definition; the bilinear pre-warp puts the digital corner at the given Hz)."""
    for fs in (50.0, 100.0, 1000.0):
        for N in (1, 2, 4, 7):
            for btype, wn in (("lowpass", 0.1 * fs), ("highpass", 0.02 * fs),
                              ("bandpass", (0.03 * fs, 0.2 * fs))):
                sos = dsp.butter_sos(N, wn, btype, fs)
                assert sos.shape == ((N + 1) // 2 if btype != "bandpass" else N, 6)
                for f in np.atleast_1d(wn):
                    _, h = dsp.sosfreqz(sos, [f], fs)
                    assert abs(abs(h[0]) - 2 ** -0.5) < 1e-9, (btype, N, fs, f)


def test_butter_refuses_what_scipy_refuses():
    with pytest.raises(ValueError):
        dsp.butter_sos(2, 50.0, "lowpass", 100.0)  # at Nyquist
    with pytest.raises(ValueError):
        dsp.butter_sos(2, 0.0, "highpass", 100.0)
    with pytest.raises(ValueError):
        dsp.butter_sos(2, (20.0, 10.0), "bandpass", 100.0)
    with pytest.raises(ValueError):
        dsp.butter_sos(2, 10.0, "bandstop", 100.0)  # not reproduced
    with pytest.raises(ValueError):
        dsp.butter_sos(0, 10.0, "lowpass", 100.0)


def _sos_grid():
    for fs in (20.0, 100.0, 198.4, 1000.0):
        for N in (1, 2, 3, 4, 5):
            yield ss.butter(N, 0.1 * fs, btype="lowpass", fs=fs, output="sos")
            yield ss.butter(N, 0.01 * fs, btype="highpass", fs=fs, output="sos")
            yield ss.butter(N, (0.02 * fs, 0.3 * fs), btype="bandpass", fs=fs, output="sos")
    for fs in (20.0, 100.0, 198.4):
        yield pf.design("thesis-hplp", fs, M=2)
        yield pf.design("range", fs, M=3, omega_range=(10.0, 60.0))


def test_sosfilt_zi_equals_scipy_bitwise_and_holds_a_constant():
    for sos in _sos_grid():
        zi = dsp.sosfilt_zi(sos)
        assert np.array_equal(zi, ss.sosfilt_zi(sos))
        # a constant input from zi * level stays at the filter's DC gain times the level
        level = 9.81
        y, _ = dsp.sosfilt(sos, np.full(50, level), zi * level)
        dc = np.prod(sos[:, :3].sum(axis=1) / sos[:, 3:].sum(axis=1))
        np.testing.assert_allclose(y, dc * level, rtol=0, atol=1e-9 * level)


def _sosfilt_loop(sos, x, zi):
    """Each section's difference equations, transposed direct form II, in plain Python."""
    z = [[float(v) for v in row] for row in zi]
    y = []
    for v in x:
        v = float(v)
        for k, (b0, b1, b2, _, a1, a2) in enumerate(sos.tolist()):
            out = b0 * v + z[k][0]
            z[k][0] = b1 * v - a1 * out + z[k][1]
            z[k][1] = b2 * v - a2 * out
            v = out
        y.append(v)
    return np.array(y), np.array(z)


def test_sosfilt_equals_scipy_bitwise():
    rng = np.random.default_rng(3)
    for i, sos in enumerate(_sos_grid()):
        n = 200_000 if i % 7 == 0 else 3000
        x = 9.81 + rng.normal(0.0, 10 ** rng.uniform(-3, 1), n) + np.cumsum(rng.normal(size=n))
        zi = rng.normal(size=(sos.shape[0], 2))
        ref_y, ref_z = ss.sosfilt(sos, x, zi=zi)
        x0, zi0 = x.copy(), zi.copy()
        y, zf = dsp.sosfilt(sos, x, zi)
        assert np.array_equal(y, ref_y) and np.array_equal(zf, ref_z)
        assert np.array_equal(x, x0) and np.array_equal(zi, zi0)  # inputs untouched
        if n <= 3000:
            ly, lz = _sosfilt_loop(sos, x, zi)
            assert np.array_equal(y, ly) and np.array_equal(zf, lz)


def test_prefilter_apply_and_step_unchanged():
    """``prefilter.apply`` (now :func:`dsp.sosfilt`) equals scipy's sosfilt from the same
    steady state, NaN gaps carrying the state, and repeated ``step``."""
    rng = np.random.default_rng(4)
    fs = 100.0
    x = 9.81 + 0.3 * rng.normal(size=4000) + np.sin(np.arange(4000) * 0.3)
    x[500:520] = np.nan
    x[3000] = np.nan
    for preset, kw in (("thesis-hp", {}), ("thesis-hplp", {"M": 2}),
                       ("range", {"omega_range": (10.0, 120.0)}), ("thesis-bp", {})):
        sos = pf.design(preset, fs, **kw)
        got = pf.apply(sos, x, level=9.7)
        ref = np.full_like(x, np.nan)
        zi = ss.sosfilt_zi(sos) * 9.7
        for lo, hi in ((0, 500), (520, 3000), (3001, 4000)):
            ref[lo:hi], zi = ss.sosfilt(sos, x[lo:hi], zi=zi)
        assert np.array_equal(got, ref, equal_nan=True), preset
        st = pf.init(sos, 9.7)
        stepped = []
        for v in x:
            st, y = pf.step(sos, st, v)
            stepped.append(y)
        assert np.array_equal(np.array(stepped), got, equal_nan=True), preset


def test_sosfreqz_equals_scipy_bitwise():
    rng = np.random.default_rng(5)
    for sos in _sos_grid():
        f = list(rng.uniform(0.0, 10.0, 3))
        for fs in (20.0, 100.0, 198.4):
            wr, hr = ss.sosfreqz(sos, worN=f, fs=fs)
            w, h = dsp.sosfreqz(sos, f, fs)
            assert np.array_equal(h, hr) and np.array_equal(w, wr)


@pytest.mark.parametrize("M", [*range(1, 40), 63, 64, 100, 128, 199, 200, 255, 256, 300, 301,
                               397, 400, 512, 1000, 1024, 2000, 4096])
def test_hann_and_psd_window_equal_scipy_bitwise(M):
    assert np.array_equal(dsp.get_window("hann", M), ss.get_window("hann", M))
    assert np.array_equal(dsp.hann(M, sym=True), ss.windows.hann(M, sym=True))
    for fs in (20.0, 100.0, 198.4, 1000.0):
        sft = ss.ShortTimeFFT(ss.get_window("hann", M), max(1, M // 2), fs, fft_mode="onesided",
                              mfft=M, scale_to="psd", phase_shift=None)
        assert np.array_equal(dsp.psd_window(dsp.hann(M), fs), sft.win.conj())
        assert np.array_equal(np.fft.rfftfreq(M, 1 / fs), sft.f)


def _median_loop(x, size):
    """The median of each edge-extended window by sorting it (plain Python)."""
    h = size // 2
    n = len(x)
    return np.array([sorted(x[min(max(j, 0), n - 1)] for j in range(i - h, i + h + 1))[h]
                     for i in range(n)])


@pytest.mark.parametrize("size", [1, 3, 5, 7, 9, 15, 31, 101])
def test_median_filter_equals_scipy_ndimage(size):
    """Values equal to ``scipy.ndimage.median_filter(mode="nearest")`` and to sorting each
    window, for noise, heavily tied (quantised) values and zeros, any length."""
    from scipy.ndimage import median_filter

    rng = np.random.default_rng(size)
    for n in [*range(1, 40), 1000, 50_000]:
        for x in (rng.normal(size=n), np.round(rng.normal(size=n) * 2) / 2,
                  np.where(rng.random(n) < 0.5, 0.0, rng.normal(size=n))):
            got = dsp.median_filter(x, size)
            assert np.array_equal(got, median_filter(x, size=size, mode="nearest")), (size, n)
            if n <= 200:
                assert np.array_equal(got, _median_loop(x, size))
    with pytest.raises(ValueError):
        dsp.median_filter(np.array([1.0, np.nan]), 3)
    with pytest.raises(ValueError):
        dsp.median_filter(np.ones(5), 4)


_NO_SCIPY_SIGNAL = r"""
import sys
import numpy as np
from vibrospeed.cli import main
from vibrospeed import io
from vibrospeed.estimators import grid
from vibrospeed.estimators.common import start_level
from vibrospeed.estimators.online import OnlineTracker

path, out = sys.argv[1], sys.argv[2]
for extra in ([], ["-m", "grid"], ["-p", "smooth=none"]):
    try:
        main(["estimate", path, "-o", out, *extra])
    except SystemExit as exc:
        assert not exc.code, exc.code
rec = io.read(path)
cfg = grid.config_for(rec, axis="z", params={"smooth": "none", "n_grid": 40})
trk = OnlineTracker(grid, cfg, level=start_level(rec["az"], 0.01))
om = [trk.update(s).omega for s in rec["az"][:300]]
assert np.isfinite(om[-1])
bad = sorted(m for m in sys.modules if m.split(".")[:2] in (["scipy", "signal"],
                                                            ["scipy", "ndimage"]))
assert not bad, bad
print("ok")
"""


def test_default_estimate_path_does_not_import_scipy_signal(tmp_path):
    """The CLI's default estimate (fuse on a drive with GPS), the grid, its causal filter and the
    grid's ``OnlineTracker`` in a fresh process: ``scipy.signal`` (and ``scipy.ndimage``)
    never imported."""
    from vibrospeed import io, sim

    path = tmp_path / "short.csv"
    io.write(sim.simulate("car", seed=1, duration=6), path)
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")])
    res = subprocess.run([sys.executable, "-c", _NO_SCIPY_SIGNAL, str(path),
                          str(tmp_path / "est.csv")], capture_output=True, text=True, env=env,
                         timeout=900)
    assert res.returncode == 0 and res.stdout.strip().endswith("ok"), res.stderr[-3000:]
