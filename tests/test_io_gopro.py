"""GoPro GPMF telemetry: a tiny MP4 with a gpmd track written here, the KLV parser on known and
random bytes, cut and corrupt files."""

import struct

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from vibrospeed import io as vio
from vibrospeed.errors import InputError, ReaderError
from vibrospeed.io.gopro import GpmfError, detect, iter_klv, parse_streams, read_gopro
from vibrospeed.types import Recording

ACC_SCAL, GYR_SCAL = 418, 374
NP, NA, NG = 3, 200, 18  # payloads of 1 s, ACCL/GYRO samples and GPS fixes per payload


def klv(key, typ, size, repeat, data):
    data = bytes(data)
    assert len(data) == size * repeat
    pad = (-len(data)) % 4
    return key.encode() + bytes([ord(typ) if typ != "\0" else 0, size]) + struct.pack(
        ">H", repeat) + data + b"\0" * pad


def nest(key, *items):
    body = b"".join(items)
    return klv(key, "\0", 1, len(body), body)


def _counts(i):
    k = np.arange(NA) + i * NA
    acc = np.stack([4000 + (k % 50), k % 7 - 3, -(k % 11)], axis=1).astype(np.int16)
    gyr = np.stack([k % 5, -(k % 3), k % 13], axis=1).astype(np.int16)
    return acc, gyr


def payload(i, *, gps_fix=3, orin="ZXY"):
    acc, gyr = _counts(i)
    gps = np.array([[int(47.5e7), int(19.0e7), 100_000, (10 + i) * 1000 + f, 0]
                    for f in range(NG)], dtype=">i4")
    strm_acc = nest("STRM", klv("STNM", "c", 13, 1, b"Accelerometer"[:13]),
                    klv("SIUN", "c", 5, 1, b"m/s\xb2\0"),
                    klv("SCAL", "s", 2, 1, struct.pack(">h", ACC_SCAL)),
                    klv("ORIN", "c", 3, 1, orin.encode()),
                    klv("ACCL", "s", 6, NA, acc.astype(">i2").tobytes()))
    strm_gyr = nest("STRM", klv("SCAL", "s", 2, 1, struct.pack(">h", GYR_SCAL)),
                    klv("ORIN", "c", 3, 1, orin.encode()),
                    klv("GYRO", "s", 6, NA, gyr.astype(">i2").tobytes()))
    strm_gps = nest("STRM", klv("GPSF", "L", 4, 1, struct.pack(">I", gps_fix)),
                    klv("SCAL", "l", 4, 5, struct.pack(">5i", 10**7, 10**7, 1000, 1000, 100)),
                    klv("GPS5", "l", 20, NG, gps.tobytes()))
    return nest("DEVC", klv("DVID", "L", 4, 1, struct.pack(">I", 1)),
                klv("DVNM", "c", 6, 1, b"Camera"), strm_acc, strm_gyr, strm_gps)


def box(typ, body):
    return struct.pack(">I4s", 8 + len(body), typ) + body


def full(typ, body, version=0):
    return box(typ, bytes([version, 0, 0, 0]) + body)


def mp4(payloads, timescale=1000, dur=1000, gpmd=True):
    """A minimal MP4: ftyp, mdat with the payloads, moov with one gpmd track (1 sample/chunk)."""
    ftyp = box(b"ftyp", b"mp41\0\0\0\0mp41")
    mdat = box(b"mdat", b"".join(payloads))
    base = len(ftyp) + 8
    offs, o = [], base
    for pl in payloads:
        offs.append(o)
        o += len(pl)
    stsd = full(b"stsd", struct.pack(">I", 1) + box(b"gpmd" if gpmd else b"avc1", b"\0" * 8))
    stts = full(b"stts", struct.pack(">III", 1, len(payloads), dur))
    stsc = full(b"stsc", struct.pack(">IIII", 1, 1, 1, 1))
    stsz = full(b"stsz", struct.pack(">II", 0, len(payloads))
                + b"".join(struct.pack(">I", len(pl)) for pl in payloads))
    stco = full(b"stco", struct.pack(">I", len(payloads)) + b"".join(struct.pack(">I", x)
                                                                    for x in offs))
    stbl = box(b"stbl", stsd + stts + stsc + stsz + stco)
    mdhd = full(b"mdhd", struct.pack(">IIIIHH", 0, 0, timescale, dur * len(payloads), 0, 0))
    hdlr = full(b"hdlr", struct.pack(">I4s", 0, b"meta") + b"\0" * 12 + b"GoPro MET\0")
    trak = box(b"trak", box(b"mdia", mdhd + hdlr + box(b"minf", stbl)))
    return ftyp + mdat + box(b"moov", trak)


@pytest.fixture
def clip(tmp_path):
    p = tmp_path / "GX010001.MP4"
    p.write_bytes(mp4([payload(i, gps_fix=0 if i == 1 else 3) for i in range(NP)]))
    return p


def _expected():
    acc = np.concatenate([_counts(i)[0] for i in range(NP)]).astype(float) / ACC_SCAL
    gyr = np.concatenate([_counts(i)[1] for i in range(NP)]).astype(float) / GYR_SCAL
    # ORIN "ZXY": stored columns are camera Z, X, Y
    return acc[:, [1, 2, 0]], gyr[:, [1, 2, 0]]


def test_clip_read_like_the_equivalent_csv(clip, tmp_path):
    assert detect(clip) and vio.detect_format(clip) == "gopro"
    r = vio.read(clip)
    acc, gyr = _expected()
    t = np.arange(NP * NA) / NA
    np.testing.assert_allclose(r.t, t, atol=1e-9)
    np.testing.assert_allclose(np.column_stack([r["ax"], r["ay"], r["az"]]), acc, atol=1e-12)
    np.testing.assert_allclose(np.column_stack([r["gx"], r["gy"], r["gz"]]), gyr, atol=1e-9)
    # GPS5: 18 Hz speed2d (SCAL 1000) at the nearest sample; payload 1 has no fix -> NaN
    g = r["gps_speed"]
    tf = np.concatenate([i + np.arange(NG) / NG for i in range(NP)])
    j = np.rint(tf * NA).astype(int)
    j = j[j < NP * NA]
    assert np.flatnonzero(np.isfinite(g)).tolist() == [x for x in j.tolist()
                                                       if not NA <= x < 2 * NA]
    assert g[0] == 10.0 and g[j[1]] == 10.001 and g[2 * NA] == 12.0
    assert r["gps_lat"][0] == 47.5 and r.units["gps_speed"] == "m/s"
    assert r.events["gps_fix"].size == NP * NG
    notes = " ".join(r.notes)
    assert "uniform 200 Hz" in notes and "ORIN ZXY" in notes and "GPS5" in notes
    # the same recording as the equivalent canonical CSV
    vio.write(Recording(t=r.t, channels=r.channels, units=r.units), tmp_path / "eq.csv")
    c = vio.read(tmp_path / "eq.csv")
    assert list(c.channels) == list(r.channels)
    for k in r.channels:
        assert c.units[k] == r.units[k]
        np.testing.assert_allclose(c[k], r[k], rtol=1e-12, equal_nan=True)


def test_varying_samples_per_payload_give_a_fitted_uniform_rate(tmp_path):
    pls = []
    for n in (199, 201, 198, 202):
        acc = np.full((n, 3), 418, dtype=">i2")
        pls.append(nest("DEVC", nest("STRM", klv("SCAL", "s", 2, 1, struct.pack(">h", 418)),
                                     klv("ACCL", "s", 6, n, acc.tobytes()))))
    p = tmp_path / "v.mp4"
    p.write_bytes(mp4(pls))
    r = read_gopro(p)
    assert len(r) == 800 and r.is_uniform(1e-9)
    assert abs(r.fs - 200.0) < 0.5 and np.all(r["ax"] == 1.0)
    assert any("stored order" in n for n in r.notes)  # no ORIN


def test_klv_parser_known_bytes():
    buf = nest("DEVC", klv("TSMP", "L", 4, 1, struct.pack(">I", 7)),
               klv("ACCL", "s", 6, 2, struct.pack(">6h", 1, 2, 3, 4, 5, 6)))
    (devc,) = iter_klv(buf + b"\0" * 8)  # trailing padding accepted
    assert devc.key == "DEVC" and [c.key for c in devc.children] == ["TSMP", "ACCL"]
    assert devc.children[1].repeat == 2 and len(devc.children[1].data) == 12
    with pytest.raises(GpmfError, match="runs past its container"):
        iter_klv(buf[:-4])
    with pytest.raises(GpmfError, match="bad GPMF key"):
        iter_klv(b"\x01\x02\x03\x04s\x02\x00\x01\x00\x01\x00\x00")
    # complex type through TYPE (GPS9-like), Q15.16 fixed point
    strm = nest("STRM", klv("TYPE", "c", 3, 1, b"lSq"),
                klv("GPS9", "?", 10, 1, struct.pack(">iHi", -5, 7, 3 * 65536 // 2)))
    s = parse_streams([nest("DEVC", strm)], keys=("GPS9",))["GPS9"]
    np.testing.assert_allclose(s.chunks[0], [[-5, 7, 1.5]])


@pytest.mark.parametrize(
    ("mutate", "pattern"),
    [
        (lambda b: b[: len(b) // 2], r"no 'moov' box|past the end"),
        (lambda b: b[:-10], r"past the end of its container|truncated"),
        (lambda b: b"\0\0\0\x08ftyp" + b"\xff" * 64, r"size|truncated|moov"),
    ],
)
def test_cut_and_corrupt_files_one_line(clip, mutate, pattern):
    clip.write_bytes(mutate(clip.read_bytes()))
    with pytest.raises(ReaderError, match=pattern) as exc:
        read_gopro(clip)
    assert str(exc.value).startswith(str(clip)) and "\n" not in str(exc.value)


def test_no_gpmd_track_and_corrupt_payload(tmp_path):
    p = tmp_path / "plain.mp4"
    p.write_bytes(mp4([payload(0)], gpmd=False))
    with pytest.raises(ReaderError, match="no GPMF telemetry track"):
        read_gopro(p)
    bad = bytearray(payload(0))
    bad[40:44] = b"\xff\xff\xff\xff"  # inside the first STRM
    p.write_bytes(mp4([bytes(bad)]))
    with pytest.raises(ReaderError, match="bad GoPro telemetry"):
        read_gopro(p)


def test_cli_exit_2_on_cut_clip(clip):
    from typer.testing import CliRunner

    from vibrospeed.cli.app import app

    res = CliRunner().invoke(app, ["info", str(clip)])
    assert res.exit_code == 0, res.output
    assert "ACCL" in res.output
    clip.write_bytes(clip.read_bytes()[:300])
    res = CliRunner().invoke(app, ["info", str(clip)])
    assert res.exit_code == 2 and "GX010001.MP4" in res.output and "Traceback" not in res.output


@settings(max_examples=150, deadline=None)
@given(st.binary(max_size=300))
def test_klv_parser_random_bytes(data):
    try:
        items = iter_klv(data)
        parse_streams([data])
    except GpmfError:
        return
    assert isinstance(items, list)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.data())
def test_mp4_random_corruption_never_crashes(clip, data):
    raw = bytearray(clip.read_bytes())
    for _ in range(data.draw(st.integers(1, 6))):
        i = data.draw(st.integers(0, len(raw) - 1))
        raw[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(len(raw) // 2, len(raw)))
    p = clip.with_name("fuzz.mp4")
    p.write_bytes(bytes(raw[:cut]))
    try:
        read_gopro(p)
    except InputError as exc:
        assert "\n" not in str(exc)


def test_same_values_as_gopros_own_parser(clip):
    """Cross-check with GoPro's C gpmf-parser (py-gpmf-parser bindings), where installed: the
    fixture is valid GPMF and the values agree (it keeps the stored column order)."""
    ext = pytest.importorskip("py_gpmf_parser.gopro_telemetry_extractor")
    e = ext.GoProTelemetryExtractor(str(clip))
    e.open_source()
    try:
        theirs, _ = e.extract_data("ACCL")
        gps, _ = e.extract_data("GPS5")
    finally:
        e.close_source()
    r = read_gopro(clip)
    np.testing.assert_allclose(theirs[:, [1, 2, 0]], np.column_stack([r["ax"], r["ay"], r["az"]]),
                               atol=1e-9)
    assert gps.shape == (NP * NG, 5) and gps[0, 3] == 10.0
