"""Streaming detectors of the inertial-aided tracker (thesis 3.1, 3.3, 4.2.3; METHODS.md 2).

Three detectors, each with a small immutable state, ``init``/``step`` for online use and a batch
function giving the same numbers (the batch function loops over the same compiled core):

* :func:`window_step` / :func:`window_test` -- the thesis' standstill test (3.1, eq. 3.1-3.3):
  over the last ``N`` samples of the pre-filtered vibration signal, mean ``ybar``, ``ymin``,
  ``ymax``; standstill when ``ymax < ybar + mu and ymin > ybar - mu`` (N = 20, mu = 0.019 m/s^2).
* :func:`cusum_step` / :func:`cusum` -- the CUSUM test of thesis eq. 4.1::

      g_0 = 0,   g_t = max(0, g_{t-1} + eps_t - nu),   if g_t > h: alarm and g_t = 0

  with O(1) memory (``g`` and a counter). :func:`standstill_eps` turns an EKF residual into the
  ``eps_t`` of a *quiet-residual* (standstill) test, see its docstring.
* :func:`mode_step` / :func:`accel_mode` -- the mode / change detector (3.3, eq. 3.14):
  ``ubar`` = mean of the last 20 longitudinal accelerations; acceleration mode when
  ``|ubar| >= mu_vib`` (0.20 m/s^2); ``boost`` marks the sample where the mode switches on.

Conventions: a NaN sample leaves the state unchanged and repeats the previous decision. Until
``N`` finite samples have been seen, the window test and the mode detector answer False.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import ParameterError

#: thesis values (3.1, 3.3): windows of 20 samples at the thesis' 100 Hz
WINDOW_N = 20
WINDOW_MU = 0.019  # m/s^2
MODE_N = 20
MODE_MU = 0.20  # m/s^2
#: s, the thesis windows in time (20 samples at 100 Hz): the estimators' defaults, so a log at
#: 400 Hz looks at the same 0.2 s and not at 0.05 s (in which a slow wheel's vibration is flat
#: and reads as standstill)
WINDOW_S = 0.2
MODE_S = 0.2


def window_samples(n: int | None, seconds: float, dt: float) -> int:
    """Window length in samples: ``n`` if given, else ``seconds`` at sample period ``dt``
    (at least 2)."""
    if n is not None:
        return int(n)
    return max(2, int(round(seconds / dt)))


# ---------------------------------------------------------------------------------------------
# compiled cores (shared with the aided estimator's kernel)
# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _ring_push(buf, pos_count, x):
    """Push ``x`` into ring ``buf``; ``pos_count`` = int64 [next position, samples seen]."""
    n = buf.size
    buf[pos_count[0]] = x
    pos_count[0] = (pos_count[0] + 1) % n
    if pos_count[1] < n:
        pos_count[1] += 1


@njit(cache=True)
def _window_core(buf, pc, flag, x, mu):
    """One window-test step in place; returns the decision. ``flag`` (1,) previous decision."""
    if not np.isfinite(x):
        return flag[0]
    _ring_push(buf, pc, x)
    n = buf.size
    if pc[1] < n:
        flag[0] = False
        return False
    s = 0.0
    lo = buf[0]
    hi = buf[0]
    for i in range(n):
        v = buf[i]
        s += v
        if v < lo:
            lo = v
        if v > hi:
            hi = v
    mean = s / n
    d = (hi < mean + mu) and (lo > mean - mu)
    flag[0] = d
    return d


@njit(cache=True)
def _cusum_core(g_cnt, eps, nu, h):
    """One CUSUM step in place on ``g_cnt`` = [g, samples since the last alarm]; -> alarm."""
    if not np.isfinite(eps):
        g_cnt[1] += 1.0
        return False
    g = g_cnt[0] + eps - nu
    if g < 0.0:
        g = 0.0
    if g > h:
        g_cnt[0] = 0.0
        g_cnt[1] = 0.0
        return True
    g_cnt[0] = g
    g_cnt[1] += 1.0
    return False


@njit(cache=True)
def _mode_core(buf, pc, flag, u, mu):
    """One mode-detector step in place -> (accelerating, boost, ubar). ``flag`` (1,) previous."""
    prev = flag[0]
    if not np.isfinite(u):
        return prev, False, np.nan
    _ring_push(buf, pc, u)
    n = buf.size
    if pc[1] < n:
        flag[0] = False
        return False, False, np.nan
    s = 0.0
    for i in range(n):
        s += buf[i]
    ubar = s / n
    acc = abs(ubar) >= mu
    flag[0] = acc
    return acc, acc and not prev, ubar


# ---------------------------------------------------------------------------------------------
# window standstill test (thesis 3.1)
# ---------------------------------------------------------------------------------------------
class WindowState(NamedTuple):
    """Ring buffer ``buf`` (N,), ``pos_count`` int64 [next slot, samples seen], ``flag`` (1,)."""

    buf: np.ndarray
    pos_count: np.ndarray
    flag: np.ndarray


def _check_window(n: int, mu: float, what: str) -> None:
    if int(n) != n or n < 1:
        raise ParameterError(f"{what}: window length N must be a positive integer, got {n}")
    if not mu > 0:
        raise ParameterError(f"{what}: threshold mu must be > 0, got {mu}")


def window_init(n: int = WINDOW_N) -> WindowState:
    """Empty window-test state for a window of ``n`` samples."""
    _check_window(n, 1.0, "window test")
    return WindowState(np.zeros(int(n)), np.zeros(2, np.int64), np.zeros(1, np.bool_))


def window_step(state: WindowState, y: float, mu: float = WINDOW_MU) -> tuple[WindowState, bool]:
    """Push pre-filtered sample ``y`` (m/s^2); standstill if thesis eq. 3.3 holds on the window."""
    _check_window(state.buf.size, mu, "window test")
    st = WindowState(state.buf.copy(), state.pos_count.copy(), state.flag.copy())
    d = _window_core(st.buf, st.pos_count, st.flag, float(y), float(mu))
    return st, bool(d)


@njit(cache=True)
def _window_run(y, buf, pc, flag, mu):
    out = np.empty(y.size, np.bool_)
    for k in range(y.size):
        out[k] = _window_core(buf, pc, flag, y[k], mu)
    return out


def window_test(
    y: np.ndarray, n: int = WINDOW_N, mu: float = WINDOW_MU, state: WindowState | None = None
) -> np.ndarray:
    """Standstill decisions (bool (n,)) of the window test; equals repeated :func:`window_step`.

    Parameters
    ----------
    y : pre-filtered vibration signal in m/s^2 (thesis: lateral axis after the pre-filter).
    n : window length N (thesis: 20 samples at 100 Hz).
    mu : threshold mu_ss in m/s^2 (thesis: 0.019).
    """
    _check_window(n, mu, "window test")
    st = window_init(n) if state is None else state
    return _window_run(np.ascontiguousarray(y, dtype=np.float64), st.buf.copy(),
                       st.pos_count.copy(), st.flag.copy(), float(mu))


# ---------------------------------------------------------------------------------------------
# CUSUM (thesis eq. 4.1)
# ---------------------------------------------------------------------------------------------
class CusumState(NamedTuple):
    """``g`` (test statistic) and ``since`` (samples since the last alarm; inf before any)."""

    g: float
    since: float


def cusum_init() -> CusumState:
    """``g_0 = 0``; no alarm yet."""
    return CusumState(0.0, np.inf)


def cusum_step(state: CusumState, eps: float, nu: float, h: float) -> tuple[CusumState, bool]:
    """``g = max(0, g + eps - nu)``; alarm (and ``g = 0``) when ``g > h`` (thesis eq. 4.1).

    A NaN ``eps`` leaves ``g`` unchanged (no information) and gives no alarm.
    """
    gc = np.array([state.g, state.since])
    a = _cusum_core(gc, float(eps), float(nu), float(h))
    return CusumState(float(gc[0]), float(gc[1])), bool(a)


@njit(cache=True)
def _cusum_run(eps, gc, nu, h):
    alarms = np.empty(eps.size, np.bool_)
    g = np.empty(eps.size)
    for k in range(eps.size):
        alarms[k] = _cusum_core(gc, eps[k], nu, h)
        g[k] = gc[0]
    return alarms, g


class CusumResult(NamedTuple):
    """Batch CUSUM: ``alarm`` (n,) bool, ``g`` (n,) statistic after each step, ``final``."""

    alarm: np.ndarray
    g: np.ndarray
    final: CusumState


def cusum(eps: np.ndarray, nu: float, h: float, state: CusumState | None = None) -> CusumResult:
    """Run the CUSUM test of thesis eq. 4.1 over ``eps``; equals repeated :func:`cusum_step`."""
    if not h > 0:
        raise ParameterError(f"CUSUM: threshold h must be > 0, got {h}")
    st = cusum_init() if state is None else state
    gc = np.array([st.g, st.since])
    alarm, g = _cusum_run(np.ascontiguousarray(eps, dtype=np.float64), gc, float(nu), float(h))
    return CusumResult(alarm, g, CusumState(float(gc[0]), float(gc[1])))


@njit(cache=True)
def _standstill_eps(residual, sigma_ss):
    r = residual / sigma_ss
    return 1.0 - r * r


def standstill_eps(residual: np.ndarray | float, sigma_ss: float) -> np.ndarray | float:
    """``eps_t = 1 - (e_t / sigma_ss)^2`` from EKF residuals ``e_t`` (m/s^2).

    At standstill the wheel harmonics and road noise vanish and the residual shrinks to the
    sensor noise; with ``sigma_ss`` between the two levels ``eps`` is close to 1 when quiet and
    negative when moving, so :func:`cusum` with drift ``0 < nu < 1`` alarms after at least
    ``h / (1 - nu)`` quiet samples. (Thesis 4.2.3 leaves the residual's use open; this is the
    choice made here: a one-sided CUSUM for a drop of the residual power.)
    """
    if not sigma_ss > 0:
        raise ParameterError(f"standstill CUSUM: sigma_ss must be > 0, got {sigma_ss}")
    return _standstill_eps(np.asarray(residual, dtype=np.float64), float(sigma_ss))


def cusum_hold(h: float, nu: float) -> int:
    """Samples a standstill flag is held after an alarm: twice the shortest alarm interval."""
    return int(np.ceil(2.0 * h / max(1.0 - nu, 1e-6))) + 1


# ---------------------------------------------------------------------------------------------
# acceleration-mode detector (thesis 3.3)
# ---------------------------------------------------------------------------------------------
class ModeState(NamedTuple):
    """Ring buffer ``buf`` (N,) of recent a_x, ``pos_count`` [next slot, seen], ``flag`` (1,)."""

    buf: np.ndarray
    pos_count: np.ndarray
    flag: np.ndarray


class ModeDecision(NamedTuple):
    """``accelerating`` (|ubar| >= mu_vib), ``boost`` (just switched on), ``ubar`` m/s^2."""

    accelerating: bool
    boost: bool
    ubar: float


def mode_init(n: int = MODE_N) -> ModeState:
    """Empty mode-detector state for a window of ``n`` samples."""
    _check_window(n, 1.0, "mode detector")
    return ModeState(np.zeros(int(n)), np.zeros(2, np.int64), np.zeros(1, np.bool_))


def mode_step(state: ModeState, u: float, mu: float = MODE_MU) -> tuple[ModeState, ModeDecision]:
    """Push longitudinal acceleration ``u`` (m/s^2); decide mode (thesis eq. 3.14, boost 3.15)."""
    _check_window(state.buf.size, mu, "mode detector")
    st = ModeState(state.buf.copy(), state.pos_count.copy(), state.flag.copy())
    a, b, ub = _mode_core(st.buf, st.pos_count, st.flag, float(u), float(mu))
    return st, ModeDecision(bool(a), bool(b), float(ub))


@njit(cache=True)
def _mode_run(u, buf, pc, flag, mu):
    n = u.size
    acc = np.empty(n, np.bool_)
    boost = np.empty(n, np.bool_)
    ubar = np.empty(n)
    for k in range(n):
        a, b, ub = _mode_core(buf, pc, flag, u[k], mu)
        acc[k] = a
        boost[k] = b
        ubar[k] = ub
    return acc, boost, ubar


class ModeResult(NamedTuple):
    """Batch mode detector: ``accelerating``, ``boost`` (n,) bool; ``ubar`` (n,) m/s^2."""

    accelerating: np.ndarray
    boost: np.ndarray
    ubar: np.ndarray


def accel_mode(
    u: np.ndarray, n: int = MODE_N, mu: float = MODE_MU, state: ModeState | None = None
) -> ModeResult:
    """Mode decisions over a whole a_x signal; equals repeated :func:`mode_step`."""
    _check_window(n, mu, "mode detector")
    st = mode_init(n) if state is None else state
    a, b, ub = _mode_run(np.ascontiguousarray(u, dtype=np.float64), st.buf.copy(),
                         st.pos_count.copy(), st.flag.copy(), float(mu))
    return ModeResult(a, b, ub)
