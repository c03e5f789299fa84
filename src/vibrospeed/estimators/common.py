"""Helpers shared by the ``estimate()`` entry points: axis selection, pre-filtering, checks."""

from __future__ import annotations

import dataclasses

import numpy as np

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.io.timebase import API_FIX, check_increasing, check_nyquist
from vibrospeed.signal import prefilter as pf
from vibrospeed.signal.normalize import running_rms_normalize
from vibrospeed.types import Recording

#: jitter tolerated as "uniform" by the vibration trackers (relative to the median period)
UNIFORM_RTOL = 0.05
#: a period longer than this many median periods is a gap (as :func:`vibrospeed.io.timebase.
#: find_gaps` counts them)
GAP_FACTOR = 3.0


def axis_channel(axis: str) -> str:
    """'y' -> 'ay'; a full channel name passes through."""
    axis = axis.strip()
    if axis in ("x", "y", "z"):
        return "a" + axis
    return axis


def signed_axis(spec: str) -> tuple[str, float]:
    """An accelerometer axis with an optional sign: ``'-ay'`` / ``'-y'`` -> ``('ay', -1.0)``,
    ``'x'`` / ``'+ax'`` -> ``('ax', 1.0)``. A leading ``-`` names an axis that points
    backwards (a phone mounted the other way round), whose values are negated."""
    spec = spec.strip()
    sign = -1.0 if spec.startswith("-") else 1.0
    return axis_channel(spec.lstrip("+-")), sign


def gps_no_fix_as_nan(recording: Recording) -> tuple[Recording, list[str]]:
    """``recording`` with a negative ``gps_speed`` / ``gps_hacc`` as NaN (no fix), and the note
    saying so; ``(recording, [])`` where there is none. The readers do this
    (:func:`vibrospeed.io._common.no_fix_as_nan`: apps write -1 for no fix); a Recording built
    through the API reaches the GPS methods as it is, where -1 m/s would be a fix."""
    from vibrospeed.io._common import no_fix_as_nan

    rec = recording.with_channels()
    notes = no_fix_as_nan(rec)
    return (rec, notes) if notes else (recording, [])


def only_axis(recording, axis: str | None) -> tuple[str | None, str | None]:
    """The vibration axis when none is given and the default ``ay`` is missing: a recording
    with a single other accelerometer axis uses it. Returns ``(axis, note)`` (note None where
    nothing was chosen)."""
    if axis is None and "ay" not in recording:
        have = [c for c in ("ax", "az") if c in recording]
        if len(have) == 1:
            return have[0][1], (f"no 'ay' in the recording: using its only accelerometer axis "
                                f"'{have[0]}' (--axis to choose)")
    return axis, None


def split_params(model_cls, params: dict) -> tuple[dict, dict]:
    """Split ``params`` into (fields of ``model_cls``, the rest)."""
    names = {f.name for f in dataclasses.fields(model_cls)}
    model_kw = {k: v for k, v in params.items() if k in names}
    rest = {k: v for k, v in params.items() if k not in names}
    return model_kw, rest


def check_time(recording: Recording) -> None:
    """:class:`InputError` naming the first bad sample unless the time line is finite and
    strictly increasing (a Recording's contract, which its constructor does not check: one
    built through the API with a NaN, repeated or reversed time failed inside NumPy or was
    estimated as if uniform): :func:`vibrospeed.io.timebase.check_increasing`, naming
    :func:`vibrospeed.io.sort_dedup` as the repair."""
    check_increasing(recording.t, recording.source or "recording", fix=API_FIX)


def check_uniform(recording: Recording) -> float:
    """Median sample period in s; :class:`InputError` if the time line is not uniform enough
    (more than 1 % of the periods off the median by > 5 %) or has a gap (a period over
    ``GAP_FACTOR`` times the median, with the same 5 %): the estimators step sample by sample,
    so a gap taken as one period would join the two sides as if no time had passed.
    :func:`vibrospeed.io.resample_uniform` (which the CLI applies itself) puts NaN samples in
    the gaps, which every estimator bridges by prediction."""
    if len(recording) < 2:
        raise InputError(f"{recording.source or 'recording'}: fewer than 2 samples")
    check_time(recording)
    d = np.diff(recording.t)
    dt = float(np.median(d))
    gaps = np.flatnonzero(d > GAP_FACTOR * (1.0 + UNIFORM_RTOL) * dt)
    if gaps.size:
        i = int(gaps[np.argmax(d[gaps])])
        raise InputError(
            f"{recording.source or 'recording'}: time line has {gaps.size} gap(s) longer than "
            f"{GAP_FACTOR:g} periods, the longest {d[i]:.4g} s after t = {recording.t[i]:.6g} "
            "s; resample it first (vibrospeed.io.resample_uniform: NaN in the gaps, which the "
            "estimators bridge; the CLI does this itself)")
    bad = np.abs(d - dt) > UNIFORM_RTOL * dt
    if np.mean(bad) > 0.01:
        raise InputError(
            f"{recording.source or 'recording'}: time line is not uniform "
            f"({np.mean(bad):.0%} of periods differ from the median {dt * 1e3:.3g} ms by > 5 %); "
            "resample it first (vibrospeed.io.timebase.resample_uniform; the CLI does this itself)"
        )
    return dt


def start_level(x: np.ndarray, dt: float, seconds: float = 1.0) -> float:
    """Mean of the finite samples in the first ``seconds``: the pre-filter's resting level."""
    head = x[: max(1, int(round(seconds / dt)))]
    head = head[np.isfinite(head)]
    return float(np.mean(head)) if head.size else float("nan")


def prepare_axis(
    recording: Recording,
    axis: str,
    *,
    prefilter: str = "thesis-hp",
    M: int = 3,
    omega_max: float | None = None,
    normalize_tau: float | None = 5.0,
    omega_range: tuple[float, float] | None = None,
) -> tuple[np.ndarray, float, list[str]]:
    """Pre-filtered vibration signal of ``axis``, its sample period and notes on what was done."""
    name = axis_channel(axis)
    recording.require(name)
    dt = check_uniform(recording)
    fs = 1.0 / dt
    if omega_max is not None:
        try:
            check_nyquist(fs, M, omega_max, recording.source or "recording")
        except ParameterError as exc:
            raise ParameterError(f"{exc} (or set a lower range, e.g. -p omega_max=...)") from None
    x = recording.channel(name)
    notes = []
    n_bad = int(np.count_nonzero(~np.isfinite(x)))
    if n_bad:
        n_inf = int(np.count_nonzero(np.isinf(x)))
        what = " and ".join(f"{k} {kind}" for k, kind in ((n_bad - n_inf, "NaN"),
                                                          (n_inf, "infinite")) if k)
        notes.append(f"{what} samples on '{name}': prediction only there")
    sos = pf.design(prefilter, fs, M=M, omega_range=omega_range)
    y = pf.apply(sos, x, level=start_level(x, dt))
    if prefilter in pf.ADAPTIVE:
        from vibrospeed.signal import whiten

        y = whiten.apply(y, fs)
    notes.append(f"pre-filter '{prefilter}' on '{name}' at fs = {fs:.4g} Hz")
    if normalize_tau:
        y = running_rms_normalize(y, dt, normalize_tau)
        notes.append(f"normalised by a running RMS (tau = {normalize_tau:g} s)")
    return y, dt, notes


def run_in_chunks(step_chunk, n: int, *, progress: bool = False, label: str = "estimating",
                  chunk: int = 50_000) -> list:
    """Call ``step_chunk(a, b)`` over consecutive index ranges covering ``0..n``.

    The estimators' ``run`` functions take a start state, so chunked runs give the numbers of one
    whole run; this only adds a progress bar (``rich``, on stderr) when ``progress`` is true and
    there is more than one chunk. Returns the list of the chunks' results.
    """
    bounds = list(range(0, n, chunk)) + [n]
    pairs = list(zip(bounds[:-1], bounds[1:], strict=True)) or [(0, 0)]
    if not progress or len(pairs) == 1:
        return [step_chunk(a, b) for a, b in pairs]
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TimeRemainingColumn

    out = []
    with Progress("[progress.description]{task.description}", BarColumn(),
                  "{task.completed}/{task.total} samples", TimeRemainingColumn(),
                  console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task(label, total=n)
        for a, b in pairs:
            out.append(step_chunk(a, b))
            bar.update(task, completed=b)
    return out
