"""The grid tracker's posterior kept at chosen samples only (``return_posterior`` = indices):
the same rows as the whole posterior at those samples, for the causal filter, the smoothers
and the chunked run; fuse reads it at its fusion samples with the same numbers."""

import numpy as np
import pytest

from vibrospeed import sim
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import fuse, grid
from vibrospeed.estimators.grid.filter import posterior_slots


@pytest.fixture(scope="module")
def drive():
    return sim.simulate("car", seed=2, duration=12.0)


@pytest.mark.parametrize("smooth", ["none", "fb", "lag"])
def test_rows_at_indices_equal_the_whole_posterior(drive, smooth):
    params = {"smooth": smooth}
    whole = grid.estimate(drive, params=params, return_posterior=True)
    idx = np.array([0, 3, 250, 251, 999, len(drive) - 1])
    some = grid.estimate(drive, params=params, return_posterior=idx)
    np.testing.assert_array_equal(some.extras["posterior_index"], idx)
    np.testing.assert_array_equal(some.extras["posterior"], whole.extras["posterior"][idx])
    np.testing.assert_array_equal(some.omega, whole.omega)  # nothing else changes


def test_chunked_run_keeps_the_same_rows(drive):
    idx = np.arange(5, len(drive), 97)
    whole = grid.estimate(drive, params={"smooth": "none"}, return_posterior=True)
    some = grid.estimate(drive, params={"smooth": "none"}, return_posterior=idx, progress=True)
    np.testing.assert_array_equal(some.extras["posterior"], whole.extras["posterior"][idx])


def test_slots():
    np.testing.assert_array_equal(posterior_slots(4, True), [0, 1, 2, 3])
    assert posterior_slots(4, False).size == 0
    np.testing.assert_array_equal(posterior_slots(5, np.array([1, 4])), [-1, 0, -1, -1, 1])
    np.testing.assert_array_equal(posterior_slots(3, np.zeros(0, np.int64)), [-1, -1, -1])
    for bad in (np.array([2, 1]), np.array([0, 5]), np.array([-1]), np.array([0.5])):
        with pytest.raises(ParameterError):
            posterior_slots(5, bad)


def test_fuse_online_reads_the_posterior_at_its_fusion_samples(drive):
    """Online fuse (posterior reading) with the tracker's posterior kept at the fusion samples
    gives the numbers it gives with the whole posterior of the same track."""
    r = drive.wheel_radius
    got = fuse.estimate(drive, wheel_radius=r, params={"online": True})
    vib = grid.estimate(drive, params={**fuse.TRACKER_DEFAULTS, "smooth": "none"},
                        return_posterior=True)
    ref = fuse.estimate(drive, wheel_radius=r, params={"online": True}, vibration=vib)
    np.testing.assert_array_equal(got.speed, ref.speed)
