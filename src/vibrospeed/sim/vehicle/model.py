"""The two-track vehicle model of :mod:`vibrospeed.sim.vehicle`: its :class:`Config`, the
:class:`State`, the compiled sub-step (body, wheels, tyre forces) and ``init`` / ``step`` /
``run``. The manoeuvres that drive it are in :mod:`~vibrospeed.sim.vehicle.manoeuvres`, the
noisy recording in :mod:`~vibrospeed.sim.vehicle.recording`.

Model (body frame x forward, y left, yaw counter-clockwise +; wheel i at ``(x_i, y_i)``)::

    m (dVx/dt - psi_dot Vy) = sum_i Fx_i - 0.5 rho CdA Vx |Vx|        (seed eq. 2 in force form)
    m (dVy/dt + psi_dot Vx) = sum_i Fy_i
    Iz d(psi_dot)/dt        = sum_i (x_i Fy_i - y_i Fx_i)
    Iw d(omega_i)/dt        = T_drive,i - T_brake,i sign(omega_i) - R Fl_i     (seed eq. 1)

Tyre (combined slip, "similarity" form of a simplified Pacejka magic formula): with the wheel's
velocity ``(vl, vt)`` in its own frame (front wheels turned by the steering angle ``delta``),
practical slips ``sx = (R omega - vl) / max(|vl|, v_eps)``, ``sy = vt / max(|vl|, v_eps)``,
``s = |(sx, sy)|``::

    F = mu Fz sin(C atan(B s)),   Fl = F sx / s,   Ft = -F sy / s

so the force saturates at ``mu Fz`` (peak near ``s = tan(pi / 2C) / B``, 0.15 by default) and a
locked wheel slides at about 0.7 ``mu Fz``. Vertical loads: static split plus load transfer
``m a_x h / L`` (front-rear) and ``m a_y h / track`` (left-right, split like the static
loads), from accelerations low-passed with ``tau_load`` (a crude suspension lag). A simple
ABS / traction control cuts the torque of a wheel whose slip exceeds ``abs_slip`` (ramping a
factor in [0, 1] at ``abs_rate``/s), so wheels really slip at 10-25 % under hard braking /
acceleration, as with a production ABS.

Sensors: white Gaussian noise on every channel, stronger than on production sensors (as the
seed, section V): ``sd_gz`` rad/s, ``sd_acc`` m/s^2, ``sd_omega`` rad/s, optional biases.

Integration: explicit Euler on ``substeps`` sub-steps per output sample (0.5 ms by default;
the wheel-slip dynamics have time constants of a few ms at low speed), controls held constant
over a sample. Brake torque is applied semi-implicitly (it stops a wheel, never reverses it).
``run`` equals repeated ``step`` exactly (same compiled sub-step).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import ParameterError

G = 9.80665
WHEELS = ("fl", "fr", "rl", "rr")


@dataclass(frozen=True)
class Config:
    """Vehicle, tyre, integration and sensor parameters (defaults: a mid-size sedan).

    m : kg, mass.  Iz : kg m^2, yaw inertia.
    L1, L2 : m, centre of gravity to the front / rear axle.
    track : m, track width.  h_cg : m, height of the centre of gravity.
    R : m, wheel radius.  Iw : kg m^2 per wheel (wheel and its share of the drive line).
    mu : road friction coefficient (seed: 0.5 / 0.7 / 0.9).
    B, B_rear : magic-formula stiffness factor of the front / rear tyres (rear stiffer per
        unit load: an understeering car).
    C : magic-formula shape factor.
    tyre : "magic" (falls off to about 0.7 mu past the peak) or "brush" (saturates).
    implicit_wheels : the tyre force on the wheel linearly implicit (stiff tyres).
    CdA : m^2, drag area (air density 1.2).  v_eps : m/s, slip regularisation at low speed.
    tau_load : s, lag of the load-transfer accelerations.
    drive_front, brake_front : share of the drive / brake torque on the front axle.
    abs_slip : |slip| above which ABS / traction control cuts the torque (<= 0: off).
    abs_rate : 1/s, rate of the torque factor of ABS / traction control.
    dt : s, output sample period.  substeps : integration sub-steps per sample.
    sd_gz, sd_acc, sd_omega : white sensor noise sds, rad/s, m/s^2, rad/s.
    bias_gz, bias_ax, bias_ay : constant sensor biases, rad/s, m/s^2, m/s^2.
    """

    m: float = 1500.0  # kg
    Iz: float = 2500.0  # kg m^2
    L1: float = 1.2  # m, CG to front axle
    L2: float = 1.5  # m, CG to rear axle
    track: float = 1.55  # m
    h_cg: float = 0.55  # m
    R: float = 0.31  # m, wheel radius
    Iw: float = 1.2  # kg m^2 per wheel (wheel + share of drive line)
    mu: float = 0.7  # friction coefficient (seed: 0.5 / 0.7 / 0.9)
    B: float = 10.0  # magic-formula stiffness factor (front tyres)
    B_rear: float = 14.0  # rear tyres stiffer per unit load: an understeering car
    C: float = 1.6  # magic-formula shape factor
    tyre: str = "magic"  # "magic" (falls off to ~0.7 mu past the peak) or "brush" (saturates)
    implicit_wheels: bool = False  # tyre force on the wheel linearly implicit (stiff tyres)
    CdA: float = 0.7  # m^2, drag area (rho = 1.2)
    v_eps: float = 1.0  # m/s, slip regularisation at low speed
    tau_load: float = 0.1  # s, lag of the load-transfer accelerations
    drive_front: float = 0.0  # share of drive torque on the front axle (0 = rear drive)
    brake_front: float = 0.7  # share of brake torque on the front axle
    abs_slip: float = 0.2  # |slip| above which ABS / traction control cuts torque (<= 0: off)
    abs_rate: float = 15.0  # 1/s, rate of the torque factor of ABS / traction control
    dt: float = 0.01  # s, output sample period
    substeps: int = 20
    sd_gz: float = 0.02  # rad/s
    sd_acc: float = 0.5  # m/s^2
    sd_omega: float = 0.3  # rad/s
    bias_gz: float = 0.0
    bias_ax: float = 0.0
    bias_ay: float = 0.0

    def __post_init__(self) -> None:
        for name in ("m", "Iz", "L1", "L2", "track", "R", "Iw", "mu", "B", "B_rear", "C", "dt",
                     "v_eps"):
            if not getattr(self, name) > 0:
                raise ParameterError(
                    f"vehicle parameter {name} must be > 0, got {getattr(self, name)}")
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ParameterError(f"substeps must be a positive integer, got {self.substeps}")
        for name in ("drive_front", "brake_front"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ParameterError(f"{name} must lie in [0, 1], got {getattr(self, name)}")
        if self.tyre not in ("magic", "brush"):
            raise ParameterError(f"tyre must be 'magic' or 'brush', got {self.tyre!r}")
        for name in ("sd_gz", "sd_acc", "sd_omega", "tau_load", "CdA", "h_cg"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"{name} must be >= 0, got {getattr(self, name)}")

    def params(self) -> np.ndarray:
        """Packed float64 parameter vector for the compiled sub-step."""
        return np.array([
            self.m, self.Iz, self.L1, self.L2, self.track, self.h_cg, self.R, self.Iw, self.mu,
            self.B, self.C, self.CdA, self.v_eps, self.tau_load, self.drive_front,
            self.brake_front, self.abs_slip, self.abs_rate, self.dt / self.substeps, self.B_rear,
            1.0 if self.tyre == "brush" else 0.0, 1.0 if self.implicit_wheels else 0.0,
        ])


class State(NamedTuple):
    """Vehicle state: velocities at the CG, wheel speeds, internal lags, pose, time."""

    vx: float  # m/s
    vy: float  # m/s
    yaw_rate: float  # rad/s
    omega: np.ndarray  # (4,) rad/s, fl fr rl rr
    ax_lag: float  # m/s^2, low-passed body accelerations for load transfer
    ay_lag: float
    abs_factor: np.ndarray  # (4,) torque factors of ABS / traction control
    x: float  # m, position in the world frame
    y: float
    psi: float  # rad, heading
    t: float  # s


# packed state: [vx, vy, wz, w1..w4, axl, ayl, f1..f4, X, Y, psi, t] (18,)
_NS = 18
# outputs per sample: [vx, vy, wz, ax, ay, w1..w4, s1..s4, t, psi] (15,)
_NO = 15


def _pack(s: State) -> np.ndarray:
    return np.concatenate([[s.vx, s.vy, s.yaw_rate], s.omega, [s.ax_lag, s.ay_lag],
                           s.abs_factor, [s.x, s.y, s.psi, s.t]]).astype(np.float64)


def _unpack(a: np.ndarray) -> State:
    return State(float(a[0]), float(a[1]), float(a[2]), a[3:7].copy(), float(a[7]), float(a[8]),
                 a[9:13].copy(), float(a[13]), float(a[14]), float(a[15]), float(a[16]))


@njit(cache=True)
def _substep(p, s, delta, t_drive, t_brake, out):
    """One Euler sub-step in place on the packed state ``s``; writes the outputs to ``out``."""
    m, Iz, L1, L2, tw, h, R, Iw, mu = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8]
    B, C, CdA, v_eps, tau_l = p[9], p[10], p[11], p[12], p[13]
    dfront, bfront, abs_slip, abs_rate, h_dt, B_rear = p[14], p[15], p[16], p[17], p[18], p[19]
    brush = p[20] > 0.5
    implicit = p[21] > 0.5
    vx, vy, wz = s[0], s[1], s[2]
    L = L1 + L2
    xw = np.array([L1, L1, -L2, -L2])
    yw = np.array([0.5 * tw, -0.5 * tw, 0.5 * tw, -0.5 * tw])
    # vertical loads: static + longitudinal and lateral transfer from lagged accelerations
    fz_front = m * G * L2 / L - m * s[7] * h / L
    fz_rear = m * G * L1 / L + m * s[7] * h / L
    dlat = m * s[8] * h / tw  # total left-minus-right load shift / 2 per side
    fz = np.empty(4)
    fz[0] = 0.5 * fz_front - dlat * L2 / L
    fz[1] = 0.5 * fz_front + dlat * L2 / L
    fz[2] = 0.5 * fz_rear - dlat * L1 / L
    fz[3] = 0.5 * fz_rear + dlat * L1 / L
    # positive a_y (to the left) loads the right-hand (outer) wheels
    fsum_x = 0.0
    fsum_y = 0.0
    mz = 0.0
    slip = np.empty(4)
    fl_arr = np.empty(4)
    kw = np.zeros(4)  # d(force)/d(omega) proxy: R (F / s) / den, for the implicit wheel update
    for i in range(4):
        fzi = max(fz[i], 50.0)
        vxw = vx - wz * yw[i]
        vyw = vy + wz * xw[i]
        d = delta if i < 2 else 0.0
        cd = np.cos(d)
        sd = np.sin(d)
        vl = vxw * cd + vyw * sd
        vt = -vxw * sd + vyw * cd
        den = max(abs(vl), v_eps)
        sx = (R * s[3 + i] - vl) / den
        sy = vt / den
        sn = np.sqrt(sx * sx + sy * sy)
        slip[i] = sx
        if sn > 1e-12:
            Bi = B if i < 2 else B_rear
            if brush:  # parabolic-pressure brush, same small-slip stiffness B C mu Fz
                th = Bi * C * sn / 3.0
                F = mu * fzi * (3.0 * th - 3.0 * th * th + th * th * th) if th < 1.0 else mu * fzi
            else:
                F = mu * fzi * np.sin(C * np.arctan(Bi * sn))
            fl = F * sx / sn
            ft = -F * sy / sn
            kw[i] = R * F / sn / den
        else:
            fl = 0.0
            ft = 0.0
            kw[i] = R * mu * fzi * (B if i < 2 else B_rear) * C / den
        fl_arr[i] = fl
        fxb = fl * cd - ft * sd
        fyb = fl * sd + ft * cd
        fsum_x += fxb
        fsum_y += fyb
        mz += xw[i] * fyb - yw[i] * fxb
    drag = 0.5 * 1.2 * CdA * vx * abs(vx)
    gam_x = (fsum_x - drag) / m
    gam_y = fsum_y / m
    # body dynamics (seed eq. 2): dVx = gamma_x + wz Vy, dVy = gamma_y - wz Vx
    s[0] = vx + h_dt * (gam_x + wz * vy)
    s[1] = vy + h_dt * (gam_y - wz * vx)
    s[2] = wz + h_dt * mz / Iz
    # wheels: drive torque explicit, brake torque semi-implicit (never reverses a wheel)
    for i in range(4):
        share_d = dfront if i < 2 else 1.0 - dfront
        share_b = bfront if i < 2 else 1.0 - bfront
        f = s[9 + i]
        td = 0.5 * share_d * t_drive * f
        tb = 0.5 * share_b * t_brake * f
        # linearly implicit in the tyre force (stable for stiff tyres) or explicit
        iw = Iw + h_dt * R * kw[i] if implicit else Iw
        w = s[3 + i] + h_dt * (td - R * fl_arr[i]) / iw
        dw = h_dt * tb / iw
        if w > dw:
            w -= dw
        elif w < -dw:
            w += dw
        else:
            w = 0.0
        s[3 + i] = w
        if abs_slip > 0.0:
            if abs(slip[i]) > abs_slip:
                f -= abs_rate * h_dt
            else:
                f += abs_rate * h_dt
            s[9 + i] = min(1.0, max(0.0, f))
    # load-transfer lag and pose
    if tau_l > 0.0:
        a = h_dt / (tau_l + h_dt)
        s[7] += a * (gam_x - s[7])
        s[8] += a * (gam_y - s[8])
    else:
        s[7] = gam_x
        s[8] = gam_y
    cpsi = np.cos(s[15])
    spsi = np.sin(s[15])
    s[13] += h_dt * (vx * cpsi - vy * spsi)
    s[14] += h_dt * (vx * spsi + vy * cpsi)
    s[15] += h_dt * wz
    s[16] += h_dt
    out[0] = s[0]
    out[1] = s[1]
    out[2] = s[2]
    out[3] = gam_x
    out[4] = gam_y
    for i in range(4):
        out[5 + i] = s[3 + i]
        out[9 + i] = slip[i]


@njit(cache=True)
def _sample(p, s, u, nsub, out):
    """``nsub`` sub-steps with controls ``u = (delta, T_drive, T_brake)`` held."""
    for _ in range(nsub):
        _substep(p, s, u[0], u[1], u[2], out)
    # sample outputs: state at the end of the sample, accelerations of the last sub-step
    out[13] = s[16]
    out[14] = s[15]


@njit(cache=True)
def _run(p, s, controls, nsub, outs):
    for k in range(controls.shape[0]):
        _sample(p, s, controls[k], nsub, outs[k])


def init(config: Config, v0: float, *, vy0: float = 0.0, yaw_rate0: float = 0.0) -> State:
    """Straight-line rolling start at ``v0`` m/s (wheels at ``v0 / R``, no slip)."""
    if not np.isfinite(v0):
        raise ParameterError(f"initial speed must be finite, got {v0}")
    return State(float(v0), float(vy0), float(yaw_rate0), np.full(4, v0 / config.R), 0.0, 0.0,
                 np.ones(4), 0.0, 0.0, 0.0, 0.0)


def _check_u(u) -> np.ndarray:
    u = np.ascontiguousarray(u, dtype=np.float64)
    if u.shape[-1] != 3:
        raise ParameterError(
            f"controls must be (delta rad, T_drive N m, T_brake N m), got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise ParameterError("controls contain NaN or inf")
    return u


def step(config: Config, state: State, u) -> tuple[State, np.ndarray]:
    """Advance one output sample ``dt`` with controls ``u = (delta, T_drive, T_brake)``.

    Returns the new state and the noise-free outputs ``(15,)``:
    ``[vx, vy, yaw_rate, gamma_x, gamma_y, omega_fl, omega_fr, omega_rl, omega_rr,
    slip_fl, slip_fr, slip_rl, slip_rr, t, psi]``.
    """
    s = _pack(state)
    out = np.zeros(_NO)
    _sample(config.params(), s, _check_u(u), int(config.substeps), out)
    return _unpack(s), out


def run(config: Config, state: State, controls: np.ndarray) -> tuple[State, np.ndarray]:
    """Advance ``len(controls)`` samples; outputs ``(n, 15)`` identical to repeated :func:`step`."""
    u = _check_u(controls).reshape(-1, 3)
    s = _pack(state)
    outs = np.zeros((u.shape[0], _NO))
    _run(config.params(), s, u, int(config.substeps), outs)
    return _unpack(s), outs
