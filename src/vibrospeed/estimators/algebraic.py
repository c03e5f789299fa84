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
3. Algorithm 1: if ``|dGx/dt| < eps1`` over ``[t_i - alpha Ts, t_i]``:
   ``Vx = r omega_mean`` (wheels roll), else
   ``Vx(t_i) = Vx(t_{i-1}) + Ts (gamma_x + psi_dot Vy)``;
4. Algorithm 2: if ``|psi_dot| < eps2`` over ``[t_i - beta Ts, t_i]``: ``Vy = 0``, else
   ``Vy(t_i) = Vy(t_{i-1}) + Ts (gamma_y - psi_dot Vx)``.

Both updates use the previous sample's ``Vx``, ``Vy`` (explicit Euler, as the seed's fixed
integration step). NaN inputs are held at their last finite value (zero-order hold).
The seed gives no numbers for its thresholds (its Table I is lost in the text); the defaults
here were tuned on :mod:`vibrospeed.sim.vehicle` (see docs/algebraic.md).
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
from vibrospeed.types import WHEEL_CHANNELS, Recording, Track

#: inputs, in this order, of :func:`step`
INPUTS = ("gz", "ax", "ay", "omega_mean")
#: per-sample outputs of :func:`step` / :func:`run`
OUTPUTS = (
    "vx", "vy", "gx", "gy", "dgx", "dgy", "slip_mode", "turn_mode",
    "yaw_rate", "yaw_acc", "ax", "ay", "omega_mean", "omega_dot",
)


@dataclass(frozen=True)
class Config:
    """Parameters of Algorithms 1 and 2.

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

    def __post_init__(self) -> None:
        for name in ("r", "L1", "dt", "window", "window_d", "eps1", "eps2"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"algebraic: {name} must be > 0, got {getattr(self, name)}")
        for name in ("alpha", "beta", "reset_hold"):
            v = getattr(self, name)
            if int(v) != v or v < 0:
                raise ParameterError(f"algebraic: {name} must be an integer >= 0, got {v}")
        if self.N < 1:
            raise ParameterError(
                f"algebraic: N must be >= 1 (derivatives are needed), got {self.N}")
        self.filters()  # validates the windows against N

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
        return np.array([self.r, self.L1, self.dt, self.eps1, self.alpha, self.eps2, self.beta,
                         self.reset_eps_x, self.reset_eps_y, self.reset_hold, self.vy0])


class State(NamedTuple):
    """Ring buffers ``buf`` (4, L) of ``INPUTS``, and ``s`` (13,) packed scalars:
    ``[Gx, Gy, Vx, Vy, n_x, n_y, n_reset, pos, started, last gz, ax, ay, omega_mean]``
    (``n_*``: consecutive samples the switching / reset conditions have held)."""

    buf: np.ndarray
    s: np.ndarray

    @property
    def vx(self) -> float:
        return float(self.s[2])

    @property
    def vy(self) -> float:
        return float(self.s[3])


def init(config: Config) -> State:
    """Empty state: the first finite sample fills the buffers and sets ``Vx = r omega_mean``."""
    L = config.taps()[0].size
    s = np.zeros(13)
    s[9:13] = np.nan
    return State(np.zeros((4, L)), s)


@njit(cache=True)
def _core(b0, b1, p, buf, s, z, out):
    """One sample of Algorithms 1 and 2 in place on ``buf``, ``s``; outputs to ``out`` (14,)."""
    r, L1, dt, eps1, alpha, eps2, beta = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    rex, rey, rhold, vy0 = p[7], p[8], p[9], p[10]
    L = b0.size
    # zero-order hold of NaN inputs
    ok = True
    for j in range(4):
        if np.isfinite(z[j]):
            s[9 + j] = z[j]
        elif not np.isfinite(s[9 + j]):
            ok = False
    if not ok:
        out[:] = np.nan
        return
    pos = int(s[7])
    if s[8] == 0.0:  # first sample: steady-state buffers, wheels roll, Vy = vy0
        for j in range(4):
            buf[j, :] = s[9 + j]
        s[0] = 0.0
        s[1] = 0.0
        s[2] = r * s[12]
        s[3] = vy0
        s[4] = alpha + 1.0
        s[5] = 0.0
        s[6] = 0.0
        s[8] = 1.0
    # algebraic filters (Algorithm 1, line 1)
    f0 = np.zeros(4)
    f1 = np.zeros(4)
    for j in range(4):
        buf[j, pos] = s[9 + j]
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
    s[7] = pos
    wz, ax, ay, wm = f0[0], f0[1], f0[2], f0[3]
    wz_dot, wm_dot = f1[0], f1[3]
    # disturbance system (seed eq. 7), explicit Euler (line 2)
    dgx, dgy = disturbance_rhs(s[0], s[1], wz, wz_dot, wm, wm_dot, ax, ay, r, L1)
    s[0] += dt * dgx
    s[1] += dt * dgy
    # remark 4: reset G when the residual derivatives stay near zero
    if rhold > 0:
        if abs(r * wm_dot) < rex and abs(L1 * wz_dot) < rey:
            s[6] += 1.0
        else:
            s[6] = 0.0
        if s[6] >= rhold:
            s[0] = 0.0
            s[1] = 0.0
    # window-held switching conditions (line 3 of Algorithms 1 and 2)
    s[4] = s[4] + 1.0 if abs(dgx) < eps1 else 0.0
    s[5] = s[5] + 1.0 if abs(wz) < eps2 else 0.0
    vx_prev = s[2]
    vy_prev = s[3]
    slip = s[4] < alpha + 1.0
    turn = s[5] < beta + 1.0
    if slip:
        s[2] = vx_prev + dt * (ax + wz * vy_prev)
    else:
        s[2] = r * wm
    if turn:
        s[3] = vy_prev + dt * (ay - wz * vx_prev)
    else:
        s[3] = 0.0
    out[0] = s[2]
    out[1] = s[3]
    out[2] = s[0]
    out[3] = s[1]
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


@njit(cache=True)
def _run(b0, b1, p, buf, s, Z, outs):
    for i in range(Z.shape[0]):
        _core(b0, b1, p, buf, s, Z[i], outs[i])


def step(config: Config, state: State, z, taps=None) -> tuple[State, np.ndarray]:
    """One sample ``z = (gz, ax, ay, omega_mean)``; returns the new state and the outputs
    (:data:`OUTPUTS`, (14,)). Pass ``taps = config.taps()`` to avoid recomputing kernels."""
    b0, b1 = config.taps() if taps is None else taps
    buf = state.buf.copy()
    s = state.s.copy()
    out = np.empty(len(OUTPUTS))
    _core(b0, b1, config.scalars(), buf, s, np.asarray(z, dtype=np.float64), out)
    return State(buf, s), out


def run(config: Config, Z: np.ndarray, state: State | None = None) -> tuple[State, np.ndarray]:
    """All samples ``Z`` (n, 4); outputs (n, 14), identical to repeated :func:`step`."""
    st = init(config) if state is None else state
    Z = np.ascontiguousarray(Z, dtype=np.float64)
    if Z.ndim != 2 or Z.shape[1] != 4:
        raise ParameterError(f"algebraic.run expects (n, 4) inputs {INPUTS}, got {Z.shape}")
    b0, b1 = config.taps()
    buf = st.buf.copy()
    s = st.s.copy()
    outs = np.empty((Z.shape[0], len(OUTPUTS)))
    _run(b0, b1, config.scalars(), buf, s, Z, outs)
    return State(buf, s), outs


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
    extras = {name: out[:, j].copy() for j, name in enumerate(OUTPUTS) if name != "vx"}
    return Track.from_speed(
        recording.t, out[:, 0], wheel_radius=float(r), method="algebraic",
        params={k: v for k, v in asdict(cfg).items()}, extras=extras, notes=notes,
    )
