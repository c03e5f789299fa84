# Over 500 lines: the thesis' aided EKF is one compiled kernel; its detectors' wiring, Config,
# protocol and entry point explain each other (the inputs are in estimators.aiding).
"""Inertial-aided vibration tracker (thesis ch. 3 and 4.2; METHODS.md section 2).

The harmonic EKF of :mod:`vibrospeed.estimators.ekf` extended with

* an accelerometer-bias state and the longitudinal acceleration ``u = a_x`` as control input
  (thesis 3.2, eq. 3.10-3.13). State ``x = [omega, alpha_1, beta_1, ..., alpha_M, beta_M, b]``::

      omega_{k+1} = omega_k + (T / r) b_k + (T / r) u_k + v^omega_k
      b_{k+1}     = b_k + v^b_k

  The thesis writes ``omega + b / r + (T / r) u`` with ``b`` a velocity increment per sample
  (eq. 3.8, 3.10); here ``b`` is an acceleration (m/s^2) so that its noise does not depend on
  the sample rate: ``b_thesis = T b``, otherwise identical. The thesis' Jacobian (eq. 3.13)
  appends a 1 on the diagonal with zeros elsewhere; that drops ``d omega_{k+1} / d b = T / r``,
  which would leave ``b`` unobservable (its cross-covariance with omega would stay 0). The exact
  derivative is used here.
* the mode / change detector (thesis 3.3, eq. 3.14): ``ubar`` = mean of the last 20 ``u``;
  if ``|ubar| < mu_vib = 0.20 m/s^2`` the vibration measurement update is made and ``u = 0``
  in the time update (thesis), otherwise the time update integrates ``u`` and the vibration
  update is skipped. On the sample where acceleration mode switches on, the boost of eq. 3.15,
  ``omega += 20 T ubar / r``, adds the speed gained while the window filled.
  ``aid_always=True`` is a variant (not the thesis'): ``u`` is integrated in both modes, so the
  vibration updates make ``b`` the real accelerometer bias; the boost is then off (nothing was
  missed).
* standstill (thesis 3.1, eq. 3.4-3.6): when the window test (N = 20, mu = 0.019 m/s^2 on the
  pre-filtered vibration signal, :func:`vibrospeed.signal.detectors.window_test`) or the CUSUM
  test on the EKF residual (4.2.3, :func:`vibrospeed.signal.detectors.standstill_eps`) says the
  vehicle stands still, a virtual measurement ``omega = 0`` with variance ``R_ss = 1`` is made
  (not in acceleration mode: there the integration is trusted).
* optional reference-speed fixes (thesis 4.2.4; :mod:`vibrospeed.signal.reference`): a measurement
  ``omega = v_ref / r`` with variance ``(sigma_v / r)^2`` on the samples where one exists.
* line gate (not in the thesis; for recordings without a usable wheel line): the share of the
  running power of the EKF input explained by the tracked harmonics, ``sum_m |a_m|^2 / 2``
  over an exponential mean of ``y^2`` (time constant ``line_tau``), is computed from the prior
  before each vibration update and averaged over the same time constant. Below ``line_min``
  the update still runs for the phasor states
  but with the gains on omega and b set to 0 (Joseph form, valid for any gain): the vibrations
  then claim nothing about the speed, omega follows the aiding and the fixes, and its variance
  grows with the random walk -- the band widens instead of showing a precision the data do not
  have. If omega meets a real line again, the phasors grow at that rotation and the gate opens.
  While closed, the phasors run as a plain Kalman filter at the current omega (cross
  covariances with omega and b dropped, no omega term in their time-update Jacobian), so their
  bandwidth stays that of q_amp / r.
  The gate stays closed until ``line_tau`` s of samples are in the running power.
  ``line_min = 0`` (default) is the thesis' filter.
* broadband standstill (``standstill='broadband'``, the default of :func:`estimate`; not the
  thesis'): a per-sample flag computed before the loop by
  :mod:`vibrospeed.signal.standstill` on the vibration axis (whole log offline, causal with
  ``causal=True``) and passed in as the input ``still``; standing samples get the omega = 0
  measurement and are never in acceleration mode. The thesis' window test (absolute
  mu = 0.019 m/s^2) and the CUSUM (absolute sigma 0.015 m/s^2) read a signal whose level varies
  100x across vehicles and sensors; the broadband level is compared with the log's own floor.
* comb check (the input ``comb``, :func:`comb_fixes`; not the thesis'): the speed of the
  strongest harmonic comb in the last 3 s. When ``comb_count`` steady candidates in a row
  (outside acceleration mode) disagree with omega by more than ``comb_rel``, omega is measured
  as the candidate: the acquisition after a start and the way out of a lock on half (or twice)
  the wheel speed. :func:`estimate` also removes the accelerometer's offset (mean of ``u``
  while standing: gravity through a tilted mount, bias) before the mode detector reads it.
* ``init_ref``: omega is unknown until the first reference fix or standstill measurement (start
  with a large ``p0_omega``); until then vibration updates do not touch omega, so the first fix
  sets it (a Kalman update from a prior of variance ``p0_omega``).

Conventions as in :mod:`vibrospeed.estimators.ekf`: the stored state is the prior for the next
sample; ``step`` updates with sample k, returns the posterior at ``t_k`` and predicts to
``t_{k+1}``; NaN inputs skip what needs them. ``run`` equals repeated ``step`` exactly.

Wrapping other trackers: the aiding acts through three hooks, all on omega only -- the time
update's shift ``(T / r)(u + b)``, the boost, and scalar omega measurements (standstill,
reference fixes). A grid tracker (the RBPMF of :mod:`vibrospeed.estimators.rbpmf`) gains the
same aiding by shifting its grid posterior by ``(T / r)(u + b)`` per sample and multiplying the
grid weights by the omega likelihoods; :func:`omega_shift` computes the shift such a wrapper
applies (benchmarks/aided/RESULTS.md).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import config_from_params, parse_flag
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.aiding import (  # noqa: F401 (re-exported: the aided API)
    BROADBAND_LO,
    Sample,
    _channel,
    aiding_inputs,
    input_arrays,
    running_gain,
    running_mean,
    standstill_band,
    standstill_flags,
    standstill_offset,
)
from vibrospeed.estimators.ekf import harmonic_update, rotate_phasors, symmetrize_into
from vibrospeed.estimators.kalman import joseph_update
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal import detectors as det
from vibrospeed.signal.comb import (  # noqa: F401  (comb_fixes, COMB_*: re-exported)
    COMB_COUNT,
    COMB_DECAY,
    COMB_FRAME_S,
    COMB_HOP_S,
    COMB_M,
    COMB_OMEGA_MIN,
    COMB_REL,
    comb_candidates,
    comb_fixes,
    comb_vote,
    restart_phasors,
)
from vibrospeed.signal.detectors import _cusum_core, _mode_core, _window_core
from vibrospeed.types import Estimate, Recording, Track

STANDSTILL_KINDS = {"none": 0, "window": 1, "cusum": 2, "broadband": 3}

#: vibration tracker of :func:`estimate` when ``params`` names none: the thesis' aided EKF.
#: ``tracker=grid`` scores like ``-m grid`` on the randomised family (the EKF below a tenth of
#: that), but offline its result *is* the grid tracker's estimate (nothing aided) and on the
#: thesis' cart its RMSE is ~4x the EKF's (benchmarks/robustness/AIDED.md)
DEFAULT_TRACKER = "ekf"


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
        samples at 100 Hz = 0.2 s, 0.019); ``ss_n`` (samples) overrides the length when set.
        In seconds, so a 400 Hz log looks at the same 0.2 s: 20 samples there (0.05 s) read a
        slow wheel's vibration as flat, i.e. standstill while driving.
    r_ss : variance of the virtual standstill measurement omega = 0 (thesis: 1).
    cusum_sigma : residual level (m/s^2) separating quiet from moving; cusum_nu, cusum_h :
        drift and threshold of the CUSUM on ``eps = 1 - (e / sigma)^2``; the standstill flag is
        held for :func:`vibrospeed.signal.detectors.cusum_hold` samples after an alarm.
    cusum_fs : Hz, the sample rate at which ``cusum_h`` holds (the thesis' 100 Hz); a log at fs
        uses the threshold ``cusum_h fs / cusum_fs`` (:attr:`cusum_threshold`) and so the same
        detection delay and hold in seconds (a per-sample threshold at 400 Hz alarms within
        0.05 s of quiet residuals while driving). None: per sample, as written in the thesis.
    mode_window, mode_mu : window length (s) and threshold (m/s^2) of the mode detector
        (0.2 s = the thesis' 20 samples at 100 Hz, 0.20); ``mode_n`` (samples) overrides.
    boost : apply the boost of eq. 3.15 (``N_mode`` T ubar / r) when acceleration mode starts.
    aid_always : integrate u in vibration mode too (variant, see the module docstring).
    omega_max : upper clip (rad/s); None: 0.98 pi fs / M.
    line_min : gate on the explained power share (see the module docstring; 0 = off).
    line_tau : time constant (s) of the running power of the EKF input for the gate.
    line_omega_min : with the gate on, omega below this (rad/s) never opens it: a phasor
        rotating slowly tracks the low-frequency content left by the high-pass (turns, body
        sway) and would "explain" it, pinning omega near 0 (seen on the Hungary drives).
    init_ref : omega unknown until the first fix / standstill measurement (module docstring).
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
        if not (self.wheel_radius and self.wheel_radius > 0):
            raise ParameterError(f"wheel_radius must be > 0 m, got {self.wheel_radius}")
        if self.standstill not in STANDSTILL_KINDS:
            raise ParameterError(f"standstill must be one of {', '.join(STANDSTILL_KINDS)}, "
                                 f"got '{self.standstill}'")
        for name in ("p0_omega", "p0_bias", "r_ss", "ss_mu", "mode_mu", "cusum_sigma",
                     "cusum_h"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.line_min < 1:
            raise ParameterError(f"line_min must be in [0, 1), got {self.line_min}")
        if not self.line_tau > 0:
            raise ParameterError(f"line_tau must be > 0 s, got {self.line_tau}")
        if int(self.comb_count) != self.comb_count or self.comb_count < 1:
            raise ParameterError(f"comb_count must be a positive integer, got {self.comb_count}")
        if not self.comb_rel > 0:
            raise ParameterError(f"comb_rel must be > 0, got {self.comb_rel}")
        for name in ("q_bias", "omega0"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.q_omega_accel is not None and not self.q_omega_accel >= 0:
            raise ParameterError(f"q_omega_accel must be >= 0, got {self.q_omega_accel}")
        for name in ("ss_n", "mode_n"):
            v = getattr(self, name)
            if v is not None and (int(v) != v or v < 1):
                raise ParameterError(f"{name} must be a positive integer, got {v}")
        if self.cusum_fs is not None and not self.cusum_fs > 0:
            raise ParameterError(f"cusum_fs must be > 0 Hz (or None), got {self.cusum_fs}")
        for name in ("ss_window", "mode_window"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0 s, got {getattr(self, name)}")

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


class State(NamedTuple):
    """Prior for the next sample plus the detectors' states.

    x (2+2M,) ``[omega, alpha_1, beta_1, ..., b]``, P (2+2M, 2+2M), window / cusum / mode:
    detector states (:mod:`vibrospeed.signal.detectors`); line (6,): [running mean of the
    EKF input's square, samples in it, 1.0 once omega is known (``init_ref``), running mean
    of the explained share, comb candidates in a row disagreeing with omega, last candidate].
    """

    x: np.ndarray
    P: np.ndarray
    window: det.WindowState
    cusum: det.CusumState
    mode: det.ModeState
    line: np.ndarray


#: extras of :func:`step`'s :class:`~vibrospeed.types.Estimate`: bias (m/s^2, estimated b
#: added to a_x), acceleration / boost modes, ubar (m/s^2, mean of the last ``mode_n`` a_x),
#: the vibration innovation (EKF units; NaN without a vibration update) and its variance, the
#: explained power share of the prior (the gate's statistic), whether the vibration update
#: was allowed to move omega, amplitudes (M,)
ESTIMATE_EXTRAS = ("bias", "accelerating", "boost", "ubar", "innovation", "innovation_var",
                   "line_share", "locked", "amplitudes")


N_OUT = 11  # omega, std, bias, ss, acc, boost, ubar, innov, innov var, share, locked; then amps


def init(config: Config) -> State:
    """Prior at the first sample and empty detectors."""
    m = config.model
    n = config.n_state
    x = np.full(n, float(config.amp0))
    x[0] = config.omega0
    x[-1] = 0.0
    P = np.eye(n) * m.p0_amp
    P[0, 0] = config.p0_omega
    P[-1, -1] = config.p0_bias
    line = np.array([0.0, 0.0, 0.0 if config.init_ref else 1.0, 0.0, 0.0, 0.0])
    return State(x, P, det.window_init(config.ss_len), det.cusum_init(),
                 det.mode_init(config.mode_len), line)


# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _scalar_update(x, P, j, z, r):
    """Update with the scalar measurement ``z = x[j] + e``, var(e) = r (Joseph form)."""
    s = P[j, j] + r
    k = P[:, j] / s
    joseph_update(x, P, k, z - x[j], r, j, 1, 1)


@njit(cache=True)
def _vib_update(x, P, y, M, r, lock):
    """Vibration update ``y = sum_m alpha_m + e`` (thesis eq. 2.23, 2.26); -> (innov, S).
    ``lock`` False: the gains on omega (index 0) and b (last) are 0 (line gate)."""
    return harmonic_update(x, P, y, M, r, not lock, not lock)


@njit(cache=True)
def _aided_step(x, P, y, u, gain, ref, ref_var, still, comb, wbuf, wpc, wflag, cgs, mbuf, mpc,
                mflag, line, M, ss_kind, boost_n, flags, fp, out):
    """One sample in place. ``still``: the external standstill flag (> 0.5 standing; read with
    ``ss_kind`` 3); ``comb``: the comb's omega candidate (NaN: none this sample), a fix when
    omega has disagreed with it by more than ``fp[18]`` (relative) ``fp[17]`` candidates in a
    row. ``flags`` int: [boost_on, aid_always, cusum_hold];
    ``fp``: [T, q_om, q_om_acc, q_amp, r, r_wheel, q_b, om_max, ss_mu, r_ss, c_sigma, c_nu,
    c_h, mode_mu, line_min, line_tau, line_omega_min]; ``line`` [power, count, known]."""
    T = fp[0]
    q_om = fp[1]
    q_om_acc = fp[2]
    q_amp = fp[3]
    r = fp[4]
    rw = fp[5]
    q_b = fp[6]
    om_max = fp[7]
    n = x.size
    nb = n - 1
    # ---- detectors -----------------------------------------------------------------------
    acc, boost, ubar = _mode_core(mbuf, mpc, mflag, u, fp[13])
    ss = False
    if ss_kind == 1:
        ss = _window_core(wbuf, wpc, wflag, y, fp[8])
    ext = ss_kind == 3 and still > 0.5  # NaN: no decision, moving
    if ext:
        # a vehicle whose broadband vibration sits at its floor stands: what the mode detector
        # reads then is the accelerometer's offset, not a speed change
        ss = True
        acc = False
        boost = False
    # ---- boost (thesis eq. 3.15) -------------------------------------------------------------
    if boost and flags[0] == 1:
        x[0] += boost_n * T * ubar / rw
    # ---- vibration measurement update (only in vibration mode) -----------------------------
    innov = np.nan
    s_var = np.nan
    share = np.nan
    lock = False
    if np.isfinite(y) and np.isfinite(gain):
        yg = y * gain
        line[1] += 1.0
        a_pw = max(T / fp[15], 1.0 / line[1])
        line[0] += a_pw * (yg * yg - line[0])
        expl = 0.0
        for m in range(M):
            expl += 0.5 * (x[1 + 2 * m] ** 2 + x[2 + 2 * m] ** 2)
        inst = expl / line[0] if line[0] > 0.0 else 0.0
        line[3] += a_pw * (inst - line[3])
        share = line[3]
        lock = line[2] > 0.5 and (fp[14] <= 0.0 or (share >= fp[14] and x[0] >= fp[16]
                                                     and line[1] * T >= fp[15]))
        if not acc:
            innov, s_var = _vib_update(x, P, yg, M, r, lock)
    if not lock and fp[14] > 0.0:
        # gate closed: the phasors are a plain Kalman filter at the current omega (no cross
        # covariance with omega, and omega's growing variance is not fed into their phase in
        # the time update); otherwise their bandwidth widens with var(omega) and they would
        # "explain" any noise, opening the gate
        for i in range(1, n - 1):
            P[0, i] = 0.0
            P[i, 0] = 0.0
            P[n - 1, i] = 0.0
            P[i, n - 1] = 0.0
    if ss_kind == 2:
        eps = np.nan
        if np.isfinite(innov) and gain > 0.0:
            e = innov / gain / fp[10]
            eps = 1.0 - e * e
        _cusum_core(cgs, eps, fp[11], fp[12])
        ss = cgs[1] <= flags[2]
    # ---- virtual standstill measurement omega = 0 (thesis eq. 3.4-3.6) ----------------------
    ss = ss and not acc  # a vehicle in acceleration mode is not standing still (thesis tests)
    if ss:
        _scalar_update(x, P, 0, 0.0, fp[9])
        line[2] = 1.0
    # ---- comb check: re-lock where omega has left the wheel's comb ---------------------------
    if np.isfinite(comb) and comb > 0.0 and not ss:
        # a candidate counts when it is steady (agrees with the previous one) and the vehicle
        # is not in acceleration mode (a 3 s frame lags a speed change)
        _, reset = comb_vote(line[4:6], comb, x[0], fp[18], fp[17], not acc)
        if reset:
            # the phasors belong to the old rotation (at half the wheel speed the line sits
            # in phasor 2 and would pull omega back): they restart, uncorrelated
            restart_phasors(x, P, 1, n - 1, fp[19])
            _scalar_update(x, P, 0, comb, (0.5 * fp[18] * comb) ** 2)
            line[2] = 1.0
    # ---- reference-speed fix (thesis 4.2.4) ------------------------------------------------
    if np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0.0:
        _scalar_update(x, P, 0, ref, ref_var)
        line[2] = 1.0
    # omega >= 0: clipped at 0 (with a_x aiding the direction is known; the EKF's mirror
    # symmetry (omega, beta) -> (-omega, -beta) would turn an overshoot below 0 into a speed)
    if x[0] < 0.0:
        x[0] = 0.0
    if x[0] > om_max:
        x[0] = om_max
    # ---- outputs -----------------------------------------------------------------------------
    out[0] = x[0]
    out[1] = np.sqrt(max(P[0, 0], 0.0))
    out[2] = x[nb]
    out[3] = 1.0 if ss else 0.0
    out[4] = 1.0 if acc else 0.0
    out[5] = 1.0 if (boost and flags[0] == 1) else 0.0
    out[6] = ubar
    out[7] = innov
    out[8] = s_var
    out[9] = share
    out[10] = 1.0 if (lock and not acc and np.isfinite(innov)) else 0.0
    for m in range(M):
        a = x[1 + 2 * m]
        b = x[2 + 2 * m]
        out[N_OUT + m] = np.sqrt(a * a + b * b)
    # ---- time update (thesis eq. 3.10-3.12) --------------------------------------------------
    ue = 0.0
    if (acc or flags[1] == 1) and np.isfinite(u):
        ue = u
    om = x[0]
    F = np.eye(n)
    xn = x.copy()
    rotate_phasors(x, xn, F, M, T, lock or fp[14] <= 0.0)
    xn[0] = om + T * (x[nb] + ue) / rw
    F[0, nb] = T / rw
    for i in range(n):
        x[i] = xn[i]
    Pn = F @ P @ F.T
    Pn[0, 0] += T * (q_om_acc if acc else q_om)
    for i in range(1, nb):
        Pn[i, i] += T * q_amp
    Pn[nb, nb] += T * q_b
    symmetrize_into(Pn, P)


@njit(cache=True)
def _aided_run(ys, us, gains, refs, ref_vars, stills, combs, x, P, wbuf, wpc, wflag, cgs, mbuf,
               mpc, mflag, line, M, ss_kind, boost_n, flags, fp):
    n_s = ys.size
    outs = np.empty((n_s, N_OUT + M))
    out = np.empty(N_OUT + M)
    for k in range(n_s):
        _aided_step(x, P, ys[k], us[k], gains[k], refs[k], ref_vars[k], stills[k], combs[k],
                    wbuf, wpc,
                    wflag, cgs, mbuf, mpc, mflag, line, M, ss_kind, boost_n, flags, fp, out)
        outs[k] = out
    return outs


def _args(config: Config) -> tuple:
    m = config.model
    q_acc = m.q_omega if config.q_omega_accel is None else config.q_omega_accel
    fp = np.array([m.dt, m.q_omega, q_acc, m.q_amp, m.r, config.wheel_radius, config.q_bias,
                   config.omega_limit, config.ss_mu, config.r_ss, config.cusum_sigma,
                   config.cusum_nu, config.cusum_threshold, config.mode_mu, config.line_min,
                   config.line_tau, config.line_omega_min, config.comb_count,
                   config.comb_rel, m.p0_amp])
    boost_on = 1 if (config.boost and not config.aid_always) else 0
    flags = np.array([boost_on, 1 if config.aid_always else 0,
                      det.cusum_hold(config.cusum_threshold, config.cusum_nu)], dtype=np.int64)
    return (m.M, STANDSTILL_KINDS[config.standstill], float(config.mode_len), flags, fp)


def _unpack(state: State) -> list:
    return [state.x.copy(), state.P.copy(), state.window.buf.copy(),
            state.window.pos_count.copy(), state.window.flag.copy(),
            np.array([state.cusum.g, state.cusum.since]), state.mode.buf.copy(),
            state.mode.pos_count.copy(), state.mode.flag.copy(), state.line.copy()]


def _pack(a: list) -> State:
    return State(a[0], a[1], det.WindowState(a[2], a[3], a[4]),
                 det.CusumState(float(a[5][0]), float(a[5][1])), det.ModeState(a[6], a[7], a[8]),
                 a[9])


def step(
    config: Config,
    state: State,
    y: float | Sample,
    u: float = np.nan,
    *,
    gain: float = 1.0,
    ref: float = np.nan,
    ref_var: float = np.nan,
    still: float = np.nan,
    comb: float = np.nan,
) -> tuple[State, Estimate]:
    """Process one sample: a :class:`~vibrospeed.estimators.aiding.Sample` of the inputs
    below, or ``y`` and the others as arguments.

    y : pre-filtered vibration sample in m/s^2 (the standstill tests read it in these units).
    u : longitudinal acceleration a_x in m/s^2 (NaN: no aiding on this sample).
    gain : factor applied to ``y`` before the EKF update (running-RMS normalisation; 1 = off).
    ref, ref_var : an omega fix (rad/s) and its variance ((rad/s)^2); NaN: none.
    still : the standstill decision for this sample (1 standing, 0 or NaN moving), read with
        ``standstill='broadband'`` (:func:`standstill_flags` computes it).
    comb : the harmonic comb's omega candidate (rad/s; NaN: none), :func:`comb_fixes`; after
        ``comb_count`` candidates in a row that disagree with omega by more than ``comb_rel``
        of the candidate, omega is measured as the candidate (std ``comb_rel / 2`` of it).
    """
    if isinstance(y, Sample):
        y, u, gain, ref, ref_var, still, comb = y
    a = _unpack(state)
    out = np.empty(N_OUT + config.model.M)
    _aided_step(a[0], a[1], float(y), float(u), float(gain), float(ref), float(ref_var),
                float(still), float(comb), *a[2:], *_args(config), out)
    return _pack(a), _estimate(out)


def _estimate(o: np.ndarray) -> Estimate:
    extras = dict(zip(ESTIMATE_EXTRAS, (
        float(o[2]), bool(o[4]), bool(o[5]), float(o[6]), float(o[7]), float(o[8]),
        float(o[9]), bool(o[10] > 0.5), o[N_OUT:].copy()), strict=True))
    return Estimate(float(o[0]), float(o[1]), standstill=float(bool(o[3])), extras=extras)


class Result(NamedTuple):
    """Batch output over samples: the columns of :func:`step`'s estimates."""

    omega: np.ndarray  # (n,) rad/s
    omega_std: np.ndarray  # (n,) rad/s
    bias: np.ndarray  # (n,) m/s^2
    standstill: np.ndarray  # (n,) bool
    accelerating: np.ndarray  # (n,) bool
    boost: np.ndarray  # (n,) bool
    ubar: np.ndarray  # (n,) m/s^2
    innovation: np.ndarray  # (n,)
    innovation_var: np.ndarray  # (n,)
    line_share: np.ndarray  # (n,)
    locked: np.ndarray  # (n,) bool
    amplitudes: np.ndarray  # (n, M)
    final: State


def run(
    config: Config,
    y: np.ndarray | Sample,
    u: np.ndarray | None = None,
    *,
    gain: np.ndarray | None = None,
    ref: np.ndarray | None = None,
    ref_var: np.ndarray | None = None,
    still: np.ndarray | None = None,
    comb: np.ndarray | None = None,
    state: State | None = None,
) -> Result:
    """Run over whole signals (see :func:`step` for the inputs; ``y`` may be a
    :class:`~vibrospeed.estimators.aiding.Sample` of arrays); identical to repeated step."""
    if isinstance(y, Sample):  # scalars (the defaults) hold for every sample
        n = np.size(y.y)
        y, u, gain, ref, ref_var, still, comb = (
            np.full(n, v, dtype=np.float64) if np.ndim(v) == 0 else v for v in y)
    y = np.ascontiguousarray(y, dtype=np.float64)
    n = y.size
    u, gain, ref, ref_var = input_arrays(n, u, gain, ref, ref_var)
    extra = []
    for name, v in (("still", still), ("comb", comb)):
        v = np.full(n, np.nan) if v is None else np.ascontiguousarray(v, dtype=np.float64)
        if v.shape != (n,):
            raise InputError(f"aided.run: '{name}' has shape {v.shape}, expected ({n},) like y")
        extra.append(v)
    a = _unpack(init(config) if state is None else state)
    o = _aided_run(y, u, gain, ref, ref_var, *extra, *a, *_args(config))
    return Result(o[:, 0], o[:, 1], o[:, 2], o[:, 3] > 0.5, o[:, 4] > 0.5, o[:, 5] > 0.5,
                  o[:, 6], o[:, 7], o[:, 8], o[:, 9], o[:, 10] > 0.5, o[:, N_OUT:], _pack(a))



# ---------------------------------------------------------------------------------------------
def omega_shift(config: Config, u: float, bias: float, accelerating: bool) -> float:
    """Omega increment (rad/s) the aiding adds in one time update: ``(T / r)(u_eff + b)``.

    ``u_eff`` is ``u`` in acceleration mode (or always with ``aid_always``), else 0. A grid
    tracker wrapped by the aiding shifts its posterior over omega by this amount per sample.
    """
    ue = u if (accelerating or config.aid_always) and np.isfinite(u) else 0.0
    return config.model.dt * (ue + bias) / config.wheel_radius


# ---------------------------------------------------------------------------------------------
def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Aided tracking of omega from vibration axis ``axis`` and longitudinal acceleration.

    ``params``: any :class:`Config` field; any :class:`HarmonicModel` field (``dt`` comes from
    the data); ``accel_axis`` (default ``ax``; ``y``/``ay``, a leading ``-`` negates, e.g.
    ``-ay``); ``prefilter`` (default ``thesis-hplp``, low-pass cut-off per M) and ``lp_cutoff``
    (rad/s); ``normalize_tau`` (s, running-RMS normalisation of the EKF input; default 0 = off,
    then the model is in m/s^2 units as in the thesis); ``reference`` ('none', 'bump', 'turn',
    'both': speed fixes from :mod:`vibrospeed.signal.reference` fed as measurements) and
    ``wheelbase`` (m, for bump fixes); ``accel_detrend`` (s; subtract a causal running mean of
    a_x with this time constant, for a tilted phone whose a_x carries a large gravity offset that
    would hold the mode detector in acceleration mode; default 0 = off, as in the thesis).
    ``tracker``: 'ekf' (default, :data:`DEFAULT_TRACKER`: the thesis' aided EKF, this
    function; ``--preset paper`` with the thesis' tests), 'grid' (the grid product's filter, its
    smoothed estimate offline or where the mount of the phone is not known well enough to aid
    it, see :func:`vibrospeed.estimators.aided_grid.estimate`) or 'rbpmf' (the aiding around
    the paper's grid filter on the thesis cart's grid); the grid trackers go to
    :func:`vibrospeed.estimators.aided_grid.estimate`. The parameters below are the EKF's.

    Defaults not in the thesis (measured in benchmarks/aided/RESULTS.md):
    ``standstill='broadband'`` (the
    broadband-level detector on the vibration axis, whole-log; ``causal=True`` for the causal
    detector, as a device would run it; 'window' / 'cusum' are the thesis' tests);
    ``accel_offset='standstill'`` (the mean of a_x while standing is removed from it; 'none'
    keeps a_x as it is); ``comb`` (default True: the comb check of :func:`comb_fixes` with
    ``comb_clarity`` 3) over ``omega_min`` (rad/s, default 2 pi) .. ``omega_max``.

    The wheel radius comes from ``wheel_radius`` or ``recording.wheel_radius``.
    """
    from vibrospeed.estimators.common import axis_channel, check_uniform, split_params, start_level
    from vibrospeed.io.timebase import check_nyquist
    from vibrospeed.signal import prefilter as pf

    params = dict(params or {})
    tracker = str(params.pop("tracker", DEFAULT_TRACKER))
    if tracker in ("rbpmf", "grid"):
        from vibrospeed.estimators import aided_grid

        return aided_grid.estimate(recording, axis=axis, wheel_radius=wheel_radius,
                                   params=params, progress=progress, kind=tracker)
    if tracker != "ekf":
        raise ParameterError(f"tracker must be 'ekf', 'rbpmf' or 'grid', got '{tracker}'")
    del progress  # one compiled pass; nothing to report
    r = wheel_radius or recording.wheel_radius
    if not r:
        raise ParameterError(
            f"{recording.source or 'recording'}: the aided tracker needs the wheel radius "
            "(pass wheel_radius=... / --wheel-radius, or use a recording that knows it)"
        )
    params = dict(params or {})
    model_kw, cfg_kw = split_params(HarmonicModel, params)
    model_kw.pop("dt", None)
    accel_axis = str(cfg_kw.pop("accel_axis", "ax"))
    pre = str(cfg_kw.pop("prefilter", "thesis-hplp"))
    lp = cfg_kw.pop("lp_cutoff", None)
    lp = None if lp in (None, "", "none") else float(lp)
    tau = float(cfg_kw.pop("normalize_tau", 0.0))
    reference = str(cfg_kw.pop("reference", "none"))
    wheelbase = cfg_kw.pop("wheelbase", None)
    detrend = float(cfg_kw.pop("accel_detrend", 0.0))
    causal = parse_flag(cfg_kw.pop("causal", False), "causal")
    offset_kind = str(cfg_kw.pop("accel_offset", "standstill"))
    if offset_kind not in ("standstill", "none"):
        raise ParameterError(f"accel_offset must be 'standstill' or 'none', got '{offset_kind}'")
    om_min = cfg_kw.pop("omega_min", None)
    om_min = None if om_min in (None, "", "none") else float(om_min)
    cfg_kw.setdefault("standstill", "broadband")
    cfg_kw_comb = cfg_kw.pop("comb", True)
    comb_clarity = float(cfg_kw.pop("comb_clarity", 3.0))
    dt = check_uniform(recording)
    defaults = _thesis_model().to_dict()
    if tau > 0:  # unit-power signal: the EKF's defaults for normalised input
        from vibrospeed.estimators.ekf import UNIT_RMS_MODEL

        defaults.update(UNIT_RMS_MODEL)
        defaults.update(M=2, q_omega=0.5)
    defaults["dt"] = dt
    model = config_from_params(HarmonicModel, model_kw, **defaults)
    config = config_from_params(Config, cfg_kw, model=model, wheel_radius=float(r))
    src = recording.source or "recording"
    nyq_note = None
    if config.omega_max is not None and om_min is not None \
            and model.M * config.omega_max >= np.pi / dt:
        # a search range given with omega_min (as to the grid trackers): its top is clipped to
        # what the sample rate allows instead of refused
        nyq_note = (f"omega_max {config.omega_max:g} rad/s above what {1 / dt:g} Hz allows for "
                    f"M = {model.M}: clipped to {model.omega_clip(None):.4g} rad/s")
        config = dataclasses.replace(config, omega_max=None)
    if config.omega_max is not None:
        check_nyquist(1.0 / dt, model.M, config.omega_max, src)
    vib_name = axis_channel(axis)
    recording.require(vib_name)
    x = recording.channel(vib_name)
    rng = None
    if pre == "range":
        if om_min is None or config.omega_max is None:
            raise ParameterError("pre-filter 'range' needs omega_min and omega_max")
        rng = (om_min, config.omega_max)
    sos = pf.design(pre, 1.0 / dt, M=model.M, lp_cutoff=lp, omega_range=rng)
    y = pf.apply(sos, x, level=start_level(x, dt))
    u, ref, ref_var, more = aiding_inputs(recording, dt, float(r), accel_axis=accel_axis,
                                          detrend=detrend, reference=reference,
                                          wheelbase=wheelbase)
    still = None
    notes = [f"pre-filter '{pre}' on '{vib_name}' at fs = {1 / dt:.4g} Hz"]
    if config.standstill == "broadband":
        band = standstill_band(dt, model.M, om_min, config.omega_max)
        # the vibration axis and every other accelerometer axis (as the grid tracker does)
        chans = [vib_name] + [c for c in ("ax", "ay", "az") if c != vib_name and c in recording
                              and np.isfinite(recording.channel(c)).any()]
        X = np.column_stack([recording.channel(c) for c in chans])
        still = standstill_flags(X, dt, band, causal=causal)
        notes.append(f"standstill: broadband vibration level at its floor "
                     f"({'causal' if causal else 'whole-log'} detector, band "
                     f"{band[0]:.3g}-{band[1]:.3g} rad/s), on {100 * still.mean():.1f} % of "
                     "the samples")
    else:
        notes.append(f"standstill test '{config.standstill}'")
    notes += more
    if nyq_note:
        notes.append(nyq_note)
    comb = parse_flag(cfg_kw_comb, "comb")
    c_om = None
    if comb:
        c_om, c_rng = comb_candidates(x, dt, om_min, config.omega_limit, still=still,
                                      clarity=comb_clarity)
        notes.append(f"comb check: {np.isfinite(c_om).sum()} candidates from the harmonic comb "
                     f"({COMB_FRAME_S:g} s frames every {COMB_HOP_S:g} s, clarity >= "
                     f"{comb_clarity:g}, range {c_rng[0]:.3g}-{c_rng[1]:.3g} rad/s); omega is "
                     f"reset to it after {config.comb_count} disagreeing by > "
                     f"{100 * config.comb_rel:g} % in a row")
    if offset_kind == "standstill":
        flags = still if still is not None else np.zeros(u.size)
        off = standstill_offset(u, flags, causal=causal)
        u = u - off
        notes.append(f"'{accel_axis}' offset removed: its mean while standing "
                     f"({'running' if causal else 'whole log'}; {off[-1]:.3g} m/s^2 at the end)")
    gain = None
    if tau > 0:
        gain = running_gain(y, dt, tau)
        notes.append(f"EKF input normalised by a running RMS (tau = {tau:g} s)")
    res = run(config, y, u, gain=gain, ref=ref, ref_var=ref_var, still=still, comb=c_om)
    extras = {f"amp{m + 1}": res.amplitudes[:, m] for m in range(model.M)}
    extras.update(
        standstill=res.standstill.astype(np.float64),
        accelerating=res.accelerating.astype(np.float64),
        boost=res.boost.astype(np.float64),
        bias=res.bias,
        ubar=res.ubar,
        nis=res.innovation**2 / res.innovation_var,
        line_share=res.line_share,
        locked=res.locked.astype(np.float64),
    )
    out_params = {**model.to_dict(), **{k: getattr(config, k) for k in (
        "omega0", "p0_omega", "amp0", "q_bias", "p0_bias", "q_omega_accel", "standstill",
        "ss_window", "ss_mu", "r_ss", "cusum_sigma", "cusum_nu", "cusum_h", "cusum_fs",
        "mode_window", "mode_mu", "boost", "aid_always", "line_min", "line_tau",
        "line_omega_min", "init_ref")},
        "ss_n": config.ss_len, "mode_n": config.mode_len,
        "omega_max": config.omega_limit, "wheel_radius": float(r),
        "prefilter": pre, "lp_cutoff": lp, "normalize_tau": tau, "accel_detrend": detrend,
        "accel_offset": offset_kind, "causal": causal, "omega_min": om_min,
        "axis": axis,
        "accel_axis": accel_axis, "reference": reference, "tracker": "ekf"}
    return Track.from_omega(recording.t, res.omega, res.omega_std, wheel_radius=float(r),
                            method="aided", params=out_params, extras=extras, notes=notes)
