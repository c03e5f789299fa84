"""The estimate with its band as the three estimate panels draw it (vibrospeed.eval.plot
.plot_estimate): the track figure's omega panel, its speed panel (speed-only tracks and fuse)
and the report's speed panel, on a simulated 20 s car drive whose tracker sees no line in its
first half: the estimate dimmed exactly where no line is seen, full exactly where one is, jumps
broken, the band drawn, fuse coloured by source."""

from dataclasses import replace

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402

from vibrospeed import sim  # noqa: E402
from vibrospeed.estimators import get  # noqa: E402
from vibrospeed.eval import plot, report  # noqa: E402
from vibrospeed.types import Track  # noqa: E402

#: (rate, floor) of a jump that is broken, written out here as the independent reference:
#: 50 rad/s^2 and 2 rad/s for omega, 15 m/s^2 and 0.6 m/s for speed
JUMP = {"omega": (50.0, 2.0), "speed": (15.0, 0.6)}


@pytest.fixture(scope="module")
def drive():
    """The car drive, its grid track (no line seen before ~10.5 s, jumps there) and its fuse
    track (inertial for a few samples, then GPS)."""
    rec = sim.simulate("car", duration=20, seed=1)
    grid = get("grid").estimate(rec, axis="ay", wheel_radius=0.3)
    fuse = get("fuse").estimate(rec, axis="ay")
    seen = grid.extras["has_signal"] > 0.5
    assert 0.2 < seen.mean() < 0.8  # partly seen: both lines have samples
    return rec, grid, fuse


def _speed_only(track: Track) -> Track:
    """``track`` as a speed-only method's (no radius: no omega), with its ``has_signal``."""
    return Track.from_speed(track.t, track.speed, lo=track.speed_lo, hi=track.speed_hi,
                            method=track.method, extras={"has_signal": track.extras["has_signal"]})


def _report_ax(rec, track, monkeypatch):
    """The report's speed panel of ``track``, built as the page builds it."""
    figs = []
    monkeypatch.setattr(report, "_fig_uri", lambda fig: figs.append(fig) or "")
    report._speed_uri(rec, track, None)
    return figs[0], figs[0].axes[0]


def _per_sample(line, t):
    """The line's y per track sample (the NaN breaks put between samples taken out)."""
    x = np.asarray(line.get_xdata(), float)
    y = np.asarray(line.get_ydata(), float)
    brk = ~np.isfinite(x)
    assert np.isnan(y[brk]).all()
    np.testing.assert_array_equal(x[~brk], t)
    return y[~brk]


def _strokes(line):
    """The start times of the segments the line draws (between neighbours both finite)."""
    x = np.asarray(line.get_xdata(), float)
    y = np.asarray(line.get_ydata(), float)
    return x[:-1][np.isfinite(y[:-1]) & np.isfinite(y[1:])]


def _joined(t, y, quantity):
    """The start times of the segments a line of ``y`` (NaN where not drawn) must draw: its
    neighbours both finite that do not jump."""
    rate, floor = JUMP[quantity]
    with np.errstate(invalid="ignore"):
        hop = np.abs(np.diff(y)) > np.maximum(floor, rate * np.diff(t))
    return t[:-1][np.isfinite(y[:-1]) & np.isfinite(y[1:]) & ~hop]


def _legend(ax):
    return [x.get_text() for x in ax.get_legend().get_texts()]


def _check(ax, track, quantity):
    """The dimmed / full estimate, its breaks and band on ``ax``."""
    y, lo, hi = (getattr(track, quantity + k) for k in ("", "_lo", "_hi"))
    seen = track.extras["has_signal"] > 0.5
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    dim = _per_sample(lines["estimate, no line seen"], track.t)
    full = _per_sample(lines["estimate (grid)"], track.t)
    assert np.isfinite(y).all()
    np.testing.assert_array_equal(np.isnan(dim), seen)
    np.testing.assert_array_equal(np.isnan(full), ~seen)
    np.testing.assert_array_equal(dim[~seen], y[~seen])
    np.testing.assert_array_equal(full[seen], y[seen])
    # the tracker's hops (in the no-line stretch) are not joined by a stroke, the rest is
    assert (np.abs(np.diff(y)) > JUMP[quantity][1]).sum() >= 2  # there are hops to break
    for ln, drawn in ((lines["estimate, no line seen"], dim), (lines["estimate (grid)"], full)):
        np.testing.assert_array_equal(_strokes(ln), _joined(track.t, drawn, quantity))
    for ln in (lines["estimate, no line seen"], lines["estimate (grid)"]):
        assert to_rgba(ln.get_color())[:3] == to_rgba("tab:blue")[:3]
        assert ln.get_zorder() == 2.5 < lines["truth"].get_zorder()
    assert lines["estimate, no line seen"].get_alpha() == pytest.approx(0.35)
    band = [c for c in ax.collections
            if isinstance(c, PolyCollection) and c.get_label() == "98% band"]
    assert len(band) == 1
    ys = np.concatenate([p.vertices[:, 1] for p in band[0].get_paths()])
    assert ys.min() == pytest.approx(lo.min()) and ys.max() == pytest.approx(hi.max())
    assert {"98% band", "estimate, no line seen", "estimate (grid)", "truth"} <= set(_legend(ax))


def _check_sources(ax, track, quantity):
    """Fuse: one line per source present, in its colour, finite exactly on its samples."""
    y = getattr(track, quantity)
    src = track.extras["source"]
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    colours = {"fuse: inertial": (0.0, "tab:red"), "fuse: gps": (1.0, "tab:blue")}
    assert set(np.unique(src)) == {0.0, 1.0}
    for label, (code, colour) in colours.items():
        drawn = _per_sample(lines[label], track.t)
        assert to_rgba(lines[label].get_color())[:3] == to_rgba(colour)[:3]
        np.testing.assert_array_equal(np.isfinite(drawn), (src == code) & np.isfinite(y))
        np.testing.assert_array_equal(drawn[src == code], y[src == code])
        np.testing.assert_array_equal(_strokes(lines[label]), _joined(track.t, drawn, quantity))
    legend = _legend(ax)
    assert "fuse: inertial" in legend and "fuse: gps" in legend and "98% band" in legend
    assert "estimate, no line seen" not in legend and "fuse: vibration" not in legend


def test_track_figure_omega_panel(drive):
    rec, grid, _ = drive
    fig = plot.track_figure(rec, grid, axis="ay")
    try:
        assert fig.axes[1].get_ylabel() == "omega [rad/s]"
        _check(fig.axes[1], grid, "omega")
    finally:
        plt.close(fig)


def test_track_figure_speed_panel_of_a_speed_only_track(drive):
    """A speed-only track with has_signal is dimmed as the omega panel is (it was not)."""
    rec, grid, _ = drive
    track = _speed_only(grid)
    fig = plot.track_figure(rec, track, axis="ay")
    try:
        assert fig.axes[1].get_ylabel() == "speed [m/s]"
        _check(fig.axes[1], track, "speed")
    finally:
        plt.close(fig)


def test_report_speed_panel_breaks_jumps(drive, monkeypatch):
    """The report's panel draws what the figure's does, jumps broken (they were joined)."""
    rec, grid, _ = drive
    fig, ax = _report_ax(rec, grid, monkeypatch)
    try:
        assert ax.get_ylabel() == "speed [m/s]"
        _check(ax, grid, "speed")
    finally:
        plt.close(fig)


def test_fuse_is_coloured_by_source_in_the_figure_and_the_report(drive, monkeypatch):
    rec, _, fuse = drive
    fig = plot.track_figure(rec, fuse, axis="ay")
    try:
        _check_sources(fig.axes[1], fuse, "speed")
    finally:
        plt.close(fig)
    fig, ax = _report_ax(rec, fuse, monkeypatch)
    try:
        _check_sources(ax, fuse, "speed")
    finally:
        plt.close(fig)


def test_an_empty_band_and_an_unknown_quantity():
    """No band entry where the band has no value; a quantity other than omega / speed is an
    error naming it."""
    t = np.arange(0.0, 2.0, 0.01)
    track = Track.from_omega(t, np.full(t.size, 30.0), lo=np.full(t.size, np.nan),
                             hi=np.full(t.size, np.nan), method="m")
    fig, ax = plt.subplots()
    try:
        plot.plot_estimate(ax, track, "omega")
        assert ax.get_legend_handles_labels()[1] == ["estimate (m)"]
        assert not ax.collections
        with pytest.raises(ValueError, match="'accel'"):
            plot.plot_estimate(ax, track, "accel")
    finally:
        plt.close(fig)


def test_fuse_figure_draws_speed_over_r_on_the_spectrogram_where_a_line_is_seen(drive):
    """The fuse figure's cyan speed / r over the spectrogram follows track_figure's rule: NaN
    where the tracker sees no line (has_signal 0; not where the source is other than vibration:
    the line is read against the wheel line, and here GPS carries every moving sample, so that
    rule would draw nothing), the samples as they are where it sees one, and a hop of 6 rad/s
    put into the seen stretch not joined by a stroke; with no line seen anywhere, no cyan line."""
    rec, _, fuse = drive
    seen = fuse.extras["has_signal"] > 0.5
    assert 0.2 < seen.mean() < 0.8 and not (fuse.extras["source"] == 2).any()
    hop = fuse.t >= fuse.t[np.flatnonzero(seen)[seen.sum() // 2]]  # inside the seen stretch
    omega = fuse.omega + 6.0 * hop
    track = replace(fuse, omega=omega, extras=dict(fuse.extras))
    fig = plot.track_figure(rec, track, axis="ay")
    try:
        lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
        drawn = _per_sample(lines["estimate (speed / r)"], track.t)
        np.testing.assert_array_equal(np.isnan(drawn), ~seen)
        np.testing.assert_array_equal(drawn[seen], omega[seen])
        strokes = _strokes(lines["estimate (speed / r)"])
        np.testing.assert_array_equal(strokes, _joined(track.t, drawn, "omega"))
        i = np.flatnonzero(np.diff(hop.astype(int)))[0]  # the hop, both ends seen and drawn
        assert seen[i] and seen[i + 1] and track.t[i] not in strokes
        assert to_rgba(lines["estimate (speed / r)"].get_color())[:3] == to_rgba("cyan")[:3]
    finally:
        plt.close(fig)
    blind = replace(fuse, extras={**fuse.extras, "has_signal": np.zeros(len(fuse))})
    fig = plot.track_figure(rec, blind, axis="ay")
    try:
        assert "estimate (speed / r)" not in [ln.get_label() for ln in fig.axes[0].get_lines()]
    finally:
        plt.close(fig)


def test_no_line_seen_anywhere_gives_only_the_dimmed_entry():
    t = np.arange(0.0, 2.0, 0.01)
    track = Track.from_omega(t, np.full(t.size, 30.0), lo=np.full(t.size, 10.0),
                             hi=np.full(t.size, 120.0), method="m",
                             extras={"has_signal": np.zeros(t.size)})
    fig, ax = plt.subplots()
    try:
        plot.plot_estimate(ax, track, "omega")
        assert ax.get_legend_handles_labels()[1] == ["98% band", "estimate, no line seen"]
        (line,) = ax.get_lines()
        np.testing.assert_array_equal(_per_sample(line, t), track.omega)
    finally:
        plt.close(fig)
