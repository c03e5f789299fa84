# Over 500 lines: one filter (state model, measurement updates with their gates, compiled loop,
# RTS smoother) and its entry point, which wires the vibration tracker and the GPS into it.
"""One speed from every sensor a log has: longitudinal acceleration, GPS speed and the wheel
vibration's frequency, with the effective wheel radius learned on the way (``--method fuse``).

State ``X = [v, a, b, r, x3, x4, d...]``: speed (m/s), acceleration (m/s^2), accelerometer offset
b (m/s^2: road slope ``g sin theta``, mount tilt and bias), the effective wheel radius r (m, the
speed-to-wheel-frequency ratio ``v = r omega``), and the GPS receiver chain of the GPS/RISS model
(:mod:`vibrospeed.models.gps_riss`: reported speed x3, its derivative x4, Pade delay states).
Continuous time ``v' = a``, ``a' = w_a``, ``b' = w_b``, ``r' = w_r``,
``[x3, x4, d]' = Ar [x3, x4, d] + Br v`` (paper eq. 1-2); each step predicts with the exact
transition ``F = expm(A_c dt)`` and ``Q = diag(q) dt``.

Measurements of one fusion sample (all scalar, sequential Kalman updates, Joseph form):

1. accelerometer ``a_m = a + b + e``, ``var e = acc_psd / dt``: the mean of the raw samples over
   the ``dt`` since the previous fusion sample (white noise of density ``acc_psd``).
2. GPS speed ``g = x3 + e`` (GPS/RISS paper section VI): used only with ``sats >= min_sats``
   (a NaN count counts as valid); its variance grows with the part of the innovation the model
   does not explain, ``R = r_gps + r_gps_sq min(E^2, e_max^2)``, ``E^2 = max(nu^2 - S0, 0)``
   (paper eq. 13, 18; ``e_max`` large, see :class:`Config`). The change of v this update makes
   is then at most
   ``sqrt(P_vv) / (2 sqrt(c (1 - c)))``, c = ``r_gps_sq``, whatever the innovation (from
   ``S >= (1 - c) S0 + c nu^2 >= 2 sqrt(c (1 - c) S0) |nu|`` and ``|P_v3| <= sqrt(P_vv S0)``):
   one standard deviation for c = 1/2, so the speed does not jump out of its band when GPS
   returns after a tunnel.
3. wheel frequency: the harmonic tracker's omega with posterior spread ``s`` where it claims a
   line. The line may be the wheel's omega/2 or 2 omega (the tracker's octave errors), so the
   wheel frequency is ``k omega``, ``k in {1/2, 1, 2}``. Each hypothesis is the *linear*
   pseudo-measurement ``0 = v - r k omega + e`` (``H = [1, 0, 0, -k omega, 0...]``, exact in the
   state given the measured omega) with ``var e = (r k)^2 (s^2 + (vib_rel omega)^2)
   vib_corr / dt``: the tracker's spread plus a relative floor, inflated by the number of fusion
   samples per correlation time of the tracker's errors (its outputs are not independent from
   sample to sample). The hypothesis with the smallest normalised innovation squared
   ``nu^2 / S`` plus ``vib_penalty`` for k != 1 is used if that sum is below ``vib_gate`` and
   the gate is decisive: GPS holds the speed (a fix in the past ``learn_hold`` s), or
   ``3 sqrt(P_vv + (r k)^2 (s^2 + (vib_rel omega)^2)) <= vib_sep r k omega`` (the band and
   the line's own spread are narrow against the spacing of the octaves;
   after a long stretch on the accelerometer alone it is not, and a gate of 4 sigma would pass
   an idling engine's line or the wrong octave); else the sample has no direct vibration
   update (re-lock below). No line is used where the filter knows the vehicle to be
   slower than ``vib_min_speed`` (``v + 3 sqrt(P_vv) < vib_min_speed``): a line claimed at a
   standstill (an idling engine) would otherwise teach ``r = v / omega = 0``; nor a hypothesis
   whose radius cannot be physical for any speed within 3 sigma:
   ``(v + 3 sqrt(P_vv)) / (k omega) < radius_min`` or ``(v - 3 sqrt(P_vv)) / (k omega) >
   radius_max`` (an engine line while the vehicle starts to roll). Octaves are relative to a
   known radius: while r is not known within ``octave_rel`` only k = 1 is tried. So the speed
   prior (GPS, the accelerometer, the radius learned so far) decides an octave, not the
   tracker's guess. The radius is defined by the
   line the tracker reports most of the time: an exponential average (time constant
   ``octave_tau`` s of updates) of ``log2 k`` over the accepted updates beyond +-1/2 means
   that most recent updates used k = 2 (or 1/2), e.g. after a tracker that locked on the
   second harmonic at the start taught the radius; then, if r is known within
   ``octave_rel`` (relative std), ``r <- k r`` (its variance by k^2) and the average restarts at
   0. The speed is unchanged by this, only the octave of r; the average moves only where GPS
   holds the speed.

   The radius learns only from GPS and a line together. Away from GPS (no fix in the past
   ``learn_hold`` s) a wheel-frequency update carries the speed but leaves r and the offset b
   alone (they are "consider" states, Schmidt: their gains are set to 0 and the Joseph form
   keeps P exact for those gains), so a wrong line taken in an outage cannot corrupt the
   radius the next drive reuses, and a line that lags the speed while braking (a causal
   tracker's) cannot teach the offset the inertial stretches of the outage rest on.
   The first radius (r not yet known within ``octave_rel``) comes from a line whose ratio
   ``ln(v / omega)`` to the GPS-held speed has stayed within ``acq_rel`` of its running mean
   (time constant ``acq_time``) for ``acq_time`` s: a wheel line scales with the speed, an
   idling engine's line while the vehicle starts to roll does not, and a radius learned from
   it would gate out the wheel line for the rest of the drive.

   Re-lock (no GPS fix for ``vib_relock`` s, r known): where a claimed line is not taken
   directly, the gap ``d = r omega - v`` between the line's speed (k = 1, the octave that
   taught r) and the filter's is followed; if it has stayed within ``acq_rel r omega`` of its
   running mean for ``vib_relock`` s (the line moves as the accelerometer says the speed
   does) and either ``|d| <= 3 sqrt(P_vv)`` or the line's speed has changed by ``acq_change``
   of itself in that run, the filter, not the line, has drifted: ``P_vv`` is increased by
   ``d^2`` and the line is taken. A constant line far outside the band (an idling engine at a
   stop in a tunnel) is not taken until it moves with the speed.
4. standstill: where the vibration tracker reports a stop (no wheel line, broadband vibration and
   body motion at their floors: the ``standstill`` input), the last valid GPS fix in the past
   ``gps_hold`` s (if any) is below ``gps_still``, and the speed the accelerometer has
   integrated is consistent with zero (``v^2 / (P_vv + r_still) <= still_gate`` or
   ``|v| <= still_speed``), the pseudo-measurements ``v = 0`` and ``a = 0`` (variance
   ``r_still``, ``r_still_acc``) are applied: zero-velocity updates that also calibrate b.
   If the other evidence has said "stop" for ``still_relock`` s while only the integrated
   speed disagrees and no GPS fix came, the integrated speed is what drifted: ``P_vv`` is
   increased by ``v^2`` and the stop is taken (a step to 0, by design).

5. speed is a magnitude (GPS speed and a wheel frequency are): where the updates leave
   ``v < 0`` the state is projected onto ``v = 0`` (``x <- x - P[:, v] v / P_vv``, the
   equality-constrained estimate of Simon & Chia; P unchanged), unless ``nonneg`` is off.

The radius is observable where GPS and a line coincide (``v`` from GPS, ``omega`` from the
vibration: r is their ratio); through an outage its random walk ``q_radius`` keeps it nearly
constant and the vibration carries the speed. Without GPS the radius prior must come from an
earlier drive (:func:`radius_from_json`, the ``radius_from`` parameter) or be given.

``source`` per sample: what the speed rests on, :data:`SOURCES` codes: 3 standstill (a
zero-speed update here), 1 gps (an accepted fix in the past ``source_hold`` s), 2 vibration
(a wheel-frequency update here), 0 inertial (the accelerometer alone).

:func:`run` is the forward filter (online); :func:`smooth` the Rauch-Tung-Striebel smoother over
its stored predictions (offline). :func:`estimate` runs the vibration tracker first (offline: the
smoothed grid tracker; online: the causal one), reduces the recording to fusion samples at
``fuse_rate`` Hz plus one at every GPS fix, fuses, and interpolates back to the recording's
time line.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import config_from_params, parse_flag
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.gps_riss import GpsFields
from vibrospeed.models.gps_riss import receiver_matrices, transition
from vibrospeed.types import Estimate, Recording, Track

#: ``source`` codes (the CSV column holds the number)
SOURCES = {0: "inertial", 1: "gps", 2: "vibration", 3: "standstill"}
SRC_INERTIAL, SRC_GPS, SRC_VIBRATION, SRC_STANDSTILL = 0, 1, 2, 3

#: octave hypotheses for the tracker's line: the wheel frequency is k * omega
HARMONIC_FACTORS = (1.0, 0.5, 2.0)

#: the grid tracker's settings under fuse (``-p`` overrides them): the comb scored at SNR 2 and
#: a line claimed at probability 0.5. The grid's own defaults (SNR 1, claims at 0.9) place
#: omega better on weak combs, but the radius is learned from the lines it offers: with them
#: the 30 simulated tunnels learned worse radii (90th percentile error 0.5 -> 3.1 % offline,
#: 6.6 -> 15.7 % online) and the Hungary drives' offline RMSE with every line used rose 5.5 ->
#: 9.8 m/s (benchmarks/fuse/RESULTS.md, "Earlier runs").
TRACKER_DEFAULTS = {"comb_snr": 2.0, "claim_level": 0.5}

# state indices
IV, IA, IB, IR, IG = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class Config(GpsFields):
    """Fusion parameters (SI units).

    Parameters
    ----------
    gps_a, gps_b, gps_delay, gps_pade, min_sats : the GPS receiver lag model (GPS/RISS paper
        eq. 3-4) and the satellite gate, shared with ``gps-riss``
        (:class:`vibrospeed.estimators.gps_riss.GpsFields`).
    q_speed, q_accel, q_offset, q_gps, q_radius : process noise intensities per second of v
        ((m/s)^2/s), a (jerk, (m/s^2)^2/s), b ((m/s^2)^2/s), the receiver states and r (m^2/s).
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
        (m; overridden by ``radius_from`` / a given wheel radius in :func:`estimate`).
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
    vib_use : which tracker samples are offered to item 3 in :func:`estimate`: ``"line"``
        (where the tracker claims a line, ``has_signal``) or ``"all"`` (every positive omega,
        its posterior spread and the gate decide: for trackers whose null state dominates on a
        real line).
    nonneg : project negative speeds onto 0 (item 5).
    fuse_rate : Hz of the fusion samples in :func:`estimate` (plus one per GPS fix).
    """

    q_speed: float = 1e-4
    q_accel: float = 10.0
    q_offset: float = 5e-3
    q_gps: float = 1e-6
    q_radius: float = 1e-9
    acc_psd: float = 0.1
    r_gps: float = 0.01
    r_gps_sq: float = 0.5
    e_max: float = 1000.0
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
    nonneg: bool = True
    fuse_rate: float = 25.0

    def __post_init__(self) -> None:
        self._check_gps("fuse: ")
        for name in ("acc_psd", "r_gps", "vib_rel", "vib_corr", "vib_gate", "r_still",
                     "r_still_acc", "still_gate", "p0_speed", "p0_accel", "p0_offset",
                     "radius0", "radius_std0", "fuse_rate", "octave_tau"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"fuse: {name} must be > 0, got {getattr(self, name)}")
        for name in ("q_speed", "q_accel", "q_offset", "q_gps", "q_radius", "e_max",
                     "vib_penalty", "still_speed", "gps_still", "gps_hold", "source_hold",
                     "vib_min_speed", "octave_rel", "vib_relock", "radius_min", "radius_max",
                     "still_relock", "learn_hold", "acq_time", "acq_rel", "acq_change",
                     "vib_sep"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"fuse: {name} must be >= 0, got {getattr(self, name)}")
        if self.vib_use not in ("line", "all"):
            raise ParameterError(f"fuse: vib_use must be line or all, got '{self.vib_use}'")
        if not 0.0 < self.r_gps_sq < 1.0:
            raise ParameterError(f"fuse: r_gps_sq must be in (0, 1) (it bounds the speed's jump "
                                 f"on a GPS fix), got {self.r_gps_sq}")

    @property
    def n_states(self) -> int:
        """Length of the state vector."""
        return IG + self.lag.n_states

    def _arrays(self):
        """``(Ac, qc, p)``: continuous system matrix, process noise intensities, scalars."""
        Ar, Br = receiver_matrices(self.lag)
        n = IG + Ar.shape[0]
        Ac = np.zeros((n, n))
        Ac[IV, IA] = 1.0
        Ac[IG:, IG:] = Ar
        Ac[IG:, IV] = Br
        qc = np.full(n, self.q_gps)
        qc[:IG] = (self.q_speed, self.q_accel, self.q_offset, self.q_radius)
        p = np.array([
            self.acc_psd, self.r_gps, self.r_gps_sq, self.e_max, self.min_sats, self.vib_rel,
            self.vib_corr, self.vib_gate, self.vib_penalty, self.r_still, self.r_still_acc,
            self.still_gate, self.still_speed, self.gps_still, self.gps_hold, self.source_hold,
            self.octave_tau, float(self.nonneg), self.vib_min_speed, self.octave_rel,
            self.vib_relock, self.radius_min, self.radius_max, self.still_relock,
            self.learn_hold, self.acq_time, self.acq_rel, self.acq_change, self.vib_sep,
        ], dtype=np.float64)
        return Ac, qc, p


class State(NamedTuple):
    """Filter state after the last sample.

    x, P : (n,), (n, n) mean and covariance of ``[v, a, b, r, x3, x4, d...]``.
    t : time of the last sample (NaN before the first).  t_gps : time of the last accepted
    fix (-inf: none).  t_fix, v_fix : time and value of the last valid fix (for the standstill
    veto).  octave : average of log2 k over recent wheel-frequency updates (module notes, 3).
    t_run, d_run, u_run : start, mean gap ``r omega - v`` and line speed at the start of the
    current re-lock run (NaN: none; module notes, 3).  t_still : start of the current run of
    refused stop evidence (NaN: none).  t_acq, z_acq : start and mean log ratio
    ``ln(v / omega)`` of the current run of consistent lines while the radius is not known
    yet (NaN: none; module notes, 3).
    """

    x: np.ndarray
    P: np.ndarray
    t: float
    t_gps: float
    t_fix: float
    v_fix: float
    octave: float = 0.0
    t_run: float = math.nan
    t_still: float = math.nan
    t_acq: float = math.nan
    z_acq: float = math.nan
    d_run: float = math.nan
    u_run: float = math.nan


class Sample(NamedTuple):
    """One fusion sample, or (n,) arrays of them (:func:`step`, :func:`run`): time (s), mean
    longitudinal acceleration since the previous sample (m/s^2, NaN: none), GPS speed (m/s,
    NaN: no fix now), satellites (NaN: unknown), the tracker's omega and spread (rad/s),
    whether it claims a line, whether the vibration reports a stop."""

    t: float
    accel: float = math.nan
    gps_speed: float = math.nan
    gps_sats: float = math.nan
    omega: float = math.nan
    omega_std: float = math.nan
    line: bool = False
    still: bool = False


#: the per-sample values of :func:`step`'s Estimate besides ``speed`` / ``speed_std``: radius
#: and its std (m), accelerometer offset (m/s^2), source (:data:`SOURCES`), the harmonic k of
#: the wheel-frequency update (NaN: none)
EXTRAS = ("radius", "radius_std", "offset", "source", "harmonic")


class Output(NamedTuple):
    """:func:`run` output, (n,) arrays; ``xp, Pp, xf, Pf, dt`` kept for :func:`smooth`."""

    speed: np.ndarray
    speed_std: np.ndarray
    radius: np.ndarray
    radius_std: np.ndarray
    offset: np.ndarray
    source: np.ndarray
    harmonic: np.ndarray
    xp: np.ndarray
    Pp: np.ndarray
    xf: np.ndarray
    Pf: np.ndarray
    dt: np.ndarray


class Result(NamedTuple):
    """:func:`run`'s result: the state after the last sample and the per-sample output; the
    output's columns read as attributes too (``result.speed``); unpacks as ``final, output``."""

    final: State
    output: Output

    def __getattr__(self, name):
        return getattr(self.output, name)


def init(config: Config, v0: float = 0.0, *, radius: float | None = None,
         radius_std: float | None = None, p0_speed: float | None = None) -> State:
    """Start state: speed ``v0`` (variance ``p0_speed``, default the config's), the receiver in
    steady state at ``v0``, radius prior ``radius +- radius_std`` (default the config's)."""
    lag = config.lag
    n = config.n_states
    x = np.zeros(n)
    x[IV] = v0
    r = config.radius0 if radius is None else float(radius)
    rs = config.radius_std0 if radius_std is None else float(radius_std)
    if not (r > 0 and rs > 0 and math.isfinite(r) and math.isfinite(rs)):
        raise ParameterError(f"fuse: radius prior must be > 0 with std > 0, got {r} +- {rs}")
    x[IR] = r
    Ar, Br = receiver_matrices(lag)
    x[IG:] = -np.linalg.solve(Ar, Br) * v0
    P = np.zeros((n, n))
    pv = config.p0_speed if p0_speed is None else float(p0_speed)
    P[IV, IV] = pv
    P[IA, IA] = config.p0_accel
    P[IB, IB] = config.p0_offset
    P[IR, IR] = rs * rs
    gain = -np.linalg.solve(Ar, Br)  # receiver states follow v at steady state
    P[IG:, IV] = gain * pv
    P[IV, IG:] = gain * pv
    P[IG:, IG:] = np.outer(gain, gain) * pv + np.eye(n - IG) * 1e-6
    return State(x, P, math.nan, -math.inf, -math.inf, math.nan)


# -- compiled core ------------------------------------------------------------------------------

@njit(cache=True)
def _update_row(x, P, h, z, r, keep=-1, keep2=-1):
    """Scalar Kalman update with row ``h``, Joseph form; returns the innovation. ``keep``,
    ``keep2 >= 0``: those states are "consider" states (Schmidt): their gain is 0, so the
    update leaves their means and variances unchanged; the Joseph form keeps P the exact
    covariance for that gain."""
    n = x.size
    Ph = P @ h
    s = h @ Ph + r
    k = Ph / s
    if keep >= 0:
        k[keep] = 0.0
    if keep2 >= 0:
        k[keep2] = 0.0
    nu = z - h @ x
    for i in range(n):
        x[i] += k[i] * nu
    IKH = np.eye(n) - np.outer(k, h)
    Pn = IKH @ P @ IKH.T + np.outer(k, k) * r
    for i in range(n):
        for j in range(n):
            P[i, j] = 0.5 * (Pn[i, j] + Pn[j, i])
    return nu


@njit(cache=True)
def _step_core(Ac, qc, p, x, P, sc, Fc, t, am, g, sats, om, om_std, line, still, out, xp, Pp):
    """One fusion sample in place. ``sc = [t_prev, t_gps, t_fix, v_fix, dt of Fc, octave,
    t_run, t_still, t_acq, z_acq, d_run, u_run]``;
    ``out`` (7,) receives speed, std, radius, radius std, offset, source, k; ``xp, Pp`` the
    prediction (for the smoother). Returns dt."""
    n = x.size
    dt = 0.0 if math.isnan(sc[0]) else t - sc[0]
    sc[0] = t
    if dt > 0.0:
        if dt != sc[4]:
            Fc[:, :] = transition(Ac, dt)
            sc[4] = dt
        xn = Fc @ x
        Pn = Fc @ P @ Fc.T
        for i in range(n):
            x[i] = xn[i]
            Pn[i, i] += qc[i] * dt
        for i in range(n):
            for j in range(n):
                P[i, j] = 0.5 * (Pn[i, j] + Pn[j, i])
    for i in range(n):
        xp[i] = x[i]
        for j in range(n):
            Pp[i, j] = P[i, j]
    h = np.zeros(n)
    # 1. accelerometer (mean over the interval)
    if dt > 0.0 and not math.isnan(am):
        h[IA] = 1.0
        h[IB] = 1.0
        _update_row(x, P, h, am, p[0] / dt)
        h[IA] = 0.0
        h[IB] = 0.0
    # 2. GPS, gated by satellites, weighted by the unexplained innovation
    if not math.isnan(g):
        valid = math.isnan(sats) or sats >= p[4]
        if valid:
            sc[2] = t
            sc[3] = g
            h[IG] = 1.0
            nu = g - x[IG]
            s0 = P[IG, IG] + p[1]
            e2 = min(max(nu * nu - s0, 0.0), p[3] * p[3])
            _update_row(x, P, h, g, p[1] + p[2] * e2)
            h[IG] = 0.0
            sc[1] = t
    # 3. wheel frequency, octave chosen by the speed prior
    kk = math.nan
    moving = x[IV] + 3.0 * math.sqrt(max(P[IV, IV], 0.0)) >= p[18]
    fresh = t - sc[1] <= p[24]  # GPS pins the speed: the radius may learn
    known = math.sqrt(max(P[IR, IR], 0.0)) < p[19] * abs(x[IR])
    if not (fresh and x[IV] >= p[18]):
        sc[8] = math.nan  # an acquisition run needs the GPS speed
    if (line and moving and dt > 0.0 and om > 0.0 and not math.isnan(om)
            and not math.isnan(om_std)):
        ready = known
        if not known and fresh and x[IV] >= p[18]:
            # acquisition: the ratio v / omega must hold for acq_time s (a wheel line scales
            # with the speed; an idling engine's or a resonance's does not)
            z = math.log(x[IV] / om)
            if math.isnan(sc[8]) or abs(z - sc[9]) > p[26]:
                sc[8] = t
                sc[9] = z
            else:
                sc[9] += (z - sc[9]) * min(1.0, dt / p[25])
            ready = t - sc[8] >= p[25]
        best = math.inf
        r_hat = max(x[IR], 1e-3)
        var_om = om_std * om_std + (p[5] * om) ** 2
        infl = p[6] / dt
        sv3 = 3.0 * math.sqrt(max(P[IV, IV], 0.0))
        for j in range((3 if known else 1) if ready else 0):
            k = 1.0 if j == 0 else (0.5 if j == 1 else 2.0)
            if (x[IV] + sv3) < p[21] * k * om or (x[IV] - sv3) > p[22] * k * om:
                continue  # no physical radius explains this line at this speed
            hr = -k * om
            nu = -(x[IV] + hr * x[IR])
            s = (P[IV, IV] + 2.0 * hr * P[IV, IR] + hr * hr * P[IR, IR]
                 + (r_hat * k) ** 2 * var_om * infl)
            cost = nu * nu / s + (0.0 if j == 0 else p[8])
            if cost < best:
                best = cost
                kk = k
        # direct use needs a decisive gate: the band narrow against the octaves' spacing
        decisive = not math.isnan(kk) and (fresh or 3.0 * math.sqrt(
            P[IV, IV] + (r_hat * kk) ** 2 * var_om) <= p[28] * r_hat * kk * om)
        if ready and known and not (best <= p[7] and decisive):
            # re-lock run on the line at k = 1 (the octave that taught r): the gap
            # d = r omega - v between the line's speed and the filter's must hold for
            # vib_relock s (no GPS in that time), and the line must have moved with the speed
            # (by acq_change) or lie inside the 3-sigma band (a constant line far outside it
            # may be an idling engine at a stop)
            best = math.inf
            kk = math.nan
            u = x[IR] * om
            d = u - x[IV]
            if math.isnan(sc[6]) or t - sc[1] <= p[20] or abs(d - sc[10]) > p[26] * u:
                sc[6] = t
                sc[10] = d
                sc[11] = u
            else:
                sc[10] += (d - sc[10]) * min(1.0, dt / p[25])
                if t - sc[6] >= p[20] and (abs(u - sc[11]) >= p[27] * u or abs(d) <= sv3):
                    P[IV, IV] += d * d
                    Pp[IV, IV] += d * d  # process noise of this step, for the smoother
                    best = 0.0
                    kk = 1.0
                    sc[6] = math.nan
        if best <= p[7]:
            h[IV] = 1.0
            h[IR] = -kk * om
            # away from GPS the radius and the offset are consider states: a line there
            # carries the speed but teaches neither (a wrong or lagging line accepted in an
            # outage would corrupt the radius and the offset the inertial stretches rest on)
            _update_row(x, P, h, 0.0, (r_hat * kk) ** 2 * var_om * infl, -1 if fresh else IR,
                        -1 if fresh else IB)
            h[IV] = 0.0
            h[IR] = 0.0
            # the radius follows the octave most updates use (where GPS confirms them)
            if fresh:
                sc[5] += (math.log2(kk) - sc[5]) * min(1.0, dt / p[16])
            if abs(sc[5]) > 0.5 and known:
                c = 2.0 if sc[5] > 0.0 else 0.5
                x[IR] *= c
                for i in range(n):
                    P[IR, i] *= c
                    P[i, IR] *= c
                sc[5] = 0.0
        else:
            kk = math.nan
    # 4. standstill from all evidence
    stopped = False
    if not still:
        sc[7] = math.nan
    else:
        gps_ok = math.isnan(sc[3]) or (t - sc[2]) > p[14] or sc[3] <= p[13]
        consistent = (x[IV] * x[IV] / (P[IV, IV] + p[9]) <= p[11]) or abs(x[IV]) <= p[12]
        if gps_ok and not consistent:
            if math.isnan(sc[7]):
                sc[7] = t
            elif t - sc[7] >= p[23] and t - sc[1] > p[23]:
                # re-lock: the integrated speed, not the stop, is wrong
                Pp[IV, IV] += x[IV] * x[IV]  # process noise of this step, for the smoother
                P[IV, IV] += x[IV] * x[IV]
                consistent = True
        if gps_ok and consistent:
            sc[7] = math.nan
            h[IV] = 1.0
            _update_row(x, P, h, 0.0, p[9])
            h[IV] = 0.0
            h[IA] = 1.0
            _update_row(x, P, h, 0.0, p[10])
            h[IA] = 0.0
            stopped = True
    # 5. speed >= 0: project onto the constraint surface
    if p[17] > 0.5 and x[IV] < 0.0 and P[IV, IV] > 0.0:
        f = x[IV] / P[IV, IV]
        col = P[:, IV].copy()
        for i in range(n):
            x[i] -= col[i] * f
        x[IV] = 0.0
    if stopped:
        src = 3
    elif t - sc[1] <= p[15]:
        src = 1
    elif not math.isnan(kk):
        src = 2
    else:
        src = 0
    out[0] = x[IV]
    out[1] = math.sqrt(max(P[IV, IV], 0.0))
    out[2] = x[IR]
    out[3] = math.sqrt(max(P[IR, IR], 0.0))
    out[4] = x[IB]
    out[5] = src
    out[6] = kk
    return dt


@njit(cache=True)
def _run_core(Ac, qc, p, x, P, sc, t, am, g, sats, om, om_std, line, still, out, xp, Pp, xf,
              Pf, dts):
    Fc = np.eye(x.size)
    for k in range(t.size):
        dts[k] = _step_core(Ac, qc, p, x, P, sc, Fc, t[k], am[k], g[k], sats[k], om[k],
                            om_std[k], line[k], still[k], out[k], xp[k], Pp[k])
        xf[k, :] = x
        Pf[k, :, :] = P


def _unpack(state: State, n: int):
    x = np.array(state.x, dtype=np.float64)
    if x.shape != (n,):
        raise ParameterError(f"fuse: state has {x.size} states but the config's model needs {n} "
                             "(GPS delay on/off changed?)")
    P = np.array(state.P, dtype=np.float64)
    sc = np.array([state.t, state.t_gps, state.t_fix, state.v_fix, -1.0, state.octave,
                   state.t_run, state.t_still, state.t_acq, state.z_acq, state.d_run,
                   state.u_run])
    return x, P, sc


def _pack(x, P, sc) -> State:
    return State(x, P, float(sc[0]), float(sc[1]), float(sc[2]), float(sc[3]), float(sc[5]),
                 float(sc[6]), float(sc[7]), float(sc[8]), float(sc[9]), float(sc[10]),
                 float(sc[11]))


_SAMPLE = Sample._fields


def step(config: Config, state: State, y) -> tuple[State, Estimate]:
    """One fusion sample ``y``, a :class:`Sample` or the tuple ``(t, accel, gps_speed,
    gps_sats, omega, omega_std, line, still)``; the Estimate holds ``speed``, ``speed_std`` and
    the :data:`EXTRAS`."""
    t, am, g, sats, om, om_std, line, still = y
    t = float(t)
    if not math.isnan(state.t) and not t >= state.t:
        raise InputError(f"fuse: time goes backwards at t = {t} s (previous {state.t} s)")
    Ac, qc, p = config._arrays()
    x, P, sc = _unpack(state, Ac.shape[0])
    out = np.empty(7)
    n = x.size
    _step_core(Ac, qc, p, x, P, sc, np.eye(n), t, float(am), float(g), float(sats), float(om),
               float(om_std), bool(line), bool(still), out, np.empty(n), np.empty((n, n)))
    est = Estimate(speed=float(out[0]), speed_std=float(out[1]),
                   extras=dict(zip(EXTRAS, (float(out[2]), float(out[3]), float(out[4]),
                                            int(out[5]), float(out[6])), strict=True)))
    return _pack(x, P, sc), est


def _as_inputs(arrays) -> list[np.ndarray]:
    if hasattr(arrays, "_fields"):  # a Sample of arrays
        arrays = arrays._asdict()
    t = np.ascontiguousarray(arrays["t"], dtype=np.float64)
    n = t.size
    out = [t]
    for name in _SAMPLE[1:]:
        v = arrays.get(name)
        if v is None:
            dflt = False if name in ("line", "still") else np.nan
            v = np.full(n, dflt)
        v = np.ascontiguousarray(v, dtype=np.bool_ if name in ("line", "still") else np.float64)
        if v.shape != (n,):
            raise InputError(f"fuse: input '{name}' has shape {v.shape}, expected ({n},)")
        out.append(v)
    if n > 1 and not np.all(np.diff(t) >= 0):
        bad = int(np.flatnonzero(np.diff(t) < 0)[0]) + 1
        raise InputError(f"fuse: time goes backwards at sample {bad}")
    return out


def run(config: Config, y, state: State | None = None) -> Result:
    """Forward filter over fusion samples; the numbers of repeated :func:`step`.

    ``y``: a :class:`Sample` of (n,) arrays, or a mapping of its names (``t``, ``accel``,
    ``gps_speed``, ``gps_sats``, ``omega``, ``omega_std``, ``line``, ``still``) to arrays; a
    missing one is "none" (NaN / False). ``state`` defaults to :func:`init` at the first valid
    fix (or 0).
    """
    ins = _as_inputs(y)
    t, g, s = ins[0], ins[2], ins[3]
    if state is None:
        fin = np.flatnonzero(config.valid_fixes(g, s))
        state = init(config, float(g[fin[0]]) if fin.size else 0.0)
    Ac, qc, p = config._arrays()
    x, P, sc = _unpack(state, Ac.shape[0])
    n, m = t.size, x.size
    out = np.empty((n, 7))
    xp, Pp = np.empty((n, m)), np.empty((n, m, m))
    xf, Pf = np.empty((n, m)), np.empty((n, m, m))
    dts = np.empty(n)
    _run_core(Ac, qc, p, x, P, sc, *ins, out, xp, Pp, xf, Pf, dts)
    o = Output(*(np.ascontiguousarray(out[:, i]) for i in range(5)),
               out[:, 5].astype(np.int8), np.ascontiguousarray(out[:, 6]), xp, Pp, xf, Pf, dts)
    return Result(_pack(x, P, sc), o)


@njit(cache=True)
def _rts(Ac, xp, Pp, xf, Pf, dts, xs, Ps):
    n = xf.shape[0]
    xs[n - 1] = xf[n - 1]
    Ps[n - 1] = Pf[n - 1]
    last = -1.0
    F = np.eye(xf.shape[1])
    for k in range(n - 2, -1, -1):
        dt = dts[k + 1]
        if dt != last:
            F = transition(Ac, dt) if dt > 0.0 else np.eye(xf.shape[1])
            last = dt
        C = Pf[k] @ F.T @ np.linalg.pinv(Pp[k + 1])
        xs[k] = xf[k] + C @ (xs[k + 1] - xp[k + 1])
        Pk = Pf[k] + C @ (Ps[k + 1] - Pp[k + 1]) @ C.T
        Ps[k] = 0.5 * (Pk + Pk.T)


def smooth(config: Config, out: Output) -> tuple[np.ndarray, np.ndarray]:
    """Rauch-Tung-Striebel smoother over a :func:`run`: ``(xs, Ps)`` (n, m) and (n, m, m), the
    state given the whole log (``C_k = Pf_k F' Pp_{k+1}^-1``,
    ``xs_k = xf_k + C_k (xs_{k+1} - xp_{k+1})``, ``Ps_k = Pf_k + C_k (Ps_{k+1} - Pp_{k+1}) C_k'``).
    """
    Ac, _, _ = config._arrays()
    xs = np.empty_like(out.xf)
    Ps = np.empty_like(out.Pf)
    if out.xf.shape[0]:
        _rts(Ac, out.xp, out.Pp, out.xf, out.Pf, out.dt, xs, Ps)
    return xs, Ps


# -- radius round trip ---------------------------------------------------------------------------

def radius_from_json(path: str | os.PathLike[str]) -> tuple[float, float]:
    """``(radius, std)`` in m from an earlier ``fuse`` estimate's sidecar (``est.csv.json``:
    ``params.learned_radius`` / ``params.learned_radius_std``), or from any JSON object with
    ``wheel_radius`` and optionally ``wheel_radius_std`` (default 1 % of it)."""
    p = Path(path)
    try:
        side = json.loads(p.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{p}: cannot read the radius file ({exc})") from None
    if not isinstance(side, dict):
        raise InputError(f"{p}: the radius file must hold a JSON object")
    par = side.get("params") if isinstance(side.get("params"), dict) else {}
    if "learned_radius" in par:
        r, s = par.get("learned_radius"), par.get("learned_radius_std")
    elif "wheel_radius" in side:
        r = side.get("wheel_radius")
        s = side.get("wheel_radius_std", None)
        s = 0.01 * r if s is None and isinstance(r, (int, float)) else s
    else:
        raise InputError(f"{p}: no learned_radius (a fuse estimate's sidecar) or wheel_radius "
                         "in the radius file")
    ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
             and v > 0 for v in (r, s))
    if not ok:
        raise InputError(f"{p}: radius and its std must be positive numbers, got {r!r}, {s!r}")
    return float(r), float(s)


# -- recording -> fusion samples ------------------------------------------------------------------

def fusion_samples(t: np.ndarray, fix: np.ndarray, rate: float) -> np.ndarray:
    """End indices (inclusive) of the fusion blocks: every ``round(fs / rate)`` samples and at
    every sample carrying a GPS fix, so that a fix is fused at its own time."""
    n = t.size
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    m = max(1, int(round(1.0 / (rate * dt))))
    ends = np.union1d(np.arange(m - 1, n, m), np.flatnonzero(fix))
    if ends.size == 0 or ends[-1] != n - 1:
        ends = np.append(ends, n - 1)
    return ends.astype(np.int64)


def _block_mean(x: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Mean of the finite samples of ``x`` in each block ``(ends[k-1], ends[k]]`` (NaN: none)."""
    ok = np.isfinite(x)
    cs = np.concatenate([[0.0], np.cumsum(np.where(ok, x, 0.0))])
    cn = np.concatenate([[0], np.cumsum(ok)])
    starts = np.concatenate([[0], ends[:-1] + 1])
    s = cs[ends + 1] - cs[starts]
    c = cn[ends + 1] - cn[starts]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c > 0, s / np.maximum(c, 1), np.nan)


def _block_all(x: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """True where every sample of the block is true."""
    cn = np.concatenate([[0], np.cumsum(~x)])
    starts = np.concatenate([[0], ends[:-1] + 1])
    return (cn[ends + 1] - cn[starts]) == 0


_TRACKER_OWN = {"online", "radius_from", "accel_axis", "vib_method"}


def _split(params: dict) -> tuple[dict, dict, dict]:
    names = {f.name for f in fields(Config)}
    fuse_kw = {k: v for k, v in params.items() if k in names}
    own = {k: v for k, v in params.items() if k in _TRACKER_OWN}
    rest = {k: v for k, v in params.items() if k not in names and k not in _TRACKER_OWN}
    return fuse_kw, own, rest


def estimate(recording: Recording, *, axis: str = "y", wheel_radius: float | None = None,
             params: dict | None = None, progress: bool = False,
             return_posterior: bool = False,
             radius_from: str | os.PathLike[str] | None = None,
             vibration: Track | None = None) -> Track:
    """Fused speed of a recording: vibration tracker on ``axis``, then the filter.

    ``params``: :class:`Config` fields; ``accel_axis`` (longitudinal accelerometer channel,
    default ``ax``); ``online`` (true: the causal grid tracker and the forward filter only;
    default false: the smoothed grid tracker and the RTS smoother); ``radius_from`` (a JSON
    file, :func:`radius_from_json`, seeding the radius prior; also a keyword); every other
    name goes to the grid tracker (e.g. ``omega_min``, ``omega_max``). A given ``wheel_radius``
    seeds the prior with 1 % spread. ``gps_speed`` / ``gps_sats`` are used where present;
    without GPS the radius prior must come from ``radius_from`` or ``wheel_radius``.
    ``return_posterior``: the vibration tracker's omega posterior in ``extras["posterior"]``.
    ``vibration``: a grid track of this recording already at hand (then no tracker runs; it
    must be the causal one for ``online``).

    Columns: speed and its band (from the fused std); omega = speed / learned radius where
    the radius is known at the end (relative std below ``octave_rel``; else empty, with a
    note); extras ``source`` (:data:`SOURCES` codes), ``radius``, ``radius_std``, ``offset``,
    ``harmonic`` (k of the wheel-frequency update) and the tracker's ``omega_vib``,
    ``has_signal``, ``standstill``. The
    learned radius and its std (the filter's at the end of the log) are in
    ``params["learned_radius"]``, ``params["learned_radius_std"]`` (the JSON sidecar).
    """
    from vibrospeed.estimators import get

    params = dict(params or {})
    fuse_kw, own, rest = _split(params)
    cfg = config_from_params(Config, fuse_kw)
    online = parse_flag(own.get("online", False), "online")
    rf = radius_from if radius_from is not None else own.get("radius_from")
    acc_ch = _axis_channel(str(own.get("accel_axis", "x")))
    name = recording.source or "recording"
    if len(recording) < 2:
        raise InputError(f"{name}: fewer than 2 samples")
    recording.require(acc_ch)
    has_gps = "gps_speed" in recording and np.isfinite(recording.channel("gps_speed")).any()
    notes: list[str] = []
    if rf is not None:
        r0, rs0 = radius_from_json(rf)
        notes.append(f"radius prior {r0:.4f} +- {rs0:.4f} m from {os.fspath(rf)}")
    elif wheel_radius:
        r0, rs0 = float(wheel_radius), 0.01 * float(wheel_radius)
        notes.append(f"radius prior {r0:.4f} +- {rs0:.4f} m (the given wheel radius, 1 %)")
    elif has_gps:
        r0, rs0 = cfg.radius0, cfg.radius_std0
    else:
        raise ParameterError(f"{name}: fuse without gps_speed needs a radius: radius_from= an "
                             "earlier fuse estimate's .json, or --wheel-radius")
    # 1. the vibration tracker (offline smoothed / online causal)
    tparams = {**TRACKER_DEFAULTS, **rest}
    if online:
        tparams["smooth"] = "none"
    if vibration is None:
        vib = get("grid").estimate(recording, axis=axis, params=tparams, progress=progress,
                                   return_posterior=return_posterior)
    elif len(vibration) != len(recording):
        raise InputError(f"{name}: the vibration track has {len(vibration)} samples, the "
                         f"recording {len(recording)}")
    else:
        vib = vibration
    claim = np.nan_to_num(vib.extras.get("has_signal", np.ones(len(vib)))) > 0.5
    still = (np.nan_to_num(vib.extras.get("standstill", np.zeros(len(vib)))) > 0.5) & ~claim
    line = claim if cfg.vib_use == "line" else (np.nan_to_num(vib.omega) > 0) & ~still
    # 2. fusion samples
    t = recording.t
    g = recording.channels.get("gps_speed", np.full(t.size, np.nan))
    s = recording.channels.get("gps_sats", np.full(t.size, np.nan))
    fix = np.isfinite(g)
    ends = fusion_samples(t, fix, cfg.fuse_rate)
    arrays = {
        "t": t[ends], "accel": _block_mean(recording.channel(acc_ch), ends),
        "gps_speed": g[ends], "gps_sats": s[ends], "omega": vib.omega[ends],
        "omega_std": vib.omega_std[ends], "line": line[ends], "still": _block_all(still, ends),
    }
    fin = np.flatnonzero(cfg.valid_fixes(g, s))
    v0 = float(g[fin[0]]) if fin.size else 0.0
    state0 = init(cfg, v0, radius=r0, radius_std=rs0)
    end, o = run(cfg, arrays, state=state0)
    r_fin, rs_fin = float(o.radius[-1]), float(o.radius_std[-1])
    if online:
        v, vs, rr, rrs, off = o.speed, o.speed_std, o.radius, o.radius_std, o.offset
    else:
        xs, Ps = smooth(cfg, o)
        v, vs = xs[:, IV], np.sqrt(np.maximum(Ps[:, IV, IV], 0.0))
        rr, rrs = xs[:, IR], np.sqrt(np.maximum(Ps[:, IR, IR], 0.0))
        off = xs[:, IB]
    # 3. back to the recording's time line: linear between fusion samples, source per block
    tb = t[ends]
    blk = np.minimum(np.searchsorted(ends, np.arange(t.size)), ends.size - 1)

    def back(x):
        return np.interp(t, tb, x)

    speed = back(v)
    speed_std = back(vs)
    shares = {SOURCES[c]: float(np.mean(o.source == c)) for c in SOURCES}
    notes.append("fused speed rests on " + ", ".join(f"{k} {100 * x:.1f} %"
                                                     for k, x in shares.items()) +
                 f" of the fusion samples ({'forward filter' if online else 'RTS smoothed'})")
    notes.append(f"learned wheel radius {r_fin:.4f} +- {rs_fin:.4f} m"
                 + ("" if has_gps else " (no GPS: the prior, kept)"))
    known = rs_fin < cfg.octave_rel * r_fin
    if not known:
        notes.append("the wheel radius is not known (no wheel line while GPS was good): omega "
                     "is left empty; the vibration tracker's own omega is omega_vib")
    pdict = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()}
    pdict.update({"online": online, "accel_axis": acc_ch, "axis": axis,
                  "learned_radius": r_fin, "learned_radius_std": rs_fin,
                  "radius_prior": [r0, rs0], "tracker": vib.method, **{
                      f"tracker_{k}": v for k, v in rest.items()}})
    extras = {
        "source": o.source.astype(np.float64)[blk], "radius": back(rr),
        "radius_std": back(rrs), "offset": back(off), "harmonic": o.harmonic[blk],
        "omega_vib": vib.omega, "has_signal": claim.astype(np.float64),
    }
    if "standstill" in vib.extras:
        extras["standstill"] = np.asarray(vib.extras["standstill"], dtype=np.float64)
    if return_posterior and "posterior" in vib.extras:  # the vibration tracker's omega posterior
        extras["posterior"] = vib.extras["posterior"]
    return Track.from_speed(t, speed, speed_std, wheel_radius=r_fin if known else None,
                            method="fuse",
                            params=pdict, extras=extras, notes=[*vib.notes, *notes])


def suits(recording: Recording, accel_axis: str = "x") -> bool:
    """Whether ``recording`` feeds ``fuse`` without a radius given: a ``gps_speed`` channel
    with at least one finite fix and the longitudinal accelerometer channel (``accel_axis``).
    ``vibrospeed estimate`` without ``--method`` picks ``fuse`` for such a recording."""
    if "gps_speed" not in recording or _axis_channel(accel_axis) not in recording:
        return False
    return bool(np.isfinite(recording.channel("gps_speed")).any())


def _axis_channel(axis: str) -> str:
    axis = axis.strip()
    return "a" + axis if axis in ("x", "y", "z") else axis
