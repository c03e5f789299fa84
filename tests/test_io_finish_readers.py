"""comma2k19 and F1/10 go through _common.finish like every reader: a bad time line is a one-line
ReaderError naming the file and row, and the time-line notes on the shared files say what numpy
measures on the raw time stamps."""

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vibrospeed import io
from vibrospeed.errors import ReaderError

DATA = Path(__file__).resolve().parents[2] / "shared/datasets"
SEG = DATA / "comma2k19_example/segment_40"
F1 = DATA / "f1tenth_frictionmaps"


def _one_line_error(path, fmt, match):
    with pytest.raises(ReaderError, match=match) as exc:
        io.read(path, fmt)
    assert "\n" not in str(exc.value)


def _npy(path, x):
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path.with_suffix(".npy"), np.asarray(x, dtype=np.float64))
    path.with_suffix(".npy").rename(path)


@pytest.mark.parametrize(("t", "match"), [
    ([0.0, 1.0, 1.0], r"wheel_speed/t: time stamps not increasing at index 2 \(1\.0 s after "
                      r"1\.0 s\)"),
    ([0.0, 1.0, 0.5], r"not increasing at index 2 \(0\.5 s after 1\.0 s\)"),
    ([0.0, np.nan, 2.0], r"wheel_speed/t: time stamp at index 1 is not a number"),
])
def test_comma2k19_bad_time_is_one_line(tmp_path, t, match):
    (tmp_path / "decoded_can").mkdir()
    _npy(tmp_path / "processed_log/CAN/wheel_speed/t", t)
    _one_line_error(tmp_path, "comma2k19", match)


@pytest.mark.parametrize(("rows", "match"), [
    ("0,1,0\n1,1,5\n2,1,5\n", r"imuData.csv, line 4, column 's': time stamp not increasing"),
    ("0,1,0\n1,1,5\n2,0,9\n", r"imuData.csv, line 4, column 's': time stamp not increasing"),
    ("0,1,0\n1,x,5\n", r"imuData.csv, line 3, column 's': time stamp is not a number"),
])
def test_f1tenth_bad_time_is_one_line(tmp_path, rows, match):
    (tmp_path / "imuData.csv").write_text(",s,ns,ax,ay,wz\n"
                                          + rows.replace("\n", ",0,0,0\n"))
    _one_line_error(tmp_path, "f1tenth", match)


def _numbers(note):
    return [float(x) for x in re.findall(r"[-+]?\d+(?:\.\d*)?(?:e[-+]?\d+)?", note)]


def _check_timebase_notes(rec, t, gaps_expected):
    """The non-uniform note's median period, rate and jitter, and the gap note's count, longest
    gap and first gap time, against numpy on the raw stamps ``t``."""
    d = np.diff(t)
    med = np.median(d)
    nonuni = [n for n in rec.notes if n.startswith("non-uniform time line")]
    assert len(nonuni) == 1
    ms, hz, jit = _numbers(nonuni[0])[:3]
    assert ms == pytest.approx(med * 1e3, rel=1e-3) and hz == pytest.approx(1 / med, rel=1e-4)
    assert jit == pytest.approx(np.std(d[d <= 3 * med]) * 1e3, rel=1e-2)
    gap_notes = [n for n in rec.notes if "time gap(s)" in n]
    big = np.flatnonzero(d > 3 * med)
    assert big.size == gaps_expected
    if not gaps_expected:
        assert gap_notes == []
        return
    (note,) = gap_notes
    n, _, longest, first = _numbers(note)
    assert n == big.size and longest == pytest.approx(d[big].max(), rel=1e-3)
    assert first == pytest.approx(t[big[0]] - t[0], rel=1e-5)


@pytest.mark.skipif(not SEG.exists(), reason="comma2k19 example not available")
def test_comma2k19_time_line_notes_on_the_segment():
    t = np.load(SEG / "processed_log/CAN/wheel_speed/t")
    rec = io.read(SEG, "comma2k19")
    _check_timebase_notes(rec, t, 0)
    assert not any("look like g" in n or "no fix" in n for n in rec.notes)


@pytest.mark.skipif(not F1.exists(), reason="F1/10 data not available")
@pytest.mark.parametrize(("ds", "gaps"), [("DS1", 0), ("DS2", 5), ("DS5", 2)])
def test_f1tenth_time_line_notes_on_the_runs(ds, gaps):
    raw = pd.read_csv(F1 / ds / "imuData.csv")
    t = raw["s"].to_numpy(float) + 1e-9 * raw["ns"].to_numpy(float)
    rec = io.read(F1 / ds, "f1tenth")
    _check_timebase_notes(rec, t, gaps)
    assert not any("look like g" in n or "no fix" in n for n in rec.notes)
