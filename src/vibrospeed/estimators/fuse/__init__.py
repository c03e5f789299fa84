"""One speed from every sensor a log has: longitudinal acceleration, GPS speed and the wheel
vibration's frequency, with the effective wheel radius learned on the way (``--method fuse``).

State ``X = [v, a, b, r, x3, x4, d..., dl]``: speed (m/s), acceleration (m/s^2), accelerometer
offset b (m/s^2: road slope ``g sin theta``, mount tilt and bias), the effective wheel radius r
(m, the speed-to-wheel-frequency ratio ``v = r omega``), the GPS receiver chain of the GPS/RISS
model (:mod:`vibrospeed.models.gps_riss`: reported speed x3, its derivative x4, Pade delay
states) and the receiver's extra lag dl (s, random walk ``q_gps_lag`` from ``0 +-
gps_lag_std``; :mod:`vibrospeed.estimators.gps_riss` explains it).
Continuous time ``v' = a``, ``a' = w_a``, ``b' = w_b``, ``r' = w_r``,
``[x3, x4, d]' = Ar [x3, x4, d] + Br v`` (paper eq. 1-2); each step predicts with the exact
transition ``F = expm(A_c dt)`` and ``Q = diag(q) dt``.

Measurements of one fusion sample (all scalar, sequential Kalman updates, Joseph form):

1. accelerometer ``a_m = a + b + e``, ``var e = acc_psd / dt``: the mean of the raw samples over
   the ``dt`` since the previous fusion sample (white noise of density ``acc_psd``). Its gain
   is taken as 1: on the simulated drives body motion and pitch leave 0.17-0.26 m/s^2 on 5 s
   means of the acceleration, against 0.02-0.08 m/s^2 for a gain error of 2-8 %, so GPS does
   not teach a gain state better than its prior (``benchmarks/fuse/RESULTS.md``).
2. GPS speed ``g = x3(t - dl) + e ~ x3 - dl x3' + e`` (GPS/RISS paper section VI, the
   receiver's extra lag learned; extended Kalman row linearised at the estimate, ``x3' = A_c[x3]
   X``; at a sample without an accelerometer mean the lag is a consider state, since GPS
   alone cannot tell a late fix from another speed history): used only with ``sats >= min_sats``
   (a NaN count counts as valid); its variance grows with the part of the innovation the model
   does not explain, ``R = r_gps + r_gps_sq min(E^2, e_max^2)``, ``E^2 = max(nu^2 - S0, 0)``
   (paper eq. 13, 18; ``e_max`` large, see :class:`Config`). The change of v this update makes
   is then at most
   ``sqrt(P_vv) / (2 sqrt(c (1 - c)))``, c = ``r_gps_sq``, whatever the innovation (from
   ``S >= (1 - c) S0 + c nu^2 >= 2 sqrt(c (1 - c) S0) |nu|`` and ``|P_v3| <= sqrt(P_vv S0)``):
   one standard deviation for c = 1/2, so the speed does not jump out of its band when GPS
   returns after a tunnel. Weighted down so, a fix would also leave a speed that the
   accelerometer pulled away from the fixes where it is, so a disagreement (``E^2 > 0``) on
   the same side of the speed at every valid fix for ``gps_persist`` s (longer than a receiver
   jump) and at least ``core.PERSIST_FIXES`` fixes (8: 2^-7 by chance with white receiver
   errors) is taken as the filter's drift: the speed's variance grows by ``E^2`` first, along
   a speed offset that has passed through the receiver, and the fix is then taken at its own
   variance (the band widens before the speed moves).
3. wheel frequency: the harmonic tracker's omega (its mode) with spread ``s`` where it claims a
   line; ``s`` is the tracker's whole posterior's spread (``vib_spread="posterior"``, the
   default) or the spread within its mode (``"mode"``, the grid tracker's ``omega_mode_std``;
   what :func:`estimate` uses online, see :class:`Config`); none where the vibration axis has
   no sample (the tracker only predicts there). The line may be
   the wheel's omega/2 or 2 omega (the tracker's octave errors), so the wheel frequency is
   ``k omega``, ``k in {1/2, 1, 2}``. Each hypothesis is the *linear*
   pseudo-measurement ``0 = v - r k omega + e`` (``H = [1, 0, 0, -k omega, 0...]``, exact in the
   state given the measured omega) with one sample's variance ``R1 = (r k)^2 (s^2 + (vib_rel
   omega)^2) + (vib_lag a)^2``: the tracker's spread, a relative floor and the speed a line
   that trails an acceleration ``a`` by up to ``vib_lag`` s misses (a causal tracker follows
   a hard braking a second or two late while its mode stays narrow; 0 for the smoothed
   tracker); ``a`` is the larger of the filter's acceleration and the accelerometer's mean
   less the offset, ``a_m - b`` (a lagging line taken at the onset of a braking pulls the
   filter's own acceleration towards 0). The update uses ``R1 vib_corr / dt``, inflated by
   the number of fusion samples per correlation time of the tracker's errors (its outputs
   are not independent from sample to sample); the gate uses ``R1``, one sample's spread (whether
   this line fits the prediction, not how much a run of such lines is worth). The
   hypothesis with the smallest normalised innovation squared ``nu^2 / S`` plus
   ``vib_penalty`` for k != 1 is used if that sum is below ``vib_gate`` and the gate is
   decisive: GPS holds the speed (a fix in the past ``learn_hold`` s), or
   ``3 sqrt(P_vv + (r k)^2 (s^2 + (vib_rel omega)^2)) <= vib_sep r k omega``
   (the band and the line's own spread are narrow against the spacing of the octaves;
   after a long stretch on the accelerometer alone it is not, and a gate of 4 sigma would pass
   an idling engine's line or the wrong octave), or the tracker claims a line that continues
   the one used at the previous fusion sample (the same k, its omega within half an octave of
   that sample's, ``|log2(omega / omega_prev)| <= 1/2``): the octave was decided when the line
   was first taken, and a claimed line that moves by less than half an octave from one sample
   to the next has not changed harmonic (at 4-8 m/s the causal tracker's spread within its
   mode is 6-15 % of omega, so the decisive gate alone refused its right lines sample after
   sample; with ``vib_use="all"`` the omegas offered are not claims and this does not apply);
   else the sample has no direct vibration update (re-lock below). No line is used where the
   filter knows the vehicle to be slower than ``vib_min_speed`` (``v + 3 sqrt(P_vv) <
   vib_min_speed``): a line claimed at a standstill (an idling engine) would otherwise teach
   ``r = v / omega = 0``; nor a hypothesis
   whose radius cannot be physical for any speed within 3 sigma:
   ``(v + 3 sqrt(P_vv)) / (k omega) < radius_min`` or ``(v - 3 sqrt(P_vv)) / (k omega) >
   radius_max`` (an engine line while the vehicle starts to roll). Once r is known, only the
   octave whose speed lies within a factor sqrt 2 of the filter's is a hypothesis,
   ``|log2(k r omega / v)| <= 1/2`` (one of the three at most; ``v <= 0``: none): a line that
   jumped an octave against the prediction (a causal tracker on the 2nd harmonic in a hard
   braking, let in at k = 1 by the lag variance) is read at the octave it jumped to, and no
   update moves the speed by a factor 2.

   The speed prior decides the octave: the GPS speed, away from GPS the filter's own speed
   (with the decisive gate above), and while r is not yet known within ``octave_rel`` the
   radius prior too: a vehicle class's prior (e.g. ``radius0 = 0.32, radius_std0 = 0.027``
   for a car) puts r / 2 six sigma away, so a tracker on the 2nd harmonic is read as 2 omega
   and r is learned as the wheel's; with the wide default prior k = 1, without the octave
   penalty, wins and r is the line's ratio. The radius is defined by the line the tracker
   reports most of the time: an exponential average (time constant ``octave_tau`` s of
   updates) of ``log2 k`` over the accepted updates with GPS beyond +-1/2 means that most
   recent updates used k = 2 (or 1/2), e.g. after a tracker that locked on the second
   harmonic at the start taught the radius; then, if r is known within ``octave_rel``
   (relative std) and ``k r`` lies within 3 sigma of the radius prior (``radius0 +- 3
   radius_std0``), ``r <- k r`` (its variance by k^2); the average restarts at 0 either way.
   The speed is unchanged by this, only the octave of r.

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
   does) and either ``|d| <= 3 sqrt(P_vv)`` with ``r omega`` within a factor sqrt 2 of ``v``,
   or the line's speed has changed by ``acq_change``
   of itself in that run, the filter, not the line, has drifted: ``P_vv`` is increased by
   ``d^2`` and the line is taken. A band that holds the line's speed and one of its octaves
   (``r omega / 2``, ``2 r omega``) cannot tell which octave the line is, and the tracker may
   have left the one that taught r (r learned on half the wheel's frequency, the wheel's own
   line in the outage): a line nearer an octave of ``v`` than ``v`` itself is not taken
   inside the band, only once it has moved with the speed. "Moved with the speed" also asks
   that the mean gap has changed by less than 0.4 of the line's change since the run began:
   a line at another octave of the one that taught r (``v = c r omega``, c = 2 or 1/2)
   changes the gap by ``|1 - c| >= 1/2`` of its own change, which a running mean alone
   would follow. A constant
   line far outside the band (an idling engine at a stop in a tunnel) is not taken until it
   moves with the speed. A line the tracker holds at a line probability of ``vib_soft`` or
   more without claiming it (the ``soft`` input) is used only away from GPS with r known, and
   only in two ways. (a) Where it continues the last line used, at most ``vib_soft_hold`` s
   before the previous fusion sample (the same k, which is then its only hypothesis, its omega
   within half an octave of that line's), it is taken directly if its normalised innovation is
   at most ``vib_soft_gate`` (two sigma; no decisive gate: the octave was decided when the
   chain began with a claimed line): a causal tracker's claims come and go on a line it
   keeps as its mode, and the chain of lines used carries the speed through those gaps
   instead of the accelerometer. A chain ends at the first gap longer than the hold, so an
   unclaimed line is never the first line taken after one. (b) Otherwise it joins only the
   re-lock run: when its run completes, ``P_vv`` grows by ``d^2`` but the line is not taken
   (a claimed line at that gap then re-locks inside the band). Where the acceleration exceeds
   ``vib_amax`` (the same ``a`` as for ``vib_lag``) no line is used, directly or by re-lock:
   a causal tracker's line trails a hard acceleration by more than its spread, or jumps an
   octave. Both runs (acquisition,
   re-lock) need a line at every fusion sample: a sample without one ends the run, so a line
   claimed now and then (a resonance or an engine order between the wheel's claims) does not
   add up to a run.

   Read through the tracker's posterior (``vib_measure="posterior"``; :func:`estimate` online),
   with r known each octave k is measured by the tracker's grid posterior instead of its mode.
   The prediction of the line, ``N(omega; m_k, S_k)`` with ``m_k = v / (r k)`` and ``S_k = h P
   h' + ((vib_lag a) / (r k))^2 + dg^2`` (h the row of ``v / (r k)`` in v and r, dg the grid
   spacing: the posterior resolves no finer), times the line-conditional posterior ``q =
   posterior / (1 - p_null)`` (the grid tracker's prior is flat on its uniform grid, so q is
   its likelihood of omega) over the grid points within ``vib_post_width sqrt(S_k)`` of
   ``m_k``, gives the Bayes factor ``B_k = sum q_j g_j / (sum g_j / N)`` (the posterior's
   mass there against a flat posterior's) and the product's moment-matched mean ``mu`` and
   variance ``V`` (plus ``dg^2 / 12``). Dividing the prediction out leaves a Gaussian
   likelihood of the line, ``R = 1 / (1 / V - 1 / S_k)``, ``z = R (mu / V - m_k / S_k)``
   (none where ``V >= S_k``: the posterior does not narrow the prediction), which is the
   update's omega with the spread ``R + (vib_rel z)^2``. The octave is the one with the
   smallest ``-2 ln B_k`` plus ``vib_penalty`` for k != 1; the line is there with probability
   ``beta = p B / (p B + 1 - p)``, ``p = 1 - p_null`` (the "no line" state explains the data
   as a flat posterior does), and is used where ``beta >= vib_post_min`` and the gate is
   decisive (as above, with z and its spread), its variance divided by beta. An unclaimed
   line (``soft``) is read the same way, its line probability in beta, without having to
   continue the last line used; of rule (a) above only the continuation acts there: an
   unclaimed line that continues the last line used within ``vib_soft_hold`` s needs no
   decisive gate (``vib_soft_gate``'s value is not used; ``vib_soft_gate = 0`` switches the
   continuation off, which moved 3 of the 30 simulated tunnels by at most 0.05 m/s online
   and the real windows not at all, benchmarks/fuse/RESULTS.md). So a posterior whose mode
   is another line (a resonance, an engine order) but which holds the wheel's line near the
   prediction gives the wheel's line, and peaks at omega / 2 and omega are read at the octave
   the prediction implies.
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

The fusion filter is a package, one concern per module, each importing only the ones above it:

============  =============================================================================
``config``    ``source`` codes, octave factors, the tracker's settings under fuse, the state
              indices and :class:`Config` (with its system matrix and parameter vector)
``band``      :func:`learn_acc_psd`, the accelerometer's density from the drive's own fixes,
              for the speed band (``Config.band_psd``)
``core``      the compiled scalar update, per-sample step and loop, the posterior's product
              with the prediction (numba; items 1-5 above)
``filter``    ``State``, ``Sample``, ``Output``, ``Result``, ``init``, ``step``, ``run``
``smoother``  :func:`smooth`, the RTS smoother over a forward run (:func:`smooth_band`: the
              band's covariance through it)
``method``    :func:`radius_from_json`, the fusion samples, :func:`estimate`, :func:`suits`
============  =============================================================================

The package's namespace is the fusion method, as the one module it was: the names above,
re-exported.
"""

from vibrospeed.estimators.fuse.band import learn_acc_psd, learn_acc_psd_causal
from vibrospeed.estimators.fuse.config import (
    CAUSAL_VIB_AMAX,
    CAUSAL_VIB_LAG,
    CAUSAL_VIB_MEASURE,
    CAUSAL_VIB_SEP,
    CAUSAL_VIB_SOFT,
    HARMONIC_FACTORS,
    IA,
    IB,
    IG,
    IR,
    IV,
    SOURCES,
    SRC_GPS,
    SRC_INERTIAL,
    SRC_STANDSTILL,
    SRC_VIBRATION,
    TRACKER_DEFAULTS,
    Config,
)
from vibrospeed.estimators.fuse.core import _run_core, _step_core
from vibrospeed.estimators.fuse.device import FuseTracker as FuseTracker  # fuse on a device
from vibrospeed.estimators.fuse.filter import (
    _SAMPLE,
    EXTRAS,
    Output,
    Result,
    Sample,
    State,
    _as_inputs,
    _pack,
    _unpack,
    init,
    run,
    step,
)
from vibrospeed.estimators.fuse.method import (
    _TRACKER_OWN,
    _block_all,
    _block_mean,
    _split,
    estimate,
    fusion_samples,
    radius_from_json,
    suits,
)
from vibrospeed.estimators.fuse.smoother import _rts, smooth, smooth_band

__all__ = [
    "CAUSAL_VIB_AMAX",
    "CAUSAL_VIB_LAG",
    "CAUSAL_VIB_MEASURE",
    "CAUSAL_VIB_SEP",
    "CAUSAL_VIB_SOFT",
    "EXTRAS",
    "HARMONIC_FACTORS",
    "IA",
    "IB",
    "IG",
    "IR",
    "IV",
    "SOURCES",
    "SRC_GPS",
    "SRC_INERTIAL",
    "SRC_STANDSTILL",
    "SRC_VIBRATION",
    "TRACKER_DEFAULTS",
    "Config",
    "Output",
    "Result",
    "Sample",
    "State",
    "estimate",
    "fusion_samples",
    "init",
    "learn_acc_psd",
    "learn_acc_psd_causal",
    "radius_from_json",
    "run",
    "smooth",
    "smooth_band",
    "step",
    "suits",
    "_SAMPLE",
    "_TRACKER_OWN",
    "_as_inputs",
    "_block_all",
    "_block_mean",
    "_pack",
    "_rts",
    "_run_core",
    "_split",
    "_step_core",
    "_unpack",
]
