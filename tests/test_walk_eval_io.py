"""``evaluate`` on a lateral velocity, batch names of gzip CSVs and their sidecars, a folder of
CSV files as an input (found walking through ``evaluate`` / ``info`` on the real recordings)."""

from __future__ import annotations

import gzip
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from cli_runner import one_line_error, run
from vibrospeed import batch, io
from vibrospeed.batch.single import EstimateOptions, read_with
from vibrospeed.errors import InputError, ReaderError
from vibrospeed.eval.metrics import evaluate
from vibrospeed.types import Recording, Track

KART = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets" / "gopro_kart"


def _lateral_pair(tmp_path: Path):
    """A truth with speed_true and vy_true (standing for 1 s at the start) and an estimate of
    speeds only (m/s, no radius, as algebraic's Vx) with a lateral velocity ``vy`` that is
    biased, noisy and missing in places; both written as files for the CLI."""
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 10.0, 0.01)
    v = np.where(t < 1.0, 0.0, 12.0 + 0.3 * t)
    vy = 0.4 * np.sin(1.3 * t) * (t >= 1.0)
    truth = Recording(t, {"speed_true": v, "vy_true": vy}, source="truth")
    vy_est = vy + 0.05 + 0.03 * rng.standard_normal(t.size)
    vy_est[500:520] = np.nan
    track = Track.from_speed(t, v + 0.1 * rng.standard_normal(t.size), np.full(t.size, 0.1),
                             extras={"vy": vy_est})
    io.write(truth, tmp_path / "truth.csv")
    io.write_track(track, tmp_path / "est.csv")
    return truth, track


def test_evaluate_scores_vy_against_vy_true(tmp_path):
    truth, track = _lateral_pair(tmp_path)
    # independent reference: same time line, moving = truth speed above 0.3 m/s, both finite
    ref = truth.channel("vy_true")
    est = track.extras["vy"]
    keep = (truth.channel("speed_true") > 0.3) & np.isfinite(est)
    e = est[keep] - ref[keep]
    m = evaluate(track, truth)
    assert m.unit == "m/s" and m.vy_n == int(keep.sum()) == 880
    np.testing.assert_allclose([m.vy_rmse, m.vy_mae, m.vy_bias, m.vy_corr],
                               [np.sqrt(np.mean(e**2)), np.mean(np.abs(e)), np.mean(e),
                                np.corrcoef(est[keep], ref[keep])[0, 1]], rtol=1e-12)
    assert 0.04 < m.vy_bias < 0.06 and m.vy_corr > 0.95
    # the same figures in the table and the JSON of `vibrospeed evaluate`
    res = run("evaluate", tmp_path / "est.csv", "--truth", tmp_path / "truth.csv", "--json",
              tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    assert "Vy RMSE" in res.stdout and f"{m.vy_rmse:.3f}" in res.stdout
    got = json.loads((tmp_path / "m.json").read_text())
    assert got["vy_n"] == 880 and got["vy_rmse"] == pytest.approx(m.vy_rmse, rel=1e-12)
    # no vy_true in the truth: no Vy figures, no row
    no_vy = Recording(truth.t, {"speed_true": truth.channel("speed_true")})
    assert evaluate(track, no_vy).vy_n == 0


def test_evaluate_against_a_mapped_gps_csv_and_an_omega_only_estimate(tmp_path):
    t = np.arange(0.0, 20.0, 0.05)
    (tmp_path / "gps.csv").write_text("t_video_s,gps_speed2d_mps\n" + "".join(
        f"{x:.2f},{10 + 0.1 * x:.4f}\n" for x in t[::4]))  # 5 Hz fixes
    omega = (10 + 0.1 * t) / 0.25
    io.write_track(Track.from_omega(t, omega, np.full(t.size, 0.5)), tmp_path / "w.csv")
    io.write_track(Track.from_omega(t, omega + 4.0, np.full(t.size, 0.5), wheel_radius=0.25),
                   tmp_path / "v.csv")
    args = ("--truth", tmp_path / "gps.csv", "--truth-columns",
            "t=t_video_s,gps_speed=gps_speed2d_mps", "--truth-channel", "gps_speed")
    line = one_line_error(run("evaluate", tmp_path / "w.csv", *args))
    assert "is a speed (m/s) and the estimate has omega only" in line and "--wheel-radius" in line
    res = run("evaluate", tmp_path / "v.csv", "--json", tmp_path / "m.json", *args)
    assert res.exit_code == 0, res.output
    m = json.loads((tmp_path / "m.json").read_text())
    assert m["unit"] == "m/s" and m["bias"] == pytest.approx(4.0 * 0.25, rel=1e-9)


def _gz_drive(folder: Path, radius: float = 0.08) -> Path:
    """``gzip drive.csv`` of a canonical recording with a .json sidecar and wheel ticks."""
    folder.mkdir(parents=True, exist_ok=True)
    t = np.arange(0.0, 3.0, 0.01)
    rec = Recording(t, {"ay": np.sin(2 * np.pi * 3.0 * t), "az": 9.81 + 0 * t},
                    events={"wss_ticks": np.arange(0.05, 3.0, 0.1)}, wheel_radius=radius)
    io.write(rec, folder / "a.csv")
    with open(folder / "a.csv", "rb") as src, gzip.open(folder / "a.csv.gz", "wb") as dst:
        shutil.copyfileobj(src, dst)
    (folder / "a.csv").unlink()
    return folder / "a.csv.gz"


def test_gzip_csv_keeps_its_sidecars_and_its_batch_name(tmp_path):
    gz = _gz_drive(tmp_path / "in")
    rec = io.read(gz)
    assert rec.wheel_radius == 0.08 and rec.events["wss_ticks"].size == 30
    # the ticks are a part of a.csv.gz, not a recording of a batch; the output is a_<method>
    assert batch.expand_inputs([tmp_path / "in"]) == [(str(gz), None)]
    assert batch.output_names([gz]) == ["a"]
    names = batch.output_names([tmp_path / "x" / "a.csv", gz])  # same name: made unique
    assert names[0] != names[1] and all(n.startswith("a-") for n in names)
    assert [q.name for q in read_with(gz, EstimateOptions())] == ["a.csv.json",
                                                                 "a.wss_ticks.csv"]
    params = {"omega_min": 5, "omega_max": 40}

    def run_batch():
        return batch.run([tmp_path / "in"], tmp_path / "out", method="ekf", params=params,
                         jobs=1)

    df = run_batch()
    assert list(df.status) == ["ok"] and list(df.output) == ["a_ekf.csv"]
    assert (tmp_path / "out" / "a_ekf.csv").is_file()
    assert list(run_batch().status) == ["skipped"]
    side = json.loads((tmp_path / "in" / "a.csv.json").read_text())
    side["wheel_radius"] = 0.3  # a corrected radius in the sidecar: estimated again
    (tmp_path / "in" / "a.csv.json").write_text(json.dumps(side))
    again = run_batch()
    assert list(again.status) == ["ok"] and list(again.output) == ["a_ekf.csv"]


def test_folder_of_csv_files_names_the_file_and_the_mapping(tmp_path):
    d = tmp_path / "kart"
    d.mkdir()
    (d / "clip_accl_raw.csv").write_text("c1,c2,c3\n10698,-615,1545\n10358,-73,223\n")
    (d / "clip_gps_speed.csv").write_text("t_video_s,gps_speed2d_mps\n0.0,15.3\n0.05,15.4\n")
    (d / "notes.txt").write_text("telemetry dump\n")
    want = f"{d / 'clip_accl_raw.csv'} --columns ax=c1,ay=c2,az=c3 --rate HZ"
    for kw in ({}, {"columns": "ax=c1", "rate": 200.0}):  # with a mapping: the same line
        with pytest.raises(ReaderError) as exc:
            io.read(d, **kw)
        msg = str(exc.value)
        assert want in msg and "clip_gps_speed.csv (t_video_s,gps_speed2d_mps)" in msg
        assert "\n" not in msg
    # the GPS file alone: its mapping names the speed
    with pytest.raises(ReaderError, match="t=t_video_s,gps_speed=gps_speed2d_mps"):
        io.read(d / "clip_gps_speed.csv")
    # a folder of recordings that are files (canonical CSVs): give one, or batch
    f = tmp_path / "drives"
    f.mkdir()
    for name in ("b.csv", "c.csv"):
        (f / name).write_text("t,ay\n0,1\n0.01,2\n")
    with pytest.raises(ReaderError, match=r"a folder of 2 recording\(s\) \(b\.csv, c\.csv\)"):
        io.read(f)
    (tmp_path / "empty").mkdir()  # nothing in it: the message as before
    with pytest.raises(ReaderError, match="not a phyphox export"):
        io.read(tmp_path / "empty")


@pytest.mark.skipif(not KART.is_dir(), reason="shared kart recording not present")
def test_real_kart_folder_is_one_line_naming_the_accelerometer_file():
    line = one_line_error(run("info", KART))
    assert "GX030410_accl_raw.csv --columns ax=c1,ay=c2,az=c3 --rate HZ" in line


def test_vy_metrics_refuse_nothing_and_keep_nan_where_flat():
    t = np.arange(0.0, 5.0, 0.1)
    truth = Recording(t, {"speed_true": np.full(t.size, 5.0), "vy_true": np.zeros(t.size)})
    tr = Track.from_speed(t, np.full(t.size, 5.0), np.full(t.size, 0.1),
                          extras={"vy": np.full(t.size, 0.2)})
    m = evaluate(tr, truth)
    assert m.vy_n == t.size and m.vy_bias == pytest.approx(0.2) and np.isnan(m.vy_corr)
    with pytest.raises(InputError, match="omega only"):
        evaluate(Track.from_omega(t, np.full(t.size, 20.0)),
                 Recording(t, {"gps_speed": np.full(t.size, 5.0)}), truth_channel="gps_speed")
