"""The grid tracker in blocks (bounded memory on long logs) against the whole-log estimate,
and the streamed ``vibrospeed estimate`` against the in-memory one."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from vibrospeed import io, sim
from vibrospeed.cli.app import app
from vibrospeed.estimators.grid import blocks, comb, stream
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


def test_blocks_with_a_short_look_ahead_within_tolerance(drive):
    """A 20 s look-ahead (blocks of 10 s): the backward pass starts 20..30 s after a sample
    instead of at the log's end; the chain has forgotten that by then: omega within 1e-6 rad/s,
    shares within 1e-6, the causal columns exact. With a 5 s look-ahead it has not (a mode
    switch at a block's end: tens of rad/s on some samples)."""
    whole = gm.estimate(drive, axis="y")
    blk = blocks.Blocks(drive, axis="y", block_s=10.0, lookahead_s=20.0).track()
    assert np.array_equal(np.isnan(whole.omega), np.isnan(blk.omega))
    assert np.nanmax(np.abs(whole.omega - blk.omega)) < 1e-6
    for k in ("p_null", "p_half", "p_double", "p_mode"):
        assert np.max(np.abs(whole.extras[k] - blk.extras[k])) < 1e-6, k
    for k in ("has_signal", "standstill", "loglik", "amp1", "rms"):  # causal or exact
        assert np.array_equal(whole.extras[k], blk.extras[k]), k
    short = blocks.Blocks(drive, axis="y", block_s=10.0, lookahead_s=5.0).track()
    assert np.nanmax(np.abs(whole.omega - short.omega)) > 1.0


@pytest.mark.parametrize("centre", [True, False])
def test_evidence_plan_is_the_whole_log_evidence(drive, centre):
    """The per-range comb evidence (computed for a block as it is needed) is bitwise the
    whole-log :func:`comb.evidence`, split anywhere."""
    config = gm.config_for(drive, axis="y")
    y = gm._prepare(drive, "y", {})[1]
    idx, vals = comb.evidence(config, y, centre=centre)
    plan = blocks._EvidencePlan(config, y, centre=centre)
    cuts = [0, 1, 149, 150, 4000, 4001, 7777, y.size]
    got = [plan.rows(a, b) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
    assert np.array_equal(np.concatenate([g[0] for g in got]), idx)
    assert np.array_equal(np.concatenate([g[1] for g in got]), vals)


def test_block_mode_refuses_what_it_cannot_do(drive):
    from vibrospeed.errors import ParameterError

    with pytest.raises(ParameterError, match="smooth must be fb or none"):
        blocks.Blocks(drive, params={"smooth": "lag"})
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
    r = _cli("estimate", path, "-m", "grid", "-o", tmp_path / "whole.csv")
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
