# Over 500 lines: one vehicle model (two-track body, wheel dynamics, tyre forces) in one compiled
# loop, with its manoeuvres and randomised drives; the parameters and equations belong together.
"""Planar two-track vehicle simulator with wheel dynamics and a friction-limited tyre model.

Ground truth for the algebraic Vx / Vy estimator (METHODS.md section 4; the seed used a 14-DOF
simulator, section V). Self-contained: it returns a :class:`vibrospeed.types.Recording` with
``gz`` (yaw rate), ``ax``, ``ay`` (accelerations in the rotating body frame at the centre of
gravity), ``wheel_omega_fl/fr/rl/rr``, truth ``speed_true`` (= Vx) and ``vy_true``, and
``meta`` holding ``L1`` (CG to front axle, m), the wheel radius and the true slip ratios.

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

from dataclasses import asdict, dataclass
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import ParameterError
from vibrospeed.types import Recording

G = 9.80665
WHEELS = ("fl", "fr", "rl", "rr")


@dataclass(frozen=True)
class Config:
    """Vehicle, tyre, integration and sensor parameters (defaults: a mid-size sedan)."""

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
# outputs per sample: [vx, vy, wz, ax, ay, w1..w4, s1..s4] (15,)
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


# -- manoeuvres ---------------------------------------------------------------------------------
def _knots(t: np.ndarray, knots: list[tuple[float, float, float, float]]) -> np.ndarray:
    k = np.asarray(knots, dtype=np.float64)
    return np.stack([np.interp(t, k[:, 0], k[:, j]) for j in (1, 2, 3)], axis=1)


SCENARIOS = {
    "braking": "25 m/s cruise, hard braking with ABS slip 2-4.5 s, wheel-spin acceleration 7-9 s",
    "combined": "steering up to ~0.8 g with braking and acceleration in the turns (seed Fig. 4)",
    "slalom": "sinusoidal steering at 20 m/s with moderate torque changes",
    "gradual": "25 m/s, brake torque ramped over 0.3 s to 0.8 mu g demand held 3 s (slip builds "
               "up gradually to a steady 3-8 %, below the ABS threshold), then drive torque "
               "ramped over 0.5 s to 0.4 mu g for 1.5 s",
    "random": "seeded random drive (needs seed=): braking / acceleration / turn events of "
              "random strength, torque ramps 0.1-1 s, 5-35 m/s (see random_config for the car)",
}


def scenario(name: str, config: Config, *, seed: int | None = None) -> tuple[float, np.ndarray]:
    """``(v0, controls (n, 3))`` of a named manoeuvre (:data:`SCENARIOS`).

    Torques are scaled with ``mu`` so that each manoeuvre demands more than the road can give
    (the wheels slip) at every friction level, as the seed's identical driver actions do.
    ``"random"`` draws its events from ``seed`` (:func:`random_controls`).
    """
    dt = config.dt
    W = config.m * G * config.R  # torque giving 1 g without slip
    if name == "random":
        if seed is None:
            raise ParameterError("scenario 'random' needs seed=")
        return random_controls(config, seed)
    if name == "braking":
        T = 12.0
        knots = [
            (0.0, 0, 0, 0), (2.0, 0, 0, 0), (2.3, 0, 0, 1.3 * W), (4.5, 0, 0, 1.3 * W),
            (4.7, 0, 0, 0), (7.0, 0, 0, 0), (7.2, 0, 0.9 * W, 0), (9.0, 0, 0.9 * W, 0),
            (9.2, 0, 0.02 * W, 0), (T, 0, 0.02 * W, 0),
        ]
        v0 = 25.0
    elif name == "gradual":
        T = 10.0
        Wm = W * config.mu
        knots = [
            (0.0, 0, 0.02 * W, 0), (1.9, 0, 0.02 * W, 0), (2.0, 0, 0, 0), (2.3, 0, 0, 0.8 * Wm),
            (5.3, 0, 0, 0.8 * Wm), (5.6, 0, 0, 0), (6.0, 0, 0.02 * W, 0), (6.5, 0, 0.02 * W, 0),
            (7.0, 0, 0.4 * Wm, 0), (8.5, 0, 0.4 * Wm, 0), (8.8, 0, 0.02 * W, 0),
            (T, 0, 0.02 * W, 0),
        ]
        v0 = 25.0
    elif name == "combined":
        T = 16.0
        d = 0.055 * config.mu / 0.9  # rad at the wheels; lateral demand ~0.8 mu g at 22 m/s
        knots = [
            (0.0, 0, 0.02 * W, 0), (1.0, 0, 0.02 * W, 0), (2.0, d, 0.02 * W, 0),
            (3.5, d, 0.02 * W, 0), (3.7, d, 0, 0.12 * W), (4.5, d, 0, 0.12 * W),
            (5.0, 0, 0.02 * W, 0), (5.5, 0, 0, 0), (5.7, 0, 0, 1.2 * W), (7.0, 0, 0, 1.2 * W),
            (7.2, 0, 0.02 * W, 0), (8.0, -d, 0.02 * W, 0), (10.0, -d, 0.02 * W, 0),
            (10.2, -d, 0.1 * W, 0), (11.0, 0, 0.1 * W, 0), (11.5, 0, 0.02 * W, 0),
            (12.0, 0, 0.8 * W, 0), (13.5, 0, 0.8 * W, 0), (13.7, 0, 0.02 * W, 0),
            (T, 0, 0.02 * W, 0),
        ]
        v0 = 22.0
    elif name == "slalom":
        T = 14.0
        t = np.arange(int(round(T / dt))) * dt
        u = np.zeros((t.size, 3))
        u[:, 0] = 0.05 * np.sin(2 * np.pi * 0.4 * t) * np.clip(t - 1.0, 0, 1)
        u[:, 1] = 0.03 * W + 0.1 * W * np.sin(2 * np.pi * 0.13 * t)
        return 20.0, u
    else:
        raise ParameterError(f"unknown scenario '{name}' (choose from: {', '.join(SCENARIOS)})")
    t = np.arange(int(round(T / dt))) * dt
    return v0, _knots(t, knots)


# -- randomised family ------------------------------------------------------------------------
#: ranges of :func:`random_config` / :func:`random_controls` (uniform unless stated)
RANDOM_RANGES = {
    "mu": (0.3, 1.0), "peak slip (front)": (0.08, 0.2), "B_rear / B": (1.0, 1.5),
    "C": (1.3, 1.9),
    "tyre": "magic or brush (1:1)", "ABS / traction control": "present with p = 0.6",
    "abs_slip": "0.7-1.5 x the tyre's peak slip", "abs_rate 1/s": (5.0, 30.0),
    "rate Hz": (50, 200), "sd_gz rad/s": (0.002, 0.02), "sd_acc m/s^2": (0.03, 0.3),
    "sd_omega rad/s": (0.03, 0.3), "bias_ax, bias_ay m/s^2": "normal sd 0.05, clipped to 0.15",
    "bias_gz rad/s": "normal sd 0.002", "m kg": (1100.0, 2300.0), "L1 m": (1.0, 1.5),
    "drive": "rear, front or 50/50", "v0 m/s": (8.0, 33.0), "duration s": 20.0,
    "torque ramp s": "log-uniform 0.1-1", "brake / drive demand": "0.2-1.6 x mu g",
    "lateral demand": "0.2-0.8 x mu g", "engine power W/kg": (60.0, 150.0),
}


def random_config(seed: int) -> Config:
    """A vehicle of the randomised family: tyre (magic formula or brush, shape C, stiffness B
    from a slip at the force peak of 8-20 %, peak mu 0.3-1.0), ABS / traction control or none,
    sensor noise and biases of production size and a sample rate of 50-200 Hz, all drawn from
    ``seed`` (:data:`RANDOM_RANGES`)."""
    rng = np.random.default_rng([int(seed), 0])
    u = rng.uniform
    C = u(1.3, 1.9)
    tyre = "brush" if rng.random() < 0.5 else "magic"
    peak = u(0.08, 0.2)  # slip at the force peak: brush 3 / (B C), magic formula tan(pi / 2C) / B
    B = 3.0 / (C * peak) if tyre == "brush" else np.tan(np.pi / (2.0 * C)) / peak
    has_abs = rng.random() < 0.6
    fs = int(round(u(50.0, 200.0)))
    dt = 1.0 / fs
    drive = float(rng.choice([0.0, 1.0, 0.5]))
    L1 = u(1.0, 1.5)
    return Config(
        m=u(1100.0, 2300.0), L1=L1, L2=L1 * u(1.0, 1.4), mu=u(0.3, 1.0), B=B,
        B_rear=B * u(1.0, 1.5), C=C, tyre=tyre, implicit_wheels=True, drive_front=drive,
        abs_slip=peak * u(0.7, 1.5) if has_abs else 0.0, abs_rate=u(5.0, 30.0), dt=dt,
        substeps=max(1, int(round(dt / 0.0005))),
        sd_gz=u(0.002, 0.02), sd_acc=u(0.03, 0.3), sd_omega=u(0.03, 0.3),
        bias_gz=float(np.clip(rng.normal(0.0, 0.002), -0.006, 0.006)),
        bias_ax=float(np.clip(rng.normal(0.0, 0.05), -0.15, 0.15)),
        bias_ay=float(np.clip(rng.normal(0.0, 0.05), -0.15, 0.15)),
    )


def random_controls(config: Config, seed: int, duration: float = 20.0,
                    ) -> tuple[float, np.ndarray]:
    """``(v0, controls)`` of a random drive for ``config`` drawn from ``seed``: cruising gaps
    and events (brake, drive, turn, turn with brake or drive) of random strength (0.2-1.6 mu g
    demand, enough to lock or spin a wheel without ABS), torque ramped up over 0.1-1 s
    (log-uniform), held 0.5-3 s, released over 0.1-0.5 s; lateral demand 0.2-0.8 mu g. A
    closed-loop driver (checked every 50 ms) releases the brakes below 5 m/s (until 8 m/s) and
    the throttle above 33 m/s (until 30 m/s), and the engine's power (60-150 W/kg) limits the
    drive torque. A drive in which the car spins (side slip over 0.15 Vx + 0.5 m/s) or slows
    below 2 m/s is drawn again (next sub-stream)."""
    for attempt in range(50):
        rng = np.random.default_rng([int(seed), 1, attempt])
        v0, u, ok = _random_attempt(config, rng, duration)
        if ok:
            return v0, u
    raise RuntimeError(f"random_controls: no stable drive for seed {seed}")  # pragma: no cover


def _random_attempt(config: Config, rng: np.random.Generator, duration: float):
    dt = config.dt
    n = int(round(duration / dt))
    W = config.m * G * config.R
    Wm = W * config.mu
    L = config.L1 + config.L2
    v0 = rng.uniform(8.0, 33.0)
    power = config.m * rng.uniform(60.0, 150.0)
    # event plan: (start, kind, demand, ramp, hold, release, lateral demand, steer ramp, sign)
    plan = []
    t = rng.uniform(0.5, 2.0)
    while t < duration - 1.0:
        kind = rng.choice(["brake", "drive", "turn", "turn+brake", "turn+drive"],
                          p=[0.3, 0.25, 0.15, 0.15, 0.15])
        ramp = float(np.exp(rng.uniform(np.log(0.1), np.log(1.0))))
        hold = rng.uniform(0.5, 3.0)
        rel = rng.uniform(0.1, 0.5)
        plan.append((t, str(kind), rng.uniform(0.2, 1.6), ramp, hold, rel,
                     rng.uniform(0.2, 0.8), rng.uniform(0.3, 1.0), rng.choice([-1.0, 1.0])))
        t += ramp + hold + rel + rng.uniform(0.5, 2.5)
    chunk = max(1, int(round(0.05 / dt)))
    u = np.zeros((n, 3))
    p = config.params()
    s = _pack(init(config, v0))
    outs = np.zeros((chunk, _NO))
    ev = 0
    ok = True
    df = config.drive_front
    fb = ft = 1.0  # driver's brake / throttle release factors
    brake_ok = drive_ok = True
    for k0 in range(0, n, chunk):
        k1 = min(n, k0 + chunk)
        vx = s[0]
        # brakes released below 5 m/s until 8 m/s, throttle above 33 m/s until 30 m/s
        brake_ok = vx > 8.0 or (brake_ok and vx > 5.0)
        drive_ok = vx < 30.0 or (drive_ok and vx < 33.0)
        w_drive = df * 0.5 * (s[3] + s[4]) + (1.0 - df) * 0.5 * (s[5] + s[6])
        t_max = power / max(abs(w_drive), 1.0)
        while ev + 1 < len(plan) and k0 * dt >= plan[ev + 1][0]:
            ev += 1
        for k in range(k0, k1):
            tt = k * dt
            fb = min(1.0, fb + dt / 0.3) if brake_ok else max(0.0, fb - dt / 0.3)
            ft = min(1.0, ft + dt / 0.3) if drive_ok else max(0.0, ft - dt / 0.3)
            cruise = 0.5 * 1.2 * config.CdA * vx * abs(vx) * config.R + 0.01 * W
            delta, td, tb = 0.0, cruise, 0.0
            if plan and tt >= plan[ev][0]:
                t0, kind, dem, ramp, hold, rel, lat, sramp, sgn = plan[ev]
                x = tt - t0
                end = ramp + hold + rel
                if x < end:
                    env = min(1.0, x / ramp) if x < ramp + hold else max(0.0, (end - x) / rel)
                    if "brake" in kind:
                        tb = dem * Wm * env * fb
                        td = 0.0
                    if "drive" in kind:
                        td = cruise + max(0.0, dem * Wm * env - cruise) * ft
                    if "turn" in kind:
                        senv = min(1.0, x / sramp) if x < ramp + hold else max(0.0, (end - x) / rel)
                        v = max(abs(vx), 5.0)
                        delta = sgn * min(0.3, lat * config.mu * G * L / (v * v)) * senv
            u[k] = (delta, min(td, t_max), tb)
        _run(p, s, u[k0:k1], int(config.substeps), outs[: k1 - k0])
        o = outs[: k1 - k0]
        if np.any(np.abs(o[:, 1]) > 0.15 * np.abs(o[:, 0]) + 0.5) or np.any(o[:, 0] < 2.0):
            ok = False
            break
    return float(v0), u, ok


def simulate_random(seed: int, **overrides) -> Recording:
    """One drive of the randomised family: :func:`random_config` (``overrides`` replace its
    fields, e.g. ``mu=0.5``) driven by :func:`random_controls`; sensor noise from ``seed``."""
    cfg = random_config(seed)
    if overrides:
        cfg = Config(**{**asdict(cfg), **overrides})
    return simulate(cfg, np.random.default_rng([int(seed), 2]), name="random", seed=seed)


def measure(config: Config, outs: np.ndarray, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """Noisy sensor channels from the outputs of :func:`run` (white Gaussian noise, biases)."""
    n = outs.shape[0]
    ch = {
        "gz": outs[:, 2] + config.bias_gz + config.sd_gz * rng.standard_normal(n),
        "ax": outs[:, 3] + config.bias_ax + config.sd_acc * rng.standard_normal(n),
        "ay": outs[:, 4] + config.bias_ay + config.sd_acc * rng.standard_normal(n),
    }
    for i, w in enumerate(WHEELS):
        ch[f"wheel_omega_{w}"] = outs[:, 5 + i] + config.sd_omega * rng.standard_normal(n)
    return ch


def simulate(
    config: Config,
    rng: np.random.Generator,
    *,
    name: str = "braking",
    controls: np.ndarray | None = None,
    v0: float | None = None,
    seed: int | None = None,
) -> Recording:
    """Run a scenario (or explicit ``controls`` from ``v0``) and return a noisy :class:`Recording`.

    Sample ``k`` holds the state at ``t_k = (k + 1) dt`` after applying ``controls[k]``.
    ``seed`` draws the events of ``name = "random"`` (:func:`simulate_random` also draws the car).
    """
    if not isinstance(rng, np.random.Generator):
        raise ParameterError("rng must be a numpy.random.Generator (np.random.default_rng(seed))")
    if controls is None:
        v0_s, controls = scenario(name, config, seed=seed)
        v0 = v0_s if v0 is None else v0
        source = f"sim.vehicle:{name}"
    else:
        if v0 is None:
            raise ParameterError("v0 is required with explicit controls")
        source = "sim.vehicle:custom"
    _, outs = run(config, init(config, v0), controls)
    ch = measure(config, outs, rng)
    ch["speed_true"] = outs[:, 0].copy()
    ch["vy_true"] = outs[:, 1].copy()
    return Recording(
        t=outs[:, 13].copy(),
        channels=ch,
        source=source,
        wheel_radius=config.R,
        notes=[f"simulated, mu = {config.mu}, noise sd gz {config.sd_gz} rad/s, "
               f"acc {config.sd_acc} m/s^2, omega {config.sd_omega} rad/s"],
        meta={
            "L1": config.L1,
            "wheel_radius": config.R,
            "mu": config.mu,
            "scenario": name if source != "sim.vehicle:custom" else "custom",
            "seed": seed,
            "config": asdict(config),
            "slip": outs[:, 9:13].copy(),
            "yaw_rate_true": outs[:, 2].copy(),
            "ax_true": outs[:, 3].copy(),
            "ay_true": outs[:, 4].copy(),
            "omega_true": outs[:, 5:9].copy(),
            "controls": np.asarray(controls, dtype=np.float64).copy(),
        },
    )
