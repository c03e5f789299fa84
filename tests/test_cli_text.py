"""Text the CLI prints from docstrings and from the user (scenario descriptions, paths, channel
names) comes out whole: a description is its docstring's first paragraph, not its first line, and
brackets in it (``[t_front, t_rear, ...]``, ``run[draft]/``) are text, not rich markup."""

import inspect
import re

import pytest
from typer.testing import CliRunner

from vibrospeed import sim
from vibrospeed.cli.app import app
from vibrospeed.sim import gps as sim_gps
from vibrospeed.sim.scenarios import describe_doc


def _paragraph(doc: str) -> str:
    """First paragraph of a docstring with its whitespace collapsed (the reference)."""
    return " ".join(inspect.cleandoc(doc).split("\n\n")[0].split())


def test_describe_doc_joins_the_first_paragraph():
    doc = """Cruise over bumps; ``meta['bumps']`` lists
        [t_front, t_rear, speed at the middle].

        Second paragraph, not part of it.
        """
    assert describe_doc(doc) == ("Cruise over bumps; `meta['bumps']` lists [t_front, t_rear, "
                                 "speed at the middle].")
    assert describe_doc(None) == describe_doc("") == ""
    assert describe_doc("  One line.  ") == "One line."


def test_scenario_descriptions_are_whole_sentences():
    desc = sim.describe()
    assert set(desc) == set(sim.SCENARIOS)
    for name, text in desc.items():
        assert text.endswith("."), (name, text)  # not cut mid-sentence at a line end
        assert "\n" not in text and "``" not in text, name
    # the Config's (car) and the builder's (GPS scenarios) first paragraphs, every line of them
    assert desc["car"] == _paragraph(sim.CarConfig.__doc__)
    for name, build in sim_gps.SCENARIOS.items():
        assert desc[name] == _paragraph(build.__doc__).replace("``", "`"), name
    assert desc["bumpy_floor"].endswith("lists [t_front, t_rear, speed at the middle].")
    assert desc["sudden_change"].endswith("brake to a stop near the end.")


def _entries(listing: str) -> dict[str, str]:
    """``simulate --list`` output: name -> its description with the line breaks undone."""
    out: dict[str, list[str]] = {}
    name = None
    for line in listing.splitlines():
        if line and not line[0].isspace():
            name, _, rest = line.partition(" ")
            out[name] = [rest]
        elif line.strip():
            assert name is not None, listing
            out[name].append(line)
    return {k: " ".join(" ".join(v).split()) for k, v in out.items()}


@pytest.mark.parametrize("columns", ["80", "200"])
def test_simulate_list_prints_every_description_whole(columns):
    res = CliRunner().invoke(app, ["simulate", "--list"], env={"COLUMNS": columns})
    assert res.exit_code == 0, res.output
    assert _entries(res.stdout) == sim.describe()
    assert all(len(line) <= int(columns) for line in res.stdout.splitlines())


def test_paths_and_names_with_brackets_are_printed_as_given(tmp_path):
    runner = CliRunner()
    run = tmp_path / "run[draft]"
    run.mkdir()
    drive, est = run / "c[1a].csv", run / "e[v2].csv"
    res = runner.invoke(app, ["simulate", "--scenario", "cart", "--duration", "8",
                              "-o", str(drive)])
    assert res.exit_code == 0, res.output
    assert f"wrote {drive}:" in res.stderr
    res = runner.invoke(app, ["estimate", str(drive), "-m", "shs", "-p", "omega_min=4",
                              "-p", "omega_max=30", "-o", str(est), "--plot",
                              str(run / "p[x].png")])
    assert res.exit_code == 0, res.output
    assert f"wrote {est} (" in res.stderr and f"wrote {run / 'p[x].png'}" in res.stderr
    res = runner.invoke(app, ["evaluate", str(est), "--truth", str(drive)])
    assert res.exit_code == 0, res.output
    assert "e[v2].csv vs truth c[1a].csv" in res.stdout
    res = runner.invoke(app, ["plot", str(drive), "-o", str(run / "s[y].png")])
    assert res.exit_code == 0, res.output
    assert f"wrote {run / 's[y].png'}" in res.stderr
    # a canonical CSV's own column name with brackets, in the info table
    odd = run / "odd[z].csv"
    odd.write_text("t,ay,temp[c]\n0,1,20\n0.01,2,21\n0.02,1,22\n")
    res = runner.invoke(app, ["info", str(odd)], env={"COLUMNS": "120"})
    assert res.exit_code == 0, res.output
    assert re.search(r"│ temp\[c\] +│", res.stdout), res.stdout
    assert res.stdout.startswith(f"{odd}:")


def test_a_preset_spelled_out_in_the_docs_is_what_methods_prints():
    # "The `lock` preset (`-p a=1 -p b=2 ...`)" on a method page: the flags `vibrospeed methods`
    # prints on that preset's "=" line, every one of them (the grid page once lacked temper)
    from pathlib import Path

    docs = Path(__file__).resolve().parents[1] / "docs"
    res = CliRunner().invoke(app, ["methods"], env={"COLUMNS": "400"})
    assert res.exit_code == 0, res.output
    printed: dict[str, set[str]] = {}  # preset name -> its flags, as printed for any method
    lines = res.stdout.splitlines()
    for line, nxt in zip(lines, lines[1:], strict=False):
        head, flags = line.split(), nxt.strip()
        if len(head) > 1 and head[0].isidentifier() and flags.startswith("= -p "):
            printed.setdefault(head[0], set()).add(flags[2:])
    spelled = [(page.name, name, flags)
               for page in sorted(docs.glob("*.md"))
               for name, flags in re.findall(r"The `(\w+)` preset \(`(-p [^`]+)`\)",
                                             " ".join(page.read_text().split()))]
    assert spelled  # at least the grid page's lock preset
    for page, name, flags in spelled:
        assert flags in printed.get(name, set()), (page, name, flags, printed.get(name))
