"""Harmonic phasor model of chassis vibrations (METHODS.md section 1; thesis eq. 2.22-2.24;
chassis-vibration paper eq. 1-3).

State ``x = [omega, alpha_1, beta_1, ..., alpha_M, beta_M]``::

    omega_{t+1}             = omega_t + sqrt(T) v^omega_t,            var(v^omega) = q_omega
    [alpha, beta]^(m)_{t+1} = R(m omega_t T) [alpha, beta]^(m)_t + sqrt(T) v^(m)_t,  var = q_amp
    y_t                     = sum_m alpha^(m)_t + e_t,                var(e) = r
    R(psi) = [[cos psi, sin psi], [-sin psi, cos psi]]                (thesis eq. 2.22)

so that the per-step process noise is ``T * q`` (the paper's ``sqrt(T)`` scaling). The linear part
``[alpha, beta]`` has shape ``(2M,)`` ordered ``alpha_1, beta_1, alpha_2, beta_2, ...``.
The model is symmetric under ``(omega, beta) -> (-omega, -beta)``; estimators keep omega >= 0.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from vibrospeed.config import is_count
from vibrospeed.errors import ParameterError


@dataclass(frozen=True)
class HarmonicModel:
    """Parameters of the harmonic phasor model.

    Parameters
    ----------
    M : number of harmonics (>= 1).
    dt : sample period T in s.
    q_omega : var(v^omega) in (rad/s)^2 / s; per-step omega variance is ``dt * q_omega``.
        Paper Table I: 4. Thesis EKF: Q_omega = 0.16 per step at 100 Hz, i.e. 16.
    q_amp : var(v^alpha) = var(v^beta) in (signal unit)^2 / s. Paper: 0.001; thesis 0.004.
    r : measurement noise variance var(e) in (signal unit)^2. Not given by the paper; the thesis
        used 0.0008..0.003 on its pre-filtered signal (m/s^2)^2.
    p0_amp : initial variance of each alpha, beta. Paper: 0.1.
    """

    M: int = 3
    dt: float = 0.01
    q_omega: float = 4.0
    q_amp: float = 0.001
    r: float = 0.003
    p0_amp: float = 0.1

    def __post_init__(self) -> None:
        # an infinite period, noise or prior variance makes every filter's output NaN; M sizes
        # arrays (np.arange, np.eye), which take no float, not even 2.0 ("-p M=2" is the int 2)
        if not is_count(self.M):
            raise ParameterError(f"M must be a positive integer, got {self.M}")
        for name in ("dt", "q_amp", "r", "p0_amp"):
            if not 0 < getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and > 0, got {getattr(self, name)}")
        if not 0 <= self.q_omega < math.inf:
            raise ParameterError(f"q_omega must be finite and >= 0, got {self.q_omega}")

    # -- constructors ---------------------------------------------------------------------
    @classmethod
    def from_paper_table1(cls, dt: float = 0.01, *, r: float = 0.003) -> HarmonicModel:
        """Chassis-vibration paper, Table I: M = 3, var(v^omega) = 4, var(v^a,b) = 0.001."""
        return cls(M=3, dt=dt, q_omega=4.0, q_amp=0.001, r=r, p0_amp=0.1)

    @classmethod
    def from_thesis(cls, dt: float = 0.01, M: int = 3) -> HarmonicModel:
        """Thesis section 2.3.5 at 100 Hz: R = 0.003, Q = 1e-5 diag(16000, 4, ...), P0 amp 20.

        The thesis gives Q per step at T = 0.01 s; converted to intensities ``q = Q / 0.01``.
        """
        return cls(M=M, dt=dt, q_omega=0.16 / 0.01, q_amp=4e-5 / 0.01, r=0.003, p0_amp=20.0)

    # -- structure ------------------------------------------------------------------------
    @property
    def n_lin(self) -> int:
        """Dimension 2M of the linear (phasor) state."""
        return 2 * self.M

    @property
    def harmonics(self) -> np.ndarray:
        """(M,) harmonic orders 1..M as float."""
        return np.arange(1, self.M + 1, dtype=np.float64)

    @property
    def H(self) -> np.ndarray:
        """(2M,) measurement row: y = sum_m alpha^(m)."""
        h = np.zeros(self.n_lin)
        h[0::2] = 1.0
        return h

    @property
    def Q_lin(self) -> np.ndarray:
        """(2M, 2M) per-step process noise of the phasor state, ``T * q_amp * I``."""
        return self.dt * self.q_amp * np.eye(self.n_lin)

    @property
    def q_omega_step(self) -> float:
        """Per-step variance of the omega random walk, ``T * q_omega`` (rad/s)^2."""
        return self.dt * self.q_omega

    def omega_clip(self, omega_max: float | None = None) -> float:
        """Largest omega (rad/s) a tracker may report: ``omega_max`` capped just below the
        Nyquist limit of harmonic M, ``0.98 pi / (M T)``."""
        nyq = 0.98 * np.pi / (self.M * self.dt)
        return nyq if omega_max is None else min(omega_max, nyq)

    def F(self, omega: float | np.ndarray) -> np.ndarray:
        """Phasor transition ``blockdiag_m R(m omega T)``; shape (2M, 2M), or (N, 2M, 2M)."""
        om = np.asarray(omega, dtype=np.float64)
        psi = om[..., None] * self.harmonics * self.dt  # (..., M)
        c, s = np.cos(psi), np.sin(psi)
        out = np.zeros(om.shape + (self.n_lin, self.n_lin))
        i = np.arange(self.M)
        out[..., 2 * i, 2 * i] = c
        out[..., 2 * i, 2 * i + 1] = s
        out[..., 2 * i + 1, 2 * i] = -s
        out[..., 2 * i + 1, 2 * i + 1] = c
        return out

    def to_dict(self) -> dict:
        """JSON-serialisable parameters."""
        return asdict(self)

    # -- simulation -------------------------------------------------------------------------
    def simulate(
        self,
        omega: np.ndarray,
        rng: np.random.Generator,
        *,
        x0: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Draw ``y`` for a given omega sequence (rad/s), following the model exactly.

        Returns ``(y (n,), x_lin (n, 2M))``. ``x0`` defaults to a draw from N(0, p0_amp I).
        """
        omega = np.asarray(omega, dtype=np.float64)
        n = omega.size
        x = (
            rng.normal(0.0, np.sqrt(self.p0_amp), self.n_lin)
            if x0 is None
            else np.array(x0, dtype=np.float64)
        )
        xs = np.empty((n, self.n_lin))
        sq = np.sqrt(self.dt * self.q_amp)
        Fs = self.F(omega)
        h = self.H
        y = np.empty(n)
        for k in range(n):
            xs[k] = x
            y[k] = h @ x + rng.normal(0.0, np.sqrt(self.r))
            x = Fs[k] @ x + sq * rng.normal(size=self.n_lin)
        return y, xs
