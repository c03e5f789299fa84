"""ROS 1 (``.bag``) and ROS 2 (folder with ``metadata.yaml`` and ``.db3`` / ``.mcap``) bags,
read with the pure-Python ``rosbags`` package (no ROS install; ``pip install vibrospeed[rosbags]``).

Messages read (ROS 1 and ROS 2 names alike):

=====================================================  ========================================
``sensor_msgs/Imu``                                    ``linear_acceleration`` -> ``ax ay az``
                                                       (m/s^2), ``angular_velocity`` -> ``gx gy
                                                       gz`` (rad/s). **Master time line.**
``nav_msgs/Odometry``                                  ``|twist.twist.linear|`` -> ``speed_odom``
                                                       (m/s), interpolated onto the IMU times.
``geometry_msgs/TwistStamped``,                        a velocity: with a ``NavSatFix`` topic in
``geometry_msgs/TwistWithCovarianceStamped``           the bag it is the GNSS velocity ->
                                                       ``gps_speed`` (each fix once at the nearest
                                                       IMU sample, NaN elsewhere, times in event
                                                       ``gps_fix``); without one -> ``speed_odom``.
``sensor_msgs/NavSatFix``                              ``latitude longitude altitude`` ->
                                                       ``gps_lat gps_lon gps_alt`` at the nearest
                                                       IMU sample; ``status < 0`` (no fix) -> NaN;
                                                       ``gps_hacc`` = sqrt of the larger
                                                       horizontal position variance when known.
=====================================================  ========================================

Topic choice: with several IMU topics the one with the most messages is used and the others
listed in a note; ``topic="/imu/data"`` (CLI ``--topic``) chooses; a comma list
(``"/imu/data,/odom"``) also restricts the speed topics to those named.

Time: each message's ``header.stamp`` is used when every message of its topic has a non-zero
stamp, else the time the recorder received it (the bag's time stamp); a note says which, per topic,
with the median receive-minus-header latency. When some topics must fall back to receive time and
the others' header clock is more than 0.5 s away from receive time (a device clock, simulated
time), every topic uses receive time (noted). ``stamps="header"`` / ``"receive"`` forces one.
``t = 0`` at the first IMU message; the epoch offset is kept in ``meta["t0_ns"]``.

A corrupt or truncated bag gives a one-line :class:`~vibrospeed.errors.ReaderError` naming the
file and what ``rosbags`` found wrong.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from vibrospeed.errors import ReaderError
from vibrospeed.io._common import finish
from vibrospeed.io.timebase import interp_onto, merge_fix_rows, nearest_index
from vibrospeed.types import Recording

__all__ = ["detect", "read_rosbag"]

IMU = "sensor_msgs/Imu"
ODOM = "nav_msgs/Odometry"
TWIST = "geometry_msgs/TwistStamped"
TWISTC = "geometry_msgs/TwistWithCovarianceStamped"
FIX = "sensor_msgs/NavSatFix"
_KINDS = (IMU, ODOM, TWIST, TWISTC, FIX)
_ROS1_MAGIC = b"#ROSBAG V2.0\n"
_LAT_LIMIT = 0.5  # s, header clock vs receive clock beyond which mixed clocks are refused


def _kind(msgtype: str) -> str:
    return msgtype.replace("/msg/", "/")


def _bag_path(p: Path) -> Path | None:
    """The path rosbags opens: a ``.bag`` file, or a ROS 2 bag folder (also from a file in it)."""
    try:
        if p.is_dir():
            return p if (p / "metadata.yaml").is_file() else None
        if p.is_file():
            if p.suffix == ".bag":
                return p
            if p.suffix in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
                return p.parent
            if p.name == "metadata.yaml":
                return p.parent
    except OSError:
        return None
    return None


def detect(path: str | os.PathLike[str]) -> bool:
    """True for a ROS 1 bag (``#ROSBAG V2.0`` magic) or a ROS 2 bag folder / file in one
    (``metadata.yaml`` with ``rosbag2_bagfile_information``). Never raises."""
    p = Path(path)
    try:
        if p.is_file() and p.suffix != ".yaml":
            with open(p, "rb") as fh:
                if fh.read(len(_ROS1_MAGIC)) == _ROS1_MAGIC:
                    return True
        b = _bag_path(p)
        if b is None or not b.is_dir():
            return False
        with open(b / "metadata.yaml", encoding="utf-8", errors="replace") as fh:
            return "rosbag2_bagfile_information" in fh.read(4096)
    except OSError:
        return False


def _stamp_ns(msg) -> int:
    st = msg.header.stamp
    return int(st.sec) * 1_000_000_000 + int(getattr(st, "nanosec", getattr(st, "nsec", 0)))


def _norm(v) -> float:
    return math.sqrt(float(v.x) ** 2 + float(v.y) ** 2 + float(v.z) ** 2)


def _extract(kind: str, msg) -> tuple[float, ...]:
    if kind == IMU:
        a, w = msg.linear_acceleration, msg.angular_velocity
        return (a.x, a.y, a.z, w.x, w.y, w.z)
    if kind == ODOM:
        return (_norm(msg.twist.twist.linear),)
    if kind == TWIST:
        return (_norm(msg.twist.linear),)
    if kind == TWISTC:
        return (_norm(msg.twist.twist.linear),)
    # NavSatFix
    cov = np.asarray(msg.position_covariance, dtype=float)
    ok = int(msg.status.status) >= 0
    hacc = (math.sqrt(max(cov[0], cov[4])) if int(msg.position_covariance_type) > 0
            and cov.size >= 5 and np.all(np.isfinite(cov[[0, 4]])) else float("nan"))
    nan = float("nan")
    return ((msg.latitude, msg.longitude, msg.altitude, hacc) if ok else (nan, nan, nan, nan))


def _open_reader(bag: Path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if bag.suffix == ".bag" else Stores.ROS2_HUMBLE)
    return AnyReader([bag], default_typestore=store)


def read_rosbag(path: str | os.PathLike[str], *, topic: str | None = None, sort: bool = False,
                stamps: str = "auto") -> Recording:
    """Read a ROS 1 or ROS 2 bag onto the IMU topic's time line (see the module docstring).

    Parameters
    ----------
    path : ``.bag`` file (ROS 1), bag folder or a ``.db3`` / ``.mcap`` file in it (ROS 2)
    topic : IMU topic to use, or a comma list of topics (IMU and speed) to restrict to
    sort : sort by time and drop repeated stamps instead of refusing time going backwards
    stamps : ``"auto"`` (header stamps where set), ``"header"`` or ``"receive"``
    """
    p = Path(path)
    if not p.exists():
        raise ReaderError(p, "file not found")
    if stamps not in ("auto", "header", "receive"):
        raise ReaderError(p, f"stamps must be auto, header or receive, got {stamps!r}")
    bag = _bag_path(p)
    if bag is None:
        raise ReaderError(p, "not a ROS bag (a ROS 1 .bag file or a ROS 2 folder with "
                             "metadata.yaml)")
    try:
        import rosbags  # noqa: F401
    except ImportError:
        raise ReaderError(p, "reading ROS bags needs the 'rosbags' package "
                             "(pip install 'vibrospeed[rosbags]')") from None
    try:
        return _read(p, bag, topic, sort, stamps)
    except ReaderError:
        raise
    except MemoryError:
        raise ReaderError(p, "corrupt ROS bag (a length field asks for more memory than "
                             "exists)") from None
    except Exception as exc:  # noqa: BLE001 - rosbags raises many types on a corrupt bag
        msg = " ".join(str(exc).split())[:200] or type(exc).__name__
        raise ReaderError(p, f"corrupt or unreadable ROS bag ({type(exc).__name__}: "
                             f"{msg})") from None


def _read(p: Path, bag: Path, topic: str | None, sort: bool, stamps: str) -> Recording:
    wanted = [s.strip() for s in topic.split(",") if s.strip()] if topic else []
    notes: list[str] = []
    with _open_reader(bag) as reader:
        by_topic: dict[str, tuple[str, list]] = {}
        for c in reader.connections:
            k = _kind(c.msgtype)
            if k in _KINDS:
                by_topic.setdefault(c.topic, (k, []))[1].append(c)
        counts = {t: sum(int(getattr(c, "msgcount", 0) or 0) for c in conns)
                  for t, (_, conns) in by_topic.items()}
        for w in wanted:
            if w not in by_topic:
                known = ", ".join(f"{t} ({k})" for t, (k, _) in sorted(by_topic.items()))
                raise ReaderError(p, f"topic {w} not found or not a supported message type "
                                     f"(supported topics here: {known or 'none'})")
        imus = [t for t, (k, _) in by_topic.items() if k == IMU]
        if wanted:
            picked = [t for t in wanted if by_topic[t][0] == IMU]
            if not picked:
                raise ReaderError(p, f"none of the topics {', '.join(wanted)} is a "
                                     f"sensor_msgs/Imu (IMU topics: {', '.join(imus) or 'none'})")
            imus = picked[:1]
        if not imus:
            have = ", ".join(f"{t} ({k})" for t, (k, _) in sorted(by_topic.items()))
            raise ReaderError(p, "no sensor_msgs/Imu topic in this bag (found: "
                                 f"{have or 'no supported topic'})")
        imu = max(imus, key=lambda t: (counts[t], t))
        others = [t for t, (k, _) in by_topic.items() if k == IMU and t != imu]
        if others and not wanted:
            notes.append(f"IMU topic {imu} used ({counts[imu]} messages); also in the bag: "
                         f"{', '.join(others)} (choose with --topic)")
        has_fix = any(k == FIX for k, _ in by_topic.values())
        speed_topics = {}
        for kinds, role in (((ODOM,), "odom"), ((TWIST, TWISTC), "twist"), ((FIX,), "fix")):
            cands = [t for t, (k, _) in by_topic.items() if k in kinds
                     and (not wanted or t in wanted)]
            if cands:
                best = max(cands, key=lambda t: (counts[t], t))
                speed_topics[role] = best
                if len(cands) > 1:
                    notes.append(f"{role} topic {best} used; also: "
                                 f"{', '.join(c for c in cands if c != best)}")
        use = [imu, *speed_topics.values()]
        data: dict[str, tuple[list[int], list[int], list[tuple]]] = {t: ([], [], []) for t in use}
        conns = [c for t in use for c in by_topic[t][1]]
        for conn, recv_ns, raw in reader.messages(connections=conns):
            msg = reader.deserialize(raw, conn.msgtype)
            hdr, rcv, vals = data[conn.topic]
            hdr.append(_stamp_ns(msg))
            rcv.append(int(recv_ns))
            vals.append(_extract(by_topic[conn.topic][0], msg))
    times = _choose_stamps(data, stamps, notes)
    t_ns, vals = times[imu], np.asarray(data[imu][2], dtype=float).reshape(-1, 6)
    if t_ns.size == 0:
        raise ReaderError(p, f"IMU topic {imu} has no messages")
    t_ns, vals = _ordered(t_ns, vals, f"{p} ({imu})", sort, notes)
    t0 = int(t_ns[0])
    t = (t_ns - t0).astype(np.float64) * 1e-9
    chans = {n: vals[:, j] for j, n in enumerate(("ax", "ay", "az", "gx", "gy", "gz"))}
    fs = 1.0 / float(np.median(np.diff(t))) if t.size > 1 else float("nan")
    notes.insert(0, f"ROS bag {bag.name}: IMU topic {imu}, {t.size} messages (~{fs:.4g} Hz), "
                    "master time line; linear_acceleration -> ax ay az, angular_velocity -> "
                    "gx gy gz")
    units: dict[str, str] = {}
    events: dict[str, np.ndarray] = {}
    speed_is_gps = has_fix and "twist" in speed_topics
    topics = {}
    for tp in speed_topics.values():
        tk, vk = _ordered(times[tp], np.asarray(data[tp][2], dtype=float).reshape(
            len(data[tp][2]), -1), f"{p} ({tp})", sort, notes)
        topics[tp] = ((tk - t0).astype(np.float64) * 1e-9, vk)
    fixes = [tk[np.isfinite(vk[:, 0])] for role, tp in speed_topics.items()
             for tk, vk in [topics[tp]] if role == "fix" or (role == "twist" and speed_is_gps)]
    meta = {"format": "rosbag", "imu_topic": imu, "t0_ns": t0,
            "topics": {r: tp for r, tp in speed_topics.items()}}
    if fixes:  # fixes inside IMU gaps: rows of their own (not piled on the gap's edge)
        t, chans, _, fnotes, fmeta = merge_fix_rows(t, np.concatenate(fixes), chans,
                                                    master="IMU")
        notes.extend(fnotes)
        meta.update(fmeta)
    for role, tp in speed_topics.items():
        tk, vk = topics[tp]
        if tk.size == 0:
            notes.append(f"{tp}: no messages")
            continue
        if role == "fix" or (role == "twist" and speed_is_gps):
            names = (["gps_lat", "gps_lon", "gps_alt", "gps_hacc"] if role == "fix"
                     else ["gps_speed"])
            out = _place(tk, vk, t)
            for j, n in enumerate(names):
                if n == "gps_hacc" and not np.any(np.isfinite(vk[:, j])):
                    continue
                chans[n] = out[:, j]
            units.update({"gps_lat": "deg", "gps_lon": "deg", "gps_alt": "m", "gps_hacc": "m",
                          "gps_speed": "m/s"})
            if role == "twist":
                events["gps_fix"] = tk
            notes.append(f"{tp} ({_kind_name(role)}): {tk.size} messages placed at the nearest "
                         "IMU sample, NaN elsewhere" + (
                             "; |twist.linear| -> gps_speed (GNSS velocity: the bag has a "
                             "NavSatFix topic)" if role == "twist" else
                             "; status < 0 (no fix) -> NaN"))
        else:
            if "speed_odom" in chans:
                notes.append(f"{tp}: not used (speed_odom already from another topic)")
                continue
            if tk.size < 2:
                notes.append(f"{tp}: {tk.size} message, not used")
                continue
            dt = float(np.median(np.diff(tk)))
            chans["speed_odom"] = interp_onto(tk, vk[:, 0], t, 5.0 * dt)
            notes.append(f"{tp} ({_kind_name(role)}, {1 / dt:.4g} Hz): |linear velocity| -> "
                         "speed_odom (m/s, unsigned), linearly interpolated onto the IMU time line")
    if "fix" in speed_topics and "twist" not in speed_topics:
        notes.append("NavSatFix without a velocity topic: no gps_speed (positions only)")
    units.update({"speed_odom": "m/s"})
    units = {k: v for k, v in units.items() if k in chans}
    return finish(t, chans, source=str(p), sort=False, units=units, events=events, notes=notes,
                  meta=meta,
                  axes="the IMU message frame (REP 103: x forward, y left, z up for a body frame)")


def _kind_name(role: str) -> str:
    return {"odom": "nav_msgs/Odometry", "twist": "TwistStamped",
            "fix": "sensor_msgs/NavSatFix"}[role]


def _choose_stamps(data, stamps: str, notes: list[str]) -> dict[str, np.ndarray]:
    """Per topic: header stamps or receive times (int64 ns), and notes saying which."""
    out: dict[str, np.ndarray] = {}
    header_ok: dict[str, bool] = {}
    lat: dict[str, float] = {}
    for tp, (hdr, rcv, _) in data.items():
        h, r = np.asarray(hdr, dtype=np.int64), np.asarray(rcv, dtype=np.int64)
        header_ok[tp] = bool(h.size) and bool(np.all(h > 0))
        if header_ok[tp]:
            lat[tp] = float(np.median(r - h)) * 1e-9
    mode = stamps
    if stamps == "auto":
        mixed = not all(header_ok.values()) and any(header_ok.values())
        far = [tp for tp, v in lat.items() if abs(v) > _LAT_LIMIT]
        if mixed and far:
            mode = "receive"
            notes.append(f"some topics have no header stamps and {', '.join(far)} run on a "
                         f"clock > {_LAT_LIMIT} s from receive time: receive time used for all "
                         "topics")
    for tp, (hdr, rcv, _) in data.items():
        use_h = header_ok[tp] if mode == "auto" else mode == "header"
        if use_h and mode == "header" and not header_ok[tp]:
            notes.append(f"{tp}: header stamps forced though some are zero")
        out[tp] = np.asarray(hdr if use_h else rcv, dtype=np.int64)
        if use_h:
            extra = f" (receive - header: median {lat[tp] * 1e3:.3g} ms)" if tp in lat else ""
            notes.append(f"{tp}: header stamps used{extra}")
        else:
            why = "" if mode == "receive" else " (header stamps unset)"
            notes.append(f"{tp}: receive time used{why}")
    return out


def _ordered(t_ns: np.ndarray, vals: np.ndarray, label: str, sort: bool, notes: list[str]):
    """Sort (stable) when asked or needed-and-allowed; drop exact repeats; refuse backwards."""
    if t_ns.size and np.any(np.diff(t_ns) < 0):
        if not sort:
            i = int(np.flatnonzero(np.diff(t_ns) < 0)[0]) + 1
            raise ReaderError(label, f"time goes backwards at message {i + 1} "
                                     f"({(t_ns[i] - t_ns[i - 1]) * 1e-9:.6g} s); --sort (sort=True "
                                     "in Python) sorts and de-duplicates")
        order = np.argsort(t_ns, kind="stable")
        notes.append(f"{label}: sorted by time")
        t_ns, vals = t_ns[order], vals[order]
    keep = np.ones(t_ns.size, dtype=bool)
    keep[1:] = np.diff(t_ns) != 0
    if not keep.all():
        notes.append(f"{label}: dropped {int((~keep).sum())} message(s) repeating the previous "
                     "stamp (first kept)")
    return t_ns[keep], vals[keep]


def _place(tk: np.ndarray, vk: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Rows of ``vk`` at the sample of ``t`` nearest ``tk`` (NaN elsewhere, outside the span
    dropped; of rows sharing a sample the last with a finite first value wins)."""
    dt = float(np.median(np.diff(t))) if t.size > 1 else 0.0
    inside = np.flatnonzero((tk >= t[0] - dt / 2) & (tk <= t[-1] + dt / 2))
    out = np.full((t.size, vk.shape[1]), np.nan)
    if inside.size == 0:
        return out
    j = nearest_index(tk[inside], t)
    valid = np.isfinite(vk[inside, 0])
    order = np.lexsort((inside, valid, j))
    last = np.ones(order.size, dtype=bool)
    last[:-1] = j[order][1:] != j[order][:-1]
    win = order[last]
    out[j[win]] = vk[inside][win]
    return out
