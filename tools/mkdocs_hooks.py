"""MkDocs hooks: the reference pages generated from the code at build time, the changelog, and
every page of ``docs/`` in the navigation.

Generated pages (never written by hand, so they cannot go stale):

* ``reference/parameters.md``: per method, every Config field (nested model and tracker
  Configs flattened, as ``-p`` names them) with type, default and description, the method's
  presets, and its ``estimate`` docstring (parameters read outside the Config);
* ``reference/columns.md``: the estimate CSV's standard columns (``vibrospeed.io.track``) and,
  per method, the extra columns it writes (found by running it on a short simulated drive
  unless ``VIBROSPEED_DOCS_FAST=1``, as the docs test sets to stay quick);
* ``reference/scenarios.md``: the simulated scenarios and their ``--set`` knobs;
* ``changelog.md``: ``CHANGELOG.md`` of the repository root.

Descriptions come from the dataclasses' docstrings: numpydoc-style ``name : text`` entries of
the class docstring (``a, b : text`` for several) or a string literal right after the field.
Run ``python tools/mkdocs_hooks.py parameters|columns|scenarios`` to print a page.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import os
import re
import sys
import textwrap
import typing
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
GENERATED = ("reference/parameters.md", "reference/columns.md", "reference/scenarios.md",
             "changelog.md")

_ENTRY = re.compile(r"^(\s*)([A-Za-z_]\w*(?:\s*,\s*[A-Za-z_]\w*)*)\s+:\s+(\S.*)$")
#: another ``name : text`` entry after a sentence on the same line
_INLINE_ENTRY = re.compile(r"(?<=[.;])\s+([A-Za-z_]\w*(?:\s*,\s*[A-Za-z_]\w*)*)\s+:\s+")


# ---- descriptions from docstrings --------------------------------------------------------------
def _class_doc_entries(cls: type) -> dict[str, str]:
    """``name : text`` entries of the class docstring (continuation lines joined)."""
    doc = inspect.getdoc(cls) or ""
    out: dict[str, str] = {}
    current: list[str] = []
    names: list[str] = []
    indent = -1

    def flush() -> None:
        if names:
            text = " ".join(" ".join(current).split())
            # further entries on the same lines: "a : x.  b : y." (the first keeps "x.")
            parts = _INLINE_ENTRY.split(text)
            for n in names:
                out.setdefault(n, parts[0])
            for more, more_text in zip(parts[1::2], parts[2::2], strict=True):
                for n in more.split(","):
                    out.setdefault(n.strip(), more_text)

    for line in doc.splitlines():
        m = _ENTRY.match(line)
        if m and (indent < 0 or len(m.group(1)) <= indent):
            flush()
            indent = len(m.group(1))
            names = [n.strip() for n in m.group(2).split(",")]
            current = [m.group(3)]
        elif names and line.strip() and len(line) - len(line.lstrip()) > indent:
            current.append(line.strip())
        else:
            flush()
            names, current = [], []
    flush()
    return out


def _attribute_docs(cls: type) -> dict[str, str]:
    """String literals right after a field's annotation in the class body."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(cls)))
    except (OSError, TypeError, SyntaxError):
        return {}
    body = tree.body[0].body if tree.body and isinstance(tree.body[0], ast.ClassDef) else []
    out: dict[str, str] = {}
    for a, b in zip(body, body[1:], strict=False):
        if (isinstance(a, ast.AnnAssign) and isinstance(a.target, ast.Name)
                and isinstance(b, ast.Expr) and isinstance(b.value, ast.Constant)
                and isinstance(b.value.value, str)):
            out[a.target.id] = " ".join(b.value.value.split())
    return out


def _inline_entry(name: str, entries: dict[str, str]) -> str:
    """A description of ``name`` written inside another entry: ``... . name : text.`` after a
    sentence, else the entry that mentions ````name````."""
    for text in entries.values():
        m = re.search(rf"(?:^|[.;]\s+){re.escape(name)}\s+:\s+([^.]*\.)", text)
        if m:
            return m.group(1)
    for text in entries.values():
        if f"``{name}``" in text:
            return text
    return ""


def _own_field_docs(cls: type) -> dict[str, str]:
    entries = _class_doc_entries(cls)
    out = {**entries, **_attribute_docs(cls)}
    for f in dataclasses.fields(cls) if dataclasses.is_dataclass(cls) else ():
        if not out.get(f.name):
            out[f.name] = _inline_entry(f.name, entries)
    return out


def field_docs(cls: type) -> dict[str, str]:
    """Field name -> one-paragraph description: the attribute docstring, else the class
    docstring's entry, else a mention inside another entry, each read in the class that
    declares the field. An inherited field (``GpsFields`` under ``gps-riss`` and ``fuse``) is
    described once, in its base class; a subclass's docstring only points there."""
    out = _own_field_docs(cls)
    for f in dataclasses.fields(cls) if dataclasses.is_dataclass(cls) else ():
        owner = next((c for c in cls.__mro__ if f.name in inspect.get_annotations(c)), cls)
        if owner is not cls:
            text = _own_field_docs(owner).get(f.name)
            if text:
                out[f.name] = text
    return out


# ---- tables --------------------------------------------------------------------------------------
_ROLE = re.compile(r":(?:func|class|mod|meth|attr|data|obj):`~?([^`]+)`")


def _cell(text: Any) -> str:
    """Table cell text: Sphinx roles as plain code, pipes escaped, one line."""
    text = _ROLE.sub(r"`\1`", str(text))
    return text.replace("|", "\\|").replace("\n", " ")


def _default(f: dataclasses.Field, inst: Any) -> tuple[bool, Any]:
    if inst is not None:
        return True, getattr(inst, f.name)
    if f.default is not dataclasses.MISSING:
        return True, f.default
    if f.default_factory is not dataclasses.MISSING:  # type: ignore[misc]
        return True, f.default_factory()  # type: ignore[misc]
    return False, None


def _show(value: Any) -> str:
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, tuple | list):
        return ",".join(_show(v) for v in value) if value else "(empty)"
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def config_rows(cls: type, inst: Any = None, prefix: str = "") -> list[tuple[str, str, str, str]]:
    """``(name, type, default, description)`` for every field of dataclass ``cls``; a field
    holding a dataclass (a model, a tracker) contributes its own fields instead."""
    from vibrospeed.config import field_types, type_name

    if inst is None:
        try:
            inst = cls()
        except Exception:  # noqa: BLE001 - a Config with required fields: show the fields' defaults
            inst = None
    docs = field_docs(cls)
    types_ = field_types(cls)
    rows = []
    for f in dataclasses.fields(cls):
        known, value = _default(f, inst)
        if known and dataclasses.is_dataclass(value) and not isinstance(value, type):
            rows += config_rows(type(value), value, prefix)
            continue
        sub = _sub_dataclass(types_[f.name])
        if sub is not None and not known:
            rows += config_rows(sub, None, prefix)
            continue
        rows.append((prefix + f.name, type_name(types_[f.name]),
                     _show(value) if known else "(required)", docs.get(f.name, "")))
    return rows


def _sub_dataclass(typ: Any) -> type | None:
    if dataclasses.is_dataclass(typ):
        return typ
    for a in typing.get_args(typ):
        if dataclasses.is_dataclass(a):
            return a
    return None


def _table(rows: list[tuple[str, ...]], head: tuple[str, ...]) -> list[str]:
    out = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    out += ["| " + " | ".join(_cell(c) for c in r) + " |" for r in rows]
    return out


def _docstring_block(obj: Any) -> list[str]:
    doc = inspect.getdoc(obj) or ""
    doc = doc.split("\nExamples\n", 1)[0].strip()
    return ["```text", *doc.splitlines(), "```"] if doc else []


# ---- pages ---------------------------------------------------------------------------------------
def parameters_page() -> str:
    from vibrospeed import presets
    from vibrospeed.estimators import METHODS, available, get

    out = ["# Parameters", "",
           "Generated from the code when the site is built: every field of each method's "
           "`Config` (nested model and tracker Configs flattened, as `-p NAME=VALUE` names "
           "them), its presets, and the `estimate` entry point's own parameters. The small set "
           "worth knowing first is in `vibrospeed methods` and the [user guide](../guide.md); "
           "values are typed as the table says (lists comma-separated, `none` for an empty "
           "optional).", ""]
    for name in available():
        mod = get(name)
        out += [f"## `{name}`", "", METHODS[name][1], ""]
        table = presets.presets(name)
        out += ["Presets (`--preset NAME`, applied before `-p`):", ""]
        out += _table([(f"`{p}`", presets.as_flags(v.params) or "(nothing set)", v.about)
                       for p, v in table.items()], ("preset", "sets", "use"))
        out.append("")
        documented = presets.PARAMETERS.get(name, {})
        if documented:
            out += ["Documented parameters:", ""]
            out += _table([(f"`{k}`", f"`{v.example}`", v.about) for k, v in documented.items()],
                          ("parameter", "example", "what it does"))
            out.append("")
        cfg = getattr(mod, "Config", None)
        if cfg is not None and dataclasses.is_dataclass(cfg):
            out += [f"All fields of `{cfg.__module__}.{cfg.__qualname__}`:", ""]
            out += _table([(f"`{n}`", f"`{t}`", f"`{d}`", text)
                           for n, t, d, text in config_rows(cfg)],
                          ("parameter", "type", "default", "description"))
            out.append("")
        est = getattr(mod, "estimate", None)
        if est is not None:
            out += [f"`{mod.__name__}.estimate`:", "", *_docstring_block(est), ""]
    return "\n".join(out) + "\n"


def _method_extras(fast: bool) -> dict[str, list[str]]:
    """Method -> extra columns of its estimate CSV on a short simulated drive."""
    if fast:
        return {}
    import numpy as np

    from vibrospeed import sim
    from vibrospeed.estimators import available, get

    car = sim.simulate("car", seed=1, duration=6)
    gps = sim.simulate("gps_tunnel", seed=1, duration=25)
    out = {}
    for name in available():
        params = {"algebraic": {"L1": "1.2"}, "rbpf": {"n_particles": "50"}}.get(name, {})
        rec, kw = (gps, {"axis": "x"}) if name == "gps-riss" else (car, {})
        try:
            track = get(name).estimate(rec, params=params, **kw)
        except Exception as exc:  # noqa: BLE001 - a method this drive cannot feed
            out[name] = [f"(not run on the simulated car: {exc})"]
            continue
        out[name] = sorted(k for k, v in track.extras.items() if np.shape(v) == (len(track),))
    return out


def columns_page(fast: bool | None = None) -> str:
    from vibrospeed.io.track import TRACK_COLUMNS
    from vibrospeed.types import Track

    if fast is None:
        fast = os.environ.get("VIBROSPEED_DOCS_FAST") == "1"
    docs = _class_doc_entries(Track)
    out = ["# Output columns", "",
           "Generated from the code when the site is built. `vibrospeed estimate -o est.csv` "
           "writes one row per input sample: first the standard columns (every method; NaN "
           "where a method has no such quantity), then the method's extra columns. The JSON "
           "sidecar `est.csv.json` records the method, its parameters, the preset, the "
           "version, the input's SHA-256 and the notes.", "",
           "## Standard columns", ""]
    out += _table([(f"`{c}`", docs.get(c, "")) for c in TRACK_COLUMNS], ("column", "meaning"))
    out += ["", "## Extra columns per method", ""]
    extras = _method_extras(fast)
    if not extras:
        out += ["(Listed by `make docs`; this build ran with `VIBROSPEED_DOCS_FAST=1`.) Each "
                "method's `estimate` docstring on the [parameters page](parameters.md) "
                "describes its extras.", ""]
    for name, cols in extras.items():
        out += [f"- `{name}`: " + ", ".join(f"`{c}`" if not c.startswith("(") else c
                                             for c in cols)]
    out += ["", "What the extras mean is in each method's `estimate` docstring on the "
            "[parameters page](parameters.md); the grid trackers' `has_signal` and "
            "`standstill` are explained in the [user guide](../guide.md).", ""]
    return "\n".join(out) + "\n"


def _md_text(doc: str) -> str:
    """A docstring as Markdown paragraphs: reST ``code`` as `code`, lines of a paragraph joined."""
    paras = [" ".join(p.split()) for p in inspect.cleandoc(doc or "").split("\n\n")]
    return "\n\n".join(p.replace("``", "`") for p in paras if p)


def _keyword_rows(fn: Any, skip: tuple[str, ...] = ()) -> list[tuple[str, str, str, str]]:
    """``(name, type, default, description)`` of the keyword parameters of ``fn`` that
    ``--set`` can reach: a plain default (number, flag, text, tuple of numbers), read as the
    type of that default (:func:`vibrospeed.sim._gps_knob`)."""
    docs = _class_doc_entries(fn)
    rows = []
    for name, par in inspect.signature(fn).parameters.items():
        d = par.default
        if name in skip or d is inspect.Parameter.empty or d is None:
            continue
        if isinstance(d, tuple):
            typ = "tuple[float, ...]"
        elif isinstance(d, (bool, int, float)):
            typ = type(d).__name__
        else:
            continue
        rows.append((name, typ, _show(d), docs.get(name, "")))
    return rows


def scenarios_page() -> str:
    from vibrospeed import sim
    from vibrospeed.sim import gps as sim_gps
    from vibrospeed.sim.scenarios import CONFIGS

    gps_builders = {name: fn for name, fn in sim_gps.SCENARIOS.items() if name in sim.SCENARIOS}
    gps_rows = _keyword_rows(sim_gps.drive, skip=("source",))
    out = ["# Simulated scenarios", "",
           "Generated from the code when the site is built. `vibrospeed simulate --scenario "
           "NAME --set KNOB=VALUE` sets any knob below (dotted names reach nested Configs, "
           "lists are comma-separated: `--set vibration.harmonic_amps=0.1,0.05`; `--set "
           "gps=off` switches an optional part off).", ""]
    for name, desc in sim.describe().items():
        out += [f"## `{name}`", ""]
        cfg = CONFIGS.get(name)
        if name in gps_builders:
            build = gps_builders[name]
            out += [_md_text(build.__doc__ or desc), ""]
            out += _table([(f"`{n}`", f"`{t}`", f"`{d}`") for n, t, d, _ in
                           _keyword_rows(build)], ("knob", "type", "default"))
            out += ["", "and the knobs of every GPS drive ([below](#gps-drive-knobs)).", ""]
            continue
        out += [desc, ""]
        if cfg is None:
            out += ["Knobs: the keyword arguments of its builder (below).", ""]
            fn = sim.SCENARIOS.get(name)
            if fn is not None:
                out += _docstring_block(fn)
                out.append("")
            continue
        out += _table([(f"`{n}`", f"`{t}`", f"`{d}`", text)
                       for n, t, d, text in _scenario_rows(cfg)],
                      ("knob", "type", "default", "description"))
        out.append("")
    if gps_builders:
        out += ["## GPS drive knobs", "",
                "Every GPS scenario (" + ", ".join(f"`{n}`" for n in gps_builders) + ") "
                "simulates its receiver and accelerometer with "
                "`vibrospeed.sim.gps.drive`, whose knobs it takes too (a scenario's own "
                "default, such as `gps_tunnel`'s `acc_bias`, comes first).", ""]
        out += _table([(f"`{n}`", f"`{t}`", f"`{d}`", text) for n, t, d, text in gps_rows],
                      ("knob", "type", "default", "description"))
        out.append("")
    return "\n".join(out) + "\n"


def _scenario_rows(cls: type, inst: Any = None, prefix: str = "") -> list:
    """Like :func:`config_rows` but nested Configs keep their dotted prefix (``--set``)."""
    from vibrospeed.config import field_types, type_name

    if inst is None:
        try:
            inst = cls()
        except Exception:  # noqa: BLE001
            inst = None
    docs = field_docs(cls)
    types_ = field_types(cls)
    rows = []
    for f in dataclasses.fields(cls):
        known, value = _default(f, inst)
        sub = _sub_dataclass(types_[f.name])
        if sub is not None:
            rows.append((prefix + f.name, type_name(types_[f.name]),
                         "on" if value is not None else "off",
                         docs.get(f.name, "") + " (on/off, or its knobs below)"))
            rows += _scenario_rows(sub, value if dataclasses.is_dataclass(value) else None,
                                   f"{prefix}{f.name}.")
            continue
        rows.append((prefix + f.name, type_name(types_[f.name]),
                     _show(value) if known else "(required)", docs.get(f.name, "")))
    return rows


def changelog_page() -> str:
    return (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")


PAGES = {"reference/parameters.md": parameters_page, "reference/columns.md": columns_page,
         "reference/scenarios.md": scenarios_page, "changelog.md": changelog_page}


# ---- MkDocs hooks --------------------------------------------------------------------------------
def _nav_files(nav: Any) -> set[str]:
    out: set[str] = set()
    if isinstance(nav, str):
        out.add(nav)
    elif isinstance(nav, dict):
        for v in nav.values():
            out |= _nav_files(v)
    elif isinstance(nav, list):
        for v in nav:
            out |= _nav_files(v)
    return out


def on_config(config, **kwargs):
    """Pages in ``docs/`` that the navigation does not list go under "More topics", so a new
    page is never left out of the site."""
    if str(ROOT / "src") not in sys.path:
        sys.path.insert(0, str(ROOT / "src"))
    nav = config.get("nav")
    if not nav:
        return config
    listed = _nav_files(nav)
    docs_dir = Path(config["docs_dir"])
    extra = sorted(p.relative_to(docs_dir).as_posix() for p in docs_dir.rglob("*.md")
                   if p.relative_to(docs_dir).as_posix() not in listed)
    if extra:
        nav.append({"More topics": extra})
    return config


def on_files(files, config, **kwargs):
    """Add the generated pages."""
    from mkdocs.structure.files import File

    for uri, make in PAGES.items():
        files.append(File.generated(config, uri, content=make()))
    return files


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT / "src"))
    which = sys.argv[1] if len(sys.argv) > 1 else "parameters"
    print({"parameters": parameters_page, "columns": columns_page,
           "scenarios": scenarios_page}[which]())
