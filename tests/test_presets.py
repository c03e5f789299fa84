"""Presets (--preset) and the documented parameters: applied before -p, recorded in the
sidecar, listed by `vibrospeed methods`, each runs; the `paper` presets equal the seed
documents' settings as the estimators' own constructors give them."""

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from vibrospeed import estimators, io, presets, sim
from vibrospeed.cli.app import app
from vibrospeed.errors import ParameterError

runner = CliRunner()


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def drives():
    return {"cart": sim.simulate("cart", seed=1, duration=10),
            "car": sim.simulate("car", seed=1, duration=10),
            "gps": sim.simulate("gps_tunnel", seed=1, duration=30)}


def _drive_for(method, drives):
    return drives[{"gps-riss": "gps", "algebraic": "car", "fuse": "car"}.get(method, "cart")]


def _kw(method):
    return {"axis": "x"} if method == "gps-riss" else {}


def _extra(method):
    # short-drive settings outside the preset: the algebraic method needs L1, the RBPF is
    # cut to 200 particles to keep the test fast
    return {"algebraic": {"L1": "1.2"}, "rbpf": {"n_particles": "200"}}.get(method, {})


def test_every_method_has_default_and_online():
    for method in estimators.available():
        if method not in presets.PRESETS:
            continue
        table = presets.presets(method)
        assert table["default"].params == {}
        assert "online" in table
        for name, pre in table.items():
            assert pre.about and "\n" not in pre.about, (method, name)
            assert all(isinstance(v, str) for v in pre.params.values())


@pytest.mark.parametrize(("method", "name"), [(m, n) for m, t in presets.PRESETS.items()
                                              for n in t])
def test_each_preset_runs_on_a_short_drive(method, name, drives):
    rec = _drive_for(method, drives)
    params = {**presets.preset_params(method, name), **_extra(method)}
    track = estimators.get(method).estimate(rec, params=params, **_kw(method))
    assert len(track) == len(rec)
    # speed methods (fuse leaves omega empty where this short drive taught no radius)
    assert np.isfinite(track.speed if method in ("gps-riss", "algebraic", "fuse")
                       else track.omega).mean() > 0.5


@pytest.mark.parametrize("method", list(presets.PARAMETERS))
def test_documented_parameters_are_accepted(method, drives, tmp_path):
    """Every documented parameter with its example value, all at once, is accepted."""
    rec = _drive_for(method, drives)
    params = {k: p.example for k, p in presets.PARAMETERS[method].items()}
    if "radius_from" in params:  # a sidecar of an earlier drive: written here
        first = tmp_path / params["radius_from"].removesuffix(".json")
        io.write_track(estimators.get(method).estimate(rec), first)
        params["radius_from"] = str(tmp_path / params["radius_from"])
    if method == "ekf":
        params["omega_max"] = "30"  # M = 2 with the example's 60 rad/s fits 100 Hz; keep margin
    params = {**_extra(method), **params}
    if method == "rbpf":
        params["n_particles"] = "200"
    track = estimators.get(method).estimate(rec, params=params, **_kw(method))
    assert len(track) == len(rec)


def test_precedence_and_unknown_preset():
    assert presets.apply("grid", "lock", {"q_omega": "8"})["q_omega"] == "8"
    assert presets.apply("grid", "lock", {})["q_omega"] == "4"
    assert presets.apply("grid", None, {"M": "2"}) == {"M": "2"}
    with pytest.raises(ParameterError, match=r"unknown preset 'lok' for method 'grid' "
                       r"\(did you mean 'lock'\?\) \(choose from: default, online, lag, lock\)"):
        presets.apply("grid", "lok", {})


def test_paper_presets_equal_the_constructors():
    """Each value a `paper` preset sets is the paper constructor's value of that field."""
    from vibrospeed.config import config_from_params, field_types, parse_value

    for method in ("rbpmf", "rbpf"):
        ref = estimators.get(method).Config.from_paper_table1()
        for k, v in presets.preset_params(method, "paper").items():
            owner = ref.model if k in field_types(type(ref.model)) else ref
            assert parse_value(v, field_types(type(owner))[k], k) == getattr(owner, k), (method, k)
    ekf = estimators.get("ekf").Config.from_thesis()
    assert ekf.amp0 == float(presets.preset_params("ekf", "paper")["amp0"])
    gr = estimators.get("gps-riss")
    assert config_from_params(gr.Config, presets.preset_params("gps-riss", "paper")) == \
        gr.Config.paper()


def test_cli_preset_is_recorded_and_explicit_p_wins(tmp_path, drives):
    path = tmp_path / "cart.csv"
    io.write(drives["cart"], path)
    a, b, c = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    res = _run("estimate", path, "--preset", "lock", "-o", a)
    assert res.exit_code == 0, res.output
    flags = [x for k, v in presets.preset_params("grid", "lock").items()
             for x in ("-p", f"{k}={v}")]
    assert _run("estimate", path, *flags, "-o", b).exit_code == 0
    # the preset is exactly its -p flags
    np.testing.assert_array_equal(np.loadtxt(a, delimiter=",", skiprows=1),
                                  np.loadtxt(b, delimiter=",", skiprows=1))
    side = json.loads(a.with_name("a.csv.json").read_text())
    assert side["meta"]["preset"] == "lock"
    assert side["params"]["mode_hold"] == 4.0 and side["params"]["smooth"] == "none"
    res = _run("estimate", path, "--preset", "lock", "-p", "mode_hold=2", "-o", c)
    assert res.exit_code == 0, res.output
    assert json.loads(c.with_name("c.csv.json").read_text())["params"]["mode_hold"] == 2.0
    # a misspelt name: suggestions from all of the method's parameters (nested Configs too)
    res = _run("estimate", path, "-p", "comb_axis=all", "-o", c)
    assert res.exit_code == 2 and ("unknown parameter 'comb_axis' for method 'grid' (did you "
                                   "mean 'comb_axes'") in res.stderr
    res = _run("estimate", path, "--preset", "nope", "-o", c)
    assert res.exit_code == 2 and "unknown preset 'nope' for method 'grid'" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_methods_lists_presets_and_parameters():
    res = _run("methods")
    assert res.exit_code == 0, res.output
    for method in estimators.available():
        assert f"{method}: " in res.output
    assert "-p smooth=none -p comb_axes=all -p q_omega=4" in res.output
    res = _run("methods", "grid")
    assert res.exit_code == 0 and "lock" in res.output and "omega_min=2" in res.output
    assert "ekf:" not in res.output
    res = _run("methods", "nope")
    assert res.exit_code == 2 and "unknown method 'nope'" in res.stderr
    res = _run("estimate", "--help")
    assert "--preset" in res.output and "lock" in res.output


def test_batch_takes_a_preset(tmp_path, drives):
    path = tmp_path / "cart.csv"
    io.write(drives["cart"], path)
    res = _run("batch", path, "-o", tmp_path / "out", "--preset", "online", "-p", "M=2",
               "-j", 1)
    assert res.exit_code == 0, res.output
    side = json.loads((tmp_path / "out" / "cart_grid.csv.json").read_text())
    assert side["params"]["smooth"] == "none" and side["params"]["M"] == 2
    assert side["meta"]["options"]["params"] == {"M": "2", "smooth": "none"}
    res = _run("batch", path, "-o", tmp_path / "out", "-m", "ekf", "--preset", "lock")
    assert res.exit_code == 2 and "unknown preset 'lock' for method 'ekf'" in res.stderr


def test_algebraic_slip_tol_is_documented_as_its_config_reads_it():
    """``vibrospeed methods algebraic``: ``slip_tol`` is in m/s with the Config's default (it
    said "0.05 relative wheel slip"; the field is a speed difference, default 0.3 m/s)."""
    from vibrospeed.estimators import algebraic

    par = presets.PARAMETERS["algebraic"]["slip_tol"]
    assert par.about.startswith("m/s,")
    assert par.about.endswith(f"default {algebraic.Config().slip_tol:g}")
    assert "relative" not in par.about
    assert algebraic.Config(slip_tol=float(par.example)).slip_tol == 0.5


def test_lag_presets_are_the_fixed_lag_runs():
    """``--preset lag``: grid's fixed-lag smoother and fuse's lag mode, 2 s; both names are
    parameters the methods take (a batch accepts them)."""
    assert presets.apply("grid", "lag", {}) == {"smooth": "lag", "lag": "2"}
    assert presets.apply("grid", "lag", {"lag": "1"}) == {"smooth": "lag", "lag": "1"}
    assert presets.apply("fuse", "lag", {}) == {"lag": "2"}
    assert float in estimators.parameters("fuse")["lag"]
    assert {"smooth", "lag"} <= set(estimators.parameters("grid"))
