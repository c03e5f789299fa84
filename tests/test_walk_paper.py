"""Walkthrough of the papers' settings (``--preset paper``): the algebraic method's published
Algorithm 1 as a preset, the trackers page's parameter names, the SHS favourable scoring's
halving rule."""

import re
from pathlib import Path

import numpy as np

from vibrospeed import estimators, presets
from vibrospeed.config import config_from_params
from vibrospeed.estimators import algebraic, shs

DOCS = Path(__file__).resolve().parents[1] / "docs"


def test_algebraic_paper_preset_is_the_published_algorithm_1():
    """``--preset paper`` for ``algebraic`` runs the seed's slip test (``detect=seed``: |dGx/dt|
    < eps1 over alpha samples) restarting the integration from the previous sample
    (``backtrack=0``, seed Algorithm 1 line 6); the default's window test is not the paper's."""
    cfg = config_from_params(algebraic.Config, presets.preset_params("algebraic", "paper"))
    assert cfg == algebraic.Config(detect="seed", backtrack=0)
    assert algebraic.Config().detect == "window"
    assert "not the paper's" in presets.presets("algebraic")["default"].about


def test_trackers_page_names_parameters_each_method_takes():
    """docs/trackers.md's sentence on the shared parameters: every parameter it names for a
    method (``All three``: rbpmf, rbpf, shs) is one that method accepts (SHS has no ``M``: its
    harmonics are ``n_harmonics``)."""
    text = (DOCS / "trackers.md").read_text()
    para = re.search(r"All three take.*?\n\n", text, re.S).group(0).replace("\n", " ")
    trackers = ("rbpmf", "rbpf", "shs")
    checked = 0
    for clause in re.split(r";|\. ", para):
        names = re.findall(r"`([A-Za-z_0-9]+)`", clause)
        methods = [n for n in names if n in trackers] or \
            (list(trackers) if "All three" in clause else [])
        # a clause "`M` for `rbpmf` and `rbpf` and `n_harmonics` for `shs`": pair each
        # parameter with the methods named after it, up to the next parameter
        groups: list[tuple[str, list[str]]] = []
        for n in names:
            if n in trackers:
                if groups:
                    groups[-1][1].append(n)
            else:
                groups.append((n, []))
        for name, after in groups:
            for m in after or methods:
                assert name in estimators.parameters(m), (name, m)
                checked += 1
    assert checked >= 8  # omega_min, omega_max for three, M for two, n_harmonics for one


def test_shs_favourable_score_halving_rule():
    """Paper IV-C: detections within 5 rad/s kept; a halved detection is doubled and kept only
    where the doubled value is within 5 rad/s (est within 2.5 of half the truth)."""
    truth = np.array([40.0, 40.0, 40.0, 40.0, 40.0])
    est = np.array([44.0, 22.4, 23.0, 17.0, 30.0])
    sc = shs.favourable_score(est, truth)
    np.testing.assert_array_equal(np.isfinite(sc.corrected), [True, True, False, False, False])
    assert sc.halved == 1 and sc.kept == 2 and sc.total == 5
    assert np.isclose(sc.rmse, np.sqrt((4.0**2 + 4.8**2) / 2))


def test_shs_paper_constructor_is_the_paper_preset():
    """``shs.Config.from_paper_table1`` and ``-m shs --preset paper`` are one setting: 200
    samples per batch on 10-120 rad/s (paper IV-B) with Hermes' 48 points per octave and
    compression 0.84 (the constructor had the default 192 points per octave)."""
    cfg = config_from_params(shs.Config, presets.preset_params("shs", "paper"))
    assert cfg == shs.Config.from_paper_table1()
    assert (cfg.batch, cfg.omega_min, cfg.omega_max) == (200, 10.0, 120.0)
    assert (cfg.points_per_octave, cfg.compression) == (48, 0.84)
