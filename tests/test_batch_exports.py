"""A folder of app exports (phyphox, Sensor Logger), one subfolder per drive, is that many
recordings, in a batch as in the format detection; a folder that is one export, directly or
unpacked into a folder of its own, is one; every file of an export comes from the folder that
holds its accelerometer."""

import json
import zipfile
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vibrospeed import batch, io, sim
from vibrospeed.cli.app import app
from vibrospeed.errors import ReaderError
from vibrospeed.io.phyphox import is_phyphox
from vibrospeed.io.sensorlogger import detect as is_sensorlogger

HUNGARY = Path(__file__).resolve().parents[2] / "shared/datasets/hungary_car_phyphox"

_ACC_H = '"Time (s)","X (m/s^2)","Y (m/s^2)","Z (m/s^2)"\n'
_GYR_H = '"Time (s)","X (rad/s)","Y (rad/s)","Z (rad/s)"\n'


def _phyphox(folder: Path, n: int, *, gyro: float = 0.0, seed: int = 0) -> np.ndarray:
    """A phyphox export of ``n`` samples at 100 Hz: a simulated cart's ``ay`` on Y, its time line
    on X (so a reader's time line can be checked), gravity on Z; a gyroscope reading ``gyro`` on
    X. Returns the written ``ay``."""
    folder.mkdir(parents=True, exist_ok=True)
    rec = sim.simulate("cart", seed=seed, duration=n / 100 + 0.5)
    t = np.arange(n) / 100
    ay = np.asarray(rec["ay"][:n], dtype=np.float64)
    (folder / "Accelerometer.csv").write_text(_ACC_H + "".join(
        f"{ti!r},{ti!r},{a!r},9.81\n" for ti, a in zip(t.tolist(), ay.tolist(), strict=True)))
    (folder / "Gyroscope.csv").write_text(_GYR_H + "".join(
        f"{ti!r},{gyro!r},0,0\n" for ti in t.tolist()))
    return ay


def _sensorlogger(folder: Path, n: int) -> None:
    """A Sensor Logger export of ``n`` samples at 100 Hz (TotalAcceleration.csv only)."""
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(n) / 100
    rows = "".join(f"{1_700_000_000_000_000_000 + round(x * 1e9)},{x!r},9.8,{x!r},0.0\n"
                   for x in t.tolist())
    (folder / "TotalAcceleration.csv").write_text("time,seconds_elapsed,z,y,x\n" + rows)


def test_folder_of_phyphox_exports_is_one_recording_each(tmp_path):
    root = tmp_path / "phone_logs"
    lengths = {"drive_a": 300, "drive_b": 450, "drive_c": 600}
    written = {name: _phyphox(root / name, n, seed=k)
               for k, (name, n) in enumerate(lengths.items())}
    (root / "notes.md").write_text("three drives\n")
    (root / ".cache").mkdir()  # hidden: never a recording
    _phyphox(root / ".cache" / "old", 100)
    assert not is_phyphox(root) and not is_sensorlogger(root)
    assert all(is_phyphox(root / name) for name in lengths)
    found = batch.expand_inputs([root])
    assert [(Path(p).name, err) for p, err in found] == [(n, None) for n in lengths]
    for p, _ in found:  # each input is its own drive, whole
        r = io.read(p, "phyphox")
        assert len(r) == lengths[Path(p).name]
        np.testing.assert_array_equal(r["ay"], written[Path(p).name])
        np.testing.assert_allclose(r["ax"], r.t, atol=1e-12)
    # the folder itself is no recording: detection and an explicit format both say why
    with pytest.raises(ReaderError, match=r"a folder of 3 recordings \(drive_a, drive_b, drive_c"):
        io.detect_format(root)
    with pytest.raises(ReaderError, match=r"a folder of 3 phyphox exports .*vibrospeed batch"):
        io.read(root, "phyphox")


def test_export_unpacked_into_a_folder_of_its_own_is_one(tmp_path):
    wrap = tmp_path / "upload"
    ay = _phyphox(wrap / "Acceleration 2024-05-01", 250, gyro=0.25)
    (wrap / "empty").mkdir()  # a subfolder without an export does not count
    assert is_phyphox(wrap) and io.detect_format(wrap) == "phyphox"
    assert batch.expand_inputs([wrap]) == [(str(wrap), None)]
    r = io.read(wrap)
    np.testing.assert_array_equal(r["ay"], ay)
    np.testing.assert_array_equal(r["gx"], np.full(250, 0.25))


def test_other_files_come_from_the_accelerometer_folder(tmp_path):
    # "a" (sorted first) holds a gyroscope only: not an export, and its file is not borrowed
    wrap = tmp_path / "w"
    (wrap / "a").mkdir(parents=True)
    (wrap / "a" / "Gyroscope.csv").write_text(_GYR_H + "0,9,9,9\n0.01,9,9,9\n")
    _phyphox(wrap / "b", 200, gyro=0.5)
    r = io.read(wrap, "phyphox")
    np.testing.assert_array_equal(r["gx"], np.full(200, 0.5))
    assert all("/a/" not in n for n in r.notes)


def test_zip_of_several_exports_is_refused_and_one_export_reads_whole(tmp_path):
    for name, gyro in (("one", 0.5), ("two", 0.75)):
        _phyphox(tmp_path / name, 120, gyro=gyro)
    several = tmp_path / "both.zip"
    with zipfile.ZipFile(several, "w") as zf:
        for name in ("one", "two"):
            for f in sorted((tmp_path / name).iterdir()):
                zf.write(f, f"{name}/{f.name}")
    with pytest.raises(ReaderError, match=r"a zip of 2 phyphox exports \(one, two\)"):
        io.read(several)
    single = tmp_path / "single.zip"  # an export, and a stray gyroscope in another zip folder
    with zipfile.ZipFile(single, "w") as zf:
        zf.write(tmp_path / "one" / "Gyroscope.csv", "aaa/Gyroscope.csv")
        for f in sorted((tmp_path / "two").iterdir()):
            zf.write(f, f"two/{f.name}")
    r = io.read(single)
    assert len(r) == 120
    np.testing.assert_array_equal(r["gx"], np.full(120, 0.75))


def test_folder_of_sensorlogger_exports(tmp_path):
    root = tmp_path / "logs"
    for name, n in (("2024-01-01_10-00-00", 200), ("2024-01-02_10-00-00", 300)):
        _sensorlogger(root / name, n)
    assert not is_sensorlogger(root)
    found = batch.expand_inputs([root])
    assert [Path(p).name for p, _ in found] == ["2024-01-01_10-00-00", "2024-01-02_10-00-00"]
    assert [len(io.read(p)) for p, _ in found] == [200, 300]
    with pytest.raises(ReaderError, match=r"a folder of 2 Sensor Logger exports"):
        io.read(root, "sensorlogger")
    with pytest.raises(ReaderError, match=r"a folder of 2 recordings"):
        io.detect_format(root)
    one = tmp_path / "one"  # unpacked into a folder of its own: one recording
    _sensorlogger(one / "2024-01-03_10-00-00", 150)
    assert is_sensorlogger(one) and len(io.read(one)) == 150
    both = tmp_path / "both.zip"  # a zip of the two drives: refused, not the first one read
    with zipfile.ZipFile(both, "w") as zf:
        for sub in sorted(root.iterdir()):
            zf.write(sub / "TotalAcceleration.csv", f"{sub.name}/TotalAcceleration.csv")
    with pytest.raises(ReaderError, match=r"a zip of 2 Sensor Logger exports \(2024-01-01"):
        io.read(both)
    single = tmp_path / "single.zip"
    with zipfile.ZipFile(single, "w") as zf:
        zf.write(root / "2024-01-02_10-00-00" / "TotalAcceleration.csv",
                 "2024-01-02_10-00-00/TotalAcceleration.csv")
    assert len(io.read(single)) == 300


def test_cli_batch_folder_of_phyphox_exports(tmp_path):
    """The fleets page's command, on a folder of three small phyphox exports."""
    root = tmp_path / "phone_logs"
    for k, name in enumerate(("d1", "d2", "d3")):
        _phyphox(root / name, 800, seed=k)
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["batch", str(root), "--format", "phyphox", "--axis", "y",
                                   "--wheel-radius", "0.31", "-o", str(out), "--report"])
    assert res.exit_code == 0, res.output
    assert "3 recordings (3 ok, 0 skipped, 0 error)" in res.stderr
    summary = pd.read_csv(out / "summary.csv")
    assert [Path(f).name for f in summary["file"]] == ["d1", "d2", "d3"]
    assert list(summary["format"]) == ["phyphox"] * 3
    np.testing.assert_allclose(summary["duration_s"], 7.99)
    for name in ("d1", "d2", "d3"):
        assert (out / f"{name}_grid.html").is_file()
        side = json.loads((out / f"{name}_grid.csv.json").read_text())
        assert side["meta"]["recording"]["format"] == "phyphox"


@pytest.mark.skipif(not HUNGARY.is_dir(), reason="../shared/datasets not present")
def test_hungary_folder_is_seven_drives(tmp_path):
    drives = sorted(q.name for q in HUNGARY.iterdir() if (q / "Accelerometer.csv").is_file())
    assert len(drives) == 7
    found = batch.expand_inputs([HUNGARY])
    assert [Path(p).name for p, _ in found] == drives
    opts = batch.EstimateOptions(method="shs", fmt="phyphox", axis="y", wheel_radius=0.31)
    df = batch.run([HUNGARY], tmp_path / "out", options=opts, jobs=1)
    assert list(df["status"]) == ["ok"] * 7, df
    # each row is its own drive: its duration is that export's accelerometer span
    for (_, row), name in zip(df.iterrows(), drives, strict=True):
        t = pd.read_csv(HUNGARY / name / "Accelerometer.csv", usecols=[0]).iloc[:, 0].to_numpy()
        assert row["duration_s"] == pytest.approx(t[-1] - t[0], abs=0.02)


def test_one_unpacked_export_beside_other_drives_is_not_the_whole_folder(tmp_path):
    """A folder holding one unpacked export and, beside it, another drive (its export as a
    zip, a canonical CSV) is a folder of recordings: every drive is an input (before, the folder
    was read as the one unpacked export and the others were silently left out). Notes and
    images beside an unpacked export still leave it one recording."""
    root = tmp_path / "phone_logs"
    ay_folder = _phyphox(root / "drive_a", 300, seed=0)
    zipped = tmp_path / "drive_b"
    ay_zip = _phyphox(zipped, 450, seed=1)
    with zipfile.ZipFile(root / "drive_b.zip", "w") as zf:
        for f in sorted(zipped.iterdir()):
            zf.write(f, f"drive_b/{f.name}")
    io.write(sim.simulate("cart", seed=2, duration=3), root / "drive_c.csv")
    assert not is_phyphox(root)
    found = batch.expand_inputs([root])
    assert [(Path(p).name, err) for p, err in found] == [
        ("drive_a", None), ("drive_b.zip", None), ("drive_c.csv", None)]
    np.testing.assert_array_equal(io.read(found[0][0])["ay"], ay_folder)
    np.testing.assert_array_equal(io.read(found[1][0])["ay"], ay_zip)
    assert len(io.read(found[2][0])) == 300
    with pytest.raises(ReaderError, match=r"a folder holding the recording drive_a, not one "
                                          r"itself: give drive_a, or `vibrospeed batch`"):
        io.detect_format(root)
    for name in ("notes.md", "map.png", "drive_a.csv.json",  # never recordings
                 "Acceleration 2024-05-01.zip"):  # the zip it was unpacked from
        wrap = tmp_path / f"wrap_{name}"
        _phyphox(wrap / "Acceleration 2024-05-01", 120)
        (wrap / name).write_text("x\n")
        assert is_phyphox(wrap) and batch.expand_inputs([wrap]) == [(str(wrap), None)]
    sl = tmp_path / "sl"  # Sensor Logger: the same rule
    _sensorlogger(sl / "2024-01-03_10-00-00", 150)
    assert is_sensorlogger(sl)
    (sl / "2024-01-04.zip").write_bytes(b"PK\x05\x06" + b"\0" * 18)  # another drive's zip
    assert not is_sensorlogger(sl)
