"""Ground truth from cog-wheel (wheel-speed sensor) tick timestamps (thesis appendix B.4).

Pipeline, thesis eq. B.1-B.6 (METHODS.md 2)::

    dt_i      = t_{i+1} - t_i                               (B.2)
    rps_i     = 1 / (n_cogs dt_i)                           (B.3)
    omega_wss = 2 pi rps_i                                  (B.4)
    omega_gt  = (r_sensor / r_wheel) omega_wss              (B.5)
    single-sample spikes: omega_gt(i) = (omega_gt(i-1) + omega_gt(i+1)) / 2     (B.6)

Choices the thesis leaves open (documented here):

* time stamp of ``omega_gt(i)``: the middle of its interval ``(t_i + t_{i+1}) / 2``. The mean
  angular speed over an interval equals the speed at its middle when the acceleration is constant,
  so a uniformly accelerating wheel is reproduced exactly.
* spike test: sample i is a spike when it differs from the mean of its two neighbours by more than
  ``spike_rel`` times that mean while the neighbours agree with each other within ``spike_rel``
  (a missed cog halves one value, a double trigger multiplies it). The first and last samples are
  never replaced (they have one neighbour).
* standstill: an interval longer than ``max_gap`` s means the wheel stopped; it gives
  ``omega = 0`` at ``t_i + max_gap / 2`` and ``t_{i+1} - max_gap / 2`` instead of one tiny
  value, so linear interpolation (thesis eq. 3.18) sees the stop.
"""

from __future__ import annotations

import csv
import os
from pathlib import Path

import numpy as np

from vibrospeed.errors import InputError, ParameterError, ReaderError
from vibrospeed.types import Recording

#: thesis appendix B: 12 cogs, cog wheel radius 0.0625 m, cart wheel radius 0.08 m
THESIS_N_COGS = 12
THESIS_R_SENSOR = 0.0625
THESIS_R_WHEEL = 0.08


def ticks_to_omega(ticks: np.ndarray, n_cogs: int = THESIS_N_COGS) -> tuple[np.ndarray, np.ndarray]:
    """Cog-wheel angular speed (rad/s) per tick interval and its mid-interval time (s), B.2-B.4."""
    t = np.asarray(ticks, dtype=np.float64)
    dt = np.diff(t)
    return 0.5 * (t[1:] + t[:-1]), 2.0 * np.pi / (n_cogs * dt)


def remove_spikes(omega: np.ndarray, spike_rel: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Replace single-sample spikes by the mean of their two neighbours (thesis eq. B.6).

    Returns ``(cleaned, spike_mask)``. A sample is a spike when
    ``|w_i - m_i| > spike_rel * |m_i|`` and ``|w_{i-1} - w_{i+1}| <= spike_rel * |m_i|`` with
    ``m_i = (w_{i-1} + w_{i+1}) / 2``. Decisions use the input values (not earlier replacements).
    """
    w = np.asarray(omega, dtype=np.float64)
    out = w.copy()
    mask = np.zeros(w.size, dtype=bool)
    if w.size < 3:
        return out, mask
    left, mid, right = w[:-2], w[1:-1], w[2:]
    m = 0.5 * (left + right)
    tol = spike_rel * np.abs(m)
    spike = (np.abs(mid - m) > tol) & (np.abs(left - right) <= tol)
    mask[1:-1] = spike
    out[1:-1] = np.where(spike, m, mid)
    return out, mask


def ticks_to_truth(
    ticks: np.ndarray,
    *,
    n_cogs: int = THESIS_N_COGS,
    r_sensor: float = THESIS_R_SENSOR,
    r_wheel: float = THESIS_R_WHEEL,
    spike_rel: float = 0.3,
    max_gap: float = 0.5,
    t_offset: float = 0.0,
    source: str = "ticks",
) -> Recording:
    """Ground-truth :class:`Recording` (``omega_true`` rad/s, ``speed_true`` m/s) from tick times.

    Parameters
    ----------
    ticks : (k,) s, times at which a cog passes the reflex sensor (non-decreasing).
    n_cogs : cogs per revolution of the sensor wheel (thesis: 12).
    r_sensor : m, radius of the wheel carrying the cogs (thesis: 0.0625).
    r_wheel : m, radius of the vehicle wheel whose omega is wanted (thesis cart: 0.08).
    spike_rel : relative size of a single-sample spike (see :func:`remove_spikes`); 0 or None off.
    max_gap : s, a longer tick interval is read as a stop (module docstring); inf disables.
    t_offset : s added to every tick (to put the sensor clock on the IMU clock).

    The result's time line is non-uniform (one sample per tick interval); use it as truth with
    :func:`vibrospeed.eval.metrics.evaluate`, which interpolates linearly (thesis eq. 3.18).

    Examples
    --------
    >>> ticks = np.arange(40) * 2 * np.pi / (12 * 12.8)    # cog wheel at 12.8 rad/s
    >>> rec = ticks_to_truth(ticks)
    >>> round(float(rec["omega_true"][0]), 6)               # 12.8 * 0.0625 / 0.08
    10.0
    """
    if int(n_cogs) != n_cogs or n_cogs < 1:
        raise ParameterError(f"{source}: n_cogs must be a positive integer, got {n_cogs}")
    for name, val in (("r_sensor", r_sensor), ("r_wheel", r_wheel)):
        if not val > 0:
            raise ParameterError(f"{source}: {name} must be > 0 m, got {val}")
    if not max_gap > 0:
        raise ParameterError(f"{source}: max_gap must be > 0 s, got {max_gap}")
    t = np.asarray(ticks, dtype=np.float64).ravel() + float(t_offset)
    notes: list[str] = []
    if not np.all(np.isfinite(t)):
        bad = int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"{source}: tick {bad} is not a finite time")
    d = np.diff(t)
    if np.any(d < 0):
        bad = int(np.flatnonzero(d < 0)[0]) + 1
        raise InputError(f"{source}: tick {bad} goes back in time ({t[bad]:.6g} s after "
                         f"{t[bad - 1]:.6g} s)")
    if np.any(d == 0):
        keep = np.concatenate([[True], d > 0])
        notes.append(f"{int((~keep).sum())} repeated tick times dropped")
        t = t[keep]
    if t.size < 2:
        raise InputError(f"{source}: need at least 2 ticks, got {t.size}")
    tm, w = ticks_to_omega(t, int(n_cogs))
    w = w * (r_sensor / r_wheel)  # eq. B.5
    gap = np.diff(t) > max_gap
    spikes = np.zeros(w.size, dtype=bool)
    if spike_rel:
        # spike removal within each moving stretch (a gap interval splits the stretches)
        seg_id = np.cumsum(gap)
        for s in np.unique(seg_id[~gap]):
            idx = np.flatnonzero((seg_id == s) & ~gap)
            w[idx], spikes[idx] = remove_spikes(w[idx], spike_rel)
        if spikes.any():
            notes.append(f"{int(spikes.sum())} single-sample spikes replaced by the mean of "
                         "their neighbours (thesis eq. B.6)")
    tt, ww = tm, w
    if gap.any():  # stops: a long interval becomes two zero samples
        gi = np.flatnonzero(gap)
        notes.append(f"{gi.size} tick gaps longer than {max_gap:g} s read as stops (omega = 0)")
        tt = np.concatenate([tm[~gap], t[gi] + max_gap / 2, t[gi + 1] - max_gap / 2])
        ww = np.concatenate([w[~gap], np.zeros(gi.size), np.zeros(gi.size)])
        order = np.argsort(tt, kind="stable")
        tt, ww = tt[order], ww[order]
    return Recording(
        t=tt,
        channels={"omega_true": ww, "speed_true": ww * r_wheel},
        events={"wss_ticks": t},
        source=source,
        wheel_radius=float(r_wheel),
        notes=[f"ground truth from {t.size} cog ticks (thesis appendix B.4: n_cogs = {n_cogs}, "
               f"r_sensor = {r_sensor:g} m, r_wheel = {r_wheel:g} m)"] + notes,
        meta={"n_cogs": int(n_cogs), "r_sensor": float(r_sensor), "r_wheel": float(r_wheel),
              "spike_rel": spike_rel, "max_gap": float(max_gap), "n_spikes": int(spikes.sum())},
    )


def truth_from_recording(recording: Recording, **kw) -> Recording:
    """:func:`ticks_to_truth` on the ``wss_ticks`` event stream of a recording."""
    if "wss_ticks" not in recording.events:
        raise InputError(f"{recording.source or 'recording'}: no 'wss_ticks' event stream")
    kw.setdefault("source", recording.source or "recording")
    return ticks_to_truth(recording.events["wss_ticks"], **kw)


def read_ticks(path: str | os.PathLike[str], *, scale: float = 1.0) -> np.ndarray:
    """Tick timestamps (s) from a one-column CSV file (optional header line; blank lines and
    ``#`` comments skipped). ``scale`` multiplies the values (e.g. 1e-3 for milliseconds).

    Raises :class:`ReaderError` naming the line for a non-number, an extra column or a time
    going backwards.
    """
    p = Path(path)
    if not p.exists():
        raise ReaderError(p, "file not found")
    if p.is_dir():
        raise ReaderError(p, "is a directory, expected a CSV file of tick times")
    vals: list[float] = []
    with open(p, newline="", encoding="utf-8-sig") as f:
        sample = f.read(4096)
        f.seek(0)
        delim = ";" if sample.count(";") > sample.count(",") else ","
        first_data = True
        for lineno, row in enumerate(csv.reader(f, delimiter=delim), start=1):
            fields = [c.strip() for c in row]
            while fields and fields[-1] == "":
                fields.pop()
            if not fields or fields[0].startswith("#"):
                continue
            if len(fields) > 1:
                raise ReaderError(p, f"expected one column of tick times, found {len(fields)}",
                                  row=lineno)
            try:
                v = float(fields[0])
            except ValueError:
                if first_data and not vals:
                    first_data = False  # a header line
                    continue
                raise ReaderError(p, f"'{fields[0]}' is not a number", row=lineno) from None
            first_data = False
            if not np.isfinite(v):
                raise ReaderError(p, f"'{fields[0]}' is not a finite time", row=lineno)
            if vals and v * scale < vals[-1]:
                raise ReaderError(p, f"time {fields[0]} goes backwards", row=lineno)
            vals.append(v * scale)
    if len(vals) < 2:
        raise ReaderError(p, f"need at least 2 tick times, found {len(vals)}")
    return np.asarray(vals, dtype=np.float64)
