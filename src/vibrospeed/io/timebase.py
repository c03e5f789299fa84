"""Time-base checks and repairs: monotonic time, sorting, uniform resampling, gaps, Nyquist.

Phone sensors deliver jittered, occasionally repeated or out-of-order timestamps and gaps; the
estimators assume a uniform period ``T``. The functions here make that explicit and record what
they did in ``Recording.notes``.

Resampling method (:func:`resample_uniform`)
    Uniform grid ``t_k = t_0 + k / fs``. *Dense* channels are linearly interpolated between the two
    neighbouring input samples, ``x(t_k) = (1 - w) x_i + w x_{i+1}``, ``w = (t_k - t_i) /
    (t_{i+1} - t_i)``; the result is NaN where a neighbour is NaN or where the two neighbours are
    more than ``max_gap`` apart (no invention of data inside gaps). *Sparse* channels (GPS fixes
    placed at one sample each, see :mod:`vibrospeed.io.phyphox`) are moved to the nearest grid
    point instead, so a fix is still seen exactly once. Event streams are left untouched.
    Linear interpolation attenuates a tone of frequency f by ``sinc^2(f / fs_in)`` at most (about
    -0.4 dB at f = fs/4 for 100 Hz data) and its error is bounded by ``h^2 max|x''| / 8``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from vibrospeed.errors import InputError, ParameterError, ReaderError
from vibrospeed.types import Recording

__all__ = [
    "SPARSE_CHANNELS",
    "check_fundamental",
    "fundamental_shortfall",
    "check_increasing",
    "check_nyquist",
    "describe_timebase",
    "as_uniform",
    "find_gaps",
    "interp_onto",
    "merge_fix_rows",
    "nearest_index",
    "place_nearest",
    "rows_for_fixes",
    "resample_uniform",
    "sort_dedup",
    "split_at_gaps",
]

#: Channels that hold isolated samples (NaN elsewhere); resampling moves them to the nearest grid
#: point instead of interpolating. Channels less than half finite are treated the same way.
SPARSE_CHANNELS = frozenset({"gps_speed", "gps_sats", "gps_hacc", "gps_lat", "gps_lon", "gps_alt"})


#: the repair a time-line error of :func:`check_increasing` names: a reader's sort option, or
#: for a Recording built in Python (no reader), :func:`sort_dedup`
READER_FIX = "--sort (sort=True in Python) sorts, de-duplicates and drops rows without a time"
API_FIX = "vibrospeed.io.sort_dedup sorts, de-duplicates and drops rows without a time"


def check_increasing(t: np.ndarray, source: str = "", *, rows: np.ndarray | None = None,
                     fix: str = READER_FIX) -> None:
    """Raise unless ``t`` is finite and strictly increasing: the one check of a time line (the
    readers, :func:`resample_uniform`, the estimators through
    :func:`vibrospeed.estimators.common.check_time`).

    Parameters
    ----------
    t : (n,) s
    source : file or recording name used in the message
    rows : (n,) optional 1-based file line number of each sample; when given a
        :class:`ReaderError` names the line, otherwise an :class:`InputError` names the sample.
    fix : the repair the message ends with (default :data:`READER_FIX`)
    """
    t = np.asarray(t, dtype=np.float64)
    name = str(source) or "recording"
    bad_fin = np.flatnonzero(~np.isfinite(t))
    bad_inc = np.flatnonzero(~(np.diff(t) > 0)) + 1 if t.size > 1 else np.empty(0, int)
    cands = [int(b[0]) for b in (bad_fin, bad_inc) if b.size]
    if not cands:
        return
    i = min(cands)
    now, prev = float(t[i]), float(t[i - 1]) if i else float("nan")
    if not np.isfinite(now):
        msg = f"time is {now} (not a number)"
    elif now == prev:
        msg = f"time {now!r} s repeats the previous sample"
    else:
        msg = f"time goes backwards ({now!r} s after {prev!r} s)"
    msg = f"{msg}; {fix}"
    if rows is not None:
        raise ReaderError(name, msg, row=int(rows[i]), column="t")
    raise InputError(f"{name}, sample {i}: {msg}")


def row_order(t: np.ndarray, lines: np.ndarray, label: str, sort: bool,
              notes: list[str]) -> np.ndarray:
    """Row order making ``t`` strictly increasing (a phone app's CSV).

    Exact repeats of the previous timestamp (phones emit a few) are dropped, keeping the first
    row, and noted; time going backwards raises (naming ``lines``, the file's row numbers)
    unless ``sort``, which sorts and de-duplicates.
    """
    if sort:
        order = np.argsort(t, kind="stable")
        order = order[np.isfinite(t[order])]
        moved = int(np.count_nonzero(order != np.arange(order.size)))
        if moved:
            notes.append(f"{label}: sorted by time ({moved} rows moved)")
    else:
        order = np.arange(t.size)
    ts = t[order]
    keep = np.ones(ts.size, dtype=bool)
    keep[1:] = ts[1:] != ts[:-1]
    if not keep.all():
        notes.append(f"{label}: dropped {ts.size - int(keep.sum())} row(s) repeating the previous "
                     "timestamp (first kept)")
    order = order[keep]
    if not sort:
        check_increasing(t[order], label, rows=lines[order])
    return order


def sort_dedup(rec: Recording) -> Recording:
    """Copy of ``rec`` sorted by time, rows with non-finite time dropped, repeated times dropped.

    For repeated timestamps the first row (in file order) is kept. What was done is appended to
    ``notes``; an already clean recording is returned as an unchanged copy.
    """
    t = rec.t
    notes = list(rec.notes)
    finite = np.isfinite(t)
    idx = np.flatnonzero(finite)
    if idx.size < t.size:
        notes.append(f"dropped {t.size - idx.size} rows with missing time")
    order = idx[np.argsort(t[idx], kind="stable")]
    # out of order: a row earlier than one before it (a repeat is not; it is dropped below).
    # Not the rows whose place changed: one late row among 1000 moves them all.
    ti = t[idx]
    late = int(np.count_nonzero(ti[1:] < np.maximum.accumulate(ti)[:-1])) if ti.size else 0
    if late:
        notes.append(f"sorted by time ({late} rows were out of order)")
    ts = t[order]
    keep = np.ones(ts.size, dtype=bool)
    keep[1:] = np.diff(ts) > 0
    ndup = int(ts.size - np.count_nonzero(keep))
    if ndup:
        notes.append(f"dropped {ndup} rows repeating an earlier timestamp (first kept)")
    sel = order[keep]
    return replace(
        rec,
        t=t[sel],
        channels={k: v[sel] for k, v in rec.channels.items()},
        units=dict(rec.units),
        events=dict(rec.events),
        notes=notes,
        meta=dict(rec.meta),
    )


def _is_sparse(name: str, x: np.ndarray) -> bool:
    return name in SPARSE_CHANNELS or (x.size > 0 and np.count_nonzero(np.isfinite(x)) < x.size / 2)


def interp_onto(t: np.ndarray, x: np.ndarray, grid: np.ndarray, max_gap: float) -> np.ndarray:
    """Linear interpolation of samples ``(t, x)`` at times ``grid`` (no extrapolation).

    NaN where ``grid`` is outside ``[t_0, t_end]``, where a neighbouring sample is NaN, or where
    the neighbours are more than ``max_gap`` s apart (unless ``grid`` hits a sample: within a
    millionth of the grid's mean spacing, so that a grid ``t_0 + k / fs`` whose rounding puts
    a point 1e-11 s before the first sample after a gap still takes that sample).
    """
    n = t.size
    tol = 1e-6 * (grid[-1] - grid[0]) / (grid.size - 1) if grid.size > 1 else 0.0
    if n == 1:
        return np.where(np.abs(grid - t[0]) <= tol, x[0], np.nan)
    i = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, n - 2)
    t0, t1 = t[i], t[i + 1]
    w = (grid - t0) / (t1 - t0)
    x0, x1 = x[i], x[i + 1]
    with np.errstate(invalid="ignore"):
        y = (1.0 - w) * x0 + w * x1
    at0, at1 = np.abs(grid - t0) <= tol, np.abs(t1 - grid) <= tol
    y = np.where(at0, x0, np.where(at1, x1, y))
    inside = at0 | at1 | ((t1 - t0) <= max_gap)
    outside = (grid < t[0] - tol) | (grid > t[-1] + tol)
    return np.where(inside & ~outside, y, np.nan)


def nearest_index(tq: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Index of the ``grid`` point nearest each time in ``tq`` (``grid`` increasing, non-empty;
    ties go to the earlier point)."""
    tq = np.asarray(tq, dtype=np.float64)
    if grid.size == 1:
        return np.zeros(tq.size, dtype=np.intp)
    j = np.clip(np.searchsorted(grid, tq), 1, grid.size - 1)
    return np.where(np.abs(grid[j - 1] - tq) <= np.abs(grid[j] - tq), j - 1, j)


def place_nearest(t: np.ndarray, x: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """Put each finite sample ``x_i`` at the grid point nearest ``t_i``; NaN elsewhere.

    A sample is seen exactly once on the grid; when two land on the same point the later wins.
    Samples outside ``[grid_0, grid_end]`` land on the end points (callers trim them first).
    """
    out = np.full(grid.size, np.nan)
    fin = np.flatnonzero(np.isfinite(x))
    if fin.size == 0 or grid.size == 0:
        return out
    out[nearest_index(t[fin], grid)] = x[fin]  # later samples overwrite earlier ones
    return out


def rows_for_fixes(
    t: np.ndarray, tq: np.ndarray, channels: dict[str, np.ndarray], lines: np.ndarray
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray, np.ndarray]:
    """Rows of their own for fixes (GPS) that fall inside a gap of the master time line ``t``.

    :func:`place_nearest` puts a fix on the nearest master sample. Inside a gap (an interval
    longer than 3 median periods, as :func:`describe_timebase` counts gaps) that sample is up to
    half the gap away and every fix of the gap's half lands on it, so all but one are lost and
    the one kept is moved by up to half the gap. Each fix time in ``tq`` inside ``[t_0,
    t_end]`` and more than 1.5 median periods from every master sample is therefore added to
    the time line as a row of its own, with the master ``channels`` NaN there (nothing was
    measured); the fixes are then placed there exactly.

    Returns ``(t, channels, lines, added)``: the merged increasing time line, the channels with
    NaN at the new rows, ``lines`` (file line numbers; 0 at the new rows) and the added times.
    """
    t = np.asarray(t, dtype=np.float64)
    tq = np.asarray(tq, dtype=np.float64)
    tq = np.unique(tq[np.isfinite(tq)])
    if t.size < 2 or tq.size == 0:
        return t, channels, lines, np.empty(0)
    tol = 1.5 * float(np.median(np.diff(t)))
    tq = tq[(tq > t[0]) & (tq < t[-1])]
    far = np.abs(t[nearest_index(tq, t)] - tq) > tol
    add = tq[far]
    if add.size == 0:
        return t, channels, lines, add
    pos = np.searchsorted(t, add)
    t2 = np.insert(t, pos, add)
    chans = {k: np.insert(np.asarray(x, dtype=np.float64), pos, np.nan)
             for k, x in channels.items()}
    return t2, chans, np.insert(lines, pos, 0), add


def merge_fix_rows(
    t: np.ndarray,
    tq: np.ndarray,
    channels: dict[str, np.ndarray],
    lines: np.ndarray | None = None,
    *,
    master: str = "accelerometer",
) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray | None, list[str], dict[str, list]]:
    """:func:`rows_for_fixes` with the note and the meta entry every reader gives for it.

    ``tq`` holds the times of the *valid* fixes only: a "no fix" (an app's -1 speed, made NaN
    first) must not get a row of its own. ``master`` names the sensor whose time line ``t`` is
    (its ``channels`` are NaN on the new rows); ``lines`` may be None (no file lines).

    Returns ``(t, channels, lines, notes, meta)``: ``notes`` is empty or the one note (how many
    fixes, the gap threshold, that the master is NaN there) and ``meta`` empty or
    ``{"fix_rows": added times}``, which :func:`describe_timebase` reads to leave those rows out.
    """
    t = np.asarray(t, dtype=np.float64)
    ln = np.zeros(t.size, dtype=np.intp) if lines is None else lines
    t2, chans, ln, added = rows_for_fixes(t, tq, channels, ln)
    if added.size == 0:
        return t2, chans, lines, [], {}
    gap = 3.0 * float(np.median(np.diff(t)))
    note = (f"{added.size} valid GPS fix(es) inside {master} gaps (intervals > 3 median periods, "
            f"{gap:.3g} s) kept on rows of their own at the fix times, the {master} NaN there "
            "(their times in meta 'fix_rows')")
    return t2, chans, None if lines is None else ln, [note], {"fix_rows": added.tolist()}


def resample_uniform(
    rec: Recording, fs: float | None = None, *, max_gap: float | None = None
) -> Recording:
    """Resample every channel of ``rec`` onto a uniform time grid by linear interpolation.

    Parameters
    ----------
    rec : recording with strictly increasing ``t``
    fs : Hz, output rate; default the median input rate ``1 / median(diff(t))``
    max_gap : s, longest interval between two input samples that is bridged by interpolation;
        grid points inside longer gaps are NaN. Default ``5 * median(diff(t))``.

    Returns
    -------
    Recording on ``t_k = t_0 + k / fs``, ``k = 0 .. floor((t_end - t_0) fs)``, same channels
    (dense ones interpolated, sparse ones moved to the nearest grid point, see module docstring),
    events untouched, and a note describing the method.
    """
    name = rec.source or "recording"
    if rec.t.size < 2:
        raise InputError(f"{name}: need at least 2 samples to resample")
    check_increasing(rec.t, name, fix=API_FIX)
    dt_med = float(np.median(np.diff(rec.t)))
    fs = 1.0 / dt_med if fs is None else float(fs)
    if not np.isfinite(fs) or fs <= 0:
        raise ParameterError(f"{name}: resampling rate must be positive, got {fs}")
    max_gap = 5.0 * dt_med if max_gap is None else float(max_gap)
    t0 = float(rec.t[0])
    n = int(np.floor((rec.t[-1] - t0) * fs * (1.0 + 1e-12))) + 1
    grid = t0 + np.arange(n) / fs
    gi = np.minimum(grid, rec.t[-1])  # the last grid point may overshoot t_end by rounding
    chans = {}
    sparse = []
    for k, x in rec.channels.items():
        if _is_sparse(k, x):
            chans[k] = place_nearest(rec.t, x, grid)
            sparse.append(k)
        else:
            chans[k] = interp_onto(rec.t, x, gi, max_gap)
    note = (
        f"resampled to a uniform {fs:.6g} Hz grid by linear interpolation between neighbouring "
        f"samples (NaN across gaps > {max_gap:.3g} s)"
    )
    if sparse:
        note += f"; sparse channels {', '.join(sparse)} moved to the nearest grid point"
    meta = dict(rec.meta)
    meta["resampled"] = {"fs": fs, "max_gap": max_gap, "method": "linear", "fs_in": 1.0 / dt_med}
    return replace(
        rec,
        t=grid,
        channels=chans,
        units=dict(rec.units),
        events=dict(rec.events),
        notes=[*rec.notes, note],
        meta=meta,
    )


#: a recording whose periods all lie within this fraction of the median is estimated as it is,
#: at its median rate (the estimators' own check, ``estimators.common.check_uniform``, allows
#: it); beyond, :func:`as_uniform` resamples
UNIFORM_ENOUGH = 0.05


def as_uniform(rec: Recording) -> Recording:
    """``rec`` ready for the estimators, as the CLI reads a file: time stamps further than
    :data:`UNIFORM_ENOUGH` from uniform (jitter, gaps, a rate change) resampled
    (:func:`resample_uniform`); jitter within it kept, with a note saying so where the
    reader's note advised a resample (the estimate runs at the median rate).
    """
    if len(rec) <= 2:
        return rec
    if not rec.is_uniform(rtol=UNIFORM_ENOUGH):
        return resample_uniform(rec)
    if not rec.is_uniform():
        d = np.diff(rec.t)
        med = float(np.median(d))
        worst = float(np.max(np.abs(d - med))) / med
        rec.notes.append(f"time stamps within {100 * worst:.2g} % of uniform (under "
                         f"{100 * UNIFORM_ENOUGH:g} %): estimated at the median rate "
                         f"{1.0 / med:.6g} Hz, not resampled")
    return rec


def find_gaps(t: np.ndarray, factor: float = 3.0) -> list[tuple[float, float]]:
    """Intervals ``(t_start, t_end)`` between consecutive samples longer than ``factor`` times the
    median period (s). ``t_start`` is the last sample before the gap, ``t_end`` the first after."""
    t = np.asarray(t, dtype=np.float64)
    if t.size < 3:
        return []
    d = np.diff(t)
    lim = factor * float(np.median(d))
    idx = np.flatnonzero(d > lim)
    return [(float(t[i]), float(t[i + 1])) for i in idx]


def split_at_gaps(rec: Recording, min_gap: float) -> list[Recording]:
    """Split ``rec`` into pieces wherever two consecutive samples are more than ``min_gap`` s apart.

    Events go to the piece whose time span ``[t_first, t_first_of_next)`` contains them.
    """
    if min_gap <= 0:
        raise ParameterError(f"min_gap must be positive, got {min_gap}")
    if rec.t.size == 0:
        return []
    cut = np.flatnonzero(np.diff(rec.t) > min_gap) + 1
    bounds = [0, *cut.tolist(), rec.t.size]
    pieces = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        lo = rec.t[a]
        hi = rec.t[b] if b < rec.t.size else np.inf
        ev = {k: v[(v >= lo) & (v < hi)] for k, v in rec.events.items()}
        if a == 0:
            ev = {k: v[v < hi] for k, v in rec.events.items()}
        note = f"piece {len(pieces) + 1} of {len(bounds) - 1} after splitting at gaps > {min_gap} s"
        pieces.append(
            replace(
                rec,
                t=rec.t[a:b],
                channels={k: v[a:b] for k, v in rec.channels.items()},
                units=dict(rec.units),
                events=ev,
                notes=[*rec.notes, note] if len(bounds) > 2 else list(rec.notes),
                meta=dict(rec.meta),
            )
        )
    return pieces


def fundamental_shortfall(fs: float, omega_max: float, hint: str = "") -> str | None:
    """Why sample rate ``fs`` (Hz) carries no fundamental up to ``omega_max`` (rad/s), in one
    sentence (``hint``, what to do, closes its parenthesis), or None where ``omega_max < pi
    fs``. The one wording of :func:`check_fundamental`'s error and of fuse's note where a log
    is too slow for the grid tracker's default range."""
    if not omega_max >= np.pi * fs:
        return None
    more = f"; {hint}" if hint else ""
    return (f"sample rate {fs:.4g} Hz is too low for omega up to omega_max = {omega_max:.4g} "
            f"rad/s (the fundamental needs fs > {omega_max / np.pi:.4g} Hz{more})")


def check_fundamental(fs: float, omega_max: float, source: str = "") -> None:
    """Raise :class:`ParameterError` unless the fundamental up to ``omega_max`` (rad/s) is
    below Nyquist at sample rate ``fs`` (Hz): ``omega_max < pi fs``.

    The harmonic trackers may let the higher harmonics alias (the rotation model describes the
    folded lines), but a fundamental above Nyquist is no wheel line at all; :func:`check_nyquist`
    is the stricter check for all M harmonics."""
    said = fundamental_shortfall(fs, omega_max, f"lower omega_max below {np.pi * fs:.4g} rad/s")
    if said is not None:
        where = f"{source}: " if source else ""
        raise ParameterError(f"{where}{said}")


def check_nyquist(fs: float, M: int, omega_max: float, source: str = "") -> None:
    """Raise :class:`ParameterError` unless harmonic ``M`` of ``omega_max`` stays below Nyquist.

    Harmonic m of a wheel turning at omega (rad/s) is a tone at ``m omega / (2 pi)`` Hz, so all
    of 1..M are representable at sample rate ``fs`` only if ``M omega_max < pi fs``
    (METHODS.md sec. 1; thesis sec. 2.1).
    """
    where = f"{source}: " if source else ""
    if M < 1 or not np.isfinite(omega_max) or omega_max <= 0 or not fs > 0:
        raise ParameterError(f"{where}need M >= 1, omega_max > 0 and fs > 0 (got {M}, "
                             f"{omega_max}, {fs})")
    limit = np.pi * fs / M
    if omega_max >= limit:
        raise ParameterError(
            f"{where}sample rate {fs:.6g} Hz is too low for M = {M} harmonics up to omega_max = "
            f"{omega_max:.6g} rad/s (M*omega_max must stay below pi*fs = {np.pi * fs:.6g} rad/s); "
            f"the maximum omega allowed is {limit:.6g} rad/s, or raise fs above "
            f"{M * omega_max / np.pi:.6g} Hz"
        )


def _rate_change(t: np.ndarray, d: np.ndarray, block: int = 200, ratio: float = 1.5) -> str:
    """Where the sample rate changes (a phone app switching rate mid-drive): the text to add to
    the time-line note, empty if it does not.

    The median period of consecutive blocks of ``block`` intervals (fewer for a short log, at
    least 10) is robust to jitter and to single gaps; a block whose median differs from the
    first block's by more than ``ratio`` marks the change. Its "jitter" is then no jitter: a
    uniform resampling at the overall median rate up-samples the slower stretch (it holds
    nothing above its own Nyquist frequency) or decimates the faster one.
    """
    w = min(block, d.size // 2)
    if w < 10:
        return ""
    nb = d.size // w
    med = np.median(d[: nb * w].reshape(nb, w), axis=1)
    far = np.flatnonzero(np.maximum(med / med[0], med[0] / med) > ratio)
    if far.size == 0:
        return ""
    k = int(far[0])
    return (f"; the rate changes from {1.0 / med[0]:.4g} Hz to {1.0 / med[k]:.4g} Hz near t = "
            f"{t[k * w]:.4g} s (block median rates {1.0 / med.max():.4g}-{1.0 / med.min():.4g} "
            "Hz)")


def describe_timebase(rec: Recording, *, gap_factor: float = 3.0) -> list[str]:
    """Notes on jitter and gaps of ``rec.t`` (empty if uniform and gap-free).

    Rows a reader added for GPS fixes inside gaps (:func:`rows_for_fixes`, their times in
    ``rec.meta["fix_rows"]``) are left out: the notes describe the sensor's own samples, its
    gap as one gap, not as the fixes' spacing.
    """
    t = rec.t
    added = rec.meta.get("fix_rows")
    if added:
        t = t[~np.isin(t, np.asarray(added, dtype=np.float64))]
    if t.size < 3:
        return []
    d = np.diff(t)
    med = float(np.median(d))
    notes = []
    gaps = find_gaps(t, gap_factor)
    if not np.all(np.abs(d - med) <= 1e-3 * med):  # Recording.is_uniform(1e-3) of these times
        dd = d[d <= gap_factor * med]
        jit = float(np.std(dd)) if dd.size else 0.0
        change = _rate_change(t, d)
        notes.append(
            f"non-uniform time line: median period {med * 1e3:.4g} ms ({1.0 / med:.5g} Hz), "
            f"jitter (std) {jit * 1e3:.3g} ms{change}; resample for estimators that need a "
            "uniform rate"
        )
    if gaps:
        longest = max(b - a for a, b in gaps)
        notes.append(
            f"{len(gaps)} time gap(s) longer than {gap_factor:g} periods, longest {longest:.4g} s "
            f"(first at t = {gaps[0][0]:.6g} s)"
        )
    return notes
