"""The comb background's running median (compiled selection) against numpy's median on the
same windows: bitwise equal, odd and even widths, edges, ties and NaN."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from vibrospeed.estimators.grid.comb import running_median


def _reference(P: np.ndarray, width: int) -> np.ndarray:
    """np.median over "nearest"-extended windows every max(1, width // 8) bins, linearly
    interpolated between (the definition in running_median's docstring)."""
    F, n = P.shape
    h = width // 2
    step = max(1, width // 8)
    Pp = np.concatenate([np.repeat(P[:, :1], h, 1), P, np.repeat(P[:, -1:], h, 1)], axis=1)
    cent = np.minimum(np.arange(0, n + step - 1, step), n - 1)
    med = np.empty((F, cent.size))
    for r in range(F):
        for c, s in enumerate(cent):
            with np.errstate(invalid="ignore"):
                med[r, c] = np.median(Pp[r, s : s + width])
    if step == 1:
        return med
    i = np.arange(n)
    j = np.minimum(i // step, cent.size - 2)
    fr = (i - cent[j]) / np.maximum(cent[j + 1] - cent[j], 1)
    return med[:, j] * (1.0 - fr) + med[:, j + 1] * fr


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


# non-negative values (a power spectrum: no -0.0, whose sign an order statistic may not keep),
# from a small set so that ties are common, or spread widely
_values = st.one_of(st.sampled_from([0.0, 1.0, 2.0, 2.5, 1e-300, 7.0]),
                    st.floats(0.0, 1e300, allow_nan=False, allow_infinity=False))


@settings(max_examples=300, deadline=None)
@given(P=hnp.arrays(np.float64, st.tuples(st.integers(1, 3), st.integers(2, 60)),
                    elements=_values),
       width=st.integers(1, 45))
def test_running_median_bitwise_equals_numpy(P, width):
    assert _same_bits(running_median(P, width), _reference(P, width))


@settings(max_examples=100, deadline=None)
@given(P=hnp.arrays(np.float64, st.tuples(st.integers(1, 2), st.integers(2, 40)),
                    elements=st.one_of(_values, st.just(np.nan))),
       width=st.integers(1, 21))
def test_running_median_nan_as_numpy(P, width):
    got, ref = running_median(P, width), _reference(P, width)
    assert np.array_equal(np.isnan(got), np.isnan(ref))
    assert _same_bits(np.nan_to_num(got), np.nan_to_num(ref))


def test_running_median_known_values():
    # one row 0..9 ("nearest" edges), width 3: the exact filter (width < 16: every bin)
    P = np.arange(10.0)[None]
    assert np.array_equal(running_median(P, 3)[0], np.r_[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0,
                                                       7.0, 8.0, 9.0])
    # an isolated line disappears; a flat background stays
    Q = np.ones((1, 50))
    Q[0, 25] = 1e6
    assert np.array_equal(running_median(Q, 5), np.ones((1, 50)))
    # even width 4 (windows start 2 bins before each bin): the mean of the two middle values,
    # [0, 0, 0, 1] -> 0, [0, 0, 1, 3] -> 0.5, [0, 1, 3, 10] -> 2, [1, 3, 10, 10] -> 6.5
    got = running_median(np.array([[0.0, 1.0, 3.0, 10.0]]), 4)[0]
    assert np.array_equal(got, [0.0, 0.5, 2.0, 6.5])
