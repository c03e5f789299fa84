"""Sample quality flags (:mod:`vibrospeed.signal.quality`): injected faults found at exactly
the samples where they were put."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.signal import quality as ql
from vibrospeed.types import Recording, Track

FS = 100.0


def vibration(n, seed=0):
    """A wheel-line-like signal: two harmonics, noise, amplitude that changes with time."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    env = 1.0 + 0.5 * np.sin(2 * np.pi * t / 40.0)
    return env * (0.3 * np.sin(2 * np.pi * 11.0 * t) + 0.1 * np.sin(2 * np.pi * 22.0 * t)
                  + 0.05 * rng.normal(size=n))


def positions(flags, bit):
    return np.flatnonzero(flags & bit)


def test_clean_signal_has_no_flags():
    q = ql.channel_quality(vibration(20000), FS, "ay")
    assert not q.flags.any() and q.rails == () and q.stuck_runs == ()


def test_clipping_found_exactly():
    x = vibration(12000, 1)
    c = np.percentile(np.abs(x), 97)
    truth = np.flatnonzero(np.abs(x) >= c)
    q = ql.channel_quality(np.clip(x, -c, c), FS, "ay")
    np.testing.assert_array_equal(positions(q.flags, ql.SATURATED), truth)
    assert set(q.rails) == {c, -c}
    assert not (q.flags & (ql.STUCK | ql.SPIKE)).any()


def test_one_sided_saturation_at_a_range():
    """az carries +g: a +-1 g sensor sits on its upper rail only."""
    x = 9.80665 + 3 * vibration(8000, 2)
    clipped = np.minimum(x, 9.80665)
    q = ql.channel_quality(clipped, FS, "az")
    np.testing.assert_array_equal(positions(q.flags, ql.SATURATED), np.flatnonzero(x >= 9.80665))
    assert q.rails == (9.80665,)


def test_stuck_run_found_exactly():
    x = vibration(10000, 3)
    x[4000:4600] = 0.123  # a frozen driver repeats one value for 6 s
    x[7000:7010] = 0.2  # 0.1 s: shorter than STUCK_S, not stuck
    q = ql.channel_quality(x, FS, "ay")
    np.testing.assert_array_equal(positions(q.flags, ql.STUCK), np.arange(4000, 4600))
    assert q.stuck_runs == ((4000, 4600),)
    assert not (q.flags & ql.SATURATED).any()


def test_spikes_found_exactly():
    rng = np.random.default_rng(4)
    x = vibration(30000, 4)
    where = np.sort(rng.choice(np.arange(10, 29990), size=60, replace=False))
    where = where[np.diff(np.concatenate(([-10], where))) > 8]  # isolated
    x[where] += rng.choice([-1.0, 1.0], size=where.size) * 20 * np.std(x)
    q = ql.channel_quality(x, FS, "ay")
    np.testing.assert_array_equal(positions(q.flags, ql.SPIKE), where)
    # a pair of adjacent samples is a spike of two
    y = vibration(5000, 5)
    y[2000:2002] += 10.0
    np.testing.assert_array_equal(positions(ql.channel_quality(y, FS).flags, ql.SPIKE),
                                  [2000, 2001])


def test_a_step_or_a_bump_is_not_a_spike():
    x = vibration(6000, 6)
    x[3000:] += 5.0  # a step
    x[1000:1020] += 4.0  # a 0.2 s bump (20 samples)
    assert not (ql.channel_quality(x, FS).flags & ql.SPIKE).any()


def test_missing_stuck_and_spike_together():
    x = vibration(10000, 7)
    x[100:150] = np.nan
    x[5000:5100] = x[4999]  # held: the run of equal values starts one sample earlier
    x[8000] += 10 * np.nanstd(x)
    q = ql.channel_quality(x, FS)
    np.testing.assert_array_equal(positions(q.flags, ql.MISSING), np.arange(100, 150))
    np.testing.assert_array_equal(positions(q.flags, ql.STUCK), np.arange(4999, 5100))
    np.testing.assert_array_equal(positions(q.flags, ql.SPIKE), [8000])
    assert not (q.flags & ql.SATURATED).any()


def test_notes_and_track_column():
    n = 6000
    t = np.arange(n) / FS
    ay = vibration(n, 8)
    ay[3000:3300] = ay[2999]
    rec = Recording(t, {"ax": vibration(n, 9), "ay": ay})
    track = Track.from_omega(t[::2], np.ones(n // 2))
    ql.annotate(track, rec, "ay")
    q = track.extras["quality"]
    assert q.shape == (n // 2,)
    np.testing.assert_array_equal(np.flatnonzero(q), np.arange(1500, 1650))
    assert len(track.notes) == 1 and "'ay'" in track.notes[0] and "stuck" in track.notes[0]
    assert "from t = 29.99 s" in track.notes[0]


@settings(max_examples=40, deadline=None)
@given(st.lists(st.one_of(st.floats(-1e6, 1e6), st.just(float("nan"))), max_size=300),
       st.floats(0.5, 1000.0))
def test_any_input(values, fs):
    """Flags for any input: one per sample, NaN exactly where missing, no crash."""
    x = np.array(values, dtype=float)
    q = ql.channel_quality(x, fs)
    assert q.flags.shape == x.shape
    np.testing.assert_array_equal((q.flags & ql.MISSING) > 0, np.isnan(x))


@given(st.lists(st.floats(0, 100), min_size=1, max_size=50, unique=True),
       st.lists(st.floats(0, 100), max_size=50))
def test_flags_at_is_nearest_sample(t_rec, t):
    t_rec = np.sort(np.array(t_rec))
    flags = np.arange(t_rec.size, dtype=np.uint8)
    got = ql.flags_at(t_rec, flags, np.array(t))
    for k, tk in enumerate(t):
        d = np.abs(t_rec - tk)
        assert d[got[k]] == d.min()


def test_cli_estimate_writes_the_quality_column_and_notes(tmp_path):
    from typer.testing import CliRunner

    from vibrospeed import io
    from vibrospeed.cli import app

    n = 3000
    t = np.arange(n) / FS
    ay = vibration(n, 10)
    ay[1000:1200] = ay[999]
    c = np.percentile(np.abs(ay), 98)
    ax = np.clip(vibration(n, 11), -c, c)
    io.write(Recording(t, {"ax": ax, "ay": ay}), tmp_path / "d.csv")
    r = CliRunner().invoke(app, ["estimate", str(tmp_path / "d.csv"), "-o",
                                 str(tmp_path / "e.csv"), "-p", "n_grid=40"])
    assert r.exit_code == 0, r.output
    tr = io.read_track(tmp_path / "e.csv")
    np.testing.assert_array_equal(np.flatnonzero(tr.extras["quality"]), np.arange(999, 1200))
    assert "quality: channel 'ay': 201 stuck" in r.output
    assert "quality: channel 'ax':" in r.output and "saturated" in r.output


def test_mask_flagged_sets_exactly_the_spikes_to_nan():
    n = 8000
    x = vibration(n, 12)
    where = np.array([500, 2100, 4400, 7000])
    x[where] += 30 * np.std(x)
    rec = Recording(np.arange(n) / FS, {"ay": x, "az": vibration(n, 13)}, notes=["kept"])
    out = ql.mask_flagged(rec)
    np.testing.assert_array_equal(np.flatnonzero(np.isnan(out["ay"])), where)
    np.testing.assert_array_equal(np.delete(out["ay"], where), np.delete(x, where))
    np.testing.assert_array_equal(out["az"], rec["az"])
    assert out.notes == ["kept", "quality: channel 'ay': 4 flagged sample(s) set to NaN"]
    assert not np.isnan(rec["ay"]).any()  # the input is not changed


@pytest.mark.parametrize("f_hz", [0.5, 3.0, 10.0, 25.0, 40.0])
def test_a_smooth_noise_free_wave_has_no_spikes_and_its_spikes_are_found(f_hz):
    # on a noise-free sine the 7-sample running median follows the flanks, so its residual's
    # robust scale fell to the resolution and the crests were flagged (800 of 2000 at 10 Hz)
    t = np.arange(2000) / 100.0
    x = np.sin(2 * np.pi * f_hz * t) + 9.81 + 0.5 * t
    assert not (ql.channel_quality(x, 100.0).flags & ql.SPIKE).any()
    x[[500, 1200]] += [15.0, -15.0]
    np.testing.assert_array_equal(positions(ql.channel_quality(x, 100.0).flags, ql.SPIKE),
                                  [500, 1200])
