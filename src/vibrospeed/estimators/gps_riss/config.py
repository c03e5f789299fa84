"""Parameters of GPS/RISS (:mod:`vibrospeed.estimators.gps_riss`): gravity, the per-sample
``mode`` flags, :class:`GpsFields` (the GPS receiver lag model and satellite gate, shared with
``fuse``) and the filter's :class:`Config` (noises, GPS error weighting, offset and pitch
handling; the paper's set :meth:`Config.paper`), validated on construction; its
``_arrays`` builds the matrices and parameter vector the compiled core reads."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.models.gps_riss import GpsLagModel, continuous_matrix

G = 9.80665

# Flags reported per sample in ``run`` output ``mode``.
MODE_INS = 0  #: accelerometer only ("KF INS")
MODE_GPS = 1  #: valid GPS fix fused ("KF1 INS/GPS")
MODE_REJECTED = 2  #: a fix was present but gated out (too few satellites)

_ERROR_MODES = ("innovation", "kf2", "states")
_OFFSET_MODES = ("state", "integrator", "off")


@dataclass(frozen=True)
class GpsFields:
    """The GPS receiver and its satellite gate, one definition for every filter that fuses GPS
    speed (``gps-riss``, ``fuse``: their Configs start with these fields).

    gps_a, gps_b : GPS lag model A_gps (row-major) and B_gps, paper eq. 3-4 (default: the
        paper's second-order receiver).
    gps_delay : pure GPS delay (s) in front of the lag, Pade order ``gps_pade`` (1 or 2).
    min_sats : satellite-count gate (paper: 7): a fix is valid where ``gps_sats >= min_sats``
        or the count is unknown (NaN).
    gps_lag_std : s, prior std of the receiver's lag beyond the model's. The extra lag ``dl``
        is the filter's last state, from ``0 +- gps_lag_std``; a fix is read as the model's
        output ``dl`` earlier, ``g = x3(t - dl) ~ x3 - dl x3'`` (an extended Kalman row
        linearised at the estimate), so the filter learns ``dl`` where the accelerometer and
        GPS both see a speed change and until then carries its uncertainty in the speed band.
        Receivers differ in lag (the paper's 0.08 s, a u-blox 0.17 s, phones and loggers
        with a time-stamp latency more); one that lags ``dl`` more than the model reads low by
        ``dl a`` while accelerating, fix after fix, an error white GPS noise does not
        describe. The estimate's sidecar reports the learned lag (``params.learned_gps_lag``,
        the model's lag plus ``dl``, and ``learned_gps_lag_std``). 0 (with ``q_gps_lag`` 0):
        the lag model is taken as exact (the paper's filter; an identified receiver model).
    q_gps_lag : s^2/s, random-walk intensity of that extra lag: its std grows by
        ``sqrt(q_gps_lag t)`` over ``t`` seconds (the default 1e-3: 0.1 s in 10 s), so the
        learned lag can follow a slow change.
    """

    gps_a: tuple[float, ...] = (0.0, 1.0, -1427.2, -114.2)
    gps_b: tuple[float, ...] = (0.0, 1427.2)
    gps_delay: float = 0.0
    gps_pade: int = 2
    min_sats: float = 7.0
    gps_lag_std: float = 0.3
    q_gps_lag: float = 1e-3

    @property
    def lag(self) -> GpsLagModel:
        """The GPS receiver model."""
        return GpsLagModel(a=tuple(self.gps_a), b=tuple(self.gps_b),  # type: ignore[arg-type]
                           delay=float(self.gps_delay), pade=int(self.gps_pade))

    def valid_fixes(self, gps_speed: np.ndarray, gps_sats: np.ndarray | None) -> np.ndarray:
        """Where a fix is valid: finite speed and not fewer than ``min_sats`` satellites."""
        g = np.asarray(gps_speed, dtype=np.float64)
        if gps_sats is None:
            return np.isfinite(g)
        return np.isfinite(g) & ~(np.asarray(gps_sats, dtype=np.float64) < self.min_sats)

    def _check_gps(self, prefix: str = "") -> None:
        """Validates the lag model and the gate (the Configs' ``__post_init__``)."""
        if self.gps_pade not in (1, 2):  # the lag model reads int(gps_pade): 2.5 was 2
            raise ParameterError(f"{prefix}gps_pade must be 1 or 2, got {self.gps_pade}")
        _ = self.lag
        if not self.min_sats >= 0:
            raise ParameterError(f"{prefix}min_sats must be >= 0, got {self.min_sats}")
        for name in ("gps_lag_std", "q_gps_lag"):
            v = getattr(self, name)
            if not (v >= 0 and math.isfinite(v)):
                raise ParameterError(f"{prefix}{name} must be finite and >= 0, got {v}")

    def _arrays(self):
        """The filter's constant arrays (the subclass's ``_build_arrays``: ``gps-riss``'s and
        ``fuse``'s), built once per Config and kept with it (a device's ``step`` per fusion
        sample rebuilt them every time: ~100-165 us of each step). Callers read them and
        never write."""
        got = self.__dict__.get("_arrays_cache")
        if got is None:
            got = self.__dict__["_arrays_cache"] = self._build_arrays()
        return got


@dataclass(frozen=True)
class Config(GpsFields):
    """Parameters (SI units; physical noise defaults, see the module notes; paper set:
    :meth:`paper`).

    Parameters
    ----------
    gps_a, gps_b, gps_delay, gps_pade, min_sats, gps_lag_std, q_gps_lag : the GPS receiver,
        its satellite gate and its learned extra lag, described in :class:`GpsFields`.
    q_speed, q_accel, q_offset, q_gps : process noise intensities per second of the speed
        ((m/s)^2/s, model error), acceleration ((m/s^2)^2/s, jerk), offset ((m/s^2)^2/s, grade
        changes) and receiver states (paper eq. 11 "P" = 5, 4, -, 1).
    acc_psd : accelerometer noise density ((m/s^2)^2 s): a sample standing for ``dt`` s has
        variance ``acc_psd / dt`` in both "KF INS" and "KF1", so the weight of the accelerometer
        per second is the same at any sample rate. The default (0.32 m/s^2/sqrt(Hz), as
        ``fuse``'s) stands for what a vehicle adds to the sensor's own noise: wheel vibration,
        body pitch and the lateral acceleration a slightly yawed mount mixes in, which on the
        simulated random family has a density of 0.1-0.24 below 1 Hz. 0: the per-sample
        variances ``r_acc_ins`` / ``r_acc_gps`` instead (the paper's filter).
    r_acc_ins, r_acc_gps : accelerometer variance per sample in "KF INS" / "KF1" (paper 0.4, 3.5),
        used where ``acc_psd`` is 0.
    r_gps : GPS speed variance per fix at zero error (paper eq. 13, 18: 40 in its units).
    r_gps_slope, r_gps_sq : R22 growth per m/s and per (m/s)^2 of the GPS error E (paper: 72, 0).
    e_max : clip of E in m/s (paper: 5).  adaptive : use the adaptive R22 (else r_gps).
    error_mode : "innovation", "kf2" or "states" (module notes, step 4).
    gain : accelerometer calibration gain.
    pitch_compensation : apply ``pitch_poly`` (deg, highest power first; paper eq. 14, fitted for
        a motorcycle, so off by default).
    offset_mode : "state", "integrator" (paper VI-b) or "off".
    q_drift, r_drift : integrator drift filter noise ((m/s)^2/s, (m/s)^2); it uses q_offset too.
    p0_speed, p0_accel, p0_offset : initial variances.
    """

    q_speed: float = 1e-4
    q_accel: float = 10.0
    q_offset: float = 5e-3
    q_gps: float = 1e-6
    acc_psd: float = 0.1
    r_acc_ins: float = 0.09
    r_acc_gps: float = 0.09
    r_gps: float = 0.01
    r_gps_slope: float = 0.0
    r_gps_sq: float = 0.5
    e_max: float = 5.0
    adaptive: bool = True
    error_mode: str = "innovation"
    gain: float = 1.0
    pitch_compensation: bool = False
    pitch_poly: tuple[float, ...] = (-0.0183, 0.2822, 0.0207)
    offset_mode: str = "state"
    q_drift: float = 1e-3
    r_drift: float = 0.1
    p0_speed: float = 1.0
    p0_accel: float = 1.0
    p0_offset: float = 0.25

    def __post_init__(self) -> None:
        self._check_gps()
        # variances, intensities and the gain are finite (an inf one made the speed and its
        # std NaN); e_max may be inf (no clip of E)
        for name in ("r_acc_ins", "r_acc_gps", "r_gps", "r_drift", "p0_offset", "p0_speed",
                     "p0_accel", "gain"):
            if not 0 < getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and > 0, got "
                                     f"{getattr(self, name)}")
        for name in ("q_speed", "q_accel", "q_offset", "q_gps", "r_gps_slope", "r_gps_sq",
                     "q_drift", "acc_psd"):
            if not 0 <= getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and >= 0, got "
                                     f"{getattr(self, name)}")
        if not self.e_max >= 0:
            raise ParameterError(f"e_max must be >= 0, got {self.e_max}")
        if not all(math.isfinite(c) for c in self.pitch_poly):
            raise ParameterError(f"pitch_poly must be finite numbers, got {self.pitch_poly}")
        if self.error_mode not in _ERROR_MODES:
            raise ParameterError(f"error_mode must be one of {', '.join(_ERROR_MODES)}, "
                                 f"got '{self.error_mode}'")
        if self.offset_mode not in _OFFSET_MODES:
            raise ParameterError(f"offset_mode must be one of {', '.join(_OFFSET_MODES)}, "
                                 f"got '{self.offset_mode}'")
        if len(self.pitch_poly) < 1:
            raise ParameterError("pitch_poly needs at least one coefficient")

    @classmethod
    def paper(cls, **kw) -> Config:
        """The paper's constants (eq. 11-13, 18; Q read as intensities per second), its KF2 error
        and separate drift filter: the weighting of the paper, but ``speed_std`` is not calibrated.
        """
        base = dict(q_speed=5.0, q_accel=4.0, q_offset=1e-2, q_gps=1.0, r_acc_ins=0.4,
                    r_acc_gps=3.5, r_gps=40.0, r_gps_slope=72.0, r_gps_sq=0.0,
                    error_mode="kf2", offset_mode="integrator", p0_speed=100.0, p0_accel=5.0,
                    gps_lag_std=0.0, q_gps_lag=0.0, acc_psd=0.0)
        base.update(kw)
        return cls(**base)

    @classmethod
    def with_lag(cls, lag: GpsLagModel, **kw) -> Config:
        """Default config using the receiver model ``lag`` (e.g. from :func:`identify_lag`)."""
        return cls(gps_a=tuple(lag.a), gps_b=tuple(lag.b), gps_delay=lag.delay,
                   gps_pade=lag.pade, **kw)

    def using_lag(self, lag: GpsLagModel) -> Config:
        """This config with the receiver model replaced by ``lag``."""
        return replace(self, gps_a=tuple(lag.a), gps_b=tuple(lag.b), gps_delay=lag.delay,
                       gps_pade=lag.pade)

    def _build_arrays(self):
        lag = self.lag
        Ac0 = continuous_matrix(lag, offset_state=True)
        n = Ac0.shape[0] + 1  # the last state: the receiver's extra lag (constant in Ac)
        Ac = np.zeros((n, n))
        Ac[:-1, :-1] = Ac0
        state_off = self.offset_mode == "state"
        qc = np.full(n, self.q_gps)
        qc[:3] = (self.q_speed, self.q_accel, self.q_offset if state_off else 0.0)
        qc[-1] = self.q_gps_lag
        ha = np.zeros(n)
        ha[1] = 1.0
        ha[2] = 1.0 if state_off else 0.0
        hg = np.zeros(n)
        hg[3] = 1.0
        p = np.array([
            self.r_acc_ins, self.r_acc_gps, self.r_gps, self.r_gps_slope, self.r_gps_sq,
            self.e_max, float(self.adaptive), self.min_sats, self.gain,
            float(self.pitch_compensation), float(self.offset_mode == "integrator"),
            self.q_drift, self.q_offset, self.r_drift, float(_ERROR_MODES.index(self.error_mode)),
            self.acc_psd,
        ], dtype=np.float64)
        return Ac, qc, ha, hg, p, np.array(self.pitch_poly, dtype=np.float64)
