# Over 500 lines: the aiding's hooks on the grid posterior (shift, merge, standstill, comb)
# share one state and one loop; splitting them would separate the equations from their code.
"""Inertial aiding around the RBPMF grid tracker (thesis ch. 3 applied to paper III-D;
METHODS.md 1.3 and 2).

The aiding of :mod:`vibrospeed.estimators.aided` acts on omega only, through three hooks; on the
grid posterior of :mod:`vibrospeed.estimators.rbpmf` they become:

* **acceleration integration** (thesis eq. 3.10): ``omega_{k+1} = omega_k + (T / r)(u_k + b)``
  is a translation of the posterior density along the omega axis. Each grid hypothesis
  ``omega_i`` carries its own phasor Kalman filter, so the translation moves weight *and* linear
  state together: the mass of point ``i`` goes to ``omega_i + s``; where that lies between two
  grid points ``j, j+1`` it is split linearly (``1 - f``, ``f``) and the phasor filters arriving at
  a point are merged by moment matching (the same merge as the RBPMF transition, METHODS 1.3
  step 4). Splitting at every sample would diffuse the posterior by ``f (1 - f) dx^2`` per step
  (with dx = 0.25 rad/s and 0.6 m/s^2 at 100 Hz about 1 (rad/s)^2 per second, more than the
  random walk), so whole-cell moves are made exactly (an index shift, no diffusion) and the
  sub-cell remainder is carried in the state as ``offset`` (``|offset| <= dx / 2``): the
  posterior is the grid posterior displaced by ``offset``. The remainder is resolved (one linear
  split) before the next vibration update, whose likelihood is evaluated at the grid points.
  Mass pushed below the first (or above the last) grid point stays there: omega is clipped at
  0, as in the EKF version.
* **mode detector and boost** (thesis 3.3, eq. 3.14-3.15): in acceleration mode the vibration
  update is skipped (the RBPMF step runs with a NaN sample: prediction only) and the omega
  random walk uses ``q_omega_accel``; on the switch into acceleration mode the posterior is
  shifted by ``N_mode T ubar / r`` (N_mode samples in the mode window).
* **scalar omega measurements**: the standstill virtual measurement ``omega = 0`` with
  variance ``R_ss`` (thesis eq. 3.4-3.6) and reference-speed fixes multiply the grid weights by
  ``N(z; omega_j + offset, R)``. Multiplying the prior before the RBPMF step equals multiplying
  the posterior after its measurement update (the per-point Kalman filters do not depend on
  the weights), so the RBPMF's own step is used unchanged.

Standstill representation: with the thesis' window test the grid must start at
``omega_min = 0``, so the point ``omega = 0`` *is* standstill (linear spacing required: the
exact whole-cell shift needs equal cells). With ``standstill='broadband'`` (flags computed
before the loop) a grid above 0 is allowed: a standing sample is then a plain vibration sample
that adds nothing to the aiding, and the caller reports omega = 0 there, as the grid product
does.
While the standstill flag is up the random walk uses ``q_omega_still`` (default 0: a standing
vehicle keeps omega = 0 until the mode detector sees it start); with the walk on, mass would
leak to the next grid point every step and the posterior *mean* of a distribution cut at 0
would stay near one grid spacing instead of 0 (the EKF's Gaussian, clipped at 0, has no such
bias).

Continuous aiding (``aiding="continuous"``, the default of ``tracker=grid``): the thesis' mode
detector reads an absolute threshold on a_x (0.2 m/s^2), which a car's body motion crosses most
of the time, and then skips the vibration update. On a grid posterior the two sources combine
without a switch: the integral of ``u + accel_bias`` over each hop of ``aid_len`` samples
(``aid_hop`` s; standing samples and NaN add nothing) shifts the posterior at the hop's last
sample (one linear split, so the sub-cell diffusion ``f (1 - f) dx^2`` is paid once per hop,
not per sample), and the vibration update runs at every sample. The random walk ``q_omega``
then only needs to cover the aiding's error. The mode detector's ``accelerating`` and
``boost`` are never set.

Bias: unlike the EKF version there is no bias state (a grid over (omega, b) would square the
cost); ``accel_bias`` is a fixed known offset added to ``u``. On real data the offset of the
forward axis is removed before (``accel_detrend`` in :func:`estimate`).

"No line" state and comb evidence (``tracker=grid``): the tracker config may
carry the RBPMF's "no line" state (``off_rate`` > 0; its omega is unknown, i.e. uniform on the
grid) and ``comb`` (a :class:`vibrospeed.estimators.grid.Config`) adds the harmonic-comb
log-evidence of the grid product every ``comb_hop`` s (``rbpmf.step(..., extra=E)``; frames of the
RBPMF input ``y * gain``, kept in a ring buffer in the state). The scalar omega measurements
above then also weigh the "no line" state by its marginal likelihood ``p(z | no line) =
mean_j N(z; omega_j + offset, R)`` (uniform omega), so a standstill measurement puts the mass
on the line state at 0. In acceleration mode the comb evidence is skipped (``comb_in_accel``:
a 3 s spectrum lags a fast speed change; the vibration update is skipped there too). The
integration and the boost move only the line part; the "no line" part stays uniform.

Conventions as in the RBPMF: the stored state is the prior for the next sample, ``step``
returns the posterior at ``t_k``; ``run`` gives exactly the numbers of repeated ``step``
(vibration-only stretches are passed to :func:`rbpmf.run`, which equals repeated
:func:`rbpmf.step`). Only the RBPMF's public API is used (``Config``, ``State``, ``init``,
``step``, ``run``, ``Config.grid``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import grid as gridmod
from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.aiding import (
    Sample,
    aiding_inputs,
    input_arrays,
    running_gain,
    standstill_band,
    standstill_flags,
    standstill_offset,
)
from vibrospeed.estimators.grid.method import GRID_DEFAULTS
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal import detectors as det
from vibrospeed.signal.detectors import _mode_core, _window_core
from vibrospeed.types import Estimate, Track

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
    accel_bias : fixed offset b (m/s^2) added to u (no bias state, see module docstring).
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
        acceleration mode), 'continuous' (module docstring, "Continuous aiding") or 'none'.
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
        if not (self.wheel_radius and self.wheel_radius > 0):
            raise ParameterError(f"wheel_radius must be > 0 m, got {self.wheel_radius}")
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
        if not self.q_omega_still >= 0:
            raise ParameterError(f"q_omega_still must be >= 0, got {self.q_omega_still}")
        if self.q_omega_accel is not None and not self.q_omega_accel >= 0:
            raise ParameterError(f"q_omega_accel must be >= 0, got {self.q_omega_accel}")
        if not np.isfinite(self.accel_bias):
            raise ParameterError(f"accel_bias must be finite, got {self.accel_bias}")
        for name in ("ss_n", "mode_n"):
            v = getattr(self, name)
            if v is not None and (int(v) != v or v < 1):
                raise ParameterError(f"{name} must be a positive integer, got {v}")
        for name in ("ss_window", "mode_window"):
            if not getattr(self, name) > 0:
                raise ParameterError(f"{name} must be > 0 s, got {getattr(self, name)}")
        if self.aiding not in AIDING_KINDS:
            raise ParameterError(f"aiding must be one of {', '.join(AIDING_KINDS)}, got "
                                 f"'{self.aiding}'")
        if not self.aid_hop > 0:
            raise ParameterError(f"aid_hop must be > 0 s, got {self.aid_hop}")
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


class State(NamedTuple):
    """Prior for the next sample: ``grid`` (RBPMF state), ``offset`` (rad/s, sub-cell shift not
    yet applied to the grid), detector states ``window`` and ``mode``; with comb evidence the
    last ``comb.frame_len`` RBPMF inputs ``buf`` (ring buffer, oldest at ``count % L``) and the
    number ``count`` of samples seen; ``usum`` (m/s^2 x samples) the sum of ``u + accel_bias`` in
    the current aiding hop (``aiding='continuous'``)."""

    grid: rbpmf.State
    offset: float
    window: det.WindowState
    mode: det.ModeState
    buf: np.ndarray | None = None
    count: int = 0
    usum: float = 0.0


class _Posterior(NamedTuple):
    """Posterior at one sample (rad/s); band = the tracker's credible interval (the first six
    fields are the run's columns in this order)."""

    omega: float
    omega_std: float
    omega_map: float
    omega_lo: float
    omega_hi: float
    p_null: float
    standstill: bool
    accelerating: bool
    boost: bool
    ubar: float
    amplitudes: np.ndarray


def init(config: Config) -> State:
    """RBPMF prior of the tracker config (uniform over the grid unless its ``omega0`` is set),
    no offset, empty detectors (and an empty comb frame buffer)."""
    buf = None if config.comb is None else np.zeros(config.comb.frame_len)
    return State(rbpmf.init(config.tracker), 0.0, det.window_init(config.ss_len),
                 det.mode_init(config.mode_len), buf, 0)


def _push(buf: np.ndarray, count: int, y: np.ndarray) -> np.ndarray:
    """Ring buffer ``buf`` (oldest at ``count % L``) after appending ``y``."""
    L = buf.size
    out = buf.copy()
    if y.size >= L:
        pos = (count + y.size - L + np.arange(L)) % L
        out[pos] = y[-L:]
    else:
        out[(count + np.arange(y.size)) % L] = y
    return out


# ---------------------------------------------------------------------------------------------
@njit(cache=True)
def _shift(lw, mean, cov, s, p0):
    """Move every grid point's mass by ``s`` cells (float) in place: point ``i`` goes to
    ``i + s``, split linearly between the two neighbouring points, clamped to the grid ends;
    phasor filters merged by moment matching; empty points get the prior N(0, p0 I)."""
    N, n = mean.shape
    mx = -np.inf
    for i in range(N):
        if lw[i] > mx:
            mx = lw[i]
    k = int(np.floor(s))
    f = s - k
    W = np.zeros(N)
    M1 = np.zeros((N, n))
    M2 = np.zeros((N, n, n))
    for i in range(N):
        wi = np.exp(lw[i] - mx)
        if wi == 0.0:
            continue
        for part in range(2):
            a = (1.0 - f) if part == 0 else f
            if a == 0.0:
                continue
            j = i + k + part
            if j < 0:
                j = 0
            elif j > N - 1:
                j = N - 1
            lam = wi * a
            W[j] += lam
            mi = mean[i]
            Pi = cov[i]
            for p in range(n):
                M1[j, p] += lam * mi[p]
                for q in range(n):
                    M2[j, p, q] += lam * (Pi[p, q] + mi[p] * mi[q])
    for j in range(N):
        if W[j] > 0.0:
            inv = 1.0 / W[j]
            for p in range(n):
                mean[j, p] = M1[j, p] * inv
            for p in range(n):
                for q in range(p, n):
                    v = M2[j, p, q] * inv - mean[j, p] * mean[j, q]
                    cov[j, p, q] = v
                    cov[j, q, p] = v
            lw[j] = np.log(W[j]) + mx
        else:
            lw[j] = -np.inf
            for p in range(n):
                mean[j, p] = 0.0
                for q in range(n):
                    cov[j, p, q] = p0 if p == q else 0.0


def _copy_grid(g: rbpmf.State) -> rbpmf.State:
    return rbpmf.State(np.array(g.log_w, dtype=np.float64), np.array(g.mean, dtype=np.float64),
                       np.array(g.cov, dtype=np.float64), float(g.log_w_null), int(g.mode_j))


def _move(config: Config, g: rbpmf.State, offset: float, delta: float) -> float:
    """Add ``delta`` rad/s: whole cells moved exactly (in place on ``g``), remainder returned."""
    dx = config.dx
    tot = offset + delta
    k = int(np.round(tot / dx))
    if k != 0:
        _shift(g.log_w, g.mean, g.cov, float(k), config.tracker.model.p0_amp)
    return tot - k * dx


def _resolve(config: Config, g: rbpmf.State, offset: float) -> float:
    """Apply the sub-cell offset by one linear split; returns the new offset 0."""
    if offset != 0.0:
        _shift(g.log_w, g.mean, g.cov, offset / config.dx, config.tracker.model.p0_amp)
    return 0.0


def _decide(config: Config, window: det.WindowState, mode: det.ModeState, y: float,
            u: float, still: float = np.nan) -> tuple[bool, bool, bool, float]:
    """Detectors in place -> (standstill, accelerating, boost, ubar)."""
    acc, boost, ubar = _mode_core(mode.buf, mode.pos_count, mode.flag, u, config.mode_mu)
    if config.aiding != "mode":
        acc = boost = False
    if config.standstill == "broadband":
        ss = bool(still > 0.5)
        return ss, bool(acc) and not ss, bool(boost) and not ss, float(ubar)
    ss = False
    if config.standstill == "window":
        ss = bool(_window_core(window.buf, window.pos_count, window.flag, y, config.ss_mu))
    return ss and not acc, bool(acc), bool(boost), float(ubar)


def _aid_sums(config: Config, u: np.ndarray, ss: np.ndarray, count: int,
              usum: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Continuous aiding over samples ``count .. count + n - 1``: ``(hop_end, total, usum)``
    with ``hop_end`` (n,) the hops' last samples, ``total`` (n,) the sum of ``u + accel_bias``
    over the hop ending there (0 elsewhere; standing and NaN samples add nothing) and the
    running sum carried past the last sample."""
    L = config.aid_len
    n = u.size
    add = np.where(np.isfinite(u) & ~ss, u + config.accel_bias, 0.0)
    hop_end = (count + np.arange(n) + 1) % L == 0
    total = np.zeros(n)
    s = float(usum)
    for k in range(n):  # sequential sums: the numbers of repeated step
        s += float(add[k])
        if hop_end[k]:
            total[k] = s
            s = 0.0
    return hop_end, total, s


def _core(config: Config, g: rbpmf.State, offset: float, y: float, u: float, gain: float,
          ref: float, ref_var: float, ss: bool, acc: bool, boost: bool,
          ubar: float, ext: np.ndarray | None = None,
          shift: float = 0.0) -> tuple[rbpmf.State, float, _Posterior]:
    """One sample on a detector decision; ``g`` is modified in place before the RBPMF step;
    ``ext`` the comb evidence of a frame ending here (None: none); ``shift`` rad/s of
    continuous aiding applied after the step (one linear split)."""
    T = config.tracker.model.dt
    r = config.wheel_radius
    if boost and config.boost:
        offset = _move(config, g, offset, config.mode_len * T * ubar / r)
    if not acc:
        offset = _resolve(config, g, offset)
    ll = None
    ss_m = ss and config.ss_on_grid
    if ss_m or (np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0):
        om = config.grid + offset
        ll = np.zeros(om.size)
        if ss_m:
            ll -= 0.5 * om * om / config.r_ss
        if np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0:
            ll -= 0.5 * (om - ref) ** 2 / ref_var
        ll0 = g.log_w_null
        if np.isfinite(ll0):  # "no line": omega uniform on the (linear) grid
            mx = np.max(ll)
            ll0 = ll0 + mx + np.log(np.mean(np.exp(ll - mx)))
        g = rbpmf.State(g.log_w + ll, g.mean, g.cov, ll0, g.mode_j)
    vib, accel, still = config.trackers
    cfg = accel if acc else (still if ss_m else vib)
    yin = np.nan if acc else y * gain
    if acc and not config.comb_in_accel:
        ext = None
    g, e = rbpmf.step(cfg, g, yin, extra=ext)
    est = _output(e.omega, e.omega_std, e.omega_map, e.omega_lo, e.omega_hi, e.p_null, offset,
                  ss, acc, boost, ubar, e.amplitudes)
    if acc and np.isfinite(u):
        g = _copy_grid(g)
        offset = _move(config, g, offset, T * (u + config.accel_bias) / r)
    if shift != 0.0:
        g = _copy_grid(g)
        offset = _resolve(config, g, offset + shift)
    return g, offset, est


#: extras of :func:`step`'s :class:`~vibrospeed.types.Estimate`: MAP (rad/s), mass of the
#: "no line" state, acceleration / boost modes, ubar (m/s^2, mean of the last a_x), amplitudes
ESTIMATE_EXTRAS = ("omega_map", "p_null", "accelerating", "boost", "ubar", "amplitudes")


def _output(om, sd, omap, lo, hi, p_null, offset, ss, acc, boost, ubar, amps) -> _Posterior:
    return _Posterior(max(om + offset, 0.0), float(sd), max(omap + offset, 0.0),
                    max(lo + offset, 0.0), max(hi + offset, 0.0), float(p_null), bool(ss),
                    bool(acc), bool(boost), float(ubar), np.asarray(amps))


def step(config: Config, state: State, y: float | Sample, u: float = np.nan, *,
         gain: float = 1.0, ref: float = np.nan, ref_var: float = np.nan,
         still: float = np.nan) -> tuple[State, Estimate]:
    """Process one sample (inputs as :func:`vibrospeed.estimators.aided.step`, or its
    :class:`~vibrospeed.estimators.aiding.Sample`: ``y`` the pre-filtered vibration sample in
    m/s^2 read by the standstill test, ``y * gain`` fed to the RBPMF, ``u`` = a_x in m/s^2,
    ``ref``/``ref_var`` an omega fix, ``still`` the standstill flag read with
    ``standstill='broadband'``; this tracker has no ``comb`` input)."""
    if isinstance(y, Sample):
        y, u, gain, ref, ref_var, still = y[:6]
    window = det.WindowState(state.window.buf.copy(), state.window.pos_count.copy(),
                             state.window.flag.copy())
    mode = det.ModeState(state.mode.buf.copy(), state.mode.pos_count.copy(),
                         state.mode.flag.copy())
    ss, acc, boost, ubar = _decide(config, window, mode, float(y), float(u), float(still))
    shift, usum = 0.0, float(state.usum)
    if config.aiding == "continuous":
        if np.isfinite(u) and not ss:
            usum += float(u) + config.accel_bias
        if (state.count + 1) % config.aid_len == 0:
            shift = config.tracker.model.dt * usum / config.wheel_radius
            usum = 0.0
    ext, buf = None, state.buf
    if config.comb is not None:
        yy = np.array([float(y) * float(gain)])
        idx, vals = gridmod.evidence(config.comb, yy,
                                     gridmod.State(state.grid, state.buf, state.count))
        ext = vals[0] if idx.size else None
        buf = _push(state.buf, state.count, yy)
    g = _copy_grid(state.grid)
    g, offset, est = _core(config, g, float(state.offset), float(y), float(u), float(gain),
                           float(ref), float(ref_var), ss, acc, boost, ubar, ext, shift)
    extras = {k: getattr(est, k) for k in ESTIMATE_EXTRAS}
    return State(g, offset, window, mode, buf, state.count + 1, usum), Estimate(
        est.omega, est.omega_std, est.omega_lo, est.omega_hi,
        has_signal=float(1.0 - est.p_null >= 0.5), standstill=float(est.standstill),
        extras=extras)


class Result(NamedTuple):
    """Batch output over samples (n,) unless noted: the columns of :func:`step`'s estimates."""

    omega: np.ndarray
    omega_std: np.ndarray
    omega_map: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    p_null: np.ndarray
    standstill: np.ndarray
    accelerating: np.ndarray
    boost: np.ndarray
    ubar: np.ndarray
    amplitudes: np.ndarray  # (n, M)
    final: State


def run(config: Config, y: np.ndarray | Sample, u: np.ndarray | None = None, *,
        gain: np.ndarray | None = None, ref: np.ndarray | None = None,
        ref_var: np.ndarray | None = None, still: np.ndarray | None = None,
        state: State | None = None) -> Result:
    """Run over whole signals (``y`` may be a :class:`~vibrospeed.estimators.aiding.Sample` of
    arrays; scalars hold for every sample); identical to repeated :func:`step`.

    The detectors depend on the inputs only, so they run first (same compiled cores);
    stretches of plain vibration samples (no standstill, no fix, no acceleration mode, offset 0)
    go to :func:`rbpmf.run` in one call, the other samples through the per-sample core.
    """
    if isinstance(y, Sample):
        n = np.size(y.y)
        y, u, gain, ref, ref_var, still = (
            np.full(n, v, dtype=np.float64) if np.ndim(v) == 0 else v for v in y[:6])
    y = np.ascontiguousarray(y, dtype=np.float64)
    n = y.size
    u, gain, ref, ref_var = input_arrays(n, u, gain, ref, ref_var, "aided_grid.run")
    still = np.full(n, np.nan) if still is None else np.ascontiguousarray(still, np.float64)
    if still.shape != (n,):
        raise InputError(f"aided_grid.run: 'still' has shape {still.shape}, expected ({n},) "
                         "like y")
    st = init(config) if state is None else state
    window = det.WindowState(st.window.buf.copy(), st.window.pos_count.copy(),
                             st.window.flag.copy())
    mode = det.ModeState(st.mode.buf.copy(), st.mode.pos_count.copy(), st.mode.flag.copy())
    acc, boost, ubar = det._mode_run(u, mode.buf, mode.pos_count, mode.flag, config.mode_mu)
    if config.aiding != "mode":
        acc, boost = np.zeros(n, np.bool_), np.zeros(n, np.bool_)
    if config.standstill == "broadband":
        ss = still > 0.5
        acc, boost = acc & ~ss, boost & ~ss
    else:
        if config.standstill == "window":
            ss = det._window_run(y, window.buf, window.pos_count, window.flag, config.ss_mu)
        else:
            ss = np.zeros(n, np.bool_)
        ss = ss & ~acc
    has_ref = np.isfinite(ref) & np.isfinite(ref_var) & (ref_var > 0)
    special = (ss if config.ss_on_grid else np.zeros(n, np.bool_)) | acc | boost | has_ref
    shift = np.zeros(n)
    usum = float(st.usum)
    if config.aiding == "continuous":
        hop_end, total, usum = _aid_sums(config, u, ss, st.count, usum)
        shift[hop_end] = config.tracker.model.dt * total[hop_end] / config.wheel_radius
        special = special | (shift != 0.0)
    yin = y * gain
    ev_row = np.full(n, -1, np.int64)
    ev_idx, ev_vals, buf = np.zeros(0, np.int64), np.zeros((0, 0)), st.buf
    if config.comb is not None:
        ev_idx, ev_vals = gridmod.evidence(config.comb, yin,
                                           gridmod.State(st.grid, st.buf, st.count))
        ev_row[ev_idx] = np.arange(ev_idx.size)
        buf = _push(st.buf, st.count, yin)
    M = config.tracker.model.M
    out = np.full((n, 6), np.nan)
    amps = np.full((n, M), np.nan)
    g = _copy_grid(st.grid)
    offset = float(st.offset)
    k = 0
    while k < n:
        if not special[k] and offset == 0.0:
            e = k + 1
            while e < n and not special[e]:
                e += 1
            sel = (ev_idx >= k) & (ev_idx < e)
            extra = (ev_idx[sel] - k, ev_vals[sel]) if np.any(sel) else None
            res = rbpmf.run(config.tracker, yin[k:e], g, extra=extra)
            g = res.final
            out[k:e] = np.column_stack([np.maximum(res.omega, 0.0), res.omega_std,
                                        np.maximum(res.omega_map, 0.0),
                                        np.maximum(res.omega_lo, 0.0),
                                        np.maximum(res.omega_hi, 0.0), res.p_null])
            amps[k:e] = res.amplitudes
            k = e
            continue
        g = _copy_grid(g)
        g, offset, est = _core(config, g, offset, float(y[k]), float(u[k]), float(gain[k]),
                               float(ref[k]), float(ref_var[k]), bool(ss[k]), bool(acc[k]),
                               bool(boost[k]), float(ubar[k]),
                               ev_vals[ev_row[k]] if ev_row[k] >= 0 else None, float(shift[k]))
        out[k] = est[:6]
        amps[k] = est.amplitudes
        k += 1
    return Result(*(out[:, c] for c in range(6)), ss, acc, boost, ubar, amps,
                  State(g, offset, window, mode, buf, st.count + n, usum))


# ---------------------------------------------------------------------------------------------
#: parameters of :func:`estimate` that are neither Config, rbpmf.Config nor HarmonicModel fields
INPUT_PARAMS = ("accel_axis", "lp_cutoff", "reference", "wheelbase", "accel_detrend",
                "accel_offset", "causal")

#: ``tracker=grid``: the grid product's tracker and model settings
#: (:data:`vibrospeed.estimators.grid.method.GRID_DEFAULTS`: jumps, "no line" state with the
#: mixture null model, likelihood tempered to 0.05 per 10 ms, whitening pre-filter, running-RMS
#: scaling, mode estimate; r, q_amp, q_omega of the product) plus its comb evidence
#: (:class:`vibrospeed.estimators.grid.Config` defaults); the aiding: broadband standstill
#: flags, continuous aiding, a_x from the mount estimate (:mod:`vibrospeed.signal.mount`).
GRID_TRACKER = {**{k: v for k, v in GRID_DEFAULTS.items() if k != "smooth"},
                "scaling": "rms", "standstill": "broadband", "aiding": "continuous",
                "accel_axis": "mount"}
#: comb-evidence parameters accepted by :func:`estimate` (grid.Config fields)
COMB_PARAMS = tuple(f.name for f in dataclasses.fields(gridmod.Config) if f.name != "tracker")


def _product_model(dt: float) -> HarmonicModel:
    """The grid product's harmonic model at period ``dt`` (paper Table I with the product's
    r, q_amp, q_omega)."""
    mkw = {k: GRID_DEFAULTS[k] for k in ("r", "q_amp", "q_omega") if k in GRID_DEFAULTS}
    return dataclasses.replace(rbpmf.Config.from_paper_table1(dt).model, **mkw)


def _vibration(recording, vib_name: str, tracker: rbpmf.Config, lp: float | None,
               dt: float) -> np.ndarray:
    """The pre-filtered vibration axis (adaptive presets whitened after their SOS)."""
    from vibrospeed.estimators.common import start_level
    from vibrospeed.signal import prefilter as pf

    x = recording.channel(vib_name)
    sos = pf.design(tracker.prefilter, 1.0 / dt, M=tracker.model.M, lp_cutoff=lp,
                    omega_range=(max(tracker.omega_min, 1e-3), tracker.omega_max))
    y = pf.apply(sos, x, level=start_level(x, dt))
    if tracker.prefilter in pf.ADAPTIVE:
        from vibrospeed.signal import whiten

        y = whiten.apply(y, 1.0 / dt)
    return y


def _standstill_input(recording, vib_name: str, dt: float, band, causal: bool,
                      on_grid: bool) -> np.ndarray:
    """Broadband standstill flags on the vibration axis and every other accelerometer axis;
    ``on_grid`` (the tracker holds omega = 0 while standing): each stop shortened at both ends
    (:func:`vibrospeed.estimators.aiding.standstill_flags`), else the detector's stops as
    :func:`vibrospeed.estimators.grid.method.with_standstill` reports them."""
    from vibrospeed.signal import standstill as ss

    chans = [vib_name] + [c for c in ("ax", "ay", "az") if c != vib_name and c in recording
                          and np.isfinite(recording.channel(c)).any()]
    X = np.column_stack([recording.channel(c) for c in chans])
    if on_grid:
        return standstill_flags(X, dt, band, causal=causal)
    return ss.standstill(X, dt, band, causal=causal).astype(np.float64)


def estimate(
    recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    kind: str = "rbpmf",
):
    """Aided RBPMF tracking of omega (``--method aided -p tracker=rbpmf``, the thesis cart's
    grid, or ``kind="grid"``: ``-p tracker=grid``, the grid product's settings
    (:data:`GRID_TRACKER`) with harmonic-comb evidence (``comb_*`` params, defaults of
    :class:`vibrospeed.estimators.grid.Config`)).

    ``params``: any :class:`Config` field, any :class:`rbpmf.Config` field (grid ``n_grid``,
    ``omega_max``, ``prefilter``, ``scaling``, ``off_rate`` ...), any :class:`HarmonicModel`
    field (``dt`` from the data), and the inputs shared with the EKF version (``accel_axis``,
    ``lp_cutoff``, ``reference``, ``wheelbase``, ``accel_detrend``, ``accel_offset``,
    ``causal``; see :func:`vibrospeed.estimators.aided.estimate`).

    ``kind="grid"``: the grid product's grid, pre-filter and scaling
    (:func:`vibrospeed.estimators.rbpmf.prepare`, ``omega_min`` / ``omega_max`` the search
    range); standstill from the broadband detector (whole log, ``causal=true``: the causal
    one) over the search band, omega = 0 on its stops (reported from the flags: the grid need
    not contain 0). ``accel_axis='mount'`` (default): first the grid product's own estimate
    (:func:`vibrospeed.estimators.grid.estimate`, smoothed offline, ``smooth=none`` with
    ``causal=true``); the mount estimate of :mod:`vibrospeed.signal.mount` on ``ax, ay, az``,
    referenced to its speed where it claims a line. With ``causal=true`` and a confident mount
    the aided causal filter runs on the longitudinal acceleration; otherwise the grid estimate
    is the result (no trustworthy axis to aid with, or offline, where the smoother's
    look-ahead scored above the aided causal filter on the randomised family). A named axis
    (``ax``, ``-ay`` ...) is used as given, minus its
    mean while standing (``accel_offset='standstill'``), in the aided causal filter.
    The Track's band is the grid posterior's credible interval (``level``).
    """
    from vibrospeed.config import config_from_params, parse_flag
    from vibrospeed.estimators.common import axis_channel, check_uniform, split_params

    del progress
    r = wheel_radius or recording.wheel_radius
    if not r:
        raise ParameterError(
            f"{recording.source or 'recording'}: the aided tracker needs the wheel radius "
            "(pass wheel_radius=... / --wheel-radius, or use a recording that knows it)")
    if kind not in ("rbpmf", "grid"):
        raise ParameterError(f"tracker must be 'ekf', 'rbpmf' or 'grid', got '{kind}'")
    params = dict(params or {})
    src = recording.source or "recording"
    dt = check_uniform(recording)
    if kind == "grid":
        params = {**GRID_TRACKER, **params}
    inp = {k: params.pop(k) for k in INPUT_PARAMS if k in params}
    comb_kw = {k: params.pop(k) for k in COMB_PARAMS if k in params}
    if comb_kw and kind != "grid":
        raise ParameterError(f"{', '.join(comb_kw)}: comb evidence needs tracker=grid")
    model_kw, rest = split_params(HarmonicModel, params)
    model_kw.pop("dt", None)
    tr_names = {f.name for f in dataclasses.fields(rbpmf.Config)} - {"model"}
    tr_kw = {k: v for k, v in rest.items() if k in tr_names}
    cfg_kw = {k: v for k, v in rest.items() if k not in tr_names}
    lp = inp.get("lp_cutoff")
    lp = None if lp in (None, "", "none") else float(lp)
    vib_name = axis_channel(axis)
    recording.require(vib_name)
    gain = None
    if kind == "grid":
        # the grid product's pre-filter, scaling and Nyquist checks on the same config
        tracker, y, _, notes = rbpmf.prepare(recording, axis, rbpmf.Config,
                                             {**model_kw, **tr_kw, "smooth": "none"},
                                             _product_model)
    else:
        base = _cart_tracker(dt)
        tdef = {f.name: getattr(base, f.name) for f in dataclasses.fields(rbpmf.Config)
                if f.name in ("n_grid", "omega_min", "omega_max", "prefilter", "scaling",
                              "kernel_var")}
        mdef = base.model.to_dict()
        mdef["dt"] = dt
        model = config_from_params(HarmonicModel, model_kw, **mdef)
        tracker = config_from_params(rbpmf.Config, tr_kw, model=model, **tdef)
        if tracker.omega_max >= np.pi / dt:
            raise ParameterError(f"{src}: omega_max {tracker.omega_max:g} rad/s needs fs > "
                                 f"{tracker.omega_max / np.pi:.4g} Hz (lower omega_max)")
        y = _vibration(recording, vib_name, tracker, lp, dt)
        notes = [f"pre-filter '{tracker.prefilter}' on '{vib_name}' at fs = {1 / dt:.4g} Hz"]
        if tracker.scaling == "rms":
            gain = tracker.signal_rms * running_gain(y, dt, tracker.rms_tau)
            notes.append(f"RBPMF input normalised by a running RMS (tau = "
                         f"{tracker.rms_tau:g} s)")
    model = tracker.model
    comb = (config_from_params(gridmod.Config, comb_kw, tracker=tracker) if kind == "grid"
            else None)
    config = config_from_params(Config, cfg_kw, tracker=tracker, wheel_radius=float(r),
                                comb=comb)
    causal = parse_flag(inp.get("causal", False), "causal")
    notes.append(f"aided rbpmf: {tracker.n_grid} grid points on [{tracker.omega_min:g}, "
                 f"{tracker.omega_max:g}] rad/s, standstill test '{config.standstill}', "
                 f"aiding '{config.aiding}'")
    accel_axis = str(inp.get("accel_axis", "ax"))
    still = None
    if config.standstill == "broadband" and accel_axis != "mount":
        band = standstill_band(dt, model.M, tracker.omega_min if kind == "grid" else None,
                               tracker.omega_max)
        still = _standstill_input(recording, vib_name, dt, band, causal, config.ss_on_grid)
        notes.append(f"standstill: broadband vibration and body motion at their floors "
                     f"({'causal' if causal else 'whole-log'} detector, band "
                     f"{band[0]:.3g}-{band[1]:.3g} rad/s), on {100 * still.mean():.1f} % of "
                     "the samples")
    ref = ref_var = None
    mount_info = {}
    if accel_axis == "mount":
        if inp.get("reference", "none") != "none":
            raise ParameterError("reference fixes need a named accel_axis (e.g. ax) with "
                                 "tracker=grid")
        # the grid product's estimate on the same settings: the mount's reference and,
        # where the mount is not confident, the result
        gparams = {**model_kw, **tr_kw, **comb_kw, "smooth": "none" if causal else "fb"}
        base_tr = gridmod.estimate(recording, axis=axis, wheel_radius=float(r),
                                   params=gparams)
        u, mount_info, note = _mount_input(recording, base_tr, dt, float(r))
        if u is not None and not causal:
            # offline the smoother's look-ahead beats the aided causal filter on the family
            # even where the mount is confident (benchmarks/robustness/AIDED.md)
            u, note = None, (f"{note}; offline the grid tracker's smoothed estimate is kept "
                             "(the aiding is for the causal filter, causal=true)")
        if u is None:
            base_params = {**base_tr.params, "tracker": kind, "accel_axis": accel_axis,
                           "causal": causal, **mount_info}
            return dataclasses.replace(
                base_tr, method="aided", params=base_params,
                notes=[*base_tr.notes, f"{note}: the grid tracker's estimate (-m grid"
                       f"{'' if not causal else ' -p smooth=none'})"])
        still = np.asarray(base_tr.extras["standstill"], dtype=np.float64)
        more = [f"{note}; the mount itself is estimated from the whole log (a device needs it "
                "calibrated beforehand: -p accel_axis=... names the longitudinal axis)"]
    else:
        u, ref, ref_var, more = aiding_inputs(
            recording, dt, float(r), accel_axis=accel_axis,
            detrend=float(inp.get("accel_detrend", 0.0)),
            reference=str(inp.get("reference", "none")), wheelbase=inp.get("wheelbase"))
        if str(inp.get("accel_offset", "none" if kind == "rbpmf" else "standstill")) \
                == "standstill" and still is not None:
            off = standstill_offset(u, still, causal=causal)
            u = u - off
            more.append(f"'{accel_axis}' offset removed: its mean while standing "
                        f"({off[-1]:.3g} m/s^2 at the end)")
    if comb is not None:
        notes.append(f"tracker=grid: 'no line' state (off {tracker.off_rate:g}/s, on "
                     f"{tracker.on_rate:g}/s, null model '{tracker.null_model}'), jumps "
                     f"{tracker.jump_rate:g}/s, temper {tracker.temper:g}, point "
                     f"'{tracker.point}'; harmonic-comb evidence ({comb.comb_window:g} s frames "
                     f"every {comb.comb_hop:g} s, weight {comb.comb_weight:g})")
    res = run(config, y, u, gain=gain, ref=ref, ref_var=ref_var, still=still)
    notes += more
    omega, std, lo, hi = res.omega.copy(), res.omega_std.copy(), res.omega_lo.copy(), \
        res.omega_hi.copy()
    if still is not None:
        st = still > 0.5
        for a in (omega, std, lo, hi):
            a[st] = 0.0
    extras = {f"amp{m + 1}": res.amplitudes[:, m] for m in range(model.M)}
    has_signal = (res.p_null <= 0.5).astype(np.float64)
    if still is not None:
        has_signal[still > 0.5] = 0.0
    extras.update(standstill=res.standstill.astype(np.float64),
                  accelerating=res.accelerating.astype(np.float64),
                  boost=res.boost.astype(np.float64), ubar=res.ubar, omega_map=res.omega_map,
                  p_null=res.p_null, has_signal=has_signal)
    out_params = {**tracker.to_dict(), **{f.name: getattr(config, f.name)
                                          for f in dataclasses.fields(Config)
                                          if f.name not in ("tracker", "comb")},
                  **({k: getattr(comb, k) for k in COMB_PARAMS} if comb is not None else {}),
                  "ss_n": config.ss_len, "mode_n": config.mode_len,
                  "tracker": kind, "axis": axis, "lp_cutoff": lp,
                  **mount_info,
                  **{k: inp.get(k) for k in INPUT_PARAMS if k != "lp_cutoff"}}
    out_params["accel_axis"] = accel_axis
    return Track.from_omega(recording.t, omega, std, lo=lo, hi=hi, level=tracker.level,
                            wheel_radius=float(r), method="aided", params=out_params,
                            extras=extras, notes=notes)


def _mount_input(recording, base: Track, dt: float, r: float
                 ) -> tuple[np.ndarray | None, dict, str]:
    """``accel_axis='mount'``: the longitudinal acceleration from the mount estimate of
    :mod:`vibrospeed.signal.mount` on ``ax, ay, az``, referenced to the grid tracker's track
    ``base`` where it claims a line; None when the mount is not confident. Returns
    ``(u or None, mount params, note)``."""
    from vibrospeed.signal import mount as mountmod

    chans = ("ax", "ay", "az")
    if not all(c in recording and np.isfinite(recording.channel(c)).any() for c in chans):
        return None, {"mount_confident": False}, "not aided (the mount needs ax, ay and az)"
    A = np.column_stack([recording.channel(c) for c in chans])
    m = mountmod.estimate(A, dt, omega=np.asarray(base.omega, dtype=np.float64),
                          wheel_radius=r, still=base.extras.get("standstill"),
                          usable=base.extras.get("has_signal"))
    info = {"mount_confident": m.confident, "mount_slope": m.slope, "mount_rho": m.rho,
            "mount_t": m.t,
            "mount_forward": [float(v) for v in m.forward]}
    desc = (f"mount: forward axis {np.round(m.forward, 3).tolist()} in the sensor frame "
            f"(correlation {m.rho:.2f}, t = {m.t:.1f}, slope {m.slope:.2f} against r d omega/dt of "
            f"the grid tracker, {m.used_s:.0f} s used)")
    if not m.confident:
        return None, info, f"not aided: {desc} not confident"
    return mountmod.longitudinal(A, m), info, f"aided by the longitudinal acceleration, {desc}"
