"""The wheel radius ``fuse`` learns, in the batch summary (``fitted_radius``,
``fitted_radius_std``) and the drive report, and empty where a drive kept its prior."""

import json
import math

import numpy as np
import pandas as pd
import pytest

from vibrospeed import batch, io, sim
from vibrospeed.eval.metrics import fitted_radius, radius_fit, track_summary
from vibrospeed.eval.report import _radius_rows
from vibrospeed.types import Recording, Track


def _side(out, name):
    return json.loads((out / f"{name}_fuse.csv.json").read_text())["params"]


def test_fuse_radius_reaches_the_summary_and_the_report_and_carries_to_a_drive_without_gps(
        tmp_path):
    """A 20 s car drive with GPS and its wheel line: the summary's radius is the sidecar's
    learned one, within 3 % of the simulated tyre (0.31 m, the prior 0.3 +- 0.15 m); the
    same drive with the line drowned in noise keeps the prior and leaves the row empty; a
    drive without GPS given the first one's sidecar (the fleet workflow) keeps that prior and
    is empty too. Skipped rows (read back from the outputs) carry the same numbers."""
    rec = sim.simulate("car", seed=1, duration=20)
    truth = rec.wheel_radius
    rng = np.random.default_rng(3)
    noline = rec.with_channels(ay=rng.normal(size=len(rec)), az=9.81 + rng.normal(size=len(rec)))
    nogps = Recording(rec.t, {k: v for k, v in rec.channels.items() if not k.startswith("gps")})
    d = tmp_path / "in"
    d.mkdir()
    io.write(rec, d / "a_gps.csv")
    io.write(noline, d / "b_noline.csv")
    out = tmp_path / "out"
    df = batch.run([d], out, method="fuse", jobs=1)
    assert list(df["status"]) == ["ok", "ok"], df[["file", "error"]]
    got = pd.read_csv(out / "summary.csv")
    a, b = _side(out, "a_gps"), _side(out, "b_noline")
    # the learned radius, as fuse wrote it, is narrow and near the truth
    assert a["learned_radius_std"] < 0.015 * a["learned_radius"]
    assert abs(a["learned_radius"] - truth) < 0.03 * truth
    assert got["fitted_radius"][0] == a["learned_radius"]
    assert got["fitted_radius_std"][0] == a["learned_radius_std"]
    # no line: the filter's radius is its prior (fuse's own test: not known), the row empty
    assert b["radius_prior"] == [0.3, 0.15]
    assert b["learned_radius_std"] >= b["octave_rel"] * b["learned_radius"]
    assert math.isnan(got["fitted_radius"][1]) and math.isnan(got["fitted_radius_std"][1])
    # again: skipped, the numbers read back from the outputs; the report of the drive that
    # learned (written now, from the estimate read back) and the row of the one that did not
    again = batch.run([d / "a_gps.csv"], out, method="fuse", jobs=1, report=True)
    assert list(again["status"]) == ["skipped"]
    assert again["fitted_radius"][0] == df["fitted_radius"][0]
    page = (out / "a_gps_fuse.html").read_text()
    r, s = a["learned_radius"], a["learned_radius_std"]
    assert f"<th>learned wheel radius</th><td>{r:.4f} ± {s:.2g} m</td>" in page
    index = (out / "index.html").read_text()
    assert "<th>wheel radius (m)</th>" in index
    assert f"<td class=\"num\">{r:.4f} ± {s:.4f}</td>" in index
    tb = io.read_track(out / "b_noline_fuse.csv")
    assert _radius_rows(tb, track_summary(tb)) == [(
        "learned wheel radius",
        "not learned (no wheel line while GPS was good): the prior 0.3000 ± 0.15 m kept")]

    # the next drive of that vehicle, without GPS: the first drive's sidecar as its prior
    io.write(nogps, tmp_path / "c_nogps.csv")
    out2 = tmp_path / "out2"
    df2 = batch.run([tmp_path / "c_nogps.csv"], out2, method="fuse", jobs=1,
                    params={"radius_from": str(out / "a_gps_fuse.csv.json")})
    assert list(df2["status"]) == ["ok"], df2["error"]
    c = _side(out2, "c_nogps")
    assert c["radius_prior"] == [a["learned_radius"], a["learned_radius_std"]]
    # known to fuse (it has omega), but the prior it was given, not learned here
    assert c["learned_radius_std"] < c["octave_rel"] * c["learned_radius"]
    assert c["learned_radius_std"] >= a["learned_radius_std"]
    assert "fitted_radius" not in df2.columns and "fitted_radius_std" not in df2.columns
    tc = io.read_track(out2 / "c_nogps_fuse.csv")
    assert _radius_rows(tc, track_summary(tc)) == [(
        "learned wheel radius", "not learned (no wheel line while GPS was good): the prior "
        f"{a['learned_radius']:.4f} ± {a['learned_radius_std']:.2g} m kept")]


def _track(**params) -> Track:
    t = np.arange(5) * 0.1
    return Track.from_speed(t, np.full(5, 10.0), np.full(5, 0.1), method="fuse", params=params)


@pytest.mark.parametrize(("params", "want"), [
    # fuse's test: std below octave_rel (5 %) of the radius
    ({"learned_radius": 0.31, "learned_radius_std": 0.0154, "octave_rel": 0.05,
      "radius_prior": [0.3, 0.15]}, (0.31, 0.0154)),
    ({"learned_radius": 0.31, "learned_radius_std": 0.0156, "octave_rel": 0.05,
      "radius_prior": [0.3, 0.15]}, None),
    ({"learned_radius": 0.31, "learned_radius_std": 0.0156, "octave_rel": 0.1}, (0.31, 0.0156)),
    # a given prior: learned only where the drive narrowed it
    ({"learned_radius": 0.3, "learned_radius_std": 0.003003, "octave_rel": 0.05,
      "radius_prior": [0.3, 0.003]}, None),
    ({"learned_radius": 0.3026, "learned_radius_std": 0.0023, "octave_rel": 0.05,
      "radius_prior": [0.3, 0.003]}, (0.3026, 0.0023)),
    # an older sidecar without octave_rel and radius_prior: fuse's default octave_rel
    ({"learned_radius": 0.31, "learned_radius_std": 0.01}, (0.31, 0.01)),
    ({"learned_radius": 0.31, "learned_radius_std": 0.02}, None),
    ({"learned_radius": None, "learned_radius_std": 0.01}, None),
    # a method's own fitted radius comes first
    ({"fitted_radius": 0.28, "fitted_radius_std": 0.002, "learned_radius": 0.31,
      "learned_radius_std": 0.01}, (0.28, 0.002)),
])
def test_radius_fit_reads_fuses_test_from_the_params(params, want):
    tr = _track(**params)
    got = radius_fit(tr)
    if want is None:
        assert math.isnan(got[0]) and math.isnan(got[1]) and math.isnan(fitted_radius(tr))
    else:
        assert got == want and fitted_radius(tr) == want[0]
        s = track_summary(tr)
        assert (s["fitted_radius"], s["fitted_radius_std"]) == want


def test_a_wheel_radius_fit_column_still_counts_without_a_std():
    tr = _track()
    tr.extras["wheel_radius_fit"] = np.array([np.nan, 0.29, 0.3, np.nan, np.nan])
    r, s = radius_fit(tr)
    assert r == 0.3 and math.isnan(s)
