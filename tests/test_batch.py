"""Batch runs: many recordings, resume, bad files as rows, local processes and Dask."""

import json
import re
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vibrospeed import batch, io, sim
from vibrospeed.cli.app import app


def _broken(folder):
    (folder / "empty.csv").write_text("")
    (folder / "garbage.csv").write_bytes(bytes(range(256)) * 8)
    (folder / "text_column.csv").write_text("t,ay\n0,1\n0.01,abc\n0.02,3\n")
    return ["empty.csv", "garbage.csv", "text_column.csv"]


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """50 short simulated drives (canonical CSV) and three broken files in one folder."""
    d = tmp_path_factory.mktemp("fleet")
    for i in range(50):
        io.write(sim.simulate("cart", seed=i, duration=8), d / f"drive{i:02d}.csv")
    broken = _broken(d)
    return d, broken


def _check_rows(df, d, broken, ok_status):
    assert len(df) == 53
    assert list(df["file"]) == sorted(df["file"])  # input order (the folder's, sorted)
    bad = df[df["file"].map(lambda f: f.split("/")[-1] in broken)]
    assert (bad["status"] == "error").all(), bad
    for _, r in bad.iterrows():
        assert r["file"] in r["error"] and "\n" not in r["error"]
    good = df[df["status"] != "error"]
    assert len(good) == 50 and (good["status"] == ok_status).all(), df[["file", "status",
                                                                        "error"]]
    assert (good["format"] == "csv").all() and np.allclose(good["duration_s"], 7.99)
    assert (good["median_speed"] > 0).all() and (good["distance_m"] > 0).all()
    assert ((good["distance_lo_m"] <= good["distance_m"])
            & (good["distance_m"] <= good["distance_hi_m"])).all()
    assert "fitted_radius" not in df.columns  # no method here fits a radius


def test_fifty_drives_on_dask_twice(fleet, tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    d, broken = fleet
    out = tmp_path / "out"
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        t0 = time.perf_counter()
        df = batch.run([d], out, method="ekf", scheduler=cluster.scheduler_address)
        first = time.perf_counter() - t0
        _check_rows(df, d, broken, "ok")
        assert df["signal_share"].isna().all()  # the EKF has no line detector
        t0 = time.perf_counter()
        again = batch.run([d], out, method="ekf", scheduler=cluster.scheduler_address)
        second = time.perf_counter() - t0
    _check_rows(again, d, broken, "skipped")
    good = again["status"] == "skipped"
    # the skipped rows carry the same numbers, read back from the outputs
    pd.testing.assert_frame_equal(df.loc[good, ["file", "format", "median_speed", "distance_m"]],
                                  again.loc[good, ["file", "format", "median_speed",
                                                   "distance_m"]])
    summary = pd.read_csv(out / "summary.csv")
    assert list(summary["status"]) == list(again["status"])
    pq = pd.read_parquet(out / "summary.parquet")
    assert len(pq) == 53
    print(f"50 drives + 3 broken on Dask: {first:.1f} s, resumed {second:.1f} s")


def test_local_pool_resume_and_changes(tmp_path):
    src = tmp_path / "in"
    (src / "a").mkdir(parents=True)
    (src / "b").mkdir()
    for i, name in enumerate(["a/drive.csv", "b/drive.csv", "a/other.csv"]):
        io.write(sim.simulate("cart", seed=i, duration=8), src / name)
    (src / "a" / "empty.csv").write_text("")
    inputs = [src / "a", str(src / "b" / "*.csv"), src / "missing.csv"]
    out = tmp_path / "out"
    params = {"omega_min": 2, "omega_max": 30}
    df = batch.run(inputs, out, method="grid", params=params, jobs=2)
    assert list(df["status"]) == ["ok", "error", "ok", "ok", "error"], df
    names = list(df.loc[df["status"] == "ok", "output"])
    assert len(set(names)) == 3 and all(n.endswith("_grid.csv") for n in names)
    assert names[0].startswith("drive-") and names[2].startswith("drive-")  # same basename
    assert df.loc[0, "signal_share"] > 0.2  # the grid tracker says where it sees a line
    assert "file not found" in df.loc[4, "error"]
    side = json.loads((out / f"{names[0]}.json").read_text())
    assert side["meta"]["options"]["params"] == {"omega_max": "30.0", "omega_min": "2.0"}
    # in this process: an unchanged recording is skipped, a changed one estimated again
    io.write(sim.simulate("cart", seed=7, duration=8), src / "a" / "other.csv")
    again = batch.run(inputs, out, method="grid", params=params, jobs=1)
    assert list(again["status"]) == ["skipped", "error", "ok", "skipped", "error"], again
    # other options: everything again
    third = batch.run(inputs, out, method="grid", params={**params, "omega_max": 40}, jobs=1)
    assert list(third["status"]) == ["ok", "error", "ok", "ok", "error"]


def test_resume_compares_parameters_by_value(tmp_path):
    """``-p omega_max=30`` and ``-p omega_max=30.0`` (or 3e1, or the number 30 from Python)
    are one option: the second run skips (it estimated everything again, the sidecar's text
    differing); a sidecar that stored the text as typed (before the values were stored read
    as their types) is still up to date for an equal value; another value is estimated."""
    io.write(sim.simulate("cart", seed=5, duration=4), tmp_path / "drive.csv")
    out = tmp_path / "out"

    def run(**params):
        df = batch.run([tmp_path / "drive.csv"], out, method="grid", jobs=1,
                       params={"omega_min": "2", **params})
        return df.loc[0, "status"]

    assert run(omega_max="30") == "ok"
    assert run(omega_max="30.0") == "skipped"
    assert run(omega_max="3e1", omega_min="2.0") == "skipped"
    assert run(omega_max=30) == "skipped"
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), "-o", str(out),
                                   "-j", "1", "-p", "omega_max=30.00,omega_min=2"])
    assert res.exit_code == 0 and "(0 ok, 1 skipped, 0 error)" in res.stderr, res.output
    side_path = out / "drive_grid.csv.json"
    side = json.loads(side_path.read_text())
    assert side["meta"]["options"]["params"] == {"omega_max": "30.0", "omega_min": "2.0"}
    side["meta"]["options"]["params"] = {"omega_max": "30", "omega_min": "2"}  # an old sidecar
    side_path.write_text(json.dumps(side))
    assert run(omega_max="30.0") == "skipped"
    assert run(omega_max="31") == "ok"


def test_resume_compares_a_switch_the_estimator_reads_itself_by_value(tmp_path):
    """``comb`` (ekf, aided) has no Config field: the estimator reads it with
    ``config.parse_flag``, to which ``1``, ``true``, ``True``, ``yes`` and ``on`` are one value.
    The resume read it as a number where it could (``1`` -> 1.0) and as a switch otherwise
    (``true``), so ``-p comb=1`` then ``-p comb=true`` estimated everything again. Spellings
    compare equal exactly where parse_flag reads them equal; sidecars written with ``true``
    (the switch as stored before) or the text as typed still match; a number read by the
    estimator itself (``normalize_tau``) still compares as a number."""
    from vibrospeed.config import parse_flag
    from vibrospeed.estimators.params import canonical_params

    spellings = ["1", "true", "True", "YES", "on", "0", "false", "No", "off", True, False, 1, 0]
    for method in ("ekf", "aided"):
        for a in spellings:
            for b in spellings:
                same = canonical_params(method, {"comb": a}) == canonical_params(method,
                                                                                 {"comb": b})
                assert same == (parse_flag(a, "comb") == parse_flag(b, "comb")), (a, b)
    assert canonical_params("ekf", {"normalize_tau": "0"}) == \
        canonical_params("ekf", {"normalize_tau": "0.0"}) != \
        canonical_params("ekf", {"normalize_tau": "5"})

    io.write(sim.simulate("cart", seed=5, duration=4), tmp_path / "drive.csv")
    out = tmp_path / "out"

    def run(**params):
        df = batch.run([tmp_path / "drive.csv"], out, method="ekf", jobs=1, params=params)
        return df.loc[0, "status"]

    assert run(comb="1") == "ok"
    assert [run(comb=v) for v in ("true", "True", "yes", "on", True)] == ["skipped"] * 5
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), "-o", str(out),
                                   "-m", "ekf", "-j", "1", "-p", "comb=true"])
    assert res.exit_code == 0 and "(0 ok, 1 skipped, 0 error)" in res.stderr, res.output
    side_path = out / "drive_ekf.csv.json"
    side = json.loads(side_path.read_text())
    for old in ("true", "yes", "1.0"):  # as stored now, as typed, as stored before
        side["meta"]["options"]["params"] = {"comb": old}
        side_path.write_text(json.dumps(side))
        assert run(comb="1") == "skipped", old
    assert run(comb="false") == "ok"
    assert run(comb="0") == "skipped" and run(comb="off") == "skipped"
    assert run(comb="false", normalize_tau="5") == "ok"
    assert run(comb="no", normalize_tau="5.0") == "skipped"


def test_names_the_estimators_read_themselves_have_the_type_they_are_read_as():
    """Every ``-p`` name has a type (``estimators.parameters``): a name an estimator reads by
    hand with ``config.parse_flag`` is a switch (``bool``), one it reads with ``float(...)`` a
    number (both found in the estimators' source), so the batch reads each value as the
    estimator will instead of guessing."""
    from vibrospeed import estimators

    src = Path(estimators.__file__).parent
    text = "\n".join((src / f).read_text() for files in _READERS.values() for f in files)
    get = r'\b(?:params|cfg_kw|own|inp)\.(?:pop|get)\(\s*"(\w+)"'
    flags = set(re.findall(r"parse_flag\(\s*" + get, text))
    numbers = set(re.findall(r"\b(?:float|parse_number)\(\s*" + get, text))
    assert {"comb", "causal", "improved", "online"} <= flags
    assert {"normalize_tau", "comb_clarity", "accel_detrend", "wheelbase"} <= numbers
    for method in estimators.METHODS:
        types = estimators.parameters(method)
        assert all(types.values()), (method, [n for n, t in types.items() if not t])
        for name in flags & set(types):
            assert types[name] == [bool], (method, name)
        for name in numbers & set(types):
            assert {float, float | None} & set(types[name]), (method, name)


@pytest.mark.parametrize(("method", "params", "line"), [
    ("ekf", {"comb": "1.0"}, "parameter 'comb': cannot read '1.0' as bool (true or false)"),
    ("ekf", {"comb": "maybe"}, "parameter 'comb': cannot read 'maybe' as bool (true or false)"),
    ("ekf", {"normalize_tau": "abc"},
     "parameter 'normalize_tau': cannot read 'abc' as float (a number)"),
    ("aided", {"causal": "2"}, "parameter 'causal': cannot read '2' as bool (true or false)"),
    ("fuse", {"online": "yes please"},
     "parameter 'online': cannot read 'yes please' as bool (true or false)"),
    ("aided", {"accel_offset": "bogus"}, "parameter 'accel_offset': cannot read 'bogus' as "
     "'standstill' | 'none' (choose from standstill, none)"),
])
def test_a_bad_value_of_a_name_the_estimator_reads_stops_the_batch(tmp_path, method, params,
                                                                   line):
    """A value the estimator's own reading refuses (``parse_flag`` takes ``1`` but not
    ``1.0``; ``float('abc')`` was an internal error) stops the batch before any recording is
    read, exit 2 and one line naming the parameter and the value (it was an error row per
    recording; ``comb=1.0`` after ``comb=true`` was even skipped as the same option)."""
    from vibrospeed.config import parse_flag
    from vibrospeed.errors import ParameterError

    name, value = next(iter(params.items()))
    if name in ("comb", "causal", "online"):  # the estimator's own reading refuses it too
        with pytest.raises(ParameterError):
            parse_flag(value, name)
    io.write(sim.simulate("cart", seed=0, duration=2), tmp_path / "drive.csv")
    out = tmp_path / "out"
    with pytest.raises(ParameterError) as exc:
        batch.run([tmp_path / "drive.csv"], out, method=method, jobs=1, params=params)
    assert str(exc.value) == line and not out.exists()
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), "-o", str(out),
                                   "-m", method, "-j", "1", "-p", f"{name}={value}"])
    assert res.exit_code == 2 and not out.exists(), res.output
    assert res.stderr == f"vibrospeed: error: {line}\n"


def test_a_switch_refused_by_the_estimator_is_no_earlier_options_switch(tmp_path):
    """``comb=1.0`` read as the number 1 matched a ``comb=true`` sidecar and the recording was
    skipped although ``ekf`` refuses the value; now it is refused before the resume looks,
    and the stored switch (``true``; ``1.0`` / ``0.0`` as sidecars stored it before) still
    matches the spellings ``parse_flag`` reads alike."""
    from vibrospeed.errors import ParameterError
    from vibrospeed.estimators.params import canonical_params

    assert canonical_params("ekf", {"comb": "1.0"}) != canonical_params("ekf", {"comb": "true"})
    assert canonical_params("ekf", {"comb": "1.0"}, stored=True) == \
        canonical_params("ekf", {"comb": "on"}) == {"comb": "true"}
    assert canonical_params("aided", {"causal": "0.0"}, stored=True) == \
        canonical_params("aided", {"causal": 0}) == {"causal": "false"}
    io.write(sim.simulate("cart", seed=5, duration=3), tmp_path / "drive.csv")
    out = tmp_path / "out"

    def run(**params):
        return batch.run([tmp_path / "drive.csv"], out, method="ekf", jobs=1,
                         params=params).loc[0, "status"]

    assert run(comb="false") == "ok"
    side_path = out / "drive_ekf.csv.json"
    side = json.loads(side_path.read_text())
    assert side["meta"]["options"]["params"] == {"comb": "false"}
    side["meta"]["options"]["params"] = {"comb": "0.0"}  # as stored before
    side_path.write_text(json.dumps(side))
    assert run(comb="0") == "skipped" and run(comb="off") == "skipped"
    for bad in ("0.0", "1.0"):
        with pytest.raises(ParameterError, match=f"'comb': cannot read '{bad}'"):
            run(comb=bad)


def test_topic_applies_to_the_ros_bags_of_a_mixed_fleet(tmp_path):
    """``--topic`` chooses the IMU of the fleet's ROS bags and leaves its CSV files alone (each
    was an error row, ``format 'csv' does not take option 'topic'``); a CSV's sidecar records
    no topic, so a run without ``--topic`` skips it, and a bag's records the one it read."""
    pytest.importorskip("rosbags")
    from test_io_rosbag import N, _write

    bag = _write(tmp_path / "bag", imu2=True, gps=False)  # /imu/data 100 Hz, /cam/imu 25 Hz
    io.write(sim.simulate("cart", seed=0, duration=4), tmp_path / "drive.csv")
    out = tmp_path / "out"
    opts = {"method": "ekf", "init_omega": 10.0, "params": {"omega_max": "30"}}
    df = batch.run([tmp_path / "drive.csv", bag], out, jobs=1,
                   options=batch.EstimateOptions(**opts, topic="/cam/imu"))
    assert list(df["status"]) == ["ok", "ok"], df["error"]
    assert list(df["format"]) == ["csv", "rosbag"]
    assert len(io.read_track(out / df.loc[1, "output"])) == N // 4  # the camera IMU's samples
    topics = [json.loads((out / f"{o}.json").read_text())["meta"]["options"]["topic"]
              for o in df["output"]]
    assert topics == [None, "/cam/imu"]
    again = batch.run([tmp_path / "drive.csv", bag], out, jobs=1,
                      options=batch.EstimateOptions(**opts))
    assert list(again["status"]) == ["skipped", "ok"]  # the bag's default IMU: another topic
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), str(bag), "-o",
                                   str(out), "-j", "1", "-m", "ekf", "--init-omega", "10",
                                   "-p", "omega_max=30", "--topic", "/cam/imu"])
    assert res.exit_code == 0 and "(1 ok, 1 skipped, 0 error)" in res.stderr, res.output


def test_expand_inputs_and_names(tmp_path):
    (tmp_path / "logs").mkdir()
    for name in ("x.csv", "y.csv", ".hidden.csv", "x.csv.json", "plot.png"):
        (tmp_path / "logs" / name).write_text("t,ay\n0,1\n")
    (tmp_path / "logs" / "x.wss_ticks.csv").write_text("t\n0\n")  # event sidecar of x.csv
    found = batch.expand_inputs([tmp_path / "logs", tmp_path / "logs" / "x.csv"])
    assert [p.split("/")[-1] for p, _ in found] == ["x.csv", "y.csv"]
    found = batch.expand_inputs([str(tmp_path / "logs" / "*.csv"), str(tmp_path / "no*.csv")])
    assert [p.split("/")[-1] for p, _ in found] == ["x.csv", "y.csv", "no*.csv"]
    assert found[-1][1] and "pattern" in found[-1][1]
    names = batch.output_names(["a/d.csv", "b/d.csv", "c/e.csv"])
    assert names[2] == "e" and names[0] != names[1] and names == batch.output_names(
        ["a/d.csv", "b/d.csv", "c/e.csv"])


def test_cli_batch_and_dask_scheduler_option(tmp_path):
    distributed = pytest.importorskip("dask.distributed")
    src = tmp_path / "in"
    src.mkdir()
    for i in range(2):
        io.write(sim.simulate("cart", seed=i, duration=8), src / f"d{i}.csv")
    runner = CliRunner()
    out = tmp_path / "out"
    res = runner.invoke(app, ["batch", str(src), "-o", str(out), "-m", "shs", "-j", "1"])
    assert res.exit_code == 0, res.output
    assert "2 ok, 0 skipped, 0 error" in res.stderr
    _broken(src)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        res = runner.invoke(app, ["batch", str(src), "-o", str(out), "-m", "shs",
                                  "--scheduler", cluster.scheduler_address])
    assert res.exit_code == 2, res.output
    assert "0 ok, 2 skipped, 3 error" in res.stderr
    errors = [ln for ln in res.stderr.splitlines() if "error:" in ln]
    assert len(errors) == 3 and all("Traceback" not in ln for ln in errors)
    assert "empty.csv: empty file" in res.stderr
    res = runner.invoke(app, ["batch", str(src), "-o", str(out), "-m", "nope"])
    assert res.exit_code == 2 and "unknown method" in res.stderr
    import dask

    with dask.config.set({"distributed.comm.timeouts.connect": "1s"}):
        res = runner.invoke(app, ["batch", str(src), "-o", str(out), "-m", "shs",
                                  "--scheduler", "tcp://127.0.0.1:1"])
    assert res.exit_code == 2 and "cannot reach the Dask scheduler" in res.stderr


def _track(has_signal=None, standstill=None, source=None, n=200):
    """A track at 100 Hz, omega ramping 10 -> 30 rad/s, wheel radius 0.3 m, given extras."""
    from vibrospeed.types import Track

    t = np.arange(n) / 100.0
    extras = {k: np.asarray(v, dtype=np.float64) for k, v in
              (("has_signal", has_signal), ("standstill", standstill), ("source", source))
              if v is not None}
    return Track.from_omega(t, np.linspace(10.0, 30.0, n), np.ones(n), wheel_radius=0.3,
                            method="test", extras=extras)


def test_drive_summary_leaves_unmeasured_speeds_empty():
    n = 200
    zeros, ones = np.zeros(n), np.ones(n)
    # the reference: median of a linear ramp 10..30 rad/s is 20; distance = 0.3 * mean * T
    full = {"median_omega": 20.0, "median_speed": 6.0, "distance_m": 0.3 * 20.0 * 1.99}
    for track in (_track(), _track(has_signal=np.r_[zeros[:-1], 1.0]),
                  _track(has_signal=zeros, standstill=ones),  # standing throughout: parked
                  _track(has_signal=zeros, source=np.full(n, 1.0))):  # fuse: GPS held
        row = batch.drive_summary(track)
        assert row["note"] == ""
        for k, v in full.items():
            assert row[k] == pytest.approx(v, rel=1e-12), k
    # a line detector that never claimed, no standstill or one only part of the time (the
    # moving part is then a guess), fuse on acceleration alone (source 0) or standing (3)
    for track in (_track(has_signal=zeros), _track(has_signal=zeros, standstill=zeros),
                  _track(has_signal=zeros, standstill=np.r_[1.0, zeros[1:]]),
                  _track(has_signal=zeros, source=zeros),
                  _track(has_signal=zeros, source=np.r_[3.0, zeros[1:]])):
        row = batch.drive_summary(track)
        assert row["signal_share"] == 0.0
        assert np.isnan([row["median_speed"], row["median_omega"], row["distance_m"]]).all()
        assert "no wheel line" in row["note"]
    assert batch.drive_summary(_track(has_signal=ones))["signal_share"] == 1.0


def test_batch_row_of_a_drive_without_a_line(tmp_path):
    from vibrospeed.types import Recording

    src = tmp_path / "in"
    src.mkdir()
    rng = np.random.default_rng(0)
    n = 8 * 400
    noise = Recording(t=np.arange(n) / 400.0, channels={
        "ax": rng.normal(0.0, 1.0, n), "ay": rng.normal(0.0, 1.0, n),
        "az": 9.81 + rng.normal(0.0, 1.0, n)})
    io.write(noise, src / "a_noise.csv")
    io.write(sim.simulate("cart", seed=0, duration=8), src / "b_cart.csv")
    out = tmp_path / "out"
    params = {"omega_min": 2, "omega_max": 30}
    for status in ("ok", "skipped"):  # the skipped row reads the same numbers back
        df = batch.run([src], out, method="grid", params=params, jobs=1)
        assert list(df["status"]) == [status, status]
        nz, cart = df.iloc[0], df.iloc[1]
        assert nz["signal_share"] == 0.0 and nz["note"] == batch.task.NO_EVIDENCE_NOTE
        assert np.isnan([nz["median_speed"], nz["median_omega"], nz["distance_m"]]).all()
        assert cart["signal_share"] > 0.2 and cart["median_speed"] > 0 and cart["note"] == ""
    summary = pd.read_csv(out / "summary.csv", keep_default_na=False)
    assert summary.loc[0, "median_speed"] == "" and summary.loc[0, "distance_m"] == ""
    assert summary.loc[0, "note"] == batch.task.NO_EVIDENCE_NOTE
    assert summary.loc[1, "note"] == "" and float(summary.loc[1, "median_speed"]) > 0


def test_batch_rows_and_reports_share_one_rule():
    # the batch row's numbers are the drive report's (vibrospeed.eval.metrics.track_summary):
    # one function, so a summary row and its report page cannot disagree
    from vibrospeed.eval import metrics

    assert batch.drive_summary is metrics.track_summary is batch.track_summary
    assert batch.task.NO_EVIDENCE_NOTE == metrics.NO_EVIDENCE_NOTE
    n = 200
    moving, standing = metrics.evidence(_track(has_signal=np.r_[1.0, np.zeros(n - 1)],
                                               standstill=np.r_[np.zeros(n - 1), 1]))
    assert moving.sum() == 1 and moving[0] and standing.sum() == 1 and standing[-1]
    moving, standing = metrics.evidence(_track(has_signal=np.zeros(n),
                                               source=np.r_[1.0, 2.0, 3.0, np.zeros(n - 3)]))
    assert list(np.flatnonzero(moving)) == [0, 1] and list(np.flatnonzero(standing)) == [2]
    assert metrics.evidence(_track()) is None


def test_error_rows_name_their_recording(tmp_path):
    """Every error row names its recording, as the summary's ``error`` column promises: a
    reader's error by the path it read (not named twice), a parameter value the method refuses
    (found per recording, by the estimator: a value its type cannot read stops the batch
    before it starts) with the file put first, one line each."""
    from vibrospeed.batch.task import _lost
    from vibrospeed.errors import ParameterError

    src = tmp_path / "in"
    src.mkdir()
    io.write(sim.simulate("cart", seed=0, duration=4), src / "drive.csv")
    (src / "empty.csv").write_text("")
    with pytest.raises(ParameterError, match="^parameter 'omega_max': cannot read 'abc'"):
        batch.run([src], tmp_path / "out", method="ekf", params={"omega_max": "abc"}, jobs=1)
    df = batch.run([src], tmp_path / "out", method="ekf", params={"prefilter": "bogus"}, jobs=1)
    assert list(df["status"]) == ["error", "error"]
    for _, r in df.iterrows():
        assert r["error"].count(r["file"]) == 1 and "\n" not in r["error"], r["error"]
    drive = df.loc[df["file"].str.endswith("drive.csv"), "error"].iloc[0]
    assert drive.startswith(f"{src / 'drive.csv'}: unknown pre-filter 'bogus'")
    empty = df.loc[df["file"].str.endswith("empty.csv"), "error"].iloc[0]
    assert empty == f"{src / 'empty.csv'}: empty file"
    job = {"file": "logs/a.csv", "input": "/x/logs/a.csv", "output": "/o/a_ekf.csv",
           "options": batch.EstimateOptions(method="ekf")}
    assert _lost(job, "its worker process died")["error"] == \
        "logs/a.csv: its worker process died"


@pytest.mark.parametrize(("opts", "said"), [
    ({"fmt": "phyphx"}, r"^unknown format 'phyphx' \(choose from: auto, .*phyphox"),
    ({"columns": "t=time,acc_y"}, r"^column mapping 'acc_y': expected NAME=COLUMN"),
    ({"mapping": "nowhere.toml"}, r"^nowhere.toml: mapping file not found$"),
])
def test_reading_option_mistakes_stop_the_batch_before_it_starts(tmp_path, opts, said):
    """A format, column mapping or mapping file that no recording could satisfy is one error
    before anything is read or written (it was one error row per recording), from Python and
    from the command line (exit status 2, no summary)."""
    from vibrospeed.errors import VibrospeedError

    io.write(sim.simulate("cart", seed=0, duration=2), tmp_path / "drive.csv")
    out = tmp_path / "out"
    with pytest.raises(VibrospeedError, match=said):
        batch.run([tmp_path / "drive.csv"], out, options=batch.EstimateOptions(**opts))
    assert not out.exists()
    flag = {"fmt": "--format", "columns": "--columns", "mapping": "--mapping"}
    (key, value), = opts.items()
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), "-o", str(out),
                                   flag[key], value])
    assert res.exit_code == 2 and not out.exists(), res.output
    assert res.stderr.count("\n") == 1 and res.stderr.startswith("vibrospeed: error: ")


@pytest.mark.parametrize(("method", "name", "said"), [
    ("ekf", "omega_mx", "'omega_max' or 'omega_min' or 'omega0'"),
    ("fuse", "vib_gte", "'vib_gate' or 'vib_use' or 'vib_sep'"),
    ("aided", "trackr", "'tracker'"),
])
def test_unknown_parameter_stops_the_batch_before_it_starts(tmp_path, method, name, said):
    """A ``-p`` name the method takes nowhere is one line naming the method and the nearest
    accepted names, before anything is read or written (it was one error row per recording,
    ``unknown parameter ... for Config``), from Python and from the command line."""
    from vibrospeed.errors import ParameterError

    io.write(sim.simulate("cart", seed=0, duration=2), tmp_path / "drive.csv")
    out = tmp_path / "out"
    line = f"unknown parameter '{name}' for method '{method}' (did you mean {said}?)"
    with pytest.raises(ParameterError) as exc:
        batch.run([tmp_path / "drive.csv"], out, method=method, params={name: "1"})
    assert str(exc.value) == line and not out.exists()
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), "-o", str(out),
                                   "-m", method, "-p", f"{name}=1"])
    assert res.exit_code == 2 and not out.exists(), res.output
    assert res.stderr == f"vibrospeed: error: {line}\n"


_EKF_TRACKERS = "it is the EKF tracker's (-p tracker=ekf)"


@pytest.mark.parametrize(("params", "line"), [
    ({"amp0": "1"}, f"unknown parameter 'amp0' for method 'aided' with this tracker: "
                    f"{_EKF_TRACKERS}"),
    ({"tracker": "rbpmf", "amp0": "1"}, f"unknown parameter 'amp0' for method 'aided' with "
                                        f"this tracker: {_EKF_TRACKERS}"),
    ({"normalize_tau": "5"}, f"unknown parameter 'normalize_tau' for method 'aided' with this "
                             f"tracker: {_EKF_TRACKERS}"),
    # the EKF's comb switch: the grid tracker read it as its comb evidence's Config
    ({"comb": "false"}, f"unknown parameter 'comb' for method 'aided' with this tracker: "
                        f"{_EKF_TRACKERS}"),
    ({"tracker": "rbpmf", "comb": "true"}, f"unknown parameter 'comb' for method 'aided' "
                                           f"with this tracker: {_EKF_TRACKERS}"),
    ({"tracker": "ekf", "n_grid": "50"}, "unknown parameter 'n_grid' for method 'aided' with "
                                         "this tracker: it is the grid tracker's "
                                         "(-p tracker=grid, the default)"),
])
def test_a_name_only_the_other_aided_tracker_takes_stops_the_batch(tmp_path, params, line):
    """``-m aided`` hands its names to the EKF or to a grid tracker (``-p tracker=``): a name
    only the tracker not chosen takes passed the up-front check (both trackers' names merged)
    and was one error row per recording; it now stops the batch before anything is read, with
    ``vibrospeed estimate``'s line, from Python and from the command line."""
    from vibrospeed.errors import ParameterError

    io.write(sim.simulate("cart", seed=0, duration=2), tmp_path / "drive.csv")
    out = tmp_path / "out"
    with pytest.raises(ParameterError) as exc:
        batch.run([tmp_path / "drive.csv"], out, method="aided", params=params)
    assert str(exc.value) == line and not out.exists()
    args = [a for k, v in params.items() for a in ("-p", f"{k}={v}")]
    for cmd in (["batch", str(tmp_path / "drive.csv"), "-o", str(out)],
                ["estimate", str(tmp_path / "drive.csv"), "-o", str(tmp_path / "e.csv")]):
        res = CliRunner().invoke(app, [*cmd, "-m", "aided", *args])
        assert res.exit_code == 2 and not out.exists(), res.output
        assert res.stderr == f"vibrospeed: error: {line}\n"
    assert not (tmp_path / "e.csv").exists() and not (tmp_path / "e.csv.json").exists()


@pytest.mark.parametrize("value", ["bogus", "EKF", "5"])
def test_an_unknown_aided_tracker_stops_the_batch_with_estimates_line(tmp_path, value):
    """``-m aided -p tracker=bogus`` was one error row per recording; now the batch stops
    before anything is read, exit 2, with the line ``vibrospeed estimate`` (and
    ``aided.estimate``) gives: the value and the valid trackers."""
    import typing

    from vibrospeed import estimators
    from vibrospeed.errors import ParameterError

    valid = typing.get_args(estimators.TRACKER)
    assert set(valid) == {"ekf", "grid", "rbpmf"}
    line = (f"parameter 'tracker': cannot read '{value}' as "
            f"{' | '.join(repr(v) for v in valid)} (choose from {', '.join(valid)})")
    rec = sim.simulate("cart", seed=0, duration=2)
    io.write(rec, tmp_path / "drive.csv")
    with pytest.raises(ParameterError) as exc:
        estimators.get("aided").estimate(rec, params={"tracker": value})
    assert str(exc.value) == line
    out = tmp_path / "out"
    with pytest.raises(ParameterError) as exc:
        batch.run([tmp_path / "drive.csv"], out, method="aided", params={"tracker": value})
    assert str(exc.value) == line and not out.exists()
    for cmd in (["batch", str(tmp_path / "drive.csv"), "-o", str(out)],
                ["estimate", str(tmp_path / "drive.csv"), "-o", str(tmp_path / "e.csv")]):
        res = CliRunner().invoke(app, [*cmd, "-m", "aided", "-p", f"tracker={value}"])
        assert res.exit_code == 2 and not out.exists(), res.output
        assert res.stderr == f"vibrospeed: error: {line}\n"
    assert not (tmp_path / "e.csv").exists()


def test_the_chosen_aided_trackers_own_names_run_in_a_batch(tmp_path):
    """The tracker's own names pass: the EKF's ``amp0`` and the names ``aided.estimate`` reads
    on the EKF path (``normalize_tau``, ``comb``) with ``tracker=ekf``, a grid name with the
    default tracker; the sidecar keeps ``amp0``."""
    io.write(sim.simulate("cart", seed=0, duration=2), tmp_path / "drive.csv")
    for params in ({"tracker": "ekf", "amp0": "1", "normalize_tau": "5", "comb": "false"},
                   {"n_grid": "50"}):
        df = batch.run([tmp_path / "drive.csv"], tmp_path / "out", method="aided", jobs=1,
                       params=params)
        assert list(df["status"]) == ["ok"], df["error"]
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), "-o",
                                   str(tmp_path / "cli"), "-j", "1", "-m", "aided", "-p",
                                   "tracker=ekf", "-p", "amp0=1"])
    assert res.exit_code == 0 and "(1 ok, 0 skipped, 0 error)" in res.stderr, res.output
    side = json.loads((tmp_path / "cli" / "drive_aided.csv.json").read_text())
    assert side["params"]["amp0"] == 1.0


# method -> the estimator modules whose estimate() reads its params (besides Config fields)
_READERS = {"ekf": ["ekf.py"], "rbpmf": ["rbpmf.py", "grid/app.py"],
            "grid": ["grid/method.py", "grid/app.py"], "rbpf": ["rbpf.py"], "shs": ["shs.py"],
            "aided": ["aided/method.py", "aided_grid/method.py"],
            "gps-riss": ["gps_riss/method.py"], "fuse": ["fuse/method.py"],
            "algebraic": ["algebraic/method.py"]}


def test_every_name_an_estimator_reads_is_accepted_by_the_batch():
    """The batch's up-front check (``estimators.parameters``) accepts every name an estimator
    takes out of its params by hand (``params.pop("comb", ...)``, read from the source) and its
    Config fields, so it refuses no name the estimator would have used; and an estimate with
    names taken besides the Config (ekf's prefilter, normalize_tau, comb) runs."""
    from vibrospeed import estimators
    from vibrospeed.config import flat_names

    assert set(_READERS) == set(estimators.METHODS)
    src = Path(estimators.__file__).parent
    popped = re.compile(r'\b(?:params|cfg_kw|own|inp|model_kw)\.(?:pop|get|setdefault)\('
                        r'\s*"(\w+)"')
    for method, files in _READERS.items():
        names = set(estimators.parameters(method))
        read = {n for f in files for n in popped.findall((src / f).read_text())}
        assert read <= names, (method, read - names)
        assert flat_names(estimators.get(method).Config) <= names
    assert {"online", "radius_from", "accel_axis", "omega_max", "comb_snr"} <= \
        set(estimators.parameters("fuse"))  # its own names and its grid tracker's


def test_names_besides_the_config_run(tmp_path):
    io.write(sim.simulate("cart", seed=0, duration=2), tmp_path / "drive.csv")
    df = batch.run([tmp_path / "drive.csv"], tmp_path / "out", method="ekf", jobs=1,
                   params={"prefilter": "thesis-hp", "normalize_tau": "5", "comb": "false"})
    assert list(df["status"]) == ["ok"], df["error"]


def test_run_stopped_between_estimate_and_sidecar_is_not_up_to_date(tmp_path, monkeypatch):
    """A run stopped after an estimate CSV was replaced but before its sidecar was leaves no
    pair that passes as up to date: the old sidecar is gone before the new CSV lands, so going
    back to the old options estimates again instead of skipping with the other options' CSV."""
    import vibrospeed.io.track as track_io

    io.write(sim.simulate("cart", seed=3, duration=4), tmp_path / "drive.csv")
    out = tmp_path / "out"
    a = {"omega_min": 2, "omega_max": 30}
    first = batch.run([tmp_path / "drive.csv"], out, method="grid", params=a, jobs=1)
    assert list(first["status"]) == ["ok"]
    csv_a = (out / "drive_grid.csv").read_bytes()

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt  # Ctrl-C between the CSV and its sidecar

    with monkeypatch.context() as m:
        m.setattr(track_io, "atomic_write_text", stopped)
        with pytest.raises(KeyboardInterrupt):
            batch.run([tmp_path / "drive.csv"], out, method="grid",
                      params={**a, "omega_max": 20}, jobs=1)
    assert (out / "drive_grid.csv").read_bytes() != csv_a  # the other options' estimate
    assert not (out / "drive_grid.csv.json").exists()
    again = batch.run([tmp_path / "drive.csv"], out, method="grid", params=a, jobs=1)
    assert list(again["status"]) == ["ok"], again
    assert (out / "drive_grid.csv").read_bytes() == csv_a
    cols = ["signal_share", "median_omega", "distance_m", "note"]
    pd.testing.assert_frame_equal(again[cols], first[cols])


def test_skipped_recording_gets_a_new_report_where_its_page_is_older(tmp_path):
    """A report left by an earlier run with other options (the estimate replaced since, by a
    run without --report) is written again for a skipped recording; an up-to-date one is
    kept as it is."""
    io.write(sim.simulate("cart", seed=4, duration=4), tmp_path / "drive.csv")
    out = tmp_path / "out"
    page = out / "drive_grid.html"

    def run(omega_max, report):
        return batch.run([tmp_path / "drive.csv"], out, method="grid", jobs=1, report=report,
                         params={"omega_min": 2, "omega_max": omega_max})

    run(30, True)
    said = r"<code>omega_max</code></th><td><code>{}(\.0)?<"
    assert re.search(said.format(30), page.read_text())
    run(20, False)  # the estimate now has omega_max = 20; the page still says 30
    df = run(20, True)
    assert list(df["status"]) == ["skipped"]
    assert re.search(said.format(20), page.read_text())
    kept = page.stat().st_mtime_ns
    run(20, True)
    assert page.stat().st_mtime_ns == kept


def test_dotted_drive_names_are_drives_and_their_ticks_are_not(tmp_path):
    """Only a canonical recording's event streams (``<stem>.<name>.csv`` with the header ``t``
    alone) are left out of a folder or pattern: ``drive.2024-05-01.csv`` beside ``drive.csv``
    is a drive of its own (it was silently left out), and ``trip.v2.csv``'s ticks
    (``trip.v2.wss_ticks.csv``) are its events (they were an error row)."""
    logs = tmp_path / "logs"
    logs.mkdir()
    car = sim.simulate("car", seed=0, duration=3)
    assert "wss_ticks" in car.events
    io.write(sim.simulate("cart", seed=0, duration=2), logs / "drive.csv")
    io.write(sim.simulate("cart", seed=1, duration=2), logs / "drive.2024-05-01.csv")
    io.write(car, logs / "trip.v2.csv")
    assert (logs / "trip.v2.wss_ticks.csv").is_file()
    want = ["drive.2024-05-01.csv", "drive.csv", "trip.v2.csv"]
    for items in ([logs], [str(logs / "*.csv")]):
        found = batch.expand_inputs(items)
        assert [p.split("/")[-1] for p, err in found if err is None] == want, found
    ticks = io.read(logs / "trip.v2.csv").events["wss_ticks"]
    np.testing.assert_array_equal(ticks, car.events["wss_ticks"])



def _alive(pids=None):
    """Live (not zombie) processes from /proc: pid -> parent pid; only ``pids`` if given."""
    out = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit() and (pids is None or int(d.name) in pids):
            try:
                fields = (d / "stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if fields[0] != "Z":
                out[int(d.name)] = int(fields[1])
    return out


def _descendants(pid):
    """Live processes below ``pid``."""
    parent = _alive()
    found, todo = set(), [pid]
    while todo:
        p = todo.pop()
        kids = [c for c, pp in parent.items() if pp == p]
        found.update(kids)
        todo += kids
    return found


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs Linux /proc")
def test_sigterm_stops_the_local_workers_too(tmp_path):
    """``kill`` (SIGTERM: ``timeout``, a job scheduler) of a batch on local processes ends its
    workers as well, with exit status 143; they used to stay behind, orphaned, waiting for work
    that never came."""
    import os
    import signal
    import subprocess
    import sys

    below: set[int] = set()
    src = tmp_path / "in"
    src.mkdir()
    for i in range(6):
        io.write(sim.simulate("cart", seed=i, duration=30), src / f"d{i}.csv")
    code = ("import sys; from vibrospeed import batch; "
            "batch.run([sys.argv[1]], sys.argv[2], method='grid', jobs=2)")
    proc = subprocess.Popen([sys.executable, "-c", code, str(src), str(tmp_path / "out")],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        t0 = time.monotonic()
        while len(_descendants(proc.pid)) < 3 and time.monotonic() - t0 < 60:  # server + 2
            time.sleep(0.1)
        below = _descendants(proc.pid)
        assert len(below) >= 3 and proc.poll() is None, below
        proc.send_signal(signal.SIGTERM)
        status = proc.wait(timeout=60)
        t0 = time.monotonic()
        while _alive(below) and time.monotonic() - t0 < 10:
            time.sleep(0.1)
        assert not _alive(below)
        assert status == 143  # 128 + SIGTERM, as a shell reports it
    finally:
        if proc.poll() is None:
            proc.kill()
        for pid in _alive(below):  # what this test started, should it be left
            os.kill(pid, signal.SIGKILL)


def test_androsensor_gps_file_is_part_of_its_trip(tmp_path):
    """An AndroSensor trip's ``gps.<trip>.csv`` is read with its ``accel.<trip>.csv``: a folder
    or pattern gives the trip once (the GPS file was an "unknown format" error row of its own);
    a GPS file without its accelerometer file beside it is still an input."""
    logs = tmp_path / "trips"
    logs.mkdir()
    head = ("Time since start in ms ,ACCELEROMETER X (m/s²),ACCELEROMETER Y (m/s²),"
            "ACCELEROMETER Z (m/s²)\n")
    gps = ("Time since start in ms ,LOCATION Latitude : ,LOCATION Longitude : ,LOCATION Speed "
           "( Kmh),LOCATION ORIENTATION (°),Satellites in range,LOCATION Altitude ( m)\n"
           "204,1,2,36.0,0,9,5\n503,1,2,72.0,0,10,5\n")
    for trip in ("a", "b"):
        (logs / f"accel.{trip}.csv").write_text(head + "".join(
            f"{k * 10},0.1,0.2,9.8\n" for k in range(100)))
        (logs / f"gps.{trip}.csv").write_text(gps)
    (logs / "gps.lonely.csv").write_text(gps)
    want = ["accel.a.csv", "accel.b.csv", "gps.lonely.csv"]
    for items in ([logs], [str(logs / "*.csv")]):
        found = batch.expand_inputs(items)
        assert [p.split("/")[-1] for p, err in found if err is None] == want, found
    rec = io.read(logs / "accel.a.csv")
    assert np.nanmax(rec["gps_speed"]) == pytest.approx(20.0)  # its GPS read with it


def test_the_band_distances_are_the_estimates_band_integrated(tmp_path):
    """``distance_lo_m`` / ``distance_hi_m``: the trapezoids of the written estimate's
    ``speed_lo`` / ``speed_hi``, recomputed with numpy from its CSV."""
    io.write(sim.simulate("cart", seed=4, duration=8), tmp_path / "drive.csv")
    df = batch.run([tmp_path / "drive.csv"], tmp_path / "out",
                   params={"omega_min": "2", "omega_max": "30"}, jobs=1)
    row = df.iloc[0]
    est = io.read_track(tmp_path / "out" / row["output"])
    for col, edge in (("distance_lo_m", est.speed_lo), ("distance_m", est.speed),
                      ("distance_hi_m", est.speed_hi)):
        ok = np.isfinite(edge[1:]) & np.isfinite(edge[:-1])
        ref = np.sum((0.5 * (edge[1:] + edge[:-1]) * np.diff(est.t))[ok])
        assert row[col] == pytest.approx(ref, rel=1e-9), col
    assert row["distance_lo_m"] < row["distance_m"] < row["distance_hi_m"]


def test_the_fleets_page_example_of_a_value_its_type_cannot_read_is_the_line_batch_prints(
        tmp_path):
    """docs/fleets.md lists a ``-p`` value its type cannot read among the mistakes that stop a
    batch up front, with an example and its line: the example run prints that line, exit 2."""
    doc = (Path(__file__).parents[1] / "docs" / "fleets.md").read_text()
    m = re.search(r"a `-p` value\s+its type cannot read \(`([^`]+)`:\s+`([^`]+)`\)", doc)
    assert m is not None, "docs/fleets.md: the example of a -p value its type cannot read"
    io.write(sim.simulate("cart", seed=0, duration=2), tmp_path / "drive.csv")
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["batch", str(tmp_path / "drive.csv"), "-o", str(out),
                                   "-j", "1", *m.group(1).split()])
    assert res.exit_code == 2 and not out.exists(), res.output
    assert res.stderr == f"vibrospeed: error: {m.group(2)}\n"
