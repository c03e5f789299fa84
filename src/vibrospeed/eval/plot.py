"""Plots: spectrogram of the vibration axis with the estimate, its band, harmonics and the truth.

Uses matplotlib's Agg backend (no screen needed); figures are written atomically.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vibrospeed.errors import InputError  # noqa: E402
from vibrospeed.io.atomic import atomic_path  # noqa: E402
from vibrospeed.signal.spectral import spectrogram  # noqa: E402
from vibrospeed.types import Recording, Track  # noqa: E402


def check_drawable(track: Track | None, name: str = "estimate") -> None:
    """One line where ``track`` has no finite omega or speed (a header without rows, a column
    of NaN): there is nothing to draw, and a page or figure without it reads as a result."""
    if track is not None and not (np.isfinite(track.omega).any()
                                  or np.isfinite(track.speed).any()):
        raise InputError(f"{name}: no finite omega or speed in its {len(track)} row(s): "
                         "nothing to draw")


def plot_track(
    path: str | Path,
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
) -> Path:
    """Spectrogram (dB) of channel ``axis`` with the track's omega, band and harmonics over it.

    Lower panel: omega (and speed axis when the radius is known) against time with the band and
    the truth (``omega_true`` of ``truth`` or of ``recording``; GPS speed / r when the radius is
    known). ``harmonics`` defaults to the track's M. ``posterior`` (n, N) over ``grid`` (N,)
    rad/s, from a grid tracker, is drawn as an image under the estimate (paper Fig. 3).
    """
    path = Path(path)
    check_drawable(track)
    speed_only = (track is not None and not np.isfinite(track.omega).any()
                  and np.isfinite(track.speed).any())
    if speed_only or (track is not None and "source" in track.extras):
        # GPS fusion / algebraic without a wheel radius, or fuse (speed coloured by its
        # source): lower panel in m/s
        return _plot_speed(path, recording, track, axis=axis, truth=truth, window_s=window_s,
                           title=title)
    if track is not None and isinstance(track.params.get("M"), int):
        harmonics = track.params["M"]
    fs = recording.fs
    x = recording.channel(axis)
    if omega_max is None:
        have = track is not None and np.isfinite(track.omega_hi).any()
        top = np.nanmax(track.omega_hi) if have else 60.0
        omega_max = float(min(np.pi * fs, max(30.0, 1.2 * harmonics * top)))
    sg = spectrogram(x, fs, window_s=window_s, t0=recording.t[0], omega_max=omega_max)
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(11, 7), sharex=True,
                                   gridspec_kw={"height_ratios": [3, 2]})
    db = 10 * np.log10(sg.power + 1e-20)
    vmax = np.percentile(db, 99.5)
    ax0.pcolormesh(sg.t, sg.omega, db, shading="auto", cmap="magma", vmin=vmax - 45, vmax=vmax)
    ax0.set_ylabel(f"{axis}: omega [rad/s]")
    ax0.set_ylim(0, omega_max)
    tr = truth if truth is not None else recording
    t_truth = om_truth = None
    if "omega_true" in tr.channels:
        t_truth, om_truth = tr.t, tr.channel("omega_true")
    elif "speed_true" in tr.channels and (track is not None and track.wheel_radius):
        t_truth, om_truth = tr.t, tr.channel("speed_true") / track.wheel_radius
    if track is not None and posterior is not None and grid is not None:
        post = np.asarray(posterior, dtype=np.float64)
        step = max(1, post.shape[0] // 1500)  # at most ~1500 image columns
        cols = post[: post.shape[0] // step * step].reshape(-1, step, post.shape[1]).mean(axis=1)
        tc = track.t[: cols.shape[0] * step : step]
        ax1.pcolormesh(tc, np.asarray(grid), np.log10(cols.T + 1e-12), shading="auto",
                       cmap="Greys", vmin=-6, vmax=0, alpha=0.8)
    if track is not None:
        shown = track.omega
        if "has_signal" in track.extras:  # harmonics only where the tracker sees a line
            shown = np.where(np.asarray(track.extras["has_signal"], float) > 0.5, shown, np.nan)
        for m in range(1, harmonics + 1):
            ax0.plot(track.t, m * shown, color="cyan", lw=0.8, alpha=0.9,
                     label="estimate x m" if m == 1 else None)
        ax1.fill_between(track.t, track.omega_lo, track.omega_hi, color="tab:blue", alpha=0.25,
                         lw=0, label=f"{track.level:.0%} band")
        if "has_signal" in track.extras:  # dim the estimate where the tracker sees no line
            sig = np.asarray(track.extras["has_signal"], float) > 0.5
            ax1.plot(track.t, np.where(sig, np.nan, track.omega), color="tab:blue", lw=0.6,
                     alpha=0.35, label="estimate, no line seen")
            ax1.plot(track.t, np.where(sig, track.omega, np.nan), color="tab:blue", lw=1.0,
                     label=f"estimate ({track.method})")
        else:
            ax1.plot(track.t, track.omega, color="tab:blue", lw=1.0,
                     label=f"estimate ({track.method})")
    if om_truth is not None:
        ax0.plot(t_truth, om_truth, color="lime", lw=0.8, ls="--", label="truth")
        ax1.plot(t_truth, om_truth, color="k", lw=0.9, ls="--", label="truth")
    if "gps_speed" in recording.channels and track is not None and track.wheel_radius:
        g = recording.channel("gps_speed")
        ok = np.isfinite(g)
        if ok.any():
            ax1.plot(recording.t[ok], g[ok] / track.wheel_radius, ".", ms=3, color="tab:orange",
                     label="GPS speed / r")
    for ax in (ax0, ax1):  # no estimate, truth or GPS: nothing labelled, no empty legend
        if ax.get_legend_handles_labels()[1]:
            ax.legend(loc="upper right", fontsize=8)
    ax1.set_ylabel("omega [rad/s]")
    ax1.set_xlabel("t [s]")
    ax1.grid(alpha=0.3)
    if track is not None and track.wheel_radius:
        r = track.wheel_radius
        sec = ax1.secondary_yaxis("right", functions=(lambda w: w * r, lambda v: v / r))
        sec.set_ylabel("speed [m/s]")
    ax0.set_title(title or f"{recording.source or 'recording'}")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".") or "png", bbox_inches="tight")
    plt.close(fig)
    return path


#: ``source`` code of a fused track -> (name, colour) (vibrospeed.estimators.fuse.SOURCES)
SOURCE_COLOURS = {0: ("inertial", "tab:red"), 1: ("gps", "tab:blue"),
                  2: ("vibration", "tab:green"), 3: ("standstill", "tab:gray")}


def _plot_speed(path: Path, recording: Recording, track: Track, *, axis: str,
                truth: Recording | None, window_s: float, title: str | None) -> Path:
    """Spectrogram of ``axis`` over a speed panel (m/s): estimate, band, truth, GPS fixes."""
    fs = recording.fs
    sg = spectrogram(recording.channel(axis), fs, window_s=window_s, t0=recording.t[0],
                     omega_max=float(min(np.pi * fs, 300.0)))
    fig, (ax0, ax1) = plt.subplots(2, 1, figsize=(11, 7), sharex=True,
                                   gridspec_kw={"height_ratios": [2, 3]})
    db = 10 * np.log10(sg.power + 1e-20)
    vmax = np.percentile(db, 99.5)
    ax0.pcolormesh(sg.t, sg.omega, db, shading="auto", cmap="magma", vmin=vmax - 45, vmax=vmax)
    ax0.set_ylabel(f"{axis}: omega [rad/s]")
    ax1.fill_between(track.t, track.speed_lo, track.speed_hi, color="tab:blue", alpha=0.25,
                     lw=0, label=f"{track.level:.0%} band")
    if "source" in track.extras:  # fuse: what each sample's speed rests on
        src = np.asarray(track.extras["source"], float)
        for code, (name, colour) in SOURCE_COLOURS.items():
            sel = src == code
            if sel.any():
                ax1.plot(track.t, np.where(sel, track.speed, np.nan), color=colour, lw=1.2,
                         label=f"{track.method}: {name}")
    else:
        ax1.plot(track.t, track.speed, color="tab:blue", lw=1.0,
                 label=f"estimate ({track.method})")
    tr = truth if truth is not None else recording
    if "speed_true" in tr.channels:
        ax1.plot(tr.t, tr.channel("speed_true"), color="k", lw=0.9, ls="--", label="truth")
    if "gps_speed" in recording.channels:
        g = recording.channel("gps_speed")
        ok = np.isfinite(g)
        ax1.plot(recording.t[ok], g[ok], ".", ms=3, color="tab:orange", label="GPS speed")
    ax1.set_ylabel("speed [m/s]")
    ax1.set_xlabel("t [s]")
    ax1.legend(loc="upper right", fontsize=8)
    ax1.grid(alpha=0.3)
    ax0.set_title(title or f"{recording.source or 'recording'}")
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format=path.suffix.lstrip(".") or "png", bbox_inches="tight")
    plt.close(fig)
    return path
