"""The paper's Rao-Blackwellized point-mass filter (paper III-D, Algorithm 1; METHODS.md 1.3)
as a method, ``-m rbpmf``: the grid tracker (:mod:`vibrospeed.estimators.grid`) with the
paper's defaults (Table I, pre-filter HP order 2 at 8 Hz), no comb evidence, causal unless
``smooth`` says otherwise. ``improved=true`` switches on the re-acquisition jumps and the "no
line" state (:data:`IMPROVED`).

The filter itself (equations, kernel, error bound) is documented in
:mod:`vibrospeed.estimators.grid.filter` and :mod:`vibrospeed.estimators.grid.kernel`; the
names below are re-exported from there so that ``rbpmf.Config``, ``rbpmf.run`` etc. are the
paper's filter.
"""

from __future__ import annotations

from vibrospeed.config import parse_flag
from vibrospeed.estimators.grid.app import (  # noqa: F401 (the filter's API, re-exported)
    fit_for_track,
    prefilter_note,
    prepare,
    track,
)
from vibrospeed.estimators.grid.config import (  # noqa: F401
    DEFAULT_R,
    IMPROVED,
    IMPROVED_NOISE,
    Config,
    improved,
)
from vibrospeed.estimators.grid.config import paper_model as _paper_model
from vibrospeed.estimators.grid.filter import (  # noqa: F401
    Estimate,
    Result,
    State,
    init,
    run,
    step,
)
from vibrospeed.estimators.grid.kernel import (  # noqa: F401
    Kernel,
    build_kernel,
    cell_edges,
    check_grid_spacing,
    make_grid,
    matched_sigmas,
)
from vibrospeed.estimators.grid.summary import N_OUT_FIXED, _summary  # noqa: F401
from vibrospeed.types import Recording, Track


def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Track omega on accelerometer axis ``axis`` of a uniformly sampled recording.

    The axis is pre-filtered (``prefilter``, paper HP by default), normalised by its running RMS
    (``scaling``) and tracked. ``params`` may set any :class:`Config` or
    :class:`HarmonicModel` field, plus ``improved=true`` (the re-acquisition settings
    :data:`IMPROVED` under any explicit params). ``smooth="fb"`` / ``"lag"`` smooths
    (:mod:`.grid_smoother`), ``fit="q_omega,q_amp,r"`` fits those by marginal likelihood first
    (:mod:`.fit`; values in the Track's params and notes).

    The Track's ``omega`` is the posterior mean (``point="mode"``: the mean of the MAP mode,
    the posterior mean then in extras ``omega_mean``), its band the ``level`` credible interval;
    extras ``omega_mode``, ``p_mode`` and ``multimodal`` (``p_mode < mode_share``) always;
    extras (per sample): ``omega_map`` (filter: MAP; smoother: Viterbi path given a line),
    ``loglik``, ``p_null``, ``p_half``, ``p_double``, ``p_third``, ``p_triple`` (mass near
    MAP/2, 2 MAP, MAP/3, 3 MAP), ``confidence`` (= 1 - p_null), ``has_signal`` (1.0 where
    confidence >= 0.5), ``ambiguous`` (1.0 where any of the four >= 0.05), ``amp1..M`` (in
    signal units), ``rms``. With ``return_posterior`` the extras also
    hold ``posterior`` (n, N) float32 and ``grid`` (N,) (for the posterior image).

    Examples
    --------
    >>> import numpy as np
    >>> from vibrospeed.types import Recording
    >>> t = np.arange(0, 20, 0.01)
    >>> rng = np.random.default_rng(0)
    >>> ay = np.sin(50 * t) + 0.5 * np.sin(100 * t) + 0.3 * rng.normal(size=t.size)
    >>> tr = estimate(Recording(t, {"ay": ay}))
    >>> bool(abs(tr.omega[-1] - 50) < 1)
    True
    """
    config, y, rms, notes = prepare(recording, axis, Config, _with_improved(params),
                                    _paper_model)
    return track(recording, config, y, rms, notes, axis=axis, wheel_radius=wheel_radius,
                 progress=progress, return_posterior=return_posterior, method="rbpmf")


def _with_improved(params: dict | None) -> dict:
    params = dict(params or {})
    if parse_flag(params.pop("improved", False), "improved"):
        params = {**IMPROVED, **params}
    return params


def config_for(recording: Recording, *, axis: str = "y", params: dict | None = None) -> Config:
    """The :class:`Config` that :func:`estimate` builds for ``recording`` and ``params``: hand it
    to :class:`vibrospeed.estimators.online.OnlineTracker` to run the same filter on a device."""
    return prepare(recording, axis, Config, _with_improved(params), _paper_model)[0]


