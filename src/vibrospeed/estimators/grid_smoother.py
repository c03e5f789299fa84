"""Old import path of :mod:`vibrospeed.estimators.grid.smoother` (and its Viterbi path)."""

from vibrospeed.estimators.grid.smoother import (  # noqa: F401
    Smoothed,
    filtered,
    fixed_lag,
    smooth,
)
from vibrospeed.estimators.grid.viterbi import Path, viterbi  # noqa: F401
