"""Noise parameters of the RBPMF by maximum marginal likelihood.

The filter's normaliser gives ``log p(y_1..T) = sum_k log p(y_k | y_1..k-1)`` (the predictive
log-likelihood column of :func:`vibrospeed.estimators.rbpmf.run`) for free, as a function of
``theta = (var(v^omega), var(v^alpha), r)``. :func:`fit` maximises it by coordinate search on a
log scale: each parameter in turn is multiplied by ``factor^k``, k in {-2, -1, 1, 2}, the best
kept, the factor square-rooted after a round without improvement, until ``rounds`` rounds or
the factor falls below ``min_factor``. Deterministic, derivative-free, ~4 runs of the filter
per parameter and round (each O(n N B)); a coarse search is all the likelihood surface needs
(it is flat to a few percent in the values: :func:`profile` shows it).

The search stays within ``[start / span, start * span]`` (``span`` 1e4 by default) and
:attr:`FitResult.warnings` says when a value ends at that limit or moved by more than three
decades: on a recording without a steady line (benchmarks/fits/RESULTS.md: the Hungary drives)
q_omega runs
to the limit and r to zero, i.e. the harmonic model does not describe the data, and the fitted
values should not be used as settings.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.estimators.grid.config import Config
from vibrospeed.estimators.grid.filter import run

FIT_NAMES = ("q_omega", "q_amp", "r")


class FitResult(NamedTuple):
    """``config`` with the fitted model; ``values`` name -> fitted value; ``loglik``
    log p(y_1..T) at the optimum (nats); ``start_loglik`` at the start; ``evals`` filter runs;
    ``history`` list of (values dict, loglik) for every evaluation; ``warnings`` one line per
    value at the search limit or moved by more than three decades."""

    config: Config
    values: dict
    loglik: float
    start_loglik: float
    evals: int
    history: list
    warnings: list


def loglik(config: Config, y: np.ndarray, extra=None) -> float:
    """``log p(y_1..T)`` under ``config`` (sum of the filter's predictive log-likelihoods;
    with ``temper`` < 1 or ``extra`` evidence, of the tempered/augmented normalisers)."""
    return float(np.sum(run(config, y, extra=extra).loglik))


def _with(config: Config, values: dict) -> Config:
    return dataclasses.replace(config, model=dataclasses.replace(config.model, **values))


def fit(
    config: Config,
    y: np.ndarray,
    *,
    names: list[str] | tuple[str, ...] = FIT_NAMES,
    factor: float = 4.0,
    min_factor: float = 1.4,
    rounds: int = 4,
    max_seconds: float | None = None,
    extra=None,
    span: float = 1e4,
) -> FitResult:
    """Maximise ``log p(y_1..T)`` over the model parameters ``names`` (coordinate search).

    ``y`` : the pre-filtered, scaled signal the filter sees. ``max_seconds``: use only the
    first that many seconds of ``y`` (faster fits on long logs). ``extra``: extra log-evidence
    as in :func:`vibrospeed.estimators.rbpmf.run` (kept fixed during the fit). ``span``: each
    value stays within ``[start / span, start * span]``.
    """
    names = list(names)
    bad = [n for n in names if n not in FIT_NAMES]
    if bad:
        raise ParameterError(f"fit: unknown parameter(s) {', '.join(bad)} "
                             f"(choose from {', '.join(FIT_NAMES)})")
    y = np.asarray(y, dtype=np.float64)
    if max_seconds is not None:
        y = y[: max(1, int(round(max_seconds / config.model.dt)))]
        if extra is not None:
            keep = np.asarray(extra[0]) < y.size
            extra = (np.asarray(extra[0])[keep], np.asarray(extra[1])[keep])
    vals = {n: float(getattr(config.model, n)) for n in names}
    start_vals = dict(vals)
    cache: dict[tuple, float] = {}
    history: list = []

    def ev(v: dict) -> float:
        key = tuple(round(np.log(v[n]), 9) for n in names)
        if key not in cache:
            ll = loglik(_with(config, v), y, extra)
            cache[key] = ll if np.isfinite(ll) else -np.inf
            history.append((dict(v), cache[key]))
        return cache[key]

    best = ev(vals)
    start = best
    f = factor
    for _ in range(rounds):
        improved = False
        for n in names:
            for k in (-2, -1, 1, 2):
                if n == "q_omega" and vals[n] == 0.0:
                    continue
                trial = dict(vals)
                trial[n] = float(np.clip(vals[n] * f**k, start_vals[n] / span,
                                         start_vals[n] * span))
                if trial[n] == vals[n]:
                    continue
                ll = ev(trial)
                if ll > best + 1e-6:
                    best, cand = ll, trial
                    improved = True
                    vals = cand
        if not improved:
            f = np.sqrt(f)
            if f < min_factor:
                break
    warnings = []
    for n in names:
        v0, v = start_vals[n], vals[n]
        if v0 <= 0:
            continue
        if v >= v0 * span * (1 - 1e-9) or v <= v0 / span * (1 + 1e-9):
            warnings.append(f"{n} = {v:.3g} ended at the search limit ({v / v0:.3g} x the start "
                            f"{v0:.3g}): the harmonic model may not describe these data (no "
                            "steady line?); do not use it as a setting")
        elif abs(np.log10(v / v0)) > 3:
            warnings.append(f"{n} = {v:.3g} moved {abs(np.log10(v / v0)):.1f} decades from "
                            f"{v0:.3g}: check the recording has a steady line")
    return FitResult(_with(config, vals), vals, best, start, len(cache), history, warnings)


def profile(config: Config, y: np.ndarray, name: str,
            values: np.ndarray) -> np.ndarray:
    """``log p(y_1..T)`` for each value of one parameter (others as in ``config``)."""
    return np.array([loglik(_with(config, {name: float(v)}), y) for v in values])
