"""Old import path of :mod:`vibrospeed.estimators.grid.fit`."""

from vibrospeed.estimators.grid.fit import FIT_NAMES, FitResult, fit, loglik, profile  # noqa: F401
