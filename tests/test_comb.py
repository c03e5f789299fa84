"""The comb check (signal.comb): the wheel speed beats half and twice it for every comb shape
of the randomised family (the decaying harmonic weights), and the per-candidate vote."""

import numpy as np
import pytest

from vibrospeed.signal import comb as cb
from vibrospeed.sim.family import COMB_SHAPES


@pytest.mark.parametrize("shape", sorted(COMB_SHAPES))
def test_comb_finds_the_wheel_not_half_or_twice_it(shape):
    rng = np.random.default_rng(0)
    dt, w = 0.01, 14.0
    t = np.arange(1200) * dt
    x = sum(a * np.cos((m + 1) * w * t + rng.uniform(0, 6)) for m, a in
            enumerate(COMB_SHAPES[shape])) + 0.05 * rng.normal(size=t.size)
    ref, _, score = cb.comb_fixes(x, dt, (2 * np.pi, 60.0))
    got = ref[np.isfinite(ref)]
    assert got.size > 10
    assert np.all(np.abs(got - w) <= 0.05 * w)


def test_comb_vote_counts_steady_disagreeing_candidates():
    cv = np.array([0.0, np.nan])
    assert cb.comb_vote(cv, 20.0, 10.0, 0.1, 2, True) == (False, False)  # first: not steady
    assert cb.comb_vote(cv, 20.2, 10.0, 0.1, 2, True) == (True, False)
    assert cb.comb_vote(cv, 20.1, 10.0, 0.1, 2, True) == (True, True)  # 2nd in a row: reset
    assert cv[0] == 0.0
    assert cb.comb_vote(cv, 20.0, 19.0, 0.1, 2, True) == (True, False)  # agrees with omega
    assert cb.comb_vote(cv, 20.0, 10.0, 0.1, 2, False) == (True, False)  # not allowed
