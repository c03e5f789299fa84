"""Reference speed fixes: bump crossings (v = L / dT) and steady turns (v = a_y / yaw rate)."""

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.eval import reference as ref
from vibrospeed.sim.aided import SCENARIOS


@pytest.mark.parametrize("seed", [0, 1])
def test_bump_fixes_within_5_percent(seed):
    rec = SCENARIOS["bumpy_floor"](seed=seed)
    fixes = ref.bump_fixes(rec)
    bumps = np.array(rec.meta["bumps"])
    assert len(fixes) >= len(bumps) - 1 and len(fixes) >= 5
    v_true = np.interp(fixes.t, rec.t, rec["speed_true"])
    np.testing.assert_allclose(fixes.speed, v_true, rtol=0.05)
    # each fix sits between a front and a rear hit of one bump
    j = np.searchsorted(bumps[:, 0], fixes.t) - 1
    assert np.all((fixes.t > bumps[j, 0]) & (fixes.t < bumps[j, 1]))
    assert np.all(fixes.t_detect > fixes.t) and np.all(fixes.speed_std > 0)


@pytest.mark.parametrize("seed", [0, 1])
def test_turn_fixes_within_5_percent(seed):
    rec = SCENARIOS["turns"](seed=seed)
    fixes = ref.turn_fixes(rec)
    assert len(fixes) >= len(rec.meta["turns"])
    v_true = np.interp(fixes.t, rec.t, rec["speed_true"])
    np.testing.assert_allclose(fixes.speed, v_true, rtol=0.05)
    # every fix lies inside a turn
    inside = np.zeros(fixes.t.size, bool)
    for tr in rec.meta["turns"]:
        inside |= (fixes.t > tr["t_start"]) & (fixes.t < tr["t_start"] + tr["duration"])
    assert inside.all()


def test_no_fixes_on_straight_flat_drive():
    rec = SCENARIOS["start_from_rest"](seed=2, duration=40)
    assert len(ref.turn_fixes(rec)) == 0
    assert len(ref.bump_fixes(rec, wheelbase=0.6)) == 0


def test_fixes_to_omega():
    fixes = ref.Fixes(np.array([0.5, 0.5, 2.0]), np.array([1.0, 1.0, 2.5]),
                      np.array([0.8, 1.0, 0.9]), np.array([0.1, 0.1, 0.05]),
                      np.array(["bump", "turn", "bump"]))
    t = np.arange(0, 3, 0.01)
    w, var = ref.fixes_to_omega(fixes, t, 0.08)
    k = np.flatnonzero(np.isfinite(w))
    np.testing.assert_allclose(t[k], [1.0, 2.5])
    # two equal-variance fixes on one sample: the mean, half the variance
    assert w[k[0]] == pytest.approx(0.9 / 0.08)
    assert var[k[0]] == pytest.approx(0.5 * (0.1 / 0.08) ** 2)
    w2, _ = ref.fixes_to_omega(fixes, t, 0.08, causal=False)
    np.testing.assert_allclose(t[np.isfinite(w2)], [0.5, 2.0])


def test_bump_needs_wheelbase():
    rec = SCENARIOS["start_from_rest"](seed=0, duration=10)
    with pytest.raises(ParameterError, match="wheelbase"):
        ref.bump_fixes(rec)
    with pytest.raises(ParameterError):
        ref.detect(rec, "potholes")
