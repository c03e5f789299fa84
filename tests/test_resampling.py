"""Resampling schemes: unbiased copy counts, ESS, policy."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import resampling as rs


@pytest.mark.parametrize("scheme", ["multinomial", "systematic"])
def test_copy_counts_match_weights(scheme):
    rng = np.random.default_rng(0)
    W = rng.dirichlet(np.ones(10))
    n, reps = 500, 400
    counts = np.zeros(10)
    for _ in range(reps):
        counts += np.bincount(rs.get_scheme(scheme)(W, n, rng), minlength=10)
    mean = counts / (reps * n)
    # multinomial: std of the mean share sqrt(W(1-W)/(n reps)); 5 sigma
    assert np.all(np.abs(mean - W) < 5 * np.sqrt(W * (1 - W) / (n * reps)) + 1e-12)


def test_systematic_counts_within_one_of_expectation():
    rng = np.random.default_rng(1)
    W = rng.dirichlet(np.ones(30))
    for _ in range(50):
        c = np.bincount(rs.systematic(W, 100, rng), minlength=30)
        assert np.all(np.abs(c - 100 * W) < 1 + 1e-9)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=1, max_size=40), st.integers(0, 2**31))
def test_indices_in_range_and_zero_weight_never_drawn(logw, seed):
    logw = np.array(logw)
    logw[0] = -np.inf if logw.size > 1 else logw[0]
    lw, W = rs.normalise_log(logw)
    assert np.isclose(W.sum(), 1.0)
    rng = np.random.default_rng(seed)
    for scheme in ("multinomial", "systematic"):
        idx = rs.get_scheme(scheme)(W, 64, rng)
        assert idx.min() >= 0 and idx.max() < W.size
        if W.size > 1:
            assert not np.any(idx == 0)


def test_ess_and_policy():
    assert rs.ess(np.zeros(8)) == pytest.approx(8.0)
    assert rs.ess(np.array([0.0, -np.inf, -np.inf])) == pytest.approx(1.0)
    rng = np.random.default_rng(2)
    assert rs.resample_if_needed(np.zeros(8), rng, threshold=0.5) is None
    idx = rs.resample_if_needed(np.array([0.0, -10, -10, -10]), rng, threshold=0.5)
    assert idx is not None and np.all(idx == 0)
    with pytest.raises(ParameterError, match="unknown resampling scheme"):
        rs.get_scheme("stratified-typo")
    with pytest.raises(ParameterError, match="lost every hypothesis"):
        rs.normalise_log(np.full(3, -np.inf))
