"""Time base: monotonic checks, sort/dedup, resampling against analytic signals, gaps, Nyquist."""

import numpy as np
import pytest

from vibrospeed.errors import InputError, ParameterError, ReaderError
from vibrospeed.io.timebase import (
    as_uniform,
    check_increasing,
    check_nyquist,
    find_gaps,
    interp_onto,
    resample_uniform,
    sort_dedup,
    split_at_gaps,
)
from vibrospeed.types import Recording


def test_check_increasing_names_first_bad_row():
    t = np.array([0.0, 0.1, 0.2, 0.15, 0.3, 0.3])
    with pytest.raises(InputError, match=r"sample 3: time goes backwards"):
        check_increasing(t, "drive.csv")
    rows = np.arange(t.size) + 2  # header on line 1
    with pytest.raises(ReaderError, match=r"drive.csv, line 5, column 't'"):
        check_increasing(t, "drive.csv", rows=rows)
    with pytest.raises(InputError, match="sample 2: time is nan"):
        check_increasing(np.array([0.0, 1.0, np.nan]), "x")
    check_increasing(np.array([0.0, 1e-9, 5.0]), "ok")


@pytest.mark.parametrize(("t", "what"), [
    ([0.0, 0.1, 0.1, 0.3], "api, sample 2: time 0.1 s repeats the previous sample"),
    ([0.0, 0.1, 0.05, 0.3], "api, sample 2: time goes backwards (0.05 s after 0.1 s)"),
    ([0.0, 0.1, np.nan, 0.3], "api, sample 2: time is nan (not a number)")])
def test_one_time_line_check_names_the_repair_its_caller_has(t, what):
    """The estimators' check_time and resample_uniform are check_increasing naming
    sort_dedup (a Recording built in Python); a reader names its sort option."""
    from vibrospeed.estimators.common import check_time

    rec = Recording(t=np.array(t), channels={"ay": np.zeros(4)}, source="api")
    api = "; vibrospeed.io.sort_dedup sorts, de-duplicates and drops rows without a time"
    for call in (check_time, resample_uniform):
        with pytest.raises(InputError) as err:
            call(rec)
        assert str(err.value) == what + api
    with pytest.raises(ReaderError) as err:
        check_increasing(np.array(t), "x.csv", rows=np.arange(4) + 2)
    assert str(err.value).endswith("; --sort (sort=True in Python) sorts, de-duplicates and "
                                   "drops rows without a time")
    assert "x.csv, line 4, column 't'" in str(err.value)


def test_sort_dedup_keeps_first_of_repeats_and_notes():
    t = np.array([0.2, 0.0, 0.1, 0.1, np.nan, 0.3])
    x = np.array([2.0, 0.0, 1.0, 9.0, 7.0, 3.0])
    r = sort_dedup(Recording(t=t, channels={"ay": x}))
    np.testing.assert_array_equal(r.t, [0.0, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(r["ay"], [0.0, 1.0, 2.0, 3.0])
    text = " ".join(r.notes)
    assert "missing time" in text and "sorted" in text and "1 rows repeating" in text


def test_resample_jittered_sine_matches_analytic():
    rng = np.random.default_rng(3)
    fs, f = 100.0, 3.0
    t = np.arange(2000) / fs + rng.uniform(-0.3, 0.3, 2000) / fs  # +-30 % jitter
    t.sort()
    x = np.sin(2 * np.pi * f * t)
    r = resample_uniform(Recording(t=t, channels={"ay": x}), fs)
    assert r.is_uniform(1e-9)
    np.testing.assert_allclose(np.diff(r.t), 1 / fs, rtol=1e-9)
    # linear interpolation error bound h^2/8 * max|x''|, h = longest input interval
    h = np.diff(t).max()
    bound = h**2 / 8 * (2 * np.pi * f) ** 2
    err = np.abs(r["ay"] - np.sin(2 * np.pi * f * r.t))
    assert np.nanmax(err) <= bound * 1.0001
    assert np.nanmax(err) > bound / 20  # the bound is not vacuous
    assert "linear interpolation" in r.notes[-1]
    assert r.meta["resampled"]["fs"] == fs


def test_resample_linear_signal_exact_and_gap_is_nan():
    t = np.concatenate([np.arange(0, 1, 0.01), np.arange(2, 3, 0.01)])
    x = 2.0 * t + 1.0
    r = resample_uniform(Recording(t=t, channels={"ax": x}, events={"wss_ticks": [0.5, 2.5]}),
                         200.0, max_gap=0.05)
    inside = (r.t > 0.99 + 1e-9) & (r.t < 2.0 - 1e-9)
    assert np.all(np.isnan(r["ax"][inside]))
    np.testing.assert_allclose(r["ax"][~inside], 2.0 * r.t[~inside] + 1.0, atol=1e-12)
    np.testing.assert_array_equal(r.events["wss_ticks"], [0.5, 2.5])


def test_resample_nan_neighbour_and_sparse_channel():
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    x = np.array([0.0, 1.0, np.nan, 3.0, 4.0])
    gps = np.array([np.nan, np.nan, 7.0, np.nan, np.nan])
    r = resample_uniform(Recording(t=t, channels={"ax": x, "gps_speed": gps}), 20.0)
    np.testing.assert_allclose(r["ax"], [0, 0.5, 1, np.nan, np.nan, np.nan, 3, 3.5, 4])
    # a GPS fix is seen exactly once, at the nearest grid point
    assert np.count_nonzero(np.isfinite(r["gps_speed"])) == 1
    assert r["gps_speed"][4] == 7.0


def test_find_and_split_gaps():
    t = np.concatenate([np.arange(100) * 0.01, 5 + np.arange(50) * 0.01, 10 + np.arange(10) * 0.01])
    gaps = find_gaps(t)
    assert gaps == [(pytest.approx(0.99), 5.0), (pytest.approx(5.49), 10.0)]
    rec = Recording(t=t, channels={"az": np.ones_like(t)}, events={"gps_fix": [0.5, 5.1, 7.0, 11]})
    parts = split_at_gaps(rec, 1.0)
    assert [len(p) for p in parts] == [100, 50, 10]
    assert [p.events["gps_fix"].tolist() for p in parts] == [[0.5], [5.1, 7.0], [11.0]]
    assert find_gaps(np.arange(10.0)) == []


def test_nyquist():
    check_nyquist(100.0, 3, 100.0)  # 300 < 314.16
    with pytest.raises(ParameterError, match=r"maximum omega allowed is 104\.7"):
        check_nyquist(100.0, 3, 105.0, "drive.csv")
    with pytest.raises(ParameterError):
        check_nyquist(100.0, 1, np.pi * 100.0)  # equality is not allowed


def test_a_rate_change_is_named_not_called_jitter():
    """A phone app that drops from 100 Hz to 50 Hz after 60 s: the time-line note names the
    change and where (block medians), as jitter alone would misread it; a jittered 100 Hz log
    with a single 5 s gap has no such change."""
    from vibrospeed.io.timebase import describe_timebase

    t = np.concatenate([np.arange(6000) * 0.01, 60.0 + np.arange(1, 3001) * 0.02])
    rec = Recording(t=t, channels={"ay": np.zeros(t.size)})
    (note,) = [n for n in describe_timebase(rec) if n.startswith("non-uniform")]
    assert "the rate changes from 100 Hz to 50 Hz near t = " in note
    at = float(note.split("near t = ")[1].split(" s")[0])
    assert 60.0 <= at <= 60.0 + 200 * 0.02  # within one block of 200 intervals after it
    assert "(block median rates 50-100 Hz)" in note
    rng = np.random.default_rng(3)
    tj = np.sort(np.arange(12000) * 0.01 + rng.normal(0.0, 0.002, 12000))
    tj = tj[(tj < 40.0) | (tj >= 45.0)]
    rec = Recording(t=tj, channels={"ay": np.zeros(tj.size)})
    assert not any("rate changes" in n for n in describe_timebase(rec))


def test_the_first_sample_after_a_gap_survives_the_grid_s_rounding():
    # 100 Hz with a 3 s hole: the median period is 0.01 up to rounding, so 1 / fs is
    # 100.00000000000213 Hz and the grid point meant for the first sample after the hole lies
    # 1e-11 s before it; it was NaN (301 NaN for 300 missing samples)
    t = np.arange(0, 20, 0.01)
    t = t[(t < 5.0) | (t >= 8.0 - 1e-9)]
    x = np.arange(t.size, dtype=float)
    r = resample_uniform(Recording(t=t, channels={"ay": x}, source="x"))
    y = r["ay"]
    assert np.isnan(y).sum() == 300  # the samples at 5.00 .. 7.99 s
    k = int(np.searchsorted(t, 8.0 - 1e-9))
    assert y[np.argmin(np.abs(r.t - t[k]))] == x[k]
    # a grid point that hits a sample only within rounding takes it; one between samples
    # across the gap stays NaN
    g = np.array([t[k] - 1e-12, 6.0, t[k] + 0.005])
    out = interp_onto(t, x, g, max_gap=0.05)
    assert out[0] == x[k] and np.isnan(out[1]) and out[2] == pytest.approx(x[k] + 0.5)


def test_as_uniform_resamples_beyond_5_percent_and_says_why_it_did_not_within():
    rng = np.random.default_rng(0)
    t = np.cumsum(0.01 * (1 + rng.uniform(-0.006, 0.006, 1000)))  # a phone's 0.6 % jitter
    rec = Recording(t=t, channels={"ay": np.sin(t)}, source="p")
    out = as_uniform(rec)
    assert out.t is rec.t  # estimated as it is
    d = np.diff(t)
    worst = np.max(np.abs(d - np.median(d))) / np.median(d)
    assert out.notes[-1] == (f"time stamps within {100 * worst:.2g} % of uniform (under 5 %): "
                             f"estimated at the median rate {1 / np.median(d):.6g} Hz, not "
                             "resampled")
    t2 = np.cumsum(0.01 * (1 + rng.uniform(-0.2, 0.2, 1000)))
    out2 = as_uniform(Recording(t=t2, channels={"ay": np.sin(t2)}, source="p"))
    assert "resampled" in out2.meta and out2.is_uniform()
    u = Recording(t=np.arange(100) * 0.01, channels={"ay": np.zeros(100)}, source="u")
    assert as_uniform(u).notes == []  # uniform: nothing to say
