"""Resampling schemes and the effective-sample-size policy (METHODS.md 1.2; paper III-C).

Every scheme has the signature ``scheme(W, n, rng) -> indices`` with normalised weights ``W``
(K,), the number of draws ``n`` and an explicit :class:`numpy.random.Generator`; it returns
``n`` ancestor indices (int64) whose expected copy counts are ``n * W`` (unbiased).

* :func:`multinomial`: ``n`` independent draws from ``W`` (the paper's choice).
* :func:`systematic`: one uniform ``U``; draws at ``(U + i) / n`` through the CDF (lower
  variance, O(n)).

"When" is separate from "how": :func:`ess` and :func:`resample_if_needed` decide, the schemes
draw. Weights are handled in log space (:func:`normalise_log`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vibrospeed.errors import ParameterError


def normalise_log(logw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(logW, W)`` with ``logsumexp(logW) = 0``; ``-inf`` entries get weight 0.

    Raises :class:`ParameterError` when no weight is finite.
    """
    logw = np.asarray(logw, dtype=np.float64)
    mx = np.max(logw)
    if not np.isfinite(mx):
        raise ParameterError(
            "all log-weights are -inf or NaN: the filter has lost every hypothesis"
        )
    lse = mx + np.log(np.sum(np.exp(logw - mx)))
    lw = logw - lse
    return lw, np.exp(lw)


def ess(logw: np.ndarray) -> float:
    """Effective sample size ``1 / sum W_i^2`` of (unnormalised) log-weights, in [1, K]."""
    _, W = normalise_log(logw)
    return float(1.0 / np.sum(W * W))


def _cdf(W: np.ndarray) -> np.ndarray:
    c = np.cumsum(np.asarray(W, dtype=np.float64))
    c /= c[-1]
    c[-1] = 1.0  # guard the last bin against rounding
    return c


def multinomial(W: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` i.i.d. ancestors with ``P(A = i) = W_i`` (inverse CDF of ``n`` uniforms)."""
    u = rng.random(n)
    return np.searchsorted(_cdf(W), u, side="right").astype(np.int64)


def systematic(W: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Systematic resampling: ancestors at ``(U + i) / n``, ``U ~ U[0, 1)``, i = 0..n-1."""
    u = (rng.random() + np.arange(n)) / n
    return np.searchsorted(_cdf(W), u, side="right").astype(np.int64)


SCHEMES: dict[str, Callable[[np.ndarray, int, np.random.Generator], np.ndarray]] = {
    "multinomial": multinomial,
    "systematic": systematic,
}


def get_scheme(name: str) -> Callable[[np.ndarray, int, np.random.Generator], np.ndarray]:
    """Scheme by name (:data:`SCHEMES`)."""
    try:
        return SCHEMES[name]
    except KeyError:
        raise ParameterError(
            f"unknown resampling scheme '{name}' (choose from: {', '.join(SCHEMES)})"
        ) from None


def resample_if_needed(
    logw: np.ndarray,
    rng: np.random.Generator,
    *,
    scheme: str = "systematic",
    threshold: float = 0.5,
) -> np.ndarray | None:
    """Ancestor indices if ``ESS < threshold * K``, else ``None``.

    ``threshold`` in [0, 1]: 0 never resamples, 1 resamples whenever the weights are not all equal
    (the bootstrap filter resamples at every step with ``threshold > 1``).
    """
    if threshold < 0:
        raise ParameterError(f"ESS threshold must be >= 0, got {threshold}")
    K = np.asarray(logw).size
    _, W = normalise_log(logw)
    e = 1.0 / np.sum(W * W)
    if e < threshold * K:
        return get_scheme(scheme)(W, K, rng)
    return None
