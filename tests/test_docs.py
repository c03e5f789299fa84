"""The documentation site builds without a warning (broken links, missing pages), its generated
reference covers the code, and the Python examples of the pages run as written."""

import dataclasses
import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _hooks():
    spec = importlib.util.spec_from_file_location("mkdocs_hooks", ROOT / "tools/mkdocs_hooks.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_strict_build(tmp_path):
    pytest.importorskip("mkdocs")
    env = {**os.environ, "VIBROSPEED_DOCS_FAST": "1"}
    res = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q",
                          "-f", str(ROOT / "mkdocs.yml"), "-d", str(tmp_path / "site")],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    for page in ("index.html", "guide/index.html", "architecture/index.html",
                 "reference/parameters/index.html", "reference/columns/index.html",
                 "reference/scenarios/index.html", "changelog/index.html"):
        assert (tmp_path / "site" / page).is_file(), page
    # every page of docs/ is in the site (listed in the nav or added under "More topics")
    for md in DOCS.rglob("*.md"):
        rel = md.relative_to(DOCS).with_suffix("")
        html = "index.html" if rel.name == "index" else f"{rel.as_posix()}/index.html"
        assert (tmp_path / "site" / html).is_file(), md


def test_reference_covers_every_config_field():
    from vibrospeed import presets
    from vibrospeed.config import flat_names
    from vibrospeed.estimators import available, get
    from vibrospeed.io.track import TRACK_COLUMNS
    from vibrospeed.sim.scenarios import CONFIGS

    hooks = _hooks()
    page = hooks.parameters_page()
    for method in available():
        assert f"## `{method}`" in page
        cfg = getattr(get(method), "Config", None)
        if dataclasses.is_dataclass(cfg):
            for name in flat_names(cfg):
                assert f"| `{name}` |" in page, (method, name)
        for pname, pre in presets.presets(method).items():
            assert f"| `{pname}` | {presets.as_flags(pre.params) or '(nothing set)'} |" in page
    cols = hooks.columns_page(fast=True)
    for c in TRACK_COLUMNS:
        assert f"| `{c}` |" in cols
    scen = hooks.scenarios_page()
    assert "| `vibration.harmonic_amps` | `tuple[float, ...]` | `0.25,0.2,0.1` |" in scen
    for name in CONFIGS:
        assert f"## `{name}`" in scen


def test_scenarios_page_says_the_gps_drive_once():
    import inspect

    from vibrospeed.sim import gps as sim_gps

    scen = _hooks().scenarios_page()
    # the receiver and accelerometer knobs every GPS scenario shares: one table, at one place
    assert scen.count("## GPS drive knobs") == 1
    assert scen.count("| `gps_rate` | `float` | `12.5` | Hz (paper: 12.5). |") == 1
    assert scen.count("| `gps_noise` |") == 1
    sections = scen.split("\n## ")
    for name, build in sim_gps.SCENARIOS.items():
        sec = next(x for x in sections if x.startswith(f"`{name}`"))
        assert sec.count("[below](#gps-drive-knobs)") == 1
        first = " ".join(inspect.getdoc(build).split("\n\n")[0].split()).replace("``", "`")
        assert scen.count(first) == 1, name  # its description once, not twice
        assert "| `duration` | `float` |" in sec and "| `fs` | `float` | `400.0` |" in sec
    # a knob of the table reaches the simulation
    from vibrospeed import sim

    rec = sim.simulate("gps_braking", seed=0, duration=20, gps_rate="5")
    assert abs(int(sum(~np.isnan(rec.channel("gps_speed")))) - 100) <= 2


def test_field_descriptions_from_docstrings():
    hooks = _hooks()

    @dataclasses.dataclass(frozen=True)
    class Knobs:
        """Knobs.

        a, b : the two ends of the range, in rad/s;
            continued on the next line.
        c : a third.  e : a fifth.  f, g : sixth
            and seventh.
        """

        a: float = 1.0
        b: float = 2.0
        c: int = 3
        d: str = "x"
        """Attribute docstring of d."""

    docs = hooks.field_docs(Knobs)
    text = "the two ends of the range, in rad/s; continued on the next line."
    assert docs == {"a": text, "b": text, "c": "a third.", "d": "Attribute docstring of d.",
                    "e": "a fifth.", "f": "sixth and seventh.", "g": "sixth and seventh."}
    rows = hooks.config_rows(Knobs)
    assert rows[0] == ("a", "float", "1.0", text)
    assert rows[3] == ("d", "str", "x", "Attribute docstring of d.")

    @dataclasses.dataclass(frozen=True)
    class More(Knobs):
        """More knobs.

        a, b, c : see Knobs.
        e : a fifth.
        """

        c: int = 4
        e: float = 5.0

    # an inherited field is described where it is declared; a redeclared one by the subclass
    assert hooks.field_docs(More) == {"a": text, "b": text, "c": "see Knobs.",
                                      "d": "Attribute docstring of d.", "e": "a fifth."}


@pytest.mark.parametrize("page", ["index.md", "guide.md"])
def test_python_examples_run(page):
    blocks = re.findall(r"```python\n(.*?)```", (DOCS / page).read_text(), flags=re.S)
    assert blocks, page
    for code in blocks:
        exec(compile(code, str(DOCS / page), "exec"), {})  # noqa: S102 - our own docs
