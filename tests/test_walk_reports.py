"""Reports, plots and batch outputs as a tester and a fleet engineer read them: the report's
truth channel and default method, a batch's pages from an earlier --report run, a drive's
hand-written sidecar, the streamed estimate's figure (vibrospeed.cli.results,
vibrospeed.eval.report, vibrospeed.batch, vibrospeed.estimators.grid.stream)."""

import json
import re

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from cli_runner import one_line_error, run  # noqa: E402
from vibrospeed import batch, io  # noqa: E402
from vibrospeed.eval import plot  # noqa: E402
from vibrospeed.types import Recording, Track  # noqa: E402

FS = 100.0
R = 0.3


def _phone(duration=20.0, gps=True):
    """A 30 rad/s wheel line on ay, ax noise; 1 Hz GPS speed at 9 m/s (9 satellites)."""
    t = np.arange(0.0, duration, 1 / FS)
    rng = np.random.default_rng(1)
    ch = {"ax": 0.05 * rng.standard_normal(t.size),
          "ay": np.sin(30.0 * t) + 0.1 * rng.standard_normal(t.size)}
    if gps:
        g = np.full(t.size, np.nan)
        s = np.full(t.size, np.nan)
        fix = np.arange(0, t.size, int(FS))
        g[fix], s[fix] = 9.0, 9.0
        ch.update(gps_speed=g, gps_sats=s)
    return Recording(t, ch, source="phone.csv")


# ---- 1. report --truth-channel ---------------------------------------------------------------
def test_report_scores_against_the_truth_channel_asked_for(tmp_path):
    """``report --truth-channel gps_speed``, as ``evaluate`` has it: a speed 0.5 m/s above the
    GPS's 9 m/s scores RMSE 0.500 m/s and bias +0.500 m/s on the page; a channel the
    recording lacks is a one-line error naming it."""
    rec = _phone()
    io.write(rec, tmp_path / "phone.csv")
    tr = Track.from_speed(rec.t, np.full(len(rec), 9.5), np.full(len(rec), 0.2),
                          wheel_radius=R, method="test")
    io.write_track(tr, tmp_path / "est.csv", input_path=tmp_path / "phone.csv")
    res = run("report", tmp_path / "phone.csv", "--estimate", tmp_path / "est.csv",
              "--truth-channel", "gps_speed", "-o", tmp_path / "p.html")
    assert res.exit_code == 0, res.output
    page = (tmp_path / "p.html").read_text()
    assert "<th>truth channel</th><td>gps_speed</td>" in page
    assert "<th>RMSE against the truth</th><td>0.500 m/s</td>" in page
    assert "<th>bias against the truth</th><td>+0.500 m/s</td>" in page
    res = run("report", tmp_path / "phone.csv", "--estimate", tmp_path / "est.csv",
              "--truth-channel", "speed_tru", "-o", tmp_path / "q.html")
    assert "'speed_tru' is missing" in one_line_error(res)
    assert not (tmp_path / "q.html").exists()


# ---- 2. report's default method is estimate's ------------------------------------------------
def test_report_without_estimate_picks_what_estimate_picks(tmp_path):
    """Without ``--estimate`` and ``-m``: fuse on a log with GPS speed and ax (as ``vibrospeed
    estimate``), grid without GPS; ``-m`` given is kept; ``-m`` beside ``--estimate`` is
    refused (it would silently do nothing)."""
    from vibrospeed.cli.results import _report_method

    io.write(_phone(), tmp_path / "gps.csv")
    io.write(_phone(gps=False), tmp_path / "plain.csv")
    args = (None, None, "auto", None, None, None, False)
    assert _report_method(tmp_path / "gps.csv", None, *args)[0] == "fuse"
    assert _report_method(tmp_path / "plain.csv", None, *args)[0] == "grid"
    assert _report_method(tmp_path / "gps.csv", "grid", *args) == ("grid", None)
    tr = Track.from_omega(np.arange(0.0, 20.0, 0.01), np.full(2000, 30.0), np.ones(2000))
    io.write_track(tr, tmp_path / "est.csv")
    res = run("report", tmp_path / "gps.csv", "--estimate", tmp_path / "est.csv", "-m", "ekf",
              "-o", tmp_path / "p.html")
    assert "--method with --estimate" in one_line_error(res)


# ---- 3. a batch without --report and an earlier run's pages ----------------------------------
def test_batch_without_report_removes_the_stale_index_and_pages(tmp_path, capsys):
    """An earlier ``--report`` run's ``index.html`` and the page of each drive estimated again
    are removed (they show replaced numbers), with a note; a foreign index.html stays."""
    from vibrospeed.sim import simulate

    src = tmp_path / "logs"
    src.mkdir()
    io.write(simulate("cart", seed=0, duration=8), src / "a.csv")
    out = tmp_path / "out"
    out.mkdir()
    (out / "index.html").write_text("<!DOCTYPE html>\n<html><head><title>vibrospeed batch: "
                                    "1 recordings</title></head></html>\n")
    (out / "a_ekf.html").write_text("old page")
    (out / "notes.html").write_text("mine")
    df = batch.run([str(src)], out, method="ekf", jobs=1)
    assert list(df["status"]) == ["ok"]
    assert not (out / "index.html").exists() and not (out / "a_ekf.html").exists()
    assert (out / "notes.html").read_text() == "mine"
    assert "removed 2 page(s)" in capsys.readouterr().err
    (out / "index.html").write_text("<html><title>my fleet</title></html>")
    batch.run([str(src)], out, method="ekf", jobs=1, force=True)
    assert (out / "index.html").read_text() == "<html><title>my fleet</title></html>"


# ---- 5. a drive's sidecar that is not read ---------------------------------------------------
@pytest.mark.parametrize(("side", "why"), [({"wheel_radius": 0.3}, 'no "kind"'),
                                           ({"kind": "track"}, '"kind" is "track"'),
                                           ([0.3], "not a JSON object")])
def test_unread_sidecar_is_a_note(tmp_path, side, why):
    """A hand-written ``drive.csv.json`` without ``"kind": "recording"`` is a note naming the
    file and why (it was ignored without a word); with the kind it is read, no note."""
    p = tmp_path / "drive.csv"
    io.write(_phone(duration=2.0, gps=False), p)
    assert not any("drive.csv.json" in n for n in batch.load_recording(p).notes)
    (tmp_path / "drive.csv.json").write_text(json.dumps(side))
    notes = [n for n in batch.load_recording(p).notes if n.startswith("drive.csv.json")]
    assert len(notes) == 1 and why in notes[0] and "not read" in notes[0]


# ---- 4. the streamed figure is the whole-log figure ------------------------------------------
def test_streamed_plot_draws_through_track_figure(monkeypatch):
    """plot_streamed(StreamPlot) goes through :func:`plot.track_figure`: legends beside the axes,
    the blocks' standstills shaded with their share (25.0 % of the kept samples here), GPS under
    the estimate where the recording has it, and its own spectrogram drawn."""
    from vibrospeed.estimators.grid import stream

    rec = _phone()
    t = rec.t
    still = ((t >= 5.0) & (t < 10.0)).astype(float)
    om = np.where(still > 0, 0.0, 30.0)
    tr = Track.from_omega(t, om, np.ones(t.size), wheel_radius=R, method="grid",
                          extras={"has_signal": 1.0 - still, "standstill": still})
    sp = stream.StreamPlot(rec, "ay", len(rec))
    sp.add(tr)
    figs = []

    def keep(path, recording, track=None, **kw):
        figs.append(plot.track_figure(recording, track, **kw))

    monkeypatch.setattr(plot, "plot_track", keep)
    sp.finish(level=0.98, method="grid", M=2, wheel_radius=R)
    plot.plot_streamed("x.png", sp)
    fig = figs[0]
    try:
        ax0, ax1 = fig.axes[:2]
        for ax in (ax0, ax1):
            assert ax.get_legend() is not None
            assert ax.get_legend().get_bbox_to_anchor().transformed(
                ax.transAxes.inverted()).x0 > 1.0  # beside, not over the data
        labels = [x.get_text() for x in ax1.get_legend().get_texts()]
        share = 100.0 * still[:: sp.k].mean()
        assert f"standstill detected ({share:.1f} %)" in labels and share == 25.0
        gps = [ln for ln in ax1.lines if ln.get_label() == "GPS speed / r"]
        est = [ln for ln in ax1.lines if ln.get_label() == "estimate (grid)"]
        assert gps and est and gps[0].get_zorder() < est[0].get_zorder()
        np.testing.assert_allclose(gps[0].get_ydata(), 9.0 / R)
        assert re.search(r"every 0\.75 s", ax0.get_ylabel())
        assert ax0.collections[0].get_array().size == sp.power[sp.omega <= ax0.get_ylim()[1]].size
    finally:
        plt.close(fig)


# ---- walk: the report's speed plot of a fuse drive -------------------------------------------
def test_report_speed_plot_of_fuse_is_by_source_not_dimmed(monkeypatch):
    """A fuse track resting on GPS with no wheel line (a phone drive): the speed plot colours
    the estimate by source (the GPS stretch is 70 % of the samples, drawn in the GPS colour
    where it is, NaN elsewhere), nothing is dimmed as "no line seen", and there is no "wheel
    line seen" entry for a line never seen."""
    from vibrospeed.eval import report

    rec = _phone()
    n = len(rec)
    src = np.where(np.arange(n) < 0.3 * n, 0.0, 1.0)  # inertial, then GPS
    tr = Track.from_speed(rec.t, np.full(n, 9.0), np.full(n, 0.2), wheel_radius=R,
                          method="fuse", extras={"source": src, "has_signal": np.zeros(n)})
    figs = []
    monkeypatch.setattr(report, "_fig_uri", lambda fig: figs.append(fig) or "")
    report._speed_uri(rec, tr, None)
    ax = figs[0].axes[0]
    try:
        labels = [x.get_text() for x in ax.get_legend().get_texts()]
        assert "fuse: gps" in labels and "fuse: inertial" in labels
        assert "wheel line seen" not in labels and "estimate, no line seen" not in labels
        gps = next(ln for ln in ax.lines if ln.get_label() == "fuse: gps")
        assert np.isfinite(gps.get_ydata()).mean() == pytest.approx(0.7, abs=1e-9)
    finally:
        plt.close(figs[0])


# ---- walk: plot draws the axis the estimate used ---------------------------------------------
def test_plot_defaults_to_the_estimates_axis(tmp_path, monkeypatch):
    """``vibrospeed plot --estimate`` of an estimate made on z (a kart's ``--axis z``) draws
    the spectrogram of az, as ``report`` does (it drew ay, a channel the estimate never read);
    ``--axis`` given still wins."""
    rec = _phone(gps=False)
    rec = Recording(rec.t, {**rec.channels, "az": rec.channel("ay")}, source="k.csv")
    io.write(rec, tmp_path / "k.csv")
    tr = Track.from_omega(rec.t, np.full(len(rec), 30.0), np.ones(len(rec)), method="grid")
    io.write_track(tr, tmp_path / "est.csv", meta={"axis": "z"}, input_path=tmp_path / "k.csv")
    drawn = []
    monkeypatch.setattr(plot, "plot_track", lambda path, r, t, **kw: drawn.append(kw["axis"]))
    for extra in ([], ["--axis", "x"]):
        res = run("plot", tmp_path / "k.csv", "--estimate", tmp_path / "est.csv",
                  "-o", tmp_path / "p.png", *extra)
        assert res.exit_code == 0, res.output
    assert drawn == ["az", "ax"]


# ---- walk: a truth channel that is not a speed; a phone drive without --truth-channel ------
def test_truth_channel_mistakes_are_one_line(tmp_path):
    """``report --truth-channel gps_sats`` (a count, not m/s) is refused in one line, not a
    page with a "not compared" row; ``evaluate`` against a phone drive with GPS speed and no
    omega_true / speed_true says to give ``--truth-channel gps_speed``."""
    rec = _phone()
    rec.units["gps_sats"] = "1"
    io.write(rec, tmp_path / "phone.csv")
    tr = Track.from_speed(rec.t, np.full(len(rec), 9.5), np.full(len(rec), 0.2),
                          wheel_radius=R, method="test")
    io.write_track(tr, tmp_path / "est.csv", input_path=tmp_path / "phone.csv")
    line = one_line_error(run("report", tmp_path / "phone.csv", "--estimate",
                              tmp_path / "est.csv", "--truth-channel", "gps_sats",
                              "-o", tmp_path / "p.html"))
    assert "'gps_sats'" in line and "not a speed" in line
    assert not (tmp_path / "p.html").exists()
    line = one_line_error(run("evaluate", tmp_path / "est.csv", "--truth", tmp_path / "phone.csv"))
    assert "--truth-channel gps_speed" in line
