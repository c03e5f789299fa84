"""Parameters of the aided grid tracker (:mod:`vibrospeed.estimators.aided_grid`): the
:class:`Config` around an RBPMF configuration (its grid must be linear; it starts at 0 unless
the standstill flags come from the broadband detector), the detectors, the aiding kind and the
optional comb evidence, validated on construction; and the thesis cart's grid tracker
(:func:`_cart_tracker`), the default. The per-mode RBPMF configs (vibration, acceleration,
standstill random walks) are derived here once (:attr:`Config.trackers`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid as gridmod
from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.aided.config import check_windows
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal import detectors as det

STANDSTILL_KINDS = ("none", "window", "broadband")
#: ``"mode"``: the thesis' mode detector (integrate a_x and skip the vibration update in
#: acceleration mode); ``"continuous"``: integrate a_x every ``aid_hop`` s, never skip;
#: ``"none"``: no aiding (the tracker with the standstill measurements only)
AIDING_KINDS = ("mode", "continuous", "none")


def _cart_tracker(dt: float = 0.01) -> rbpmf.Config:
    """Grid tracker for the thesis' cart: the aided EKF's model (M = 2, R = 0.0022 and q_amp
    0.004 in m/s^2 units, q_omega 0.5 (rad/s)^2/s, no scaling, thesis HP + LP pre-filter),
    161 points on [0, 40] rad/s (dx = 0.25 rad/s). The kernel is variance-matched
    (``kernel_var="matched"``): q_omega 0.025 (rad/s)^2/s is the walk's variance on this grid
    at any sample rate (the paper's *sampled* kernel, on which the values were first chosen,
    shrinks it by the grid spacing: 0.5 there is about 0.025 effective at 100 Hz, and the walk
    freezes at 400 Hz); measured in benchmarks/aided/RESULTS.md."""
    model = HarmonicModel(M=2, dt=dt, q_omega=0.025, q_amp=0.004, r=0.0022, p0_amp=0.1)
    return rbpmf.Config(model=model, n_grid=161, omega_min=0.0, omega_max=40.0,
                        prefilter="thesis-hplp", scaling="none", kernel_var="matched")


@dataclass(frozen=True)
class Config:
    """Parameters of the aided grid tracker (SI units).

    tracker : the RBPMF configuration (grid, model, pre-filter, scaling); its grid must be
        linear and start at omega_min = 0. Default: :func:`_cart_tracker`.
    wheel_radius : r in m.
    q_omega_accel : omega random walk (rad/s)^2/s in acceleration mode (None: the tracker's).
    q_omega_still : omega random walk while the standstill flag is up (default 0).
    accel_bias : fixed offset b (m/s^2) added to u (no bias state, see the package docstring).
    standstill : 'window' (thesis 3.1) or 'none'. ss_window (s) / ss_n, ss_mu, r_ss : as in
        :class:`vibrospeed.estimators.aided.Config`.
    mode_window (s) / mode_n, mode_mu, boost : mode detector (thesis 3.3) and the boost of
        eq. 3.15.
    comb : harmonic-comb evidence (:class:`vibrospeed.estimators.grid.Config`, its ``tracker``
        must have this tracker's grid and ``dt``) or None (none; the default).
    comb_in_accel : also apply the comb evidence in acceleration mode (default False).
    standstill 'broadband' : the per-sample input ``still`` (flags of
        :func:`vibrospeed.estimators.aiding.standstill_flags`) is the standstill decision.
    aiding : 'mode' (thesis 3.3: a_x integrated and the vibration update skipped in
        acceleration mode), 'continuous' (package docstring, "Continuous aiding") or 'none'.
    aid_hop : s, with ``aiding='continuous'``: the posterior is shifted by the integral of
        ``u + accel_bias`` over each hop of ``aid_len`` samples at the hop's last sample.
    """

    tracker: rbpmf.Config = field(default_factory=_cart_tracker)
    wheel_radius: float = 0.08
    q_omega_accel: float | None = 0.5
    q_omega_still: float = 0.0
    accel_bias: float = 0.0
    standstill: str = "window"
    ss_n: int | None = None
    ss_window: float = det.WINDOW_S
    ss_mu: float = det.WINDOW_MU
    r_ss: float = 1.0
    mode_n: int | None = None
    mode_window: float = det.MODE_S
    mode_mu: float = det.MODE_MU
    boost: bool = True
    comb: gridmod.Config | None = None
    comb_in_accel: bool = False
    aiding: str = "mode"
    aid_hop: float = 0.1

    def __post_init__(self) -> None:
        tr = self.tracker
        if not 0 < self.wheel_radius < math.inf:  # inf: every speed 0 or NaN
            raise ParameterError(f"wheel_radius must be finite and > 0 m, got "
                                 f"{self.wheel_radius}")
        if tr.spacing != "linear" or tr.n_grid < 2:
            raise ParameterError("aided rbpmf needs a linear grid of >= 2 points "
                                 "(spacing='linear')")
        if tr.omega_min != 0.0 and self.standstill != "broadband":
            raise ParameterError(f"aided rbpmf needs omega_min = 0 (the grid point omega = 0 is "
                                 f"standstill; standstill='broadband' reports it from its "
                                 f"flags instead), got {tr.omega_min}")
        if tr.smooth != "none" or tr.fit_names:
            raise ParameterError("aided rbpmf is a causal filter: smooth and fit are not offered")
        if self.standstill not in STANDSTILL_KINDS:
            raise ParameterError(f"standstill must be one of {', '.join(STANDSTILL_KINDS)} for the "
                                 f"rbpmf tracker, got '{self.standstill}'")
        for name in ("r_ss", "ss_mu", "mode_mu"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0, got {getattr(self, name)}")
        if not 0 <= self.q_omega_still < math.inf:
            raise ParameterError(f"q_omega_still must be finite and >= 0, got "
                                 f"{self.q_omega_still}")
        if self.q_omega_accel is not None and not 0 <= self.q_omega_accel < math.inf:
            raise ParameterError(f"q_omega_accel must be finite and >= 0 (or None), got "
                                 f"{self.q_omega_accel}")
        if not np.isfinite(self.accel_bias):
            raise ParameterError(f"accel_bias must be finite, got {self.accel_bias}")
        for name in ("ss_n", "mode_n"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and int(v) == v and v >= 1):
                raise ParameterError(f"{name} must be a positive integer, got {v}")
        for name in ("ss_window", "mode_window", "aid_hop"):  # inf failed in int() in run
            if not 0 < getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and > 0 s, got "
                                     f"{getattr(self, name)}")
        check_windows(self, self.tracker.model.dt)
        if self.aiding not in AIDING_KINDS:
            raise ParameterError(f"aiding must be one of {', '.join(AIDING_KINDS)}, got "
                                 f"'{self.aiding}'")
        if self.comb is not None:
            ct = self.comb.tracker
            if (ct.n_grid != tr.n_grid or not np.array_equal(ct.grid, tr.grid)
                    or ct.model.dt != tr.model.dt or ct.model.M != tr.model.M):
                raise ParameterError("comb: its tracker must have the aided tracker's grid, dt "
                                     "and M")
            if self.comb.comb_axes:
                raise ParameterError("comb_axes: the aided tracker reads one vibration axis "
                                     "(-m grid takes several)")

    @property
    def ss_len(self) -> int:
        """Samples in the standstill window: ``ss_n``, else ``ss_window`` s."""
        return det.window_samples(self.ss_n, self.ss_window, self.tracker.model.dt)

    @property
    def ss_on_grid(self) -> bool:
        """The standstill measurement omega = 0 acts on the grid (it starts at 0); otherwise
        (``standstill='broadband'`` on a search range above 0) a standing sample is a plain
        vibration sample whose omega is reported as 0 by the caller."""
        return self.tracker.omega_min == 0.0

    @property
    def aid_len(self) -> int:
        """Samples per aiding hop (``aid_hop`` s, at least 1)."""
        return max(1, int(round(self.aid_hop / self.tracker.model.dt)))

    @property
    def mode_len(self) -> int:
        """Samples in the mode-detector window: ``mode_n``, else ``mode_window`` s."""
        return det.window_samples(self.mode_n, self.mode_window, self.tracker.model.dt)

    def _with_q(self, q: float | None) -> rbpmf.Config:
        if q is None or q == self.tracker.model.q_omega:
            return self.tracker
        return dataclasses.replace(
            self.tracker, model=dataclasses.replace(self.tracker.model, q_omega=float(q)))

    @cached_property
    def trackers(self) -> tuple[rbpmf.Config, rbpmf.Config, rbpmf.Config]:
        """RBPMF configs for (vibration, acceleration, standstill) samples: same grid and
        model, omega random walk q_omega, q_omega_accel, q_omega_still."""
        return (self.tracker, self._with_q(self.q_omega_accel), self._with_q(self.q_omega_still))

    @property
    def grid(self) -> np.ndarray:
        """(N,) omega grid in rad/s."""
        return self.tracker.grid

    @property
    def dx(self) -> float:
        """Grid spacing in rad/s."""
        g = self.tracker.grid
        return float(g[1] - g[0])
