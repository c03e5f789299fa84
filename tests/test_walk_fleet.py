"""A fleet's folder of mixed, partly broken logs through ``vibrospeed batch``'s input expansion,
its local pool and the CSV reader's errors (found walking through a fleet of phone logs)."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from vibrospeed import io
from vibrospeed.batch import expand_inputs
from vibrospeed.errors import ReaderError


def _canonical(path: Path, n: int = 50) -> Path:
    rows = "".join(f"{i / 100:.2f},0.1,0.2,9.8\n" for i in range(n))
    path.write_text("t,ax,ay,az\n" + rows)
    return path


def _phyphox(folder: Path) -> Path:
    """A tiny phyphox export: Accelerometer.csv is the master, Gyroscope.csv beside it."""
    folder.mkdir(parents=True)
    acc = "".join(f"{i / 100:.2f},0.1,0.2,9.8\n" for i in range(50))
    (folder / "Accelerometer.csv").write_text(
        '"Time (s)","X (m/s^2)","Y (m/s^2)","Z (m/s^2)"\n' + acc)
    (folder / "Gyroscope.csv").write_text(
        '"Time (s)","X (rad/s)","Y (rad/s)","Z (rad/s)"\n' + acc.replace("9.8", "0.0"))
    return folder


def test_folder_with_symlink_loop_is_an_error_row_not_a_crash(tmp_path):
    # a link to itself in a fleet folder: Path.resolve raised RuntimeError ("Symlink loop")
    # and the whole batch ended in an internal error before any recording was read
    fleet = tmp_path / "fleet"
    fleet.mkdir()
    _canonical(fleet / "a.csv")
    os.symlink("loop", fleet / "loop")
    found = dict(expand_inputs([fleet], exclude=tmp_path / "out"))
    assert found == {os.fspath(fleet / "a.csv"): None, os.fspath(fleet / "loop"): None}
    with pytest.raises(ReaderError, match=r"loop: broken symbolic link \(to 'loop'"):
        io.read(fleet / "loop")
    # named on the command line, it is a row saying so, not "file not found"
    assert expand_inputs([fleet / "loop"]) == [
        (os.fspath(fleet / "loop"), "broken symbolic link (to 'loop': missing, or a link loop)")]


def test_glob_counts_a_recording_folder_once_not_once_per_csv_in_it(tmp_path):
    # 'fleet/**/*.csv' matched Accelerometer.csv and Gyroscope.csv of a phyphox export; the
    # reader reads either as the whole export, so the same drive was estimated three times
    # (the folder, matched by '**', and each CSV) under names such as Accelerometer-1f0c9e2a
    fleet = tmp_path / "fleet"
    d1 = _phyphox(fleet / "phones" / "drive1")
    d2 = _phyphox(fleet / "phones" / "drive2")
    wrapped = fleet / "wrapped"  # one export unpacked into a folder of its own: the folder
    _phyphox(wrapped / "phyphox 2024-05-01 10-00-00")
    plain = _canonical(fleet / "b.csv")
    want = [(os.fspath(p), None) for p in (plain, d1, d2, wrapped)]
    for pattern in ("**/*.csv", "**"):
        assert expand_inputs([os.fspath(fleet / pattern)]) == want, pattern
    # the export's own CSVs named by a pattern are the export
    assert expand_inputs([os.fspath(d1 / "*.csv")]) == [(os.fspath(d1), None)]
    # a file named explicitly is still read as given
    assert expand_inputs([d1 / "Gyroscope.csv"]) == [(os.fspath(d1 / "Gyroscope.csv"), None)]


def test_glob_star_star_does_not_follow_a_link_back_up(tmp_path):
    # glob's '**' follows sub/up -> .. some 40 levels deep; the deepest copy of each file
    # sorted first and named the recording (fleet/sub/up/sub/up/.../z.csv)
    fleet = tmp_path / "fleet"
    (fleet / "sub").mkdir(parents=True)
    b = _canonical(fleet / "sub" / "b.csv")
    z = _canonical(fleet / "z.csv")  # 'fleet/sub/up/sub/up/.../z.csv' sorts before it
    os.symlink("..", fleet / "sub" / "up")
    found = expand_inputs([os.fspath(fleet / "**" / "*.csv")])
    assert found == [(os.fspath(b), None), (os.fspath(z), None)]


def test_not_utf8_names_the_line_with_the_bad_byte(tmp_path):
    # the text layer decodes 8 kB ahead: a bad byte in the first block said "line 0", one
    # later the line being parsed, not the one that holds it
    lines = ["t,ax,ay,az"] + [f"{i / 100:.2f},0.1,0.2,9.8" for i in range(3000)]
    for bad in (2, 40, 2500):
        data = "\n".join(lines).encode()
        k = data.index(("\n" + lines[bad - 1] + "\n").encode()) + 1
        p = tmp_path / f"bad{bad}.csv"
        p.write_bytes(data[:k] + b"\xff" + data[k:])
        with pytest.raises(ReaderError, match=rf"line {bad}: not UTF-8 text"):
            io.read(p)
    p = tmp_path / "latin1.csv"  # a Latin-1 header: line 1
    p.write_bytes("t,ax,ay,az,temp_\xb0C\n0,1,2,9.8,20\n".encode("latin-1"))
    with pytest.raises(ReaderError, match="line 1: not UTF-8 text"):
        io.read(p)


def _interrupted_pool() -> list[str]:
    from vibrospeed.batch import pool
    from vibrospeed.batch.single import EstimateOptions

    seen: list[str] = []
    old = threading.excepthook
    threading.excepthook = lambda args: seen.append(args.exc_type.__name__)
    jobs = [{"file": f"x{i}", "input": f"/nonexistent/x{i}", "error": "no such log",
             "output": f"/nonexistent/x{i}_grid.csv", "options": EstimateOptions()}
            for i in range(40)]
    got = []

    def done(row):  # Ctrl-C while the rows come in
        got.append(row)
        if len(got) == 2:
            raise KeyboardInterrupt

    try:
        with pytest.raises(KeyboardInterrupt):
            pool._run_local(jobs, 2, done)
    finally:
        threading.excepthook = old
    return seen


def test_ctrl_c_stops_the_pool_without_a_thread_traceback():
    # the pool cancelled its queued futures and then terminated the workers; the pool's
    # manager thread then failed each cancelled future (InvalidStateError on Python < 3.12),
    # a traceback on stderr after the Ctrl-C
    assert _interrupted_pool() == []


def test_resume_estimates_again_when_a_file_read_with_the_recording_changes(tmp_path):
    # a canonical CSV's drive.csv.json holds the wheel radius the reader applies, a --mapping
    # file the units; resume compared the checksum of the CSV alone, so a corrected radius or
    # unit kept the old numbers ('skipped') until --force
    import json

    import numpy as np

    from vibrospeed import batch, sim

    src = tmp_path / "drive.csv"
    io.write(sim.simulate("cart", seed=0, duration=3), src)
    out = tmp_path / "out"
    first = batch.run([src], out, method="ekf", params={"omega_max": 30}, jobs=1)
    assert list(first["status"]) == ["ok"]
    again = batch.run([src], out, method="ekf", params={"omega_max": 30}, jobs=1)
    assert list(again["status"]) == ["skipped"]
    side = Path(f"{src}.json")
    meta = json.loads(side.read_text())
    r0 = meta["wheel_radius"]
    meta["wheel_radius"] = 2 * r0
    side.write_text(json.dumps(meta))
    third = batch.run([src], out, method="ekf", params={"omega_max": 30}, jobs=1)
    assert list(third["status"]) == ["ok"]
    np.testing.assert_allclose(third["median_omega"], first["median_omega"], rtol=1e-12)
    np.testing.assert_allclose(third["median_speed"], 2 * first["median_speed"], rtol=1e-9)

    # the mapping file's contents, not only its name
    raw = tmp_path / "raw.csv"
    raw.write_text("ms,acc\n" + "".join(f"{10 * i},{np.sin(0.3 * i):.4f}\n" for i in range(300)))
    mapping = tmp_path / "m.toml"
    mapping.write_text('[columns]\nt = { column = "ms", unit = "ms" }\nay = "acc"\n')
    opts = batch.EstimateOptions(method="ekf", params={"omega_max": 30}, mapping=str(mapping))
    assert list(batch.run([raw], out, options=opts, jobs=1)["status"]) == ["ok"]
    assert list(batch.run([raw], out, options=opts, jobs=1)["status"]) == ["skipped"]
    mapping.write_text('[columns]\nt = { column = "ms", unit = "ms" }\nay = { column = "acc", '
                       'unit = "g" }\n')
    assert list(batch.run([raw], out, options=opts, jobs=1)["status"]) == ["ok"]


def test_batch_refuses_a_unit_of_the_wrong_quantity_before_it_starts(tmp_path):
    # 'ay=acc:m/s' (a speed unit for an acceleration) and a time column beside a rate fail
    # for every recording alike: they were one error row per recording, not one line
    from vibrospeed import batch
    from vibrospeed.errors import ParameterError

    src = tmp_path / "log.csv"
    src.write_text("ms,acc,yaw\n" + "".join(f"{10 * i},0.1,2\n" for i in range(100)))
    out = tmp_path / "out"
    bad = [
        (dict(columns="t=ms:ms,ay=acc:m/s"), r"^column mapping 'ay': unit 'm/s'"),
        (dict(columns="t=ms:ms,gz=yaw:deg"), r"^column mapping 'gz': unit 'deg' "
                                             r"gives rad, but gz is in rad/s"),
        (dict(columns="t=ms:ms,ay=acc:g", rate=100.0), "time column 't' or a sample rate"),
    ]
    mapping = tmp_path / "m.toml"
    mapping.write_text('rate = 100\n[columns]\nay = { column = "acc", unit = "km/h" }\n')
    bad.append((dict(mapping=str(mapping)), r"m.toml: column mapping 'ay': unit 'km/h'"))
    good = tmp_path / "good.toml"  # its rate, and a time column given beside it
    good.write_text('rate = 100\n[columns]\nay = { column = "acc", unit = "g" }\n')
    bad.append((dict(mapping=str(good), columns="t=ms:ms"), "or a sample rate"))
    for kw, match in bad:
        opts = batch.EstimateOptions(method="ekf", **kw)
        with pytest.raises(ParameterError, match=match):
            batch.run([src], out, options=opts, jobs=1)
        assert not (out / "summary.csv").exists()


def test_a_rerun_removes_temporaries_of_a_killed_writer(tmp_path):
    # Ctrl-C or SIGTERM terminates the pool's workers: one stopped mid-write left its hidden
    # '.drive_ekf.csv.<pid>-<hex>.tmp.csv' in the output folder for good
    import subprocess
    import sys

    from vibrospeed import batch, sim

    src = tmp_path / "drive.csv"
    io.write(sim.simulate("cart", seed=0, duration=2), src)
    out = tmp_path / "out"
    out.mkdir()
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    dead = [out / f".drive_ekf.csv.{gone.pid}-0badc0de.tmp.csv",
            out / f".drive_ekf.csv.json.{gone.pid}-0badc0de.tmp.json"]
    live = out / f".drive_ekf.csv.{os.getpid()}-0badc0de.tmp.csv"  # another batch, writing
    for q in (*dead, live):
        q.write_text("t,omega\n0.0,")
    df = batch.run([src], out, method="ekf", params={"omega_max": 30}, jobs=1)
    assert list(df["status"]) == ["ok"]
    assert not any(q.exists() for q in dead)
    assert live.exists()


def test_sort_note_counts_the_rows_out_of_order(tmp_path):
    # one late row and five repeated ones: the note counted the rows whose place the sort
    # changed ('1000 rows were out of order' for one late sample; 8 for the five repeats)
    import numpy as np

    t = np.round(np.arange(1000) * 0.01, 2)
    rows = [f"{x:.2f},0.1,0.2,9.8" for x in t]
    rows = rows[:1] + rows[2:] + rows[1:2]  # t = 0.01 written last
    rows = rows[:500] + rows[495:500] + rows[500:]  # five stamps repeated
    p = tmp_path / "late.csv"
    p.write_text("t,ax,ay,az\n" + "\n".join(rows) + "\n")
    rec = io.read(p, sort=True)
    assert rec.t.size == 1000 and np.all(np.diff(rec.t) > 0)
    assert "sorted by time (5 rows were out of order)" in rec.notes  # 0.01 and 4.96-4.99
    assert "dropped 5 rows repeating an earlier timestamp (first kept)" in rec.notes
