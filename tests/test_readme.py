"""The README's, the docs' and every `--help`'s examples work as written (a stale example
is a bug for a new user): the Python example runs, and every `vibrospeed ...` command line
parses against the CLI (its command and options exist, values have the right type, a preset
exists for its method)."""

import re
import shlex
from pathlib import Path

import click
import pytest
import typer.main

from vibrospeed import presets
from vibrospeed.cli.app import app

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]


def test_readme_python_examples_run():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "no Python example in the README"
    for code in blocks:
        ns: dict = {}
        exec(compile(code, str(README), "exec"), ns)  # noqa: S102 - our own README
        assert "est" in ns or "track" in ns


def _command_lines(path: Path) -> list[str]:
    """``vibrospeed ...`` lines of the ``sh`` blocks, comments removed, continuations joined."""
    out = []
    for block in re.findall(r"```sh\n(.*?)```", path.read_text(), flags=re.S):
        for line in block.replace("\\\n", " ").splitlines():
            line = line.strip()
            if line.startswith("vibrospeed "):
                out.append(line)
    return out


def _help_lines() -> list[tuple[str, str]]:
    """The example command lines in each command's ``--help`` (its docstring, from "Examples"
    on): a line that starts with ``vibrospeed``, continued by following lines that start with
    ``-``; a trailing ``(comment)`` after two spaces is dropped."""
    out = []
    for cmd in typer.main.get_command(app).commands.values():
        lines = [ln.strip() for ln in (cmd.help or "").splitlines()]
        first = next((k for k, ln in enumerate(lines) if ln.startswith("Example")), len(lines))
        for k, line in enumerate(lines):
            if k < first or not line.startswith("vibrospeed "):
                continue
            full = line
            for cont in lines[k + 1:]:
                if not cont.startswith("-"):
                    break
                full += " " + cont
            out.append((f"{cmd.name} --help", re.sub(r"\s{2,}\(.*\)$", "", full)))
    return out


CASES = [(p.name, line) for p in PAGES for line in _command_lines(p)] + _help_lines()


def test_there_are_command_examples():
    assert sum(1 for name, _ in CASES if name == "README.md") >= 15


@pytest.mark.parametrize(("page", "line"), CASES)
def test_command_examples_parse(page, line):
    args = shlex.split(line, comments=True)[1:]
    group = typer.main.get_command(app)
    assert args[0] in group.commands, f"{page}: unknown command in {line!r}"
    cmd = group.commands[args[0]]
    try:
        ctx = cmd.make_context(args[0], list(args[1:]))
    except click.exceptions.UsageError as exc:  # unknown option, bad value, missing argument
        pytest.fail(f"{page}: {line!r}: {exc.format_message()}")
    preset = ctx.params.get("preset")
    if preset is not None:
        assert preset in presets.presets(ctx.params.get("method") or "grid"), (page, line)


# the online examples' claim "the numbers of the causal batch run": each OnlineTracker the
# page builds, in order, with the params of the batch run it stands for
ONLINE_CASES = {
    "README.md": [{"smooth": "none"}, {"smooth": "none", "comb_axes": "all"}],
    # the guide's second tracker takes the other axes for its stops (standstill=3)
    "guide.md": [{"smooth": "none", "omega_min": 2, "omega_max": 30}] * 2,
}


@pytest.mark.parametrize("page", sorted(ONLINE_CASES))
def test_online_examples_match_the_causal_batch_run(page, monkeypatch):
    import numpy as np

    from vibrospeed.estimators import grid, online

    seen = []

    class Recording(online.OnlineTracker):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            self.omegas = []
            seen.append(self)

        def update(self, sample, *others):
            est = super().update(sample, *others)
            self.omegas.append(est.omega)
            return est

    monkeypatch.setattr(online, "OnlineTracker", Recording)
    path = next(p for p in PAGES if p.name == page)
    code = next(b for b in re.findall(r"```python\n(.*?)```", path.read_text(), flags=re.S)
                if "OnlineTracker(" in b)
    ns: dict = {}
    exec(compile(code, str(path), "exec"), ns)  # noqa: S102 - our own docs
    rec = ns["rec"]
    assert len(seen) == len(ONLINE_CASES[page])
    for trk, params in zip(seen, ONLINE_CASES[page], strict=True):
        assert trk.config == grid.config_for(rec, params=params)
        batch = grid.estimate(rec, axis="y", params=params)
        n = len(trk.omegas)
        assert n >= 100
        np.testing.assert_array_equal(trk.omegas, batch.omega[:n])
