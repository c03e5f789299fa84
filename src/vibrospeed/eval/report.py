"""One self-contained HTML page per drive, and an index page for a batch.

:func:`write_report` puts on one page: the summary numbers (duration, distance, median speed,
share of the time with a wheel line, method, parameters; against the truth where the recording
has one), the spectrogram with the estimate, its band and the truth or GPS
(:func:`vibrospeed.eval.plot.plot_track`), the speed over time with the stretches where a wheel
line was seen, and the notes of the recording and of the estimate. The numbers are
:func:`vibrospeed.eval.metrics.track_summary`'s, the rule of a batch row, so the page and the row
never disagree: a drive where nothing was measured shows the note instead of a distance and
medians. Images are PNGs embedded as ``data:`` URIs; the page has no external URL and no
script, so it can be mailed or archived as one file. :func:`write_index` lists a batch's
recordings with links to their pages.
"""

from __future__ import annotations

import base64
import html
import io as _io
import math
import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vibrospeed.io.atomic import atomic_write_text  # noqa: E402
from vibrospeed.types import Recording, Track  # noqa: E402

__all__ = ["render_report", "signal_intervals", "write_index", "write_report"]

_CSS = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:2em auto;max-width:1100px;
color:#222;padding:0 1em}
h1{font-size:1.4em;word-break:break-all}h2{font-size:1.15em;margin-top:1.6em;
border-bottom:1px solid #ddd}
table{border-collapse:collapse;margin:.5em 0}td,th{padding:.2em .7em;border-bottom:1px solid #eee;
text-align:left;vertical-align:top}th{background:#f5f5f5}td.num{text-align:right;
font-variant-numeric:tabular-nums}
img{max-width:100%;height:auto;border:1px solid #eee}
.ok{color:#176c2c}.error{color:#b00020}.skipped{color:#666}
details{margin:.5em 0}code{font-size:.95em}.muted{color:#666}
"""


def _esc(x: Any) -> str:
    return html.escape(str(x), quote=True)


def _num(x: float | None, fmt: str = ".3g", unit: str = "") -> str:
    if x is None or not isinstance(x, (int, float)) or not math.isfinite(x):
        return "–"
    return f"{x:{fmt}}{(' ' + unit) if unit else ''}"


def _png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _fig_uri(fig) -> str:
    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=100, bbox_inches="tight")
    plt.close(fig)
    return _png_uri(buf.getvalue())


def signal_intervals(t: np.ndarray, has_signal: np.ndarray) -> list[tuple[float, float]]:
    """The stretches ``(start, end)`` in s where ``has_signal`` is set."""
    t = np.asarray(t, dtype=np.float64)
    s = np.asarray(has_signal, dtype=np.float64) > 0.5
    if not s.any():
        return []
    d = np.diff(np.r_[0, s.astype(np.int8), 0])
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return [(float(t[a]), float(t[b])) for a, b in zip(starts, ends, strict=True)]


def _spectrogram_uri(rec: Recording, track: Track, axis: str, truth: Recording | None,
                     posterior, grid, title: str) -> str:
    from vibrospeed.eval.plot import plot_track

    with tempfile.TemporaryDirectory(prefix="vibrospeed-report-") as d:
        png = Path(d) / "spectrogram.png"
        plot_track(png, rec, track, axis=axis, truth=truth, posterior=posterior, grid=grid,
                   title=title)
        return _png_uri(png.read_bytes())


def _speed_uri(rec: Recording, track: Track, truth: Recording | None) -> str:
    """Speed (m/s; omega in rad/s without a wheel radius) against time, with the band, the
    truth and GPS (under the estimate; fixes the method ignores marked), the stretches with a
    wheel line, detected standstills and NaN stretches shaded; the legend beside the plot. The
    estimate and its band are :func:`vibrospeed.eval.plot.plot_estimate`'s, as in the figure."""
    from vibrospeed.eval.plot import legend_outside, plot_estimate, plot_gps, shade_stretches

    r = track.wheel_radius
    as_speed = np.isfinite(track.speed).any()
    y = track.speed if as_speed else track.omega
    unit = "m/s" if as_speed else "rad/s"
    fig, ax = plt.subplots(figsize=(12.5, 3.6))
    sig = track.extras.get("has_signal")
    if sig is not None and np.any(np.asarray(sig, dtype=np.float64) > 0.5):
        # one artist however many stretches (a 2 h log has hundreds); none seen: no entry
        ax.fill_between(track.t, 0, 1, where=np.asarray(sig, dtype=np.float64) > 0.5,
                        transform=ax.get_xaxis_transform(), color="tab:green", alpha=0.12,
                        lw=0, step="mid", label="wheel line seen")
    shade_stretches(ax, track, y)
    plot_estimate(ax, track, "speed" if as_speed else "omega")
    scale = 1.0 if as_speed else (1.0 / r if r else None)
    if scale is not None:
        plot_gps(ax, rec, track, scale, "GPS speed" + ("" if as_speed else " / r"))
    ref = truth if truth is not None else rec
    if as_speed and "speed_true" in ref.channels:
        ax.plot(ref.t, ref.channel("speed_true"), "k--", lw=0.9, zorder=3, label="truth")
    elif not as_speed and "omega_true" in ref.channels:
        ax.plot(ref.t, ref.channel("omega_true"), "k--", lw=0.9, zorder=3, label="truth")
    ax.set_xlim(rec.t[0], rec.t[-1])
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{'speed' if as_speed else 'omega'} [{unit}]")
    ax.grid(alpha=0.3)
    legend_outside(ax)
    fig.tight_layout()
    return _fig_uri(fig)


def _table(rows: Sequence[tuple[str, str]]) -> str:
    body = "".join(f"<tr><th>{_esc(k)}</th><td>{_esc(v)}</td></tr>"
                   for k, v in rows)
    return f"<table>{body}</table>"


def _truth_rows(track: Track, rec: Recording, truth: Recording | None,
                truth_channel: str | None = None) -> list[tuple[str, str]]:
    """The summary's rows against the truth (``truth``, else the recording): ``truth_channel``
    as ``vibrospeed evaluate --truth-channel`` (``gps_speed``: the drive against its own GPS);
    a channel asked for that is missing or not a speed is the caller's one-line error; without
    one asked for, a failure is a row."""
    ref = truth if truth is not None else rec
    if truth_channel is not None:
        ref.require(truth_channel)  # asked for: missing or all NaN is an error, not a row
    elif not ({"omega_true", "speed_true"} & set(ref.channels)):
        return []
    from vibrospeed.eval.metrics import evaluate

    try:
        m = evaluate(track, ref, truth_channel=truth_channel)
    except Exception as exc:  # noqa: BLE001 - the comparison is a bonus, never a reason to fail
        if truth_channel is not None:  # asked for: a page without it would hide the mistake
            raise
        return [("against the truth", f"not compared: {exc}")]
    if m.n == 0:  # a row of dashes would read as a missing number, not as no overlap
        return [("against the truth", f"not compared: no moving truth sample ({ref.t[0]:g}-"
                 f"{ref.t[-1]:g} s) where the estimate ({track.t[0]:g}-{track.t[-1]:g} s) "
                 "has a value")]
    rows = [("truth channel", truth_channel)] if truth_channel else []
    rows += [("RMSE against the truth", _num(m.rmse, ".3f", m.unit)),
            ("bias against the truth", _num(m.bias, "+.3f", m.unit)),
            (f"coverage of the {m.level:.0%} band", _num(100 * m.coverage, ".1f", "%"))]
    if m.unit != "m/s":
        rows.append(("within max(2 rad/s, 10 %)", _num(100 * m.ok_share, ".1f", "%")))
    return rows


def _radius_rows(track: Track, s: dict[str, Any]) -> list[tuple[str, str]]:
    """The summary's row of a radius the method fitted on this drive
    (:func:`vibrospeed.eval.metrics.radius_fit`, the batch's ``fitted_radius`` /
    ``fitted_radius_std``): for ``fuse`` the radius it learned, or that it learned none and kept
    its prior (its sidecar's ``learned_radius`` is then that prior, not a measurement to re-use
    with ``radius_from``); for other methods only where they fit one."""
    def pm(r: float, std: float, fmt: str) -> str:
        return f"{r:{fmt}}" + (f" ± {std:.2g}" if math.isfinite(std) else "") + " m"

    r, rs = s["fitted_radius"], s.get("fitted_radius_std", math.nan)
    par = track.params if isinstance(track.params, dict) else {}
    if track.method == "fuse" and "learned_radius" in par:
        if math.isfinite(r):
            return [("learned wheel radius", pm(r, rs, ".4f"))]
        prior = par.get("radius_prior")
        r0, s0 = prior if isinstance(prior, (list, tuple)) and len(prior) == 2 else (
            par.get("learned_radius"), None)
        r0, s0 = (float(x) if isinstance(x, (int, float)) else math.nan for x in (r0, s0))
        kept = f"the prior {pm(r0, s0, '.4f')} kept" if math.isfinite(r0) else "the prior kept"
        return [("learned wheel radius",
                 f"not learned (no wheel line while GPS was good): {kept}")]
    if math.isfinite(r):
        return [("fitted wheel radius", pm(r, rs, ".4g"))]
    return []


def render_report(
    recording: Recording,
    track: Track,
    *,
    axis: str = "ay",
    truth: Recording | None = None,
    posterior: np.ndarray | None = None,
    grid: np.ndarray | None = None,
    title: str | None = None,
    input_path: str | os.PathLike[str] | None = None,
    estimate_path: str | os.PathLike[str] | None = None,
    recording_notes: Sequence[str] | None = None,
    truth_channel: str | None = None,
) -> str:
    """The HTML text of a drive's report (see :func:`write_report`); ``truth_channel``: the
    channel of ``truth`` (or of the recording) the estimate is scored against, as ``vibrospeed
    evaluate --truth-channel`` (default ``omega_true`` / ``speed_true``)."""
    from vibrospeed import __version__
    from vibrospeed.eval.metrics import track_summary
    from vibrospeed.eval.plot import check_drawable

    check_drawable(track, os.fspath(estimate_path) if estimate_path else "estimate")
    rec = recording
    title = title or rec.source or (os.fspath(input_path) if input_path else "recording")
    s = track_summary(track)
    notes_rec = list(recording_notes) if recording_notes is not None else list(rec.notes)
    rows = [
        ("recording", os.fspath(input_path) if input_path else (rec.source or "")),
        ("duration", _num(rec.duration, ".1f", "s")),
        ("samples", f"{len(rec)} at {rec.fs:.4g} Hz"),
        ("method", track.method or "?"),
        ("distance", _num(s["distance_m"], ".1f", "m")),
        ("distance at the speed band's edges",
         f"{s['distance_lo_m']:.1f} – {s['distance_hi_m']:.1f} m"
         if math.isfinite(s["distance_lo_m"]) and math.isfinite(s["distance_hi_m"]) else "–"),
        ("median speed", _num(s["median_speed"], ".2f", "m/s")
         + (f" ({s['median_speed'] * 3.6:.1f} km/h)" if math.isfinite(s["median_speed"])
            else "")),
        ("median omega", _num(s["median_omega"], ".2f", "rad/s")),
    ]
    if s["note"]:  # nothing measured: the numbers above are empty, the note says why
        rows.append(("note", s["note"]))
    rows += [
        ("share with a wheel line", _num(100 * s["signal_share"], ".1f", "%")
         if math.isfinite(s["signal_share"]) else "– (the method has no line detector)"),
        ("wheel radius", _num(track.wheel_radius, ".4g", "m")),
    ]
    rows += _radius_rows(track, s)
    if estimate_path:
        rows.append(("estimate file", os.fspath(estimate_path)))
    rows += _truth_rows(track, rec, truth, truth_channel)
    spec = _spectrogram_uri(rec, track, axis, truth, posterior, grid, title)
    speed = _speed_uri(rec, track, truth)
    sig = track.extras.get("has_signal")
    if sig is not None:
        iv = signal_intervals(track.t, sig)
        shown = iv[:40]
        items = "".join(f"<li>{a:.1f} – {b:.1f} s</li>" for a, b in shown)
        more = f"<p class=\"muted\">… and {len(iv) - len(shown)} more</p>" if len(iv) > 40 else ""
        line = (f"<p>A wheel line was seen during {len(iv)} stretch(es), "
                f"{_num(100 * s['signal_share'], '.1f', '%')} of the samples (green in the speed "
                f"plot):</p><ul>{items}</ul>{more}" if iv else
                "<p>No wheel line was seen in this drive, and no GPS: wherever no standstill "
                "was detected the estimate is the tracker's prior carried through the drive "
                "with a wide band, not a measurement, so the summary leaves its distance and "
                "medians empty.</p>"
                if s["note"] else
                "<p>No wheel line was seen in this drive; the summary numbers rest on what "
                "was measured instead (a detected standstill, or GPS fixes for fuse).</p>")
    else:
        line = (f"<p class=\"muted\">The method '{_esc(track.method)}' does not say where it "
                "sees a wheel line.</p>")
    params = "".join(f"<tr><th><code>{_esc(k)}</code></th><td><code>{_esc(v)}</code></td></tr>"
                     for k, v in sorted(track.params.items(), key=lambda kv: str(kv[0])))

    def notes_html(notes: Sequence[str]) -> str:
        if not notes:
            return "<p class=\"muted\">none</p>"
        return "<ul>" + "".join(f"<li>{_esc(n)}</li>" for n in notes) + "</ul>"

    parts = [
        "<!DOCTYPE html>",
        "<html lang=\"en\"><head><meta charset=\"utf-8\">",
        f"<title>{_esc(title)} – vibrospeed report</title>",
        f"<style>{_CSS}</style></head><body>",
        f"<h1>{_esc(title)}</h1>",
        "<h2>Summary</h2>",
        _table(rows),
        "<h2>Spectrogram with the estimate</h2>",
        f"<img alt=\"spectrogram of {_esc(axis)} with the estimate, its band and the truth\" "
        f"src=\"{spec}\">",
        "<h2>Speed over time</h2>",
        f"<img alt=\"speed over time\" src=\"{speed}\">",
        "<h2>Where a wheel line was seen</h2>",
        line,
        "<h2>Notes</h2>",
        "<h3>Recording</h3>",
        notes_html(notes_rec),
        "<h3>Estimate</h3>",
        notes_html(track.notes),
        "<h2>Parameters</h2>",
        f"<details><summary>{len(track.params)} parameters of "
        f"{_esc(track.method or 'the method')}</summary><table>{params}</table></details>",
        f"<p class=\"muted\">vibrospeed {_esc(__version__)}</p>",
        "</body></html>",
    ]
    return "\n".join(parts) + "\n"


def write_report(path: str | os.PathLike[str], recording: Recording, track: Track,
                 **kw: Any) -> Path:
    """Write the drive's report to ``path`` (atomic); keywords as :func:`render_report`."""
    p = Path(path)
    atomic_write_text(p, render_report(recording, track, **kw))
    return p


def _radius_cell(row) -> str:
    """A summary row's ``fitted_radius`` ± ``fitted_radius_std`` (m, 4 decimals: a learned
    radius is known to millimetres); the radius alone where it has no std, "–" where none."""
    def val(key: str) -> float:
        x = row.get(key)
        return float(x) if isinstance(x, (int, float)) and math.isfinite(x) else math.nan

    r, s = val("fitted_radius"), val("fitted_radius_std")
    if not math.isfinite(r):
        return _num(None)
    return f"{r:.4f}" + (f" ± {s:.4f}" if math.isfinite(s) else "")


def write_index(path: str | os.PathLike[str], summary, *, title: str = "vibrospeed batch") -> Path:
    """A batch's summary page: one row per recording (status, numbers, error, and the note of a
    drive whose speed numbers are empty) linking to its report; links are relative, so the
    output folder can be moved as a whole. A "wheel radius (m)" column (``fitted_radius`` ±
    ``fitted_radius_std``) only where some drive learned or fitted one, as in the CSV."""
    p = Path(path)
    df = summary
    counts = df["status"].value_counts().to_dict()
    # the learned wheel radius, as the CSV has it: a column only where some drive learned one
    radius = "fitted_radius" in df.columns and any(
        _radius_cell(r) != _num(None) for _, r in df.iterrows())
    head = ["file", "status", "duration", "distance", "median speed", "with a line",
            *(["wheel radius (m)"] if radius else []), "method", "error", "note", "wall"]
    rows = []
    for _, r in df.iterrows():
        name = _esc(r["file"])
        rep = r.get("report")
        if isinstance(rep, str) and rep:
            name = f"<a href=\"{_esc(rep)}\">{name}</a>"
        share = r.get("signal_share")
        share = share if isinstance(share, (int, float)) and math.isfinite(share) else None
        error = r.get("error")
        error = error if isinstance(error, str) else ""
        note = r.get("note")
        note = note if isinstance(note, str) else ""
        cells = [
            f"<td>{name}</td>",
            f"<td class=\"{_esc(r['status'])}\">{_esc(r['status'])}</td>",
            f"<td class=\"num\">{_num(r['duration_s'], '.1f', 's')}</td>",
            f"<td class=\"num\">{_num(r['distance_m'], '.1f', 'm')}</td>",
            f"<td class=\"num\">{_num(r['median_speed'], '.2f', 'm/s')}</td>",
            f"<td class=\"num\">{_num(None if share is None else 100 * share, '.1f', '%')}</td>",
            *([f"<td class=\"num\">{_radius_cell(r)}</td>"] if radius else []),
            f"<td>{_esc(r['method'])}</td>",
            f"<td class=\"error\">{_esc(error)}</td>",
            f"<td class=\"muted\">{_esc(note)}</td>",
            f"<td class=\"num\">{_num(r['wall_s'], '.1f', 's')}</td>",
        ]
        rows.append("<tr>" + "".join(cells) + "</tr>")
    summary_line = ", ".join(f"{v} {k}" for k, v in sorted(counts.items()))
    text = "\n".join([
        "<!DOCTYPE html>",
        "<html lang=\"en\"><head><meta charset=\"utf-8\">",
        f"<title>{_esc(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{_esc(title)}</h1>",
        f"<p>{_esc(summary_line)}. The table as <a href=\"summary.csv\">CSV</a>.</p>",
        "<table><tr>" + "".join(f"<th>{_esc(h)}</th>" for h in head) + "</tr>",
        *rows,
        "</table></body></html>",
    ]) + "\n"
    atomic_write_text(p, text)
    return p
