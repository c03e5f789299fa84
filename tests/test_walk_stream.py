"""The streamed ``vibrospeed estimate`` (a long log, read in chunks and estimated in blocks)
against the whole-log path: the plot's truth and GPS overlays and the recording's notes; and
the online tracker's speed with a wheel radius against the batch Track's."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from vibrospeed import io, sim
from vibrospeed.cli.app import app
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid, rbpmf
from vibrospeed.estimators.common import start_level
from vibrospeed.estimators.grid import blocks, stream
from vibrospeed.estimators.online import OnlineTracker

P = {"smooth": "none", "omega_min": 2, "omega_max": 30}


# ---- the online tracker's speed ------------------------------------------------------------
def test_online_speed_with_a_wheel_radius_is_the_batch_tracks():
    """``wheel_radius=``: speed, its std and band are r times omega's, bitwise the speed
    columns of the causal batch Track estimated with the same radius (stops included: 0
    there); without a radius speed stays NaN and omega is the same."""
    rec = sim.simulate("stop_and_go", seed=6, duration=22)
    r = 0.2837
    batch = grid.estimate(rec, axis="y", params=P, wheel_radius=r)
    assert (batch.extras["standstill"] > 0.5).any() and np.isfinite(batch.speed).all()
    cfg = grid.config_for(rec, params=P)
    lvl = start_level(rec["ay"], cfg.tracker.model.dt)
    trk = OnlineTracker(grid, cfg, level=lvl, standstill=3, wheel_radius=r)
    got = [trk.update(float(a), (x, z)) for a, x, z in zip(rec["ay"], rec["ax"], rec["az"],
                                                           strict=True)]
    for k in ("speed", "speed_std", "speed_lo", "speed_hi", "omega"):
        np.testing.assert_array_equal([getattr(e, k) for e in got], getattr(batch, k))
    plain = OnlineTracker(grid, cfg, level=lvl)
    old = [plain.update(float(a)) for a in rec["ay"][:300]]
    assert np.isnan([e.speed for e in old]).all()
    assert not hasattr(old[0], "speed_lo")
    np.testing.assert_array_equal([e.omega for e in old], batch.omega[:300])


def test_online_speed_rbpmf_and_a_bad_radius():
    rec = sim.simulate("cart", seed=1, duration=8)
    p = {"omega_min": 2, "omega_max": 30}
    batch = rbpmf.estimate(rec, axis="y", params=p, wheel_radius=0.3)
    cfg = rbpmf.config_for(rec, params=p)
    trk = OnlineTracker(rbpmf, cfg, level=start_level(rec["ay"], cfg.model.dt),
                        wheel_radius=0.3)
    got = [trk.update(float(a)) for a in rec["ay"]]
    np.testing.assert_array_equal([e.omega for e in got], batch.omega)
    np.testing.assert_array_equal([e.speed for e in got], batch.speed)
    np.testing.assert_array_equal([e.speed_hi for e in got], batch.speed_hi)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ParameterError, match="wheel_radius"):
            OnlineTracker(rbpmf, cfg, wheel_radius=bad)


# ---- the streamed CLI path against the whole-log one ----------------------------------------
def _cli(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def _one_line(text: str) -> str:
    return " ".join(text.split())  # rich wraps long notes


def _small_blocks(m):
    m.setattr(stream, "STREAM_ROWS", 1000)
    m.setattr(stream, "CHUNK_ROWS", 777)
    m.setattr(blocks, "BLOCK_S", 10.0)
    m.setattr(blocks, "LOOKAHEAD_S", 100.0)


def _drawn(monkeypatch):
    """The data of every line the plot draws, by label, one dict per figure built."""
    from vibrospeed.eval import plot

    figures = []
    real = plot.track_figure

    def keep(*a, **k):
        fig = real(*a, **k)
        lines = {}
        for ax in fig.axes:
            for ln in ax.get_lines():
                lines.setdefault(ln.get_label(), []).append(
                    (np.asarray(ln.get_xdata(), float), np.asarray(ln.get_ydata(), float)))
        figures.append(lines)
        return fig

    monkeypatch.setattr(plot, "track_figure", keep)
    return figures


def test_streamed_plot_and_notes_are_the_whole_logs(tmp_path, monkeypatch):
    """A simulated drive with GPS speed (a fix a second, some without satellites), truth and
    a hand-written ``drive.csv.json`` without ``"kind": "recording"``, forced onto the
    streaming path: its ``--plot`` draws the truth line and the GPS fixes (used and ignored)
    with the whole-log plot's values, the unread sidecar is noted in the same place among the
    recording's notes (stderr and the output's sidecar), the estimate is the whole log's byte
    for byte."""
    rec = sim.simulate("car", seed=2, duration=20)
    sats = rec["gps_sats"].copy()
    fixes = np.flatnonzero(np.isfinite(rec["gps_speed"]))
    sats[fixes[5:9]] = 0.0  # a tunnel: fixes without satellites, drawn as ignored
    rec.channels["gps_sats"] = sats
    path = tmp_path / "drive.csv"
    io.write(rec, path)
    (tmp_path / "drive.csv.json").write_text(json.dumps({"wheel_radius": 0.3}))  # no kind
    r = 0.29
    figures = _drawn(monkeypatch)
    args = ("-m", "grid", "--wheel-radius", r)
    w = _cli("estimate", path, *args, "--plot", tmp_path / "w.png", "-o", tmp_path / "w.csv")
    assert w.exit_code == 0 and "in blocks" not in w.output, w.output
    with monkeypatch.context() as m:
        _small_blocks(m)
        s = _cli("estimate", path, *args, "--plot", tmp_path / "s.png",
                 "-o", tmp_path / "s.csv")
    assert s.exit_code == 0 and "in blocks" in s.output, s.output
    assert (tmp_path / "s.csv").read_bytes() == (tmp_path / "w.csv").read_bytes()
    # the plot's overlays
    whole, streamed = figures
    ok = np.isfinite(rec["gps_speed"])
    used, gone = ok & (sats >= 1), ok & (sats < 1)
    want = {"truth": (rec.t, rec["omega_true"]),
            "GPS speed / r": (rec.t[used], rec["gps_speed"][used] / r),
            "GPS, 0 satellites (no fix)": (rec.t[gone], rec["gps_speed"][gone] / r)}
    for label, (x, y) in want.items():
        assert len(whole[label]) == len(streamed[label]) == (2 if label == "truth" else 1)
        for (xw, yw), (xs, ys) in zip(whole[label], streamed[label], strict=True):
            np.testing.assert_array_equal(xs, xw)
            np.testing.assert_array_equal(ys, yw)
        np.testing.assert_array_equal(streamed[label][-1][0], x)
        np.testing.assert_allclose(streamed[label][-1][1], y, rtol=1e-15)
    assert (tmp_path / "s.png").read_bytes()[:4] == b"\x89PNG"
    # the unread sidecar's note
    a, b = (json.loads((tmp_path / f"{x}.csv.json").read_text()) for x in "ws")
    said = [n for n in a["meta"]["recording_notes"] if "drive.csv.json: not read" in n]
    assert len(said) == 1
    assert b["meta"]["recording_notes"] == a["meta"]["recording_notes"]
    assert f"note: {said[0]}" in _one_line(s.output)


def test_overlay_bounds_the_gps_fixes_and_decimates_the_truth():
    """More fixes than the bound: every 2^j-th fix kept (evenly spread), at most twice the
    bound, whatever the chunks; the truth every k-th row, counted across chunks."""
    from vibrospeed.io.chunks import Chunk

    n = 5000
    t = np.arange(n) * 0.01
    g = np.full(n, np.nan)
    g[::3] = np.arange(0, n, 3) * 0.5  # 1667 fixes
    truth = np.sin(t)
    ov = stream.Overlay(k=7, max_fixes=100)
    for a, b in ((0, 1), (1, 1000), (1000, 1001), (1001, 4321), (4321, n)):
        ov.add(Chunk(t[a:b], {"gps_speed": g[a:b], "omega_true": truth[a:b]},
                     np.arange(a, b) + 2, a))
    got = ov.gps()
    assert ov.stride == 16 and 100 < len(got) <= 200
    fix_t = t[::3]
    np.testing.assert_array_equal(got.t, fix_t[::16])
    np.testing.assert_array_equal(got["gps_speed"], g[::3][::16])
    assert "gps_sats" not in got.channels
    tr = ov.truth()
    np.testing.assert_array_equal(tr.t, t[::7])
    np.testing.assert_array_equal(tr["omega_true"], truth[::7])
    assert stream.Overlay().gps() is None and stream.Overlay().truth() is None


def test_an_interrupted_streamed_estimate_never_leaves_a_stale_sidecar(tmp_path, monkeypatch):
    """Ctrl-C while the blocks are written: the earlier CSV and sidecar stay, as a pair, no
    temporary file; Ctrl-C after the CSV is in place, before its sidecar is: the CSV stands
    without one (``io.write_track``'s rule), not beside the earlier run's options."""
    from vibrospeed.io import atomic
    from vibrospeed.types import Recording

    rec = sim.simulate("car", seed=2, duration=15)
    path = tmp_path / "drive.parquet"
    io.write(Recording(rec.t, {c: rec[c] for c in ("ax", "ay", "az")}), path)
    out = tmp_path / "o.csv"
    kw = {"block_s": 10.0, "chunk_rows": 700}
    stream.estimate_file(path, out, params={"smooth": "none"}, **kw)
    before = out.read_bytes(), (tmp_path / "o.csv.json").read_bytes()
    assert json.loads(before[1])["params"]["smooth"] == "none"

    def stop(track):
        if track.t[0] > 0:  # the second block
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        stream.estimate_file(path, out, params={}, on_block=stop, **kw)
    assert (out.read_bytes(), (tmp_path / "o.csv.json").read_bytes()) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["drive.parquet", "o.csv",
                                                          "o.csv.json"]

    def interrupted(p, text, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(atomic, "atomic_write_text", interrupted)
    with pytest.raises(KeyboardInterrupt):
        stream.estimate_file(path, out, params={}, **kw)
    assert out.read_bytes() != before[0] and not (tmp_path / "o.csv.json").exists()


def test_ctrl_c_while_drawing_leaves_no_earlier_figure_beside_the_new_csv(tmp_path, monkeypatch):
    from vibrospeed.eval import plot

    log = tmp_path / "cart.csv"
    io.write(sim.simulate("cart", seed=1, duration=12), log)
    out, png = tmp_path / "e.csv", tmp_path / "e.png"
    args = ["estimate", str(log), "-p", "omega_min=2", "-p", "omega_max=30", "-o", str(out),
            "--plot", str(png)]
    runner = CliRunner()
    assert runner.invoke(app, args).exit_code == 0 and png.exists()
    old_csv = out.read_bytes()

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(plot, "plot_track", interrupted)
    res = runner.invoke(app, [*args, "-p", "smooth=none"])
    assert isinstance(res.exception, KeyboardInterrupt) or res.exit_code == 130
    assert out.read_bytes() != old_csv and not png.exists()


def test_reading_a_long_log_reports_its_progress(tmp_path):
    # the bar started with the blocks: a day-long CSV was read for minutes without one
    rec = sim.simulate("cart", seed=2, duration=12)
    path = tmp_path / "drive.csv"
    io.write(rec, path)
    seen = []
    got = stream.read_accelerometer(path, chunk_rows=500,
                                    progress=lambda done, total: seen.append((done, total)))
    assert [d for d, _ in seen] == [*range(500, len(rec), 500), len(rec)]
    assert all(total == len(rec) for _, total in seen)
    np.testing.assert_array_equal(got["ay"], rec["ay"])
