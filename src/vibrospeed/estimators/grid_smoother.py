"""Old import path of :mod:`vibrospeed.estimators.grid.smoother`."""

from vibrospeed.estimators.grid.smoother import (  # noqa: F401
    Path,
    Smoothed,
    filtered,
    fixed_lag,
    smooth,
    viterbi,
)
