"""The README quotes the current measurements of the pages it cites, and the files a page names
exist (a figure or a path left behind by a change is a bug for a new reader)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
ROBUSTNESS = ROOT / "docs" / "robustness.md"
#: pages whose backticked paths are checked
PAGES = [README, ROOT / "benchmarks" / "algebraic" / "RESULTS.md"]
#: written by a command, not part of a checkout
_OUTPUTS = {"demo_out/"}


def _family_medians() -> dict[str, float]:
    """Median "within" per method of the family table in docs/robustness.md."""
    out = {}
    for line in ROBUSTNESS.read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) >= 2 and re.fullmatch(r"0\.\d+", cells[1]):
            out[cells[0]] = float(cells[1])
    return out


def test_readme_family_figures_are_the_robustness_pages():
    med = _family_medians()
    grid = med["`grid` (offline, default)"]
    rbpmf = med["`rbpmf` (the paper's filter)"]
    stft = med["3 s STFT harmonic sum (offline)"]
    text = " ".join(README.read_text().split())
    m = re.search(r"median (\d+) % of moving time within max\(10 %, omega_min / 5\), the "
                  r"paper's `rbpmf` (\d+) %, a 3 s STFT harmonic sum (\d+) %", text)
    assert m, "the README's Methods table no longer quotes the family figures"
    assert [int(g) for g in m.groups()] == [round(100 * x) for x in (grid, rbpmf, stft)]


def _paths(page: Path) -> list[str]:
    """Backticked repository paths of a page: with a '/', ending in .py, .md or '/'."""
    found = re.findall(r"`([A-Za-z0-9_.][A-Za-z0-9_./-]*/[A-Za-z0-9_./-]*)`", page.read_text())
    return sorted({p for p in found if p.endswith((".py", ".md", "/")) and p not in _OUTPUTS
                   and not p.startswith("../")})


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_paths_named_on_the_page_exist(page):
    paths = _paths(page)
    assert paths
    # a path is relative to the repository, to src/ or src/vibrospeed/ (code), or to benchmarks/
    bases = [ROOT, ROOT / "src", ROOT / "src" / "vibrospeed", ROOT / "benchmarks"]
    missing = [p for p in paths if not any((b / p).exists() for b in bases)]
    assert not missing, f"{page.name} names files that do not exist: {missing}"
