"""Reader for the F1/10 FrictionMaps drifting runs (github.com/AhmadAmine998/FrictionMaps, MIT).

One data set folder (``DS1`` .. ``DS5``) holds ROS logs as csv files whose first three columns
are a pandas index, ``s`` and ``ns`` (time stamp = s + 1e-9 ns)::

    imuData.csv     VESC IMU, 18-44 Hz, irregular: accelerations in g, rates in deg/s.
                    The column 'ax' is the LATERAL axis (left +: ax * g ~ +v * wz, slope 0.93-1.08
                    on DS1/2/5) and 'ay' is the longitudinal axis with forward NEGATIVE
                    (corr(-ay, dv/dt) = 0.56-0.79); 'wz' is the yaw rate, CCW +.
    odomData.csv    VESC odometry ``vx`` (m/s, from motor ERPM: a wheel-speed sensor that slips
                    with the wheels).
    pfPoseData.csv  particle-filter localisation ``x, y`` (m), ~40 Hz.

Channels on the IMU time stamps (irregular; gaps longer than ``max_gap`` s are kept as gaps):
``ax`` (forward +), ``ay`` (left +), ``gz`` (rad/s), ``wheel_omega_*`` (odometry speed /
``wheel_radius``, the same for the four wheels: the car has one motor and no wheel sensors),
``speed_true`` (particle-filter speed: central difference of the pose over +-``pf_half``
samples), and the non-canonical ``speed_odom`` (m/s). ``meta['L1']`` = 0.15875 m (F1TENTH gym
default ``lf``), ``wheel_radius`` 0.05 m (nominal; ``r * omega`` equals the odometry speed).
Note (upstream README): the odometry speed comes from commanded/ERPM values; the authors use the
particle-filter speed as truth on DS1-DS4.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._common import finish
from vibrospeed.types import WHEEL_CHANNELS, Recording

if TYPE_CHECKING:
    import pandas as pd

G = 9.80665
F1TENTH_L1 = 0.15875  # m, F1TENTH gym default lf
F1TENTH_WHEEL_RADIUS = 0.05  # m, nominal


def _read(path: Path, cols: list[str]) -> tuple[np.ndarray, pd.DataFrame]:
    if not path.exists():
        raise ReaderError(path, "missing file (expected an F1/10 FrictionMaps DS folder)")
    import pandas as pd  # ~0.5 s to import: only when such a file is read

    try:
        df = pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001
        raise ReaderError(path, f"cannot parse csv ({exc.__class__.__name__})") from None
    for c in ["s", "ns", *cols]:
        if c not in df.columns:
            raise ReaderError(path, "missing column", column=c)
    for c in ["s", "ns", *cols]:
        x = pd.to_numeric(df[c], errors="coerce").to_numpy(float)
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size and c in ("s", "ns"):
            raise ReaderError(path, "time stamp is not a number", row=int(bad[0]) + 2, column=c)
        df[c] = x
    t = df["s"].to_numpy(float) + 1e-9 * df["ns"].to_numpy(float)
    if t.size < 2:
        raise ReaderError(path, f"fewer than 2 rows ({t.size})")
    back = np.flatnonzero(~(np.diff(t) > 0))
    if back.size:
        raise ReaderError(path, "time stamp not increasing", row=int(back[0]) + 3, column="s")
    return t, df


def _interp(tq, t, x):
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return np.full(tq.shape, np.nan)
    return np.interp(tq, t[ok], x[ok], left=np.nan, right=np.nan)


#: the three logs :func:`read_f1tenth` needs
LOGS = ("imuData.csv", "odomData.csv", "pfPoseData.csv")


def detect(path) -> bool:
    """True for a FrictionMaps data set folder (or one of its three logs): the folder holds
    ``imuData.csv``, ``odomData.csv`` and ``pfPoseData.csv`` and the IMU log's header has the
    ROS time columns ``s, ns`` and ``ax, ay, wz``. Never raises."""
    try:
        root = Path(path)
        if root.is_file():
            if root.name not in LOGS:
                return False
            root = root.parent
        if not root.is_dir() or not all((root / f).is_file() for f in LOGS):
            return False
        with open(root / "imuData.csv", encoding="utf-8", errors="replace") as fh:
            head = [h.strip() for h in fh.readline().split(",")]
        return all(c in head for c in ("s", "ns", "ax", "ay", "wz"))
    except OSError:
        return False


def read_f1tenth(
    path, *, wheel_radius: float = F1TENTH_WHEEL_RADIUS, pf_half: int = 6, max_gap: float = 0.5
) -> Recording:
    """Read one FrictionMaps data set folder (or a csv inside it) into a :class:`Recording`."""
    root = Path(path)
    if root.is_file():
        root = root.parent
    if not root.is_dir():
        raise ReaderError(root, "not a directory (expected an F1/10 FrictionMaps DS folder)")
    ti, imu = _read(root / "imuData.csv", ["ax", "ay", "wz"])
    to, od = _read(root / "odomData.csv", ["vx"])
    tp, pose = _read(root / "pfPoseData.csv", ["x", "y"])
    ch: dict[str, np.ndarray] = {
        "ax": -G * imu["ay"].to_numpy(float),
        "ay": G * imu["ax"].to_numpy(float),
        "gz": np.deg2rad(imu["wz"].to_numpy(float)),
    }
    v_odom = _interp(ti, to, od["vx"].to_numpy(float))
    # no odometry across long gaps of the odometry stream
    gap = np.searchsorted(to, ti)
    gap = np.clip(gap, 1, to.size - 1)
    v_odom[(to[gap] - to[gap - 1]) > max_gap] = np.nan
    for name in WHEEL_CHANNELS:
        ch[name] = v_odom / wheel_radius
    # particle-filter speed: central difference over +-pf_half pose samples, sign of odometry
    x = pose["x"].to_numpy(float)
    y = pose["y"].to_numpy(float)
    k = int(pf_half)
    if tp.size <= 2 * k:
        raise ReaderError(root / "pfPoseData.csv", f"fewer than {2 * k + 1} pose rows")
    sp = np.hypot(x[2 * k:] - x[:-2 * k], y[2 * k:] - y[:-2 * k]) / (tp[2 * k:] - tp[:-2 * k])
    tc = tp[k:-k]
    span = tp[2 * k:] - tp[:-2 * k]
    sp[span > max_gap * 2] = np.nan
    v_pf = _interp(ti, tc, sp)
    ch["speed_true"] = np.where(v_odom < 0, -v_pf, v_pf)
    ch["speed_odom"] = v_odom
    dt = np.diff(ti)
    notes = [
        "F1/10 FrictionMaps: IMU 'ax' column is lateral (-> ay), '-ay' is forward (-> ax); "
        "g and deg/s converted to SI",
        f"odometry and particle-filter speed interpolated onto the IMU time stamps "
        f"(median period {np.median(dt) * 1e3:.3g} ms, max gap {dt.max():.3g} s)",
        f"wheel_omega = odometry speed / {wheel_radius:g} m on all four wheels",
    ]
    # through finish() like every reader: time-line, no-fix and gravity notes (the IMU time was
    # checked by _read, naming imuData.csv and its line, as the other two logs' times)
    return finish(
        ti - ti[0],
        ch,
        units={"speed_odom": "m/s"},
        source=str(root),
        wheel_radius=wheel_radius,
        axes="x forward, y left, z up (converted from the VESC IMU)",
        notes=notes,
        meta={"L1": F1TENTH_L1, "wheel_radius": wheel_radius, "t0_s": float(ti[0]),
              "vehicle": "F1/10 1:10 RC car"},
    )
