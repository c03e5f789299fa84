"""The grid tracker: a Rao-Blackwellized point-mass filter over an omega grid (paper III-D)
with harmonic-comb evidence and grid smoothers; the default method (``-m grid``).

One concern per module, each importing only the ones above it in this list:

=================  =========================================================================
``kernel``         the omega grid, cell edges and the banded random-walk transition kernel
``config``         the tracker's :class:`~vibrospeed.estimators.grid.config.Config` (model,
                   grid, jumps, "no line" state, tempering, smoothing), the paper's defaults
``summary``        posterior summaries of grid weights (mean, std, band, MAP, mode, masses
                   near MAP/2 ...), one named row layout shared by the filter and the smoother
``core``           the compiled filter iteration and loop (numba)
``filter``         the causal tracker: ``State``, ``init``, ``step``, ``run``
``smoother``       forward-backward and fixed-lag smoothing (checkpointed)
``viterbi``        the MAP path of the smoother's chain (checkpointed)
``fit``            noise parameters by marginal likelihood
``app``            a recording in, a Track out: pre-filter, scaling, fit, filter or smoother
``background``     a spectrum's running-median background and its bias on noise
``comb``           the harmonic-comb evidence of a longer window's whitened spectrum
``frames``         where the comb's frames lie: the whole-log and the streaming walkers
``method``         the grid method (tracker + comb evidence + standstill): its ``Config``,
                   ``State``, ``init``, ``step``, ``run``, ``estimate``
``blocks``         a long log in blocks of bounded memory (the same numbers as one pass)
``lagged``         the fixed-lag smoother on a device, one raw sample at a time
``stream``         blocks streamed from a file as it is read
=================  =========================================================================

This package's namespace is the grid method (:mod:`~vibrospeed.estimators.grid.method`);
:mod:`vibrospeed.estimators.rbpmf` is the paper's filter on the same modules.
"""

from vibrospeed.estimators.grid.comb import running_median
from vibrospeed.estimators.grid.lagged import LaggedTracker
from vibrospeed.estimators.grid.method import (
    AXES_EXPONENT,
    CLAIM_LEVEL,
    GRID_DEFAULTS,
    Config,
    Result,
    State,
    _default_tracker,
    _prepare,
    comb_channels,
    config_for,
    estimate,
    evidence,
    frame_ends_at,
    frame_evidence,
    init,
    q_omega_for,
    run,
    step,
    with_standstill,
)

__all__ = [
    "AXES_EXPONENT",
    "CLAIM_LEVEL",
    "GRID_DEFAULTS",
    "Config",
    "LaggedTracker",
    "Result",
    "State",
    "comb_channels",
    "config_for",
    "estimate",
    "evidence",
    "frame_ends_at",
    "frame_evidence",
    "q_omega_for",
    "init",
    "run",
    "running_median",
    "step",
    "with_standstill",
    "_default_tracker",
    "_prepare",
]
