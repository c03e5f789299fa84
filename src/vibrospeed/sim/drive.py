"""Assemble a simulated drive: exact motion -> vibrations, IMU, wheels, ticks, GPS -> Recording.

Specific force measured by the accelerometer (body frame x forward, y left, z up; road grade
``g_r`` > 0 uphill)::

    ax = dv/dt + g sin(g_r) + s_x + b_x + n_x
    ay = v * yaw_rate       + s_y + b_y + n_y       (centripetal acceleration in turns)
    az = g cos(g_r)         + s_z + b_z + n_z       (+9.80665 m/s^2 when level)

with vibrations ``s`` (:mod:`vibrospeed.sim.vibration`), constant biases ``b`` and white noise
``n``. Gyros: ``gz = yaw_rate + b + n``; ``gy = -d g_r / dt + b + n`` (nose-up pitching is a
negative rotation about the left-pointing y axis); ``gx = b + n``.

Randomness: one :class:`numpy.random.Generator` is split (``spawn``) into fixed, independent
streams per component, so switching GPS or ticks on or off leaves the vibrations unchanged.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.sim.profile import SpeedProfile
from vibrospeed.sim.sensors import (
    G0,
    GpsConfig,
    GpsModel,
    ImuConfig,
    TickConfig,
    WheelConfig,
    cog_ticks,
    digitise,
    draw_biases,
    mount_matrix,
    simple_gps,
    wheel_speeds,
)
from vibrospeed.sim.vibration import VibrationConfig, vibration
from vibrospeed.types import Recording

#: Units of the extra truth channels the simulator writes beside the canonical ones.
EXTRA_TRUTH_UNITS = {
    "accel_true": "m/s^2",  # dv/dt of the reference point
    "yaw_rate_true": "rad/s",
    "grade_true": "rad",  # road grade (only when a grade is simulated)
}

_STREAMS = ("vibration", "imu", "ticks", "wheels", "gps")


def simulate_drive(
    profile: SpeedProfile,
    rng: np.random.Generator,
    *,
    duration: float,
    fs: float = 100.0,
    wheel_radius: float,
    vibration_cfg: VibrationConfig,
    imu: ImuConfig,
    ticks: TickConfig | None = None,
    wheels: WheelConfig | None = None,
    gps: GpsConfig | None = None,
    gps_model: GpsModel | None = None,
    grade: Callable[[np.ndarray], np.ndarray] | None = None,
    source: str = "sim",
) -> Recording:
    """Simulate every sensor of a drive following ``profile``.

    Parameters
    ----------
    profile : exact motion (speed, acceleration, distance, yaw rate).
    rng : source of all randomness (split into per-component streams).
    duration : s; the time line is ``profile.t0 + k / fs``, ``k = 0 .. round(duration fs) - 1``.
    fs : Hz IMU sample rate.
    wheel_radius : m, ``omega_true = speed_true / wheel_radius``.
    vibration_cfg, imu : vibration and IMU knobs.
    ticks, wheels, gps : optional sensors (None: off).
    gps_model : replaces the built-in GPS (see :class:`vibrospeed.sim.sensors.GpsModel`); used
        whether or not ``gps`` is set.
    grade : optional road grade (rad) as a function of time.
    """
    if not fs > 0 or not duration > 0:
        raise ParameterError(f"{source}: need fs > 0 and duration > 0 (got {fs}, {duration})")
    if not wheel_radius > 0:
        raise ParameterError(f"{source}: wheel_radius must be > 0 m, got {wheel_radius}")
    n = int(round(duration * fs))
    if n < 2:
        raise ParameterError(f"{source}: duration {duration} s gives fewer than 2 samples")
    streams = dict(zip(_STREAMS, rng.spawn(len(_STREAMS)), strict=True))
    t = profile.t0 + np.arange(n) / fs
    v = profile.speed(t)
    acc = profile.accel(t)
    x = profile.distance(t)
    yaw = profile.yaw_rate(t)
    omega = v / wheel_radius
    theta = x / wheel_radius
    notes: list[str] = []
    M = vibration_cfg.M
    if M * omega.max() > np.pi * fs:
        notes.append(
            f"harmonic {M} reaches {M * omega.max():.0f} rad/s above Nyquist {np.pi * fs:.0f} "
            f"rad/s (attenuated by the anti-alias model, order {vibration_cfg.aa_order})"
        )

    vib = vibration(t, theta, omega, v, fs, vibration_cfg, streams["vibration"])
    ab, gb = draw_biases(imu, streams["imu"])
    noise_a = streams["imu"].normal(0.0, imu.accel_noise, (3, n))
    noise_g = streams["imu"].normal(0.0, imu.gyro_noise, (3, n))
    gr = np.zeros(n) if grade is None else np.asarray(grade(t), dtype=np.float64)
    pitch_rate = np.gradient(gr, t) if grade is not None else np.zeros(n)
    base_a = np.stack([acc + G0 * np.sin(gr), v * yaw, G0 * np.cos(gr)])
    accel = base_a + vib.accel
    gyro = np.stack([np.zeros(n), -pitch_rate, yaw])
    if any(imu.mount):
        rot = mount_matrix(imu.mount)
        accel, gyro = rot @ accel, rot @ gyro
    accel = digitise(accel + ab[:, None] + noise_a, imu.accel_lsb, imu.accel_range)
    gyro = gyro + gb[:, None] + noise_g

    channels: dict[str, np.ndarray] = {
        "ax": accel[0], "ay": accel[1], "az": accel[2],
        "gx": gyro[0], "gy": gyro[1], "gz": gyro[2],
    }
    meta: dict[str, Any] = {
        "segments": profile.segments,
        "turns": [vars_turn(tr) for tr in profile.turns],
        "accel_bias": ab.tolist(),
        "gyro_bias": gb.tolist(),
        "fades": vib.fades,
        "harmonics": M,
        "clipped_share": float(np.mean(np.abs(accel) >= imu.accel_range)),
        "vibration_law": "A_m = a_m g_axis (omega/omega_ref)^gamma exp(OU) fade H_aa(m omega)",
    }
    if vibration_cfg.engine is not None:
        ch = np.flatnonzero(np.diff(vib.gear)) + 1
        meta["gear_changes"] = [[float(t[i]), int(vib.gear[i]) + 1] for i in ch]
        meta["initial_gear"] = int(vib.gear[0]) + 1

    if wheels is not None:
        channels.update(wheel_speeds(v, yaw, wheel_radius, wheels, streams["wheels"]))
    if gps_model is not None:
        gs, gsat = gps_model(t, v, streams["gps"])
        gs = np.asarray(gs, dtype=np.float64)
        gsat = np.asarray(gsat, dtype=np.float64)
        if gs.shape != (n,) or gsat.shape != (n,):
            raise ParameterError(f"{source}: gps_model must return two arrays of shape ({n},)")
        channels.update(gps_speed=gs, gps_sats=gsat)
        meta["gps_model"] = getattr(gps_model, "__name__", type(gps_model).__name__)
    elif gps is not None:
        gs, gsat, spans = simple_gps(gps, t, v, streams["gps"])
        channels.update(gps_speed=gs, gps_sats=gsat)
        meta["gps_outages"] = [list(s) for s in spans]
        meta["gps_model"] = "simple"

    channels.update(omega_true=omega, speed_true=v, accel_true=acc, yaw_rate_true=yaw)
    if grade is not None:
        channels["grade_true"] = gr
    events = {}
    if ticks is not None:
        events["wss_ticks"] = cog_ticks(profile, t, ticks, wheel_radius, streams["ticks"])
        meta["ticks_radius"] = ticks.radius if ticks.radius is not None else wheel_radius
        meta["ticks_n_cogs"] = int(ticks.n_cogs)
    units = {k: u for k, u in EXTRA_TRUTH_UNITS.items() if k in channels}
    return Recording(t=t, channels=channels, units=units, events=events, source=source,
                     wheel_radius=float(wheel_radius), notes=notes, meta=meta)


def vars_turn(turn) -> dict:
    """JSON-friendly description of a :class:`~vibrospeed.sim.profile.Turn`."""
    return {"t_start": turn.t_start, "duration": turn.duration, "kappa_peak": turn.kappa_peak}
