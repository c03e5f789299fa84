"""ROS 1 and ROS 2 bags written with rosbags itself: channels, stamps, topic choice, bad bags."""

import numpy as np
import pytest

pytest.importorskip("rosbags")

from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from vibrospeed import io as vio  # noqa: E402
from vibrospeed.errors import ParameterError, ReaderError  # noqa: E402
from vibrospeed.io.rosbag import detect, read_rosbag  # noqa: E402
from vibrospeed.types import Recording  # noqa: E402

T0 = 1_700_000_000 * 10**9  # ns
N = 200  # IMU at 100 Hz


def _msgs(ts):
    T = ts.types
    Time = T["builtin_interfaces/msg/Time"]
    Header = T["std_msgs/msg/Header"]
    V3 = T["geometry_msgs/msg/Vector3"]
    Q = T["geometry_msgs/msg/Quaternion"]
    z9 = np.zeros(9)

    def header(ns):
        kw = {"sec": ns // 10**9}
        kw["nanosec" if "nanosec" in Time.__dataclass_fields__ else "nsec"] = ns % 10**9
        h = {"stamp": Time(**kw), "frame_id": "base_link"}
        if "seq" in Header.__dataclass_fields__:
            h["seq"] = 0
        return Header(**h)

    def imu(ns, i):
        t = i * 0.01
        return T["sensor_msgs/msg/Imu"](
            header=header(ns), orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
            orientation_covariance=z9, angular_velocity=V3(x=0.1 * t, y=0.0, z=-0.2),
            angular_velocity_covariance=z9,
            linear_acceleration=V3(x=t, y=-2 * t, z=9.81), linear_acceleration_covariance=z9)

    def twist(v):
        return T["geometry_msgs/msg/Twist"](linear=V3(x=v * 0.6, y=v * 0.8, z=0.0),
                                            angular=V3(x=0.0, y=0.0, z=0.0))

    def odom(ns, v):
        P = T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=0.0, y=0.0, z=0.0),
                                        orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0))
        return T["nav_msgs/msg/Odometry"](
            header=header(ns), child_frame_id="base_link",
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=P, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](twist=twist(v),
                                                             covariance=np.zeros(36)))

    def vel(ns, v):
        return T["geometry_msgs/msg/TwistStamped"](header=header(ns), twist=twist(v))

    def fix(ns, status):
        return T["sensor_msgs/msg/NavSatFix"](
            header=header(ns), status=T["sensor_msgs/msg/NavSatStatus"](status=status, service=1),
            latitude=47.5, longitude=19.0, altitude=100.0,
            position_covariance=np.array([4.0, 0, 0, 0, 9.0, 0, 0, 0, 16.0]),
            position_covariance_type=2)

    return imu, odom, vel, fix


def _write(path, ros1=False, *, header_zero=(), latency_ns=2_000_000, imu2=False, gps=True,
           imu_gap=()):
    """IMU 100 Hz (none at the indices in ``imu_gap``), odometry 50 Hz (v = 1 + t), GNSS fix +
    TwistStamped velocity at 10 Hz."""
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    imu, odom, vel, fix = _msgs(ts)
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    writer = Writer1(path) if ros1 else Writer2(path, version=9)
    with writer as w:
        def conn(topic, typ):
            return w.add_connection(topic, typ, typestore=ts)

        c_imu = conn("/imu/data", "sensor_msgs/msg/Imu")
        c_odom = conn("/odom", "nav_msgs/msg/Odometry")
        c_imu2 = conn("/cam/imu", "sensor_msgs/msg/Imu") if imu2 else None
        c_fix = conn("/fix", "sensor_msgs/msg/NavSatFix") if gps else None
        c_vel = conn("/vel", "geometry_msgs/msg/TwistStamped") if gps else None
        msgs = []
        for i in range(N):
            ns = T0 + i * 10_000_000
            if i not in imu_gap:
                msgs.append((ns, c_imu, imu(0 if "/imu/data" in header_zero else ns, i),
                             "sensor_msgs/msg/Imu"))
            if imu2 and i % 4 == 0:
                msgs.append((ns, c_imu2, imu(ns, i), "sensor_msgs/msg/Imu"))
            if i % 2 == 1:
                msgs.append((ns, c_odom, odom(0 if "/odom" in header_zero else ns, 1 + i * 0.01),
                             "nav_msgs/msg/Odometry"))
            if gps and i % 10 == 5:
                msgs.append((ns, c_fix, fix(ns, -1 if i == 55 else 0), "sensor_msgs/msg/NavSatFix"))
                msgs.append((ns, c_vel, vel(ns, 3.0 + i), "geometry_msgs/msg/TwistStamped"))
        for ns, c, m, typ in msgs:
            w.write(c, ns + latency_ns, ser(m, typ))  # received 2 ms after the stamp
    return path


def _check(r):
    t = np.arange(N) * 0.01
    assert len(r) == N
    np.testing.assert_allclose(r.t, t, atol=1e-12)
    np.testing.assert_allclose(r["ax"], t, atol=1e-12)
    np.testing.assert_allclose(r["ay"], -2 * t, atol=1e-12)
    np.testing.assert_allclose(r["az"], 9.81)
    np.testing.assert_allclose(r["gx"], 0.1 * t, atol=1e-12)
    np.testing.assert_allclose(r["gz"], -0.2)
    # odometry at 50 Hz (odd samples), |v| = 1 + t, interpolated: exact for a linear speed
    ok = np.isfinite(r["speed_odom"])
    assert ok.sum() == N - 1 and not ok[0]  # before the first odometry message
    np.testing.assert_allclose(r["speed_odom"][ok], 1 + t[ok], atol=1e-9)
    # GNSS velocity once per fix at its sample, NaN elsewhere
    g = r["gps_speed"]
    assert np.flatnonzero(np.isfinite(g)).tolist() == list(range(5, N, 10))
    np.testing.assert_allclose(g[15], 18.0, atol=1e-12)
    assert np.isnan(r["gps_lat"][55]) and r["gps_lat"][65] == 47.5  # status -1: no fix
    assert r["gps_hacc"][65] == 3.0 and r.units["gps_speed"] == "m/s"
    assert r.units["ax"] == "m/s^2" and r.units["gx"] == "rad/s"
    assert r.events["gps_fix"].size == N // 10


@pytest.mark.parametrize("ros1", [False, True])
def test_bag_read_and_detected(tmp_path, ros1):
    p = _write(tmp_path / ("d.bag" if ros1 else "d"), ros1)
    assert detect(p) and vio.detect_format(p) == "rosbag"
    r = vio.read(p)
    _check(r)
    assert r.meta["imu_topic"] == "/imu/data" and r.meta["t0_ns"] == T0
    notes = " ".join(r.notes)
    assert "/imu/data: header stamps used (receive - header: median 2 ms)" in notes
    assert "gps_speed" in notes and "speed_odom" in notes
    if not ros1:  # a file inside the bag folder reads the bag
        db = next(p.glob("*.db3"))
        assert vio.detect_format(db) == "rosbag"
        np.testing.assert_array_equal(vio.read(db)["ax"], r["ax"])


def test_same_recording_as_the_equivalent_csv(tmp_path):
    r = vio.read(_write(tmp_path / "b"))
    vio.write(Recording(t=r.t, channels=r.channels, units=r.units), tmp_path / "eq.csv")
    c = vio.read(tmp_path / "eq.csv")
    assert list(c.channels) == list(r.channels)
    for k in r.channels:
        assert c.units[k] == r.units[k]
        np.testing.assert_allclose(c[k], r[k], rtol=1e-12, equal_nan=True)


def test_receive_time_when_header_unset(tmp_path):
    r = read_rosbag(_write(tmp_path / "b", header_zero=("/imu/data", "/odom"), gps=False))
    np.testing.assert_allclose(r.t, np.arange(N) * 0.01, atol=1e-12)  # 2 ms latency cancels
    assert r.meta["t0_ns"] == T0 + 2_000_000
    assert any("/imu/data: receive time used (header stamps unset)" in n for n in r.notes)
    r = read_rosbag(_write(tmp_path / "c", gps=False), stamps="receive")
    assert r.meta["t0_ns"] == T0 + 2_000_000


def test_mixed_clocks_fall_back_to_receive_time(tmp_path):
    # odometry without stamps, IMU stamps 1 s from receive time: one clock for all
    p = _write(tmp_path / "b", header_zero=("/odom",), latency_ns=1_000_000_000, gps=False)
    r = read_rosbag(p)
    assert r.meta["t0_ns"] == T0 + 1_000_000_000
    assert any("receive time used for all topics" in n for n in r.notes)


def test_topic_choice(tmp_path):
    p = _write(tmp_path / "b", imu2=True, gps=False)
    r = vio.read(p)
    assert r.meta["imu_topic"] == "/imu/data" and any("/cam/imu" in n for n in r.notes)
    r = vio.read(p, topic="/cam/imu")
    assert r.meta["imu_topic"] == "/cam/imu" and len(r) == N // 4
    with pytest.raises(ReaderError, match="topic /nope not found"):
        vio.read(p, topic="/nope")
    with pytest.raises(ReaderError, match="none of the topics /odom is a sensor_msgs/Imu"):
        vio.read(p, topic="/odom")
    with pytest.raises(ParameterError, match="does not take option 'topic'"):
        vio.write(Recording(t=np.arange(3.0), channels={"ay": np.zeros(3)}), tmp_path / "x.csv")
        vio.read(tmp_path / "x.csv", topic="/imu")


def _corrupt(path, keep):
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


@pytest.mark.parametrize("keep", [0.05, 0.5, 0.95])
def test_truncated_ros1_bag_one_line_error(tmp_path, keep):
    p = _write(tmp_path / "t.bag", ros1=True, gps=False)
    _corrupt(p, keep)
    with pytest.raises(ReaderError) as exc:
        read_rosbag(p)
    assert str(exc.value).startswith(str(p)) and "\n" not in str(exc.value)


def test_corrupt_ros2_bag_one_line_error(tmp_path):
    p = _write(tmp_path / "b", gps=False)
    db = next(p.glob("*.db3"))
    data = bytearray(db.read_bytes())
    data[100:4000] = b"\x00" * 3900
    db.write_bytes(bytes(data))
    with pytest.raises(ReaderError, match="corrupt or unreadable ROS bag") as exc:
        read_rosbag(p)
    assert "\n" not in str(exc.value)
    (p / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    with pytest.raises(ReaderError, match="corrupt or unreadable ROS bag"):
        read_rosbag(p)


def test_no_imu_topic(tmp_path):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    _, odom, _, _ = _msgs(ts)
    p = tmp_path / "o"
    with Writer2(p, version=9) as w:
        c = w.add_connection("/odom", "nav_msgs/msg/Odometry", typestore=ts)
        w.write(c, T0, ts.serialize_cdr(odom(T0, 1.0), "nav_msgs/msg/Odometry"))
    with pytest.raises(ReaderError, match=r"no sensor_msgs/Imu topic in this bag \(found: /odom"):
        read_rosbag(p)


def test_cli_corrupt_bag_exit_2(tmp_path):
    from typer.testing import CliRunner

    from vibrospeed.cli.app import app

    p = _write(tmp_path / "c.bag", ros1=True, gps=False)
    res = CliRunner().invoke(app, ["info", str(p)])
    assert res.exit_code == 0, res.output
    assert "/imu/data" in res.output
    _corrupt(p, 0.6)
    res = CliRunner().invoke(app, ["info", str(p)])
    assert res.exit_code == 2 and "c.bag" in res.output and "Traceback" not in res.output


def test_cli_topic_option(tmp_path):
    import json

    from typer.testing import CliRunner

    from vibrospeed.cli.app import app

    p = _write(tmp_path / "b", imu2=True, gps=False)
    out = tmp_path / "est.csv"
    res = CliRunner().invoke(app, ["estimate", str(p), "--topic", "/cam/imu", "-m", "ekf",
                                   "--init-omega", "10", "-p", "omega_max=30", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert sum(1 for _ in open(out)) - 1 == N // 4  # the camera IMU's samples
    assert json.load(open(str(out) + ".json"))["method"] == "ekf"
    res = CliRunner().invoke(app, ["estimate", str(p), "--topic", "/nope", "-o", str(out)])
    assert res.exit_code == 2 and "topic /nope not found" in res.output


def test_gnss_messages_in_an_imu_gap_keep_rows_of_their_own(tmp_path):
    """The IMU is silent for 0.8 s while GNSS goes on at 10 Hz: each fix inside the gap is
    placed once at its own time on a row of its own (IMU channels NaN there), not piled onto
    the gap's edge samples with all but two lost; the time-line note still sees one gap."""
    gap = range(60, 140)
    r = read_rosbag(_write(tmp_path / "bag", imu_gap=gap))
    g = r["gps_speed"]
    fin = np.isfinite(g)
    want_t = np.arange(5, N, 10) * 0.01
    np.testing.assert_allclose(r.t[fin], want_t, atol=1e-9)
    np.testing.assert_allclose(g[fin], 3.0 + np.arange(5, N, 10))  # |twist| = 3 + i
    lat = np.isfinite(r["gps_lat"])  # status -1 at i = 55: no position there, a row all the same
    np.testing.assert_allclose(r.t[lat], want_t[want_t != 0.55], atol=1e-9)
    added = ~np.isin(np.round(r.t, 6), np.round(np.setdiff1d(np.arange(N), gap) * 0.01, 6))
    np.testing.assert_allclose(r.t[added], np.arange(65, 140, 10) * 0.01, atol=1e-9)
    assert np.all(np.isnan(r["ax"][added])) and np.all(np.isfinite(r["ax"][~added]))
    assert "8 valid GPS fix(es) inside IMU gaps" in "\n".join(r.notes)
    assert any(n.startswith("1 time gap(s) longer than 3 periods, longest 0.81 s")
               for n in r.notes)
