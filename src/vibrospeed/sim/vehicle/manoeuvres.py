"""What drives the vehicle model of :mod:`vibrospeed.sim.vehicle`: the named manoeuvres
(:data:`SCENARIOS`, :func:`scenario`: braking with ABS, combined braking and steering,
slalom, gradual slip) and the randomised family (:func:`random_config` draws a car, its
tyres, ABS and sensors; :func:`random_controls` a drive of events under a closed-loop
driver; :data:`RANDOM_RANGES`). Controls are ``(n, 3)`` arrays, one row
``(delta, T_drive, T_brake)`` per output sample (steering angle at the wheels in rad,
torques in N m).
"""

from __future__ import annotations

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.sim.vehicle.model import _NO, Config, G, _pack, _run, init


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
