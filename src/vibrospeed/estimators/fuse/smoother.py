"""Rauch-Tung-Striebel smoother over a forward run of the fusion filter
(:func:`vibrospeed.estimators.fuse.filter.run` keeps its predictions, posteriors and steps):
the offline estimate given the whole log."""

from __future__ import annotations

import numpy as np
from numba import njit

from vibrospeed.estimators.fuse.config import IV, Config
from vibrospeed.estimators.fuse.filter import Output
from vibrospeed.models.gps_riss import transition


@njit(cache=True)
def _rts(Ac, xp, Pp, xf, Pf, dts, xs, Ps):
    n = xf.shape[0]
    xs[n - 1] = xf[n - 1]
    Ps[n - 1] = Pf[n - 1]
    last = -1.0
    F = np.eye(xf.shape[1])
    for k in range(n - 2, -1, -1):
        dt = dts[k + 1]
        if dt != last:
            F = transition(Ac, dt) if dt > 0.0 else np.eye(xf.shape[1])
            last = dt
        C = Pf[k] @ F.T @ np.linalg.pinv(Pp[k + 1])
        xs[k] = xf[k] + C @ (xs[k + 1] - xp[k + 1])
        Pk = Pf[k] + C @ (Ps[k + 1] - Pp[k + 1]) @ C.T
        Ps[k] = 0.5 * (Pk + Pk.T)


def smooth(config: Config, out: Output) -> tuple[np.ndarray, np.ndarray]:
    """Rauch-Tung-Striebel smoother over a :func:`run`: ``(xs, Ps)`` (n, m) and (n, m, m), the
    state given the whole log (``C_k = Pf_k F' Pp_{k+1}^-1``,
    ``xs_k = xf_k + C_k (xs_{k+1} - xp_{k+1})``, ``Ps_k = Pf_k + C_k (Ps_{k+1} - Pp_{k+1}) C_k'``).
    With ``config.nonneg`` a smoothed ``v < 0`` is projected onto ``v = 0`` as the filter
    projects its own (package notes, item 5: ``xs_k <- xs_k - Ps_k[:, v] v / Ps_k[v, v]``, Ps
    unchanged): the smoother sums the filter's projected posteriors with their unconstrained
    dynamics, which carry a speed slightly below 0 into a stop.
    """
    Ac, _, _ = config._arrays()
    xs = np.empty_like(out.xf)
    Ps = np.empty_like(out.Pf)
    if out.xf.shape[0]:
        _rts(Ac, out.xp, out.Pp, out.xf, out.Pf, out.dt, xs, Ps)
    if config.nonneg:
        pvv = Ps[:, IV, IV]
        neg = (xs[:, IV] < 0.0) & (pvv > 0.0)
        xs[neg] -= Ps[neg, :, IV] * (xs[neg, IV] / pvv[neg])[:, None]
        xs[neg, IV] = 0.0  # exactly (the line above leaves rounding)
    return xs, Ps

