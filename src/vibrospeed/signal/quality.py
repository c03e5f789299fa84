"""Sample quality: saturated, stuck and spike samples of an accelerometer, found before any
estimate and reported as notes and a per-sample ``quality`` column.

A sensor at the end of its range, a frozen driver, or an electrical spike all leave the
samples finite, so neither the readers nor the trackers see them; the trackers bridge them
as if they were vibration. Three tests, per channel, each on the samples themselves:

* **saturated** (:data:`SATURATED`): the sample equals the channel's largest (or smallest)
  finite value and that extreme is *flat-topped*: reached in a run of at least
  :data:`SAT_RUN` equal consecutive samples and by at least :data:`SAT_MIN` samples in all. A
  continuous signal reaches its extreme once; a clipped one sits on it.
* **stuck** (:data:`STUCK`): the sample belongs to a run of exactly equal consecutive values at
  least :data:`STUCK_S` s long (and at least :data:`STUCK_MIN` samples) that is not at a
  saturated extreme. A vibrating accelerometer never repeats its value for that long, unless
  its resolution is coarser than the vibration (then the run carries no information either).
* **spike** (:data:`SPIKE`): ``|x - med_7(x)| > SPIKE_K * s`` where ``med_7`` is the running
  median over 7 samples (it passes runs of up to 3 outliers through as outliers) and ``s`` a
  robust local scale: 1.4826 times the median of ``|x - med_7|`` over blocks of
  :data:`SCALE_S` s, the largest of a block and its two neighbours (so a quiet block next to a
  loud one does not flag the loud one's edge), floored at the channel's resolution (smallest
  non-zero step); and ``|x - med_7(x)| > SPREAD_K * s_d`` with ``s_d`` the same block scale of
  the first difference of ``x`` (a smooth wave's crests, which the running median cuts, are
  not spikes: on a noise-free stretch ``s`` falls to the resolution, ``s_d`` does not). Runs
  of more than :data:`SPIKE_MAX` flagged samples are not spikes (a bump,
  a step) and are left alone. Saturated and stuck samples are not also spikes.

Bits of the ``quality`` column (0 = good; flags OR-ed):

===== =========== ==============================================
bit   value        meaning
===== =========== ==============================================
0     1            saturated (at a flat-topped extreme)
1     2            stuck (constant run >= STUCK_S s)
2     4            spike (isolated robust outlier)
3     8            missing (NaN: empty cell, gap filled by resampling)
===== =========== ==============================================
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from vibrospeed.signal.dsp import median_filter  # scipy.ndimage's, mode "nearest"

SATURATED = 1
STUCK = 2
SPIKE = 4
MISSING = 8

SAT_RUN = 2
SAT_MIN = 3
STUCK_S = 0.25
STUCK_MIN = 8
SPIKE_K = 8.0
SPIKE_MAX = 3
#: a spike also exceeds this many times the robust scale of the channel's first difference
SPREAD_K = 2.0
SCALE_S = 5.0
_MED = 7


@dataclass(frozen=True)
class ChannelQuality:
    """Flags of one channel (``flags``: (n,) uint8 bit flags) and what was found."""

    name: str
    flags: np.ndarray
    rails: tuple[float, ...]  # the saturated extremes
    stuck_runs: tuple[tuple[int, int], ...]  # [start, stop) sample indices

    def count(self, bit: int) -> int:
        """Samples with ``bit`` set."""
        return int(np.count_nonzero(self.flags & bit))


def _runs(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops ([start, stop)) of the runs of exactly equal consecutive values of
    ``x`` (NaN never equals anything, so a NaN is a run of its own)."""
    if x.size == 0:
        return np.zeros(0, int), np.zeros(0, int)
    change = np.flatnonzero(x[1:] != x[:-1]) + 1
    starts = np.concatenate(([0], change))
    stops = np.concatenate((change, [x.size]))
    return starts, stops


def _resolution(x: np.ndarray) -> float:
    d = np.abs(np.diff(x[np.isfinite(x)]))
    d = d[d > 0]
    return float(d.min()) if d.size else 0.0


def _scale(r: np.ndarray, block: int) -> np.ndarray:
    """Per-sample robust scale of ``r`` (module docstring), NaN-aware."""
    n = r.size
    nb = -(-n // block)
    pad = np.full(nb * block, np.nan)
    pad[:n] = np.abs(r)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # an all-NaN block has no scale
        s = 1.4826 * np.nanmedian(pad.reshape(nb, block), axis=1)
    s = np.nan_to_num(s, nan=0.0)
    s3 = s.copy()
    s3[1:] = np.maximum(s3[1:], s[:-1])
    s3[:-1] = np.maximum(s3[:-1], s[1:])
    return np.repeat(s3, block)[:n]


def channel_quality(x: np.ndarray, fs: float, name: str = "") -> ChannelQuality:
    """Quality flags of one channel sampled at ``fs`` Hz (module docstring)."""
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    flags = np.zeros(n, dtype=np.uint8)
    fin = np.isfinite(x)
    flags[~fin] |= MISSING
    if not fin.any():
        return ChannelQuality(name, flags, (), ())
    starts, stops = _runs(x)
    lengths = stops - starts
    vals = x[starts]
    rails = []
    for ext in (np.max(x[fin]), np.min(x[fin])):
        at = vals == ext
        if at.any() and lengths[at].max() >= SAT_RUN and lengths[at].sum() >= SAT_MIN:
            if ext not in rails:
                rails.append(float(ext))
    sat = np.isin(x, rails) if rails else np.zeros(n, bool)
    flags[sat] |= SATURATED
    need = max(STUCK_MIN, int(np.ceil(STUCK_S * fs)))
    long_ = (lengths >= need) & np.isfinite(vals) & ~np.isin(vals, rails)
    stuck_runs = tuple((int(a), int(b)) for a, b in zip(starts[long_], stops[long_],
                                                        strict=True))
    for a, b in stuck_runs:
        flags[a:b] |= STUCK
    # spikes: residual from a 7-sample running median, robust local scale
    xf = np.where(fin, x, 0.0)
    med = median_filter(xf, _MED)
    r = np.where(fin, x - med, np.nan)
    block = max(_MED, int(round(SCALE_S * fs)))
    s = np.maximum(_scale(r, block), _resolution(x))
    # the signal's own spread: on a smooth, noise-free stretch the running median follows
    # the signal and ``s`` collapses to the resolution, so a wave's crests would stand out
    d = np.full(n, np.nan)
    d[1:] = np.diff(np.where(fin, x, np.nan))
    spread = _scale(d, block)
    with np.errstate(invalid="ignore"):
        cand = (fin & (np.abs(r) > SPIKE_K * s) & (np.abs(r) > SPREAD_K * spread) & (s > 0)
                & ~sat)
    if stuck_runs:
        cand &= (flags & STUCK) == 0
    if cand.any():
        cs, ce = _runs(cand.astype(np.int8))
        for a, b in zip(cs, ce, strict=True):
            if cand[a] and b - a <= SPIKE_MAX:
                flags[a:b] |= SPIKE
    return ChannelQuality(name, flags, tuple(rails), stuck_runs)


def describe(q: ChannelQuality, t: np.ndarray, unit: str = "") -> str | None:
    """One note for a channel with saturated, stuck or spike samples (None when clean)."""
    n = q.flags.size
    parts = []
    ns = q.count(SATURATED)
    if ns:
        at = " / ".join(f"{v:.6g}" for v in q.rails)
        parts.append(f"{ns} saturated ({100 * ns / n:.2g} %, at {at}{' ' + unit if unit else ''})")
    nk = q.count(STUCK)
    if nk:
        a, b = max(q.stuck_runs, key=lambda ab: ab[1] - ab[0])
        longest = (b - a) * (float(np.median(np.diff(t))) if t.size > 1 else 0.0)
        parts.append(f"{nk} stuck ({len(q.stuck_runs)} constant run(s), longest {longest:.3g} s "
                     f"from t = {t[a]:.6g} s)")
    nsp = q.count(SPIKE)
    if nsp:
        parts.append(f"{nsp} spike(s)")
    if not parts:
        return None
    return (f"quality: channel '{q.name}': " + ", ".join(parts)
            + " (flagged in the 'quality' column)")


def recording_quality(rec, channels=None) -> tuple[dict[str, ChannelQuality], list[str]]:
    """Per-channel quality of ``rec``'s accelerometer channels (or ``channels``) and one note
    per channel with findings."""
    names = [c for c in (channels or ("ax", "ay", "az")) if c in rec.channels]
    fs = rec.fs if len(rec) > 1 else 1.0
    out, notes = {}, []
    for c in names:
        q = channel_quality(rec.channels[c], fs, c)
        out[c] = q
        note = describe(q, rec.t, rec.units.get(c, ""))
        if note:
            notes.append(note)
    return out, notes


def flags_at(t_rec: np.ndarray, flags: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``flags`` of the recording sample nearest to each time in ``t`` (a track's rows)."""
    t_rec = np.asarray(t_rec, float)
    t = np.asarray(t, float)
    if t_rec.size < 2:
        return np.full(t.size, flags[0] if flags.size else 0, dtype=np.uint8)
    j = np.clip(np.searchsorted(t_rec, t), 1, t_rec.size - 1)
    left = (t - t_rec[j - 1]) <= (t_rec[j] - t)
    return flags[j - left.astype(int)]


def annotate(track, rec, channel: str | None = None):
    """Add the ``quality`` column (bit flags of ``channel``, the vibration axis the estimate
    used; default the first accelerometer channel present) and the notes on every
    accelerometer channel to ``track`` (in place; returned)."""
    qs, notes = recording_quality(rec)
    if channel is not None and channel not in qs and channel in rec.channels:
        qs.update(recording_quality(rec, (channel,))[0])
    use = channel if channel in qs else next(iter(qs), None)
    if use is not None:
        track.extras["quality"] = flags_at(rec.t, qs[use].flags, track.t).astype(np.float64)
    track.notes.extend(notes)
    return track


def mask_flagged(rec, bits: int = SPIKE, channels=None):
    """A copy of ``rec`` with the samples flagged ``bits`` set to NaN on each accelerometer
    channel (or ``channels``), and a note per channel: the trackers then bridge them by
    prediction instead of fitting them as vibration. Spikes only by default: a saturated or
    stuck sample still carries the sign or the rough level of the vibration."""
    qs, _ = recording_quality(rec, channels)
    new = dict(rec.channels)
    notes = list(rec.notes)
    for c, q in qs.items():
        hit = (q.flags & bits) != 0
        if hit.any():
            x = new[c].copy()
            x[hit] = np.nan
            new[c] = x
            notes.append(f"quality: channel '{c}': {int(hit.sum())} flagged sample(s) set to NaN")
    return replace(rec, channels=new, notes=notes)
