"""Longitudinal and lateral velocity at the centre of gravity, algebraic estimation.

METHODS.md section 4; seed: algebraic-velocity-estimation-paper, sections II-IV, Algorithms 1-2.
Inputs: yaw rate ``gz``, accelerations ``ax``, ``ay`` (rotating body frame) and the four wheel
speeds ``wheel_omega_*``; parameters: wheel radius ``r`` and front axle distance ``L1``. No
tyre model.

Per sample ``t_i`` (sample period ``Ts``):

1. algebraic filters (:mod:`vibrospeed.signal.differentiation`, degree ``N``, causal, window
   ``window`` for values / ``window_d`` for derivatives) give ``psi_dot``, ``psi_ddot``,
   ``gamma_x``, ``gamma_y``, ``omega_mean`` and ``d(omega_mean)/dt`` (Algorithm 1, line 1);
2. the disturbance system (seed eq. 7, :func:`vibrospeed.models.kinematics.disturbance_rhs`)
   is integrated (explicit Euler at ``Ts``) from ``G(t0) = 0``;
   remark 4: ``G`` is reset to 0 when ``|r d(omega_mean)/dt| < reset_eps_x`` and
   ``|L1 psi_ddot| < reset_eps_y`` have held over the last ``reset_hold`` samples;
3. Algorithm 1: if the wheels roll ``Vx = r omega_mean``, else
   ``Vx(t_i) = Vx(t_{i-1}) + Ts (gamma_x + psi_dot Vy)``. Default ``detect = "window"``: the
   wheels start to slip when the change of ``r omega_mean`` over the last ``slip_window`` s
   differs from the dead-reckoned change by ``slip_tol`` m/s or more (the integration restarts
   a window back), and roll again after a window in which they agree with the integrated
   ``Vx`` within ``slip_tol``, or in which ``|a_x| < slip_tol / slip_window`` (no force, no
   slip) and the windowed changes agree. ``detect = "seed"``: the seed's rule, wheels roll iff
   ``|dGx/dt| < eps1`` over ``[t_i - alpha Ts, t_i]`` (it only sees *changes* of slip: a slip
   that builds up and stays is taken back as rolling);
4. Algorithm 2: if ``|psi_dot| < eps2`` over ``[t_i - beta Ts, t_i]``: ``Vy = 0``, else
   ``Vy(t_i) = Vy(t_{i-1}) + Ts (gamma_y - psi_dot Vx)``.

Both updates use the previous sample's ``Vx``, ``Vy`` (explicit Euler, as the seed's fixed
integration step). Extensions (benchmarks/algebraic/RESULTS.md): at the onset of slip the
integration restarts
``backtrack`` samples earlier (within the preceding wheel-mode run); optional noise-scaled
thresholds (``eps_k``) and a cap on an integration episode (``max_int``); and standard
deviations of Vx and Vy: wheel-speed noise plus slip allowances in wheel mode, a random walk of
the measured accelerometer / gyro noise plus a bias ramp since the switch in integration mode.
NaN inputs are held at their last finite value (zero-order hold).
The seed gives no numbers for its thresholds (its Table I is lost in the text); the defaults
here were tuned on :mod:`vibrospeed.sim.vehicle` (benchmarks/algebraic/RESULTS.md).

The algebraic estimator is a package, one concern per module, each importing only the ones
above it:

==========  ===============================================================================
``core``    the compiled per-sample update and loop (numba) and the layout of its packed
            scalar state
``config``  :class:`Config` (thresholds, windows, noise allowances), :class:`State`, ``init``
``filter``  ``step`` and ``run`` on the compiled core, :class:`Result`
``method``  a recording in, a Track out (:func:`estimate`): wheel-speed mean, resampling of a
            non-uniform time line
==========  ===============================================================================
"""

from vibrospeed.estimators.algebraic.config import INPUTS, OUTPUTS, Config, State, init
from vibrospeed.estimators.algebraic.filter import Result, run, step
from vibrospeed.estimators.algebraic.method import estimate

__all__ = ["INPUTS", "OUTPUTS", "Config", "Result", "State", "estimate", "init", "run", "step"]
