"""Algebraic numerical differentiation (Fliess, Join, Mboup, Sira-Ramirez) as FIR kernels.

METHODS.md section 4; seed: algebraic-velocity-estimation-paper, section III (eq. 8-10).

The signal is approximated on a sliding window of length ``T_w`` by a truncated Taylor polynomial
of degree ``N``; the n-th derivative is read from iterated integrals of the signal. Mboup, Join &
Fliess (2009, "Numerical differentiation with annihilators in noisy environment", Numer.
Algorithms 50) showed that every such estimator is a truncated Jacobi expansion: with the
normalised window coordinate ``tau in [0, 1]`` (``tau = 0`` the estimation end) and the weight
``w(tau) = (1 - tau)^kappa * tau^mu`` (``kappa, mu > -1``),

    x^(n)_hat(xi) = T_w^-n * int_0^1 g(tau) x(tau T_w) dtau,
    g(tau) = w(tau) * sum_{k=n..N} p_k(tau) p_k^(n)(xi) / ||p_k||^2,
    p_k(tau) = P_k^(kappa, mu)(2 tau - 1)  (Jacobi),   ||p_k||^2 = int_0^1 w p_k^2,
    p_k^(n)(xi) = Gamma(k + kappa + mu + 1 + n) / Gamma(k + kappa + mu + 1)
                  * P_{k-n}^(kappa + n, mu + n)(2 xi - 1),

i.e. the n-th derivative, at ``xi``, of the degree-N least-squares fit in ``L2(w)``
(:func:`jacobi_kernel`). The paper writes the same family with an order ``nu`` of the
integrating factor ``s^-nu`` (eq. 8); its example N = 1, nu = 2 has no extra multiplicity of
the annihilator, i.e. ``kappa = mu = 0``, and in general we use ``mu = nu - N - 1``,
``kappa = 0`` (:func:`paper_kappa_mu`). The seed's general formula (eq. 10) is garbled in the
text extraction; we re-derived the family from Mboup-Join-Fliess and check that it reproduces
the paper's two closed forms (N = 1, nu = 2, window ``[0, T]``):

    a0_hat = (2 / T^2)  int_0^T (2T - 3 tau) y(tau) dtau          (filtered value)
    a1_hat = -(3! / T^3) int_0^T (T - 2 tau) y(tau) dtau           (first derivative)

Discrete kernels (:func:`fir_kernel`) are computed once: the same weighted least-squares fit on
the ``L`` samples of the window, each sample weighted by the integral of ``w`` over its cell
(a quadrature that stays finite for ``kappa, mu < 0``). The kernel is therefore exact for every
polynomial of degree <= N (to float precision) and tends to ``g`` as ``L`` grows.

Time conventions (cf. scipy ``ShortTimeFFT``)
--------------------------------------------
``causal`` mode: the estimate output at sample ``i`` uses samples ``i-L+1 .. i`` (``tau`` is
the age of a sample divided by ``T_w = (L-1) T``) and estimates ``x^(n)(t_i - xi T_w)``: its
*delay* is ``xi * T_w`` seconds (:attr:`Config.delay`). ``xi = 0`` (the paper's choice) gives no
delay and is exact for degree-N signals only; the point ``xi*`` returned by
:func:`exact_point` makes the estimate exact for degree N+1 as well (for the minimal estimator
N = n, ``xi* = (mu + n + 1) / (kappa + mu + 2n + 2)``, the mean of the weight
``w_{kappa+n, mu+n}``), at the price of the delay ``xi* T_w``.
``centred`` mode (offline): the same kernel with its output moved back by the delay, so the
estimate at sample ``i`` refers to ``t_i``; it needs ``xi (L-1)`` to be an integer (``xi = 1/2``
with ``L`` odd gives a symmetric window, zero phase when ``kappa = mu``).

The streaming state is a ring buffer of the last ``L`` samples, initialised with the first
sample (steady state, like ``sosfilt_zi * x[0]``: a constant start gives no transient).
:func:`run` equals repeated :func:`step` exactly; :func:`apply` computes the same numbers with
``np.convolve`` (equal to float rounding).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy import special

from vibrospeed.errors import ParameterError

MODES = ("causal", "centred")


# -- continuous kernels -----------------------------------------------------------------------
def _check_orders(n: int, N: int, kappa: float, mu: float) -> None:
    if int(n) != n or n < 0:
        raise ParameterError(f"derivative order n must be an integer >= 0, got {n}")
    if int(N) != N or N < n:
        raise ParameterError(f"polynomial degree N must be an integer >= n = {n}, got {N}")
    if not (kappa > -1 and mu > -1):
        raise ParameterError(f"kappa and mu must be > -1, got kappa = {kappa}, mu = {mu}")


def _jacobi_norm2(k: int, a: float, b: float) -> float:
    """int_0^1 (1-tau)^a tau^b P_k^(a,b)(2 tau - 1)^2 dtau (log-gamma form, stable)."""
    lg = (
        special.gammaln(k + a + 1)
        + special.gammaln(k + b + 1)
        - special.gammaln(k + a + b + 1)
        - special.gammaln(k + 1)
    )
    return float(np.exp(lg) / (2 * k + a + b + 1))


def _jacobi_dn_at(k: int, n: int, a: float, b: float, xi: float) -> float:
    """d^n/dtau^n P_k^(a,b)(2 tau - 1) at tau = xi (DLMF 18.9.15, chain rule factor 2^n)."""
    if k < n:
        return 0.0
    fac = np.exp(special.gammaln(k + a + b + 1 + n) - special.gammaln(k + a + b + 1))
    return float(fac * special.eval_jacobi(k - n, a + n, b + n, 2.0 * xi - 1.0))


def jacobi_kernel(
    tau: np.ndarray, n: int, N: int, kappa: float = 0.0, mu: float = 0.0, xi: float = 0.0
) -> np.ndarray:
    """Continuous algebraic kernel ``g(tau)`` on ``[0, 1]`` in Jacobi form (Mboup et al. 2009).

    ``x^(n)_hat(xi T_w) = T_w^-n int_0^1 g(tau) x(tau T_w) dtau`` where ``tau`` increases away
    from the estimation end (derivatives are taken with respect to ``tau``).

    Examples
    --------
    The paper's N = 1, nu = 2 estimator of the value: ``g = 4 - 6 tau``.

    >>> jacobi_kernel(np.array([0.0, 0.5, 1.0]), 0, 1).round(12).tolist()
    [4.0, 1.0, -2.0]
    """
    _check_orders(n, N, kappa, mu)
    tau = np.asarray(tau, dtype=np.float64)
    s = 2.0 * tau - 1.0
    acc = np.zeros_like(tau)
    for k in range(n, N + 1):
        coef = _jacobi_dn_at(k, n, kappa, mu, xi) / _jacobi_norm2(k, kappa, mu)
        acc += coef * special.eval_jacobi(k, kappa, mu, s)
    with np.errstate(divide="ignore", invalid="ignore"):
        w = (1.0 - tau) ** kappa * tau**mu
    return w * acc


def paper_kappa_mu(N: int, nu: int) -> tuple[float, float]:
    """(kappa, mu) of the seed's (N, nu) estimator: ``kappa = 0``, ``mu = nu - N - 1``.

    The integrating factor ``s^-nu`` must make every term of eq. 8 a proper integral, which
    needs ``nu >= N + 1``; ``nu = N + 1`` (the paper's N = 1, nu = 2) is the plain least-squares
    fit, each extra order adds a factor ``tau`` to the weight at the estimation end.
    """
    if int(nu) != nu or nu < N + 1:
        raise ParameterError(f"nu must be an integer >= N + 1 = {N + 1}, got {nu}")
    return 0.0, float(nu - N - 1)


def exact_point(n: int, N: int, kappa: float = 0.0, mu: float = 0.0) -> float:
    """Smallest ``xi`` in [0, 1] where the estimator is also exact for degree N + 1.

    The error on ``tau^(N+1)`` is a polynomial in ``xi`` of degree ``N + 1 - n``; its roots are
    the zeros of ``P_{N+1-n}^(kappa+n, mu+n)(2 xi - 1)`` (Mboup et al. 2009, section 4). For the
    minimal estimator (N = n) this is ``(mu + n + 1) / (kappa + mu + 2n + 2)``.
    """
    _check_orders(n, N, kappa, mu)
    q1 = N + 1 - n
    x, _ = special.roots_jacobi(q1, kappa + n, mu + n)  # zeros on [-1, 1]
    return float(np.min((np.asarray(x) + 1.0) / 2.0))


# -- discrete FIR kernels -----------------------------------------------------------------------
def _cell_weights(L: int, kappa: float, mu: float) -> np.ndarray:
    """Integral of ``(1-tau)^kappa tau^mu`` over each sample's cell (half cells at the ends)."""
    h = 1.0 / (L - 1)
    edges = np.clip(np.concatenate([[0.0], (np.arange(L - 1) + 0.5) * h, [1.0]]), 0.0, 1.0)
    # regularised incomplete beta: I_x(mu + 1, kappa + 1) = int_0^x w / B(mu + 1, kappa + 1)
    cdf = special.betainc(mu + 1.0, kappa + 1.0, edges)
    return np.diff(cdf) * special.beta(mu + 1.0, kappa + 1.0)


def fir_kernel(
    L: int, n: int, N: int, kappa: float = 0.0, mu: float = 0.0, xi: float = 0.0
) -> np.ndarray:
    """Discrete kernel ``h`` (L,) on normalised time: ``x^(n)_hat = T_w^-n * sum_j h_j x_j``.

    ``x_j`` is the sample at ``tau_j = j / (L - 1)`` (``j = 0`` the estimation end) and the
    derivative is with respect to ``tau``. Weighted least squares (Legendre basis, QR), exact for
    polynomials of degree <= N.
    """
    _check_orders(n, N, kappa, mu)
    if int(L) != L or L < N + 1 or L < 2:
        raise ParameterError(f"window must hold at least N + 1 = {N + 1} (and 2) samples, got {L}")
    if not 0.0 <= xi <= 1.0:
        raise ParameterError(f"evaluation point xi must lie in [0, 1], got {xi}")
    tau = np.arange(L) / (L - 1)
    w = _cell_weights(L, kappa, mu)
    keep = w > 0
    if np.count_nonzero(keep) < N + 1:
        raise ParameterError(f"window of {L} samples is too short for N = {N}")
    B = np.polynomial.legendre.legvander(2.0 * tau - 1.0, N)  # (L, N+1)
    # e_k = d^n/dtau^n Leg_k(2 tau - 1) at xi  (factor 2^n from the chain rule)
    e = np.empty(N + 1)
    for k in range(N + 1):
        c = np.zeros(N + 1)
        c[k] = 1.0
        e[k] = np.polynomial.legendre.legval(2.0 * xi - 1.0, np.polynomial.legendre.legder(c, n))
    e *= 2.0**n
    sw = np.sqrt(w[keep])
    Q, R = np.linalg.qr(sw[:, None] * B[keep])  # A = Q R
    # estimate = e^T (A^T A)^-1 A^T (sw * x) = (Q R^-T e)^T (sw * x)
    z = np.linalg.solve(R.T, e)
    h = np.zeros(L)
    h[keep] = sw * (Q @ z)
    return h


# -- configuration and streaming state -------------------------------------------------------
@dataclass(frozen=True)
class Config:
    """One algebraic differentiator.

    Parameters
    ----------
    n : derivative order (0 = filtered value).
    N : degree of the local polynomial (N >= n). Paper: 1.
    L : window length in samples (window ``T_w = (L - 1) * dt``).
    dt : sample period in s.
    kappa, mu : Jacobi weight exponents (> -1); paper N = 1, nu = 2: 0, 0 (:func:`paper_kappa_mu`).
    xi : evaluation point in [0, 1] of the window (0 = newest sample). The causal delay is
        ``xi * T_w``. Use :func:`exact_point` for the delayed, more accurate estimate.
    mode : 'causal' (online) or 'centred' (offline, output aligned to the estimated instant).
    """

    n: int = 0
    N: int = 1
    L: int = 21
    dt: float = 0.01
    kappa: float = 0.0
    mu: float = 0.0
    xi: float = 0.0
    mode: str = "causal"

    def __post_init__(self) -> None:
        _check_orders(self.n, self.N, self.kappa, self.mu)
        if not self.dt > 0:
            raise ParameterError(f"dt must be > 0, got {self.dt}")
        if self.mode not in MODES:
            raise ParameterError(f"mode must be one of {MODES}, got '{self.mode}'")
        if self.mode == "centred":
            shift = self.xi * (self.L - 1)
            if abs(shift - round(shift)) > 1e-9:
                raise ParameterError(
                    f"centred mode needs xi * (L - 1) to be an integer, got {shift:g} "
                    "(use xi = 0.5 with an odd L)"
                )
        fir_kernel(self.L, self.n, self.N, self.kappa, self.mu, self.xi)  # validates L, xi

    @classmethod
    def from_window(
        cls, window_s: float, dt: float, *, n: int = 0, N: int = 1, **kw
    ) -> Config:
        """Window given in seconds: ``L = round(window_s / dt) + 1`` samples."""
        return cls(n=n, N=N, L=int(round(window_s / dt)) + 1, dt=dt, **kw)

    @property
    def window(self) -> float:
        """Window length ``T_w = (L - 1) dt`` in s."""
        return (self.L - 1) * self.dt

    @property
    def delay(self) -> float:
        """Delay in s of the causal output (``xi * T_w``); 0 in centred mode."""
        return 0.0 if self.mode == "centred" else self.xi * self.window

    @property
    def shift(self) -> int:
        """Samples by which centred mode moves the causal output back (``xi (L - 1)``)."""
        return int(round(self.xi * (self.L - 1)))

    def taps(self) -> np.ndarray:
        """FIR taps ``b`` (L,) in physical units: ``y[i] = sum_j b[j] x[i - j]``.

        The ``tau`` derivative is converted to time: ``d/dt = -(1 / T_w) d/dtau`` because
        ``tau`` is the age of a sample.
        """
        h = fir_kernel(self.L, self.n, self.N, self.kappa, self.mu, self.xi)
        return h * (-1.0 / self.window) ** self.n


class State(NamedTuple):
    """Ring buffer ``buf`` (L,) of the last samples, ``pos`` index of the next write,
    ``started`` False until the first finite sample has filled the buffer."""

    buf: np.ndarray
    pos: int
    started: bool


def init(config: Config) -> State:
    """Empty state; the first finite sample fills the whole buffer (steady state)."""
    return State(np.zeros(config.L), 0, False)


@njit(cache=True)
def _ring_step(taps, buf, pos, x):
    """Write ``x`` at ``pos`` and return ``sum_j taps[j] * x[i - j]`` and the next position."""
    L = taps.size
    buf[pos] = x
    acc = 0.0
    for j in range(L):
        k = pos - j
        if k < 0:
            k += L
        acc += taps[j] * buf[k]
    pos += 1
    if pos == L:
        pos = 0
    return acc, pos


@njit(cache=True)
def _ring_run(taps, buf, pos, started, x, out):
    """Loop of :func:`_ring_step`; NaN input holds the last sample (output NaN there)."""
    for i in range(x.size):
        xi = x[i]
        if not np.isfinite(xi):
            out[i] = np.nan
            continue
        if not started:
            buf[:] = xi
            started = True
        out[i], pos = _ring_step(taps, buf, pos, xi)
    return pos, started


def step(config: Config, state: State, x: float, taps: np.ndarray | None = None
         ) -> tuple[State, float]:
    """One causal sample: returns the new state and the estimate of ``x^(n)(t - delay)``.

    ``taps`` may be passed (``config.taps()``) to avoid recomputing the kernel on every call.
    A NaN sample gives NaN and leaves the state unchanged.
    """
    b = config.taps() if taps is None else taps
    buf = state.buf.copy()
    out = np.empty(1)
    pos, started = _ring_run(b, buf, state.pos, state.started, np.array([float(x)]), out)
    return State(buf, int(pos), bool(started)), float(out[0])


def run(config: Config, x: np.ndarray, state: State | None = None
        ) -> tuple[State, np.ndarray]:
    """Causal streaming over ``x``; identical numbers to repeated :func:`step`."""
    st = init(config) if state is None else state
    x = np.ascontiguousarray(x, dtype=np.float64)
    buf = st.buf.copy()
    out = np.empty_like(x)
    pos, started = _ring_run(config.taps(), buf, st.pos, st.started, x, out)
    return State(buf, int(pos), bool(started)), out


def apply(config: Config, x: np.ndarray) -> np.ndarray:
    """Batch differentiation of a whole NaN-free signal with ``np.convolve``.

    ``causal``: equals :func:`run` (start padded with ``x[0]``, the steady-state start).
    ``centred``: the causal output moved back by :attr:`Config.shift` samples, so that entry
    ``i`` estimates ``x^(n)(t_i)``; the last ``shift`` entries (window not full) are NaN.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.size == 0:
        return x.copy()
    if not np.all(np.isfinite(x)):
        raise ParameterError("apply() needs a NaN-free signal; use run() for streams with gaps")
    b = config.taps()
    padded = np.concatenate([np.full(config.L - 1, x[0]), x])
    y = np.convolve(padded, b, mode="valid")
    if config.mode == "causal":
        return y
    s = config.shift
    out = np.full_like(x, np.nan)
    out[: x.size - s] = y[s:]
    return out


def noise_gain(config: Config) -> float:
    """Standard deviation of the output per unit white-noise standard deviation: ``||b||_2``."""
    return float(np.linalg.norm(config.taps()))
