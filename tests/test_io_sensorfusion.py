"""Sensor Fusion app logs: a synthetic log with known signals, and malformed lines."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vibrospeed.errors import ReaderError
from vibrospeed.io import detect_format, read
from vibrospeed.io.sensorfusion import read_sensorfusion


def _log(n=100, t0=1_446_211_006_000):
    lines = []
    for i in range(n):
        ts = t0 + 10 * i + (i % 3)  # 100 Hz with +-2 ms jitter
        lines.append(f"{ts}\tACC\t{0.1 * i}\t{-0.2 * i}\t9.81")
        if i % 2 == 0:
            lines.append(f"{ts + 5}\tGYR\t{0.001 * (ts + 5 - t0)}\t0.0\t-1.5")
        if i % 4 == 1:
            lines.append(f"{ts + 1}\tMAG\t10\t20\t30")
            lines.append(f"{ts + 2}\tORI\t1\t0\t0\t0")
        if i in (20, 70):
            lines.append(f"{ts + 3}\tGPS\t58.39\t15.57\t{100 + i}")
    lines.append(f"{t0 + 5000}\tFOO\t1")
    return lines


def test_synthetic_log(tmp_path):
    p = tmp_path / "sensorLog.txt"
    p.write_text("\r\n".join(_log()) + "\r\n")
    assert detect_format(p) == "sensorfusion"
    r = read(p)
    assert len(r) == 100 and r.meta["t0_ms"] == 1_446_211_006_000
    ts = (10 * np.arange(100) + np.arange(100) % 3) / 1000
    np.testing.assert_allclose(r.t, ts)
    np.testing.assert_allclose(r["ax"], 0.1 * np.arange(100))
    # GYR x is linear in its own time (0.001 * ms), so interpolation is exact: gx = t in s
    ok = np.isfinite(r["gx"])
    np.testing.assert_allclose(r["gx"][ok], r.t[ok], atol=1e-12)
    assert ok.sum() >= 97 and np.isnan(r["gx"][0])  # before the first GYR line
    np.testing.assert_allclose(r["gz"][ok], -1.5)
    assert np.flatnonzero(np.isfinite(r["gps_alt"])).tolist() == [20, 70]
    assert r["gps_alt"][70] == 170 and r.events["gps_fix"].size == 2
    notes = " ".join(r.notes)
    assert "ORI" in notes and "unknown tag FOO" in notes and "non-uniform" in notes


@pytest.mark.parametrize(
    ("lines", "pattern"),
    [
        (["100\tACC\t1\t2"], r"line 1: ACC line needs 3 values, found 2"),
        (["100\tACC\t1\t2\t3", "110\tACC\t1\tx\t3"], r"line 2, column 'ACC value 2': 'x' is not"),
        (["100\tGYR\t1\t2\t3"], r"no ACC lines"),
        (["100\tACC\t1\t2\t3", "90\tACC\t1\t2\t3"], r"line 2, column 't': time goes backwards"),
        (["100"], r"line 1: expected 'timestamp TAG values...'"),
    ],
)
def test_malformed(tmp_path, lines, pattern):
    p = tmp_path / "log.txt"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(ReaderError, match=pattern):
        read_sensorfusion(p)


def test_repeat_dropped_and_sort(tmp_path):
    p = tmp_path / "log.txt"
    p.write_text("100\tACC\t1\t2\t3\n100\tACC\t9\t9\t9\n120\tACC\t1\t2\t3\n110\tACC\t4\t5\t6\n")
    with pytest.raises(ReaderError, match="line 4"):
        read_sensorfusion(p)
    r = read_sensorfusion(p, sort=True)
    np.testing.assert_allclose(r.t, [0.0, 0.01, 0.02])
    np.testing.assert_allclose(r["ax"], [1, 4, 1])


_LINES = _log(12)


@settings(max_examples=80, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    drop=st.sets(st.integers(0, len(_LINES) - 1), max_size=4),
    junk=st.lists(st.tuples(st.integers(0, len(_LINES)), st.text(max_size=12)), max_size=3),
    cut=st.integers(0, 400),
)
def test_corrupted_logs_raise_reader_error_only(tmp_path, drop, junk, cut):
    lines = [ln for i, ln in enumerate(_LINES) if i not in drop]
    for pos, text in junk:
        lines.insert(min(pos, len(lines)), text)
    body = "\n".join(lines)
    body = body[: len(body) - cut] if cut < len(body) else body
    p = tmp_path / "log.txt"
    p.write_text(body, encoding="utf-8", errors="surrogatepass")
    try:
        r = read_sensorfusion(p)
    except ReaderError as exc:
        assert "\n" not in str(exc)
    else:
        assert np.all(np.diff(r.t) > 0) and r.t[0] == 0.0


def test_gps_fixes_in_an_acc_gap_and_on_one_sample(tmp_path):
    """ACC stops for 5 s while GPS goes on: each fix inside the gap gets a row of its own at
    its time (ACC NaN there) rather than all landing on the gap's edge samples; two fixes 1 ms
    apart share a sample, and the one dropped is noted (the note counted every fix as placed)."""
    t0 = 1_446_211_006_000
    lines = [f"{t0 + 10 * i}\tACC\t0.1\t{0.01 * i}\t9.81" for i in range(1000)
             if not 300 <= i < 800]
    fixes = [(1000, 58.1), (1001, 58.2), (3500, 58.3), (5500, 58.4), (7500, 58.5)]
    lines += [f"{t0 + ms}\tGPS\t{lat}\t15.57\t100" for ms, lat in fixes]
    p = tmp_path / "sensorLog.txt"
    p.write_text("\n".join(sorted(lines, key=lambda s: int(s.split("\t")[0]))) + "\n")
    r = read_sensorfusion(p)
    lat = r["gps_lat"]
    fin = np.isfinite(lat)
    np.testing.assert_allclose(r.t[fin], [1.0, 3.5, 5.5, 7.5])
    np.testing.assert_array_equal(lat[fin], [58.2, 58.3, 58.4, 58.5])  # 1.001 s wins at 1.0 s
    added = np.isin(r.t, [3.5, 5.5, 7.5])
    assert len(r) == 500 + 3 and np.all(np.isnan(r["ay"][added]))
    np.testing.assert_allclose(r["ay"][~added], 0.01 * np.r_[0:300, 800:1000])
    notes = "\n".join(r.notes)
    assert "3 valid GPS fix(es) inside accelerometer gaps" in notes
    assert "GPS: 5 fixes, 5 inside the ACC span" in notes
    assert "GPS: 1 fix(es) fell on the same ACC sample as a later one" in notes
    assert "1 time gap(s) longer than 3 periods, longest 5.01 s (first at t = 2.99 s)" in notes
