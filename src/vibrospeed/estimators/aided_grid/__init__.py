"""Inertial aiding around the RBPMF grid tracker (thesis ch. 3 applied to paper III-D;
METHODS.md 1.3 and 2).

The aiding of :mod:`vibrospeed.estimators.aided` acts on omega only, through three hooks; on the
grid posterior of :mod:`vibrospeed.estimators.rbpmf` they become:

* **acceleration integration** (thesis eq. 3.10): ``omega_{k+1} = omega_k + (T / r)(u_k + b)``
  is a translation of the posterior density along the omega axis. Each grid hypothesis
  ``omega_i`` carries its own phasor Kalman filter, so the translation moves weight *and* linear
  state together: the mass of point ``i`` goes to ``omega_i + s``; where that lies between two
  grid points ``j, j+1`` it is split linearly (``1 - f``, ``f``) and the phasor filters arriving at
  a point are merged by moment matching (the same merge as the RBPMF transition, METHODS 1.3
  step 4). Splitting at every sample would diffuse the posterior by ``f (1 - f) dx^2`` per step
  (with dx = 0.25 rad/s and 0.6 m/s^2 at 100 Hz about 1 (rad/s)^2 per second, more than the
  random walk), so whole-cell moves are made exactly (an index shift, no diffusion) and the
  sub-cell remainder is carried in the state as ``offset`` (``|offset| <= dx / 2``): the
  posterior is the grid posterior displaced by ``offset``. The remainder is resolved (one linear
  split) before the next vibration update, whose likelihood is evaluated at the grid points.
  Mass pushed below the first (or above the last) grid point stays there: omega is clipped at
  0, as in the EKF version.
* **mode detector and boost** (thesis 3.3, eq. 3.14-3.15): in acceleration mode the vibration
  update is skipped (the RBPMF step runs with a NaN sample: prediction only) and the omega
  random walk uses ``q_omega_accel``; on the switch into acceleration mode the posterior is
  shifted by ``N_mode T ubar / r`` (N_mode samples in the mode window).
* **scalar omega measurements**: the standstill virtual measurement ``omega = 0`` with
  variance ``R_ss`` (thesis eq. 3.4-3.6) and reference-speed fixes multiply the grid weights by
  ``N(z; omega_j + offset, R)``. Multiplying the prior before the RBPMF step equals multiplying
  the posterior after its measurement update (the per-point Kalman filters do not depend on
  the weights), so the RBPMF's own step is used unchanged.

Standstill representation: with the thesis' window test the grid must start at
``omega_min = 0``, so the point ``omega = 0`` *is* standstill (linear spacing required: the
exact whole-cell shift needs equal cells). With ``standstill='broadband'`` (flags computed
before the loop) a grid above 0 is allowed: a standing sample is then a plain vibration sample
that adds nothing to the aiding, and the caller reports omega = 0 there, as the grid product
does.
While the standstill flag is up the random walk uses ``q_omega_still`` (default 0: a standing
vehicle keeps omega = 0 until the mode detector sees it start); with the walk on, mass would
leak to the next grid point every step and the posterior *mean* of a distribution cut at 0
would stay near one grid spacing instead of 0 (the EKF's Gaussian, clipped at 0, has no such
bias).

Continuous aiding (``aiding="continuous"``, the default of ``tracker=grid``): the thesis' mode
detector reads an absolute threshold on a_x (0.2 m/s^2), which a car's body motion crosses most
of the time, and then skips the vibration update. On a grid posterior the two sources combine
without a switch: the integral of ``u + accel_bias`` over each hop of ``aid_len`` samples
(``aid_hop`` s; standing samples and NaN add nothing) shifts the posterior at the hop's last
sample (one linear split, so the sub-cell diffusion ``f (1 - f) dx^2`` is paid once per hop,
not per sample), and the vibration update runs at every sample. The random walk ``q_omega``
then only needs to cover the aiding's error. The mode detector's ``accelerating`` and
``boost`` are never set.

Bias: unlike the EKF version there is no bias state (a grid over (omega, b) would square the
cost); ``accel_bias`` is a fixed known offset added to ``u``. On real data the offset of the
forward axis is removed before (``accel_detrend`` in :func:`estimate`).

"No line" state and comb evidence (``tracker=grid``): the tracker config may
carry the RBPMF's "no line" state (``off_rate`` > 0; its omega is unknown, i.e. uniform on the
grid) and ``comb`` (a :class:`vibrospeed.estimators.grid.Config`) adds the harmonic-comb
log-evidence of the grid product every ``comb_hop`` s (``rbpmf.step(..., extra=E)``; frames of the
RBPMF input ``y * gain``, kept in a ring buffer in the state). The scalar omega measurements
above then also weigh the "no line" state by its marginal likelihood ``p(z | no line) =
mean_j N(z; omega_j + offset, R)`` (uniform omega), so a standstill measurement puts the mass
on the line state at 0. In acceleration mode the comb evidence is skipped (``comb_in_accel``:
a 3 s spectrum lags a fast speed change; the vibration update is skipped there too). The
integration and the boost move only the line part; the "no line" part stays uniform.


The aided grid tracker is a package, one concern per module, each importing only the ones
above it:

============  =============================================================================
``config``    the tracker's :class:`Config` (the RBPMF config, detectors, aiding kind, comb
              evidence) and the thesis cart's grid
``shift``     the translation of the grid posterior by a number of cells (numba) and the
              whole-cell / sub-cell bookkeeping of ``offset``
``filter``    ``State``, ``init``, ``step``, ``run``: the detectors, the aiding's hooks around
              :func:`vibrospeed.estimators.rbpmf.step`, plain stretches through
              :func:`vibrospeed.estimators.rbpmf.run`
``smoother``  the aided forward-backward smoother (continuous aiding): the forward pass with
              the per-state emissions, the shift inside the transition both ways
``method``    a recording in, a Track out (:func:`estimate`): ``tracker=rbpmf`` on the cart's
              grid, ``tracker=grid`` with the grid product's settings and the mount estimate
============  =============================================================================
"""

from vibrospeed.estimators.aided_grid.config import (
    AIDING_KINDS,
    STANDSTILL_KINDS,
    Config,
    _cart_tracker,
)
from vibrospeed.estimators.aided_grid.filter import (
    ESTIMATE_EXTRAS,
    Result,
    State,
    init,
    run,
    step,
)
from vibrospeed.estimators.aided_grid.method import (
    COMB_PARAMS,
    GRID_TRACKER,
    INPUT_PARAMS,
    _mount_input,
    estimate,
)
from vibrospeed.estimators.aided_grid.shift import _shift

__all__ = [
    "AIDING_KINDS",
    "COMB_PARAMS",
    "ESTIMATE_EXTRAS",
    "GRID_TRACKER",
    "INPUT_PARAMS",
    "STANDSTILL_KINDS",
    "Config",
    "Result",
    "State",
    "estimate",
    "init",
    "run",
    "step",
    "_cart_tracker",
    "_mount_input",
    "_shift",
]
