"""The ``vibrospeed`` command line in-process, for the CLI tests: ``run`` a command and read a
refused command's ``one_line_error``."""

from typer.testing import CliRunner

from vibrospeed.cli.app import app

runner = CliRunner()


def run(*args):
    """``vibrospeed ARGS`` (each argument as text); the click result."""
    return runner.invoke(app, [str(a) for a in args])


def one_line_error(res) -> str:
    """The one stderr line of a refused command (exit status 2, no traceback)."""
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, res.stderr
    assert "Traceback" not in res.output
    return lines[0]
