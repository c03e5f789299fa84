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

Standstill representation: the grid must start at ``omega_min = 0``, so the point ``omega = 0``
*is* standstill (linear spacing required: the exact whole-cell shift needs equal cells).
While the standstill flag is up the random walk uses ``q_omega_still`` (default 0: a standing
vehicle keeps omega = 0 until the mode detector sees it start); with the walk on, mass would
leak to the next grid point every step and the posterior *mean* of a distribution cut at 0
would stay near one grid spacing instead of 0 (the EKF's Gaussian, clipped at 0, has no such
bias).

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

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid as gridmod
from vibrospeed.estimators import rbpmf
from vibrospeed.estimators.aiding import Sample, aiding_inputs, input_arrays, running_gain
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal import detectors as det
from vibrospeed.signal.detectors import _mode_core, _window_core
from vibrospeed.types import Estimate

STANDSTILL_KINDS = ("none", "window")


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

    def __post_init__(self) -> None:
        tr = self.tracker
        if not (self.wheel_radius and self.wheel_radius > 0):
            raise ParameterError(f"wheel_radius must be > 0 m, got {self.wheel_radius}")
        if tr.spacing != "linear" or tr.n_grid < 2:
            raise ParameterError("aided rbpmf needs a linear grid of >= 2 points "
                                 "(spacing='linear')")
        if tr.omega_min != 0.0:
            raise ParameterError(f"aided rbpmf needs omega_min = 0 (the grid point omega = 0 is "
                                 f"standstill), got {tr.omega_min}")
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
    number ``count`` of samples seen."""

    grid: rbpmf.State
    offset: float
    window: det.WindowState
    mode: det.ModeState
    buf: np.ndarray | None = None
    count: int = 0


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
            u: float) -> tuple[bool, bool, bool, float]:
    """Detectors in place -> (standstill, accelerating, boost, ubar)."""
    acc, boost, ubar = _mode_core(mode.buf, mode.pos_count, mode.flag, u, config.mode_mu)
    ss = False
    if config.standstill == "window":
        ss = bool(_window_core(window.buf, window.pos_count, window.flag, y, config.ss_mu))
    return ss and not acc, bool(acc), bool(boost), float(ubar)


def _core(config: Config, g: rbpmf.State, offset: float, y: float, u: float, gain: float,
          ref: float, ref_var: float, ss: bool, acc: bool, boost: bool,
          ubar: float, ext: np.ndarray | None = None) -> tuple[rbpmf.State, float, _Posterior]:
    """One sample on a detector decision; ``g`` is modified in place before the RBPMF step;
    ``ext`` the comb evidence of a frame ending here (None: none)."""
    T = config.tracker.model.dt
    r = config.wheel_radius
    if boost and config.boost:
        offset = _move(config, g, offset, config.mode_len * T * ubar / r)
    if not acc:
        offset = _resolve(config, g, offset)
    ll = None
    if ss or (np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0):
        om = config.grid + offset
        ll = np.zeros(om.size)
        if ss:
            ll -= 0.5 * om * om / config.r_ss
        if np.isfinite(ref) and np.isfinite(ref_var) and ref_var > 0:
            ll -= 0.5 * (om - ref) ** 2 / ref_var
        ll0 = g.log_w_null
        if np.isfinite(ll0):  # "no line": omega uniform on the (linear) grid
            mx = np.max(ll)
            ll0 = ll0 + mx + np.log(np.mean(np.exp(ll - mx)))
        g = rbpmf.State(g.log_w + ll, g.mean, g.cov, ll0, g.mode_j)
    vib, accel, still = config.trackers
    cfg = accel if acc else (still if ss else vib)
    yin = np.nan if acc else y * gain
    if acc and not config.comb_in_accel:
        ext = None
    g, e = rbpmf.step(cfg, g, yin, extra=ext)
    est = _output(e.omega, e.omega_std, e.omega_map, e.omega_lo, e.omega_hi, e.p_null, offset,
                  ss, acc, boost, ubar, e.amplitudes)
    if acc and np.isfinite(u):
        g = _copy_grid(g)
        offset = _move(config, g, offset, T * (u + config.accel_bias) / r)
    return g, offset, est


#: extras of :func:`step`'s :class:`~vibrospeed.types.Estimate`: MAP (rad/s), mass of the
#: "no line" state, acceleration / boost modes, ubar (m/s^2, mean of the last a_x), amplitudes
ESTIMATE_EXTRAS = ("omega_map", "p_null", "accelerating", "boost", "ubar", "amplitudes")


def _output(om, sd, omap, lo, hi, p_null, offset, ss, acc, boost, ubar, amps) -> _Posterior:
    return _Posterior(max(om + offset, 0.0), float(sd), max(omap + offset, 0.0),
                    max(lo + offset, 0.0), max(hi + offset, 0.0), float(p_null), bool(ss),
                    bool(acc), bool(boost), float(ubar), np.asarray(amps))


def step(config: Config, state: State, y: float | Sample, u: float = np.nan, *,
         gain: float = 1.0, ref: float = np.nan, ref_var: float = np.nan
         ) -> tuple[State, Estimate]:
    """Process one sample (inputs as :func:`vibrospeed.estimators.aided.step`, or its
    :class:`~vibrospeed.estimators.aiding.Sample`: ``y`` the pre-filtered vibration sample in
    m/s^2 read by the standstill test, ``y * gain`` fed to the RBPMF, ``u`` = a_x in m/s^2,
    ``ref``/``ref_var`` an omega fix; this tracker has no ``still`` / ``comb`` inputs)."""
    if isinstance(y, Sample):
        y, u, gain, ref, ref_var = y[:5]
    window = det.WindowState(state.window.buf.copy(), state.window.pos_count.copy(),
                             state.window.flag.copy())
    mode = det.ModeState(state.mode.buf.copy(), state.mode.pos_count.copy(),
                         state.mode.flag.copy())
    ss, acc, boost, ubar = _decide(config, window, mode, float(y), float(u))
    ext, buf = None, state.buf
    if config.comb is not None:
        yy = np.array([float(y) * float(gain)])
        idx, vals = gridmod.evidence(config.comb, yy,
                                     gridmod.State(state.grid, state.buf, state.count))
        ext = vals[0] if idx.size else None
        buf = _push(state.buf, state.count, yy)
    g = _copy_grid(state.grid)
    g, offset, est = _core(config, g, float(state.offset), float(y), float(u), float(gain),
                           float(ref), float(ref_var), ss, acc, boost, ubar, ext)
    extras = {k: getattr(est, k) for k in ESTIMATE_EXTRAS}
    return State(g, offset, window, mode, buf, state.count + 1), Estimate(
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
        ref_var: np.ndarray | None = None, state: State | None = None) -> Result:
    """Run over whole signals (``y`` may be a :class:`~vibrospeed.estimators.aiding.Sample` of
    arrays; scalars hold for every sample); identical to repeated :func:`step`.

    The detectors depend on the inputs only, so they run first (same compiled cores);
    stretches of plain vibration samples (no standstill, no fix, no acceleration mode, offset 0)
    go to :func:`rbpmf.run` in one call, the other samples through the per-sample core.
    """
    if isinstance(y, Sample):
        n = np.size(y.y)
        y, u, gain, ref, ref_var = (np.full(n, v, dtype=np.float64) if np.ndim(v) == 0 else v
                                    for v in y[:5])
    y = np.ascontiguousarray(y, dtype=np.float64)
    n = y.size
    u, gain, ref, ref_var = input_arrays(n, u, gain, ref, ref_var, "aided_grid.run")
    st = init(config) if state is None else state
    window = det.WindowState(st.window.buf.copy(), st.window.pos_count.copy(),
                             st.window.flag.copy())
    mode = det.ModeState(st.mode.buf.copy(), st.mode.pos_count.copy(), st.mode.flag.copy())
    acc, boost, ubar = det._mode_run(u, mode.buf, mode.pos_count, mode.flag, config.mode_mu)
    if config.standstill == "window":
        ss = det._window_run(y, window.buf, window.pos_count, window.flag, config.ss_mu)
    else:
        ss = np.zeros(n, np.bool_)
    ss = ss & ~acc
    has_ref = np.isfinite(ref) & np.isfinite(ref_var) & (ref_var > 0)
    special = ss | acc | boost | has_ref
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
                               ev_vals[ev_row[k]] if ev_row[k] >= 0 else None)
        out[k] = est[:6]
        amps[k] = est.amplitudes
        k += 1
    return Result(*(out[:, c] for c in range(6)), ss, acc, boost, ubar, amps,
                  State(g, offset, window, mode, buf, st.count + n))


# ---------------------------------------------------------------------------------------------
#: parameters of :func:`estimate` that are neither Config, rbpmf.Config nor HarmonicModel fields
INPUT_PARAMS = ("accel_axis", "lp_cutoff", "reference", "wheelbase", "accel_detrend")

#: ``tracker=grid``: the grid product's tracker settings
#: (:data:`vibrospeed.estimators.grid.GRID_DEFAULTS`: jumps, "no line" state with the mixture
#: null model, tempered likelihood, mode estimate) on the aided model, plus its comb evidence
#: (:class:`vibrospeed.estimators.grid.Config` defaults). The noise levels and q_omega stay the
#: aided ones (the aiding follows the accelerations that the product's q_omega = 16 covers).
GRID_TRACKER = {"jump_rate": 0.05, "off_rate": 0.01, "on_rate": 0.5, "temper": 1.0,
                "null_model": "mixture", "point": "mode"}
#: comb-evidence parameters accepted by :func:`estimate` (grid.Config fields)
COMB_PARAMS = tuple(f.name for f in dataclasses.fields(gridmod.Config) if f.name != "tracker")


def estimate(
    recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    kind: str = "rbpmf",
):
    """Aided RBPMF tracking of omega (``--method aided -p tracker=rbpmf``, or ``kind="grid"``:
    ``-p tracker=grid``, the grid product's "no line" state, jumps, tempering, mode estimate
    (:data:`GRID_TRACKER`) and harmonic-comb evidence (``comb_*`` params, defaults of
    :class:`vibrospeed.estimators.grid.Config`)).

    ``params``: any :class:`Config` field, any :class:`rbpmf.Config` field (grid ``n_grid``,
    ``omega_max``, ``prefilter``, ``scaling``, ``off_rate`` ...; defaults of
    :func:`_cart_tracker`), any :class:`HarmonicModel` field (``dt`` from the data), and the
    inputs shared with the EKF version (``accel_axis``, ``lp_cutoff``, ``reference``,
    ``wheelbase``, ``accel_detrend``; see :func:`vibrospeed.estimators.aided.estimate`).
    The Track's band is the grid posterior's credible interval (``level``).
    """
    from vibrospeed.config import config_from_params
    from vibrospeed.estimators.common import axis_channel, check_uniform, split_params, start_level
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.types import Track

    del progress
    r = wheel_radius or recording.wheel_radius
    if not r:
        raise ParameterError(
            f"{recording.source or 'recording'}: the aided tracker needs the wheel radius "
            "(pass wheel_radius=... / --wheel-radius, or use a recording that knows it)")
    if kind not in ("rbpmf", "grid"):
        raise ParameterError(f"tracker must be 'ekf', 'rbpmf' or 'grid', got '{kind}'")
    params = dict(params or {})
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
    dt = check_uniform(recording)
    base = _cart_tracker(dt)
    mdef = base.model.to_dict()
    mdef["dt"] = dt
    model = config_from_params(HarmonicModel, model_kw, **mdef)
    tdef = {f.name: getattr(base, f.name) for f in dataclasses.fields(rbpmf.Config)
            if f.name in ("n_grid", "omega_min", "omega_max", "prefilter", "scaling",
                          "kernel_var")}
    tracker = config_from_params(rbpmf.Config, tr_kw, model=model, **tdef)
    comb = (config_from_params(gridmod.Config, comb_kw, tracker=tracker) if kind == "grid"
            else None)
    config = config_from_params(Config, cfg_kw, tracker=tracker, wheel_radius=float(r),
                                comb=comb)
    src = recording.source or "recording"
    if tracker.omega_max >= np.pi / dt:
        raise ParameterError(f"{src}: omega_max {tracker.omega_max:g} rad/s needs fs > "
                             f"{tracker.omega_max / np.pi:.4g} Hz (lower omega_max)")
    vib_name = axis_channel(axis)
    recording.require(vib_name)
    x = recording.channel(vib_name)
    lp = inp.get("lp_cutoff")
    lp = None if lp in (None, "", "none") else float(lp)
    sos = pf.design(tracker.prefilter, 1.0 / dt, M=model.M, lp_cutoff=lp)
    y = pf.apply(sos, x, level=start_level(x, dt))
    u, ref, ref_var, notes = aiding_inputs(
        recording, dt, float(r), accel_axis=str(inp.get("accel_axis", "ax")),
        detrend=float(inp.get("accel_detrend", 0.0)),
        reference=str(inp.get("reference", "none")), wheelbase=inp.get("wheelbase"))
    notes = [f"pre-filter '{tracker.prefilter}' on '{vib_name}' at fs = {1 / dt:.4g} Hz",
             f"aided rbpmf: {tracker.n_grid} grid points on [0, {tracker.omega_max:g}] rad/s, "
             f"standstill test '{config.standstill}'"] + notes
    if comb is not None:
        notes.append(f"tracker=grid: 'no line' state (off {tracker.off_rate:g}/s, on "
                     f"{tracker.on_rate:g}/s, null model '{tracker.null_model}'), jumps "
                     f"{tracker.jump_rate:g}/s, temper {tracker.temper:g}, point "
                     f"'{tracker.point}'; harmonic-comb evidence ({comb.comb_window:g} s frames "
                     f"every {comb.comb_hop:g} s, weight {comb.comb_weight:g})")
    gain = None
    if tracker.scaling == "rms":
        gain = tracker.signal_rms * running_gain(y, dt, tracker.rms_tau)
        notes.append(f"RBPMF input normalised by a running RMS (tau = {tracker.rms_tau:g} s)")
    res = run(config, y, u, gain=gain, ref=ref, ref_var=ref_var)
    extras = {f"amp{m + 1}": res.amplitudes[:, m] for m in range(model.M)}
    extras.update(standstill=res.standstill.astype(np.float64),
                  accelerating=res.accelerating.astype(np.float64),
                  boost=res.boost.astype(np.float64), ubar=res.ubar, omega_map=res.omega_map,
                  p_null=res.p_null, has_signal=(res.p_null <= 0.5).astype(np.float64))
    out_params = {**tracker.to_dict(), **{f.name: getattr(config, f.name)
                                          for f in dataclasses.fields(Config)
                                          if f.name not in ("tracker", "comb")},
                  **({k: getattr(comb, k) for k in COMB_PARAMS} if comb is not None else {}),
                  "ss_n": config.ss_len, "mode_n": config.mode_len,
                  "tracker": kind, "axis": axis, "lp_cutoff": lp,
                  **{k: inp.get(k) for k in INPUT_PARAMS if k != "lp_cutoff"}}
    return Track.from_omega(recording.t, res.omega, res.omega_std, lo=res.omega_lo,
                            hi=res.omega_hi, level=tracker.level, wheel_radius=float(r),
                            method="aided", params=out_params, extras=extras, notes=notes)
