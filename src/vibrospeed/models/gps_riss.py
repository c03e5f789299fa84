"""GPS/RISS speed model: accelerometer integrator plus a second-order GPS lag (METHODS.md section 3;
O'Kane & Ringwood, "Vehicle speed estimation using GPS/RISS", section IV, eq. 1-9).

State ``X = [x1, x2, x3, x4]`` = [vehicle speed (m/s), vehicle acceleration (m/s^2), speed as
reported by the GPS receiver (m/s), its derivative (m/s^2)]. Continuous time::

    x1' = x2,        x2' = 0 (+ noise)                                  (paper eq. 1)
    [x3, x4]' = A_gps [x3, x4] + B_gps x1                               (paper eq. 2)
    A_gps = [[0, 1], [-1427.2, -114.2]],  B_gps = [0, 1427.2]           (paper eq. 3-4)

The paper's receiver model is overdamped (natural frequency 37.8 rad/s, damping 1.51, poles at
-14.3 and -99.9 rad/s, i.e. about 0.08 s of lag, unity DC gain). Other receivers differ, so the lag
model is a parameter (:class:`GpsLagModel`) and :func:`identify_lag` fits one from data.

Delay. Receivers and logs add a pure delay (time-stamp latency, ~0.46 s on comma2k19) that a
second-order lag represents poorly; ``GpsLagModel.delay`` puts a Pade-approximated delay in front of
the lag (:func:`receiver_matrices`), still a finite linear system discretised exactly.

Discretisation. The paper writes (eq. 7) ``F = [[1, T, 0, 0], [0, 1, 0, 0], [G1, 0, F11, F12],
[G2, 0, F21, F22]]`` with ``[F11..F22], [G1, G2]`` the zero-order-hold discretisation of
``(A_gps, B_gps)``, i.e. x1 held constant over a step although x1 itself ramps with x2. We use the
exact discretisation of the whole 4-state system instead, ``F = expm(A_c T)`` of the 4x4 continuous
matrix (which is the augmented matrix ``[[A_gps, B_gps, 0], [0, 0, 1], [0, 0, 0]]`` of the lag model
driven by a ramp): its x1 column and lower-right block equal the paper's ZOH terms exactly; it only
adds the ramp term ``F[2:, 1] = O(T^2)`` that the paper drops (negligible at 400 Hz, not at 1 Hz).
:func:`discretise` (scipy) and :func:`transition` (numba, any step length, used by the filters
for irregular sampling) compute the same matrix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from vibrospeed.errors import InputError, ParameterError

#: Paper eq. 3-4 (their 12.5 Hz receiver, identified with Matlab's System Identification Toolbox).
PAPER_A_GPS = ((0.0, 1.0), (-1427.2, -114.2))
PAPER_B_GPS = (0.0, 1427.2)



@dataclass(frozen=True)
class GpsLagModel:
    """Continuous model of the GPS receiver's speed output driven by the true speed: a pure delay
    followed by the paper's second-order lag.

    Parameters
    ----------
    a : A_gps row-major ``(a11, a12, a21, a22)``, 1/s and 1/s^2; must be stable (trace < 0,
        det > 0). Paper eq. 3: ``(0, 1, -1427.2, -114.2)``.
    b : B_gps ``(b1, b2)``; paper eq. 4: ``(0, 1427.2)`` (unity DC gain).
    delay : pure delay tau (s) before the lag (time-stamp latency; not in the paper), represented
        by a Pade approximant ``e^{-s tau} ~ N(s) / D(s)`` of order ``pade`` (1 or 2) so that the
        model stays a finite linear system (:func:`receiver_matrices`). 0 = the paper's model.
    """

    a: tuple[float, float, float, float] = (0.0, 1.0, -1427.2, -114.2)
    b: tuple[float, float] = (0.0, 1427.2)
    delay: float = 0.0
    pade: int = 2

    def __post_init__(self) -> None:
        if len(self.a) != 4 or len(self.b) != 2:
            raise ParameterError("GPS lag model: a needs 4 values (row-major 2x2), b needs 2")
        A = self.A
        if not np.all(np.isfinite(A)) or not np.all(np.isfinite(self.B)):
            raise ParameterError("GPS lag model: a and b must be finite")
        if not (np.trace(A) < 0 and np.linalg.det(A) > 0):
            raise ParameterError(
                f"GPS lag model must be stable (trace < 0, det > 0), got a={self.a}"
            )
        if not (math.isfinite(self.delay) and 0.0 <= self.delay <= 10.0):
            raise ParameterError(f"GPS delay must be in 0..10 s, got {self.delay}")
        if self.pade not in (1, 2):
            raise ParameterError(f"GPS delay Pade order must be 1 or 2, got {self.pade}")

    @classmethod
    def paper(cls) -> GpsLagModel:
        """The paper's receiver, eq. 3-4."""
        return cls()

    @classmethod
    def from_wn_zeta(cls, wn: float, zeta: float, gain: float = 1.0, delay: float = 0.0,
                     pade: int = 2) -> GpsLagModel:
        """``x3'' + 2 zeta wn x3' + wn^2 x3 = gain wn^2 u`` (companion form like the paper's),
        ``u(t) = x1(t - delay)``.

        ``zeta < 1`` gives a receiver that overshoots after a speed step, ``zeta >= 1`` a pure lag.
        """
        if not (wn > 0 and zeta > 0):
            raise ParameterError(f"GPS lag model needs wn > 0 and zeta > 0, got {wn}, {zeta}")
        return cls(a=(0.0, 1.0, -wn * wn, -2.0 * zeta * wn), b=(0.0, gain * wn * wn),
                   delay=float(delay), pade=pade)

    @property
    def A(self) -> np.ndarray:
        """(2, 2) A_gps."""
        return np.array(self.a, dtype=np.float64).reshape(2, 2)

    @property
    def B(self) -> np.ndarray:
        """(2,) B_gps."""
        return np.array(self.b, dtype=np.float64)

    @property
    def wn(self) -> float:
        """Natural frequency sqrt(det A) in rad/s."""
        return float(math.sqrt(np.linalg.det(self.A)))

    @property
    def zeta(self) -> float:
        """Damping ratio -trace(A) / (2 wn)."""
        return float(-np.trace(self.A) / (2.0 * self.wn))

    @property
    def dc_gain(self) -> float:
        """Steady-state x3 / x1 = -(A^-1 B)[0]."""
        return float(-np.linalg.solve(self.A, self.B)[0])

    @property
    def lag(self) -> float:
        """Steady ramp-following lag in s (time by which x3 trails a ramp of x1, unity gain):
        ``c1 / c0 + delay`` for ``x3'' + c1 x3' + c0 x3 = c0 u`` (the Pade forms are exact here)."""
        return float(-np.trace(self.A) / np.linalg.det(self.A)) + self.delay

    @property
    def n_states(self) -> int:
        """Receiver states: 2 (x3, x4) plus ``pade`` delay states when ``delay > 0``."""
        return 2 + (self.pade if self.delay > 0 else 0)

    def as_array(self) -> np.ndarray:
        """(6,) ``[a11, a12, a21, a22, b1, b2]`` (the second-order part only)."""
        return np.array([*self.a, *self.b], dtype=np.float64)


def receiver_matrices(lag: GpsLagModel) -> tuple[np.ndarray, np.ndarray]:
    """``(Ar, Br)`` of the receiver chain ``r' = Ar r + Br x1`` with ``r = [x3, x4, d...]``;
    the reported speed is ``r[0] = x3``.

    Delay states (Pade, tau = ``lag.delay``): order 1 ``e^{-s tau} ~ (1 - s tau/2)/(1 + s tau/2)``:
    ``d' = (2/tau)(x1 - d)``, ``u = 2 d - x1``; order 2 ``(1 - s tau/2 + (s tau)^2/12) /
    (1 + s tau/2 + (s tau)^2/12) = 1 - (12/tau) s / (s^2 + 6 s/tau + 12/tau^2)``:
    ``d1' = d2``, ``d2' = -12/tau^2 d1 - 6/tau d2 + x1``, ``u = x1 - (12/tau) d2``. The lag block is
    driven by u: ``[x3, x4]' = A_gps [x3, x4] + B_gps u`` (paper eq. 2).
    """
    m = lag.n_states
    Ar = np.zeros((m, m))
    Br = np.zeros(m)
    Ar[:2, :2] = lag.A
    B = lag.B
    tau = lag.delay
    if m == 2:
        Br[:2] = B
    elif lag.pade == 1:
        Br[:2] = -B
        Ar[:2, 2] = 2.0 * B
        Ar[2, 2] = -2.0 / tau
        Br[2] = 2.0 / tau
    else:
        Br[:2] = B
        Ar[:2, 3] = -(12.0 / tau) * B
        Ar[2, 3] = 1.0
        Ar[3, 2] = -12.0 / tau**2
        Ar[3, 3] = -6.0 / tau
        Br[3] = 1.0
    return Ar, Br


def receiver_steady_state(lag: GpsLagModel, v: float) -> np.ndarray:
    """(m,) receiver states at constant true speed ``v``: ``r = -Ar^-1 Br v``."""
    Ar, Br = receiver_matrices(lag)
    return -np.linalg.solve(Ar, Br) * v


def continuous_matrix(lag: GpsLagModel, *, offset_state: bool = False) -> np.ndarray:
    """Continuous system matrix ``A_c`` of ``X = [x1, x2, (b), x3, x4, d...]`` (paper eq. 1-2;
    with ``offset_state`` an accelerometer offset ``b' = 0`` is inserted as the third state).
    Without delay and offset this is the paper's (4, 4) matrix."""
    Ar, Br = receiver_matrices(lag)
    k = 3 if offset_state else 2
    n = k + Ar.shape[0]
    Ac = np.zeros((n, n))
    Ac[0, 1] = 1.0
    Ac[k:, k:] = Ar
    Ac[k:, 0] = Br
    return Ac


def discretise(lag: GpsLagModel, T: float, *, offset_state: bool = False) -> np.ndarray:
    """Exact transition ``F = expm(A_c T)`` (scipy); see the module notes on eq. 7.

    Examples
    --------
    >>> F = discretise(GpsLagModel.paper(), 1 / 400)
    >>> bool(np.allclose(F[:2], [[1, 1 / 400, 0, 0], [0, 1, 0, 0]]))
    True
    """
    from scipy.linalg import expm  # here: the compiled filters use expm_small, not scipy

    if not T > 0:
        raise ParameterError(f"sample period must be > 0, got {T}")
    return expm(continuous_matrix(lag, offset_state=offset_state) * T)


@njit(cache=True)
def expm_small(M):
    """expm of a small square matrix: scaling and squaring with a degree-18 Taylor series."""
    n = M.shape[0]
    norm = 0.0
    for i in range(n):
        s = 0.0
        for j in range(n):
            s += abs(M[i, j])
        norm = max(norm, s)
    k = 0
    while norm > 0.25:
        norm *= 0.5
        k += 1
    Ms = M / (2.0**k)
    E = np.eye(n)
    term = np.eye(n)
    for p in range(1, 19):
        term = term @ Ms / p
        E = E + term
    for _ in range(k):
        E = E @ E
    return E


@njit(cache=True)
def transition(Ac, dt):
    """``expm(Ac dt)`` (compiled, any dt >= 0) for a continuous matrix from
    :func:`continuous_matrix`."""
    return expm_small(Ac * dt)


def simulate_receiver(t: np.ndarray, speed: np.ndarray, lag: GpsLagModel, *,
                      exact_delay: bool = False) -> np.ndarray:
    """Speed the receiver model reports, x3, for a true speed ``speed`` sampled at ``t``.

    The true speed is taken piecewise linear between samples (exact: the ramp term of ``F``), and
    the receiver starts in steady state at ``speed[0]``. With ``exact_delay`` the delay is applied
    exactly (the lag output is read ``delay`` s earlier, ``speed[0]`` before the start) instead of
    through the model's Pade states.

    Parameters
    ----------
    t : (n,) s, strictly increasing.  speed : (n,) m/s, finite.

    Returns
    -------
    (n,) m/s receiver output x3 at each ``t``.
    """
    t = np.asarray(t, dtype=np.float64)
    v = np.asarray(speed, dtype=np.float64)
    if t.shape != v.shape or t.ndim != 1 or t.size < 1:
        raise InputError("simulate_receiver: t and speed must be 1-D of equal length")
    if not np.all(np.isfinite(v)):
        raise InputError("simulate_receiver: speed must be finite")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        raise InputError("simulate_receiver: t must be strictly increasing")
    if exact_delay and lag.delay > 0:
        nodelay = GpsLagModel(a=lag.a, b=lag.b)
        x3 = simulate_receiver(t, v, nodelay)
        return np.interp(t - lag.delay, t, x3, left=x3[0])
    Ac = continuous_matrix(lag)
    r0 = receiver_steady_state(lag, v[0])
    return _simulate_receiver(t, v, Ac, r0)


@njit(cache=True)
def _simulate_receiver(t, v, Ac, r0):
    n = t.size
    m = r0.size
    out = np.empty(n)
    r = r0.copy()
    out[0] = r[0]
    last_dt = -1.0
    F = np.eye(m + 2)
    for k in range(n - 1):
        dt = t[k + 1] - t[k]
        if dt != last_dt:
            F = transition(Ac, dt)
            last_dt = dt
        slope = (v[k + 1] - v[k]) / dt
        rn = F[2:, 0] * v[k] + F[2:, 1] * slope + np.ascontiguousarray(F[2:, 2:]) @ r
        r = rn
        out[k + 1] = r[0]
    return out
