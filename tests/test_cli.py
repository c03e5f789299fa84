"""The ``vibrospeed`` command end to end, and its one-line errors (exit status 2)."""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cli_runner import one_line_error as _err
from cli_runner import run as _run
from vibrospeed import io


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    path = d / "cart.csv"
    res = _run("simulate", "--scenario", "cart", "--seed", 2, "--duration", 30, "-o", path)
    assert res.exit_code == 0, res.output
    return path


def test_simulate_estimate_evaluate_plot(drive, tmp_path):
    est = tmp_path / "est.csv"
    png = tmp_path / "est.png"
    res = _run("estimate", drive, "--method", "ekf", "--init-omega", 10, "-o", est,
               "--plot", png)
    assert res.exit_code == 0, res.output
    header = est.read_text().splitlines()[0].split(",")
    assert header[:5] == ["t", "omega", "omega_lo", "omega_hi", "speed"]
    side = json.loads(est.with_name(est.name + ".json").read_text())
    assert side["method"] == "ekf" and len(side["input_sha256"]) == 64
    assert png.stat().st_size > 10_000
    track = io.read_track(est)
    rec = io.read(drive)
    np.testing.assert_allclose(track.speed, 0.08 * track.omega)  # cart radius carried over
    assert np.array_equal(track.t, rec.t)
    res = _run("evaluate", est, "--truth", drive, "--json", tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    assert "RMSE" in res.output
    m = json.loads((tmp_path / "m.json").read_text())
    assert m["n"] > 0 and np.isfinite(m["rmse"])
    res = _run("plot", drive, "--estimate", est, "-o", tmp_path / "p.png")
    assert res.exit_code == 0, res.output


def test_params_reach_the_estimator(drive, tmp_path):
    est = tmp_path / "e.csv"
    # M = 3 up to 120 rad/s needs fs > 115 Hz: refused at 100 Hz, fine with a lower range
    assert "too low" in _err(_run("estimate", drive, "-m", "ekf", "-o", est, "-p", "M=3"))
    res = _run("estimate", drive, "-m", "ekf", "-o", est, "-p", "M=3", "-p",
               "q_omega=2,omega_max=100")
    assert res.exit_code == 0, res.output
    side = json.loads(est.with_name("e.csv.json").read_text())
    assert side["params"]["M"] == 3 and side["params"]["q_omega"] == 2.0




def test_errors_are_one_line(tmp_path, drive):
    out = tmp_path / "o.csv"
    assert "nope.csv" in _err(_run("estimate", tmp_path / "nope.csv", "-o", out))
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    assert "empty.csv" in _err(_run("estimate", empty, "-o", out))
    bad = tmp_path / "bad.csv"
    bad.write_text("t,ay\n0,1\n0.01,abc\n0.02,3\n")
    msg = _err(_run("estimate", bad, "-o", out))
    assert "bad.csv" in msg and "3" in msg
    back = tmp_path / "back.csv"
    back.write_text("t,ay\n0,1\n0.02,2\n0.01,3\n")
    assert "back.csv" in _err(_run("estimate", back, "-o", out))
    slow = tmp_path / "slow.csv"
    slow.write_text("t,ay\n" + "".join(f"{k / 10},{np.sin(k)}\n" for k in range(300)))
    nanc = tmp_path / "nan.csv"
    nanc.write_text("t,ay\n" + "".join(f"{k / 100},\n" for k in range(50)))
    assert "ay" in _err(_run("estimate", nanc, "-o", out))
    assert "'az'" in _err(_run("estimate", bad.with_name("slow.csv"), "--axis", "z", "-o", out))
    assert "too low" in _err(_run("estimate", slow, "-o", out))
    assert "unknown format" in _err(_run("estimate", drive, "--format", "xyz", "-o", out))
    assert "unknown method" in _err(_run("estimate", drive, "--method", "xyz", "-o", out))
    assert not out.exists()  # nothing half-written


def test_module_entry_point_and_help():
    res = subprocess.run([sys.executable, "-m", "vibrospeed", "--help"], capture_output=True,
                         text=True, check=True)
    assert "simulate" in res.stdout and "estimate" in res.stdout
    res = _run("estimate", "--help")
    assert "Examples" in res.output
    from vibrospeed import __version__

    res = _run("--version")
    assert res.exit_code == 0 and res.output.strip() == f"vibrospeed {__version__}"


def test_truth_from_ticks_and_scenario_list(tmp_path):
    rec_path = tmp_path / "cart.csv"
    res = _run("simulate", "--scenario", "cart", "--duration", 20, "--set", "ticks=on",
               "-o", rec_path)
    assert res.exit_code == 0, res.output
    ticks = io.read(rec_path).events["wss_ticks"]
    tick_csv = tmp_path / "ticks.csv"
    tick_csv.write_text("t\n" + "".join(f"{float(v)!r}\n" for v in ticks))
    for args in ([rec_path, "--from-recording"], [tick_csv]):
        truth = tmp_path / "truth.csv"
        res = _run("truth", *args, "-o", truth)
        assert res.exit_code == 0, res.output
        tr = io.read(truth)
        rec = io.read(rec_path)
        w = np.interp(tr.t, rec.t, rec["omega_true"])
        moving = tr["omega_true"] > 1
        # the simulator's cog wheel has the thesis' 0.0625 m radius, as the CLI default
        assert np.median(np.abs(tr["omega_true"][moving] - w[moving])) < 0.05
    res = _run("simulate", "--list", "-o", tmp_path / "x.csv")
    assert res.exit_code == 0 and "stop_and_go" in res.output and "gps_tunnel" in res.output


def test_gps_riss_speed_only_evaluation(tmp_path):
    rec_path = tmp_path / "tunnel.csv"
    assert "bogus" in _err(_run("simulate", "--scenario", "gps_tunnel", "--set", "bogus=1",
                                "-o", rec_path))
    assert _run("simulate", "--scenario", "gps_tunnel", "--duration", 30, "-o",
                rec_path).exit_code == 0
    est = tmp_path / "gps.csv"
    res = _run("estimate", rec_path, "--method", "gps-riss", "--axis", "x", "-o", est,
               "--plot", tmp_path / "gps.png")
    assert res.exit_code == 0, res.output
    assert (tmp_path / "gps.png").stat().st_size > 10_000  # speed panel (no wheel radius)
    res = _run("evaluate", est, "--truth", rec_path, "--json", tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    m = json.loads((tmp_path / "m.json").read_text())
    assert m["unit"] == "m/s" and m["rmse"] < 0.3


def test_info_describes_channels(drive):
    res = _run("info", drive)
    assert res.exit_code == 0, res.output
    assert "omega_true" in res.output and "rad/s" in res.output and "can feed" in res.output
    assert "comb_axes=all reads ax, ay, az together" in " ".join(res.output.split())


def test_gps_riss_paper_preset(tmp_path):
    rec_path = tmp_path / "jump.csv"
    assert _run("simulate", "--scenario", "gps_jump", "--duration", 20, "-o",
                rec_path).exit_code == 0
    est = tmp_path / "p.csv"
    res = _run("estimate", rec_path, "-m", "gps-riss", "-p", "preset=paper", "-o", est)
    assert res.exit_code == 0, res.output
    side = json.loads(est.with_name("p.csv.json").read_text())
    assert side["params"]["r_gps_slope"] == 72.0 and side["params"]["error_mode"] == "kf2"
    assert "preset" in _err(_run("estimate", rec_path, "-m", "gps-riss", "-p", "preset=x",
                                 "-o", est))


def test_a_log_with_one_accelerometer_axis_uses_it(tmp_path):
    """Without --axis the vibration axis is y; a log that has only az uses az (and says so);
    two axes without y still need --axis."""
    t = np.arange(0, 20, 0.01)
    rng = np.random.default_rng(0)
    az = np.sin(50 * t) + 0.5 * np.sin(100 * t) + 0.3 * np.sin(150 * t) + 0.3 * rng.normal(
        size=t.size)
    path = tmp_path / "onlyz.csv"
    np.savetxt(path, np.c_[t, az], delimiter=",", header="t,az", comments="")
    est = tmp_path / "est.csv"
    res = _run("estimate", path, "-o", est)
    assert res.exit_code == 0, res.output
    assert "only accelerometer axis 'az'" in res.output
    side = json.loads(est.with_name(est.name + ".json").read_text())
    assert side["meta"]["axis"] == "z" and side["notes"][0].startswith("no 'ay'")
    omega = np.loadtxt(est, delimiter=",", skiprows=1, usecols=1)
    assert abs(np.median(omega[500:]) - 50.0) < 1.0
    two = tmp_path / "xz.csv"
    np.savetxt(two, np.c_[t, az, az], delimiter=",", header="t,ax,az", comments="")
    res = _run("estimate", two, "-o", tmp_path / "e2.csv")
    assert res.exit_code == 2 and "'ay' is missing" in res.output


def test_simulate_list_needs_no_output_and_a_missing_output_is_a_clear_error():

    from vibrospeed.cli.app import app

    r = CliRunner().invoke(app, ["simulate", "--list"])
    assert r.exit_code == 0 and "random" in r.output
    r = CliRunner().invoke(app, ["simulate", "--scenario", "cart"])
    assert r.exit_code == 2


def test_a_reader_that_goes_away_ends_the_output_quietly():
    """``vibrospeed methods | head -1``: the pipe closes before the output is written; the CLI
    stops with status 0 and no 'internal error' (BrokenPipeError) on stderr."""
    proc = subprocess.Popen([sys.executable, "-m", "vibrospeed", "methods"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()  # before the child has imported anything, let alone printed
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=120) == 0, err
    assert "internal error" not in err and "Traceback" not in err, err


def test_batch_counts_the_drives_without_a_measurement(tmp_path):
    """``vibrospeed batch`` says after its status counts how many rows have a note (speed
    numbers left empty); with none it says nothing of the kind."""
    from vibrospeed import sim
    from vibrospeed.types import Recording

    src = tmp_path / "in"
    src.mkdir()
    rng = np.random.default_rng(1)
    n = 8 * 400
    for name in ("n1.csv", "n2.csv"):  # white noise: no wheel line, standstill or GPS
        io.write(Recording(t=np.arange(n) / 400.0, channels={
            "ax": rng.normal(0.0, 1.0, n), "ay": rng.normal(0.0, 1.0, n),
            "az": 9.81 + rng.normal(0.0, 1.0, n)}), src / name)
    io.write(sim.simulate("cart", seed=0, duration=8), src / "cart.csv")
    grid = ["-m", "grid", "-p", "omega_min=2", "-p", "omega_max=30", "-j", 1]
    res = _run("batch", src, "-o", tmp_path / "out", *grid)
    assert res.exit_code == 0, res.output
    lines = res.stderr.splitlines()
    said = next(k for k, ln in enumerate(lines) if "3 recordings (3 ok, 0 skipped, 0 error)" in ln)
    assert lines[said + 1] == ("2 drives without a wheel line or GPS while moving: speed "
                               "numbers left empty (see the note column)")
    res = _run("batch", src / "cart.csv", "-o", tmp_path / "cart_out", *grid)
    assert res.exit_code == 0, res.output
    assert "1 ok, 0 skipped, 0 error" in res.stderr and "note column" not in res.stderr


def _shell_lines(text: str) -> list[str]:
    """The commands of a page's ```sh blocks, continuation lines (``\\``) joined, comments
    dropped."""
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", text, flags=re.S):
        for cmd in block.replace("\\\n", " ").splitlines():
            cmd = cmd.split("#", 1)[0].strip()
            if cmd:
                lines.append(" ".join(cmd.split()))
    return lines


def test_the_docs_cart_examples_give_a_grid_tracker_the_carts_range():
    # the grid trackers search 10-120 rad/s (a car's wheels) unless told: a cart (r 0.08 m,
    # about 10 rad/s) run without its range sits at the bottom edge (the simulated cart:
    # RMSE 9.7 rad/s against 1.3 with -p omega_min=2 -p omega_max=30), so a page's example on
    # cart.csv that runs one gives the range; the EKF (clip 2-120 rad/s) and the aided EKF
    # (--preset paper, -p tracker=ekf) need none
    from pathlib import Path

    docs = Path(__file__).resolve().parents[1] / "docs"
    grid_trackers = {"grid", "rbpmf", "rbpf", "shs", "aided"}
    seen = 0
    for page in sorted(docs.glob("*.md")):
        for cmd in _shell_lines(page.read_text()):
            words = cmd.split()
            if words[:2] != ["vibrospeed", "estimate"] or not words[2].endswith("cart.csv"):
                continue
            method = next((words[i + 1] for i, w in enumerate(words[:-1])
                           if w in ("-m", "--method")), "grid")
            if method not in grid_trackers or "--preset paper" in cmd \
                    or "tracker=ekf" in cmd:
                continue
            seen += 1
            assert "omega_min=" in cmd and "omega_max=" in cmd, (page.name, cmd)
    assert seen >= 3


def test_a_negative_band_edge_distance_reads_as_a_range():
    # algebraic's Vx is signed: a drifting lower edge integrates to a negative distance, and
    # "(-185-380 m ...)" read as a subtraction; the distances are the trapezoids of the columns
    from vibrospeed.cli.estimate import summary_line
    from vibrospeed.eval.metrics import track_summary
    from vibrospeed.types import Track

    t = np.arange(101) * 0.1  # 10 s
    speed = np.full(t.size, 2.0)
    track = Track.from_speed(t, speed, np.full(t.size, 1.0), lo=speed - 30.0, hi=speed + 3.0)
    s = track_summary(track)
    assert s["distance_lo_m"] == pytest.approx(np.trapezoid(speed - 30.0, t))  # -280 m
    line = summary_line(s)
    assert line.endswith("distance 20 m (-280 to 50 m at the edges of the speed band)"), line
    s_pos = track_summary(Track.from_speed(t, speed, np.full(t.size, 1.0), lo=speed - 1.0,
                                           hi=speed + 3.0))
    assert summary_line(s_pos).endswith("distance 20 m (10-50 m at the edges of the speed band)")


def _notes(res) -> str:
    """The note lines of a command's stderr, each joined back into one line."""
    return " ".join(res.stderr.split())


def test_a_default_search_range_is_named_with_the_speeds_it_covers(drive, tmp_path,
                                                                    monkeypatch):
    # the cart (r = 0.08 m) run with the grid's default range: the note names the range and,
    # with the radius, v = r omega at its ends (0.8 and 9.6 m/s), and how to give another
    est = tmp_path / "est.csv"
    for args in ([], ["-m", "shs"], ["-m", "aided"]):
        res = _run("estimate", drive, *args, "-o", est)
        assert res.exit_code == 0, res.output
        assert ("note: searched wheel speeds 10-120 rad/s (0.8-9.6 m/s at wheel radius 0.08 "
                "m), the default: for another vehicle give its range, v / r (a cart or "
                "forklift on r = 0.08 m: -p omega_min=2 -p omega_max=30)") in _notes(res), args
    # a range given (either end, or by a preset) or none searched (the EKF): no note
    for args in (["-p", "omega_min=2"], ["-p", "omega_max=30"], ["-m", "rbpmf", "--preset",
                 "paper"], ["-m", "ekf"], ["-m", "aided", "--preset", "paper"],
                 ["-m", "aided", "-p", "tracker=rbpmf"]):
        res = _run("estimate", drive, *args, "-o", est)
        assert res.exit_code == 0, res.output
        assert "searched wheel speeds" not in res.stderr, args
    # the streamed path (a long log in blocks) says it too, from the sidecar it wrote
    from vibrospeed.estimators.grid import stream

    monkeypatch.setattr(stream, "STREAM_ROWS", 1000)
    res = _run("estimate", drive, "-o", est)
    assert res.exit_code == 0, res.output
    assert "in blocks" in res.stderr
    assert "searched wheel speeds 10-120 rad/s (0.8-9.6 m/s at wheel radius 0.08 m)" \
        in _notes(res)
    # without a radius the range in rad/s alone
    bare = tmp_path / "bare.csv"
    rec = io.read(drive)
    rows = zip(rec.t, rec["ay"], strict=True)
    bare.write_text("t,ay\n" + "".join(f"{t:.17g},{a:.17g}\n" for t, a in rows))
    monkeypatch.setattr(stream, "STREAM_ROWS", 500_000)
    res = _run("estimate", bare, "-o", est)
    assert res.exit_code == 0, res.output
    assert "note: searched wheel speeds 10-120 rad/s, the default:" in _notes(res)


def test_evaluate_json_is_strict_json_with_null_for_a_metric_that_does_not_apply(drive,
                                                                                  tmp_path):
    # SHS has no band and no has_signal: coverage and the claimed metrics are NaN, written as
    # null (a bare NaN is not JSON: JavaScript's JSON.parse, jq and strict readers refuse it)
    est, out = tmp_path / "shs.csv", tmp_path / "m.json"
    res = _run("estimate", drive, "-m", "shs", "-p", "omega_min=4", "-p", "omega_max=30",
               "-o", est)
    assert res.exit_code == 0, res.output
    res = _run("evaluate", est, "--truth", drive, "--json", out)
    assert res.exit_code == 0, res.output

    def refuse(name):
        raise AssertionError(f"{name} in {out.read_text()}")

    m = json.loads(out.read_text(), parse_constant=refuse)
    assert m["coverage"] is None and m["claimed_share"] is None and m["n"] > 0
    # the finite ones as computed from the two files
    track, rec = io.read_track(est), io.read(drive)
    w = np.interp(track.t, rec.t, rec["omega_true"])
    moving = (w > 1.0) & np.isfinite(track.omega)
    assert m["n"] == int(moving.sum())
    e = track.omega[moving] - w[moving]
    assert m["rmse"] == pytest.approx(np.sqrt(np.mean(e**2)), rel=1e-12)
    assert m["bias"] == pytest.approx(np.mean(e), rel=1e-12)


def test_evaluate_with_nothing_to_compare_is_a_one_line_error(drive, tmp_path):
    # a warm-up past the end, a --min-omega above every truth sample, a truth from another
    # time: no moving sample to score, which was a table of NaN with exit status 0
    est = tmp_path / "est.csv"
    res = _run("estimate", drive, "-m", "ekf", "-o", est)
    assert res.exit_code == 0, res.output
    rec = io.read(drive)
    span = f"({rec.t[0]:g}-{rec.t[-1]:g} s)"
    line = _err(_run("evaluate", est, "--truth", drive, "--warmup", 1000))
    assert line == (f"vibrospeed: error: {est}: nothing to compare: no sample of the estimate "
                    f"{span} 1000 s after its start (--warmup) has a finite value where the "
                    f"truth {drive} {span} moves faster than --min-omega 1 rad/s")
    line = _err(_run("evaluate", est, "--truth", drive, "--min-omega",
                     float(np.max(rec["omega_true"])) + 1))
    assert "nothing to compare" in line and "--warmup" not in line
    later = tmp_path / "later.csv"
    later.write_text("t,omega_true\n100,5\n101,5\n102,5\n")
    line = _err(_run("evaluate", est, "--truth", later, "--json", tmp_path / "m.json"))
    assert line.endswith(f"the truth {later} (100-102 s) moves faster than --min-omega 1 rad/s")
    assert not (tmp_path / "m.json").exists()
    # one moving sample is enough to score
    res = _run("evaluate", est, "--truth", drive, "--warmup", rec.t[-1] - rec.t[0] - 0.5)
    assert res.exit_code == 0, res.output


def test_evaluate_help_says_what_min_omega_means_for_a_comparison_of_speeds(tmp_path):
    # speeds without a wheel radius are compared in m/s with standstill below 0.3 m/s, and
    # --min-omega (rad/s) does not apply there: the help says so, and it is so
    from vibrospeed.cli.app import app

    res = CliRunner().invoke(app, ["evaluate", "--help"], env={"COLUMNS": "300"})
    assert res.exit_code == 0
    text = " ".join(res.stdout.split())  # the help, its line breaks undone
    assert ("truth below this (rad/s) = standing, excluded (speeds compared in m/s, an "
            "estimate or truth without a wheel radius: below 0.3 m/s)") in text
    rec_path, est = tmp_path / "braking.csv", tmp_path / "gps.csv"
    assert _run("simulate", "--scenario", "gps_braking", "--duration", 20, "-o",
                rec_path).exit_code == 0
    assert _run("estimate", rec_path, "-m", "gps-riss", "-o", est).exit_code == 0
    ns = []
    for min_omega in (0, 1, 50):
        res = _run("evaluate", est, "--truth", rec_path, "--min-omega", min_omega, "--json",
                   tmp_path / "m.json")
        assert res.exit_code == 0, res.output
        ns.append(json.loads((tmp_path / "m.json").read_text())["n"])
    track, rec = io.read_track(est), io.read(rec_path)
    v = np.interp(track.t, rec.t, rec["speed_true"])
    assert ns == [int(np.sum((v > 0.3) & np.isfinite(track.speed)))] * 3


def test_a_preset_of_another_method_without_m_names_the_methods_that_have_it(drive):
    # without -m the method is fuse or grid; "paper" is neither's, and the error named grid,
    # a method the user never chose, as if the preset were misspelt
    from vibrospeed import presets

    owners = [m for m in presets.PRESETS if "paper" in presets.presets(m)]
    assert "grid" not in owners and "fuse" not in owners and "rbpmf" in owners
    line = _err(_run("estimate", drive, "--preset", "paper", "-o", "x.csv"))
    assert line == ("vibrospeed: error: --preset paper is not a preset of the method chosen "
                    "without -m (fuse, with GPS speed: default, online, lag; grid: default, "
                    f"online, lag, lock); it is a preset of {', '.join(owners)}: give the method "
                    "with -m")
    # a name no method has: grid's list, as before
    assert "unknown preset 'nope' for method 'grid' (choose from: default, online, lag, lock)" \
        in _err(_run("estimate", drive, "--preset", "nope", "-o", "x.csv"))


def test_evaluate_leaves_out_the_claimed_rows_where_nothing_was_claimed(drive, tmp_path):
    # a grid tracker that claims no line (has_signal 0 throughout): the share row says 0.0 %,
    # and the rows scored "there" are left out (they printed "nan" and "nan%")
    from vibrospeed.types import Track

    rec = io.read(drive)
    truth = rec["omega_true"]
    for claims, name in ((np.zeros(rec.t.size), "none.csv"),
                         ((truth > 5).astype(float), "some.csv")):
        track = Track.from_omega(rec.t, truth + 0.5, np.full(rec.t.size, 0.4),
                                 wheel_radius=0.08, method="grid",
                                 extras={"has_signal": claims})
        io.write_track(track, tmp_path / name)
        res = _run("evaluate", tmp_path / name, "--truth", drive)
        assert res.exit_code == 0, res.output
        assert "nan" not in res.stdout
        has_rows = "RMSE there" in res.stdout and "band coverage there" in res.stdout
        assert has_rows == bool(claims.any()), res.stdout
        share = 100 * np.mean(claims[truth > 1.0])  # of the moving samples
        assert re.search(rf"share where it claims a signal +│ +{share:.1f}%", res.stdout)
        if claims.any():  # the estimate is the truth + 0.5 rad/s everywhere
            assert re.search(r"RMSE there +│ +0\.500 │ rad/s", res.stdout), res.stdout


def test_plot_of_a_recording_with_nothing_labelled_warns_nothing(tmp_path):
    """``plot`` without an estimate, truth or GPS: the spectrogram alone, no empty legend (it
    was matplotlib's "No artists with labels found to put in legend" twice on stderr)."""
    import warnings

    from vibrospeed import sim
    from vibrospeed.types import Recording

    rec = sim.simulate("cart", seed=1, duration=10)
    io.write(Recording(rec.t, {c: rec.channel(c) for c in ("ax", "ay", "az")}),
             tmp_path / "bare.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any warning, as an error, fails the command
        res = _run("plot", tmp_path / "bare.csv", "-o", tmp_path / "p.png")
    assert res.exit_code == 0, res.output
    assert "legend" not in res.output
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_no_line_with_unread_gps_points_to_fuse(tmp_path):
    """``-m grid`` claims no line on a recording with GPS speed: the summary says no line was
    claimed (not "no GPS seen": grid does not read it) and points to ``-m fuse``."""
    from vibrospeed import sim
    from vibrospeed.eval.metrics import NO_EVIDENCE_NOTE
    from vibrospeed.types import Recording

    rec = sim.simulate("car", seed=1, duration=20)
    rng = np.random.default_rng(0)
    n = len(rec.t)  # accelerometer noise, no wheel line; the car's GPS
    io.write(Recording(rec.t, {"ax": rng.normal(0, 1, n), "ay": rng.normal(0, 1, n),
                               "az": 9.81 + rng.normal(0, 1, n),
                               "gps_speed": rec.channel("gps_speed")}), tmp_path / "n.csv")
    res = _run("estimate", tmp_path / "n.csv", "-m", "grid", "--wheel-radius", 0.3, "-o",
               tmp_path / "e.csv")
    assert res.exit_code == 0, res.output
    line = " ".join(res.stderr.split())
    assert line.endswith(f"summary: a wheel line claimed on 0.0 % of the samples; "
                         f"{NO_EVIDENCE_NOTE}; the recording has GPS speed, which this method "
                         "does not read: -m fuse reads it")
    res = _run("estimate", tmp_path / "n.csv", "-m", "fuse", "-o", tmp_path / "f.csv")
    assert res.exit_code == 0 and "-m fuse reads it" not in res.stderr, res.output


def test_every_simulate_help_example_runs(tmp_path, monkeypatch):
    """The example lines of ``simulate --help`` run as written (``--set M=4`` was refused: the
    harmonics are ``vibration.harmonic_amps``), and a CSV output gets its cog ticks beside it
    in ``<name>.wss_ticks.csv``, as the help says."""
    import shlex

    from test_readme import _help_lines
    from vibrospeed.io.canonical import read_events

    lines = [line for page, line in _help_lines() if page == "simulate --help"]
    assert len(lines) >= 5 and any("harmonic_amps" in line for line in lines)
    monkeypatch.chdir(tmp_path)
    for line in lines:
        args = shlex.split(line)[2:]
        res = _run("simulate", *args)
        assert res.exit_code == 0, (line, res.output)
        if "-o" in args and args[args.index("-o") + 1].endswith(".csv"):
            out = Path(args[args.index("-o") + 1])
            scenario = args[args.index("--scenario") + 1] if "--scenario" in args else "cart"
            with_ticks = scenario not in ("random", "validation") \
                and not scenario.startswith("gps_")  # as the help says
            assert out.with_name(out.stem + ".wss_ticks.csv").is_file() == with_ticks, line
    from vibrospeed import sim

    four = sim.simulate("cart", seed=0, **{"vibration.harmonic_amps": (0.25, 0.2, 0.1, 0.05)})
    assert four.channels.keys() == io.read("cart4.csv").channels.keys()
    np.testing.assert_allclose(io.read("cart4.csv")["ay"], four["ay"], rtol=1e-12, atol=1e-12)
    assert not np.allclose(four["ay"], sim.simulate("cart", seed=0)["ay"])  # M = 4, not 3
    np.testing.assert_allclose(read_events(Path("cart.csv"))["wss_ticks"],
                               sim.simulate("cart", seed=0).events["wss_ticks"], rtol=1e-12)
