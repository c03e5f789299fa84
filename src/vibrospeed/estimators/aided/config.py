"""Parameters of the aided EKF (:mod:`vibrospeed.estimators.aided`): the thesis' harmonic model
(ch. 3) and the :class:`Config` of the tracker, its detectors (standstill window / CUSUM /
broadband, mode detector), the line gate and the comb check, validated on construction.
The derived quantities the compiled core reads (window lengths in samples, the CUSUM threshold
at the log's rate, the omega clip) are properties here, so they have one definition."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from vibrospeed.errors import ParameterError
from vibrospeed.estimators.grid.config import MAX_FLOATS
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal import detectors as det
from vibrospeed.signal.comb import COMB_COUNT, COMB_REL

STANDSTILL_KINDS = {"none": 0, "window": 1, "cusum": 2, "broadband": 3}

#: most samples in a detector window (``ss_n`` / ``ss_window``, ``mode_n`` / ``mode_window``):
#: 4 Mi samples (11.6 h at 100 Hz); a typo (1e12) died allocating TiB
MAX_WINDOW = 1 << 22


def check_windows(config, dt: float) -> None:
    """:class:`ParameterError` unless the standstill and mode windows of ``config`` (the aided
    EKF's or the aided grid tracker's, fields ``ss_n``, ``ss_window``, ``mode_n``,
    ``mode_window``) hold at most :data:`MAX_WINDOW` samples at period ``dt`` s."""
    for n_name, s_name in (("ss_n", "ss_window"), ("mode_n", "mode_window")):
        n, seconds = getattr(config, n_name), getattr(config, s_name)
        if det.window_samples(n, seconds, dt) > MAX_WINDOW:
            got = f"{n_name} = {n}" if n is not None else f"{s_name} = {seconds:g} s"
            raise ParameterError(f"{s_name} / {n_name} must be at most {MAX_WINDOW} samples "
                                 f"({MAX_WINDOW * dt:.4g} s at {1 / dt:.4g} Hz), got {got}")


def check_inputs(lp_cutoff: float | None, wheelbase: float | None,
                 accel_detrend: float) -> None:
    """:class:`ParameterError` unless the aided trackers' input parameters (read by their
    ``estimate``, not Config fields) are in their domains: NaN ``lp_cutoff`` died in the
    filter design, inf there too with the EKF and was ignored with the grid, and 0 was the
    preset's cut-off without a word; a NaN, negative or zero
    ``wheelbase`` and a NaN or negative ``accel_detrend`` (0: off; inf: the plain running
    mean) were used as given."""
    if lp_cutoff is not None and not 0 < lp_cutoff < math.inf:
        raise ParameterError(f"lp_cutoff must be finite and > 0 rad/s (or none: the "
                             f"pre-filter's own cut-off), got {lp_cutoff}")
    if wheelbase is not None and not 0 < wheelbase < math.inf:
        raise ParameterError(f"wheelbase must be finite and > 0 m (or none), got {wheelbase}")
    if not accel_detrend >= 0:
        raise ParameterError(f"accel_detrend must be >= 0 s (0: off), got {accel_detrend}")



def _is_count(v) -> bool:
    """``v`` is a whole number >= 1 (NaN and inf failed in ``int()``)."""
    return math.isfinite(v) and int(v) == v and v >= 1


def _thesis_model() -> HarmonicModel:
    # thesis 3.5: M = 2 best; R = 0.0022 (table 3.1; the text says 0.0008); q_amp from ch. 2
    # (Q = 4e-5 per step at 100 Hz). q_omega 0.5 instead of the ch. 2 value 16 (rad/s)^2/s,
    # which makes the vibration-mode omega wander on the cart: the aiding handles the fast
    # changes (benchmarks/aided/RESULTS.md).
    return HarmonicModel(M=2, dt=0.01, q_omega=0.5, q_amp=0.004, r=0.0022, p0_amp=0.1)


@dataclass(frozen=True)
class Config:
    """Parameters of the aided tracker (SI units).

    model : harmonic model (M, dt, q_omega, q_amp, r, p0_amp); default the thesis' ch. 3 choice
        M = 2, R = 0.0022, q_amp = 0.004 in m/s^2 units, with q_omega = 0.5 (rad/s)^2/s
        (lower than the thesis' ch. 2 value 16, see ``_thesis_model``).
    wheel_radius : r in m (required for the aiding).
    omega0, p0_omega : initial omega (rad/s) and its variance (start from rest: 0, 1).
    amp0 : initial alpha, beta.
    q_bias : random-walk intensity of b, (m/s^2)^2/s. p0_bias : initial variance of b.
    q_omega_accel : omega random-walk intensity (rad/s)^2/s in acceleration mode, when the
        integrated acceleration drives omega (None: the model's q_omega).
    standstill : 'window' (thesis 3.1), 'cusum' (thesis 4.2.3), 'broadband' (the per-sample
        ``still`` input, :func:`standstill_flags`; :func:`estimate`'s default) or 'none'.
    ss_window, ss_mu : window length (s) and threshold (m/s^2) of the window test (thesis: 20
        samples at 100 Hz = 0.2 s, 0.019; ``ss_mu = inf``: every full window passes the
        test); ``ss_n`` (samples) overrides the length when set.
        In seconds, so a 400 Hz log looks at the same 0.2 s: 20 samples there (0.05 s) read a
        slow wheel's vibration as flat, i.e. standstill while driving.
    r_ss : variance of the virtual standstill measurement omega = 0 (thesis: 1).
    release_on_accel : with ``standstill='broadband'``, a sample the mode detector puts in
        acceleration mode is moving even where ``still`` says standing (the acceleration is
        integrated). For causal stop flags, which reach 1-1.7 s into the start
        (:func:`estimate` sets it with ``causal=True``); the whole-log flags end 0.5 s before
        the motion, and there an offset while standing that differs from stop to stop (a ramp)
        would release stops.
    cusum_sigma : residual level (m/s^2) separating quiet from moving; cusum_nu, cusum_h :
        drift (``inf``: no alarm) and threshold of the CUSUM on ``eps = 1 - (e / sigma)^2``;
        the standstill flag is held for :func:`vibrospeed.signal.detectors.cusum_hold` samples
        after an alarm.
    cusum_fs : Hz, the sample rate at which ``cusum_h`` holds (the thesis' 100 Hz); a log at fs
        uses the threshold ``cusum_h fs / cusum_fs`` (:attr:`cusum_threshold`) and so the same
        detection delay and hold in seconds (a per-sample threshold at 400 Hz alarms within
        0.05 s of quiet residuals while driving). None: per sample, as written in the thesis.
    mode_window, mode_mu : window length (s) and threshold (m/s^2) of the mode detector
        (0.2 s = the thesis' 20 samples at 100 Hz, 0.20; ``mode_mu = inf``: never acceleration
        mode); ``mode_n`` (samples) overrides.
    boost : apply the boost of eq. 3.15 (``N_mode`` T ubar / r) when acceleration mode starts.
    aid_always : integrate u in vibration mode too (variant, see the package docstring).
    omega_max : upper clip (rad/s); None: 0.98 pi fs / M.
    line_min : gate on the explained power share (see the package docstring; 0 = off).
    line_tau : time constant (s) of the running power of the EKF input for the gate.
    line_omega_min : with the gate on, omega below this (rad/s) never opens it: a phasor
        rotating slowly tracks the low-frequency content left by the high-pass (turns, body
        sway) and would "explain" it, pinning omega near 0 (seen on the Hungary drives).
    init_ref : omega unknown until the first fix / standstill measurement (package docstring).
    comb_count, comb_rel : comb check (the ``comb`` input, :func:`comb_fixes`): after
        ``comb_count`` steady comb candidates in a row (outside acceleration mode) that differ
        from omega by more than ``comb_rel`` of the candidate, omega is measured as the
        candidate with std ``comb_rel / 2`` of it (acquisition, re-lock from half or twice the
        wheel speed).
    """

    model: HarmonicModel = field(default_factory=_thesis_model)
    wheel_radius: float = 0.08
    omega0: float = 0.0
    p0_omega: float = 1.0
    amp0: float = 0.0
    q_bias: float = 1e-4
    p0_bias: float = 0.01
    q_omega_accel: float | None = 1.0
    standstill: str = "window"
    ss_n: int | None = None
    ss_window: float = det.WINDOW_S
    ss_mu: float = det.WINDOW_MU
    r_ss: float = 1.0
    release_on_accel: bool = False
    cusum_sigma: float = 0.015
    cusum_nu: float = 0.5
    cusum_h: float = 10.0
    cusum_fs: float | None = 100.0
    mode_n: int | None = None
    mode_window: float = det.MODE_S
    mode_mu: float = det.MODE_MU
    boost: bool = True
    aid_always: bool = False
    omega_max: float | None = None
    line_min: float = 0.0
    line_tau: float = 2.0
    line_omega_min: float = 5.0
    init_ref: bool = False
    comb_count: int = COMB_COUNT
    comb_rel: float = COMB_REL

    def __post_init__(self) -> None:
        if not 0 < self.wheel_radius < math.inf:  # inf: every speed 0 or NaN
            raise ParameterError(f"wheel_radius must be finite and > 0 m, got "
                                 f"{self.wheel_radius}")
        # the filter's state holds 2M phasors and b, omega, with their covariance: M = 1e12
        # died allocating TiB
        M = int(self.model.M)
        if (2 * M + 2) ** 2 > MAX_FLOATS:
            raise ParameterError(f"M = {M} is too large: the aided EKF's covariance ((2M + 2)^2) "
                                 f"would hold {(2 * M + 2) ** 2:.3g} floats, at most "
                                 f"{MAX_FLOATS:.3g} (1 GiB)")
        if self.standstill not in STANDSTILL_KINDS:
            raise ParameterError(f"standstill must be one of {', '.join(STANDSTILL_KINDS)}, "
                                 f"got '{self.standstill}'")
        for name in ("ss_mu", "mode_mu", "cusum_sigma"):  # thresholds: inf is allowed
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)}")
        # an infinite prior or standstill variance made the output NaN; an infinite cusum_h
        # failed in run (standstill='none' is the detector off)
        for name in ("p0_omega", "p0_bias", "r_ss", "cusum_h"):
            if not 0 < getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and > 0, got {getattr(self, name)}")
        if not math.isfinite(self.amp0):
            raise ParameterError(f"amp0 must be finite, got {self.amp0}")
        if math.isnan(self.cusum_nu):  # failed in int() of the hold in run
            raise ParameterError(f"cusum_nu must be a number, got {self.cusum_nu}")
        if not 0 <= self.line_min < 1:
            raise ParameterError(f"line_min must be in [0, 1), got {self.line_min}")
        if not self.line_tau > 0:
            raise ParameterError(f"line_tau must be > 0 s, got {self.line_tau}")
        if not _is_count(self.comb_count):
            raise ParameterError(f"comb_count must be a positive integer, got {self.comb_count}")
        if not self.comb_rel > 0:
            raise ParameterError(f"comb_rel must be > 0, got {self.comb_rel}")
        for name in ("q_bias", "omega0"):
            if not 0 <= getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and >= 0, got "
                                     f"{getattr(self, name)}")
        if self.q_omega_accel is not None and not 0 <= self.q_omega_accel < math.inf:
            raise ParameterError(f"q_omega_accel must be finite and >= 0 (or None), got "
                                 f"{self.q_omega_accel}")
        for name in ("ss_n", "mode_n"):
            v = getattr(self, name)
            if v is not None and not _is_count(v):
                raise ParameterError(f"{name} must be a positive integer, got {v}")
        if self.cusum_fs is not None and not self.cusum_fs > 0:
            raise ParameterError(f"cusum_fs must be > 0 Hz (or None), got {self.cusum_fs}")
        for name in ("ss_window", "mode_window"):  # inf failed in int() in run
            if not 0 < getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and > 0 s, got "
                                     f"{getattr(self, name)}")
        check_windows(self, self.model.dt)

    @property
    def cusum_threshold(self) -> float:
        """CUSUM alarm threshold per sample: ``cusum_h``, scaled by ``fs / cusum_fs``."""
        if self.cusum_fs is None:
            return float(self.cusum_h)
        return float(self.cusum_h) / (float(self.cusum_fs) * self.model.dt)

    @property
    def ss_len(self) -> int:
        """Samples in the standstill window: ``ss_n``, else ``ss_window`` s."""
        return det.window_samples(self.ss_n, self.ss_window, self.model.dt)

    @property
    def mode_len(self) -> int:
        """Samples in the mode-detector window: ``mode_n``, else ``mode_window`` s."""
        return det.window_samples(self.mode_n, self.mode_window, self.model.dt)

    @property
    def omega_limit(self) -> float:
        """Upper clip for omega in rad/s (:meth:`HarmonicModel.omega_clip`)."""
        return self.model.omega_clip(self.omega_max)

    @property
    def n_state(self) -> int:
        """Length of the state vector, 2 + 2M."""
        return 2 + self.model.n_lin
