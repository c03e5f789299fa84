"""Harmonic EKF with the comb check (issue 13): re-lock from half the wheel speed, acquisition
without --init-omega, step == run with the comb input."""

import dataclasses

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.estimators import ekf
from vibrospeed.models.harmonic import HarmonicModel


@pytest.fixture(scope="module")
def cart():
    # a cart that keeps rolling (no stops), from 5 s: the wheel at ~10 rad/s
    return sim.simulate("cart", seed=1, duration=30.0, initial_stop=0, p_stop=0).slice_time(5.0)


def _within(tr, rec, t0):
    truth = rec["omega_true"]
    sel = rec.t - rec.t[0] >= t0
    return np.mean(np.abs(tr.omega[sel] - truth[sel]) <= 0.1 * truth[sel])


def test_started_at_half_the_wheel_speed_relocks_within_seconds(cart):
    half = 0.5 * float(np.median(cart["omega_true"]))
    p = {"omega0": half, "omega_min": 2, "omega_max": 30}
    stuck = ekf.estimate(cart, params={**p, "comb": "false"})
    assert _within(stuck, cart, 6.0) < 0.1  # the thesis' EKF stays on half the speed
    tr = ekf.estimate(cart, params=p)
    assert tr.extras["acquired"].all()  # an --init-omega is trusted from the start
    assert _within(tr, cart, 6.0) > 0.9  # 3 s frame + 2 candidates in a row, then locked


def test_without_init_omega_acquires_from_the_comb(cart):
    tr = ekf.estimate(cart, params={"omega_min": 2, "omega_max": 30})
    acq = tr.extras["acquired"] > 0.5
    t_acq = (cart.t - cart.t[0])[np.argmax(acq)]
    assert acq.any() and t_acq < 5.0
    assert np.all(acq[np.argmax(acq):])
    assert _within(tr, cart, 6.0) > 0.9
    assert tr.params["acquire"] and any("comb check" in n for n in tr.notes)


def test_step_equals_run_with_comb_input():
    rng = np.random.default_rng(2)
    n = 900
    t = np.arange(n) / 100.0
    y = np.cos(12.0 * t) + 0.5 * np.cos(24.0 * t) + 0.3 * rng.normal(size=n)
    y[100:110] = np.nan
    comb = np.full(n, np.nan)
    comb[300::25] = 12.0  # acquisition at the 2nd (steady) candidate
    comb[600::25] = 24.5  # steady at 625, 2nd in a row at 650: reset
    model = dataclasses.replace(HarmonicModel.from_thesis(), M=2, p0_amp=1.0, r=0.3)
    cfg = ekf.Config(model, omega0=5.0, acquire=True, omega_min=2.0)
    res = ekf.run(cfg, y, comb=comb)
    st = ekf.init(cfg)
    om, acq = [], []
    for k in range(n):
        st, e = ekf.step(cfg, st, y[k], comb[k])
        om.append(e.omega)
        acq.append(e.acquired)
    assert np.array_equal(np.array(om), res.omega)
    assert np.array_equal(np.array(acq), res.acquired)
    np.testing.assert_array_equal(st.P, res.final.P)
    np.testing.assert_array_equal(st.comb, res.final.comb)
    assert not res.acquired[324] and res.acquired[325]
    assert res.omega[325] == 12.0 and res.omega[650] == 24.5
    a = ekf.run(cfg, y[:450], comb=comb[:450])
    b = ekf.run(cfg, y[450:], state=a.final, comb=comb[450:])
    assert np.array_equal(np.concatenate([a.omega, b.omega]), res.omega)
    # without the input the filter is the thesis' EKF: acquire only marks the output
    plain = ekf.run(dataclasses.replace(cfg, acquire=False), y)
    assert np.array_equal(ekf.run(cfg, y).omega, plain.omega) and plain.acquired.all()
