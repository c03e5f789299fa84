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

``-m aided`` runs the grid tracker aided (``tracker=grid``, :data:`DEFAULT_TRACKER`:
:mod:`vibrospeed.estimators.aided_grid`, offline its aided smoother) unless ``tracker=ekf``
(``--preset paper``) asks for this EKF.

The aided EKF is a package, one concern per module, each importing only the ones above it:

==========  ===============================================================================
``config``  the tracker's :class:`Config` (the thesis' model, detectors, gate, comb check)
``core``    the compiled per-sample update and loop (numba)
``filter``  ``State``, ``init``, ``step``, ``run``, :func:`omega_shift` (the hook a wrapped
            tracker uses)
``method``  a recording in, a Track out (:func:`estimate`): pre-filter, aiding inputs,
            broadband standstill, comb candidates, ``tracker=grid`` / ``rbpmf`` dispatch
==========  ===============================================================================

The package's namespace is the aided method, as the one module it was: the names above plus
the aiding inputs of :mod:`vibrospeed.estimators.aiding` and the comb check of
:mod:`vibrospeed.signal.comb`, re-exported.
"""

from vibrospeed.estimators.aided.config import STANDSTILL_KINDS, Config, _thesis_model
from vibrospeed.estimators.aided.core import N_OUT
from vibrospeed.estimators.aided.filter import (
    ESTIMATE_EXTRAS,
    Result,
    State,
    init,
    omega_shift,
    run,
    step,
)
from vibrospeed.estimators.aided.method import DEFAULT_TRACKER, estimate
from vibrospeed.estimators.aiding import (
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
from vibrospeed.signal.comb import (
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

__all__ = [
    "BROADBAND_LO",
    "COMB_COUNT",
    "COMB_DECAY",
    "COMB_FRAME_S",
    "COMB_HOP_S",
    "COMB_M",
    "COMB_OMEGA_MIN",
    "COMB_REL",
    "DEFAULT_TRACKER",
    "ESTIMATE_EXTRAS",
    "N_OUT",
    "STANDSTILL_KINDS",
    "Config",
    "Result",
    "Sample",
    "State",
    "aiding_inputs",
    "comb_candidates",
    "comb_fixes",
    "comb_vote",
    "estimate",
    "init",
    "input_arrays",
    "omega_shift",
    "restart_phasors",
    "run",
    "running_gain",
    "running_mean",
    "standstill_band",
    "standstill_flags",
    "standstill_offset",
    "step",
    "_channel",
    "_thesis_model",
]
