"""The ``vibrospeed`` commands: simulate, estimate, batch, report, evaluate, plot, truth, info,
methods. The Typer ``app`` is built in :mod:`vibrospeed.cli.base`; the commands live in a
module per group (:mod:`~vibrospeed.cli.recordings`, :mod:`~vibrospeed.cli.estimate`,
:mod:`~vibrospeed.cli.results`) and are registered here, in the order ``--help`` lists them."""

from __future__ import annotations

from vibrospeed.cli.base import OneLineCommand, app
from vibrospeed.cli.estimate import batch, estimate, methods
from vibrospeed.cli.recordings import info, simulate, truth
from vibrospeed.cli.results import evaluate, plot, report

for _command in (simulate, estimate, batch, report, evaluate, plot, truth, info, methods):
    app.command(cls=OneLineCommand)(_command)

__all__ = ["app"]
