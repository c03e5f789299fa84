"""Standstill from the broadband level (:mod:`vibrospeed.signal.standstill`)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.signal import standstill as ss
from vibrospeed.signal import standstill_stream as sst

FS = 100.0
DT = 1.0 / FS


def drive(rng, pattern, still_std=0.005, move_std=0.1, line=0.0, sway=0.3):
    """White noise at ``still_std`` where ``pattern`` is 0 and ``move_std`` where it is 1
    (one entry per second), body sway below 1 Hz of std ``sway`` while moving, plus an optional
    line at 84 rad/s throughout (an idling engine)."""
    from scipy import signal

    s = np.repeat(np.asarray(pattern, float), int(FS))
    x = rng.normal(0, 1, s.size) * np.where(s > 0, move_std, still_std)
    b, a = signal.butter(2, 1.0, fs=FS)
    lf = signal.lfilter(b, a, rng.normal(0, 1, s.size))
    x += sway * lf / lf.std() * (s > 0)
    t = np.arange(s.size) * DT
    return x + line * np.sin(84.0 * t), s == 0


def test_level_of_white_noise_matches_its_spectrum():
    rng = np.random.default_rng(0)
    sigma = 0.05
    _, lev = ss.broadband_level(rng.normal(0, sigma, 60_000), DT, (10.0, 300.0))
    # amplitude spectrum of white noise over N samples: sigma sqrt(6 / N) rms, and the median
    # of an exponential power is ln 2 times its mean
    expect = sigma * np.sqrt(6.0 / FS) * np.sqrt(np.log(2.0))
    assert np.median(lev) == pytest.approx(expect, rel=0.05)


def test_a_line_does_not_raise_the_level():
    rng = np.random.default_rng(1)
    x = rng.normal(0, 0.01, 20_000)
    t = np.arange(x.size) * DT
    _, a = ss.broadband_level(x, DT, (10.0, 300.0))
    _, b = ss.broadband_level(x + 0.2 * np.sin(84.0 * t), DT, (10.0, 300.0))  # 26 dB
    assert np.median(b) == pytest.approx(np.median(a), rel=0.2)


def test_stops_found_offline_and_causally():
    rng = np.random.default_rng(2)
    pattern = [0] * 8 + [1] * 40 + [0] * 10 + [1] * 60 + [0] * 6 + [1] * 30
    x, truth = drive(rng, pattern, line=0.05)
    for causal in (False, True):
        got = ss.standstill(x, DT, (10.0, 300.0), causal=causal)
        inner = truth & (np.convolve(truth, np.ones(201), "same") >= 201)  # 1 s from motion
        moving = ~truth
        assert got[moving].mean() < 0.01
        if causal:  # the first stop has nothing to compare with; the later ones are found
            # after a delay: the trailing 2 s body-motion window and 1.5 s of dwell
            settled = np.zeros_like(truth)
            settled[int(52.5 * FS) : int(58 * FS)] = True  # 4.5 s into the 10 s stop
            settled[int(122.5 * FS) : int(124 * FS)] = True  # and into the 6 s stop
            assert got[settled].mean() > 0.7
        else:  # the 2 s body-motion window and the 0.5 s edges cost ~1.5 s of each stop
            assert got[inner].mean() > 0.75
            deep = truth & (np.convolve(truth, np.ones(501), "same") >= 501)  # 2.5 s inside
            assert got[deep].all()


def test_no_stop_no_standstill():
    rng = np.random.default_rng(3)
    x, _ = drive(rng, [1] * 120, move_std=0.1)
    x *= np.repeat(rng.uniform(0.7, 1.3, 120), int(FS))  # speed changes, no stop
    assert not ss.standstill(x, DT, (10.0, 300.0)).any()
    assert not ss.standstill(x, DT, (10.0, 300.0), causal=True).any()


@settings(max_examples=15, deadline=None)
@given(cut=st.integers(min_value=3000, max_value=15000), seed=st.integers(0, 100))
def test_causal_decisions_do_not_use_later_data(cut, seed):
    rng = np.random.default_rng(seed)
    x, _ = drive(rng, [1] * 60 + [0] * 20 + [1] * 70)
    whole = ss.standstill(x, DT, (10.0, 300.0), causal=True)
    part = ss.standstill(x[:cut], DT, (10.0, 300.0), causal=True)
    np.testing.assert_array_equal(whole[:cut], part)


def test_nan_frames_repeat_the_last_decision():
    rng = np.random.default_rng(4)
    x, truth = drive(rng, [1] * 40 + [0] * 20 + [1] * 40)
    y = x.copy()
    y[4500:5000] = np.nan  # inside the stop
    got = ss.standstill(y, DT, (10.0, 300.0))
    assert got[4300:5700].all()
    assert not got[~truth].any()


def test_several_axes_stand_only_together():
    rng = np.random.default_rng(5)
    x, truth = drive(rng, [1] * 30 + [0] * 15 + [1] * 40 + [0] * 10 + [1] * 30)
    y, _ = drive(rng, [1] * 125)  # an axis that keeps moving
    one = ss.standstill(x, DT, (10.0, 300.0))
    both = ss.standstill(np.column_stack([x, y]), DT, (10.0, 300.0))
    assert one[truth].mean() > 0.7 and not both.any()


def test_short_input():
    assert not ss.standstill(np.zeros(10), DT, (10.0, 300.0)).any()


@pytest.mark.parametrize("omega_min", [2.0, 3.0, 5.0, 8.0])
def test_a_slow_vehicles_short_stops_whatever_its_range_floor(omega_min):
    # below ~9 rad/s the body-motion band (0.2 Hz .. 0.7 omega_min / 2 pi) held little but the
    # tail of a braking: from omega_min = 2.7 rad/s on, a cart's 3-5 s stops were lost (1.4 %
    # of the stop time found at 3 rad/s, 0 % at 5 against 97.5 % at 2)
    from vibrospeed import sim

    rec = sim.simulate("stop_and_go", seed=1)
    X = np.column_stack([rec[c] for c in ("ay", "ax", "az")])
    still = ss.standstill(X, rec.dt, (omega_min, 90.0))
    truth = rec["omega_true"] < 0.05
    assert np.mean(still[truth]) > 0.9
    assert ss._motion_upper(omega_min / (2 * np.pi)) == 0.0
    assert ss._motion_upper(10.0 / (2 * np.pi)) > 1.0  # a car's range keeps the test


@pytest.mark.parametrize("band", [(10.0, 300.0), (10.0, 30.0)])  # 46 bins, 3 bins
def test_level_is_the_median_power_of_each_frame(band):
    """broadband_level against a frame-by-frame reference written from its definition (Hann
    window, amplitude scale 2 |X| / sum(w), np.median over the band's bins; a frame less than
    half finite has none), for an even and an odd count of bins."""
    rng = np.random.default_rng(3)
    x = rng.normal(0, 0.02, 2000)
    x[300:360] = np.nan  # 60 of a frame's 100 samples missing: no level
    x[900:920] = np.nan  # 20 missing: counted as 0
    ends, lev = ss.broadband_level(x, DT, band)
    w = np.hanning(100)
    f = 2 * np.pi * np.fft.rfftfreq(100, DT)
    sel = (f >= band[0]) & (f <= band[1])
    want = []
    for e in ends:
        fr = x[e - 99 : e + 1]
        if np.isfinite(fr).sum() < 50:
            want.append(np.nan)
            continue
        fr = np.where(np.isfinite(fr), fr, 0.0)
        X = np.fft.rfft((fr - fr.mean()) * w)
        want.append(2 * np.sqrt(np.median(np.abs(X[sel]) ** 2)) / w.sum())
    assert sel.sum() % 2 == (band[1] < 100)
    assert np.isnan(want).sum() == 2  # the frames starting at 2.75 and 3.0 s
    np.testing.assert_allclose(lev, want, rtol=1e-12)


def test_stream_step_with_the_body_motion_is_the_causal_run():
    """A car's band (body-motion level in use): one sample at a time, the causal batch run's
    decisions, which the body-motion level changes on this drive."""
    from vibrospeed import sim

    x = sim.simulate("stop_and_go", seed=2, duration=60)["ay"].copy()
    x[1000:1030] = np.nan
    x[2600:2900] = np.nan
    band = (15.0, 300.0)
    ref = ss.standstill(x, DT, band, causal=True)
    plan = sst.stream_plan(DT, band)
    assert plan.lp_sos is not None and 0.03 < ref.mean() < 0.3
    st = sst.stream_init(plan)
    got = np.zeros(x.size, bool)
    for i, v in enumerate(x):
        st, got[i] = sst.stream_step(plan, st, v)
    np.testing.assert_array_equal(got, ref)
    hp, _ = ss._filters(DT, band)
    from vibrospeed.signal import prefilter as pf

    ends, lev = ss.broadband_level(pf.apply(hp, x), DT, band)
    without = ss.classify(lev, causal=True)  # the broadband level alone, before the dwell
    assert without[np.searchsorted(ends, np.flatnonzero(ref))].all()
    assert np.sum(without) > 2 * np.sum(ref[ends])


@settings(max_examples=60, deadline=None)
@given(flags=st.lists(st.booleans(), min_size=0, max_size=60), dwell=st.integers(0, 8),
       ahead=st.integers(0, 10))
def test_lag_dwell_is_the_run_seen_up_to_the_look_ahead(flags, dwell, ahead):
    f = np.array(flags, dtype=bool)
    want = np.zeros(f.size, bool)
    for i in range(f.size):  # brute force: the run through i, cut at i + ahead
        if f[i]:
            a = i
            while a > 0 and f[a - 1]:
                a -= 1
            b = i
            while b + 1 < min(f.size, i + ahead + 1) and f[b + 1]:
                b += 1
            want[i] = b - a + 1 > dwell
    np.testing.assert_array_equal(ss._lag_dwell(f, dwell, ahead), want)
    if ahead == 0:  # no look-ahead: the causal dwell (a run of more than dwell frames so far)
        run = 0
        for i in range(f.size):
            run = run + 1 if f[i] else 0
            assert want[i] == (run > dwell)


@settings(max_examples=12, deadline=None)
@given(cut=st.integers(min_value=3000, max_value=15000), seed=st.integers(0, 100),
       lag=st.sampled_from([0.3, 1.0, 2.0, 3.3]))
def test_lagged_decisions_use_no_data_beyond_the_lag(cut, seed, lag):
    rng = np.random.default_rng(seed)
    x, _ = drive(rng, [1] * 60 + [0] * 20 + [1] * 70)
    whole = ss.standstill(x, DT, (1.0, 300.0), causal=True, lag=lag)  # body motion tested
    part = ss.standstill(x[:cut], DT, (1.0, 300.0), causal=True, lag=lag)
    known = cut - int(np.floor(lag * FS + 1e-9))
    np.testing.assert_array_equal(whole[:known], part[:known])


def test_a_lag_declares_the_stops_sooner_and_releases_them_sooner():
    rng = np.random.default_rng(2)
    pattern = [0] * 8 + [1] * 40 + [0] * 10 + [1] * 60 + [0] * 6 + [1] * 30
    x, truth = drive(rng, pattern, line=0.05)
    for band in ((10.0, 300.0), (1.0, 300.0)):  # without and with the body-motion test
        causal = ss.standstill(x, DT, band, causal=True)
        np.testing.assert_array_equal(ss.standstill(x, DT, band, causal=True, lag=0.0), causal)
        prev = causal
        for lag in (1.0, 2.0, 3.0):
            got = ss.standstill(x, DT, band, causal=True, lag=lag)
            assert got[truth].mean() >= prev[truth].mean()
            assert got[~truth].mean() <= prev[~truth].mean()
            prev = got
        # each later stop found from at most ~2.5 s (the trailing frames) into it
        for a, b in ((48, 58), (118, 124)):
            first = a + np.argmax(prev[int(a * FS): int(b * FS)]) * DT
            assert prev[int(a * FS): int(b * FS)].any() and first - a < 2.6
        assert not prev[~truth].any()


def test_the_fixed_lag_grid_decides_stops_with_its_own_delay():
    from vibrospeed.estimators import get
    from vibrospeed.sim import simulate

    rec = simulate("stop_and_go", seed=1, duration=40)
    params = {"omega_min": 2, "omega_max": 30, "smooth": "lag", "lag": 2.0}
    track = get("grid").estimate(rec, params=params)
    X = np.column_stack([rec["ay"], rec["ax"], rec["az"]])
    want = ss.standstill(X, 1.0 / rec.fs, (2.0, 90.0), causal=True, lag=2.0)
    np.testing.assert_array_equal(track.extras["standstill"] > 0.5, want)
    assert want.any() and not np.array_equal(
        want, ss.standstill(X, 1.0 / rec.fs, (2.0, 90.0)))  # not the whole-log decision
    assert np.all(track.omega[want] == 0.0)
    assert any("causal, 2 s lag detector" in n for n in track.notes)


@pytest.mark.parametrize("lag, causal, said", [
    (float("nan"), True, "lag must be a finite number >= 0 s, got nan"),
    (-1.0, True, "lag must be a finite number >= 0 s, got -1.0"),
    (float("inf"), True, "lag must be a finite number >= 0 s, got inf"),
    (2.0, False, "lag = 2 s is the causal detector's delay"),
])
def test_a_lag_outside_its_domain_is_refused(lag, causal, said):
    # NaN or a negative lag gave the causal detector's stops without a word, a lag given to
    # the offline detector was ignored
    from vibrospeed.errors import ParameterError

    x = np.random.default_rng(0).normal(size=2000)
    with pytest.raises(ParameterError, match=f"^standstill: {said}"):
        ss.standstill(x, DT, (10.0, 300.0), causal=causal, lag=lag)
    ends = np.arange(99, 2000, 25)
    with pytest.raises(ParameterError, match=f"^standstill: {said}"):
        ss.decide(ends, np.ones(ends.size), None, 2000, DT, causal=causal, lag=lag)
