"""Walkthrough of the algebraic Vx / Vy estimator as a tyre / ABS tester: parameter domains,
the thesis' low-pass table, a motor-speed "wheel" on an RC car."""

from pathlib import Path

import numpy as np
import pytest
from scipy import signal as sps

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import algebraic as A
from vibrospeed.signal import prefilter as pf
from vibrospeed.sim import vehicle as sim
from vibrospeed.types import WHEEL_CHANNELS, Recording


# -- parameter domains ------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "value", "says"), [
    ("L1", 1e9, r"L1 must be in \(0, 10\] m"),
    ("r", 1e9, r"r must be in \(0, 3\] m"),
    ("window", 1e9, r"window must be in \(0, 10\] s"),  # was a 745 GiB kernel (MemoryError)
    ("window_d", 0.0, r"window_d must be in \(0, 10\] s"),
    ("slip_window", 1e6, r"slip_window must be in \(0, 10\] s"),
    ("N", 50, r"N must be an integer in \[1, 10\]"),
    ("alpha", 10**8, r"alpha must be at most 6000 samples \(60 s at Ts = 0.01 s\)"),
    ("backtrack", 10**8, r"backtrack must be at most 6000 samples"),
    ("noise_tau", 1e-9, r"noise_tau must be >= Ts = 0.01 s"),
    ("vy0", 1e9, r"vy0 must be in \[-100, 100\] m/s"),
    ("slip_sd", 2.0, r"slip_sd must be in \[0, 1\]"),
    ("eps_k", -1.0, r"eps_k must be >= 0 \(inf: never\)"),
    ("beta", float("inf"), r"beta must be an integer >= 0 samples"),
    ("L1", float("nan"), r"L1 must be in \(0, 10\] m, got nan"),
    ("eps1", 0.0, r"eps1 must be > 0 m/s\^2 \(inf: never\)"),
])
def test_out_of_domain_parameter_is_one_line_naming_it(name, value, says):
    with pytest.raises(ParameterError, match=r"^algebraic: " + says) as exc:
        A.Config(**{name: value})
    assert "\n" not in str(exc.value)


def test_domain_edges_and_never_thresholds_are_accepted():
    A.Config(L1=10.0, r=3.0, window=10.0, window_d=10.0, N=10, slip_window=10.0, vy0=-100.0,
             alpha=6000, eps1=np.inf, eps2=np.inf, slip_tol=np.inf, max_int=np.inf)


def test_window_too_short_for_the_degree_names_the_windows():
    with pytest.raises(ParameterError, match=r"^algebraic: window = 0.02 s / window_d = 0.2 s "
                                             r"at Ts = 0.01 s: window must hold at least"):
        A.Config(window=0.02, N=3)


# -- thesis table 3.1 -------------------------------------------------------------------------
def test_thesis_lowpass_table_is_table_3_1():
    """Thesis (indoor-vehicle-vibration-ekf-thesis) table 3.1, best omega_lp per M:
    M = 1: 12, M = 2: 19, M = 3: 10, M = 4: 8 rad/s (the code had 25 for M = 1 and 10 for
    M >= 4); the -3 dB point of the designed low-pass is there."""
    table = {1: 12.0, 2: 19.0, 3: 10.0, 4: 8.0}
    assert pf.THESIS_LP_CUTOFF == table
    for M, wc in {**table, 6: 8.0}.items():
        lp = pf.design("thesis-hplp", 100.0, M=M)[-1:]
        _, h = sps.sosfreqz(lp, worN=[wc], fs=2 * np.pi * 100.0)
        assert abs(h[0]) == pytest.approx(1 / np.sqrt(2), rel=0.02)


# -- a slip episode longer than any tyre slips -------------------------------------------------
F1TENTH_DS1 = Path(__file__).resolve().parents[2] / "shared/datasets/f1tenth_frictionmaps/DS1"


def _noisy_rc_car(n=1500, dt=1 / 30, sd=4.0, seed=0):
    """A tiny car at a steady 2 m/s (r = 0.05 m) with a vibrating accelerometer (sd 4 m/s^2):
    the F1/10 case in 50 s."""
    rng = np.random.default_rng(seed)
    t = dt * np.arange(n)
    w = np.full(n, 2.0 / 0.05)
    ch = {"gz": np.zeros(n), "ax": sd * rng.standard_normal(n), "ay": sd * rng.standard_normal(n),
          **{c: w for c in WHEEL_CHANNELS}}
    return Recording(t, ch, wheel_radius=0.05, meta={"L1": 0.16})


def test_long_slip_episode_is_noted_and_max_int_bounds_it():
    rec = _noisy_rc_car()
    tr = A.estimate(rec)
    slip = tr.extras["slip_mode"]
    assert slip.mean() > 0.9  # the noise alone keeps the wheels "slipping"
    note = [n for n in tr.notes if "slip episode" in n]
    assert len(note) == 1 and "-p max_int=0.5 -p eps_k=3" in note[0]
    err = np.sqrt(np.mean((tr.speed - 2.0) ** 2))
    capped = A.estimate(rec, params={"max_int": 0.5, "eps_k": 3})
    assert not [n for n in capped.notes if "slip episode" in n]
    assert np.sqrt(np.mean((capped.speed - 2.0) ** 2)) < min(0.5, err / 3)


def test_simulated_braking_gets_no_slip_note():
    rec = sim.simulate(sim.Config(mu=0.5), np.random.default_rng(0), name="braking")
    tr = A.estimate(rec)
    assert 0.3 < tr.extras["slip_mode"].mean()  # it does slip, in episodes of seconds
    assert not [n for n in tr.notes if "slip episode" in n]


@pytest.mark.skipif(not F1TENTH_DS1.is_dir(), reason="../shared/datasets not present")
def test_f1tenth_ds1_the_minus_28_ms_is_one_39_s_slip_episode():
    from vibrospeed import io

    rec = io.read(F1TENTH_DS1)
    tr = A.estimate(rec)
    assert tr.speed.min() == pytest.approx(-28.6, abs=0.1)
    assert tr.extras["slip_mode"].mean() > 0.97
    assert any("one slip episode lasted 39" in n for n in tr.notes)
    capped = A.estimate(rec, params={"max_int": 0.5, "eps_k": 3})
    ok = np.isfinite(rec["speed_true"])
    rmse = np.sqrt(np.mean((capped.speed[ok] - rec["speed_true"][ok]) ** 2))
    assert rmse == pytest.approx(0.88, abs=0.02)


# -- the vehicle manoeuvres from `vibrospeed simulate` -----------------------------------------
def test_vehicle_scenarios_are_the_python_api_drives():
    from vibrospeed import sim as scen

    a = scen.simulate("vehicle_braking", seed=1, **{"vehicle.mu": "0.5"})
    b = sim.simulate(sim.Config(mu=0.5), np.random.default_rng(1), name="braking")
    assert set(a.channels) == set(b.channels)
    for c in b.channels:
        np.testing.assert_array_equal(a[c], b[c])
    assert a.meta["L1"] == 1.2 and a.wheel_radius == 0.31 and a.meta["car"]["mu"] == 0.5
    r = scen.simulate("vehicle_random", seed=3)
    np.testing.assert_array_equal(r["speed_true"], sim.simulate_random(3)["speed_true"])
    short = scen.simulate("vehicle_braking", seed=1, duration=5, fs=50)
    assert len(short) == 250 and short.t[-1] == pytest.approx(5.0)
    with pytest.raises(ParameterError, match="fs must be in"):
        scen.simulate("vehicle_braking", fs=0.5)


def test_cli_braking_scenario_estimate_and_evaluate(tmp_path):
    """simulate -> estimate -m algebraic (L1 and r from the sidecar) -> Vx RMSE: the default
    and the paper preset on the braking at mu 0.5, seed 1 (0.089 and 0.72 m/s by hand), both
    well below the plain wheel speed's ~2 m/s."""
    from typer.testing import CliRunner

    from vibrospeed import io
    from vibrospeed.cli.app import app

    run = CliRunner().invoke
    drive, est = tmp_path / "b.csv", tmp_path / "e.csv"
    res = run(app, ["simulate", "--scenario", "vehicle_braking", "--seed", "1",
                    "--set", "vehicle.mu=0.5", "-o", str(drive)])
    assert res.exit_code == 0, res.output
    truth = io.read(drive)
    for preset, want in ((None, 0.089), ("paper", 0.719)):
        args = ["estimate", str(drive), "-m", "algebraic", "-o", str(est)]
        res = run(app, args + (["--preset", preset] if preset else []))
        assert res.exit_code == 0, res.output
        rmse = np.sqrt(np.mean((io.read_track(est).speed - truth["speed_true"]) ** 2))
        assert rmse == pytest.approx(want, abs=0.01), preset


def test_wheel_radius_given_twice():
    """``-p r`` beside ``--wheel-radius`` ran the filter on ``-p r`` while the Track converted
    with the other (speed at 0.5 m, omega = speed / 0.3 m); two different values are refused,
    one value either way gives one estimate."""
    rec = sim.simulate(sim.Config(mu=0.5), np.random.default_rng(1), name="braking")
    with pytest.raises(ParameterError, match=r"wheel radius is given twice, --wheel-radius 0.3 m "
                                             r"and -p r=0.5"):
        A.estimate(rec, wheel_radius=0.3, params={"r": "0.5"})
    a = A.estimate(rec, wheel_radius=0.3, params={"r": 0.3})
    b = A.estimate(rec, params={"r": "0.3"})
    assert a.params["r"] == b.params["r"] == a.wheel_radius == 0.3
    np.testing.assert_array_equal(a.speed, b.speed)
    np.testing.assert_allclose(a.omega, a.speed / 0.3)
