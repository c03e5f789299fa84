"""``fuse`` on a device, one IMU sample at a time: :class:`FuseTracker` gives the numbers of
``fuse.estimate(rec, params={"online": True})`` (the forward filter computed in batch) from a
stream, with the same pieces: the causal grid tracker
(:class:`vibrospeed.estimators.online.OnlineTracker` with its stop detector), the fusion
samples (:func:`~vibrospeed.estimators.fuse.method.fusion_samples`' rule, which is causal: a
block ends every ``round(1 / (fuse_rate dt))`` samples counted from the first and at every
GPS fix, and the last at the log's end), their block means, the causal learned band density
(:func:`~vibrospeed.estimators.fuse.band.learn_acc_psd_causal`, its fix pairs decided as the
fixes come) and :func:`~vibrospeed.estimators.fuse.filter.step`.

An estimate becomes final (is returned) once what the batch run decides it from has arrived:

* the filter starts at the first valid fix's speed (the batch's ``init``), so before it the
  fusion samples wait (``v0=`` starts at once; without GPS give ``v0=0.0``, the batch's start);
* a sample between two fusion samples is interpolated between them (linear, ``np.interp``);
* with ``band_psd=learned`` a fusion sample's band density is the one estimated at the last
  checkpoint (every 5 s, later every 2 % of the elapsed time:
  :func:`~vibrospeed.estimators.fuse.band.next_checkpoint`), from the fix pairs ending by
  then; whether a pair ends there can hang on the next fix (the pair's partner is the fix
  nearest ``T`` s later, within 20 %), so a fusion sample may wait until no fix to come could
  be nearer, at most ``0.4 T`` (3.2 s) past the checkpoint; and the log's last fusion sample
  takes the density of all pairs (batch: a checkpoint at the last sample), so the newest
  fusion sample waits for the next IMU sample.

With a fixed lag (:func:`config_for` with ``params={"lag": S}``, a device that can wait
``S`` s) the tracker inside is :class:`vibrospeed.estimators.grid.LaggedTracker` (the grid
tracker's fixed-lag smoother and its stops) and the lines are read with the offline settings,
the numbers of ``fuse.estimate(rec, params={"lag": S})``: each sample is processed once the
tracker gives its estimate (``S`` to ``2 S`` s later), so every estimate comes that much
later than with the causal tracker. With ``vib_measure="posterior"`` the tracker's estimates
carry their smoothed posterior rows (``LaggedTracker(..., posterior=True)``, the rows of the
batch smoother's ``return_posterior``), read at the fusion samples as the batch reads them.

Left out (the batch run decides them from the whole log; notes, not numbers): the accelerometer
sign and axis checks against the GPS speed, the radius-prior mismatch note, the note of the
learned radius. ``omega`` is the speed over the radius learned so far (where known); the batch
column divides by the radius at the log's end.
"""

from __future__ import annotations

import math
from array import array
from collections import deque
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from vibrospeed.config import config_from_params, parse_flag
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.common import gps_no_fix_as_nan, signed_axis
from vibrospeed.estimators.fuse.band import (
    CAUSAL_EVERY,
    INTERVALS,
    PAIR_TOL,
    _slope,
    next_checkpoint,
)
from vibrospeed.estimators.fuse.config import (
    CAUSAL_VIB_AMAX,
    CAUSAL_VIB_LAG,
    CAUSAL_VIB_MEASURE,
    CAUSAL_VIB_SEP,
    CAUSAL_VIB_SOFT,
    SRC_STANDSTILL,
    TRACKER_DEFAULTS,
    Config,
)
from vibrospeed.estimators.fuse.filter import Sample, init, step
from vibrospeed.estimators.fuse.method import _lag_of, _read_radius, _split, _too_slow
from vibrospeed.types import Estimate, Recording, check_wheel_radius

__all__ = ["DeviceConfig", "FuseTracker", "config_for"]


class DeviceConfig(NamedTuple):
    """What :class:`FuseTracker` is built from: the fusion ``fuse`` Config (the online
    defaults applied, or with a lag the offline reading of lines; ``radius0`` /
    ``radius_std0`` the radius prior) and the grid tracker's Config, causal
    (``smooth="none"``) or fixed-lag (``smooth="lag"``) (None: the log is too slow to carry
    a wheel line, the vibration is off)."""

    fuse: Config
    tracker: object | None


def config_for(recording: Recording, *, axis: str = "y", params: dict | None = None,
               wheel_radius: float | None = None,
               radius_from: str | None = None) -> DeviceConfig:
    """The configs ``fuse.estimate(recording, axis=axis, params={"online": True, **params},
    wheel_radius=, radius_from=)`` runs on (as ``grid.config_for`` for the grid): the
    recording only fixes the tracker's sample rate, the radius prior and whether it has GPS.
    With ``params["lag"]`` (s): those of ``fuse.estimate(recording, params={"lag": S, ...})``,
    the fixed-lag tracker (``smooth="lag"``) and the lines read as offline (none of the
    ``CAUSAL_*`` settings; ``vib_measure="posterior"`` reads the fixed-lag smoother's
    posterior)."""
    from vibrospeed.estimators import grid

    fuse_kw, own, rest = _split(dict(params or {}))
    lag = _lag_of(own.get("lag"))
    # with a lag the batch runs the forward filter whatever online says
    if lag is None and not parse_flag(own.get("online", True), "online"):
        raise ParameterError("fuse device: a device runs the forward filter (online=true)")
    cfg = config_from_params(Config, fuse_kw)
    if lag is None:  # the causal tracker's lines trail the speed: the online settings
        online = {"vib_lag": CAUSAL_VIB_LAG, "vib_spread": "mode",
                  "vib_amax": CAUSAL_VIB_AMAX, "vib_soft": CAUSAL_VIB_SOFT}
        cfg = replace(cfg, **{k: v for k, v in online.items() if k not in fuse_kw})
        if "vib_measure" not in fuse_kw and cfg.vib_use == "line":
            cfg = replace(cfg, vib_measure=CAUSAL_VIB_MEASURE)
        if cfg.vib_measure == "posterior" and "vib_sep" not in fuse_kw:
            cfg = replace(cfg, vib_sep=CAUSAL_VIB_SEP)
    name = recording.source or "recording"
    rec, _ = gps_no_fix_as_nan(recording)
    has_gps = "gps_speed" in rec and np.isfinite(rec.channel("gps_speed")).any()
    rf = radius_from if radius_from is not None else own.get("radius_from")
    if rf is not None:
        r0, rs0, _ = _read_radius(rf)
        if rs0 >= cfg.octave_rel * r0 and not has_gps:
            raise ParameterError(f"{rf}: {r0:.4f} +- {rs0:.4f} m is no learned radius; fuse "
                                 "without gps_speed needs a radius")
    elif wheel_radius:
        r0 = check_wheel_radius(wheel_radius)
        rs0 = 0.01 * r0
    elif has_gps:
        r0, rs0 = cfg.radius0, cfg.radius_std0
    else:
        raise ParameterError(f"{name}: fuse without gps_speed needs a radius: radius_from= an "
                             "earlier fuse estimate's .json, or wheel_radius=")
    if not cfg.radius_min <= r0 <= cfg.radius_max:
        raise ParameterError(f"{name}: radius prior {r0:.4g} m is outside radius_min.."
                             f"radius_max ({cfg.radius_min:g}-{cfg.radius_max:g} m)")
    cfg = replace(cfg, radius0=r0, radius_std0=rs0)
    if _too_slow(rec, rest) is not None:
        return DeviceConfig(replace(cfg, vib_measure="mode"), None)
    if lag is None:
        tparams = {**TRACKER_DEFAULTS, **rest, "smooth": "none"}
    else:
        tparams = {**TRACKER_DEFAULTS, **rest, "smooth": "lag", "lag": lag}
    return DeviceConfig(cfg, grid.config_for(rec, axis=axis, params=tparams))


class _Band:
    """The causal band density of :func:`learn_acc_psd_causal` as fixes come: each fix's
    partner ``T`` s later is decided as batch ``_pairs`` decides it on the whole log (the
    nearer of the last fix before ``fix + T`` and the first at or after it), once that is
    known; a checkpoint's density (:func:`_slope` of the pairs ending by it) once no fix
    still undecided could get a partner by it."""

    def __init__(self, every: float = CAUSAL_EVERY) -> None:
        self.every = every
        self.cum = 0.0  # sum of accel dt over the fusion samples (batch: a cumsum)
        self.nbad = 0  # fusion samples without an acceleration, the first not counted
        self.t_prev = math.nan
        # per valid fix: time, speed, cum, nbad at it; per interval the pairs' r, dt and end.
        # Flat float64 arrays (8 bytes a value, not a Python float's 32): the batch's density
        # is a median over every pair so far, so they are all kept (~30 MB a day at 10 Hz)
        self.tf, self.gf, self.cf, self.bf = array("d"), array("d"), array("d"), array("q")
        self.pending = [deque() for _ in INTERVALS]  # fixes whose partner is not decided
        self.pairs = [(array("d"), array("d"), array("d")) for _ in INTERVALS]
        self.t0 = math.nan  # the first fusion sample's time
        self.c = math.nan  # the next checkpoint (band.next_checkpoint's sequence)
        self.q = math.nan  # the last density learned (NaN: none yet)

    def add(self, t: float, accel: float, fix: float) -> None:
        """One fusion sample: its time, mean acceleration, valid GPS fix (NaN: none)."""
        if math.isnan(self.t_prev):
            self.t0, self.c = t, t + self.every
            ok = True
            dt = 0.0
        else:
            ok = math.isfinite(accel)
            dt = t - self.t_prev
        self.cum += (accel if math.isfinite(accel) else 0.0) * dt
        self.nbad += 0 if ok else 1
        self.t_prev = t
        if math.isnan(fix):
            return
        self.tf.append(t)
        self.gf.append(fix)
        self.cf.append(self.cum)
        self.bf.append(self.nbad)
        j = len(self.tf) - 1
        for n, T in enumerate(INTERVALS):
            pend = self.pending[n]
            while pend and t >= self.tf[pend[0]] + T:  # the first fix at or after the target
                self._pair(n, pend.popleft(), j)
            pend.append(j)

    def _choice(self, i: int, j: int, T: float) -> int:
        """Batch's partner of fix ``i`` with ``j`` the first fix at / after its target (or
        the last fix): ``j - 1`` where strictly nearer."""
        tf = self.tf
        return j - 1 if abs(tf[j - 1] - tf[i] - T) < abs(tf[j] - tf[i] - T) else j

    def _valid(self, i: int, j: int, T: float) -> bool:
        return j > i and abs(self.tf[j] - self.tf[i] - T) <= PAIR_TOL * T \
            and self.bf[j] == self.bf[i]

    def _pair(self, n: int, i: int, j: int) -> None:
        T = INTERVALS[n]
        j = self._choice(i, max(j, 1), T)
        if self._valid(i, j, T):
            r, d, e = self.pairs[n]
            r.append((self.gf[j] - self.gf[i]) - (self.cf[j] - self.cf[i]))
            d.append(self.tf[j] - self.tf[i])
            e.append(self.tf[j])

    def finish(self) -> None:
        """The log ended: the undecided fixes take the last fix as batch's clipped search."""
        last = len(self.tf) - 1
        for n in range(len(INTERVALS)):
            while self.pending[n]:
                i = self.pending[n].popleft()
                if last >= 1:
                    self._pair(n, i, last)

    def _settle(self, c: float, t_now: float) -> bool:
        """Decide the undecided fixes that could still give a pair ending by ``c`` where the
        fixes up to ``t_now`` decide them already (any later fix would be further from the
        target); True where one still hangs on a fix to come."""
        last = len(self.tf) - 1
        for n, T in enumerate(INTERVALS):
            pend = self.pending[n]
            for i in list(pend):
                ends = {last, self._choice(i, max(last, 1), T)} if last >= 1 else set()
                if not any(self._valid(i, j, T) and self.tf[j] <= c for j in ends):
                    continue  # no partner it may still get ends by c
                if len(ends) > 1:
                    return True  # the log's end would give another partner
                gap = t_now - self.tf[i] - T
                if not (gap >= 0 and gap > abs(self.tf[last] - self.tf[i] - T)):
                    return True  # a fix still to come could be nearer the target
                pend.remove(i)
                self._pair(n, i, last)
        return False

    def density(self, t: float, t_now: float, last: bool) -> float | None:
        """The density of a fusion sample at ``t`` (NaN: none learned yet; None: not known
        yet); ``t_now``: the time up to which every fix has arrived; ``last``: the log's last
        fusion sample (after :meth:`finish`)."""
        while True:
            c = self.c
            if not c <= t or (last and c >= t):
                break
            if self._settle(c, t_now):
                return None
            self._learn(c)
            self.c = next_checkpoint(c, self.t0, self.every)
        if last:
            self._learn(t)
        return self.q

    def _learn(self, c: float) -> None:
        """The density from the pairs ending by ``c`` (kept where too few pairs)."""
        sel = []
        for r, d, e in self.pairs:  # each in order of the pairs' ends: the prefix ending by c
            e = np.frombuffer(e, dtype=np.float64)
            m = int(np.searchsorted(e, c, side="right"))
            sel.append((np.frombuffer(r, dtype=np.float64)[:m],
                        np.frombuffer(d, dtype=np.float64)[:m], e[:m]))
        q = _slope(sel, INTERVALS)
        if q is not None:
            self.q = q


class _Block(NamedTuple):
    """A fusion sample waiting for the filter: its last IMU sample and the filter's input."""

    end: int
    sample: Sample
    band_fix: float  # the valid fix for the band (NaN: none)


class FuseTracker:
    """``fuse``'s forward filter on a stream of IMU samples (module notes).

    Parameters
    ----------
    config, tracker : :func:`config_for`'s ``fuse`` and ``tracker`` (``DeviceConfig``
        unpacks as both); tracker None: no vibration part (a log too slow for a wheel line),
        then ``dt`` (s) gives the sample period. A tracker config with ``smooth="lag"`` runs
        :class:`vibrospeed.estimators.grid.LaggedTracker` inside (each sample processed
        once its lagged estimate comes; with ``vib_measure="posterior"`` it keeps its
        smoothed posterior rows), ``smooth="none"`` the causal ``OnlineTracker``.
    level : the tracked axis' resting level (:func:`vibrospeed.estimators.common.start_level`
        of its first second, as the batch pre-filter starts), one per comb axis.
    standstill : the accelerometer axes the stop detector reads (the tracked one first, the
        rest in ``others``): the batch run reads every axis of ``ax ay az`` present (3).
    accel_axis : the longitudinal channel as fuse's ``accel_axis``: only its sign is used (a
        leading ``-`` negates the ``accel`` samples).
    v0 : m/s, start speed; None: the first valid fix's, as the batch run (samples wait for it;
        without GPS at all give 0.0).
    """

    def __init__(self, config: Config, tracker=None, *, level=None, standstill: int = 3,
                 accel_axis: str = "x", v0: float | None = None,
                 dt: float | None = None) -> None:
        from vibrospeed.estimators import grid
        from vibrospeed.estimators.online import OnlineTracker

        if not isinstance(config, Config):
            raise ParameterError(f"FuseTracker: config must be a fuse Config, got "
                                 f"{type(config).__name__}")
        self.config = config
        self.sign = signed_axis(accel_axis)[1]
        self.trk = None
        self.lagged = False
        self.n_vib = 1
        if tracker is not None:
            if not isinstance(tracker, grid.Config):
                raise ParameterError(f"FuseTracker: tracker must be a grid Config "
                                     f"(config_for), got {type(tracker).__name__}")
            smooth = tracker.tracker.smooth
            if smooth not in ("none", "lag"):
                raise ParameterError(f"FuseTracker: the tracker must be causal (smooth=none) "
                                     f"or fixed-lag (smooth=lag), got smooth={smooth}")
            self.lagged = smooth == "lag"
            if self.lagged:
                self.trk = grid.LaggedTracker(tracker, level=level, standstill=standstill,
                                              posterior=config.vib_measure == "posterior")
            else:
                self.trk = OnlineTracker(grid, tracker, level=level, standstill=standstill)
            self.n_vib = self.trk.n_axes
            dt = tracker.tracker.model.dt
            self.grid = np.asarray(tracker.tracker.grid, dtype=np.float64)
        elif dt is None or not dt > 0:
            raise ParameterError("FuseTracker: without a tracker give the sample period dt > 0")
        self.n_others = max(standstill - self.n_vib, 0) if tracker is not None else 0
        self.block = max(1, int(round(1.0 / (config.fuse_rate * dt))))
        self.post = tracker is not None and config.vib_measure == "posterior"
        self.band = _Band() if config.band_density() == "learned" else None
        if v0 is not None and not math.isfinite(v0):
            raise ParameterError(f"FuseTracker: v0 must be a finite speed, got {v0}")
        self.v0 = None if v0 is None else float(v0)
        self.state = None if v0 is None else self._init(self.v0)
        self.n = 0  # samples given to update()
        self.t = math.nan  # the last one's time
        # per sample given but not yet processed (its tracker estimate not yet in; with the
        # causal tracker none stays): t, accel, gps_speed, gps_sats, vib sample finite
        self.raw: deque[tuple] = deque()
        self.m = 0  # samples processed (their tracker estimate in), in index order
        self.tm = math.nan  # the last processed one's time
        self.cs = 0.0  # running sums of the finite accel samples (batch: a cumsum)
        self.cn = 0
        self.cs0, self.cn0 = 0.0, 0  # at the start of the open block
        self.still_all = True
        self.blocks: deque[_Block] = deque()
        self.samples: deque[tuple] = deque()  # (index, t, omega_vib, has_signal, still_vib)
        self.prev = None  # the last fusion sample's (t, its speed, std, radius, std, offset)
        self._last = None  # what closes the open block (update's last sample)
        self.finished = False

    def _init(self, v0: float):
        c = self.config
        return init(c, v0, radius=c.radius0, radius_std=c.radius_std0)

    def _check(self, t, accel, vib, g, sats, others):
        i = self.n
        if self.finished:
            raise InputError(f"FuseTracker: sample {i}: update after finish()")
        vals = {"t": t, "accel": accel, "gps_speed": g, "gps_sats": sats,
                "vib": np.ravel(vib)[0] if np.size(vib) == 1 else 0.0}
        try:
            vals = {k: float(v) for k, v in vals.items()}
        except (TypeError, ValueError):
            bad = next(k for k, v in vals.items() if not isinstance(v, (int, float, np.number)))
            raise InputError(f"FuseTracker: sample {i}: {bad} must be a number, got "
                             f"{vals[bad]!r}") from None
        if not math.isfinite(vals["t"]) or not (math.isnan(self.t) or vals["t"] > self.t):
            raise InputError(f"FuseTracker: sample {i}: time {vals['t']} s is not after the "
                             f"previous {self.t} s")
        nv = np.size(vib)
        if self.trk is not None and nv != self.n_vib:
            raise InputError(f"FuseTracker: sample {i}: {nv} vibration sample(s), the tracker "
                             f"reads {self.n_vib} (comb axes)")
        for name, xs in (("vib", vib), ("others", others)):
            try:
                np.asarray(xs, dtype=np.float64)
            except (TypeError, ValueError):
                raise InputError(f"FuseTracker: sample {i}: {name} must be numbers, got "
                                 f"{xs!r}") from None
        if self.trk is None and np.size(others):
            raise InputError(f"FuseTracker: sample {i}: others given but no tracker (no stop "
                             "detector reads them)")
        if self.trk is not None and np.size(others) != self.n_others:
            raise InputError(f"FuseTracker: sample {i}: {np.size(others)} sample(s) in others, "
                             f"the stop detector reads {self.n_others} more axes")
        return vals

    def update(self, t: float, accel: float, vib=math.nan, gps_speed: float = math.nan,
               gps_sats: float = math.nan, others=()) -> list[tuple[int, Estimate]]:
        """One IMU sample at ``t`` s: ``accel`` the raw longitudinal accelerometer (m/s^2),
        ``vib`` the tracked axis (one per comb axis), ``gps_speed`` / ``gps_sats`` where a fix
        arrived with this sample (NaN else; a negative speed is no fix), ``others`` the further
        axes of the stop detector. Returns the estimates that became final as ``(k, Estimate)``
        pairs (k: the sample's index from 0, oldest first; as
        :class:`vibrospeed.estimators.grid.LaggedTracker`): ``speed``, ``speed_std``,
        ``omega`` / ``omega_std`` (speed over the radius so far where it is known),
        ``has_signal`` (the tracker claims a line), ``standstill`` (fuse's stop, source 3),
        extras ``t``, ``source``, ``radius``, ``radius_std``, ``offset``, ``harmonic``,
        ``omega_vib``, ``standstill_vib``."""
        v = self._check(t, accel, vib, gps_speed, gps_sats, others)
        t, a, g, s = v["t"], v["accel"], v["gps_speed"], v["gps_sats"]
        g = math.nan if g < 0 else g
        i = self.n
        if self.trk is None:
            pairs = [(i, None)]
            seen = False
        else:
            x = vib if self.n_vib > 1 else float(np.ravel(vib)[0])
            seen = math.isfinite(float(np.ravel(vib)[0]))
            pairs = self.trk.update(x, others) if self.lagged else \
                [(i, self.trk.update(x, others))]
        self.raw.append((t, a, g, s, seen))
        self.n, self.t = i + 1, t
        for k, est in pairs:
            self._process(k, est)
        return self._drain()

    def _process(self, k: int, est: Estimate | None) -> None:
        """Sample ``k`` (the oldest not processed) with its tracker estimate (None: no
        tracker): its line and stop evidence, its block's sums; its block closes here at a
        fusion sample's end."""
        t, a, g, s, seen = self.raw.popleft()
        if k != self.m:  # the trackers emit each sample once, in order
            raise RuntimeError(f"FuseTracker: the tracker gave sample {k}, expected {self.m}")
        ends = (k + 1) % self.block == 0 or math.isfinite(g)
        c = self.config
        if est is not None:
            om = est.omega
            claim = est.has_signal > 0.5
            still = est.standstill > 0.5 and not claim
            line = claim if c.vib_use == "line" else (om > 0 and not still)
            spread = est.omega_std
            if c.vib_spread == "mode" and claim:
                spread = float(est.extras["omega_mode_std"])
            soft = False
            if c.vib_soft < 1.0 and c.vib_use == "line":
                p_null = float(est.extras["p_null"])
                p_line = 1.0 - (1.0 if math.isnan(p_null) else p_null)
                soft = not line and not still and p_line >= c.vib_soft and om > 0
                if soft:
                    spread = float(est.extras["omega_mode_std"])
                line = line or soft
            line, still, soft = line and seen, still and seen, soft and seen
            svib = est.standstill
        else:
            om = spread = svib = math.nan
            claim = line = still = soft = False
        if math.isfinite(a):
            self.cs += a
            self.cn += 1
        self.still_all = self.still_all and still
        self.samples.append((k, t, om, float(claim), svib))
        self.m, self.tm = k + 1, t
        # what closes a block here, or at finish() if this is the log's last sample
        self._last = (s, om, spread, line, soft, est if self.post else None)
        if ends:
            self._close(t, g, *self._last)

    def _close(self, t, g, s, om, spread, line, soft, est) -> None:
        """The open block ends at the last sample: its fusion sample joins the queue (the
        tracker's posterior there as the batch keeps it, float32)."""
        post = None
        if est is not None:
            post = np.asarray(est.extras["posterior"], dtype=np.float32).astype(np.float64)
        cnt = self.cn - self.cn0
        am = self.sign * ((self.cs - self.cs0) / max(cnt, 1) if cnt > 0 else math.nan)
        smp = Sample(t, am, g, s, om, spread, line, self.still_all, soft, post)
        fix = g if math.isfinite(g) and not s < self.config.min_sats else math.nan
        self.blocks.append(_Block(self.m - 1, smp, fix))
        if self.band is not None:
            self.band.add(t, am, fix)
        if self.state is None and math.isfinite(fix):
            self.state = self._init(fix)
        self.cs0, self.cn0, self.still_all = self.cs, self.cn, True

    def finish(self) -> list[tuple[int, Estimate]]:
        """The log ended: the last block closes at the last sample, the rest becomes final."""
        if self.finished:
            return []
        if self.n < 2:
            raise InputError(f"FuseTracker: fewer than 2 samples ({self.n})")
        if self.lagged:  # the tracker's last estimates
            for k, est in self.trk.finish():
                self._process(k, est)
        if self.samples and (not self.blocks or self.blocks[-1].end != self.m - 1):
            self._close(self.tm, math.nan, *self._last)  # the open block ends here
        self.finished = True
        if self.band is not None:
            self.band.finish()
        if self.state is None:
            self.state = self._init(0.0)
        return self._drain()

    def _drain(self) -> list[tuple[int, Estimate]]:
        out: list[tuple[int, Estimate]] = []
        while self.blocks and self.state is not None:
            b = self.blocks[0]
            band = None
            if self.band is not None:
                last = self.finished and len(self.blocks) == 1
                if not last and not self.finished and b.end == self.m - 1:
                    break  # it may be the log's last (its band: all pairs)
                band = self.band.density(b.sample.t, self.tm, last)
                if band is None:
                    break
            self.state, est = step(self.config, self.state, b.sample,
                                   grid=self.grid if self.post else None, band_psd=band)
            self.blocks.popleft()
            out.extend(self._emit(b, est))
        return out

    def _emit(self, b: _Block, est: Estimate) -> list[tuple[int, Estimate]]:
        """The samples of block ``b``: linear between the previous fusion sample and this
        one (``np.interp`` on the two, the batch's numbers), the block's source; the first
        block's samples take its values (``np.interp`` left of its first point)."""
        t1 = b.sample.t
        x = est.extras
        now = (est.speed, est.speed_std, x["radius"], x["radius_std"], x["offset"])
        tp, before = self.prev if self.prev is not None else (t1, now)
        self.prev = (t1, now)
        rows = []
        while self.samples and self.samples[0][0] <= b.end:
            rows.append(self.samples.popleft())
        ts = np.array([r[1] for r in rows])
        if tp == t1:
            cols = [np.full(ts.size, q) for q in now]
        else:
            cols = [np.interp(ts, (tp, t1), (p, q)) for p, q in zip(before, now, strict=True)]
        src = int(x["source"])
        stop = float(src == SRC_STANDSTILL)
        rel = self.config.octave_rel
        res = []
        for k, (i, t, om, claim, svib) in enumerate(rows):
            sp, ss, r, rs, off = (float(c[k]) for c in cols)
            known = rs < rel * r
            res.append((i, Estimate(
                omega=sp / r if known else math.nan, omega_std=ss / r if known else math.nan,
                speed=sp, speed_std=ss, has_signal=claim, standstill=stop,
                extras={"t": t, "source": src, "radius": r, "radius_std": rs,
                        "offset": off, "harmonic": x["harmonic"], "omega_vib": om,
                        "standstill_vib": svib})))
        return res
