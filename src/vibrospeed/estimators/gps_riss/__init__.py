"""GPS + single-accelerometer Kalman fusion, "GPS/RISS" (METHODS.md section 3; O'Kane & Ringwood,
sections IV-VI, eq. 1-18), with the accelerometer offset as a filter state and a GPS delay.

State ``X = [v, a, b, x3, x4, d..., dl]``: speed (m/s), acceleration (m/s^2), accelerometer
offset b (m/s^2; road slope ``g sin theta`` plus calibration bias), the receiver's reported speed
x3 and its derivative x4 (paper eq. 2), the Pade states of an optional pure GPS delay
(:func:`~vibrospeed.models.gps_riss.receiver_matrices`) and the receiver's extra lag dl (s,
beyond the lag model's; a random walk ``q_gps_lag`` from ``0 +- gps_lag_std``, the fix read as
``g = x3(t - dl) ~ x3 - dl x3'``: why and how, :class:`GpsFields`). Per accelerometer sample,
``dt`` the time since the previous one:

1. accelerometer pre-processing (paper Fig. 1): ``a_m = gain * a_raw``; optional pitch
   compensation ``p = poly(a_m)`` in degrees (eq. 14), ``a_m <- (a_m - g sin p) / cos p``.
2. predict with the exact transition ``F = expm(A_c dt)`` (paper eq. 7 without its ZOH
   approximation) and ``Q = diag(q_speed, q_accel, q_offset, q_gps...) dt`` (white-noise
   intensities per second).
3. update: on a sample with a *new valid* fix (``gps_speed`` finite and ``gps_sats >= min_sats``;
   a missing or NaN count counts as valid) "KF1 INS/GPS" (eq. 9, 12): ``a_m = a + b + e``,
   var ``acc_psd / dt`` (a noise density; with ``acc_psd = 0`` the paper's per-sample
   ``r_acc_gps``), and ``gps = x3 + e``, var ``R22``; otherwise "KF INS" (eq. 10): the
   accelerometer row alone, var ``acc_psd / dt`` (or ``r_acc_ins``). A NaN accelerometer
   sample drops its row.
   The GPS row of the main filter is the extra-lag row above; KF2 (error modes "kf2",
   "states") takes ``gps = x3 + e``.
4. GPS error E and adaptive weighting (section VI-c, eq. 13, 18):
   ``R22 = r_gps + r_gps_slope E + r_gps_sq E^2`` with E clipped to ``0..e_max``. Default
   ``error_mode="innovation"``: E^2 = max(nu^2 - S, 0), nu the main filter's GPS innovation and S
   its predicted variance (the part of the disagreement the model does not explain, so R22 grows
   with nu^2 on a receiver jump). ``"kf2"``: the paper's KF2 (same model, fixed
   R = (r_acc_gps, r_gps)) predicts the fix through the lag model and E = |fix - prediction|
   before KF2's update;
   ``"states"``: the paper's literal E = |x3_KF2 - lag(x1_KF2)| after it.
5. offset (section VI-b): ``offset_mode="state"`` (default) estimates b inside the filter above
   (random walk ``q_offset``), so grade changes are followed with the filter's own gain and the
   speed covariance includes the offset uncertainty. ``"integrator"`` is the paper's separate
   drift KF ``[drift, offset]`` on ``integral(a_m) - v`` at valid fixes (eq. 16-17), its offset
   subtracted from ``a_m``; ``"off"`` estimates none.

Noise units. The paper's Q = diag(5, 4, 1, 1) and R values have no units or sample rate (only their
ratios matter for its fixed-gain filter), so ``speed_std`` computed with them is ~40x too wide.
The defaults here are physical (the accelerometer's error as a density of 0.1 (m/s^2)^2 s,
what a vehicle's vibration, pitch and a yawed mount add below 1 Hz; GPS 0.1 m/s per fix; jerk
intensity; offset random walk; the receiver's lag learned), so ``speed_std = sqrt(P11)`` is an
honest 1-sigma; the paper's set is :meth:`Config.paper` (with Q read per second). Override them
per sensor: a clean accelerometer rigidly on the vehicle's axis earns a smaller ``acc_psd``.

GPS/RISS is a package, one concern per module, each importing only the ones above it:

==========  ===============================================================================
``config``  gravity, the ``mode`` flags, :class:`GpsFields` (the receiver and the satellite
            gate, shared with ``fuse``) and :class:`Config`
``core``    the compiled update, prediction, per-sample step and loop (numba; items 1-5)
``filter``  ``State``, ``Output``, ``Sample``, ``Result``, ``init``, ``step``, ``run``
``method``  :func:`estimate` (a recording in, a Track out) and the lag identification
            (:func:`identify_lag`, :func:`identify_lag_recording`)
==========  ===============================================================================

The package's namespace is the GPS/RISS method, as the one module it was: the names above,
re-exported.
"""

from vibrospeed.estimators.gps_riss.config import (
    _ERROR_MODES,
    _OFFSET_MODES,
    MODE_GPS,
    MODE_INS,
    MODE_REJECTED,
    Config,
    G,
    GpsFields,
)
from vibrospeed.estimators.gps_riss.core import (
    _run_core,
    _step_core,
)
from vibrospeed.estimators.gps_riss.filter import (
    _NOUT,
    _OUT_NAMES,
    Output,
    Result,
    Sample,
    State,
    _copy_state,
    _pack,
    _run_progress,
    init,
    run,
    step,
)
from vibrospeed.estimators.gps_riss.method import (
    _AXIS_CHANNEL,
    estimate,
    identify_lag,
    identify_lag_recording,
)

__all__ = [
    "Config",
    "G",
    "GpsFields",
    "MODE_GPS",
    "MODE_INS",
    "MODE_REJECTED",
    "Output",
    "Result",
    "Sample",
    "State",
    "estimate",
    "identify_lag",
    "identify_lag_recording",
    "init",
    "run",
    "step",
    "_AXIS_CHANNEL",
    "_ERROR_MODES",
    "_NOUT",
    "_OFFSET_MODES",
    "_OUT_NAMES",
    "_copy_state",
    "_pack",
    "_run_core",
    "_run_progress",
    "_step_core",
]
