"""Reader for a comma2k19 segment (github.com/commaai/comma2k19, MIT): CAN wheel speeds, yaw rate,
accelerations, GNSS speed and the fused pose, on the CAN wheel-speed time line.

Layout read (one segment folder, e.g. ``shared/datasets/comma2k19_example/segment_40``)::

    processed_log/CAN/wheel_speed/{t,value}   (n, 4) m/s, order fl fr rl rr (checked against
                                              decoded_can/can_0x0aa.csv, which is fr fl rr rl kph)
    processed_log/CAN/speed/{t,value}         vehicle speed, m/s (CAN 0x0b4)
    decoded_can/can_0x024.csv                 yaw_rate_degps (CCW +), accel_y_mps2 (RIGHT +)
    decoded_can/can_0x228.csv                 accel_x_mps2 (forward +; slope 0.92 and corr 0.98
                                              against d(speed)/dt on segment 40)
    processed_log/GNSS/live_gnss_ublox/{t,value}  column 2 = ground speed, m/s
    global_pose/{frame_times,frame_velocities}    ECEF velocity of the fused pose, m/s

Channels (SI, body frame x forward, y left, yaw CCW +): ``gz`` (CAN yaw rate), ``ax`` (CAN),
``ay`` (CAN, sign flipped to left +: a_y ~ +Vx * yaw rate), ``wheel_omega_fl/fr/rl/rr``
(CAN wheel speed / ``wheel_radius``), ``speed_true`` (CAN vehicle speed), ``gps_speed`` (u-blox),
and the non-canonical ``speed_pose`` (norm of the fused pose velocity, m/s). Every stream is
interpolated linearly onto the wheel-speed time stamps (~89 Hz, jittered); samples outside a
stream's span are NaN. ``wheel_radius`` defaults to 0.362 m, the nominal radius of the 2018 RAV4's
225/65R17 tyres: the CAN wheel speeds are already speeds, so ``r * omega`` equals them exactly
for any radius. ``meta['L1']`` = 1.13 m is an assumed CG to front axle distance (wheelbase
2.66 m, ~57 % of the weight on the front axle).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._common import finish
from vibrospeed.io.timebase import place_nearest
from vibrospeed.types import WHEEL_CHANNELS, Recording

if TYPE_CHECKING:
    import pandas as pd

RAV4_WHEEL_RADIUS = 0.362  # m, 225/65R17: (17 * 25.4 + 2 * 0.65 * 225) / 2 mm
RAV4_L1 = 1.13  # m, assumed


def _npy(path: Path) -> np.ndarray:
    if not path.exists():
        raise ReaderError(path, "missing file (is this a comma2k19 segment folder?)")
    try:
        return np.load(path, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - any numpy failure is a bad file
        raise ReaderError(path, f"not a readable .npy array ({exc.__class__.__name__})") from None


def _csv(path: Path, cols: list[str]) -> pd.DataFrame:
    if not path.exists():
        raise ReaderError(path, "missing file (decoded CAN csv)")
    import pandas as pd  # ~0.5 s to import: only when such a file is read

    try:
        df = pd.read_csv(path)
    except Exception as exc:  # noqa: BLE001
        raise ReaderError(path, f"cannot parse csv ({exc.__class__.__name__})") from None
    for c in ["t_boot_s", *cols]:
        if c not in df.columns:
            raise ReaderError(path, "missing column", column=c)
    return df


def _monotonic(t: np.ndarray, path: Path) -> None:
    if t.ndim != 1 or t.size < 2:
        raise ReaderError(path, f"time stamps must be a 1-D array of >= 2 values, got {t.shape}")
    nan = np.flatnonzero(~np.isfinite(t))
    if nan.size:
        raise ReaderError(path, f"time stamp at index {int(nan[0])} is not a number")
    bad = np.flatnonzero(~(np.diff(t) > 0))
    if bad.size:
        i = int(bad[0]) + 1
        raise ReaderError(path, f"time stamps not increasing at index {i} ({float(t[i])!r} s after "
                                f"{float(t[i - 1])!r} s)")


def _interp(tq: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    ok = np.isfinite(x) & np.isfinite(t)
    if ok.sum() < 2:
        return np.full(tq.shape, np.nan)
    return np.interp(tq, t[ok], x[ok], left=np.nan, right=np.nan)


def detect(path) -> bool:
    """True for a comma2k19 segment folder: it holds ``processed_log/CAN/wheel_speed/t`` and
    ``decoded_can/`` (the layout :func:`read_comma2k19` reads). Never raises."""
    try:
        root = Path(path)
        return (root.is_dir()
                and (root / "processed_log" / "CAN" / "wheel_speed" / "t").is_file()
                and (root / "decoded_can").is_dir())
    except OSError:
        return False


def read_comma2k19(path, *, wheel_radius: float = RAV4_WHEEL_RADIUS) -> Recording:
    """Read one comma2k19 segment folder into a :class:`Recording` (see the module docstring).

    Examples
    --------
    >>> rec = read_comma2k19("../shared/datasets/comma2k19_example/segment_40")  # doctest: +SKIP
    >>> sorted(rec.channels)[:3]                                                # doctest: +SKIP
    ['ax', 'ay', 'gps_speed']
    """
    root = Path(path)
    if not root.is_dir():
        raise ReaderError(root, "not a directory (expected a comma2k19 segment folder)")
    can = root / "processed_log" / "CAN"
    tw_path = can / "wheel_speed" / "t"
    t = _npy(tw_path).astype(np.float64)
    _monotonic(t, tw_path)
    ws = _npy(can / "wheel_speed" / "value").astype(np.float64)
    if ws.shape != (t.size, 4):
        raise ReaderError(can / "wheel_speed" / "value",
                          f"expected shape ({t.size}, 4) like its time stamps, got {ws.shape}")
    ch: dict[str, np.ndarray] = {}
    for j, name in enumerate(WHEEL_CHANNELS):
        ch[name] = ws[:, j] / wheel_radius
    p24 = root / "decoded_can" / "can_0x024.csv"
    k = _csv(p24, ["yaw_rate_degps", "accel_y_mps2"])
    tk = k["t_boot_s"].to_numpy(float)
    ch["gz"] = _interp(t, tk, np.deg2rad(k["yaw_rate_degps"].to_numpy(float)))
    ch["ay"] = -_interp(t, tk, k["accel_y_mps2"].to_numpy(float))  # right + -> left +
    p228 = root / "decoded_can" / "can_0x228.csv"
    a = _csv(p228, ["accel_x_mps2"])
    ch["ax"] = _interp(t, a["t_boot_s"].to_numpy(float), a["accel_x_mps2"].to_numpy(float))
    ts = _npy(can / "speed" / "t").astype(np.float64)
    sv = _npy(can / "speed" / "value").astype(np.float64).reshape(ts.size, -1)[:, 0]
    ch["speed_true"] = _interp(t, ts, sv)
    units = {}
    gnss = root / "processed_log" / "GNSS" / "live_gnss_ublox"
    if (gnss / "t").exists():
        tg = _npy(gnss / "t").astype(np.float64)
        vg = _npy(gnss / "value").astype(np.float64)
        if vg.ndim == 2 and vg.shape[0] == tg.size and vg.shape[1] > 2:
            # each 10 Hz fix appears once, at the nearest sample (NaN between fixes), as the
            # phyphox reader does: estimators must see a new fix exactly once
            inside = (tg >= t[0]) & (tg <= t[-1])
            ch["gps_speed"] = place_nearest(tg[inside], vg[inside, 2], t)
    pose = root / "global_pose"
    if (pose / "frame_times").exists():
        tp = _npy(pose / "frame_times").astype(np.float64)
        vp = _npy(pose / "frame_velocities").astype(np.float64)
        if vp.shape == (tp.size, 3):
            ch["speed_pose"] = _interp(t, tp, np.linalg.norm(vp, axis=1))
            units["speed_pose"] = "m/s"
    # through finish() like every reader: time-line, no-fix and gravity notes (the time was
    # checked above, naming the .npy file and index, before the other files are read)
    return finish(
        t - t[0],
        ch,
        units=units,
        source=str(root),
        wheel_radius=wheel_radius,
        notes=[
            "comma2k19: CAN yaw rate / accelerations, GNSS and pose interpolated onto the CAN "
            "wheel-speed time stamps",
            f"wheel_omega = CAN wheel speed / {wheel_radius:g} m (nominal radius)",
            "ay sign flipped (CAN right + -> left +)",
        ],
        meta={"L1": RAV4_L1, "wheel_radius": wheel_radius, "t0_boot_s": float(t[0]),
              "vehicle": "2018 Toyota RAV4"},
    )
