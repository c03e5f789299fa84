"""Parameters of the fusion filter (:mod:`vibrospeed.estimators.fuse`): the ``source`` codes,
the octave hypotheses, the grid tracker's settings under fuse, the state indices and the
:class:`Config` (GPS receiver fields shared with ``gps-riss``, process and measurement noises,
gates), validated on construction; :meth:`Config._arrays` builds the continuous system matrix
and the parameter vector the compiled core reads, so both have one definition."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.estimators.gps_riss.config import GpsFields
from vibrospeed.models.gps_riss import receiver_matrices
from vibrospeed.presets import STRICT_COMB

#: ``source`` codes (the CSV column holds the number)
SOURCES = {0: "inertial", 1: "gps", 2: "vibration", 3: "standstill"}
SRC_INERTIAL, SRC_GPS, SRC_VIBRATION, SRC_STANDSTILL = 0, 1, 2, 3

#: octave hypotheses for the tracker's line: the wheel frequency is k * omega
HARMONIC_FACTORS = (1.0, 0.5, 2.0)

#: the grid tracker's settings under fuse (``-p`` overrides them): the strict comb of the grid's
#: ``lock`` preset (:data:`vibrospeed.presets.STRICT_COMB`), the comb scored at SNR 2, a line
#: claimed at probability 0.5, the likelihood tempered to 0.05 per 10 ms (with the grid's 0.2
#: the online tunnels' share within 3 % where a line is visible fell 72.7 -> 59.4 %). The
#: grid's own defaults (SNR 1, claims at 0.9) place
#: omega better on weak combs, but the radius is learned from the lines it offers: with them
#: the 30 simulated tunnels learned worse radii (90th percentile error 0.5 -> 3.1 % offline,
#: 6.6 -> 15.7 % online) and the Hungary drives' offline RMSE with every line used rose 5.5 ->
#: 9.8 m/s (benchmarks/fuse/RESULTS.md, "Earlier runs").
TRACKER_DEFAULTS = {name: float(value) for name, value in STRICT_COMB.items()}

#: s, the causal grid tracker's lag behind an acceleration that ``estimate(online=True)`` gives
#: its lines (``Config.vib_lag``): it follows a hard braking a second or two late
CAUSAL_VIB_LAG = 2.0

#: m/s^2, ``Config.vib_amax`` of ``estimate(online=True)``: beyond it the causal tracker's line
#: trails the speed by 5-17 % (1-2 s at 2-2.5 m/s^2) or has jumped to another octave while its
#: mode stays narrow, and the accelerometer carries the speed better (benchmarks/fuse/RESULTS.md)
CAUSAL_VIB_AMAX = 1.5

#: ``Config.vib_soft`` of ``estimate(online=True)``: the causal tracker's line probability from
#: which its unclaimed mode is offered (to the re-lock, and taken directly where it continues
#: the line in use, ``vib_soft_hold``). Where it claims no line in the simulated tunnels while
#: a line is visible, its line probability is 0.1-0.5 (its "no line" state saturates near 0.88)
#: and its mode is the wheel's on 63 % of the samples at 0.1-0.2, 74 % at 0.2-0.3, 84 % at
#: 0.3-0.5. With those continuations taken, offered from 0.25 rather than 0.3 the online share
#: within 3 % where a line is visible rose 81.6 -> 82.1 %, from 0.1 to 83.8 %, but on the
#: Hungary phone drives (GPS withheld) below 0.25 the online share within 3 % fell 16.1 ->
#: 14.6-14.9 % and the tunnels' RMSE rose (benchmarks/fuse/RESULTS.md)
CAUSAL_VIB_SOFT = 0.25

#: ``Config.vib_measure`` of ``estimate(online=True)``: the causal tracker's posterior times the
#: prediction (item 3), with the decisive gate at :data:`CAUSAL_VIB_SEP`. On the simulated
#: tunnels online: line-visible time within 3 % 81.8 -> 82.8 %, tunnel RMSE 4.99 -> 4.94 m/s,
#: seeds at most gps-riss 24 -> 25 (benchmarks/fuse/RESULTS.md)
CAUSAL_VIB_MEASURE = "posterior"

#: ``Config.vib_sep`` of ``estimate(online=True)`` with the posterior measurement: the product
#: with the prediction reads the posterior's line nearest the prediction, so a wider band is
#: decisive (line-visible within 3 % online: 0.35 / 0.45 / 0.55 / 0.65: 82.0 / 82.6 / 82.8 /
#: 82.7 %); with the tracker's mode 0.55 did not help (81.9 %), and 0.75 (measured with
#: ``vib_soft`` 0.1) read lines at the wrong octave after hard brakings, where the filter's
#: speed had drifted far (75.0 %; benchmarks/fuse/RESULTS.md)
CAUSAL_VIB_SEP = 0.55

# state indices: speed, acceleration, accelerometer offset, radius, then the receiver chain
# from IG on (its extra lag last)
IV, IA, IB, IR, IG = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class Config(GpsFields):
    """Fusion parameters (SI units).

    Parameters
    ----------
    gps_a, gps_b, gps_delay, gps_pade, min_sats, gps_lag_std, q_gps_lag : the GPS receiver
        lag model (GPS/RISS paper eq. 3-4), the satellite gate and the prior and random walk of
        the receiver's extra lag (a state), shared with ``gps-riss``
        (:class:`vibrospeed.estimators.gps_riss.GpsFields`).
    q_speed, q_accel, q_offset, q_gps, q_radius : process noise intensities per second of v
        ((m/s)^2/s), a (jerk, (m/s^2)^2/s), b ((m/s^2)^2/s), the receiver states and r (m^2/s).
        The offset's walk (0.05 m/s^2 per sqrt s) is half gps-riss's: slower, the offset
        learned under GPS holds longer through an outage (on the simulated family the
        tunnel RMSE online 5.06 -> 4.08 m/s, offline 1.23 -> 1.16; at 1e-3 a hard braking
        left the online speed an octave off for 100 s; benchmarks/fuse/RESULTS.md).
    acc_psd : accelerometer white-noise density ((m/s^2)^2 s = (m/s^2)^2/Hz); a fusion sample
        averaging ``dt`` s has variance ``acc_psd / dt``. The default (0.32 m/s^2/sqrt(Hz)) is
        far above a MEMS sensor's own noise: it stands for the body motion, the wheel vibration
        and the lateral acceleration a slightly yawed mount mixes into the longitudinal axis
        (on the simulated family this weighting was best, benchmarks/fuse).
    r_gps : GPS speed variance per fix ((m/s)^2).  r_gps_sq : growth of that variance with the
        unexplained innovation squared (module notes, item 2; in (0, 1) bounds the jump).
    e_max : clip of the GPS error E (m/s; the paper clips at 5). The default 1000 m/s does not
        clip in practice, so the jump bound of item 2 holds: with a clip, a fix far from a
        speed that drifted in an outage is weighted as if E were ``e_max`` and moves the speed
        by more than its band.
    gps_persist : how long (s) the fixes may disagree with the filter's speed beyond the
        innovation's spread, on the same side at every valid fix (and for at least
        ``core.PERSIST_FIXES`` of them), before the disagreement is taken as the filter's (its
        speed drifted on the accelerometer), not the receiver's (module notes, item 2).
        Longer than a receiver jump (0.4-1.2 s in :func:`vibrospeed.sim.gps.outage_gps`, the
        paper's section VI-c); inf: never.
    vib_rel : relative floor on the wheel frequency's spread.  vib_corr : correlation time (s)
        of the tracker's errors.  vib_gate, vib_penalty : acceptance gate and octave penalty on
        the normalised innovation squared (item 3).
    r_still, r_still_acc : variances of the zero-speed and zero-acceleration pseudo-measurements.
    still_gate, still_speed : the integrated speed must be consistent with zero (item 4); the
        default gate (the 98 % chi-square quantile, 2.326^2) keeps the step a stop makes inside
        the 98 % band.
    gps_still, gps_hold : a valid fix within ``gps_hold`` s above ``gps_still`` m/s vetoes a stop.
    source_hold : s an accepted fix keeps ``source`` at gps.
    p0_speed, p0_accel, p0_offset : initial variances.  radius0, radius_std0 : radius prior
        (m; overridden by ``radius_from`` / a given wheel radius in :func:`estimate`); the
        octave changes of r stay within ``radius0 +- 3 radius_std0`` (item 3), so a vehicle
        class's prior (car: 0.32 +- 0.027 m) keeps r at the wheel's where the tracker follows
        a harmonic.
    octave_tau : s, time constant of the octave average (item 3).
    vib_min_speed : m/s; no wheel-frequency update where the speed is surely below it (item 3).
    radius_min, radius_max : m, the physical range of the effective radius (item 3).
    octave_rel : relative radius std below which the octave average and the re-lock act.
    vib_relock : s of a consistent line (and of no GPS) before the re-lock (item 3).
    learn_hold : s after an accepted fix in which a line may teach the radius and decides the
        octave without ``vib_sep`` (item 3).
    acq_time, acq_rel : s and relative tolerance of the consistency runs (first radius,
        re-lock; item 3).  acq_change : relative change of the line's speed that lets a
        re-lock outside the band happen (item 3).
    vib_sep : decisive gate: 3 sigma of the speed and the line within ``vib_sep r k omega``
        (item 3).
    still_relock : s of stop evidence refused by the integrated speed, without GPS, before the
        stop is taken anyway (item 4).
    vib_lag : s, how far the tracker's line may trail the speed (a causal tracker follows an
        acceleration late): a line read while the acceleration is ``a`` carries an extra
        speed variance ``(vib_lag a)^2`` (item 3). 0 (default) for the smoothed
        tracker; :func:`estimate` with ``online`` and no ``vib_lag`` given uses
        :data:`CAUSAL_VIB_LAG`.
    vib_amax : m/s^2; no wheel-frequency update (direct or re-lock) where the acceleration
        (the larger of the filter's and the accelerometer's, as for ``vib_lag``) exceeds it: a
        causal tracker's line lags a hard acceleration or braking by more than its spread says,
        or jumps to another octave, and the ``(vib_lag a)^2`` that admits the lag would also
        admit the octave. ``inf`` (default): no limit; :func:`estimate` with ``online`` and no
        ``vib_amax`` given uses :data:`CAUSAL_VIB_AMAX`.
    vib_soft : line probability ``1 - p_null`` of the tracker from which :func:`estimate`
        offers a line the tracker does not claim (its mode, with the spread within the mode)
        to the re-lock's band only (item 3): away from GPS, with r known, a re-lock run of
        such lines (``vib_relock`` s, each moving with the speed) widens the filter's band by
        its gap, ``P_vv += d^2``, but the line is not taken, and it teaches neither r nor the
        first radius; a claimed line at that gap then lies inside the band and re-locks.
        ``1`` (default): none; :func:`estimate` with ``online`` and no ``vib_soft`` given uses
        :data:`CAUSAL_VIB_SOFT`. Such a line is also taken directly where it continues the last
        line used (``vib_soft_hold``, ``vib_soft_gate``).
    vib_soft_hold, vib_soft_gate : an unclaimed line (the ``soft`` input) is taken directly,
        away from GPS with r known, where it continues the last line used at most
        ``vib_soft_hold`` s before the previous fusion sample (the same k, its omega within half
        an octave of that line's) and its normalised innovation is at most ``vib_soft_gate``
        (4: two sigma of the prediction and the mode's own spread, where a claimed line has
        ``vib_gate``); its octave is the one in use, decided when a line was first taken
        (item 3). The chain of lines used then carries the speed through the tracker's gaps in
        its claims. ``vib_soft_gate = 0``: no unclaimed line is taken (the re-lock's band
        only). The hold bounds the gap: with 1.5 s a causal tracker's mode stuck through a
        braking was taken on the simulated tunnels (benchmarks/fuse/RESULTS.md). With
        ``vib_measure="posterior"`` (online default) an unclaimed line is read like a claimed
        one and only the continuation acts: it needs no decisive gate (the gate's value is
        not used; 0 still switches the continuation off).
    vib_spread : the line's spread ``s`` in :func:`estimate` where the tracker claims a line:
        ``"posterior"`` (default; its whole posterior's ``omega_std``: all its modes and its
        "no line" mass) or ``"mode"`` (the grid tracker's ``omega_mode_std``, the spread
        within the mode it reports). :func:`estimate` with ``online`` and no ``vib_spread``
        given uses ``"mode"``: the causal tracker's whole posterior is wide on its right lines
        at low speed (other lines keep mass there) and kept them out of the tunnels, while the
        smoothed tracker's is narrow on them and its mode's spread taught an engine order's
        radius harder (benchmarks/fuse/RESULTS.md).
    vib_measure : how a line is read (item 3): ``"mode"`` (default; the tracker's omega and
        the spread ``vib_spread``) or ``"posterior"`` (with r known, the tracker's grid
        posterior times the prediction's Gaussian on the line, read as a likelihood and weighed
        by the probability that the line is there; the ``posterior`` input and the tracker's
        grid). :func:`estimate` with ``online``, no ``vib_measure`` given and ``vib_use="line"``
        uses :data:`CAUSAL_VIB_MEASURE` (and ``vib_sep`` :data:`CAUSAL_VIB_SEP`), unless the
        given vibration track holds no posterior.
    vib_post_width : the product's window, in standard deviations of the prediction (item 3).
    vib_post_min : the least probability ``beta`` that the posterior's line is there for the
        line to be used (item 3; online on the simulated tunnels 0.5 -> 0.2 took the
        line-visible share within 3 % 82.4 -> 82.8 %, benchmarks/fuse/RESULTS.md).
    vib_use : which tracker samples are offered to item 3 in :func:`estimate`: ``"line"``
        (where the tracker claims a line, ``has_signal``) or ``"all"`` (every positive omega,
        its posterior spread and the gate decide: for trackers whose null state dominates on a
        real line; those omegas are not claims, so no line continues one used before without
        the decisive gate, item 3).
    band_psd : the accelerometer density ((m/s^2)^2 s) the reported speed band assumes:
        ``"off"`` (the filter's own covariance, ``acc_psd``), a number, or ``"learned"``
        (:func:`vibrospeed.estimators.fuse.band.learn_acc_psd` from the drive's own fixes; in
        :func:`estimate` offline the whole drive's, online and in :func:`run` the fixes so
        far). The band is a second covariance propagated with the filter's gains (Joseph
        form, the accelerometer's variance ``max(band_psd, acc_psd) / dt``), so the speed
        stays the filter's to the bit and only ``speed_std`` widens; offline the band is the
        smoothed estimate's error covariance with the smoother's own gains
        (:func:`~vibrospeed.estimators.fuse.smoother.smooth_band`). Default ``"learned"``:
        GPS withheld in 60 s windows, the GoPro kart's band held the truth on 62 % offline
        before, now 100 %; the Hungary drives 95.9 %, simulated tunnels 99.9 %
        (benchmarks/fuse/RESULTS.md).
    nonneg : project negative speeds onto 0 (item 5).
    fuse_rate : Hz of the fusion samples in :func:`estimate` (plus one per GPS fix).
    """

    q_speed: float = 1e-4
    q_accel: float = 10.0
    q_offset: float = 2.5e-3
    q_gps: float = 1e-6
    q_radius: float = 1e-9
    acc_psd: float = 0.1
    r_gps: float = 0.01
    r_gps_sq: float = 0.5
    e_max: float = 1000.0
    gps_persist: float = 1.5
    vib_rel: float = 0.005
    vib_corr: float = 0.05
    vib_gate: float = 16.0
    vib_penalty: float = 9.0
    r_still: float = 1e-4
    r_still_acc: float = 1.0
    still_gate: float = 5.41
    still_speed: float = 0.5
    gps_still: float = 0.5
    gps_hold: float = 2.0
    source_hold: float = 1.5
    p0_speed: float = 100.0
    p0_accel: float = 1.0
    p0_offset: float = 1.0
    radius0: float = 0.3
    radius_std0: float = 0.15
    octave_tau: float = 10.0
    vib_use: str = "line"
    vib_min_speed: float = 1.0
    radius_min: float = 0.03
    radius_max: float = 1.0
    octave_rel: float = 0.05
    vib_relock: float = 1.0
    still_relock: float = 3.0
    learn_hold: float = 1.5
    acq_time: float = 0.5
    acq_rel: float = 0.03
    acq_change: float = 0.1
    vib_sep: float = 0.35
    vib_lag: float = 0.0
    vib_amax: float = math.inf
    vib_soft: float = 1.0
    vib_spread: str = "posterior"
    vib_soft_hold: float = 1.0
    vib_soft_gate: float = 4.0
    vib_measure: str = "mode"
    vib_post_width: float = 4.0
    vib_post_min: float = 0.2
    band_psd: str | float = "learned"
    nonneg: bool = True
    fuse_rate: float = 25.0

    def __post_init__(self) -> None:
        self._check_gps("fuse: ")
        # an infinite noise, variance, prior or gate made (nearly) every speed NaN; the other
        # limits (vib_amax, e_max, the holds) take inf as "none"
        for name in ("q_speed", "q_accel", "q_offset", "q_gps", "q_radius", "acc_psd", "r_gps",
                     "vib_rel", "vib_corr", "vib_gate", "vib_lag", "r_still", "r_still_acc",
                     "p0_speed", "p0_accel", "p0_offset", "radius0", "radius_std0"):
            if getattr(self, name) == math.inf:
                raise ParameterError(f"fuse: {name} must be finite, got {getattr(self, name)}")
        for name in ("acc_psd", "r_gps", "vib_rel", "vib_corr", "vib_gate", "r_still",
                     "r_still_acc", "still_gate", "p0_speed", "p0_accel", "p0_offset",
                     "radius0", "radius_std0", "fuse_rate", "octave_tau"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"fuse: {name} must be > 0, got {getattr(self, name)}")
        for name in ("q_speed", "q_accel", "q_offset", "q_gps", "q_radius", "e_max",
                     "vib_penalty", "still_speed", "gps_still", "gps_hold", "source_hold",
                     "vib_min_speed", "octave_rel", "vib_relock", "radius_min", "radius_max",
                     "still_relock", "learn_hold", "acq_time", "acq_rel", "acq_change",
                     "vib_sep", "vib_lag", "vib_amax", "vib_soft_hold", "vib_soft_gate",
                     "gps_persist"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"fuse: {name} must be >= 0, got {getattr(self, name)}")
        if not 0.0 < self.vib_soft <= 1.0:
            raise ParameterError(f"fuse: vib_soft must be in (0, 1], got {self.vib_soft}")
        if self.vib_spread not in ("mode", "posterior"):
            raise ParameterError(f"fuse: vib_spread must be mode or posterior, got "
                                 f"'{self.vib_spread}'")
        if self.vib_measure not in ("mode", "posterior"):
            raise ParameterError(f"fuse: vib_measure must be mode or posterior, got "
                                 f"'{self.vib_measure}'")
        if not (self.vib_post_width > 0 and 0.0 <= self.vib_post_min <= 1.0):
            raise ParameterError(f"fuse: vib_post_width must be > 0 and vib_post_min in [0, 1], "
                                 f"got {self.vib_post_width}, {self.vib_post_min}")
        if self.vib_use not in ("line", "all"):
            raise ParameterError(f"fuse: vib_use must be line or all, got '{self.vib_use}'")
        self.band_density()  # validates band_psd
        if not 0.0 < self.r_gps_sq < 1.0:
            raise ParameterError(f"fuse: r_gps_sq must be in (0, 1) (it bounds the speed's jump "
                                 f"on a GPS fix), got {self.r_gps_sq}")

    def band_density(self) -> str | float:
        """``band_psd`` read: ``"off"``, ``"learned"`` or the density as a float (> 0)."""
        b = self.band_psd
        if isinstance(b, str) and b.strip().lower() in ("off", "learned"):
            return b.strip().lower()
        try:
            q = float(b)
        except (TypeError, ValueError):
            q = math.nan
        if not (q > 0 and math.isfinite(q)) or isinstance(b, bool):
            raise ParameterError(f"fuse: band_psd must be off, learned or a density > 0 "
                                 f"((m/s^2)^2 s), got {b!r}")
        return q

    @property
    def n_states(self) -> int:
        """Length of the state vector: the receiver chain, then the receiver's extra lag."""
        return IG + self.lag.n_states + 1

    def _build_arrays(self):
        """``(Ac, qc, p)``: continuous system matrix, process noise intensities, scalars."""
        Ar, Br = receiver_matrices(self.lag)
        n = IG + Ar.shape[0] + 1  # the last state: the receiver's extra lag (constant)
        Ac = np.zeros((n, n))
        Ac[IV, IA] = 1.0
        Ac[IG:-1, IG:-1] = Ar
        Ac[IG:-1, IV] = Br
        qc = np.full(n, self.q_gps)
        qc[:IG] = (self.q_speed, self.q_accel, self.q_offset, self.q_radius)
        qc[-1] = self.q_gps_lag
        p = np.array([
            self.acc_psd, self.r_gps, self.r_gps_sq, self.e_max, self.min_sats, self.vib_rel,
            self.vib_corr, self.vib_gate, self.vib_penalty, self.r_still, self.r_still_acc,
            self.still_gate, self.still_speed, self.gps_still, self.gps_hold, self.source_hold,
            self.octave_tau, float(self.nonneg), self.vib_min_speed, self.octave_rel,
            self.vib_relock, self.radius_min, self.radius_max, self.still_relock,
            self.learn_hold, self.acq_time, self.acq_rel, self.acq_change, self.vib_sep,
            self.vib_lag, self.radius0, self.radius_std0, self.vib_amax,
            float(self.vib_use == "line"), self.vib_soft_hold, self.vib_soft_gate,
            float(self.vib_measure == "posterior"), self.vib_post_width, self.vib_post_min,
            self.gps_persist,
        ], dtype=np.float64)
        return Ac, qc, p
