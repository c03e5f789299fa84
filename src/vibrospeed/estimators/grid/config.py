"""Parameters of the grid tracker (the Rao-Blackwellized point-mass filter over an omega grid):
:class:`Config`, the paper's defaults (Table I) and the improved settings (:func:`improved`)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from vibrospeed.config import flat_dict
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import scaling as _scaling
from vibrospeed.estimators.grid.kernel import Kernel, build_kernel
from vibrospeed.models.harmonic import HarmonicModel

#: most floats a config may ask its arrays to hold (1 GiB): a larger grid, harmonic count or
#: particle count is a typo (1e12), refused before numpy dies allocating it
MAX_FLOATS = 1 << 27

#: measurement noise variance used with the running-RMS scaling (signal RMS 0.5, variance
#: 0.25): the harmonics are assumed to carry about 80 % of the pre-filtered signal power.
DEFAULT_R = 0.05


def paper_model(dt: float = 0.01) -> HarmonicModel:
    """The paper's harmonic model (Table I) at period ``dt``, ``r`` = :data:`DEFAULT_R`."""
    return HarmonicModel.from_paper_table1(dt, r=DEFAULT_R)

@dataclass(frozen=True)
class Config:
    """RBPMF parameters (defaults: paper Table I and section IV-B).

    model : harmonic model; Table I: M = 3, var(v^omega) = 4, var(v^a,b) = 0.001,
        var(alpha_0) = 0.1. ``r`` (not in the paper) defaults to :data:`DEFAULT_R` for a signal
        normalised to RMS ``signal_rms``.
    n_grid, omega_min, omega_max : grid of N points on [omega_min, omega_max] rad/s
        (paper: 200 on [10, 120]). ``spacing``: "linear" (paper) or "log" (geometric, constant
        relative resolution).
    kernel : "banded" (default) or "exact" (full rows, reference). ``kernel_tol``: largest
        discarded mass per kernel row (see module docstring).
    kernel_var : "sampled" (default, the paper's) or "matched": how the random walk's
        variance ``T q_omega`` reaches the grid. The sampled density ``N(omega_j; omega_i,
        sigma^2) Delta_j`` has a variance on the grid well below ``sigma^2`` once ``sigma`` is
        smaller than the spacing (sigma / Delta = 0.36: 33 %; 0.14: 1e-10), so the walk's
        effective q_omega shrinks with the sample rate; "matched" widens each row's Gaussian
        (:func:`matched_sigmas`) until its variance on a grid of that row's spacing is
        ``sigma^2``, so q_omega means the same at any sample rate (equal to "sampled" within
        1e-6 for sigma >= 1.2 Delta).
    omega0, omega0_std : Gaussian prior on omega in rad/s; ``omega0=None`` (default) is the
        paper's "unknown initial angular velocity", a prior uniform in omega.
    log_floor : weights kept within this many nats of the best grid point.
    level : probability of the credible interval (paper figures: 98 %).
    prefilter : pre-filter preset for :func:`estimate` (paper: HP order 2 at 8 Hz).
    scaling : "rms" (running-RMS normalisation, :mod:`.scaling`) or "none" (data used as is).
    rms_tau : time constant of the running RMS in s. signal_rms : RMS after normalisation.
    nyquist : "warn" (default; harmonics above Nyquist alias, which the rotation model still
        describes exactly, only the fundamental must stay below it) or "error" (require
        ``M omega_max < pi fs``).

    Beyond the paper (all off by default = the paper's filter, see :func:`improved`):

    jump_rate : 1/s, rate of a jump of omega to anywhere on the grid (re-acquisition). Per step
        ``eps = 1 - exp(-jump_rate T)`` of every grid point's mass moves to the grid with
        weights proportional to the cell widths (uniform in omega), and the jumped mass gets the
        linear-state prior ``N(0, var(alpha_0) I)``.
    off_rate, on_rate : 1/s, switching rates of a "no line" state (``off_rate = 0``: no such
        state). In it the sample is broadband, ``y ~ N(0, null_var)`` with ``null_var``
        defaulting to ``signal_rms^2`` (the running-RMS scaled signal's power). Its mass is
        reported as ``p_null``; the band spreads it uniformly over the grid (honest "no signal").
        ``on_rate = inf`` is an immediate return to "line" (``p_on = 1``, as for any
        ``on_rate T`` over ~37): a "no line" sample is a single broadband outlier, entered
        with probability ``p_off`` at every sample, and its stationary share is 0.
    p_null0 : prior mass of the "no line" state at the first sample; None (default): the
        switching chain's stationary share ``off_rate / (off_rate + on_rate)`` (2 % for the
        grid's rates, i.e. "a wheel line is there" before any data). 0.5 ("not known yet")
        suits a device switched on at standstill: an idling engine then reads "no line"
        sooner, but a start while driving locks later (the "no line" mass re-enters the grid
        uniformly; benchmarks/beyond/RESULTS.md).
    amb_rel, amb_abs : half-width ``max(amb_abs, amb_rel * x)`` of the window around ``x =
        MAP/2`` and ``2 MAP`` in which the posterior mass ``p_half``, ``p_double`` is reported;
        the same window defines the mode (``point``).
    smooth : "none" (causal filter), "fb" (forward-backward smoother over the whole log, with
        the Viterbi MAP path) or "lag" (fixed-lag smoother, ``lag`` s); see
        :mod:`vibrospeed.estimators.grid_smoother`.
    fit : comma-separated model parameters to fit by marginal likelihood before tracking
        (e.g. ``"q_omega,q_amp,r"``; :mod:`vibrospeed.estimators.fit`); empty: none.
    temper : power ``c`` in (0, 1] on the per-sample predictive likelihoods (grid and "no
        line"): ``log w_j += c log N(y; h m_j, S_j)``. ``c = 1`` is the paper's filter; ``c < 1``
        is the coarsened ("power") likelihood for a misspecified model (unmodelled resonances
        and interfering lines make the per-sample evidence over-confident): the posterior then
        moves as if it had seen ``c`` times the samples, leaving room for other evidence
        (:mod:`vibrospeed.estimators.grid`).
    temper_fs : Hz or None (default: ``temper`` is per sample). Set, ``temper`` is the power
        at this sample rate and a recording sampled at ``fs`` uses ``min(1, temper *
        temper_fs / fs)`` per sample (:attr:`temper_step`): the tempered evidence *per second*
        and its balance with per-second evidence (the grid's comb) then do not depend on the
        sample rate (benchmarks/beyond/RESULTS.md).
    null_model : time-domain emission of the "no line" state. ``"white"`` (default):
        ``y ~ N(0, null_var)``. ``"mixture"``: the signal part's own one-step predictive
        density, ``p0(y_k) = sum_j p(omega_j | y_1..k-1, line) p(y_k | omega_j, y_1..k-1)``
        (tempered like the grid's), so the per-sample data never favour "line" over "no
        line": a single strong line (idling engine, resonance) that the harmonic model fits
        no longer proves that a *wheel* is turning; that decision is left to ``extra``
        evidence that scores the harmonic comb (:mod:`vibrospeed.estimators.grid`) and to the
        switching rates. The data still place omega within the signal part.
    point : the point estimate :func:`estimate` reports as the Track's ``omega``: ``"mean"``
        (the paper's posterior mean) or ``"mode"``: the conditional mean of the window
        ``|omega - x| <= max(amb_abs, amb_rel x)`` whose mass most exceeds a flat posterior's,
        ``sum_window (w_j - (1 - p_null) u_j)`` with ``u`` the prior (uniform in omega): a
        window, not the highest grid point, so a spiky posterior does not make the point hop
        between close peaks (benchmarks/trackers/RESULTS.md); its excess, not its mass, so
        where the data say little the widest windows (the top of the range) do not win
        (benchmarks/robustness/RESULTS.md). Windows tied within round-off (a flat posterior)
        go to the one nearest the mean. Its basin is the set of windows reached from it by
        non-increasing window excess; ``p_mode`` is the mass they cover. For a unimodal
        posterior both are equal; while the posterior is split between lines (acquisition
        from a uniform prior, a resonance, omega/2) the global mean lies between the modes,
        on no line, while the mode mean stays on the most probable one. Both are always in
        the outputs (``omega`` and ``omega_mode``, with the basin's share ``p_mode`` of the
        signal mass); samples with ``p_mode < mode_share`` are flagged ``multimodal``.
        ``step``/``run`` report the chosen one as ``omega`` (and the mean as ``omega_mean``).
    mode_hold : hysteresis of the mode in the causal filter (``step`` / ``run``; 1: none): the
        current mode window, re-centred on its best window within its half-width, is kept
        unless the best window holds more than ``mode_hold`` times its mass (plain masses:
        their ratio, unlike that of excesses, has a meaning), so a second line
        that briefly draws level does not make the point estimate hop.
        The smoothers report the stateless mode.
    claim_level : posterior probability of "a line is present", ``1 - p_null``, at which the
        tracker claims a line (``has_signal``); 0.5 is the maximum a-posteriori decision, a
        higher level trades recall for precision (a decision threshold, not part of the model:
        the posterior and the point are the same at every level).
    q_omega_fast, p_fast : two-component ("slow cruise / fast acceleration") omega random
        walk (off by default, ``p_fast = 0`` is the paper's kernel): each
        step's increment is drawn from ``(1 - p_fast) N(0, T q_omega) + p_fast N(0, T
        q_omega_fast)`` (rad/s)^2/s, i.e. kernel rows ``K = (1 - p_fast) K_slow + p_fast
        K_fast`` with each component normalised over the grid. The band B (and the work per
        sample) follows the wider component; the ``kernel_tol`` bound holds for the mixture
        rows. Memory stays O(N B).
    """

    model: HarmonicModel = field(default_factory=paper_model)
    n_grid: int = 200
    omega_min: float = 10.0
    omega_max: float = 120.0
    spacing: str = "linear"
    kernel: str = "banded"
    kernel_tol: float = 1e-9
    kernel_var: str = "sampled"
    omega0: float | None = None
    omega0_std: float = 2.0
    log_floor: float = 600.0
    level: float = 0.98
    prefilter: str = "paper-hp"
    scaling: str = "rms"
    rms_tau: float = _scaling.DEFAULT_TAU
    signal_rms: float = _scaling.DEFAULT_SIGNAL_RMS
    nyquist: str = "warn"
    jump_rate: float = 0.0
    off_rate: float = 0.0
    on_rate: float = 1.0
    null_var: float | None = None
    p_null0: float | None = None
    amb_rel: float = 0.05
    amb_abs: float = 1.5
    smooth: str = "none"
    lag: float = 2.0
    fit: str = ""
    temper: float = 1.0
    temper_fs: float | None = None
    null_model: str = "white"
    point: str = "mean"
    mode_share: float = 0.9
    mode_hold: float = 1.0
    claim_level: float = 0.5
    q_omega_fast: float = 0.0
    p_fast: float = 0.0

    def __post_init__(self) -> None:
        # numpy's grid takes no float count (40.0 failed there, NaN / inf in int())
        n = self.n_grid
        if not (isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1):
            raise ParameterError(f"n_grid must be a positive integer, got {self.n_grid}")
        # the kernel holds a (2M, 2M) phasor transition per grid point (and kernel=exact an
        # (n_grid, n_grid) matrix): n_grid or M = 1e12 died allocating TiB (MemoryError)
        n, M = int(n), int(self.model.M)  # Python ints: no int64 wrap-around
        need = max(n * (2 * M) ** 2, n * n if self.kernel == "exact" else 0)
        if need > MAX_FLOATS:
            raise ParameterError(f"n_grid = {n} and M = {M} are too large: the grid's transition "
                                 f"arrays (n_grid * (2M)^2, with kernel=exact n_grid^2) would "
                                 f"hold {need:.3g} floats, at most {MAX_FLOATS:.3g} (1 GiB)")
        if not 0 <= self.omega_min <= self.omega_max < math.inf:
            raise ParameterError(
                f"grid needs 0 <= omega_min <= omega_max < inf rad/s, got [{self.omega_min}, "
                f"{self.omega_max}]"
            )
        if self.n_grid > 1 and not self.omega_min < self.omega_max:
            raise ParameterError("omega_min must be < omega_max when n_grid > 1")
        if self.spacing not in ("linear", "log"):
            raise ParameterError(f"spacing must be 'linear' or 'log', got '{self.spacing}'")
        if self.spacing == "log" and self.omega_min <= 0:
            raise ParameterError("spacing='log' needs omega_min > 0")
        if self.kernel not in ("banded", "exact"):
            raise ParameterError(f"kernel must be 'banded' or 'exact', got '{self.kernel}'")
        if self.kernel_var not in ("sampled", "matched"):
            raise ParameterError(f"kernel_var must be 'sampled' or 'matched', got "
                                 f"'{self.kernel_var}'")
        if not 0 < self.kernel_tol < 0.5:
            raise ParameterError(f"kernel_tol must be in (0, 0.5), got {self.kernel_tol}")
        if not 0 < self.level < 1:
            raise ParameterError(f"level must be in (0, 1), got {self.level}")
        if not self.omega0_std > 0:
            raise ParameterError(f"omega0_std must be > 0, got {self.omega0_std}")
        # a NaN or infinite omega0 made every output NaN
        if self.omega0 is not None and not math.isfinite(self.omega0):
            raise ParameterError(f"omega0 must be finite rad/s (or None), got {self.omega0}")
        if self.omega0 is not None and self.omega0 < 0:  # a prior below the grid: its bottom
            raise ParameterError(f"omega0 must be >= 0 rad/s (or None), got {self.omega0}")
        # a NaN signal_rms made every output NaN, a negative one flipped the signal; a bad
        # rms_tau failed only once a recording was scaled
        for name in ("rms_tau", "signal_rms"):
            if not 0 < getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and > 0, got {getattr(self, name)}")
        if not 10 <= self.log_floor <= 700:
            raise ParameterError(f"log_floor must be in [10, 700] nats, got {self.log_floor}")
        if self.scaling not in ("rms", "none"):
            raise ParameterError(f"scaling must be 'rms' or 'none', got '{self.scaling}'")
        if self.nyquist not in ("warn", "error"):
            raise ParameterError(f"nyquist must be 'warn' or 'error', got '{self.nyquist}'")
        for name in ("jump_rate", "off_rate", "on_rate", "amb_rel", "amb_abs"):
            if not getattr(self, name) >= 0:
                raise ParameterError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.off_rate == math.inf:  # every step left the line: all output NaN
            raise ParameterError(f"off_rate must be finite, got {self.off_rate}")
        if self.off_rate > 0 and not self.on_rate > 0:
            raise ParameterError("on_rate must be > 0 when off_rate > 0")
        if self.p_null0 is not None and not 0 < self.p_null0 < 1:
            raise ParameterError(f"p_null0 must be in (0, 1) (or None), got {self.p_null0}")
        if self.null_var is not None and not self.null_var > 0:
            raise ParameterError(f"null_var must be > 0, got {self.null_var}")
        if self.smooth not in ("none", "fb", "lag"):
            raise ParameterError(f"smooth must be 'none', 'fb' or 'lag', got '{self.smooth}'")
        if self.null_model not in ("white", "mixture"):
            raise ParameterError(f"null_model must be 'white' or 'mixture', got "
                                 f"'{self.null_model}'")
        if not 0 < self.temper <= 1:
            raise ParameterError(f"temper must be in (0, 1], got {self.temper}")
        if self.temper_fs is not None and not self.temper_fs > 0:
            raise ParameterError(f"temper_fs must be > 0 Hz (or None), got {self.temper_fs}")
        if self.point not in ("mean", "mode"):
            raise ParameterError(f"point must be 'mean' or 'mode', got '{self.point}'")
        if not self.q_omega_fast >= 0:
            raise ParameterError(f"q_omega_fast must be >= 0, got {self.q_omega_fast}")
        if not 0 <= self.p_fast <= 1:
            raise ParameterError(f"p_fast must be in [0, 1], got {self.p_fast}")
        if not 0 < self.mode_share <= 1:
            raise ParameterError(f"mode_share must be in (0, 1], got {self.mode_share}")
        if not 0 < self.claim_level < 1:
            raise ParameterError(f"claim_level must be in (0, 1), got {self.claim_level}")
        if not self.mode_hold >= 1:
            raise ParameterError(f"mode_hold must be >= 1, got {self.mode_hold}")
        if not (self.lag > 0 and math.isfinite(self.lag)):  # inf: smooth=fb is the whole log
            raise ParameterError(f"lag must be a finite number > 0 s (smooth=fb smooths over "
                                 f"the whole log), got {self.lag}")
        bad = [p for p in self.fit_names if p not in ("q_omega", "q_amp", "r")]
        if bad:
            raise ParameterError(f"fit: unknown parameter(s) {', '.join(bad)} "
                                 "(choose from q_omega, q_amp, r)")

    @property
    def fit_names(self) -> list[str]:
        """Parameters named in ``fit``."""
        return [p.strip() for p in str(self.fit).split(",") if p.strip()]

    def claims(self, p_null):
        """``has_signal`` (1.0 / 0.0, float64, array or 0-d) for the "no line" mass ``p_null``:
        a line is claimed where ``1 - p_null >= claim_level``."""
        return np.asarray(1.0 - np.asarray(p_null) >= self.claim_level, dtype=np.float64)

    @property
    def has_fast(self) -> bool:
        """Whether the omega random walk is the two-component mixture (``p_fast > 0``)."""
        return self.p_fast > 0

    @property
    def has_null(self) -> bool:
        """Whether the "no line" state is part of the model."""
        return self.off_rate > 0

    def rates(self) -> tuple[float, float, float, float]:
        """Per-step probabilities ``(eps_jump, p_off, p_on, null_var)``."""
        T = self.model.dt
        eps = -np.expm1(-self.jump_rate * T)
        p_off = -np.expm1(-self.off_rate * T) if self.has_null else 0.0
        p_on = -np.expm1(-self.on_rate * T) if self.has_null else 0.0
        nv = self.null_var if self.null_var is not None else self.signal_rms**2
        return float(eps), float(p_off), float(p_on), float(nv)

    @classmethod
    def from_paper_table1(cls, dt: float = 0.01, **kw) -> Config:
        """Paper Table I / IV-B: M = 3, var(v^omega) = 4, var(v^a,b) = 0.001, var(a_0) = 0.1,
        N = 200 linear on [10, 120] rad/s, HP order 2 at 8 Hz; ``r`` = :data:`DEFAULT_R`."""
        return cls(model=paper_model(dt), n_grid=200, omega_min=10.0, omega_max=120.0, **kw)

    @property
    def temper_step(self) -> float:
        """Power on each sample's predictive likelihood: ``temper``, or with ``temper_fs``
        ``min(1, temper * temper_fs * dt)``."""
        if self.temper_fs is None:
            return float(self.temper)
        return min(1.0, float(self.temper) * (float(self.temper_fs) * self.model.dt))

    @cached_property
    def kern(self) -> Kernel:
        """Grid and transition kernel (built once per config)."""
        return build_kernel(self)

    @property
    def grid(self) -> np.ndarray:
        """(N,) grid of omega in rad/s."""
        return self.kern.grid

    def to_dict(self) -> dict:
        """JSON-serialisable parameters (model flattened)."""
        return flat_dict(self)

def improved(config: Config | None = None, **kw) -> Config:
    """``config`` (default: the paper's) with :data:`IMPROVED` (re-acquisition jumps, "no line"
    state)
    switched on;
    ``kw`` overrides any Config field."""
    base = Config() if config is None else config
    kw = {**IMPROVED, **kw}
    mkw = {k: kw.pop(k) for k in list(kw) if k in ("M", "q_omega", "q_amp", "r", "p0_amp")}
    return dataclasses.replace(base, model=dataclasses.replace(base.model, **mkw), **kw)


#: noise levels for the improved tracker on the running-RMS scaled signal
#: (benchmarks/beyond/RESULTS.md):
#: between the marginal-likelihood fits on the car (r 0.2, q_omega 16, q_amp 0.002) and the
#: cart (r 0.0125, q_omega 0.125, q_amp 0.002); r large enough that a weak line still beats
#: the "no line" state.
IMPROVED_NOISE = {"r": 0.15, "q_amp": 0.002}
#: the settings used by :func:`improved` and ``params={"improved": True}``: jumps at
#: 0.05/s (a lost track is re-found within ~1/(0.05 * share of evidence) s; the posterior
#: cost is a floor of eps u_j on far grid points), "no line" state entered at 0.05/s, left at
#: 0.5/s, plus :data:`IMPROVED_NOISE`.
IMPROVED = {"jump_rate": 0.05, "off_rate": 0.05, "on_rate": 0.5, **IMPROVED_NOISE}
