"""Command-line interface: argument parsing only; numerics live in the library.

Every :class:`~vibrospeed.errors.VibrospeedError` (and an unreadable file) becomes one line on
stderr and exit status 2, without a traceback.
"""

from __future__ import annotations

import sys

from vibrospeed.cli.app import app


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``vibrospeed`` command."""
    from vibrospeed.errors import VibrospeedError

    try:
        app(args=argv, prog_name="vibrospeed", standalone_mode=True)
    except VibrospeedError as exc:  # pragma: no cover - typer re-raises only with standalone off
        print(f"vibrospeed: error: {exc}", file=sys.stderr)
        sys.exit(2)
