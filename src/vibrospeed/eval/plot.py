"""Plots: spectrogram of the vibration axis with the estimate, its band, harmonics and the truth.

Uses matplotlib's Agg backend (no screen needed); figures are written atomically.
:func:`track_figure` builds the figure (tests read its artists), :func:`plot_track` writes it.
Legends sit outside the axes (never over the data), GPS fixes are drawn under the estimate,
fixes a method ignores (too few satellites) are marked as such, and detected standstills and
stretches without an estimate (NaN) are shaded, so none of them reads as a measured speed.
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import matplotlib

matplotlib.use("Agg")
import matplotlib.patheffects as pe  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vibrospeed.errors import InputError  # noqa: E402
from vibrospeed.io.atomic import atomic_path  # noqa: E402
from vibrospeed.signal.spectral import spectrogram  # noqa: E402
from vibrospeed.types import Recording, Track  # noqa: E402

#: a dark edge under the lines drawn over the spectrogram: lime or cyan alone vanish over its
#: bright (yellow) cells, which are where the wheel line is
_OUTLINE = [pe.Stroke(linewidth=2.0, foreground="black", alpha=0.7), pe.Normal()]

#: logs longer than this (s) get the fundamental alone over the spectrogram: at several seconds
#: per pixel the harmonics' strokes cover the image they are meant to be read against
LONG_LOG_S = 1800.0

#: z-order: GPS fixes under the band's edge lines, the estimate over them, the truth on top
_Z_GPS, _Z_EST, _Z_TRUTH = 1.5, 2.5, 3.0


class Spectrum(NamedTuple):
    """A spectrogram computed elsewhere, drawn by :func:`track_figure` in place of its own: the
    streamed estimate's (:class:`vibrospeed.estimators.grid.stream.StreamPlot`, built block by
    block in bounded memory), so a long log's figure is this module's figure."""

    t: np.ndarray  #: (frames,) s, centre of each window
    omega: np.ndarray  #: (bins,) rad/s
    power: np.ndarray  #: (bins, frames) power density
    label: str  #: what the panel's y label says of it, e.g. "STFT 3 s, every 0.75 s"


def spectrogram_top(fs: float, harmonics: int, top: float | None) -> float:
    """The spectrogram's height in rad/s: 1.2 ``harmonics`` times the band's highest edge
    ``top`` (60 rad/s where there is none), at least 30 rad/s, at most Nyquist."""
    top = top if top is not None and np.isfinite(top) else 60.0
    return float(min(np.pi * fs, max(30.0, 1.2 * harmonics * top)))


def check_drawable(track: Track | None, name: str = "estimate") -> None:
    """One line where ``track`` has no finite omega or speed (a header without rows, a column
    of NaN): there is nothing to draw, and a page or figure without it reads as a result."""
    if track is not None and not (np.isfinite(track.omega).any()
                                  or np.isfinite(track.speed).any()):
        raise InputError(f"{name}: no finite omega or speed in its {len(track)} row(s): "
                         "nothing to draw")


def stft_window(recording: Recording, window_s: float) -> float:
    """The STFT window actually used: ``window_s``, shortened to an eighth of a short log (at
    least 0.25 s) so a few-second log still shows several spectrogram columns."""
    return float(min(window_s, max(0.25, recording.duration / 8.0)))


#: (rate, floor) of the jumps :func:`plot_estimate` breaks: for omega in rad/s^2 and rad/s (50
#: rad/s^2 is past a car's braking on its wheels), for speed in m/s^2 and m/s (the same at a
#: 0.3 m wheel: 15 m/s^2, 1.5 g), so a speed panel breaks what the omega panel breaks
_JUMPS = {"omega": (50.0, 2.0), "speed": (15.0, 0.6)}


def _jump_at(t: np.ndarray, y: np.ndarray, rate: float, floor: float) -> np.ndarray:
    """Indices before which ``y`` jumps by more than ``max(floor, rate dt)`` (NaN never does)."""
    with np.errstate(invalid="ignore"):
        hop = np.abs(np.diff(y)) > np.maximum(floor, rate * np.diff(t))
    return np.flatnonzero(hop) + 1


def break_jumps(t: np.ndarray, y: np.ndarray, *, rate: float = 50.0,
                floor: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """``t``, ``y`` with a NaN put between samples where ``y`` jumps by more than
    ``max(floor, rate dt)`` (rad/s; 50 rad/s^2 is past a car's braking on its wheels), so a
    tracker's hop reads as a jump, not as a vertical stroke through the spectrogram."""
    t = np.asarray(t, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    if len(y) < 2:
        return t, y
    at = _jump_at(t, y, rate, floor)
    return np.insert(t, at, np.nan), np.insert(y, at, np.nan)


def legend_outside(ax, *, right_axis: bool = False) -> None:
    """Legend to the right of ``ax`` (past a secondary y axis): it never covers data."""
    if ax.get_legend_handles_labels()[1]:
        ax.legend(loc="upper left", bbox_to_anchor=(1.09 if right_axis else 1.01, 1.0),
                  fontsize=8, borderaxespad=0.0)


def _share(mask: np.ndarray) -> str:
    """``mask``'s share of the samples in percent; a share that is not 0 never reads 0."""
    share = 100.0 * float(np.mean(mask))
    return f"{share:.1f} %" if share >= 0.05 else "< 0.1 %"


def shade_stretches(ax, track: Track, y: np.ndarray) -> None:
    """Shade, over the whole height of ``ax``, where the track flags a standstill and where
    ``y`` (its omega or speed) is NaN, with their shares of the samples in the legend (a few
    NaN samples are too narrow to see): one artist each, so a 2 h log stays light."""
    tr = ax.get_xaxis_transform()
    if "standstill" in track.extras:
        still = np.asarray(track.extras["standstill"], dtype=np.float64) > 0.5
        if still.any():
            ax.fill_between(track.t, 0, 1, where=still, transform=tr, color="0.55", alpha=0.2,
                            lw=0, step="mid", label=f"standstill detected ({_share(still)})")
    gap = ~np.isfinite(np.asarray(y, dtype=np.float64))
    if gap.any():
        ax.fill_between(track.t, 0, 1, where=gap, transform=tr, facecolor="none",
                        edgecolor="tab:red", hatch="///", alpha=0.5, lw=0, step="mid",
                        label=f"no estimate, NaN ({_share(gap)})")


def plot_gps(ax, recording: Recording, track: Track | None, scale: float, label: str) -> None:
    """GPS speed fixes times ``scale`` under the estimate; fixes with fewer satellites than the
    track's ``min_sats`` (1 where the method has none: 0 satellites is no fix) are marked as
    ignored, not drawn as a speed (a tunnel's receiver reports 0 m/s)."""
    if "gps_speed" not in recording.channels:
        return
    g = recording.channel("gps_speed")
    ok = np.isfinite(g)
    used = ok
    if "gps_sats" in recording.channels:
        min_sats = track.params.get("min_sats") if track is not None else None
        sats = np.nan_to_num(recording.channel("gps_sats"), nan=np.inf)
        used = ok & (sats >= float(min_sats or 1))
        ignored = ok & ~used
        if ignored.any():
            ax.plot(recording.t[ignored], g[ignored] * scale, "x", ms=3, color="0.45",
                    alpha=0.6, zorder=_Z_GPS,
                    label=f"GPS fix ignored (< {min_sats:g} satellites)" if min_sats
                    else "GPS, 0 satellites (no fix)")
    if used.any():
        ax.plot(recording.t[used], g[used] * scale, ".", ms=2.5, alpha=0.5, color="tab:orange",
                zorder=_Z_GPS, label=label)


def _spectrogram_panel(ax, recording: Recording, axis: str, window_s: float,
                       omega_max: float, spectrum: Spectrum | None = None) -> None:
    if spectrum is None:
        w = stft_window(recording, window_s)
        sg = spectrogram(recording.channel(axis), recording.fs, window_s=w, t0=recording.t[0],
                         omega_max=omega_max)
        spectrum = Spectrum(sg.t, sg.omega, sg.power, f"STFT {w:.3g} s")
    keep = np.asarray(spectrum.omega) <= omega_max
    db = 10 * np.log10(np.asarray(spectrum.power)[keep] + 1e-20)
    vmax = np.percentile(db, 99.5)
    ax.pcolormesh(spectrum.t, np.asarray(spectrum.omega)[keep], db, shading="auto",
                  cmap="magma", vmin=vmax - 45, vmax=vmax, rasterized=True)
    ax.set_ylabel(f"{axis}: omega [rad/s]\n({spectrum.label}, 45 dB)")
    ax.set_ylim(0, omega_max)


def _omega_over_line(track: Track) -> tuple[np.ndarray, np.ndarray]:
    """The track's omega as drawn over the spectrogram, to be read against the wheel line:
    only where the tracker sees a line (``has_signal`` > 0.5, where the track has it; elsewhere
    there is no line to read it against), jumps broken (:func:`break_jumps`)."""
    shown = np.asarray(track.omega, dtype=np.float64)
    if "has_signal" in track.extras:
        shown = np.where(np.asarray(track.extras["has_signal"], float) > 0.5, shown, np.nan)
    return break_jumps(track.t, shown, rate=_JUMPS["omega"][0], floor=_JUMPS["omega"][1])


def _truth_omega(recording: Recording, truth: Recording | None, track: Track | None):
    tr = truth if truth is not None else recording
    if "omega_true" in tr.channels:
        return tr.t, tr.channel("omega_true")
    if "speed_true" in tr.channels and track is not None and track.wheel_radius:
        return tr.t, tr.channel("speed_true") / track.wheel_radius
    return None, None


def track_figure(
    recording: Recording,
    track: Track | None = None,
    *,
    axis: str = "ay",
    truth: Recording | None = None,
    harmonics: int = 3,
    omega_max: float | None = None,
    window_s: float = 3.0,
    title: str | None = None,
    posterior: np.ndarray | None = None,
    grid: np.ndarray | None = None,
    spectrum: Spectrum | None = None,
    gps: Recording | None = None,
):
    """The figure of :func:`plot_track` (not written; the caller closes it); ``spectrum``: a
    spectrogram computed elsewhere (a streamed log's) drawn instead of the recording's;
    ``gps``: the GPS channels (``gps_speed``, ``gps_sats``) on their own time line, drawn
    instead of the recording's (a streamed log keeps its fixes only)."""
    check_drawable(track)
    speed_only = (track is not None and not np.isfinite(track.omega).any()
                  and np.isfinite(track.speed).any())
    if speed_only or (track is not None and "source" in track.extras):
        # GPS fusion / algebraic without a wheel radius, or fuse (speed coloured by its
        # source): lower panel in m/s
        return _speed_figure(recording, track, axis=axis, truth=truth, window_s=window_s,
                             title=title, spectrum=spectrum, gps=gps)
    if track is not None and isinstance(track.params.get("M"), int):
        harmonics = track.params["M"]
    drawn = 1 if recording.duration > LONG_LOG_S else harmonics
    fs = recording.fs
    if omega_max is None:
        have = track is not None and np.isfinite(track.omega_hi).any()
        omega_max = spectrogram_top(fs, harmonics,
                                    float(np.nanmax(track.omega_hi)) if have else None)
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(12.5, 7), sharex=True,
                                   gridspec_kw={"height_ratios": [3, 2]})
    _spectrogram_panel(ax0, recording, axis, window_s, omega_max, spectrum)
    t_truth, om_truth = _truth_omega(recording, truth, track)
    if track is not None and posterior is not None and grid is not None:
        post = np.asarray(posterior, dtype=np.float64)
        step = max(1, post.shape[0] // 1500)  # at most ~1500 image columns
        cols = post[: post.shape[0] // step * step].reshape(-1, step, post.shape[1]).mean(axis=1)
        tc = track.t[: cols.shape[0] * step : step]
        ax1.pcolormesh(tc, np.asarray(grid), np.log10(cols.T + 1e-12), shading="auto",
                       cmap="Greys", vmin=-6, vmax=0, alpha=0.8, rasterized=True)
    if track is not None:
        shade_stretches(ax1, track, track.omega)
        tj, shown = _omega_over_line(track)
        for m in range(1, drawn + 1):
            ax0.plot(tj, m * shown, color="cyan", lw=0.8, alpha=0.9, zorder=_Z_EST,
                     path_effects=_OUTLINE,
                     label=(f"estimate x m, m = 1..{drawn}" if drawn > 1 else "estimate")
                     if m == 1 else None)
        plot_estimate(ax1, track, "omega")
    if om_truth is not None:
        ax0.plot(t_truth, om_truth, color="lime", lw=0.8, ls="--", zorder=_Z_TRUTH,
                 path_effects=_OUTLINE,
                 label="truth")
        ax1.plot(t_truth, om_truth, color="k", lw=0.9, ls="--", zorder=_Z_TRUTH, label="truth")
    radius = track.wheel_radius if track is not None else None
    if radius:
        plot_gps(ax1, recording if gps is None else gps, track, 1.0 / radius, "GPS speed / r")
        sec = ax1.secondary_yaxis("right", functions=(lambda w: w * radius,
                                                      lambda v: v / radius))
        sec.set_ylabel("speed [m/s]")
    legend_outside(ax0)
    legend_outside(ax1, right_axis=bool(radius))
    ax1.set_ylabel("omega [rad/s]")
    _finish(fig, ax0, ax1, recording, title)
    return fig


def plot_streamed(path: str | Path, drawing) -> Path:
    """The figure of a streamed estimate (:class:`vibrospeed.estimators.grid.stream.StreamPlot`,
    its kept samples and decimated spectrogram) as :func:`plot_track` draws a whole log's:
    legends beside the axes, standstills and NaN stretches shaded, GPS under the estimate and
    the truth where the reading kept them; written atomically."""
    sp, over = drawing, drawing.overlay
    spectrum = Spectrum(sp.t, sp.omega, sp.power, f"STFT {sp.window_s:.3g} s every "
                        f"{sp.hop_s:.3g} s")
    every = "every sample" if sp.k == 1 else f"every {sp.k} samples"
    return plot_track(path, sp.rec, sp.track(), axis=sp.channel, spectrum=spectrum,
                      truth=over.truth() if over is not None else None,
                      gps=over.gps() if over is not None else None,
                      omega_max=spectrogram_top(sp.fs, sp.M, sp.top if np.isfinite(sp.top)
                                                else None),
                      title=f"{sp.source or 'recording'} (streamed: spectrogram every "
                            f"{sp.hop_s:.3g} s, estimate {every})")


def plot_track(path: str | Path, recording: Recording, track: Track | None = None,
               **kw) -> Path:
    """Spectrogram (dB) of channel ``axis`` with the track's omega, band and harmonics over it.

    Lower panel: omega (and speed axis when the radius is known) against time with the band and
    the truth (``omega_true`` of ``truth`` or of ``recording``; GPS speed / r when the radius is
    known), detected standstills and NaN stretches shaded. ``harmonics`` defaults to the track's
    M. ``posterior`` (n, N) over ``grid`` (N,) rad/s, from a grid tracker, is drawn as an image
    under the estimate (paper Fig. 3). A track without omega (GPS fusion, algebraic) gets a
    speed panel in m/s. Keywords as :func:`track_figure`.
    """
    path = Path(path)
    fig = track_figure(recording, track, **kw)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".") or "png", bbox_inches="tight")
    plt.close(fig)
    return path


def _finish(fig, ax0, ax1, recording: Recording, title: str | None) -> None:
    """Time axis over the recording's span (a short log fills the width), grid, title."""
    ax1.set_xlim(recording.t[0], recording.t[-1])
    ax1.set_xlabel("t [s]")
    ax1.grid(alpha=0.3)
    ax0.set_title(title or f"{recording.source or 'recording'}")
    fig.tight_layout()


#: ``source`` code of a fused track -> (name, colour) (vibrospeed.estimators.fuse.SOURCES)
SOURCE_COLOURS = {0: ("inertial", "tab:red"), 1: ("gps", "tab:blue"),
                  2: ("vibration", "tab:green"), 3: ("standstill", "tab:gray")}


def plot_estimate(ax, track: Track, quantity: str = "omega", *,
                  label: str | None = None) -> None:
    """The track's ``quantity`` ("omega" or "speed") with its band on ``ax``, as every estimate
    panel draws it (the figure's lower panel, the report's speed panel), so they show the same:
    the band where it has values; the estimate dimmed where the tracker sees no line
    (``has_signal`` <= 0.5: there it is the prior carried on, not a measurement) or, for fuse
    (``source``), coloured by what each sample rests on (inertial, GPS, vibration, standstill:
    a GPS-borne speed is measured though no line is seen); jumps (:data:`_JUMPS`) broken, so a
    hop or a standstill's drop to 0 is not joined by a stroke. ``label``: the full line's legend
    entry (default ``estimate (method)``)."""
    if quantity not in _JUMPS:
        raise ValueError(f"quantity {quantity!r}: not one of {sorted(_JUMPS)}")
    t = np.asarray(track.t, dtype=np.float64)
    y, lo, hi = (np.asarray(getattr(track, quantity + k), dtype=np.float64)
                 for k in ("", "_lo", "_hi"))
    if np.isfinite(lo).any() and np.isfinite(hi).any():  # an empty band is no band
        ax.fill_between(t, lo, hi, color="tab:blue", alpha=0.25, lw=0,
                        label=f"{track.level:.0%} band")
    at = _jump_at(t, y, *_JUMPS[quantity])
    tj = np.insert(t, at, np.nan)

    def draw(sel: np.ndarray, **kw) -> None:
        ax.plot(tj, np.insert(np.where(sel, y, np.nan), at, np.nan), zorder=_Z_EST, **kw)

    label = label or f"estimate ({track.method or '?'})"
    if "source" in track.extras:
        src = np.asarray(track.extras["source"], dtype=np.float64)
        for code, (name, colour) in SOURCE_COLOURS.items():
            if (src == code).any():
                draw(src == code, color=colour, lw=1.2, label=f"{track.method}: {name}")
    elif "has_signal" in track.extras:
        seen = np.asarray(track.extras["has_signal"], dtype=np.float64) > 0.5
        if not seen.all():
            draw(~seen, color="tab:blue", lw=0.6, alpha=0.35, label="estimate, no line seen")
        if seen.any():  # no line seen anywhere: no empty legend entry
            draw(seen, color="tab:blue", lw=1.0, label=label)
    else:
        draw(np.ones(t.size, dtype=bool), color="tab:blue", lw=1.0, label=label)


def _speed_figure(recording: Recording, track: Track, *, axis: str, truth: Recording | None,
                  window_s: float, title: str | None, spectrum: Spectrum | None = None,
                  gps: Recording | None = None):
    """Spectrogram of ``axis`` (with omega where the track has it, drawn as track_figure draws
    it: where a line is seen, jumps broken) over a speed panel (m/s): estimate, band, truth, GPS
    fixes."""
    fs = recording.fs
    have_omega = np.isfinite(track.omega).any()
    top = float(np.nanmax(track.omega)) if have_omega else 0.0
    omega_max = float(min(np.pi * fs, max(300.0, 1.5 * top)))
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(12.5, 7), sharex=True,
                                   gridspec_kw={"height_ratios": [2, 3]})
    _spectrogram_panel(ax0, recording, axis, window_s, omega_max, spectrum)
    if have_omega:  # fuse: its speed / learned radius over the wheel line, where one is seen
        tj, shown = _omega_over_line(track)
        if np.isfinite(shown).any():
            ax0.plot(tj, shown, color="cyan", lw=0.8, alpha=0.9, zorder=_Z_EST,
                     path_effects=_OUTLINE, label="estimate (speed / r)")
        t_truth, om_truth = _truth_omega(recording, truth, None)
        if om_truth is not None:
            ax0.plot(t_truth, om_truth, color="lime", lw=0.8, ls="--", zorder=_Z_TRUTH,
                     path_effects=_OUTLINE,
                     label="truth")
    shade_stretches(ax1, track, track.speed)
    plot_estimate(ax1, track, "speed")
    tr = truth if truth is not None else recording
    if "speed_true" in tr.channels:
        ax1.plot(tr.t, tr.channel("speed_true"), color="k", lw=0.9, ls="--", zorder=_Z_TRUTH,
                 label="truth")
    plot_gps(ax1, recording if gps is None else gps, track, 1.0, "GPS speed")
    legend_outside(ax0)
    legend_outside(ax1)
    ax1.set_ylabel("speed [m/s]")
    _finish(fig, ax0, ax1, recording, title)
    return fig
