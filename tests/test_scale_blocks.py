"""The grid tracker in blocks (bounded memory on long logs) against the whole-log estimate,
and the streamed ``vibrospeed estimate`` against the in-memory one."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
from typer.testing import CliRunner

from vibrospeed import io, sim
from vibrospeed.cli.app import app
from vibrospeed.estimators.grid import blocks, frames, stream
from vibrospeed.estimators.grid import method as gm

COLS = ("omega", "omega_std", "omega_lo", "omega_hi", "speed")


@pytest.fixture(scope="module")
def drive():
    return sim.simulate("car", seed=1, duration=75)


def _columns(track):
    out = {k: np.asarray(getattr(track, k)) for k in COLS}
    out.update({f"extra.{k}": np.asarray(v) for k, v in track.extras.items()})
    return out


def _assert_same(a, b):
    ca, cb = _columns(a), _columns(b)
    assert list(ca) == list(cb)
    for k in ca:
        assert np.array_equal(ca[k], cb[k], equal_nan=True), k


@pytest.mark.parametrize("params", [{}, {"smooth": "none"}, {"comb_axes": "all"}])
def test_blocks_equal_whole_log_when_the_look_ahead_reaches_the_end(drive, params):
    """Tiny blocks (13 s, not a multiple of the comb hop) whose look-ahead reaches the log's
    end: the forward recursions, the filter and the evidence carried exactly, the backward
    pass from the same end: bitwise the whole-log estimate."""
    whole = gm.estimate(drive, axis="y", params=dict(params))
    blk = blocks.Blocks(drive, axis="y", params=dict(params), block_s=13.0,
                        lookahead_s=100.0).track()
    _assert_same(whole, blk)
    assert whole.notes == [x for x in blk.notes if not x.startswith("block mode")]


@pytest.mark.parametrize("lag, block_s", [(3.0, 13.0), (3.0, 0.5), (1.0, 7.77), (2.2, 30.0),
                                          (0.05, 4.0)])
def test_fixed_lag_in_blocks_is_the_whole_log_fixed_lag(drive, lag, block_s):
    """``smooth=lag``: blocks rounded to whole sub-blocks of the fixed-lag smoother, each with
    one sub-block of look-ahead, the forward recursion carried: bitwise the whole-log
    fixed-lag estimate, notes and params included, whatever the block length (shorter than a
    sub-block too) and whether the evidence is placed mid-frame (lag >= 1.5 s + dt here) or at
    the frame's end (shorter lags)."""
    params = {"smooth": "lag", "lag": str(lag)}
    whole = gm.estimate(drive, axis="y", params=dict(params))
    blk = blocks.Blocks(drive, axis="y", params=dict(params), block_s=block_s)
    got = blk.track()
    _assert_same(whole, got)
    assert whole.notes == [x for x in got.notes if not x.startswith("block mode")]
    assert whole.params == blk.params
    assert blk.nb % blk.L == 0 and blk.la == blk.L
    assert any("fixed-lag smoother, lag" in x for x in got.notes)
    assert ("comb evidence placed mid-frame" in " ".join(got.notes)) == (lag >= 1.51)


def test_fixed_lag_in_blocks_with_all_axes(drive):
    params = {"smooth": "lag", "lag": "2.5", "comb_axes": "all"}
    whole = gm.estimate(drive, axis="y", params=dict(params))
    _assert_same(whole, blocks.Blocks(drive, axis="y", params=dict(params),
                                      block_s=11.0).track())


def test_blocks_with_a_short_look_ahead_within_tolerance(drive):
    """A 20 s look-ahead (blocks of 10 s): the backward pass starts 20..30 s after a sample
    instead of at the log's end; the chain has forgotten that by then: omega within 1e-4 rad/s
    (measured 1.7e-5), shares within 1e-4 (5e-5), the causal columns exact. With a 5 s
    look-ahead it has not (a mode switch at a block's end: tens of rad/s on some samples)."""
    whole = gm.estimate(drive, axis="y")
    blk = blocks.Blocks(drive, axis="y", block_s=10.0, lookahead_s=20.0).track()
    assert np.array_equal(np.isnan(whole.omega), np.isnan(blk.omega))
    assert np.nanmax(np.abs(whole.omega - blk.omega)) < 1e-4
    for k in ("p_null", "p_half", "p_double", "p_mode"):
        assert np.max(np.abs(whole.extras[k] - blk.extras[k])) < 1e-4, k
    for k in ("has_signal", "standstill", "loglik", "amp1", "rms"):  # causal or exact
        assert np.array_equal(whole.extras[k], blk.extras[k]), k
    short = blocks.Blocks(drive, axis="y", block_s=10.0, lookahead_s=5.0).track()
    assert np.nanmax(np.abs(whole.omega - short.omega)) > 1.0


@pytest.mark.parametrize("centre", [True, False])
def test_evidence_plan_is_the_whole_log_evidence(drive, centre):
    """The per-range comb evidence (computed for a block as it is needed) is bitwise the
    whole-log :func:`frames.evidence`, split anywhere."""
    config = gm.config_for(drive, axis="y")
    y = gm._prepare(drive, "y", {})[1]
    idx, vals = frames.evidence(config, y, centre=centre)
    plan = blocks._EvidencePlan(config, y, centre=centre)
    cuts = [0, 1, 149, 150, 4000, 4001, 7777, y.size]
    got = [plan.rows(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
    assert np.array_equal(np.concatenate([g[0] for g in got]), idx)
    assert np.array_equal(np.concatenate([g[1] for g in got]), vals)


def test_block_mode_refuses_what_it_cannot_do(drive):
    from vibrospeed.errors import ParameterError

    with pytest.raises(ParameterError, match="smooth must be 'none', 'fb' or 'lag'"):
        blocks.Blocks(drive, params={"smooth": "rts"})
    with pytest.raises(ParameterError, match="no parameter fit"):
        blocks.Blocks(drive, params={"fit": "r"})


def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def test_streamed_cli_output_equals_the_in_memory_one(tmp_path, monkeypatch):
    """``vibrospeed estimate`` above the streaming threshold (lowered here) reads in chunks,
    estimates in 20 s blocks and appends them to the output: with a look-ahead reaching the end,
    the CSV is byte for byte the whole-log path's; the sidecar has the same columns and params
    and says it ran in blocks; below the threshold nothing changes."""
    rec = sim.simulate("car", seed=2, duration=60)
    path = tmp_path / "drive.csv"
    io.write(rec, path)
    # -m grid: this drive has GPS speed, where estimate's default is fuse (not streamed)
    r = whole = _cli("estimate", path, "-m", "grid", "-o", tmp_path / "whole.csv")
    assert r.exit_code == 0, r.output
    assert "in blocks" not in r.output
    monkeypatch.setattr(stream, "STREAM_ROWS", 1000)
    monkeypatch.setattr(stream, "CHUNK_ROWS", 777)
    monkeypatch.setattr(blocks, "BLOCK_S", 20.0)
    monkeypatch.setattr(blocks, "LOOKAHEAD_S", 100.0)
    r = _cli("estimate", path, "-m", "grid", "-o", tmp_path / "streamed.csv")
    assert r.exit_code == 0, r.output
    assert "in blocks" in r.output
    assert (tmp_path / "streamed.csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
    a = json.loads((tmp_path / "whole.csv.json").read_text())
    b = json.loads((tmp_path / "streamed.csv.json").read_text())
    for k in ("kind", "method", "params", "level", "wheel_radius", "columns", "input_sha256"):
        assert a[k] == b[k], k
    assert [x for x in b["notes"] if not x.startswith("block mode")] == a["notes"]
    assert a["meta"]["axis"] == b["meta"]["axis"] == "y"
    # both end with the same summary numbers (the streamed medians from float32 copies)
    lines = [next(ln for ln in res.output.splitlines() if ln.startswith("summary: "))
             for res in (whole, r)]
    nums = [np.array([float(x) for x in re.findall(r"[-+]?\d+\.?\d*", ln)]) for ln in lines]
    assert re.sub(r"[\d.]+", "#", lines[0]) == re.sub(r"[\d.]+", "#", lines[1])
    assert np.allclose(nums[0], nums[1], rtol=1e-6, atol=0.011)
    # a 20 s look-ahead past each 20 s block: within the block mode's tolerance
    monkeypatch.setattr(blocks, "LOOKAHEAD_S", 20.0)
    r = _cli("estimate", path, "-m", "grid", "-o", tmp_path / "short.csv")
    assert r.exit_code == 0, r.output
    s, w = io.read_track(tmp_path / "short.csv"), io.read_track(tmp_path / "whole.csv")
    assert np.array_equal(np.isnan(s.omega), np.isnan(w.omega))
    assert np.nanmax(np.abs(s.omega - w.omega)) < 1e-6
    assert not list(tmp_path.glob(".*tmp*"))  # no temporary file left


def test_count_rows(tmp_path):
    rec = sim.simulate("car", seed=2, duration=3)
    io.write(rec, tmp_path / "a.csv")
    io.write(rec, tmp_path / "a.parquet")
    assert stream.count_rows(tmp_path / "a.csv") == len(rec)
    assert stream.count_rows(tmp_path / "a.parquet") == len(rec)
    assert stream.count_rows(tmp_path / "missing.csv") is None
    (tmp_path / "b.csv").write_text("t,ay\n0,1\n0.01,2")  # no newline at the end
    assert stream.count_rows(tmp_path / "b.csv") == 2


@pytest.mark.parametrize("causal", [False, True])
def test_standstill_in_pieces_is_the_detector(monkeypatch, causal):
    """The standstill detector in pieces (small pieces here, so that frames, running sums and
    samples cross many boundaries) decides exactly as :func:`signal.standstill.standstill` on
    drives with stops, NaN bursts included."""
    from vibrospeed.signal import standstill as ss

    monkeypatch.setattr(blocks, "_PIECE", 1000)
    monkeypatch.setattr(blocks, "_PIECE_FRAMES", 37)
    found = 0
    for scen, seed in (("car", 1), ("random", 4), ("random", 9)):
        rec = sim.simulate(scen, seed=seed, duration=150)
        for ch in ("ax", "ay", "az"):
            x = rec.channel(ch).copy()
            x[3000:3100] = np.nan
            want = ss.standstill(x, rec.dt, (10.0, 360.0), causal=causal)
            got = blocks.standstill(x, rec.dt, (10.0, 360.0), causal=causal)
            assert np.array_equal(got, want), (scen, seed, ch)
            found += int(want.sum())
    assert found > 0  # the drives have stops
    # a slow vehicle's range: no body-motion test (the pieces kept the old 0.3 Hz rule, and
    # disagreed with the detector for a range floor of 2.7-9 rad/s)
    rec = sim.simulate("stop_and_go", seed=1, duration=60)
    for band in ((5.0, 90.0), (2.0, 90.0)):
        want = ss.standstill(rec["ay"], rec.dt, band, causal=causal)
        assert want.any() and np.array_equal(
            blocks.standstill(rec["ay"], rec.dt, band, causal=causal), want), band


def test_motion_level_in_pieces_bitwise(monkeypatch):
    from vibrospeed.signal import standstill as ss

    monkeypatch.setattr(blocks, "_PIECE", 777)
    rec = sim.simulate("car", seed=1, duration=60)
    x = rec.channel("ax").copy()
    x[100:130] = np.nan
    ends = np.arange(99, x.size, 25)
    want = ss.motion_level(x, rec.dt, ends, 2.0)
    got = blocks._motion_level(x, rec.dt, ends, 2.0)
    assert np.array_equal(got, want, equal_nan=True)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
@pytest.mark.parametrize("counted", [True, False])
def test_read_accelerometer_equals_the_whole_read(tmp_path, monkeypatch, suffix, counted):
    """The streaming path's reader (chunks copied into arrays of the counted length, grown when
    the count falls short) gives the whole-file reader's time line and accelerometer axes."""
    rec = sim.simulate("car", seed=2, duration=20)
    path = tmp_path / f"drive{suffix}"
    io.write(rec, path)
    if not counted:
        monkeypatch.setattr(stream, "count_rows", lambda *a, **k: 10)
    got = stream.read_accelerometer(path, chunk_rows=333)
    want = io.read(path)
    assert np.array_equal(got.t, want.t)
    assert sorted(got.channels) == ["ax", "ay", "az"]
    for c in got.channels:
        assert np.array_equal(got.channels[c], want.channels[c], equal_nan=True)
    assert got.wheel_radius == want.wheel_radius


# ---- what streams, counted once, and says so -------------------------------------------------
def _small_blocks(monkeypatch, look_ahead=100.0):
    monkeypatch.setattr(stream, "STREAM_ROWS", 1000)
    monkeypatch.setattr(stream, "CHUNK_ROWS", 777)
    monkeypatch.setattr(blocks, "BLOCK_S", 20.0)
    monkeypatch.setattr(blocks, "LOOKAHEAD_S", look_ahead)


def _whole_and_streamed(tmp_path, monkeypatch, path, *args, look_ahead=100.0):
    """``vibrospeed estimate path *args`` on the whole-log path, then streamed (small blocks
    and chunks): the two results' paths and CLI outputs."""
    r = _cli("estimate", path, *args, "-o", tmp_path / "whole.csv")
    assert r.exit_code == 0, r.output
    assert "in blocks" not in r.output
    with monkeypatch.context() as m:
        _small_blocks(m, look_ahead)
        s = _cli("estimate", path, *args, "-o", tmp_path / "streamed.csv")
    assert s.exit_code == 0, s.output
    assert "in blocks" in s.output
    return tmp_path / "whole.csv", tmp_path / "streamed.csv", r.output, s.output


def _assert_same_files(whole, streamed, extra_notes=()):
    """Byte-identical CSVs; sidecars equal but for the block-mode note (and ``extra_notes``
    put first)."""
    assert streamed.read_bytes() == whole.read_bytes()
    a = json.loads(whole.with_name(whole.name + ".json").read_text())
    b = json.loads(streamed.with_name(streamed.name + ".json").read_text())
    assert sorted(a) == sorted(b)
    for k in a:
        if k not in ("notes", "input"):
            assert a[k] == b[k], k
    assert b["notes"][: len(extra_notes)] == list(extra_notes)
    assert [x for x in b["notes"][len(extra_notes):] if not x.startswith("block mode")] \
        == a["notes"]


def _accel(rec):
    from vibrospeed.types import Recording

    return Recording(rec.t, {c: rec.channel(c) for c in ("ax", "ay", "az")})


def _one_line(text: str) -> str:
    return " ".join(text.split())  # rich wraps long notes


def test_default_method_on_a_streamed_log_with_gps_says_grid(tmp_path, monkeypatch):
    """Without -m, a log with GPS speed long enough to stream is estimated with grid (fuse
    holds the whole log): a note says so on stderr and in the sidecar; the output is the
    whole-log grid estimate's, byte for byte. Short, it is fused (no such note)."""
    rec = sim.simulate("car", seed=2, duration=60)
    path = tmp_path / "drive.csv"
    io.write(rec, path)
    assert np.isfinite(rec.channel("gps_speed")).any()
    r = _cli("estimate", path, "-o", tmp_path / "fused.csv")
    assert r.exit_code == 0 and "method fuse" in r.output
    assert "are estimated with grid in blocks" not in _one_line(r.output)
    r = _cli("estimate", path, "-m", "grid", "-o", tmp_path / "whole.csv")
    assert r.exit_code == 0, r.output
    _small_blocks(monkeypatch)
    s = _cli("estimate", path, "-o", tmp_path / "streamed.csv")
    assert s.exit_code == 0, s.output
    note = ("the recording has GPS speed, but its 6000 rows are estimated with grid in blocks "
            "(bounded memory; fuse holds the whole log in memory): -m fuse to fuse it anyway")
    assert f"note: {note}" in _one_line(s.output)
    assert "method grid, in blocks" in _one_line(s.output)
    _assert_same_files(tmp_path / "whole.csv", tmp_path / "streamed.csv", [note])
    # no GPS speed channel: no such note
    io.write(_accel(rec), tmp_path / "nogps.csv")
    s = _cli("estimate", tmp_path / "nogps.csv", "-o", tmp_path / "n.csv")
    assert s.exit_code == 0 and "in blocks" in s.output
    assert "GPS" not in s.output
    assert not any("GPS" in x for x in json.loads((tmp_path / "n.csv.json").read_text())["notes"])


@pytest.mark.parametrize("args", [(), ("-m", "grid"), ("-m", "grid", "--lag", "3"),
                                  ("--smooth",)])
@pytest.mark.parametrize("streams", [True, False])
def test_rows_are_counted_once(tmp_path, monkeypatch, args, streams):
    """Deciding to stream counts the file's rows; the count then sizes the reader's arrays:
    one count per run, streamed or not, with or without -m."""
    rec = sim.simulate("car", seed=2, duration=20)
    path = tmp_path / "drive.csv"
    io.write(_accel(rec), path)
    calls = []
    real = stream.count_rows

    def counting(*a, **k):
        calls.append(a)
        return real(*a, **k)

    monkeypatch.setattr(stream, "count_rows", counting)
    _small_blocks(monkeypatch)
    if not streams:
        monkeypatch.setattr(stream, "STREAM_ROWS", 10**9)
    r = _cli("estimate", path, *args, "-o", tmp_path / "o.csv")
    assert r.exit_code == 0, r.output
    assert ("in blocks" in r.output) == streams
    assert len(calls) == 1


def test_streamed_non_uniform_time_line_has_the_whole_logs_notes(tmp_path, monkeypatch):
    """Jittered time stamps: both paths note the time line and resample it; the same notes,
    the same bytes."""
    from vibrospeed.types import Recording

    rec = _accel(sim.simulate("car", seed=2, duration=40))
    rng = np.random.default_rng(3)
    t = rec.t + rng.uniform(-2e-3, 2e-3, rec.t.size)
    io.write(Recording(t, dict(rec.channels)), tmp_path / "jit.csv")
    whole, streamed, _, out = _whole_and_streamed(tmp_path, monkeypatch, tmp_path / "jit.csv",
                                                  "-m", "grid")
    _assert_same_files(whole, streamed)
    notes = json.loads(whole.with_name("whole.csv.json").read_text())["meta"]["recording_notes"]
    assert any(n.startswith("non-uniform time line") for n in notes)
    assert "non-uniform time line" in _one_line(out)


def _mapped_file(tmp_path, rec, with_time=True):
    """``rec``'s accelerometer in g (and time in ms) under other names, a text column first,
    semicolons."""
    p = tmp_path / "logger.txt"
    rows = ["date;time_ms;acc_x;acc_y;acc_z" if with_time else "date;acc_x;acc_y;acc_z"]
    g = 9.80665
    for i in range(len(rec)):
        cells = ["2026-01-01"] + ([repr(float(rec.t[i] * 1e3))] if with_time else [])
        cells += [repr(float(rec.channel(c)[i] / g)) for c in ("ax", "ay", "az")]
        rows.append(";".join(cells))
    p.write_text("\n".join(rows) + "\n")
    return p


def test_streamed_mapped_columns_equal_the_whole_log(tmp_path, monkeypatch):
    """``--columns "t=time_ms:ms,ax=acc_x:g,..."``: read in chunks through the mapping, the
    same bytes and sidecar as the whole-file reader's estimate (units, scaling, time line,
    notes)."""
    rec = sim.simulate("car", seed=2, duration=45)
    p = _mapped_file(tmp_path, rec)
    cols = "t=time_ms:ms,ax=acc_x:g,ay=acc_y:g,az=acc_z:g"
    whole, streamed, _, out = _whole_and_streamed(tmp_path, monkeypatch, p, "--columns", cols)
    _assert_same_files(whole, streamed)
    assert "columns mapped: t<-time_ms [ms]" in _one_line(out)


@pytest.mark.parametrize("how", ["toml", "cli"])
def test_streamed_rate_without_a_time_column_equals_the_whole_log(tmp_path, monkeypatch, how):
    """No time column: ``t = i / rate`` from a TOML mapping's ``rate`` or ``--rate``, counted
    from the file's first row in every chunk; scale and offset applied as the whole reader
    does: the same bytes."""
    rec = sim.simulate("car", seed=2, duration=45)
    p = _mapped_file(tmp_path, rec, with_time=False)
    if how == "toml":
        m = tmp_path / "map.toml"
        m.write_text('rate = 100.0\n[columns]\n'
                     'ax = { column = "acc_x", unit = "g" }\n'
                     'ay = { column = "acc_y", scale = 2.0, offset = 0.01, unit = "g" }\n'
                     'az = { column = "acc_z", unit = "g" }\n')
        args = ("--mapping", m, "-m", "grid")
    else:
        args = ("--columns", "ax=acc_x:g,ay=acc_y*2:g,az=acc_z:g", "--rate", "100")
    whole, streamed, _, out = _whole_and_streamed(tmp_path, monkeypatch, p, *args)
    _assert_same_files(whole, streamed)
    assert "no time column: t = i / 100 Hz" in _one_line(out)


@pytest.mark.parametrize("bad", ["cell", "time"])
def test_streamed_mapped_errors_are_the_whole_logs(tmp_path, monkeypatch, bad):
    """A text cell or time going back far into a mapped file: exit status 2 and the same
    one-line error, naming the file line and column, on both paths."""
    rec = sim.simulate("car", seed=2, duration=30)
    p = _mapped_file(tmp_path, rec)
    lines = p.read_text().splitlines()
    parts = lines[2500].split(";")
    if bad == "cell":
        parts[3] = "oops"
    else:
        parts[1] = "5.0"
    lines[2500] = ";".join(parts)
    p.write_text("\n".join(lines) + "\n")
    cols = "t=time_ms:ms,ax=acc_x:g,ay=acc_y:g,az=acc_z:g"
    r = _cli("estimate", p, "--columns", cols, "-o", tmp_path / "w.csv")
    _small_blocks(monkeypatch)
    s = _cli("estimate", p, "--columns", cols, "-o", tmp_path / "s.csv")
    assert r.exit_code == s.exit_code == 2
    assert _one_line(s.output) == _one_line(r.output)
    assert "line 2501" in _one_line(s.output)
    assert not (tmp_path / "s.csv").exists()


@pytest.mark.parametrize("args", [("--lag", "3"), ("-p", "smooth=lag", "-p", "lag=1.0")])
def test_streamed_fixed_lag_equals_the_whole_log(tmp_path, monkeypatch, args):
    """``--lag`` on a streamed log: 20 s blocks (rounded to whole sub-blocks), each with the
    fixed-lag smoother's own look-ahead (the look-ahead setting is not used: 0 here): the
    whole-log fixed-lag output byte for byte."""
    rec = sim.simulate("car", seed=2, duration=45)
    io.write(_accel(rec), tmp_path / "drive.parquet")
    whole, streamed, _, out = _whole_and_streamed(tmp_path, monkeypatch,
                                                  tmp_path / "drive.parquet", "-m", "grid",
                                                  *args, look_ahead=0.0)
    _assert_same_files(whole, streamed)
    assert "fixed-lag smoother exactly as on the whole log" in _one_line(out)


# ---- the streamed plot ---------------------------------------------------------------------
def test_stream_plot_spectrogram_is_the_whole_logs(drive):
    """Frames every 0.25 window (a short log): the whole-log plot's spectrogram
    (:func:`signal.spectral.spectrogram`, scipy), to rounding, NaN gaps included."""
    from vibrospeed.signal.spectral import spectrogram
    from vibrospeed.types import Recording

    x = drive.channel("ay").copy()
    x[1000:1200] = np.nan
    rec = Recording(drive.t, {"ay": x})
    sp = stream.StreamPlot(rec, "ay", len(rec), batch=7)
    want = spectrogram(x, rec.fs, window_s=3.0, t0=rec.t[0])
    np.testing.assert_allclose(sp.t, want.t, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sp.omega, want.omega, rtol=1e-12)
    np.testing.assert_allclose(sp.power, want.power, rtol=1e-9, atol=1e-12 * want.power.max())
    assert sp.hop_s == pytest.approx(0.75)


def test_stream_plot_decimates_to_its_bounds(drive, monkeypatch):
    """At most PLOT_FRAMES columns, each the periodogram of its own 3 s window (scipy's,
    computed here frame by frame), and every k-th sample of the blocks' estimate, however the
    blocks cut the log."""
    from scipy.signal import periodogram

    monkeypatch.setattr(stream, "PLOT_FRAMES", 50)
    monkeypatch.setattr(stream, "PLOT_POINTS", 333)
    x = drive.channel("ay")
    sp = stream.StreamPlot(drive, "ay", len(drive))
    assert sp.power.shape[1] <= 50 and sp.hop_s > 0.75
    hop = int(round(sp.hop_s * drive.fs))
    x0 = np.nan_to_num(x - np.nanmean(x))
    for j in (0, 17, sp.power.shape[1] - 1):
        _, pw = periodogram(x0[j * hop: j * hop + 300], fs=drive.fs, window="hann",
                            detrend="constant", scaling="density")
        np.testing.assert_allclose(sp.power[:, j], pw, rtol=1e-9, atol=1e-12 * pw.max())
    tr = blocks.Blocks(drive, axis="y", params={"smooth": "none"}, block_s=7.3).track()
    cuts = [0, 5, 6, 731, 2000, 2001, len(tr)]
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        part = dataclasses.replace(tr, t=tr.t[a:b], omega=tr.omega[a:b],
                                   omega_lo=tr.omega_lo[a:b], omega_hi=tr.omega_hi[a:b],
                                   extras={k: v[a:b] for k, v in tr.extras.items()})
        sp.add(part)
    k = sp.k
    assert k == -(-len(drive) // 333)
    got = [np.concatenate([p[i] for p in sp._parts]) for i in range(5)]
    for g, w in zip(got, (tr.t, tr.omega, tr.omega_lo, tr.omega_hi, tr.extras["has_signal"]),
                    strict=True):
        assert np.array_equal(g, w[::k], equal_nan=True)
    assert sp.top == np.nanmax(tr.omega_hi)


def test_streamed_plot_is_written_and_the_output_unchanged(tmp_path, monkeypatch):
    """``--plot`` no longer keeps a long log off the streaming path: the PNG is written, the
    estimate is the whole-log path's byte for byte."""
    rec = sim.simulate("car", seed=2, duration=45)
    io.write(_accel(rec), tmp_path / "drive.csv")
    whole, streamed, _, out = _whole_and_streamed(
        tmp_path, monkeypatch, tmp_path / "drive.csv", "--plot", tmp_path / "p.png")
    _assert_same_files(whole, streamed)
    assert "decimated spectrogram" in _one_line(out)
    png = (tmp_path / "p.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
