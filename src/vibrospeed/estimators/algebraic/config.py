"""Parameters and state of the algebraic estimator: the inputs and outputs in their order,
:class:`Config` (filter windows and degree, reset, slip and yaw thresholds, noise allowances;
validated on construction, with the filter taps and the packed scalars the compiled core reads)
and :class:`State` (ring buffers, Vx history, packed scalars)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.estimators.algebraic.core import _LAST, _NS, _VX, _VY
from vibrospeed.signal import differentiation as dif

#: inputs, in this order, of :func:`step`
INPUTS = ("gz", "ax", "ay", "omega_mean")
#: per-sample outputs of :func:`step` / :func:`run`
OUTPUTS = (
    "vx", "vy", "gx", "gy", "dgx", "dgy", "slip_mode", "turn_mode",
    "yaw_rate", "yaw_acc", "ax", "ay", "omega_mean", "omega_dot",
    "vx_std", "vy_std", "sd_gz", "sd_ax", "sd_ay", "sd_omega",
)


#: longest hold or backtracking depth in s (``alpha``, ``beta``, ``reset_hold``, ``backtrack``
#: in samples at ``Ts``): the Vx history is that long
_MAX_HOLD_S = 60.0

#: domain of each parameter: (low, low excluded, high, unit); a vehicle's geometry (an RC car's
#: 0.03 m wheel to a mining truck's 2 m, CG to front axle up to a bus's 10 m), filter windows up
#: to 10 s, sds of sensors that still measure something
_DOMAINS = {
    "r": (0.0, True, 3.0, "m"), "L1": (0.0, True, 10.0, "m"), "dt": (0.0, True, 1.0, "s"),
    "window": (0.0, True, 10.0, "s"), "window_d": (0.0, True, 10.0, "s"),
    "N": (1, False, 10, ""), "kappa": (-1.0, True, 50.0, ""), "mu": (-1.0, True, 50.0, ""),
    "xi": (0.0, False, 1.0, ""),
    "eps1": (0.0, True, np.inf, "m/s^2"), "alpha": (0, False, np.inf, "samples"),
    "eps2": (0.0, True, np.inf, "rad/s"), "beta": (0, False, np.inf, "samples"),
    "reset_eps_x": (0.0, False, np.inf, "m/s^2"), "reset_eps_y": (0.0, False, np.inf, "m/s^2"),
    "reset_hold": (0, False, np.inf, "samples"), "vy0": (-100.0, False, 100.0, "m/s"),
    "backtrack": (0, False, np.inf, "samples"), "eps_k": (0.0, False, np.inf, ""),
    "slip_sd": (0.0, False, 1.0, ""), "acc_bias_sd": (0.0, False, 10.0, "m/s^2"),
    "gyro_bias_sd": (0.0, False, 1.0, "rad/s"), "handover_tau": (0.0, True, np.inf, "s"),
    "noise_tau": (0.0, True, 1e6, "s"), "max_int": (0.0, True, np.inf, "s"),
    "slip_tol": (0.0, True, np.inf, "m/s"), "slip_window": (0.0, True, 10.0, "s"),
}
#: the parameters counted in samples (integers)
_COUNTS = ("alpha", "beta", "reset_hold", "backtrack")


def _domain_text(name: str) -> str:
    """``name``'s domain as text: ``in (0, 10] m``, ``an integer >= 0 samples``."""
    lo, lo_open, hi, unit = _DOMAINS[name]
    unit = f" {unit}" if unit else ""
    if name in _COUNTS or name == "N":
        return (f"an integer >= {lo}{unit}" if hi == np.inf
                else f"an integer in [{lo}, {hi}]{unit}")
    if hi == np.inf:
        return f"{'>' if lo_open else '>='} {lo:g}{unit} (inf: never)"
    return f"in {'(' if lo_open else '['}{lo:g}, {hi:g}]{unit}"


@dataclass(frozen=True)
class Config:
    """Parameters of Algorithms 1 and 2 and of the uncertainty model.

    Parameters
    ----------
    r : wheel radius in m. L1 : CG to front axle distance in m (``Ry = -L1 psi_dot``).
    dt : sample period Ts in s.
    window, window_d : algebraic filter windows in s for values / first derivatives.
    N, kappa, mu, xi : differentiator degree, Jacobi weights and evaluation point
        (:mod:`vibrospeed.signal.differentiation`); the seed uses N = 1, nu = 2
        (kappa = mu = 0) and estimates at the newest sample (xi = 0).
    eps1 : m/s^2, threshold on ``|dGx/dt|``; alpha : hold window in samples (``alpha Ts``).
    eps2 : rad/s, threshold on ``|psi_dot|``; beta : hold window in samples (``beta Ts``).
    reset_eps_x : m/s^2 on ``|r d(omega_mean)/dt|``; reset_eps_y : m/s^2 on
        ``|L1 psi_ddot|``; reset_hold : samples (0 disables the reset of remark 4).
    vy0 : initial lateral velocity in m/s (Algorithm 2 requires it).
    backtrack : samples; at the onset of slip the integration restarts from ``Vx`` that many
        samples before the switch (the wheels already slipped while ``dGx/dt`` was building
        up); ``None`` -> ``alpha``, 0 -> the seed's restart from the previous sample.
    eps_k : if > 0, the thresholds become ``max(eps1, eps_k sd(dGx/dt))`` and
        ``max(eps2, eps_k sd(psi_dot))`` with the noise sds predicted from the sensor noise
        measured on line (second differences); 0 (default) keeps the fixed thresholds.
    Uncertainty: ``slip_sd`` relative allowance for undetected slip in wheel mode (sd of Vx
    = ``slip_sd |Vx|``); ``acc_bias_sd`` m/s^2 and ``gyro_bias_sd`` rad/s, sds of the sensor
    biases (integration drift ``b T``); ``handover_tau`` s, decay time of the disagreement
    allowance at a switch back; ``noise_tau`` s, memory of the on-line noise estimates.
    max_int : s, longest integration episode: after it the wheels are trusted again (the hold
        window restarts); ``inf`` (default) is the seed's rule.
    detect : ``"window"`` (default) or ``"seed"`` (Algorithm 1 as published: ``eps1``,
        ``alpha``, ``backtrack`` and the reset only act there).
    slip_tol : m/s, window detection: largest disagreement between the wheel speed and the
        dead-reckoned speed taken as rolling (raised to ``eps_k`` sd of the measured noise).
    slip_window : s, window detection: the window of that comparison and of the hold.
    """

    r: float = 0.31
    L1: float = 1.2
    dt: float = 0.01
    window: float = 0.1
    window_d: float = 0.2
    N: int = 1
    kappa: float = 0.0
    mu: float = 0.0
    xi: float = 0.0
    eps1: float = 0.4
    alpha: int = 20
    eps2: float = 0.02
    beta: int = 30
    reset_eps_x: float = 0.3
    reset_eps_y: float = 0.3
    reset_hold: int = 50
    vy0: float = 0.0
    backtrack: int | None = None
    eps_k: float = 0.0
    slip_sd: float = 0.002
    acc_bias_sd: float = 0.03
    gyro_bias_sd: float = 0.001
    handover_tau: float = 0.5
    noise_tau: float = 5.0
    max_int: float = float("inf")
    detect: str = "window"
    slip_tol: float = 0.3
    slip_window: float = 0.5

    def __post_init__(self) -> None:
        # each parameter's domain, one line naming it and its range: an absurd gain or window
        # (-p L1=1e9, -p window=1e9) was accepted silently, or failed deep inside (a 745 GiB
        # filter kernel). The thresholds eps1, eps2, slip_tol, max_int, handover_tau and the
        # reset thresholds may be inf ("never"); lengths, windows, sds and vy0 may not (inf or
        # NaN made Vx, Vy or their std inf or NaN)
        for name, (lo, lo_open, hi, _unit) in _DOMAINS.items():
            v = getattr(self, name)
            if v is None and name == "backtrack":
                continue
            ok = isinstance(v, (int, float, np.integer, np.floating)) and not np.isnan(v) and (
                v > lo if lo_open else v >= lo) and v <= hi
            if ok and name in _COUNTS:
                ok = bool(np.isfinite(v)) and int(v) == v
            if not ok:
                raise ParameterError(f"algebraic: {name} must be {_domain_text(name)}, got {v}")
        if self.noise_tau < self.dt:  # running-mean weight dt / noise_tau above 1 oscillates
            raise ParameterError(f"algebraic: noise_tau must be >= Ts = {self.dt:g} s, got "
                                 f"{self.noise_tau}")
        horizon = int(_MAX_HOLD_S / self.dt)
        for name in _COUNTS:  # a hold or backtrack over a minute made a buffer of that length
            v = getattr(self, name)
            if v is not None and v > max(horizon, 1):
                raise ParameterError(f"algebraic: {name} must be at most {horizon} samples "
                                     f"({_MAX_HOLD_S:g} s at Ts = {self.dt:g} s), got {v}")
        if self.detect not in ("window", "seed"):
            raise ParameterError(f"algebraic: detect must be 'window' or 'seed', got "
                                 f"{self.detect!r}")
        if not (isinstance(self.N, (int, np.integer)) and self.N >= 1):  # numpy's degree
            raise ParameterError(
                f"algebraic: N must be an integer >= 1 (derivatives are needed), got {self.N}")
        try:
            self.filters()  # validates the windows against N
        except ParameterError as exc:
            raise ParameterError(f"algebraic: window = {self.window:g} s / window_d = "
                                 f"{self.window_d:g} s at Ts = {self.dt:g} s: {exc}") from None

    @property
    def k_window(self) -> int:
        """``slip_window`` in samples (at least 2)."""
        return max(2, int(round(self.slip_window / self.dt)))

    @property
    def n_back(self) -> int:
        """Backtracking depth in samples: ``k_window`` for the window detection, else
        ``backtrack`` (default ``alpha``)."""
        if self.detect == "window":
            return self.k_window
        return int(self.alpha if self.backtrack is None else self.backtrack)

    def filters(self) -> tuple[dif.Config, dif.Config]:
        """Differentiator configurations (value, first derivative)."""
        kw = dict(N=self.N, kappa=self.kappa, mu=self.mu, xi=self.xi)
        return (dif.Config.from_window(self.window, self.dt, n=0, **kw),
                dif.Config.from_window(self.window_d, self.dt, n=1, **kw))

    def taps(self) -> tuple[np.ndarray, np.ndarray]:
        """FIR taps (value, derivative) zero-padded to one common length."""
        c0, c1 = self.filters()
        b0, b1 = c0.taps(), c1.taps()
        L = max(b0.size, b1.size)
        return np.pad(b0, (0, L - b0.size)), np.pad(b1, (0, L - b1.size))

    def scalars(self) -> np.ndarray:
        b0, b1 = self.taps()
        return np.array([self.r, self.L1, self.dt, self.eps1, self.alpha, self.eps2, self.beta,
                         self.reset_eps_x, self.reset_eps_y, self.reset_hold, self.vy0,
                         self.n_back, self.eps_k, self.slip_sd, self.acc_bias_sd,
                         self.gyro_bias_sd, self.handover_tau, self.noise_tau,
                         float(np.linalg.norm(b0)), float(np.linalg.norm(b1)), self.max_int,
                         1.0 if self.detect == "window" else 0.0, self.slip_tol,
                         self.k_window])


class State(NamedTuple):
    """Ring buffers ``buf`` (4, L) of ``INPUTS``; ``hist`` (4, ``n_back`` + 2) of past ``Vx``,
    its variance, the integration increments ``Ts (gamma_x + psi_dot Vy)`` and the wheel speed
    ``r omega_mean`` (m/s); ``s`` (42,) packed scalars (``G``, ``V``, hold counters, held
    inputs, noise statistics, variances; see the ``_*`` indices in
    :mod:`vibrospeed.estimators.algebraic.core`)."""

    buf: np.ndarray
    hist: np.ndarray
    s: np.ndarray

    @property
    def vx(self) -> float:
        return float(self.s[_VX])

    @property
    def vy(self) -> float:
        return float(self.s[_VY])


def init(config: Config) -> State:
    """Empty state: the first finite sample fills the buffers and sets ``Vx = r omega_mean``."""
    L = config.taps()[0].size
    s = np.zeros(_NS)
    s[_LAST:_LAST + 4] = np.nan
    return State(np.zeros((4, L)), np.zeros((4, config.n_back + 2)), s)
