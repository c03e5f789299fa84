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


@njit(cache=True)
def _rts_band(Ac, Pp, Pf, Pbp, Pbf, Js, dts, Pbs):
    n, m = Pf.shape[0], Pf.shape[1]
    Pbs[n - 1] = Pbf[n - 1]
    L = np.eye(m)  # the smoothed error's map of the forward error at k + 1
    H = np.zeros((m, m))  # the covariance of the rest (sources after k + 1)
    last = -1.0
    F = np.eye(m)
    for k in range(n - 2, -1, -1):
        dt = dts[k + 1]
        if dt != last:
            F = transition(Ac, dt) if dt > 0.0 else np.eye(m)
            last = dt
        C = Pf[k] @ F.T @ np.linalg.pinv(Pp[k + 1])
        A = Js[k + 1] @ F  # e_f(k+1) = A e_f(k) + z, z of the sources at k + 1
        Q = Pbp[k + 1] - F @ Pbf[k] @ F.T
        Z = Pbf[k + 1] - A @ Pbf[k] @ A.T
        LJQ = L @ Js[k + 1] @ Q
        H = C @ (H + L @ Z @ L.T - LJQ - LJQ.T + Q) @ C.T
        L = np.eye(m) - C @ F + C @ L @ A
        Pk = L @ Pbf[k] @ L.T + H
        Pbs[k] = 0.5 * (Pk + Pk.T)


def smooth_band(config: Config, out: Output) -> np.ndarray | None:
    """The speed band's covariance given the whole log (n, m, m), for a :func:`run` that kept
    it (``Config.band_psd``; None where it did not): the error covariance of :func:`smooth`'s
    estimate (its gains ``C_k`` from the filter's covariances) where the sources have the
    band's variances. The smoothed error ``e_k = (I - C_k F) f_k - C_k w_{k+1} + C_k e_{k+1}``
    (``f``: the forward error, ``w``: the process noise) is written ``e_k = L_k f_k + eta_k``
    with ``eta_k`` of the sources after ``k`` only: ``L_k = I - C_k F + C_k L_{k+1} A_{k+1}``
    (``A = J F``, ``J`` the sample's updates' ``I - k h``), ``cov(eta_k) = C_k (cov(eta_{k+1})
    + L Z L' - L J Q - Q J' L' + Q) C_k'`` with ``Q = Pbp_{k+1} - F Pbf_k F'`` and
    ``Z = Pbf_{k+1} - A Pbf_k A'``; ``Pbs_k = L_k Pbf_k L_k' + cov(eta_k)``. With the filter's
    own covariances it is the RTS covariance."""
    if out.Pbf is None:
        return None
    Ac, _, _ = config._arrays()
    Pbs = np.empty_like(out.Pbf)
    if out.Pbf.shape[0]:
        _rts_band(Ac, out.Pp, out.Pf, out.Pbp, out.Pbf, out.Jb, out.dt, Pbs)
    return Pbs
