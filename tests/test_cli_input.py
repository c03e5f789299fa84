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
