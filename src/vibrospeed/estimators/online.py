"""Online (device) use: raw accelerometer sample in, omega estimate out.

:class:`OnlineTracker` chains the same stages as ``estimate()`` does in batch: pre-filter
(:mod:`vibrospeed.signal.prefilter`), running-RMS normalisation
(:mod:`vibrospeed.signal.normalize`) and an estimator's ``step``. Feeding a recording sample by
sample gives the numbers of the batch path (tested), so a tracker tuned offline behaves the same
on a device. The object is the only mutable thing here; its ``state`` is a tuple of the stages'
immutable states and can be saved and restored.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np

from vibrospeed.signal import normalize as nz
from vibrospeed.signal import prefilter as pf


class OnlineTracker:
    """Streaming pipeline ``raw sample -> pre-filter -> normalise -> estimator.step``.

    Parameters
    ----------
    estimator : an estimator module with ``init(config)`` and ``step(config, state, y)``
        (e.g. :mod:`vibrospeed.estimators.ekf`).
    config : that estimator's ``Config`` (its model's ``dt`` is the sample period).
    prefilter : pre-filter preset name. normalize_tau : s, 0 or None = off.
    level : resting level of the raw signal (e.g. the mean of a first second buffered on the
        device; :func:`vibrospeed.estimators.common.start_level` computes it as ``estimate()``
        does); None = the first sample.

    Examples
    --------
    >>> from vibrospeed.estimators import ekf
    >>> trk = OnlineTracker(ekf, ekf.Config())
    >>> est = trk.update(0.01)
    """

    def __init__(
        self,
        estimator: ModuleType,
        config: Any,
        *,
        prefilter: str = "thesis-hp",
        normalize_tau: float | None = 5.0,
        level: float | None = None,
    ) -> None:
        self.estimator = estimator
        self.config = config
        dt = config.model.dt
        self.dt = dt
        self.sos = pf.design(prefilter, 1.0 / dt, M=config.model.M)
        self.tau = normalize_tau or None
        self.state = (pf.init(self.sos, level), nz.init(), estimator.init(config))

    def update(self, sample: float) -> Any:
        """Process one raw sample (NaN = missing); returns the estimator's estimate."""
        fs, ns, es = self.state
        fs, y = pf.step(self.sos, fs, float(sample))
        if self.tau:
            ns, y = nz.step(ns, y, self.dt, self.tau)
        es, est = self.estimator.step(self.config, es, y if np.isfinite(y) else np.nan)
        self.state = (fs, ns, es)
        return est
