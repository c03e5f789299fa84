"""Aided tracker, issue 13: broadband standstill input, a_x offset, comb check, family drive."""

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.estimators import aided


def _drive(n=3000, dt=0.01, seed=0):
    """Stand 5 s, ramp to 20 rad/s, cruise; comb at k * omega plus noise; a_x with an offset."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    w = np.clip((t - 5.0) * 8.0, 0.0, 20.0)
    th = np.cumsum(w) * dt
    y = 0.2 * np.cos(th) + 0.1 * np.cos(2 * th) + 0.05 * np.cos(3 * th)
    y += rng.normal(0, 0.003, n) + rng.normal(0, 0.05, n) * (w > 0)  # road only while rolling
    u = np.gradient(w * 0.1, dt) + 0.8 + rng.normal(0, 0.003, n)  # 0.8 m/s^2 gravity offset
    u += rng.normal(0, 0.05, n) * (w > 0)  # the road shakes every axis
    return t, w, y, u


def test_step_equals_run_with_still_and_comb():
    _, w, y, u = _drive(n=900)
    cfg = aided.Config(standstill="broadband")
    still = (w == 0).astype(float)
    comb = np.full(y.size, np.nan)
    comb[600::25] = 20.0
    comb[700::25] = 9.0
    res = aided.run(cfg, y, u, still=still, comb=comb)
    st = aided.init(cfg)
    for k in range(y.size):
        st, est = aided.step(cfg, st, y[k], u[k], still=still[k], comb=comb[k])
        assert est.omega == res.omega[k] and est.standstill == res.standstill[k]
    np.testing.assert_array_equal(st.x, res.final.x)
    a = aided.run(cfg, y[:400], u[:400], still=still[:400], comb=comb[:400])
    b = aided.run(cfg, y[400:], u[400:], still=still[400:], comb=comb[400:], state=a.final)
    np.testing.assert_array_equal(np.concatenate([a.omega, b.omega]), res.omega)


def test_broadband_flag_overrides_the_mode_detector():
    """Standing (flag 1): omega = 0 measurements and no acceleration mode, whatever a_x reads."""
    n = 300
    cfg = aided.Config(standstill="broadband", omega0=5.0)
    res = aided.run(cfg, np.zeros(n), np.full(n, 2.0), still=np.ones(n))
    assert res.standstill.all() and not res.accelerating.any()
    assert res.omega[-1] < 0.05
    # without the flag the same a_x is acceleration mode (thesis detector)
    res = aided.run(cfg, np.zeros(n), np.full(n, 2.0))
    assert res.accelerating[50:].all() and not res.standstill.any()


def test_standstill_offset_offline_and_causal():
    u = np.array([1.0, 1.0, 3.0, 5.0, 1.2, 7.0, np.nan])
    still = np.array([1, 1, 0, 0, 1, 0, 0])
    np.testing.assert_allclose(aided.standstill_offset(u, still), np.full(7, 3.2 / 3))
    c = aided.standstill_offset(u, still, causal=True)
    np.testing.assert_allclose(c, [1.0, 1.0, 1.0, 1.0, 3.2 / 3, 3.2 / 3, 3.2 / 3])
    # no standing sample: offline the whole mean, causally the running mean
    u2 = np.array([1.0, 3.0])
    np.testing.assert_allclose(aided.standstill_offset(u2, np.zeros(2)), [2.0, 2.0])
    np.testing.assert_allclose(aided.standstill_offset(u2, np.zeros(2), causal=True), [1.0, 2.0])


def test_comb_fixes_find_the_wheel_not_half_of_it():
    t, w, y, _ = _drive()
    ref, var, score = aided.comb_fixes(y, 0.01, (2 * np.pi, 150.0))
    cruise = np.isfinite(ref) & (t > 12)
    assert cruise.sum() > 50
    np.testing.assert_allclose(ref[cruise], 20.0, rtol=0.03)
    np.testing.assert_allclose(np.sqrt(var[cruise]), 0.05 * ref[cruise])
    # causal: a frame's candidate uses samples up to its end only
    y2 = y.copy()
    y2[2000:] = 0.0
    ref2, _, _ = aided.comb_fixes(y2, 0.01, (2 * np.pi, 150.0))
    np.testing.assert_array_equal(ref2[:2000], ref[:2000])


def test_comb_check_relocks_from_half_the_wheel_speed():
    t, w, y, u = _drive()
    cfg = aided.Config(standstill="none", omega0=10.0, p0_omega=0.01)
    comb, _, _ = aided.comb_fixes(y, 0.01, (2 * np.pi, 150.0))
    late = t > 15
    y0, u0 = y[late], np.zeros(late.sum())
    res = aided.run(cfg, y0, u0, comb=comb[late])
    assert abs(res.omega[-200:].mean() - 20.0) < 1.0
    assert np.flatnonzero(np.abs(res.omega - 20.0) < 2.0)[0] * 0.01 < 2.0


def test_estimate_defaults_on_a_synthetic_drive():
    t, w, y, u = _drive()
    from vibrospeed.types import Recording

    rec = Recording(t=t, channels={"ay": y, "ax": u}, wheel_radius=0.1)
    tr = aided.estimate(rec, params={"tracker": "ekf"})
    assert tr.params["standstill"] == "broadband" and tr.params["accel_offset"] == "standstill"
    st = tr.extras["standstill"] > 0.5
    assert st[(t > 1.0) & (t < 4.0)].mean() > 0.9 and not st[t > 8].any()
    cruise = t > 12
    assert np.mean(np.abs(tr.omega[cruise] - 20.0) < 2.0) > 0.9


@pytest.mark.parametrize("seed", [6])
def test_family_drive_with_stops(seed):
    """A randomised-family cart (mount near the vehicle frame, raw a_x): stops found, no
    standstill while rolling, the speed tracked most of the time."""
    rec = sim.simulate("random", seed=seed, duration=120)
    w = rec["omega_true"]
    lo = rec.meta["omega_range"][0]
    tr = aided.estimate(rec, params={"tracker": "ekf"})
    st = tr.extras["standstill"] > 0.5
    k = int(round(rec.fs))
    stop = np.convolve((w <= 0).astype(float), np.ones(2 * k + 1), "same") >= 2 * k + 1
    assert st[stop].mean() > 0.9
    assert st[w > 0].mean() < 0.01
    moving = w >= lo
    assert np.mean(np.abs(tr.omega - w)[moving] <= np.maximum(0.1 * w, lo / 5)[moving]) > 0.5


def test_causal_option_and_errors():
    t, w, y, u = _drive()
    from vibrospeed.types import Recording

    rec = Recording(t=t, channels={"ay": y, "ax": u}, wheel_radius=0.1)
    tr = aided.estimate(rec, params={"tracker": "ekf", "causal": True})
    assert tr.params["causal"] is True
    with pytest.raises(Exception, match="accel_offset"):
        aided.estimate(rec, params={"tracker": "ekf", "accel_offset": "maybe"})
    with pytest.raises(Exception, match="comb_count"):
        aided.Config(comb_count=0)



@pytest.mark.parametrize("tracker", ["ekf", "grid", "rbpmf"])
def test_every_tracker_refuses_an_accel_offset_it_does_not_take_alike(tracker):
    """``accel_offset`` is 'standstill' or 'none' (estimators.ACCEL_OFFSET) for every
    tracker; the grid ones took any other text as 'none'."""
    from vibrospeed.errors import ParameterError
    from vibrospeed.types import Recording

    t, _, y, u = _drive(n=600)
    rec = Recording(t=t, channels={"ay": y, "ax": u}, wheel_radius=0.1)
    with pytest.raises(ParameterError) as err:
        aided.estimate(rec, params={"tracker": tracker, "accel_offset": "bogus"})
    assert str(err.value) == ("parameter 'accel_offset': cannot read 'bogus' as 'standstill' | "
                              "'none' (choose from standstill, none)")


@pytest.mark.parametrize("causal", [False, True])
def test_grid_tracker_reads_wheelbase_and_detrend_as_numbers(causal):
    """``wheelbase`` and ``accel_detrend`` given as text (``-p``) are the numbers they spell:
    the estimate is the one from the numbers, bit for bit, and the Track's params hold the
    numbers (they held the text)."""
    from vibrospeed.types import Recording

    t, _, y, u = _drive()
    rec = Recording(t=t, channels={"ay": y, "ax": u}, wheel_radius=0.1)
    base = {"tracker": "grid", "accel_axis": "ax", "causal": causal}
    text = aided.estimate(rec, params={**base, "wheelbase": "0.6", "accel_detrend": "0.5"})
    num = aided.estimate(rec, params={**base, "wheelbase": 0.6, "accel_detrend": 0.5})
    assert np.array_equal(text.omega, num.omega, equal_nan=True)
    for tr in (text, num):
        assert type(tr.params["wheelbase"]) is float and tr.params["wheelbase"] == 0.6
        assert type(tr.params["accel_detrend"]) is float and tr.params["accel_detrend"] == 0.5
