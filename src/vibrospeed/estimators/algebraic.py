# Over 500 lines: slip detection, resets and the algebraic differentiation share one compiled
# loop and one Config; the entry point maps the recording's channels onto it.
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
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import config_from_params
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.models.kinematics import disturbance_rhs
from vibrospeed.signal import differentiation as dif
from vibrospeed.types import WHEEL_CHANNELS, Estimate, Recording, Track

#: inputs, in this order, of :func:`step`
INPUTS = ("gz", "ax", "ay", "omega_mean")
#: per-sample outputs of :func:`step` / :func:`run`
OUTPUTS = (
    "vx", "vy", "gx", "gy", "dgx", "dgy", "slip_mode", "turn_mode",
    "yaw_rate", "yaw_acc", "ax", "ay", "omega_mean", "omega_dot",
    "vx_std", "vy_std", "sd_gz", "sd_ax", "sd_ay", "sd_omega",
)

# packed scalar state: indices into State.s
_GX, _GY, _VX, _VY, _NX, _NY, _NRESET, _POS, _STARTED = 0, 1, 2, 3, 4, 5, 6, 7, 8
_LAST = 9  # 4 values: last finite input per channel (zero-order hold)
_LAST2 = 13  # 4 values: the finite input before it
_NSEEN = 17  # 4 values: finite samples seen per channel
_ND2 = 21  # 4 values: second differences averaged per channel
_MSQ = 25  # 4 values: running mean of the squared second differences
_VX0, _VXRW, _TX, _VY0, _VYRW, _TY = 29, 30, 31, 32, 33, 34  # integration-mode variances
_HX, _HY = 35, 36  # hand-over allowances (variances, decaying)
_HPOS, _NSTEP, _VARX, _VARY = 37, 38, 39, 40
_SLIP = 41  # window detection: 1 while integrating
_NS = 42


@dataclass(frozen=True)
class Config:
    """Parameters of Algorithms 1 and 2 and of the uncertainty model.

    Parameters
    ----------
    r : wheel radius in m. L1 : CG to front axle distance in m (``Ry = -L1 psi_dot``).
    dt : sample period Ts in s.
    window, window_d : algebraic filter windows in s for values / first derivatives.
    N, kappa, mu, xi : differentiator degree, Jacobi weights and evaluation point
        (:mod:`vibrospeed.signal.differentiation`); the seed uses N = 1, nu = 2
        (kappa = mu = 0) and estimates at the newest sample (xi = 0).
    eps1 : m/s^2, threshold on ``|dGx/dt|``; alpha : hold window in samples (``alpha Ts``).
    eps2 : rad/s, threshold on ``|psi_dot|``; beta : hold window in samples (``beta Ts``).
    reset_eps_x : m/s^2 on ``|r d(omega_mean)/dt|``; reset_eps_y : m/s^2 on
        ``|L1 psi_ddot|``; reset_hold : samples (0 disables the reset of remark 4).
    vy0 : initial lateral velocity in m/s (Algorithm 2 requires it).
    backtrack : samples; at the onset of slip the integration restarts from ``Vx`` that many
        samples before the switch (the wheels already slipped while ``dGx/dt`` was building
        up); ``None`` -> ``alpha``, 0 -> the seed's restart from the previous sample.
    eps_k : if > 0, the thresholds become ``max(eps1, eps_k sd(dGx/dt))`` and
        ``max(eps2, eps_k sd(psi_dot))`` with the noise sds predicted from the sensor noise
        measured on line (second differences); 0 (default) keeps the fixed thresholds.
    Uncertainty: ``slip_sd`` relative allowance for undetected slip in wheel mode (sd of Vx
    = ``slip_sd |Vx|``); ``acc_bias_sd`` m/s^2 and ``gyro_bias_sd`` rad/s, sds of the sensor
    biases (integration drift ``b T``); ``handover_tau`` s, decay time of the disagreement
    allowance at a switch back; ``noise_tau`` s, memory of the on-line noise estimates.
    max_int : s, longest integration episode: after it the wheels are trusted again (the hold
        window restarts); ``inf`` (default) is the seed's rule.
    detect : ``"window"`` (default) or ``"seed"`` (Algorithm 1 as published: ``eps1``,
        ``alpha``, ``backtrack`` and the reset only act there).
    slip_tol : m/s, window detection: largest disagreement between the wheel speed and the
        dead-reckoned speed taken as rolling (raised to ``eps_k`` sd of the measured noise).
    slip_window : s, window detection: the window of that comparison and of the hold.
    """

    r: float = 0.31
    L1: float = 1.2
    dt: float = 0.01
    window: float = 0.1
    window_d: float = 0.2
    N: int = 1
    kappa: float = 0.0
    mu: float = 0.0
    xi: float = 0.0
    eps1: float = 0.4
    alpha: int = 20
    eps2: float = 0.02
    beta: int = 30
    reset_eps_x: float = 0.3
    reset_eps_y: float = 0.3
    reset_hold: int = 50
    vy0: float = 0.0
    backtrack: int | None = None
    eps_k: float = 0.0
    slip_sd: float = 0.002
    acc_bias_sd: float = 0.03
    gyro_bias_sd: float = 0.001
    handover_tau: float = 0.5
    noise_tau: float = 5.0
    max_int: float = float("inf")
    detect: str = "window"
    slip_tol: float = 0.3
    slip_window: float = 0.5

    def __post_init__(self) -> None:
        for name in ("r", "L1", "dt", "window", "window_d", "eps1", "eps2", "handover_tau",
                     "noise_tau", "max_int", "slip_tol", "slip_window"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"algebraic: {name} must be > 0, got {getattr(self, name)}")
        for name in ("eps_k", "slip_sd", "acc_bias_sd", "gyro_bias_sd"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"algebraic: {name} must be >= 0, got {getattr(self, name)}")
        for name in ("alpha", "beta", "reset_hold", "backtrack"):
            v = getattr(self, name)
            if v is None and name == "backtrack":
                continue
            if int(v) != v or v < 0:
                raise ParameterError(f"algebraic: {name} must be an integer >= 0, got {v}")
        if self.detect not in ("window", "seed"):
            raise ParameterError(f"algebraic: detect must be 'window' or 'seed', got "
                                 f"{self.detect!r}")
        if self.N < 1:
            raise ParameterError(
                f"algebraic: N must be >= 1 (derivatives are needed), got {self.N}")
        self.filters()  # validates the windows against N

    @property
    def k_window(self) -> int:
        """``slip_window`` in samples (at least 2)."""
        return max(2, int(round(self.slip_window / self.dt)))

    @property
    def n_back(self) -> int:
        """Backtracking depth in samples: ``k_window`` for the window detection, else
        ``backtrack`` (default ``alpha``)."""
        if self.detect == "window":
            return self.k_window
        return int(self.alpha if self.backtrack is None else self.backtrack)

    def filters(self) -> tuple[dif.Config, dif.Config]:
        """Differentiator configurations (value, first derivative)."""
        kw = dict(N=self.N, kappa=self.kappa, mu=self.mu, xi=self.xi)
        return (dif.Config.from_window(self.window, self.dt, n=0, **kw),
                dif.Config.from_window(self.window_d, self.dt, n=1, **kw))

    def taps(self) -> tuple[np.ndarray, np.ndarray]:
        """FIR taps (value, derivative) zero-padded to one common length."""
        c0, c1 = self.filters()
        b0, b1 = c0.taps(), c1.taps()
        L = max(b0.size, b1.size)
        return np.pad(b0, (0, L - b0.size)), np.pad(b1, (0, L - b1.size))

    def scalars(self) -> np.ndarray:
        b0, b1 = self.taps()
        return np.array([self.r, self.L1, self.dt, self.eps1, self.alpha, self.eps2, self.beta,
                         self.reset_eps_x, self.reset_eps_y, self.reset_hold, self.vy0,
                         self.n_back, self.eps_k, self.slip_sd, self.acc_bias_sd,
                         self.gyro_bias_sd, self.handover_tau, self.noise_tau,
                         float(np.linalg.norm(b0)), float(np.linalg.norm(b1)), self.max_int,
                         1.0 if self.detect == "window" else 0.0, self.slip_tol,
                         self.k_window])


class State(NamedTuple):
    """Ring buffers ``buf`` (4, L) of ``INPUTS``; ``hist`` (3, backtrack + 2) of past ``Vx``,
    its variance and the integration increments ``Ts (gamma_x + psi_dot Vy)``; ``s`` (41,)
    packed scalars (``G``, ``V``, hold counters, held inputs, noise statistics, variances;
    see the ``_*`` indices in the module)."""

    buf: np.ndarray
    hist: np.ndarray
    s: np.ndarray

    @property
    def vx(self) -> float:
        return float(self.s[_VX])

    @property
    def vy(self) -> float:
        return float(self.s[_VY])


def init(config: Config) -> State:
    """Empty state: the first finite sample fills the buffers and sets ``Vx = r omega_mean``."""
    L = config.taps()[0].size
    s = np.zeros(_NS)
    s[_LAST:_LAST + 4] = np.nan
    return State(np.zeros((4, L)), np.zeros((4, config.n_back + 2)), s)


@njit(cache=True)
def _noise_update(s, j, x, w_min, update):
    """Second-difference noise statistic of channel ``j``: for white noise of sd sigma,
    ``E[(x_i - 2 x_{i-1} + x_{i-2})^2] = 6 sigma^2``; running mean, memory ``noise_tau``."""
    if s[_NSEEN + j] >= 2.0 and update:
        d2 = x - 2.0 * s[_LAST + j] + s[_LAST2 + j]
        s[_ND2 + j] += 1.0
        w = max(1.0 / s[_ND2 + j], w_min)
        s[_MSQ + j] += w * (d2 * d2 - s[_MSQ + j])
    s[_LAST2 + j] = s[_LAST + j]
    s[_LAST + j] = x
    s[_NSEEN + j] += 1.0


@njit(cache=True)
def _core(b0, b1, p, buf, hist, s, z, out):
    """One sample of Algorithms 1 and 2 in place on ``buf``, ``hist``, ``s``; outputs to
    ``out`` (:data:`OUTPUTS`)."""
    r, L1, dt, eps1, alpha, eps2, beta = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    rex, rey, rhold, vy0 = p[7], p[8], p[9], p[10]
    nback, eps_k, slip_sd, b_acc, b_gyro, h_tau, n_tau = (
        int(p[11]), p[12], p[13], p[14], p[15], p[16], p[17])
    g0, g1, max_int = p[18], p[19], p[20]
    win, tol, kwin = p[21] > 0.5, p[22], int(p[23])
    L = b0.size
    K = hist.shape[1]
    first = s[_STARTED] == 0.0
    # all channels known at least once (zero-order hold of NaN inputs)
    ok = True
    for j in range(4):
        if not (np.isfinite(z[j]) or np.isfinite(s[_LAST + j])):
            ok = False
    if not ok:
        out[:] = np.nan
        return
    # on-line noise statistics; the wheel-speed noise only in wheel mode (ABS cycles are no
    # noise) once 50 differences are known
    w_min = dt / n_tau
    if win:
        wheel_upd = s[_SLIP] == 0.0 or s[_ND2 + 3] < 50.0
    else:
        wheel_upd = s[_NX] >= alpha + 1.0 or s[_ND2 + 3] < 50.0
    for j in range(4):
        if np.isfinite(z[j]):
            _noise_update(s, j, z[j], w_min, j < 3 or wheel_upd)
    sig2_gz = s[_MSQ] / 6.0
    sig2_ax = s[_MSQ + 1] / 6.0
    sig2_ay = s[_MSQ + 2] / 6.0
    sig2_wm = s[_MSQ + 3] / 6.0
    pos = int(s[_POS])
    if first:  # steady-state buffers, wheels roll, Vy = vy0
        for j in range(4):
            buf[j, :] = s[_LAST + j]
        s[_GX] = 0.0
        s[_GY] = 0.0
        s[_VX] = r * s[_LAST + 3]
        s[_VY] = vy0
        s[_NX] = alpha + 1.0
        s[_NY] = 0.0
        s[_NRESET] = 0.0
        s[_SLIP] = 0.0
        s[_STARTED] = 1.0
    # algebraic filters (Algorithm 1, line 1)
    f0 = np.zeros(4)
    f1 = np.zeros(4)
    for j in range(4):
        buf[j, pos] = s[_LAST + j]
        a0 = 0.0
        a1 = 0.0
        for k in range(L):
            q = pos - k
            if q < 0:
                q += L
            a0 += b0[k] * buf[j, q]
            a1 += b1[k] * buf[j, q]
        f0[j] = a0
        f1[j] = a1
    pos += 1
    if pos == L:
        pos = 0
    s[_POS] = pos
    wz, ax, ay, wm = f0[0], f0[1], f0[2], f0[3]
    wz_dot, wm_dot = f1[0], f1[3]
    # disturbance system (seed eq. 7), explicit Euler (line 2)
    dgx, dgy = disturbance_rhs(s[_GX], s[_GY], wz, wz_dot, wm, wm_dot, ax, ay, r, L1)
    s[_GX] += dt * dgx
    s[_GY] += dt * dgy
    # remark 4: reset G when the residual derivatives stay near zero
    if rhold > 0:
        if abs(r * wm_dot) < rex and abs(L1 * wz_dot) < rey:
            s[_NRESET] += 1.0
        else:
            s[_NRESET] = 0.0
        if s[_NRESET] >= rhold:
            s[_GX] = 0.0
            s[_GY] = 0.0
    # thresholds, optionally scaled to the measured noise of dGx/dt and of psi_dot
    e1 = eps1
    e2 = eps2
    if eps_k > 0.0:
        e1 = max(eps1, eps_k * np.sqrt(g0 * g0 * sig2_ax + r * r * g1 * g1 * sig2_wm))
        e2 = max(eps2, eps_k * g0 * np.sqrt(sig2_gz))
        # window residual: two filtered wheel speeds and kwin filtered accelerations
        tol = max(tol, eps_k * g0 * np.sqrt(2.0 * r * r * sig2_wm + kwin * dt * dt * sig2_ax))
    # no longitudinal force below the acceleration that moves the speed by tol in a window
    a_free = tol / (kwin * dt)
    # window-held switching conditions (line 3 of Algorithms 1 and 2)
    nx_prev = s[_NX]
    was_turn = s[_NY] < beta + 1.0
    s[_NY] = s[_NY] + 1.0 if abs(wz) < e2 else 0.0
    vx_prev = s[_VX]
    vy_prev = s[_VY]
    varx_prev = s[_VARX]
    vary_prev = s[_VARY]
    turn = s[_NY] < beta + 1.0
    # history of Vx and of the increments Ts (gamma_x + psi_dot Vy) for the backtracking
    hpos = int(s[_HPOS])
    inc = dt * (ax + wz * vy_prev)
    hist[2, hpos] = inc
    if win:
        # window detection: res = change of r omega_mean over the last kwin samples minus the
        # dead-reckoned change (the increments); the wheels start to slip when |res| >= tol.
        # Integrating, they are trusted again after kwin samples in which they agree with the
        # integrated speed, or in which there is no longitudinal force (|a_x| < a_free: no
        # force, no slip) and |res| < tol (the integrated speed has drifted, the wheels roll)
        was_slip = s[_SLIP] == 1.0
        vw = r * wm
        nb0 = min(kwin, int(s[_NSTEP]))
        res = 0.0
        if nb0 > 0:
            q = hpos - nb0
            if q < 0:
                q += K
            res = vw - hist[3, q]
            for _m in range(nb0):
                q += 1
                if q == K:
                    q = 0
                res -= hist[2, q]
        if was_slip:
            agree = abs(vw - (vx_prev + inc)) < tol or (abs(ax) < a_free and abs(res) < tol)
            s[_NX] = s[_NX] + 1.0 if agree else 0.0
            slip = s[_NX] < kwin
        elif s[_NX] < 0.0:  # wheels trusted for a window after a capped episode
            slip = False
            s[_NX] += 1.0
        else:
            slip = nb0 > 0 and abs(res) >= tol
            s[_NX] = 0.0
        if slip and was_slip and s[_TX] + dt > max_int:  # integration episode too long
            slip = False
            s[_NX] = -float(kwin)
        s[_SLIP] = 1.0 if slip else 0.0
    else:
        was_slip = nx_prev < alpha + 1.0
        s[_NX] = s[_NX] + 1.0 if abs(dgx) < e1 else 0.0
        slip = s[_NX] < alpha + 1.0
        if slip and was_slip and s[_TX] + dt > max_int:  # integration episode too long
            s[_NX] = alpha + 1.0
            slip = False
    decay = np.exp(-2.0 * dt / h_tau)
    # Vx: Algorithm 1 with its standard deviation
    qx = dt * dt * (sig2_ax + vy_prev * vy_prev * sig2_gz + wz * wz * vary_prev)
    if slip:
        # never back into the previous integration episode (nx_prev - alpha samples of wheel
        # mode precede this one)
        if win:
            nb = -1
        else:
            nb = min(nback, int(s[_NSTEP]) - 1, int(nx_prev - alpha) - 1)
        if win and not was_slip:
            # slip onset: restart from the wheel speed kwin samples back plus the increments
            q = hpos - nb0
            if q < 0:
                q += K
            vx0 = hist[0, q]
            for _m in range(nb0):
                q += 1
                if q == K:
                    q = 0
                vx0 += hist[2, q]
            s[_VX] = vx0
            q = hpos - nb0
            if q < 0:
                q += K
            s[_VX0] = hist[1, q]
            s[_VXRW] = nb0 * qx
            s[_TX] = nb0 * dt
        elif not was_slip and nb >= 0:
            # slip onset: restart from Vx(t_i - (nb + 1) Ts), re-integrate the nb + 1 increments
            q = hpos - nb - 1
            if q < 0:
                q += K
            vx = hist[0, q]
            s[_VX0] = hist[1, q]
            for _m in range(nb + 1):
                q += 1
                if q == K:
                    q = 0
                vx += hist[2, q]
            s[_VX] = vx
            s[_VXRW] = (nb + 1) * qx
            s[_TX] = (nb + 1) * dt
        else:
            if not was_slip:  # slip from the first sample on
                s[_VX0] = varx_prev
                s[_VXRW] = 0.0
                s[_TX] = 0.0
            s[_VX] = vx_prev + inc
            s[_VXRW] += qx
            s[_TX] += dt
        bx = s[_TX] * b_acc
        varx = s[_VX0] + s[_VXRW] + bx * bx
    else:
        s[_VX] = r * wm
        if was_slip and not first:
            d = vx_prev - s[_VX]  # disagreement at the hand-over: one of the two is wrong
            s[_HX] = max(s[_HX] * decay, d * d)
        else:
            s[_HX] *= decay
        sx = slip_sd * s[_VX]
        varx = r * r * g0 * g0 * sig2_wm + sx * sx + s[_HX]
    # Vy: Algorithm 2 with its standard deviation
    if turn:
        qy = dt * dt * (sig2_ay + vx_prev * vx_prev * sig2_gz + wz * wz * varx_prev)
        if not was_turn:
            s[_VY0] = vary_prev
            s[_VYRW] = qy
            s[_TY] = dt
        else:
            s[_VYRW] += qy
            s[_TY] += dt
        s[_VY] = vy_prev + dt * (ay - wz * vx_prev)
        by2 = (b_acc * b_acc + vx_prev * vx_prev * b_gyro * b_gyro) * s[_TY] * s[_TY]
        vary = s[_VY0] + s[_VYRW] + by2
    else:
        s[_VY] = 0.0
        sy = L1 * e2  # kinematic side-slip bound while |psi_dot| < eps2
        vary = sy * sy
    if first:
        vary = (L1 * e2) ** 2
    s[_VARX] = varx
    s[_VARY] = vary
    hist[0, hpos] = s[_VX]
    hist[1, hpos] = varx
    hist[3, hpos] = r * wm
    hpos += 1
    if hpos == K:
        hpos = 0
    s[_HPOS] = hpos
    s[_NSTEP] += 1.0
    out[0] = s[_VX]
    out[1] = s[_VY]
    out[2] = s[_GX]
    out[3] = s[_GY]
    out[4] = dgx
    out[5] = dgy
    out[6] = 1.0 if slip else 0.0
    out[7] = 1.0 if turn else 0.0
    out[8] = wz
    out[9] = wz_dot
    out[10] = ax
    out[11] = ay
    out[12] = wm
    out[13] = wm_dot
    out[14] = np.sqrt(varx)
    out[15] = np.sqrt(vary)
    out[16] = np.sqrt(sig2_gz)
    out[17] = np.sqrt(sig2_ax)
    out[18] = np.sqrt(sig2_ay)
    out[19] = np.sqrt(sig2_wm)


@njit(cache=True)
def _run(b0, b1, p, buf, hist, s, Z, outs):
    for i in range(Z.shape[0]):
        _core(b0, b1, p, buf, hist, s, Z[i], outs[i])


class Result(NamedTuple):
    """:func:`run`'s output: ``final`` the state after the last sample and ``outputs`` (n,
    len(:data:`OUTPUTS`)) the per-sample columns, also readable by name (``res.vy``,
    ``res.slip_mode``; ``speed`` and ``speed_std`` are ``vx`` and ``vx_std``). In this order,
    so ``state, outputs = run(...)`` unpacks it."""

    final: State
    outputs: np.ndarray

    def __getattr__(self, name: str) -> np.ndarray:
        if name.startswith("__"):
            raise AttributeError(name)
        col = _ALIAS.get(name, name)
        if col not in OUTPUTS:
            raise AttributeError(f"algebraic.Result has no column '{name}'")
        return tuple.__getitem__(self, 1)[:, OUTPUTS.index(col)]


#: the Estimate's and Track's names of the outputs ``vx``, ``vx_std``
_ALIAS = {"speed": "vx", "speed_std": "vx_std"}


def _estimate(out: np.ndarray) -> Estimate:
    vals = dict(zip(OUTPUTS, out, strict=True))
    return Estimate(speed=vals.pop("vx"), speed_std=vals.pop("vx_std"), extras=vals)


def step(config: Config, state: State, y, taps=None) -> tuple[State, Estimate]:
    """One sample ``y = (gz, ax, ay, omega_mean)``; returns the new state and the estimate
    (``speed`` = vx, ``speed_std`` = vx_std, the other :data:`OUTPUTS` as extras). Pass
    ``taps = config.taps()`` to avoid recomputing kernels."""
    b0, b1 = config.taps() if taps is None else taps
    buf = state.buf.copy()
    hist = state.hist.copy()
    s = state.s.copy()
    out = np.empty(len(OUTPUTS))
    _core(b0, b1, config.scalars(), buf, hist, s, np.asarray(y, dtype=np.float64), out)
    return State(buf, hist, s), _estimate(out)


def run(config: Config, y: np.ndarray, state: State | None = None) -> Result:
    """All samples ``y`` (n, 4) (columns :data:`INPUTS`); outputs (n, len(OUTPUTS)),
    identical to repeated :func:`step`."""
    st = init(config) if state is None else state
    Z = np.ascontiguousarray(y, dtype=np.float64)
    if Z.ndim != 2 or Z.shape[1] != 4:
        raise ParameterError(f"algebraic.run expects (n, 4) inputs {INPUTS}, got {Z.shape}")
    b0, b1 = config.taps()
    buf = st.buf.copy()
    hist = st.hist.copy()
    s = st.s.copy()
    outs = np.empty((Z.shape[0], len(OUTPUTS)))
    _run(b0, b1, config.scalars(), buf, hist, s, Z, outs)
    return Result(State(buf, hist, s), outs)


# -- recordings -----------------------------------------------------------------------------
def _uniform_grid(recording: Recording) -> tuple[np.ndarray, bool]:
    t = recording.t
    if recording.is_uniform(0.05):
        return t, False
    dt = recording.dt
    n = int(np.ceil((t[-1] - t[0]) / dt - 1e-9)) + 1  # the grid covers the last time stamp
    return t[0] + dt * np.arange(n), True


def _interp_finite(tq: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Linear interpolation over the finite samples, edge values held outside them."""
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return np.full(tq.shape, np.nan)
    return np.interp(tq, t[ok], x[ok])


def estimate(
    recording: Recording,
    *,
    axis: str | None = None,
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Vx (``speed``) and Vy (``extras['vy']``) of a recording with ``gz, ax, ay`` and the four
    ``wheel_omega_*`` channels.

    ``wheel_radius``: argument, else ``recording.wheel_radius``, else ``meta['wheel_radius']``.
    ``params`` may set any :class:`Config` field; ``L1`` defaults to ``meta['L1']``. ``axis`` is
    not used (the channels are fixed). A non-uniform time line is resampled (linear
    interpolation) to its median period and the results interpolated back.
    """
    del axis, progress
    src = recording.source or "recording"
    params = dict(params or {})
    recording.require("gz", "ax", "ay", *WHEEL_CHANNELS)
    r = wheel_radius or params.pop("r", None) or recording.wheel_radius
    r = r or recording.meta.get("wheel_radius")
    if not r:
        raise ParameterError(f"{src}: the algebraic method needs the wheel radius (--wheel-radius)")
    L1 = params.pop("L1", None) or recording.meta.get("L1")
    if not L1:
        raise ParameterError(f"{src}: the algebraic method needs L1, the CG to front axle "
                             "distance in m (--param L1=...)")
    if len(recording) < 3:
        raise InputError(f"{src}: fewer than 3 samples")
    tg, resampled = _uniform_grid(recording)
    dt = float(np.median(np.diff(tg)))
    cfg = config_from_params(Config, params, r=float(r), L1=float(L1), dt=dt)
    W = np.stack([recording.channel(c) for c in WHEEL_CHANNELS], axis=1)
    fin = np.isfinite(W)
    cnt = fin.sum(axis=1)
    wm = np.full(len(recording), np.nan)
    wm[cnt > 0] = np.where(fin, W, 0.0).sum(axis=1)[cnt > 0] / cnt[cnt > 0]  # mean of finite
    cols = [recording.channel("gz"), recording.channel("ax"), recording.channel("ay"), wm]
    if resampled:
        cols = [_interp_finite(tg, recording.t, c) for c in cols]
    _, out = run(cfg, np.stack(cols, axis=1))
    notes = [f"algebraic: r = {cfg.r:g} m, L1 = {cfg.L1:g} m, Ts = {dt * 1e3:.4g} ms, windows "
             f"{cfg.window:g} / {cfg.window_d:g} s, N = {cfg.N}"]
    if resampled:
        notes.append(f"non-uniform time line resampled to {dt * 1e3:.4g} ms and back (linear)")
        out = np.stack([_interp_finite(recording.t, tg, out[:, j]) for j in range(out.shape[1])],
                       axis=1)
    extras = {name: out[:, j].copy() for j, name in enumerate(OUTPUTS)
              if name not in ("vx", "vx_std")}
    return Track.from_speed(
        recording.t, out[:, 0], out[:, OUTPUTS.index("vx_std")], wheel_radius=float(r),
        method="algebraic",
        params={k: v for k, v in asdict(cfg).items()}, extras=extras, notes=notes,
    )
