"""The comb evidence's background as the evidence computes it (:func:`comb._frame_background`:
windows copied from the row's phases, interpolation positions from a table) against
:func:`comb._background` (windows gathered one by one) and a sort per window, bitwise, for
any width, step, order statistic and row length, with and without NaN."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from background_reference import sorted_windows
from vibrospeed.estimators.grid import comb


def _both(row: np.ndarray, width: int, step: int, rank: int, scale: float):
    """(``_frame_background``, ``_background``) of ``row`` with fresh work space each."""
    row = np.ascontiguousarray(row, dtype=np.float64)
    n = row.size
    net = comb.selection_network(width, rank)
    nc = (n + step - 2) // step + 1
    ij, ifr, ifr1 = np.empty(n, np.int64), np.empty(n), np.empty(n)
    comb._interp_tables(n, step, nc, ij, ifr, ifr1)
    fast = np.full(n, -1.0)
    ph = np.full((width, n // step + width + 2), np.nan)  # every read value is written first
    comb._frame_background(row, width, step, rank, scale, net, np.full((width, nc), np.nan),
                           np.empty(width), np.empty(n), ph, ij, ifr, ifr1, fast)
    ref = np.full(n, -2.0)
    comb._background(row, width, step, rank, scale, net, np.empty((width, nc)),
                     np.empty(width), np.empty(n), ref)
    return fast, ref


_values = st.one_of(st.sampled_from([0.0, 1.0, 2.0, 2.5, 1e-300, 7.0]),
                    st.floats(0.0, 1e300, allow_nan=False, allow_infinity=False))


@settings(max_examples=300, deadline=None)
@given(row=hnp.arrays(np.float64, st.integers(2, 160), elements=_values),
       half=st.integers(0, 30), step_div=st.integers(1, 12), q=st.floats(0.0, 1.0))
def test_frame_background_is_the_background_bitwise(row, half, step_div, q):
    width = 2 * half + 1
    step = max(1, width // step_div)  # the evidence's step is width // 8; others as well
    rank = min(width - 1, int(q * width))
    fast, ref = _both(row, width, step, rank, float(np.log(2.0)))
    assert np.array_equal(fast.view(np.uint64), ref.view(np.uint64))
    np.testing.assert_array_equal(_both(row, width, step, rank, 1.0)[0],
                                  sorted_windows(row, width, step, rank))


@pytest.mark.parametrize(("n", "width"), [(1025, 41), (1025, 43), (513, 21), (2049, 83),
                                          (17, 3), (130, 41)])
def test_frame_background_on_spectra(n, width):
    """Spectrum-like rows (exponential powers over a sloping floor, lines, exact ties) at the
    widths the evidence uses (step = width // 8)."""
    rng = np.random.default_rng(n + width)
    row = rng.exponential(size=n) * np.linspace(3.0, 0.2, n)
    row[rng.integers(0, n, 6)] *= 200.0
    row[n // 3 : n // 3 + 12] = 0.5
    step = max(1, width // 8)
    fast, ref = _both(row, width, step, width // 2, float(np.log(2.0)))
    assert np.array_equal(fast.view(np.uint64), ref.view(np.uint64))


def test_frame_background_with_nan_is_the_background():
    row = np.arange(300.0) % 17
    row[[0, 150, 299]] = np.nan
    fast, ref = _both(row, 41, 5, 20, float(np.log(2.0)))
    np.testing.assert_array_equal(np.isnan(fast), np.isnan(ref))
    assert np.array_equal(np.nan_to_num(fast).view(np.uint64), np.nan_to_num(ref).view(np.uint64))
    assert np.isnan(fast[150]) and np.isfinite(fast[40:100]).all()
