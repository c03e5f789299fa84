"""Track output: CSV + JSON sidecar round trip, empty cells for NaN, checksum of the input."""

import hashlib
import json

import numpy as np
import pytest

from vibrospeed.errors import InputError, ReaderError
from vibrospeed.io import read_track, write_track
from vibrospeed.io.track import TRACK_COLUMNS
from vibrospeed.types import Track


def test_round_trip_with_radius_and_extras(tmp_path):
    rng = np.random.default_rng(1)
    t = np.arange(50) / 100
    tr = Track.from_omega(t, 10 + rng.standard_normal(50), np.full(50, 0.3), wheel_radius=0.08,
                          level=0.9, method="ekf", params={"M": 3, "q": (1e-3, 2.0)},
                          extras={"amp_1": rng.standard_normal(50)}, notes=["init 10 rad/s"])
    inp = tmp_path / "drive.csv"
    inp.write_text("t,ay\n0,1\n")
    out = tmp_path / "est.csv"
    write_track(tr, out, meta={"axis": "y"}, input_path=inp)
    assert out.read_text().splitlines()[0] == ",".join([*TRACK_COLUMNS, "amp_1"])
    side = json.loads((tmp_path / "est.csv.json").read_text())
    assert side["input_sha256"] == hashlib.sha256(inp.read_bytes()).hexdigest()
    assert side["method"] == "ekf" and side["params"] == {"M": 3, "q": [0.001, 2.0]}
    assert side["meta"] == {"axis": "y"} and side["version"]
    back = read_track(out)
    for k in TRACK_COLUMNS:
        np.testing.assert_array_equal(getattr(back, k), getattr(tr, k))
    np.testing.assert_array_equal(back.extras["amp_1"], tr.extras["amp_1"])
    assert (back.method, back.level, back.wheel_radius) == ("ekf", 0.9, 0.08)
    assert back.notes == ["init 10 rad/s"]


def test_unknown_radius_gives_empty_speed_cells(tmp_path):
    tr = Track.from_omega([0.0, 0.01], [10.0, np.nan], [0.5, 0.5])
    out = tmp_path / "e.csv"
    write_track(tr, out)
    rows = out.read_text().splitlines()
    cells = rows[1].split(",")
    assert cells[1] == "10.0" and cells[4] == "" and rows[2].split(",")[1] == ""
    back = read_track(out)
    assert np.isnan(back.speed).all() and back.wheel_radius is None
    assert json.loads((tmp_path / "e.csv.json").read_text())["input_sha256"] is None


def test_track_errors(tmp_path):
    tr = Track.from_omega([0.0], [1.0], extras={"omega": np.zeros(1)})
    with pytest.raises(InputError, match="clash"):
        write_track(tr, tmp_path / "x.csv")
    assert not (tmp_path / "x.csv").exists()
    (tmp_path / "y.csv").write_text("t,ay\n0,1\n")
    with pytest.raises(ReaderError, match="not a track file"):
        read_track(tmp_path / "y.csv")


def test_a_gaussian_band_is_cut_at_zero_below_a_magnitude():
    from statistics import NormalDist

    from vibrospeed.types import Track

    z = NormalDist().inv_cdf(0.99)
    v = np.array([0.0, 0.5, 3.0, -0.2, np.nan, 1.0])
    s = np.array([1.0, 1.0, 1.0, 1.0, 1.0, np.nan])
    tr = Track.from_speed(np.arange(6.0), v, s, wheel_radius=0.5)
    # speed and omega are magnitudes: the lower edge never below 0 under an estimate >= 0
    np.testing.assert_array_equal(tr.speed_lo[:3], [0.0, 0.0, 3.0 - z])
    assert tr.speed_lo[3] == -0.2 - z  # a negative estimate keeps its plain band
    assert np.isnan(tr.speed_lo[4]) and np.isnan(tr.speed_lo[5])
    np.testing.assert_array_equal(tr.speed_hi[:4], v[:4] + z)
    np.testing.assert_array_equal(tr.omega_lo, tr.speed_lo / 0.5)
    given = Track.from_omega(np.arange(2.0), [1.0, 2.0], [5.0, 5.0], lo=[-1.0, -2.0],
                             hi=[3.0, 4.0])
    np.testing.assert_array_equal(given.omega_lo, [-1.0, -2.0])  # a band given is kept
