"""The phone's mount from its own accelerometer: gravity, the vehicle's forward axis, a confidence.

A phone (or a logger) lies in the vehicle at an unknown orientation, so none of its axes is the
longitudinal acceleration ``a_x`` that the inertial aiding integrates. With the three axes
``a`` (n, 3) in the sensor frame (specific force, m/s^2):

1. **gravity** ``g0`` (3,): the mean of ``a`` over the standing samples (the sensor's bias comes
   with it), over all samples when none stands. ``g0 / |g0|`` is the vehicle's up axis as far
   as the road is level; every horizontal acceleration is in the plane orthogonal to it,
   spanned by an orthonormal pair ``e1, e2``.
2. **forward**: the horizontal components ``h = [e1, e2]^T (a - g0)`` and a reference of the
   longitudinal acceleration ``a_ref = r d omega / dt`` (the vibration tracker's wheel speed
   ``omega``, where it claims a line) are both low-passed by the same moving average
   (``SMOOTH_S`` s; body motion, engine and wheel vibration average out, turns and braking
   stay), and the least-squares fit ``h ~ c a_ref`` over the usable samples gives the
   forward direction in the plane, ``c / |c|``, with its sign. Lateral acceleration in turns
   is uncorrelated with ``a_ref`` to first order and only adds noise to the fit.
3. **checks**: the slope ``|c|`` is 1 when the tracker's speed and the wheel radius are right
   (a half-speed lock gives 2); noise in the reference (a tracker's jitter) pulls it towards
   0. The correlation ``rho`` of ``a_ref`` with the projection ``p = (c / |c|)^T h`` says how
   much of the horizontal motion the reference explains, and its significance
   ``t = rho sqrt((n_eff - 2) / (1 - rho^2))`` counts one independent sample per smoothing
   window. The mount is ``confident`` when ``rho >= RHO_MIN``, ``t >= T_MIN``,
   ``SLOPE_RANGE[0] <= |c| <= SLOPE_RANGE[1]`` and at least ``MIN_USED_S`` s were usable.
   Otherwise a caller should not trust the axis (an aided tracker then aids nothing).

:func:`longitudinal` turns a :class:`Mount` into ``a_x(t) = f^T (a(t) - g0)`` (gravity and
bias removed). :func:`estimate` is whole-log (every sample's ``a`` and the whole ``omega``);
:func:`running` is the mount a device knows: re-estimated on the data so far, each sample
projected with the last estimate before it (nothing where none is confident yet).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from vibrospeed.errors import InputError

#: s, moving average applied to the horizontal acceleration and to omega before the fit
SMOOTH_S = 1.0
#: smallest correlation between the reference and the projected horizontal acceleration
RHO_MIN = 0.5
#: smallest significance of that correlation
T_MIN = 5.0
#: accepted range of the fitted slope |c| (1 = the reference's scale). The direction
#: ``c / |c|`` does not depend on the reference's scale, so a tracker that sits on half or a
#: third of the wheel speed for part of the drive still gives the right axis; the range only
#: keeps out fits whose scale is off by more than a harmonic lock explains (thesis cart
#: stop-and-go seeds 1 and 9: slopes 2.5 and 2.1, the axis right to 0.999; measured in
#: benchmarks/robustness/AIDED.md)
SLOPE_RANGE = (1.0 / 3.0, 3.0)
#: s, least time of usable samples
MIN_USED_S = 10.0
#: m/s^2, reference accelerations above this are tracker jumps, not the vehicle's
A_REF_MAX = 5.0


class Mount(NamedTuple):
    """The mount estimate, vectors in the sensor frame: ``gravity`` (3,) m/s^2 (the mean
    specific force at rest, bias included), ``forward`` (3,) unit vector (NaN when no fit),
    ``slope`` |c| (1: the reference's scale), ``rho`` the correlation of the reference with
    the projection, ``used_s`` seconds of samples used, ``t`` the significance of ``rho``,
    ``confident`` whether to trust ``forward``."""

    gravity: np.ndarray
    forward: np.ndarray
    slope: float
    rho: float
    used_s: float
    t: float
    confident: bool


def _centred_sum(x: np.ndarray, k: int) -> np.ndarray:
    """Sum over a centred window of ``k`` samples, as long as ``x`` (numpy's ``"same"``
    convolution is ``k`` long when ``x`` is shorter than the window: a record under
    ``SMOOTH_S`` s)."""
    a = (k - 1) // 2
    return np.convolve(x, np.ones(k), "full")[a:a + x.size]


def _moving_average(x: np.ndarray, k: int) -> np.ndarray:
    """Centred moving average over ``k`` samples along axis 0 (NaN-aware: the mean of the
    finite samples in the window, NaN where none)."""
    if k <= 1:
        return np.asarray(x, dtype=np.float64).copy()
    x = np.asarray(x, dtype=np.float64)
    fin = np.isfinite(x)
    xz = np.where(fin, x, 0.0)
    if x.ndim == 1:
        s = _centred_sum(xz, k)
        c = _centred_sum(fin.astype(np.float64), k)
    else:
        s = np.column_stack([_centred_sum(xz[:, j], k) for j in range(x.shape[1])])
        c = np.column_stack([_centred_sum(fin[:, j].astype(np.float64), k)
                             for j in range(x.shape[1])])
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c > 0, s / np.maximum(c, 1), np.nan)


def plane_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal ``(e1, e2)`` spanning the plane orthogonal to ``up`` (any nonzero (3,)),
    ``e1`` from the sensor axis least aligned with ``up`` (deterministic)."""
    u = np.asarray(up, dtype=np.float64)
    u = u / np.linalg.norm(u)
    ref = np.eye(3)[int(np.argmin(np.abs(u)))]
    e1 = ref - (ref @ u) * u
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(u, e1)


def estimate(acc: np.ndarray, dt: float, *, omega: np.ndarray | None = None,
             wheel_radius: float | None = None, still: np.ndarray | None = None,
             usable: np.ndarray | None = None) -> Mount:
    """Mount of a sensor from its axes ``acc`` (n, 3) in m/s^2 at period ``dt`` s.

    ``omega`` (n,) rad/s and ``wheel_radius`` m: the reference for the forward axis (without
    them only gravity is estimated and the mount is not confident); ``still`` (n,) standstill
    flags (gravity from those samples); ``usable`` (n,) where omega may be trusted (e.g. the
    tracker claims a line), standing samples are never used for the fit.
    """
    a = np.asarray(acc, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"mount.estimate: acc must have shape (n, 3), got {a.shape}")
    n = a.shape[0]
    fin = np.all(np.isfinite(a), axis=1)
    st = np.zeros(n, bool) if still is None else (np.asarray(still) > 0.5)
    sel = st & fin
    if not sel.any():
        sel = fin
    g0 = a[sel].mean(axis=0) if sel.any() else np.full(3, np.nan)
    nan3 = np.full(3, np.nan)
    if omega is None or not wheel_radius or not np.all(np.isfinite(g0)) \
            or np.linalg.norm(g0) == 0:
        return Mount(g0, nan3, np.nan, np.nan, 0.0, np.nan, False)
    om = np.asarray(omega, dtype=np.float64)
    if om.shape != (n,):
        raise InputError(f"mount.estimate: omega has shape {om.shape}, expected ({n},)")
    k = max(1, int(round(SMOOTH_S / dt)))
    e1, e2 = plane_basis(g0)
    d = a - g0
    h = _moving_average(np.column_stack([d @ e1, d @ e2]), k)
    from scipy.ndimage import median_filter

    om_m = median_filter(np.where(np.isfinite(om), om, 0.0), size=2 * k + 1, mode="nearest")
    om_s = _moving_average(np.where(np.isfinite(om), om_m, np.nan), k)
    a_ref = float(wheel_radius) * np.gradient(om_s, dt)
    ok = np.isfinite(a_ref) & np.all(np.isfinite(h), axis=1) & ~st & (np.abs(a_ref) < A_REF_MAX)
    if usable is not None:
        ok &= np.asarray(usable) > 0.5
    used_s = float(ok.sum() * dt)
    if ok.sum() < 3:
        return Mount(g0, nan3, np.nan, np.nan, used_s, np.nan, False)
    ar, hh = a_ref[ok], h[ok]
    den = float(ar @ ar)
    if den == 0.0:
        return Mount(g0, nan3, np.nan, np.nan, used_s, 0.0, False)
    c = (hh.T @ ar) / den
    slope = float(np.hypot(c[0], c[1]))
    if slope == 0.0:
        return Mount(g0, nan3, np.nan, np.nan, used_s, 0.0, False)
    cu = c / slope
    proj = hh @ cu
    sa, sp = float(np.std(ar)), float(np.std(proj))
    rho = float(np.mean((ar - ar.mean()) * (proj - proj.mean())) / (sa * sp)) \
        if sa > 0 and sp > 0 else 0.0
    n_eff = ok.sum() / k  # about one independent sample per smoothing window
    t = rho * np.sqrt(max(n_eff - 2.0, 0.0) / max(1.0 - rho * rho, 1e-12))
    fwd = cu[0] * e1 + cu[1] * e2
    confident = bool(rho >= RHO_MIN and t >= T_MIN and SLOPE_RANGE[0] <= slope <= SLOPE_RANGE[1]
                     and used_s >= MIN_USED_S)
    return Mount(g0, fwd, slope, rho, used_s, float(t), confident)


def longitudinal(acc: np.ndarray, mount: Mount) -> np.ndarray:
    """``a_x = forward^T (a - gravity)`` (n,) in m/s^2: the vehicle's longitudinal acceleration
    with gravity and the sensor's bias removed (NaN where the mount has no forward axis)."""
    a = np.asarray(acc, dtype=np.float64)
    if not np.all(np.isfinite(mount.forward)):
        return np.full(a.shape[0], np.nan)
    return (a - mount.gravity) @ mount.forward


class Running(NamedTuple):
    """The mount as a device would know it (:func:`running`): ``u`` (n,) m/s^2 the longitudinal
    acceleration by the mount known at each sample (NaN where none is confident yet),
    ``confident`` (n,) bool, ``times`` (K,) s after the start at which the mount was
    re-estimated and ``mounts`` the K estimates."""

    u: np.ndarray
    confident: np.ndarray
    times: np.ndarray
    mounts: list


#: s, the causal mount is re-estimated every ``max(RUNNING_HOP_S, RUNNING_HOP_REL * elapsed)``
RUNNING_HOP_S = 1.0
#: share of the elapsed time between re-estimates once that exceeds ``RUNNING_HOP_S``
RUNNING_HOP_REL = 0.02


def running(acc: np.ndarray, dt: float, *, omega: np.ndarray, wheel_radius: float,
            still: np.ndarray | None = None, usable: np.ndarray | None = None) -> Running:
    """The mount from the data so far: :func:`estimate` on the samples ``0..k`` at re-estimate
    times ``k`` (every ``RUNNING_HOP_S`` s, later every ``RUNNING_HOP_REL`` of the elapsed time,
    so the work grows as n log n, not n^2); the samples after ``k`` up to the next re-estimate
    are projected with that estimate where it is confident (NaN otherwise). ``omega``,
    ``still`` and ``usable`` must themselves be causal (a causal tracker's speed, the causal
    standstill detector) for the result to be: each estimate reads only samples up to its
    time (the moving averages at the prefix's end use what is there)."""
    a = np.asarray(acc, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"mount.running: acc must have shape (n, 3), got {a.shape}")
    n = a.shape[0]
    om = np.asarray(omega, dtype=np.float64)
    if om.shape != (n,):
        raise InputError(f"mount.running: omega has shape {om.shape}, expected ({n},)")
    u = np.full(n, np.nan)
    conf = np.zeros(n, bool)
    times, mounts = [], []
    hop = max(1, int(round(RUNNING_HOP_S / dt)))
    k = hop
    while k <= n:
        m = estimate(a[:k], dt, omega=om[:k], wheel_radius=wheel_radius,
                     still=None if still is None else np.asarray(still)[:k],
                     usable=None if usable is None else np.asarray(usable)[:k])
        nxt = min(n, k + max(hop, int(round(RUNNING_HOP_REL * k))))
        if m.confident and nxt > k:
            u[k:nxt] = longitudinal(a[k:nxt], m)
            conf[k:nxt] = True
        times.append(k * dt)
        mounts.append(m)
        if k == n:
            break
        k = nxt
    return Running(u, conf, np.asarray(times), mounts)
