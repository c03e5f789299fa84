"""vibrospeed.eval.spectra_stats: the statistics of the simulator calibration (issue 13) on
signals whose answer is known."""

import numpy as np
import pytest
from scipy import signal as sps

from vibrospeed.eval import spectra_stats as ss


@pytest.mark.parametrize("f0", [10.0, 10.125, 13.37, 31.9])  # on a bin, half-way, arbitrary
def test_amplitude_spectrum_reads_a_sinusoid_amplitude(f0):
    fs = 100.0
    t = np.arange(int(4 * fs)) / fs  # one 4 s frame
    a = 0.09
    f, A = ss.amplitude_spectrum(a * np.cos(2 * np.pi * f0 * t + 0.7) + 3.0, fs)
    peak = ss.band_max(f, A, f0 - 0.5, f0 + 0.5)[0]
    assert peak == pytest.approx(a, rel=0.02)
    assert f[np.argmax(A)] == pytest.approx(f0, abs=0.05)


def test_frame_spectra_line_in_noise_and_floor_of_white_noise():
    fs, T = 200.0, 120.0
    rng = np.random.default_rng(1)
    t = np.arange(int(T * fs)) / fs
    sigma = 0.1
    x = 0.05 * np.cos(2 * np.pi * 23.3 * t) + sigma * rng.standard_normal(t.size)
    fr = ss.frame_spectra(x, fs, win_s=4.0, hop_s=2.0)
    assert fr.A.shape[0] == (t.size - fr.n) // int(2 * fs) + 1
    peak = ss.band_max(fr.f, fr.A, 22.8, 23.8)
    assert np.median(peak) == pytest.approx(0.05, rel=0.1)  # noise shifts it a little
    floor = ss.band_median(fr.f, fr.A, 20.0, 27.0, exclude=[(22.5, 24.1)])
    asd = sigma * np.sqrt(2.0 / fs)  # one-sided density of white noise
    assert np.median(floor) == pytest.approx(ss.floor_from_asd(asd, 4.0), rel=0.06)
    assert ss.asd_from_floor(ss.floor_from_asd(asd)) == pytest.approx(asd)


def test_frame_spectra_nan_frame_and_empty_band():
    x = np.ones(1000)
    x[500] = np.nan
    fr = ss.frame_spectra(x, 100.0, win_s=2.0, hop_s=1.0)
    bad = (fr.start <= 500) & (fr.start + fr.n > 500)
    m = ss.band_max(fr.f, fr.A, 5.0, 6.0)
    assert np.isnan(m[bad]).all() and np.isfinite(m[~bad]).all()
    assert np.isnan(ss.band_max(fr.f, fr.A, 60.0, 70.0)).all()  # above Nyquist: no band


def test_band_std_lowpass_highpass_and_mask():
    fs = 100.0
    t = np.arange(0, 200, 1 / fs)
    slow, fast = 0.8 * np.sin(2 * np.pi * 0.5 * t), 0.3 * np.sin(2 * np.pi * 10.0 * t)
    x = 5.0 + slow + fast
    assert ss.band_std(x, fs, hi=2.0) == pytest.approx(0.8 / np.sqrt(2), rel=0.02)
    assert ss.band_std(x, fs, lo=2.0) == pytest.approx(0.3 / np.sqrt(2), rel=0.02)
    assert ss.band_std(x, fs) == pytest.approx(np.hypot(0.8, 0.3) / np.sqrt(2), rel=0.01)
    # a mask selects samples: the second half carries no slow part
    y = 5.0 + np.where(t < 100, slow, 0.0) + fast
    quiet = (t > 110) & (t < 190)
    assert ss.band_std(y, fs, hi=2.0, mask=quiet) < 0.02
    # NaN samples are left out, not propagated
    y[1000:1010] = np.nan
    assert np.isfinite(ss.band_std(y, fs, lo=2.0))


def test_welch_psd_white_noise_level_and_mask():
    fs, sigma = 100.0, 0.2
    x = sigma * np.random.default_rng(2).standard_normal(60_000)
    f, P, n = ss.welch_psd(x, fs, seg_s=4.0)
    band = (f > 1) & (f < 49)
    assert np.mean(P[band]) == pytest.approx(2 * sigma**2 / fs, rel=0.03)
    f2, P2 = sps.welch(x, fs, nperseg=400, detrend="linear")  # periodic vs symmetric Hann
    assert np.allclose(P[band], P2[band], rtol=2e-3)
    mask = np.zeros(x.size, bool)
    mask[:1000] = True  # 10 s: the 4 s segments starting at 0, 2, 4 and 6 s lie inside
    assert ss.welch_psd(x, fs, seg_s=4.0, mask=mask)[2] == 4
    assert np.isnan(ss.welch_psd(x, fs, seg_s=4.0, mask=np.zeros(x.size, bool))[1]).all()


def test_loglog_knee_finds_slopes_and_knee():
    f = np.linspace(0.01, 5, 5000)
    P = np.where(f < 0.5, 1.0, (f / 0.5) ** -2.0)  # flat, then 1/f^2 from 0.5 Hz
    k = ss.loglog_knee(f, P, 0.1, 2.0)
    assert k.slope_lo == pytest.approx(0.0, abs=0.15)
    assert k.slope_hi == pytest.approx(-2.0, abs=0.15)
    assert k.f_knee == pytest.approx(0.5, rel=0.2)
    assert k.gain > 0.5
    straight = ss.loglog_knee(f, f**-2.0, 0.1, 2.0)
    assert straight.slope == pytest.approx(-2.0, abs=0.02)


def test_spectral_bands_resonance_and_power_law():
    fs = 100.0
    f = np.linspace(0, 50, 2001)
    b, a = sps.iirpeak(13.0, 15.0, fs=fs)
    _, h = sps.freqz(b, a, worN=f, fs=fs)
    P = 1e-4 * (0.02 + np.abs(h) ** 2)  # a resonance 17 dB above a white floor
    bands = ss.spectral_bands(f, P, 3.0, 45.0)
    assert len(bands) == 1
    assert bands[0].f == pytest.approx(13.0, abs=0.05)
    assert bands[0].fwhm == pytest.approx(13.0 / 15.0, rel=0.1)
    assert bands[0].prominence_db == pytest.approx(10 * np.log10(1.02 / 0.02), abs=0.5)
    v = np.linspace(2, 30, 50)
    p, c, n = ss.power_law(v, 0.004 * v**1.3)
    assert (p, c, n) == (pytest.approx(1.3), pytest.approx(0.004), 50)
    assert np.isnan(ss.power_law([1.0, 2.0], [1.0, 2.0])[0])


def test_order_peaks_constant_speed_equals_spectrum_and_chirp_stays_sharp():
    fs = 200.0
    t = np.arange(int(20 * fs)) / fs
    r = 0.1
    # constant speed: the order-tracked peak equals the frequency spectrum's peak
    omega = np.full(t.size, 150.0)
    theta = np.cumsum(omega) / fs
    x = 0.2 * np.cos(theta + 0.3) + 0.05 * np.cos(2 * theta)
    fr = ss.frame_spectra(x, fs, win_s=4.0, hop_s=2.0)
    pk, where = ss.order_peaks(x, theta, fr.start, fr.n, 0.97, 1.03)
    f0 = 150.0 / (2 * np.pi)
    plain = ss.band_max(fr.f, fr.A, f0 - 0.3, f0 + 0.3)
    assert np.allclose(pk, 0.2, rtol=0.01) and np.allclose(plain, pk, rtol=0.01)
    assert np.allclose(where, 1.0, atol=0.01)
    pk2, _ = ss.order_peaks(x, theta, fr.start, fr.n, 1.94, 2.06)
    assert np.allclose(pk2, 0.05, rtol=0.02)
    # speed ramps 30 % per 4 s: the plain spectrum smears the line, the tracked one does not
    v = 10.0 + 0.75 * t  # m/s
    omega = v / r
    theta = np.cumsum(omega) / fs
    x = 0.2 * np.cos(theta)
    pk, where = ss.order_peaks(x, theta, fr.start, fr.n, 0.97, 1.03)
    assert np.allclose(pk, 0.2, rtol=0.02) and np.allclose(where, 1.0, atol=0.01)
    wm = np.array([omega[s:s + fr.n].mean() for s in fr.start]) / (2 * np.pi)
    fr = ss.frame_spectra(x, fs, win_s=4.0, hop_s=2.0)
    plain = ss.band_max(fr.f, fr.A, 0.8 * wm, 1.2 * wm)
    assert np.all(plain < 0.1)  # ~2.5 Hz of sweep in the frame: well under half the amplitude
    # NaN samples: no peak
    x[100] = np.nan
    assert np.isnan(ss.order_peaks(x, theta, fr.start[:1], fr.n, 0.9, 1.1)[0][0])


def test_order_spectrum_even_grid_matches_direct_sum():
    rng = np.random.default_rng(3)
    x = rng.standard_normal(300)
    theta = np.cumsum(rng.uniform(0.5, 1.5, 300))
    grid = np.linspace(0.9, 1.1, 41)
    fast = ss.order_spectrum(x, theta, grid)  # running product
    slow = ss.order_spectrum(x, theta, grid[[0, 3, 1, 2]])  # uneven: one exponential each
    w = np.hanning(300)
    ph = theta - theta[150]
    direct = np.array([2 * abs(np.sum((x - x.mean()) * w * np.exp(-1j * o * ph))) / w.sum()
                       for o in grid])
    assert np.allclose(fast, direct, rtol=1e-9)
    assert np.allclose(slow, direct[[0, 3, 1, 2]], rtol=1e-12)
