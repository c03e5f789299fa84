"""Bad input on the ``vibrospeed`` command line: one line on stderr naming what is wrong, exit
status 2, no traceback and nothing written; and what ``info`` and ``--help`` tell the user."""

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cli_runner import one_line_error as _err
from cli_runner import run as _run
from vibrospeed import io
from vibrospeed.estimators import fuse


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A cart log (no GPS) and a car log (gps_speed with fixes, ax, wheel speeds)."""
    d = tmp_path_factory.mktemp("cli_input")
    paths = {}
    for name in ("cart", "car"):
        paths[name] = d / f"{name}.csv"
        res = _run("simulate", "--scenario", name, "--duration", 20, "-o", paths[name])
        assert res.exit_code == 0, res.output
    return paths


def _can_feed(res) -> str:
    assert res.exit_code == 0, res.output
    text = " ".join(res.stdout.split())
    return text[text.index("can feed:"):]


def test_info_lists_fuse_where_fuse_suits_the_log(logs):
    car, cart = io.read(logs["car"]), io.read(logs["cart"])
    assert fuse.suits(car) and not fuse.suits(cart)  # the estimator's own test
    feed = _can_feed(_run("info", logs["car"]))
    assert "fuse (vibration + acceleration + GPS speed" in feed
    for method in ("ekf", "rbpmf", "grid", "rbpf", "shs", "aided", "gps-riss", "algebraic"):
        assert method in feed
    feed = _can_feed(_run("info", logs["cart"]))  # ax but no GPS: fuse only with a radius
    assert "fuse (with --wheel-radius or --radius-from" in feed
    assert "gps-riss" not in feed


@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf", "-inf"])
def test_a_wheel_radius_that_is_not_positive_is_refused_before_any_work(logs, tmp_path, value):
    out = tmp_path / "o.csv"
    line = _err(_run("estimate", logs["cart"], "-m", "ekf", f"--wheel-radius={value}", "-o", out))
    shown = f"{float(value):g}"  # -1, 0, nan, inf, -inf as the user wrote them
    assert line == f"vibrospeed: error: --wheel-radius: wheel radius must be > 0 m, got {shown}"
    assert list(tmp_path.iterdir()) == []  # nothing written, not even a temporary file


@pytest.mark.parametrize(("args", "message"), [
    (["plot", "{cart}", "--window", "0", "-o", "{out}.png"], "--window: window must be > 0 s"),
    (["plot", "{cart}", "--harmonics", "-1", "-o", "{out}.png"],
     "--harmonics: harmonics must be >= 1"),
    (["simulate", "--duration", "0", "-o", "{out}.csv"], "--duration: duration must be > 0 s"),
    (["simulate", "--duration", "-5", "-o", "{out}.csv"], "--duration: duration must be > 0 s"),
    (["simulate", "--fs", "nan", "-o", "{out}.csv"], "--fs: sample rate must be > 0 Hz, got nan"),
    (["simulate", "--seed", "-1", "-o", "{out}.csv"], "--seed: seed must be >= 0, got -1"),
    (["estimate", "{cart}", "--lag", "-1", "-o", "{out}.csv"], "--lag: lag must be > 0 s"),
    (["batch", "{cart}", "--lag", "0", "-o", "{out}"], "--lag: lag must be > 0 s, got 0"),
    (["estimate", "{cart}", "--init-omega", "inf", "-o", "{out}.csv"],
     "--init-omega: initial omega must be >= 0 rad/s, got inf"),
    (["estimate", "{cart}", "--rate", "-3", "-o", "{out}.csv"],
     "--rate: sample rate must be > 0 Hz, got -3"),
    (["batch", "{cart}", "-j", "0", "-o", "{out}"], "--jobs: worker count must be >= 1, got 0"),
    (["batch", "{cart}", "--wheel-radius", "0", "-o", "{out}"], "wheel radius must be > 0 m"),
    (["report", "{cart}", "--wheel-radius", "-0.3", "-o", "{out}.html"],
     "wheel radius must be > 0 m, got -0.3"),
    (["evaluate", "{cart}", "--truth", "{cart}", "--warmup", "-1", "--json", "{out}.json"],
     "--warmup: warm-up must be >= 0 s"),
    (["truth", "{cart}", "--cogs", "0", "-o", "{out}.csv"], "--cogs: cogs must be >= 1, got 0"),
    (["truth", "{cart}", "--r-wheel", "nan", "-o", "{out}.csv"],
     "--r-wheel: wheel radius must be > 0 m, got nan"),
])
def test_out_of_range_numbers_are_refused_while_parsing(logs, tmp_path, args, message):
    out = tmp_path / "o"
    line = _err(_run(*[a.format(cart=logs["cart"], out=out) for a in args]))
    assert line.startswith("vibrospeed: error: ") and message in line
    assert list(tmp_path.iterdir()) == []


def _mapped_csv(path):
    t = np.arange(400) / 100.0
    acc = np.sin(2 * np.pi * 5 * t)
    lines = ["time,acc_y,a:b"] + [f"{a:.6f},{b:.6f},{b:.6f}" for a, b in zip(t, acc, strict=True)]
    path.write_text("\n".join(lines) + "\n")
    return t, acc


def test_an_unknown_unit_in_columns_is_named_with_the_known_units(tmp_path):
    from vibrospeed.io.mapped import UNITS

    m = tmp_path / "m.csv"
    _mapped_csv(m)
    line = _err(_run("estimate", m, "--columns", "t=time:fortnights,ay=acc_y",
                     "-o", tmp_path / "o.csv"))
    assert "unknown unit 'fortnights'" in line and "m.csv" in line and "t=time:fortnights" in line
    assert "not found" not in line
    known = line[line.index("(known: ") + 8:line.index(")", line.index("(known: "))]
    assert known.split(", ") == list(UNITS)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]
    from vibrospeed.errors import ParameterError
    from vibrospeed.io.chunks import ChunkedRecording

    with pytest.raises(ParameterError) as exc:  # the streamed reader says the same
        list(ChunkedRecording(m, columns="t=time:fortnights,ay=acc_y"))
    assert str(exc.value) in line


def test_columns_take_unit_and_scale_in_either_order_and_colons_in_names(tmp_path):
    m = tmp_path / "m.csv"
    t, acc = _mapped_csv(m)
    g = 9.80665
    for spec in ("t=time:ms,ay=acc_y*2:g,az=a:b", "t=time:ms,ay=acc_y:g*2,az=a:b"):
        rec = io.read(m, columns=spec)
        np.testing.assert_allclose(rec.t, np.round(t, 6) * 1e-3)
        np.testing.assert_allclose(rec.channel("ay"), np.round(acc, 6) * 2 * g)
        np.testing.assert_allclose(rec.channel("az"), np.round(acc, 6))  # column 'a:b'


def test_columns_help_shows_the_syntax_and_every_unit():
    from vibrospeed.io.mapped import UNITS

    for command in ("estimate", "info", "batch", "plot", "report"):
        res = _run(command, "--help")
        assert res.exit_code == 0, res.output
        text = " ".join(res.stdout.split())
        assert "NAME=COLUMN[*SCALE][:UNIT]" in text
        assert "'t=time:ms,ay=acc_y:g,gz=yaw*0.01:deg/s'" in text
        assert "Units: " + ", ".join(UNITS) + "." in text


def _no_work(monkeypatch):
    """Make the work itself fail loudly: an output check must refuse before it starts."""
    import vibrospeed.batch as vb
    from vibrospeed import sim

    def work(*args, **kwargs):
        raise AssertionError("the work started")

    for mod, name in ((vb, "estimate_recording"), (vb, "load_recording"), (vb, "run"),
                      (sim, "simulate")):
        monkeypatch.setattr(mod, name, work)


def test_an_output_in_a_missing_folder_is_refused_before_the_work(logs, tmp_path, monkeypatch):
    _no_work(monkeypatch)
    gone = tmp_path / "nonexistent" / "dir"
    out = gone / "o.csv"
    expect = f"vibrospeed: error: -o {out}: folder {gone} does not exist"
    assert _err(_run("estimate", logs["cart"], "-m", "ekf", "-o", out)) == expect
    assert _err(_run("simulate", "--scenario", "cart", "-o", out)) == expect
    assert _err(_run("plot", logs["cart"], "-o", gone / "p.png")).endswith(
        f"folder {gone} does not exist")
    line = _err(_run("estimate", logs["cart"], "-m", "ekf", "-o", tmp_path / "o.csv", "--plot",
                     gone / "p.png"))
    assert line == f"vibrospeed: error: --plot {gone / 'p.png'}: folder {gone} does not exist"
    line = _err(_run("estimate", logs["cart"], "-m", "ekf", "-o", tmp_path))
    assert line == f"vibrospeed: error: -o {tmp_path}: is a folder; give a file name"
    line = _err(_run("batch", logs["cart"], "-o", logs["cart"]))
    assert line == f"vibrospeed: error: -o {logs['cart']}: is a file, not a folder"
    assert list(tmp_path.iterdir()) == []  # no temporary file, no probe left behind


def test_a_figure_suffix_matplotlib_does_not_write_is_refused_before_the_work(
        logs, tmp_path, monkeypatch):
    from matplotlib.backend_bases import FigureCanvasBase

    _no_work(monkeypatch)
    kinds = ", ".join("." + k for k in sorted(FigureCanvasBase.get_supported_filetypes()))
    assert ".png" in kinds and ".txt" not in kinds
    fig = tmp_path / "out.txt"
    why = f"{fig}: .txt is not a figure format; give one of {kinds}"
    line = _err(_run("estimate", logs["cart"], "-o", tmp_path / "o.csv", "--plot", fig))
    assert line == f"vibrospeed: error: --plot {why}"
    assert _err(_run("plot", logs["cart"], "-o", fig)) == f"vibrospeed: error: -o {why}"
    assert list(tmp_path.iterdir()) == []  # neither the CSV nor its sidecar written


def test_the_cli_starts_without_matplotlib():
    import subprocess
    import sys

    code = "import sys, vibrospeed.cli.app; print('matplotlib' in sys.modules)"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert res.stdout.strip() == "False"


@pytest.mark.skipif(not __import__("os").path.isdir("/proc/self"), reason="needs Linux /proc")
def test_an_output_folder_that_cannot_be_written_is_refused_before_the_work(logs, monkeypatch):
    _no_work(monkeypatch)  # /proc takes no new files, not even from root
    line = _err(_run("batch", logs["cart"], "-o", "/proc/forbidden"))
    assert line.startswith("vibrospeed: error: -o /proc/forbidden: folder /proc is not writable")
    line = _err(_run("simulate", "-o", "/proc/o.csv"))
    assert line.startswith("vibrospeed: error: -o /proc/o.csv: folder /proc is not writable")


def test_a_writable_output_folder_is_created_by_batch(logs, tmp_path):
    out = tmp_path / "new" / "deeper"
    res = _run("batch", logs["cart"], "-m", "ekf", "-j", 1, "-p", "omega_min=2", "-p",
               "omega_max=30", "-o", out)
    assert res.exit_code == 0, res.output
    assert (out / "summary.csv").is_file()
    assert not [p for p in tmp_path.rglob(".vibrospeed-probe-*")]


def test_the_typical_session_of_the_top_level_help_runs_and_tracks_the_cart(tmp_path, monkeypatch):
    import shlex

    from vibrospeed.cli.base import app as base_app
    from vibrospeed.eval.metrics import evaluate

    text = base_app.info.help
    session = text[text.index("Typical session"):text.index("A phone log")]
    commands = [shlex.split(ln.strip())[1:] for ln in session.splitlines()
                if ln.strip().startswith("vibrospeed ")]
    assert [c[0] for c in commands] == ["simulate", "estimate", "evaluate"]
    assert "--method" not in commands[1] and "omega_max=30" in commands[1]  # the cart's range
    monkeypatch.chdir(tmp_path)
    out = {}
    for args in commands:
        res = out[args[0]] = _run(*args)
        assert res.exit_code == 0, (args, res.output)
    m = evaluate(io.read_track("est.csv"), io.read("cart.csv"))
    # the estimate ends with what it rests on: the claimed share, as read back from its CSV
    sig = np.asarray(io.read_track("est.csv").extras["has_signal"], dtype=float)
    share = np.mean(sig[np.isfinite(sig)] > 0.5)
    line = next(ln for ln in out["estimate"].stderr.splitlines() if ln.startswith("summary: "))
    assert line.startswith(f"summary: a wheel line claimed on {100 * share:.1f} % of the samples")
    assert ("elsewhere omega is the tracker's guess" in line) == (share < 1)
    truth = io.read("cart.csv").channel("omega_true")
    assert 2 < np.median(truth[truth > 1]) < 30  # the cart's wheels sit in the range given
    assert m.ok_share > 0.8 and m.rmse < 2.0  # rad/s: the default method on the cart's line


def _with_bad_cells(src, dst, cells):
    """``src`` with ``cells`` (row -> text) written into its ay column."""
    lines = src.read_text().splitlines()
    col = lines[0].split(",").index("ay")
    for row, text in cells.items():
        parts = lines[row].split(",")
        parts[col] = text
        lines[row] = ",".join(parts)
    dst.write_text("\n".join(lines) + "\n")


def test_infinite_values_are_counted_apart_from_nan(logs, tmp_path):
    from vibrospeed.io.chunks import ChunkedRecording

    bad = tmp_path / "bad.csv"
    cells = {100: "inf", 200: "-inf", 300: "inf", 400: "nan", 500: ""}
    _with_bad_cells(logs["cart"], bad, cells)
    n = len(bad.read_text().splitlines()) - 1
    n_inf = sum(v.strip("+-") == "inf" for v in cells.values())  # 3
    expect = f"channel 'ay': {len(cells) - n_inf} empty or NaN cell(s) and {n_inf} infinite " \
             f"value(s) (inf or -inf) of {n}"
    assert expect in io.read(bad).notes
    chunked = ChunkedRecording(bad, chunk_rows=128)
    list(chunked)  # one pass completes the notes
    assert expect in chunked.notes  # the streamed reader says the same
    res = _run("info", bad)
    assert res.exit_code == 0 and expect in " ".join(res.stdout.split())
    allinf = tmp_path / "allinf.csv"
    allinf.write_text("t,ay\n0,inf\n0.01,nan\n0.02,-inf\n")
    line = _err(_run("info", allinf))
    assert line.endswith("allinf.csv, column 'ay': channel has no finite value (all empty, NaN "
                         "or infinite)")


def test_a_damaged_zip_is_named_as_one(logs, tmp_path):
    import zipfile

    good = tmp_path / "export.zip"
    with zipfile.ZipFile(good, "w") as zf:
        zf.write(logs["cart"], "run/Accelerometer.csv")
    broken = tmp_path / "broken.zip"
    broken.write_bytes(good.read_bytes()[:40])  # the signature survives, the directory not
    line = _err(_run("info", broken))
    assert "broken.zip: not a valid zip file" in line and "unknown format" not in line
    named = tmp_path / "named.zip"  # a CSV with a .zip name is still read as the CSV it is
    named.write_bytes(logs["cart"].read_bytes())
    assert _run("info", named).exit_code == 0


def test_a_mapping_offset_is_printed_with_its_own_sign(tmp_path):
    m = tmp_path / "m.csv"
    m.write_text("time,acc_y,yaw,pitch\n0,1,2,3\n0.01,2,3,4\n0.02,3,4,5\n")
    toml = tmp_path / "m.toml"
    toml.write_text('[columns]\nt = "time"\nay = "acc_y"\n'
                    'gz = { column = "yaw", unit = "deg/s", offset = -0.3 }\n'
                    'gy = { column = "pitch", unit = "deg/s", offset = 0.25 }\n')
    rec = io.read(m, mapping_file=toml)
    note = next(n for n in rec.notes if n.startswith("columns mapped:"))
    assert "gz<-yaw-0.3 [deg/s]" in note and "gy<-pitch+0.25 [deg/s]" in note
    assert "+-" not in note
    np.testing.assert_allclose(rec.channel("gz"), (np.array([2, 3, 4]) - 0.3) * np.pi / 180)


# ---- values that are not numbers: one line, exit status 2, while parsing ----------------------
#: every option of the command line that takes one number (the test below checks that the
#: commands have no other): command, flag, float or int
NUMBER_OPTIONS = [
    ("simulate", "--seed", int), ("simulate", "--duration", float), ("simulate", "--fs", float),
    ("estimate", "--wheel-radius", float), ("estimate", "--init-omega", float),
    ("estimate", "--lag", float), ("estimate", "--rate", float),
    ("batch", "--wheel-radius", float), ("batch", "--init-omega", float),
    ("batch", "--lag", float), ("batch", "--jobs", int), ("batch", "--rate", float),
    ("report", "--wheel-radius", float), ("report", "--rate", float),
    ("evaluate", "--min-omega", float), ("evaluate", "--warmup", float),
    ("plot", "--harmonics", int), ("plot", "--window", float), ("plot", "--rate", float),
    ("truth", "--cogs", int), ("truth", "--r-sensor", float), ("truth", "--r-wheel", float),
    ("truth", "--scale", float), ("truth", "--spike-rel", float), ("truth", "--max-gap", float),
    ("info", "--rate", float),
]


def _command_args(command, cart, out):
    """``command`` with its required arguments, every output under folder ``out``."""
    return {
        "simulate": ["simulate", "-o", out / "s.csv"],
        "estimate": ["estimate", cart, "-o", out / "e.csv"],
        "batch": ["batch", cart, "-o", out / "b"],
        "report": ["report", cart, "-o", out / "r.html"],
        "evaluate": ["evaluate", cart, "--truth", cart, "--json", out / "m.json"],
        "plot": ["plot", cart, "-o", out / "p.png"],
        "truth": ["truth", cart, "-o", out / "t.csv"],
        "info": ["info", cart],
    }[command]


def test_the_table_holds_every_number_option_of_every_command():
    import typer

    from vibrospeed.cli.app import app

    group = typer.main.get_command(app)
    found = set()
    for name, command in group.commands.items():
        for p in command.params:
            typ = getattr(p.type_descriptor, "annotation", None)
            if typ in (float, int):
                found.add((name, max(p.opts, key=len), typ))
    assert found == set(NUMBER_OPTIONS)


def _not_a_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return True
    return False


@pytest.mark.parametrize(("command", "flag", "kind"), NUMBER_OPTIONS)
@pytest.mark.parametrize("value", ["abc", "1,5", ""])
def test_an_option_given_text_that_is_no_number_is_one_line(logs, tmp_path, command, flag,
                                                            kind, value):
    res = _run(*_command_args(command, logs["cart"], tmp_path), f"{flag}={value}")
    what = "a number" if kind is float else "an integer"
    if kind is float and value == "1,5":  # a decimal comma
        what += " (write the decimal point as '.')"
    assert _err(res) == f"vibrospeed: error: {flag}: {value!r} is not {what}"
    assert "Usage:" not in res.output
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("command", "flag"), [("plot", "--harmonics"), ("truth", "--cogs"),
                                               ("batch", "--jobs"), ("simulate", "--seed")])
def test_an_integer_option_given_a_fraction_is_one_line(logs, tmp_path, command, flag):
    res = _run(*_command_args(command, logs["cart"], tmp_path), flag, "2.5")
    assert _err(res) == f"vibrospeed: error: {flag}: '2.5' is not an integer"
    assert list(tmp_path.iterdir()) == []


_TEXT = st.text(st.characters(exclude_categories=("Cs",)), max_size=16).filter(_not_a_number)


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=_TEXT)
def test_any_text_that_is_no_number_gives_the_one_line(logs, tmp_path, text):
    for command, flag, kind in (("estimate", "--wheel-radius", float),
                                ("batch", "--jobs", int), ("evaluate", "--warmup", float)):
        res = _run(*_command_args(command, logs["cart"], tmp_path), f"{flag}={text}")
        what = "a number" if kind is float else "an integer"
        if kind is float and text.count(",") == 1 and not _not_a_number(text.replace(",", ".")):
            what += " (write the decimal point as '.')"
        # the text as Python writes it: a newline or a control character stays on the line
        assert _err(res) == f"vibrospeed: error: {flag}: {text!r} is not {what}"
        assert list(tmp_path.iterdir()) == []


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(text=st.text(st.characters(min_codepoint=33, max_codepoint=126, exclude_characters=","),
                    min_size=1, max_size=12).filter(_not_a_number))
def test_a_number_parameter_given_text_is_refused_before_the_recording_is_read(
        logs, tmp_path, monkeypatch, text):
    _no_work(monkeypatch)
    res = _run("estimate", logs["cart"], "-m", "grid", "-p", f"omega_max={text}",
               "-o", tmp_path / "e.csv")
    if text.lower() in ("none", "null"):  # omega_max may be None in some Configs only
        return
    assert _err(res) == (f"vibrospeed: error: parameter 'omega_max': cannot read {text!r} as "
                         "float (a number)")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("method", "name"), [
    ("ekf", "q_omega"), ("rbpmf", "omega_min"), ("grid", "omega_max"), ("rbpf", "q_omega"),
    ("shs", "omega_max"), ("aided", "q_omega"), ("gps-riss", "r_gps"), ("fuse", "min_sats"),
    ("algebraic", "window"),
])
def test_every_method_refuses_a_number_parameter_given_text(logs, tmp_path, monkeypatch,
                                                            method, name):
    _no_work(monkeypatch)  # refused from the parameters alone, before the recording is read
    line = _err(_run("estimate", logs["cart"], "-m", method, "-p", f"{name}=abc",
                     "-o", tmp_path / "e.csv"))
    assert line == f"vibrospeed: error: parameter '{name}': cannot read 'abc' as float (a number)"
    assert list(tmp_path.iterdir()) == []


def test_fuse_checks_the_names_it_hands_to_its_grid_tracker(logs, tmp_path, monkeypatch):
    _no_work(monkeypatch)
    line = _err(_run("estimate", logs["car"], "-m", "fuse", "-p", "omega_max=fast",
                     "-o", tmp_path / "e.csv"))
    assert line.endswith("parameter 'omega_max': cannot read 'fast' as float (a number)")


def test_every_preset_and_documented_example_passes_the_number_check():
    from vibrospeed import estimators, presets
    from vibrospeed.estimators.params import check_values

    for method in estimators.METHODS:
        for name in presets.presets(method):
            check_values(method, presets.preset_params(method, name))
        check_values(method, {k: p.example for k, p in presets.PARAMETERS.get(method,
                                                                                {}).items()})


@pytest.mark.parametrize(("method", "param", "line"), [
    ("ekf", "normalize_tau=abc", "parameter 'normalize_tau': cannot read 'abc' as float "
                                 "(a number)"),
    ("ekf", "comb=maybe", "parameter 'comb': cannot read 'maybe' as bool (true or false)"),
    ("rbpmf", "improved=1.0", "parameter 'improved': cannot read '1.0' as bool (true or false)"),
    ("grid", "improved=perhaps", "parameter 'improved': cannot read 'perhaps' as bool "
                                 "(true or false)"),
    ("grid", "omega_max=abc", "parameter 'omega_max': cannot read 'abc' as float (a number)"),
    ("aided", "wheelbase=long", "parameter 'wheelbase': cannot read 'long' as float | None "
                                "(a number, or none)"),
    ("aided", "causal=sometimes", "parameter 'causal': cannot read 'sometimes' as bool "
                                  "(true or false)"),
    ("aided", "tracker=bogus", "parameter 'tracker': cannot read 'bogus' as 'grid' | 'ekf' | "
                               "'rbpmf' (choose from grid, ekf, rbpmf)"),
    ("aided", "amp0=abc", "unknown parameter 'amp0' for method 'aided' with this tracker: "
                          "it is the EKF tracker's (-p tracker=ekf)"),
    ("fuse", "online=perhaps", "parameter 'online': cannot read 'perhaps' as bool "
                               "(true or false)"),
])
def test_estimate_and_batch_refuse_a_value_with_the_same_line_before_reading(
        logs, tmp_path, monkeypatch, method, param, line):
    """A ``-p`` value its types cannot read (:func:`vibrospeed.estimators.parameters`) is one
    line, exit 2, from ``estimate`` as from ``batch``, before the recording is read: both read
    it with :func:`vibrospeed.estimators.params.check_values`."""
    _no_work(monkeypatch)
    est = _run("estimate", logs["car"], "-m", method, "-p", param, "-o", tmp_path / "e.csv")
    bat = _run("batch", logs["car"], "-m", method, "-p", param, "-o", tmp_path / "out")
    assert est.exit_code == bat.exit_code == 2
    assert _err(est) == _err(bat) == f"vibrospeed: error: {line}"
    assert list(tmp_path.iterdir()) == []


def test_simulate_refuses_its_own_arguments_given_by_set(tmp_path):
    for args, line in (([], "--set seed=3: give it as --seed"),
                       ([], "--set duration=abc: give it as --duration"),
                       (["--fs", "50"], "--set fs=100: give it as --fs")):
        knob = line.split()[1].rstrip(":")
        res = _run("simulate", *args, "--set", knob, "-o", tmp_path / "s.csv")
        assert _err(res) == f"vibrospeed: error: {line}"
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("args", "line"), [
    (["estimate", "{cart}", "--bogus", "-o", "{out}"],
     "no such option: --bogus (Possible options: --columns); see 'vibrospeed estimate --help'"),
    (["estimate"], "missing argument 'input'; see 'vibrospeed estimate --help'"),
    (["estimate", "{cart}"], "missing option '-o' / '--output'; "
     "see 'vibrospeed estimate --help'"),
    (["estimate", "{cart}", "-o", "{out}", "--wheel-radius"],
     "option '--wheel-radius' requires an argument; see 'vibrospeed estimate --help'"),
    (["--bogus"], "no such option: --bogus; see 'vibrospeed --help'"),
    (["bogus"], "no such command 'bogus'; see 'vibrospeed --help'"),
])
def test_other_command_line_mistakes_are_one_line_too(logs, tmp_path, args, line):
    res = _run(*[a.format(cart=logs["cart"], out=tmp_path / "e.csv") for a in args])
    assert _err(res) == f"vibrospeed: error: {line}"
    assert list(tmp_path.iterdir()) == []


def test_help_is_still_the_help():
    res = _run()  # no arguments: the top-level help, as before (Click writes it to stderr)
    assert res.output.startswith("Usage: vibrospeed [OPTIONS] COMMAND [ARGS]...")
    assert "vibrospeed: error" not in res.output
    for command in ("simulate", "estimate", "batch", "report", "evaluate", "plot", "truth",
                    "info", "methods"):
        res = _run(command, "--help")
        assert res.exit_code == 0 and res.stderr == ""
        assert res.stdout.startswith(f"Usage: vibrospeed {command} [OPTIONS]")


def test_a_full_disk_is_the_systems_word_in_one_line_not_an_internal_error(tmp_path, monkeypatch):
    """An OSError with the system's message (ENOSPC, EIO) is no bug of vibrospeed: one line
    naming the file and the system's words, exit status 1, no 'please report it'."""
    import errno
    import os

    from vibrospeed.batch.task import _one_line

    src = tmp_path / "cart.csv"
    assert _run("simulate", "--scenario", "cart", "--duration", "4", "-o", src).exit_code == 0

    def full(*a, **k):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp_path / "est.csv"))

    monkeypatch.setattr("vibrospeed.io.write_track", full)
    res = _run("estimate", src, "-p", "omega_min=2", "-p", "omega_max=30", "-o",
               tmp_path / "est.csv")
    assert res.exit_code == 1, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("vibrospeed:")]
    assert lines == [f"vibrospeed: error: {tmp_path / 'est.csv'}: No space left on device"]
    assert "internal error" not in res.stderr and "Traceback" not in res.output
    # a batch row says the same in its error column
    exc = OSError(errno.EIO, os.strerror(errno.EIO), "/data/a.csv")
    assert _one_line(exc) == "/data/a.csv: Input/output error"
    assert _one_line(RuntimeError("x")) == "internal error: RuntimeError: x"


@pytest.mark.parametrize(("params", "line"), [
    (["amp0=1"], "unknown parameter 'amp0' for method 'aided' with this tracker: it is the EKF "
                 "tracker's (-p tracker=ekf)"),
    (["tracker=rbpmf", "amp0=1"], "unknown parameter 'amp0' for method 'aided' with this "
                                  "tracker: it is the EKF tracker's (-p tracker=ekf)"),
    (["tracker=ekf", "n_grid=50"], "unknown parameter 'n_grid' for method 'aided' with this "
                                   "tracker: it is the grid tracker's (-p tracker=grid, the "
                                   "default)"),
    (["n_gird=50"], "unknown parameter 'n_gird' for method 'aided' (did you mean 'n_grid'?)"),
])
def test_an_aided_name_of_the_other_tracker_names_that_tracker(logs, tmp_path, params, line):
    """``-m aided`` hands its names to the EKF or to a grid tracker (``-p tracker=``); a name
    only the other one takes said "did you mean 'amp0'" for 'amp0' (the hint merged both
    trackers' names), and a misspelt grid name was matched against the EKF's names only."""
    out = tmp_path / "e.csv"
    args = [a for p in params for a in ("-p", p)]
    assert _err(_run("estimate", logs["cart"], "-m", "aided", *args, "-o", out)) == \
        f"vibrospeed: error: {line}"
    assert list(tmp_path.iterdir()) == []


def test_an_aided_ekf_name_with_the_ekf_tracker_still_runs(logs, tmp_path):
    import json

    out = tmp_path / "e.csv"
    res = _run("estimate", logs["cart"], "-m", "aided", "-p", "tracker=ekf", "-p", "amp0=1",
               "-o", out)
    assert res.exit_code == 0, res.output
    assert json.loads(out.with_name("e.csv.json").read_text())["params"]["amp0"] == 1.0


def test_info_on_a_slow_phone_log_says_the_omega_max_that_grid_and_fuse_need(tmp_path):
    """A 35 Hz phone log with GPS: info said "fuse ... estimate's default for such a log" while
    estimate then refused the default 120 rad/s ("too low for omega up to 120 rad/s"). It now
    names the limit, pi fs; the default fuse runs without its vibration part, and an
    omega_max just below the limit is taken, one just above refused (the grid tracker's own
    test)."""
    log = tmp_path / "slow.csv"
    assert _run("simulate", "--scenario", "car", "--duration", 20, "--fs", 35,
                "-o", log).exit_code == 0
    fs = io.read(log).fs
    top = np.pi * fs
    feed = _can_feed(_run("info", log))
    assert f"grid needs -p omega_max below {top:.0f} rad/s at this rate (default 120)" in feed
    assert (f"estimate's default for such a log; at this rate without its vibration part unless "
            f"-p omega_max is below {top:.0f} rad/s)") in feed
    res = _run("estimate", log, "-o", tmp_path / "default.csv")  # fuse, vibration off
    assert res.exit_code == 0 and "vibration part off" in " ".join(res.output.split())
    assert "refused" not in _run("estimate", log, "-p", f"omega_max={top - 1:.1f}",
                                 "-o", tmp_path / "ok.csv").output
    assert (tmp_path / "ok.csv").exists()
    res = _run("estimate", log, "-p", f"omega_max={top + 0.5:.1f}", "-o", tmp_path / "no.csv")
    assert res.exit_code == 2 and "too low for omega up to" in res.output
    fast = tmp_path / "fast.csv"  # the scenario's own rate: the default range fits
    assert _run("simulate", "--scenario", "car", "--duration", 5, "-o", fast).exit_code == 0
    assert "omega_max below" not in _can_feed(_run("info", fast))


def test_accel_axis_without_method_names_what_keeps_fuse_out(logs, tmp_path, monkeypatch):
    """``-p accel_axis`` without ``-m`` is for fuse, the default with GPS speed: where the
    default falls back to grid, the line says why (it was grid's "unknown parameter")."""
    from vibrospeed.estimators.grid import stream

    out = tmp_path / "o.csv"
    line = _err(_run("estimate", logs["car"], "-p", "accel_axis=w", "-o", out))
    assert line == ("vibrospeed: error: -p accel_axis=w: the recording has no channel 'w' (it "
                    "has ax, ay, az) for fuse, the default where it has GPS speed")
    line = _err(_run("estimate", logs["cart"], "-p", "accel_axis=x", "-o", out))
    assert line.startswith("vibrospeed: error: -p accel_axis=x: it is fuse's, the default only "
                           "where the recording has GPS speed, and this one has none")
    res = _run("estimate", logs["car"], "-p", "accel_axis=-x", "-o", out)
    assert res.exit_code == 0 and "method fuse" in res.output, res.output
    # a log long enough to stream: the signed axis is the car's ax, so fuse would suit it
    monkeypatch.setattr(stream, "STREAM_ROWS", 1000)
    line = _err(_run("estimate", logs["car"], "-p", "accel_axis=-x", "-o", out))
    assert line == ("vibrospeed: error: -p accel_axis=-x: it is fuse's, and this log's 2000 "
                    "rows are estimated with grid in blocks (bounded memory; fuse holds the "
                    "whole log in memory): -m fuse to fuse it")
    line = _err(_run("estimate", logs["car"], "-p", "accel_axis=w", "-o", out))
    assert "the recording has no channel 'w' (it has ax, ay, az)" in line
