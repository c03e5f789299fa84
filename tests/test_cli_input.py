"""Bad input on the ``vibrospeed`` command line: one line on stderr naming what is wrong, exit
status 2, no traceback and nothing written; and what ``info`` and ``--help`` tell the user."""

import pytest
from typer.testing import CliRunner

from vibrospeed import io
from vibrospeed.cli.app import app
from vibrospeed.estimators import fuse

runner = CliRunner()


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


def _err(res):
    """The one stderr line of a refused command (exit status 2, no traceback)."""
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.output
    return lines[0]


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
    (["estimate", "{cart}", "--lag", "-1", "-o", "{out}.csv"], "--lag: lag must be >= 0 s"),
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
