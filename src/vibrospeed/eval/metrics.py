"""Accuracy metrics of a :class:`~vibrospeed.types.Track` against ground truth.

The truth is linearly interpolated onto the estimate's time stamps (thesis eq. 3.18) and the
error statistics are taken over *moving* samples (truth omega above ``min_omega``), after an
optional warm-up. Coverage is the share of moving samples whose truth lies inside the reported
credible band: for an honest 98 % band it should be close to 0.98.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from typing import Any

import numpy as np

from vibrospeed.errors import InputError
from vibrospeed.types import Recording, Track


@dataclass(frozen=True)
class Metrics:
    """Error statistics in rad/s (``*_speed`` in m/s when both radii are known)."""

    n: int  # samples evaluated
    moving_share: float  # share of samples (after warm-up) where the truth is moving
    rmse: float
    mae: float
    bias: float  # mean(estimate - truth)
    rel_error: float  # mean(|error| / truth)
    coverage: float  # share of truth inside [lo, hi]
    level: float  # nominal band probability
    half_share: float  # share of samples near truth/2 (locked on a subharmonic)
    double_share: float  # share near 2 * truth
    rmse_speed: float
    unit: str = "rad/s"  # unit of rmse, mae, bias: "rad/s", or "m/s" when compared as speeds
    ok_share: float = float("nan")  # share within max(ok_abs, ok_rel * truth)
    claimed_share: float = float("nan")  # share of moving samples where has_signal (if reported)
    rmse_claimed: float = float("nan")  # RMSE where the tracker claims a signal
    ok_claimed: float = float("nan")  # ok share where the tracker claims a signal
    coverage_claimed: float = float("nan")  # band coverage where the tracker claims a signal
    vy_n: int = 0  # moving samples with both an estimated ``vy`` and a truth ``vy_true``
    vy_rmse: float = float("nan")  # lateral velocity (m/s) against vy_true, over those samples
    vy_mae: float = float("nan")
    vy_bias: float = float("nan")  # mean(vy - vy_true)
    vy_corr: float = float("nan")  # Pearson correlation of vy with vy_true (NaN if one is flat)
    #: median(|error| / truth): the typical relative error (the mean is ruled by a few samples
    #: near the truth's floor, where a guess off by a few rad/s is off by several hundred %)
    rel_error_median: float = float("nan")

    def to_dict(self) -> dict:
        """Plain dict (for JSON)."""
        return asdict(self)


def truth_omega(truth: Recording, wheel_radius: float | None = None) -> np.ndarray:
    """Truth omega (rad/s) from ``omega_true``, or ``speed_true / r``."""
    if "omega_true" in truth.channels:
        return truth.channel("omega_true")
    r = wheel_radius or truth.wheel_radius
    if "speed_true" in truth.channels and r:
        return truth.channel("speed_true") / r
    raise InputError(
        f"{truth.source or 'truth'}: no 'omega_true' channel (nor 'speed_true' with a known "
        "wheel radius) to compare against"
    )


#: s: a truth channel named for :func:`evaluate` (GPS speed: fixes with NaN between them) is
#: not interpolated between fixes further apart than this (an outage has no truth)
TRUTH_GAP_S = 2.0

#: a run of NaN truth samples spanning more than this many median periods of the finite ones is
#: a gap with no truth (the readers' rule for dense sensors), not bridged by interpolation
TRUTH_NAN_PERIODS = 5.0


def interp_truth(t_truth: np.ndarray, x_truth: np.ndarray, t: np.ndarray,
                 max_gap: float | None = None) -> np.ndarray:
    """Linear interpolation of the truth's finite samples at ``t``; NaN outside their span and,
    with ``max_gap`` (s), between finite samples further apart than that. Without ``max_gap``
    a stretch of NaN truth samples longer than :data:`TRUTH_NAN_PERIODS` median periods of the
    finite ones is no truth either: a dropped reference is not a straight line."""
    ok = np.isfinite(x_truth)
    if ok.sum() < 2:
        return np.full(t.shape, np.nan)
    tt = t_truth[ok]
    out = np.interp(t, tt, x_truth[ok], left=np.nan, right=np.nan)
    j = np.clip(np.searchsorted(tt, t), 1, tt.size - 1)  # tt[j - 1] <= t <= tt[j] inside
    dt = np.diff(tt)
    if max_gap is not None:
        cut = dt > max_gap
    else:  # only where NaN samples lie between two finite ones
        cut = (np.diff(np.flatnonzero(ok)) > 1) & (dt > TRUTH_NAN_PERIODS * np.median(dt))
    out[cut[j - 1] & (t != tt[j])] = np.nan
    return out


def compare(
    track: Track,
    truth_t: np.ndarray,
    truth_omega_values: np.ndarray,
    *,
    min_omega: float = 1.0,
    warmup: float = 0.0,
    tol: float = 0.15,
    ok_abs: float = 2.0,
    ok_rel: float = 0.10,
    truth_max_gap: float | None = None,
    truth_speed_values: np.ndarray | None = None,
    truth_vy_values: np.ndarray | None = None,
) -> Metrics:
    """Metrics of ``track`` against truth samples ``(truth_t, truth_omega_values)`` (rad/s).

    ``min_omega``: truth below this (rad/s) counts as standing still and is excluded.
    ``warmup``: seconds at the start of the track excluded. ``tol``: relative tolerance for the
    half/double harmonic shares. ``ok_abs`` (rad/s) and ``ok_rel``: a sample is "ok" within
    ``max(ok_abs, ok_rel * truth)`` (the tolerance of the accuracy tables). Where the track
    reports ``has_signal`` (grid trackers), the ``*_claimed`` fields score only the samples it
    claims. ``truth_max_gap`` (s): no truth between finite truth samples further apart
    (:func:`interp_truth`). ``truth_speed_values`` (m/s, at ``truth_t``): ``rmse_speed`` is the
    track's ``speed`` against them (its own radius may differ from the truth's: a learned or
    wrong one); without them it is the omega error times the track's radius.
    ``truth_vy_values`` (m/s, at ``truth_t``): where the track has a lateral velocity
    (``extras['vy']``, the algebraic method), the ``vy_*`` fields score it over the moving
    samples where both are finite (a vehicle tester's Vy figures beside the Vx ones).
    """
    w = interp_truth(np.asarray(truth_t, float), np.asarray(truth_omega_values, float), track.t,
                     truth_max_gap)
    after = track.t >= track.t[0] + warmup
    valid = after & np.isfinite(w)
    moving = valid & (w > min_omega) & np.isfinite(track.omega)
    n = int(moving.sum())
    share = float(moving.sum() / max(valid.sum(), 1))
    if n == 0:
        nan = float("nan")
        return Metrics(0, share, nan, nan, nan, nan, nan, track.level, nan, nan, nan)
    e = track.omega[moving] - w[moving]
    wt = w[moving]
    lo, hi = track.omega_lo[moving], track.omega_hi[moving]
    band_ok = np.isfinite(lo) & np.isfinite(hi)
    cov = float(np.mean((wt >= lo) & (wt <= hi))) if band_ok.any() else float("nan")
    est = track.omega[moving]
    half = float(np.mean(np.abs(est - wt / 2) < tol * wt / 2))
    double = float(np.mean(np.abs(est - 2 * wt) < tol * 2 * wt))
    r = track.wheel_radius
    rmse_v = float(np.sqrt(np.mean((r * e) ** 2))) if r else float("nan")
    if truth_speed_values is not None:
        vt = interp_truth(np.asarray(truth_t, float), np.asarray(truth_speed_values, float),
                          track.t, truth_max_gap)[moving]
        ev = np.asarray(track.speed, float)[moving] - vt
        ev = ev[np.isfinite(ev)]
        rmse_v = float(np.sqrt(np.mean(ev**2))) if ev.size else float("nan")
    ok = np.abs(e) <= np.maximum(ok_abs, ok_rel * wt)
    lateral = {}
    if truth_vy_values is not None and "vy" in track.extras:
        lateral = _vy_metrics(np.asarray(track.extras["vy"], float), interp_truth(
            np.asarray(truth_t, float), np.asarray(truth_vy_values, float), track.t,
            truth_max_gap), moving)
    claimed = {}
    if "has_signal" in track.extras:
        c = np.asarray(track.extras["has_signal"], float)[moving] > 0.5
        claimed = dict(claimed_share=float(c.mean()))
        if c.any():
            cov_c = (wt[c] >= lo[c]) & (wt[c] <= hi[c])
            claimed.update(rmse_claimed=float(np.sqrt(np.mean(e[c] ** 2))),
                           ok_claimed=float(ok[c].mean()), coverage_claimed=float(cov_c.mean()))
    return Metrics(
        n=n,
        moving_share=share,
        rmse=float(np.sqrt(np.mean(e**2))),
        mae=float(np.mean(np.abs(e))),
        bias=float(np.mean(e)),
        rel_error=float(np.mean(np.abs(e) / wt)),
        rel_error_median=float(np.median(np.abs(e) / wt)),
        coverage=cov,
        level=track.level,
        half_share=half,
        double_share=double,
        rmse_speed=rmse_v,
        ok_share=float(ok.mean()),
        **claimed,
        **lateral,
    )


def _vy_metrics(vy: np.ndarray, vy_true: np.ndarray, moving: np.ndarray) -> dict[str, Any]:
    """The ``vy_*`` fields of :class:`Metrics`: the estimate's lateral velocity against the
    truth's (both m/s, on the estimate's time line) over the ``moving`` samples where both are
    finite; none such: no fields (``vy_n`` stays 0)."""
    both = moving & np.isfinite(vy) & np.isfinite(vy_true)
    if not both.any():
        return {}
    est, ref = vy[both], vy_true[both]
    e = est - ref
    flat = np.ptp(est) == 0 or np.ptp(ref) == 0  # a constant series has no correlation
    corr = float("nan") if flat or e.size < 2 else float(np.corrcoef(est, ref)[0, 1])
    return dict(vy_n=int(e.size), vy_rmse=float(np.sqrt(np.mean(e**2))),
                vy_mae=float(np.mean(np.abs(e))), vy_bias=float(np.mean(e)), vy_corr=corr)


def evaluate(track: Track, truth: Recording, *, min_speed: float = 0.3,
             truth_channel: str | None = None, **kw) -> Metrics:
    """:func:`compare` against a truth recording (``omega_true`` or ``speed_true``).

    A speed estimate without a wheel radius (GPS fusion, algebraic Vx) against ``speed_true`` is
    compared as speeds (m/s; ``min_speed`` m/s marks standstill), reported with ``unit="m/s"``.
    ``truth_channel``: another channel of ``truth`` holding the speed in m/s (``gps_speed``: a
    phone drive scored against its GPS), used as ``speed_true``, not interpolated across gaps
    over :data:`TRUTH_GAP_S` between its finite samples (its fixes). Where the truth has
    ``vy_true`` and the estimate a lateral velocity ``vy``, the ``vy_*`` fields score it.
    """
    if "vy_true" in truth.channels:  # kept whatever channel the speed is scored against
        kw.setdefault("truth_vy_values", truth.channel("vy_true"))
    measured = truth_channel is not None and truth_channel not in ("omega_true", "speed_true")
    src = truth.source or "truth"
    if truth_channel is not None:
        truth.require(truth_channel)
        unit = truth.units.get(truth_channel, "")
        if measured and unit not in ("", "m/s"):  # a count, an acceleration: not a speed
            raise InputError(f"{src}: truth channel '{truth_channel}' is in {unit}, not a "
                             "speed in m/s")
        truth = Recording(truth.t, {"speed_true" if measured else truth_channel:
                                    truth.channel(truth_channel)},
                          wheel_radius=truth.wheel_radius, source=truth.source)
    if measured:  # a measured speed: compared as speeds where the estimate has one
        kw.setdefault("truth_max_gap", TRUTH_GAP_S)
        if not np.isfinite(track.speed).any() and not (track.wheel_radius
                                                       or truth.wheel_radius):
            raise InputError(f"{src}: truth channel '{truth_channel}' is a speed (m/s) and the "
                             "estimate has omega only (rad/s, no wheel radius): estimate "
                             "with --wheel-radius to compare them")
    if "speed_true" not in truth.channels and "omega_true" in truth.channels \
            and truth.wheel_radius:  # the truth's speed through its own wheel
        truth = Recording(truth.t, {**truth.channels, "speed_true":
                                    truth.channel("omega_true") * truth.wheel_radius},
                          wheel_radius=truth.wheel_radius, source=truth.source)
    speed_only = not np.isfinite(track.omega).any() and np.isfinite(track.speed).any()
    if speed_only and "speed_true" not in truth.channels:
        raise InputError(f"{src}: the estimate has speeds only (m/s, no wheel radius) and the "
                         "truth omega_true without a wheel radius (a .json sidecar with "
                         "wheel_radius) or speed_true: nothing to compare them in")
    r = track.wheel_radius or truth.wheel_radius
    has_omega_truth = "omega_true" in truth.channels or ("speed_true" in truth.channels and r)
    speed_est = np.isfinite(track.speed).any()
    if (measured or not has_omega_truth or not np.isfinite(track.omega).any()) and speed_est \
            and "speed_true" in truth.channels:
        as_speed = Track(track.t, track.speed, track.speed_std, track.speed_lo, track.speed_hi,
                         track.speed, track.speed_std, track.speed_lo, track.speed_hi,
                         level=track.level, wheel_radius=1.0,
                         extras={k: track.extras[k] for k in ("vy", "has_signal")
                                 if k in track.extras})  # scored as on the omega path
        kw.pop("min_omega", None)
        m = compare(as_speed, truth.t, truth.channel("speed_true"), min_omega=min_speed, **kw)
        return replace(m, unit="m/s")
    # the speed error from the speeds themselves: a track's radius (fuse's learned one) need not
    # be the truth's, and then the omega error times it is not the speed error
    if "speed_true" in truth.channels:
        kw.setdefault("truth_speed_values", truth.channel("speed_true"))
    return compare(track, truth.t, truth_omega(truth, track.wheel_radius), **kw)


def time_to_lock(
    t: np.ndarray, est: np.ndarray, truth: np.ndarray, *, tol: float = 2.0
) -> float:
    """Seconds from ``t[0]`` until ``|est - truth| < tol`` holds for good (inf if never)."""
    bad = ~(np.abs(est - truth) < tol)
    if not bad.any():
        return 0.0
    last_bad = int(np.flatnonzero(bad)[-1])
    if last_bad == t.size - 1:
        return float("inf")
    return float(t[last_bad + 1] - t[0])


# -- summary numbers of one track (batch summaries, reports) ---------------------------------
def fitted_radius(track) -> float:
    """The wheel radius in m that the method fitted on this drive, else NaN
    (:func:`radius_fit`'s radius)."""
    return radius_fit(track)[0]


def radius_fit(track) -> tuple[float, float]:
    """``(radius, std)`` in m of a wheel radius that the method fitted on this drive: NaN, NaN
    where it fitted none (the std NaN where the method gives none). The sources, first found:

    - ``params['fitted_radius']`` (with ``params['fitted_radius_std']``);
    - the last finite value of a per-sample ``wheel_radius_fit`` column;
    - ``fuse``'s learned radius (``params['learned_radius']``, ``['learned_radius_std']``)
      where :func:`fuse_radius_learned` says this drive taught it.
    """
    par = track.params if isinstance(track.params, dict) else {}
    r = par.get("fitted_radius")
    if _finite(r):
        s = par.get("fitted_radius_std")
        return float(r), float(s) if _finite(s) else math.nan
    col = track.extras.get("wheel_radius_fit")
    if col is not None:
        x = np.asarray(col, dtype=np.float64)
        x = x[np.isfinite(x)]
        if x.size:
            return float(x[-1]), math.nan
    if fuse_radius_learned(par):
        return float(par["learned_radius"]), float(par["learned_radius_std"])
    return math.nan, math.nan


def _finite(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def fuse_radius_learned(params: dict) -> bool:
    """Whether a ``fuse`` estimate's parameters (its sidecar's ``params``) hold a radius this
    drive learned: fuse's own test of a known radius (std below ``octave_rel`` of it, the test
    that gives the estimate its omega column) and, where a prior was given (``radius_prior``
    ``[r0, std0]``: ``radius_from`` or a wheel radius), a std below the prior's. A drive that
    saw no wheel line while GPS was good keeps its prior: with the default prior (std 0.15 m)
    the radius is not known; with a given one it is, but it is that drive's input, not what
    it measured (without GPS the filter's std stays at the prior's or grows)."""
    r, s = params.get("learned_radius"), params.get("learned_radius_std")
    if not (_finite(r) and _finite(s) and r > 0):
        return False
    rel = params.get("octave_rel")
    if not _finite(rel):
        from vibrospeed.estimators.fuse.config import Config

        rel = Config.octave_rel
    if not s < rel * r:
        return False
    prior = params.get("radius_prior")
    if isinstance(prior, (list, tuple)) and len(prior) == 2 and _finite(prior[1]):
        return s < prior[1]
    return True


#: what ``fuse``'s ``source`` column's values 0-3 mean (:mod:`vibrospeed.estimators.fuse`)
SOURCE_NAMES = ("accelerometer", "gps", "vibration", "standstill")

#: The ``note`` of a track whose speed numbers are left empty (see :func:`track_summary`). It
#: names the wheel line alone: most methods that say where they see one read no GPS (a
#: recording's GPS is no evidence for them), and ``fuse``'s summary gives its source shares.
NO_EVIDENCE_NOTE = ("no wheel line claimed while moving: median_speed, median_omega and "
                    "distance_m left empty")


def evidence(track) -> tuple[np.ndarray, np.ndarray] | None:
    """Per sample, ``(moving, standing)``: whether the estimate rests on a measurement of the
    moving vehicle (a claimed wheel line, ``has_signal``; for ``fuse`` a GPS or vibration
    ``source``) and whether it is a detected standstill (``standstill``; ``fuse``'s standstill
    source). ``None`` when the track does not say (no ``has_signal`` column: the EKF, SHS,
    gps-riss, ...)."""
    if "has_signal" not in track.extras:
        return None
    moving = np.nan_to_num(np.asarray(track.extras["has_signal"], dtype=np.float64)) > 0.5
    standing = np.zeros(moving.size, bool)
    if "standstill" in track.extras:
        standing |= np.nan_to_num(np.asarray(track.extras["standstill"], dtype=np.float64)) > 0.5
    if "source" in track.extras:
        from vibrospeed.estimators.fuse.config import SRC_GPS, SRC_STANDSTILL, SRC_VIBRATION

        src = np.asarray(track.extras["source"], dtype=np.float64)
        moving |= (src == SRC_GPS) | (src == SRC_VIBRATION)
        standing |= src == SRC_STANDSTILL
    return moving, standing & ~moving


def track_summary(track) -> dict[str, Any]:
    """The summary numbers of a track, the same for a batch row and a drive report:
    ``signal_share``, ``median_speed``, ``median_omega``, ``distance_m``, ``distance_lo_m``,
    ``distance_hi_m``, ``fitted_radius`` and ``fitted_radius_std`` (:func:`radius_fit`; NaN
    where they do not apply), ``source_shares``
    (``fuse``: the share of the samples whose speed rests on each of :data:`SOURCE_NAMES`;
    empty for other methods) and ``note``.
    ``distance_lo_m`` / ``distance_hi_m`` integrate the band's edges (``speed_lo``,
    ``speed_hi``) as ``distance_m`` integrates the speed: the distance if every sample sat at
    the lower or at the upper edge of its band, an envelope (the errors of neighbouring
    samples are not independent, so no narrower band follows from the per-sample ones
    without a model of their correlation).

    Where the method says per sample whether it saw anything (``has_signal``) and no sample
    rests on a measurement of the moving vehicle (:func:`evidence`: no claimed line, no
    GPS-held ``fuse`` sample), the estimate wherever the vehicle was not detected standing is
    the tracker's prior carried through the drive, not a measurement: ``median_speed``,
    ``median_omega`` and the distances are NaN and ``note`` is :data:`NO_EVIDENCE_NOTE`. A
    parked vehicle (a standstill on every sample) keeps its 0 m/s and 0 m, a ``fuse`` drive
    without a wheel line keeps its GPS-held speed. Otherwise the medians and the distance are
    over all samples and ``note`` is empty; ``signal_share`` says how much of them rests on a
    line.
    """
    acc = SummaryAccumulator(np.float64)
    acc.add(track)
    return acc.result()


class SummaryAccumulator:
    """:func:`track_summary` of a track given in consecutive pieces (a long log estimated in
    blocks, :func:`vibrospeed.estimators.grid.stream.estimate_file`): ``add`` each piece in
    order, then ``result()``. The shares and the distance are those of the whole track (the
    interval between two pieces counted as its own trapezoid); the medians are taken over
    copies of the finite speeds and omegas in ``dtype``: float32 for a long log in blocks (4
    bytes a sample each, 69 MB for a day of 100 Hz; the medians then agree with the whole
    track's to float32 precision), float64 for one whole track (:func:`track_summary`)."""

    def __init__(self, dtype=np.float32) -> None:
        self.dtype = dtype
        self.has_signal = False  # whether the pieces carry a has_signal column
        self.n_sig = 0
        self.n_sig_finite = 0
        self.sources = np.zeros(4, np.int64)  # fuse's samples per source (SRC_* order)
        self.seen_moving = False  # a sample rests on a measurement of the moving vehicle
        self.n_guessed = 0  # samples resting neither on that nor on a detected standstill
        self.speeds: list[np.ndarray] = []
        self.omegas: list[np.ndarray] = []
        self.dist = np.zeros(3)  # the trapezoids of speed, speed_lo, speed_hi
        self.dist_ok = np.zeros(3, bool)
        self.last: tuple[float, np.ndarray] | None = None
        self.radius = (math.nan, math.nan)  # the last piece's radius_fit that has one

    def add(self, track) -> None:
        t = np.asarray(track.t, dtype=np.float64)
        v = np.asarray(track.speed, dtype=np.float64)
        sig = track.extras.get("has_signal")
        if sig is not None:
            s = np.asarray(sig, dtype=np.float64)
            s = s[np.isfinite(s)]
            self.has_signal = True
            self.n_sig += int(np.count_nonzero(s > 0.5))
            self.n_sig_finite += int(s.size)
        src = track.extras.get("source")
        if src is not None:
            src = np.asarray(src, dtype=np.float64)
            src = src[np.isfinite(src)].astype(np.int64)
            self.sources += np.bincount(src[(src >= 0) & (src < 4)], minlength=4)
        ev = evidence(track)
        if ev is not None:
            self.seen_moving |= bool(ev[0].any())
            self.n_guessed += int(np.count_nonzero(~(ev[0] | ev[1])))
        for keep, x in ((self.speeds, v), (self.omegas, track.omega)):
            x = np.asarray(x, dtype=np.float64)
            keep.append(x[np.isfinite(x)].astype(self.dtype))
        V = np.vstack([v, np.asarray(track.speed_lo, dtype=np.float64),
                       np.asarray(track.speed_hi, dtype=np.float64)])
        tt, VV = (t, V) if self.last is None else (np.r_[self.last[0], t],
                                                   np.column_stack([self.last[1], V]))
        if tt.size >= 2:
            dt = np.diff(tt)
            for i, vv in enumerate(VV):
                ok = np.isfinite(vv[:-1]) & np.isfinite(vv[1:])
                if ok.any():
                    self.dist[i] += float(np.sum(0.5 * (vv[:-1] + vv[1:])[ok] * dt[ok]))
                    self.dist_ok[i] = True
        if t.size:
            self.last = (float(t[-1]), V[:, -1].copy())
        fit = radius_fit(track)
        if math.isfinite(fit[0]):
            self.radius = fit

    def result(self) -> dict[str, Any]:
        """The dict of :func:`track_summary`."""
        def median(parts):
            x = np.concatenate(parts) if parts else np.zeros(0, self.dtype)
            return float(np.median(x.astype(np.float64))) if x.size else math.nan

        share = math.nan
        if self.has_signal and self.n_sig_finite:
            share = self.n_sig / self.n_sig_finite
        out: dict[str, Any] = {
            "signal_share": share,
            "median_speed": median(self.speeds),
            "median_omega": median(self.omegas),
            "distance_m": self.dist[0] if self.dist_ok[0] else math.nan,
            "distance_lo_m": self.dist[1] if self.dist_ok[1] else math.nan,
            "distance_hi_m": self.dist[2] if self.dist_ok[2] else math.nan,
            "fitted_radius": self.radius[0],
            "fitted_radius_std": self.radius[1],
            "source_shares": ({name: int(k) / int(self.sources.sum()) for name, k in zip(
                SOURCE_NAMES, self.sources, strict=True)} if self.sources.sum() else {}),
            "note": "",
        }
        if self.has_signal and not self.seen_moving and self.n_guessed:
            out.update(median_speed=math.nan, median_omega=math.nan, distance_m=math.nan,
                       distance_lo_m=math.nan, distance_hi_m=math.nan, note=NO_EVIDENCE_NOTE)
        return out
