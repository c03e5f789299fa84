"""read(): format dispatch, registration of more readers, resampling on read."""

import numpy as np
import pytest

import vibrospeed.io as vio
from vibrospeed.errors import ParameterError, ReaderError
from vibrospeed.types import Recording


def test_formats_listed_and_dispatch(tmp_path):
    for name in ("csv", "mapped", "phyphox", "sensorfusion", "parquet"):
        assert name in vio.FORMATS and vio.FORMATS[name]
    (tmp_path / "x.bin").write_bytes(b"\x01\x02")
    with pytest.raises(ReaderError, match=r"x\.bin, line 1: unknown format"):
        vio.read(tmp_path / "x.bin")
    (tmp_path / "d").mkdir()
    with pytest.raises(ReaderError, match="not a phyphox export"):
        vio.read(tmp_path / "d")


def test_register_format(tmp_path):
    p = tmp_path / "a.mine"
    p.write_text("MINE 3\n")

    def reader(path, *, sort=False):
        n = int(path.read_text().split()[1])
        return Recording(t=np.arange(n, dtype=float), channels={"ay": np.ones(n)}, source=str(path))

    vio.register_format("mine", reader, description="test format",
                        detect=lambda q: q.suffix == ".mine")
    try:
        assert vio.FORMATS["mine"] == "test format"
        assert list(vio.FORMATS)[-2:] == ["csv", "mapped"]  # generic formats stay last
        assert len(vio.read(p)) == 3
        with pytest.raises(ParameterError, match="does not take option 'rate'"):
            vio.read(p, format="mine", rate=5.0)
    finally:
        vio._REGISTRY.pop("mine")
        vio.FORMATS.pop("mine")


def test_read_with_resample(tmp_path):
    t = np.array([0.0, 0.011, 0.019, 0.030, 0.041, 0.050])
    vio.write(Recording(t=t, channels={"ax": 3 * t}), tmp_path / "j.csv")
    r = vio.read(tmp_path / "j.csv", resample=100.0)
    np.testing.assert_allclose(r.t, np.arange(6) / 100, atol=1e-15)
    np.testing.assert_allclose(r["ax"], 3 * r.t, atol=1e-12)
    assert "linear interpolation" in r.notes[-1]


def test_unknown_format_quotes_the_header_printably(tmp_path):
    """A binary file's first line is quoted with its control characters escaped (a terminal
    escape, NUL or BEL in the error line would act on the terminal or the summary table) and
    cut at 40 characters."""
    p = tmp_path / "x.bin"
    p.write_bytes(b"AB\x1b[31mRED\x00\x07CD" + b"z" * 60 + b"\n1,2\n")
    with pytest.raises(ReaderError, match=r"unknown format \(header starts 'AB\\x1b\[31mRED"
                                          r"\\x00\\x07CDz+\.\.\.'\)") as exc:
        vio.read(p)
    assert str(exc.value).isprintable()


def test_format_takes_says_which_reader_takes_which_option():
    from vibrospeed.io import FORMATS, format_takes

    assert format_takes("mapped", "columns") and format_takes("mapped", "rate")
    assert not format_takes("csv", "topic") and not format_takes("nosuch", "topic")
    if "rosbag" in FORMATS:
        assert format_takes("rosbag", "topic")



def test_read_refuses_an_option_its_format_does_not_take(tmp_path):
    import pytest

    from vibrospeed import io
    from vibrospeed.errors import ParameterError

    p = tmp_path / "a.csv"
    p.write_text("t,ay\n0,1\n0.01,2\n0.02,3\n")
    assert not io.format_takes("csv", "topic")
    with pytest.raises(ParameterError, match="format 'csv' does not take option 'topic'"):
        io.read(p, topic="/imu")
