"""Bootstrap Rao-Blackwellized particle filter on the harmonic model (paper III-C; METHODS.md 1.2).

Particles ``omega_i`` (i = 1..K), each with a Kalman filter (mean (2M,), covariance (2M, 2M)) of
the phasor states and a log-weight. One iteration for sample ``y_k`` (state = prior at k, as in
:mod:`vibrospeed.estimators.rbpmf`):

1. ``log w_i += log N(y_k; h m_i, h P_i h' + r)``, KF measurement update per particle;
   normalise in log space;
2. output: weighted mean, std, the ``level`` credible interval (weighted quantiles) of omega,
   widened to hold the mean where one particle carries the weight (:func:`_measure`);
3. resample (:mod:`vibrospeed.estimators.resampling`; multinomial as the paper, or systematic)
   when ``ESS < ess_threshold * K``; weights then reset to ``1/K``;
4. KF time update with ``F(omega_i)`` (the old omega, model eq. 4c), then the bootstrap
   proposal ``omega_i += sqrt(T var(v^omega)) z``, ``z ~ N(0, 1)``, reflected into
   ``[omega_min, omega_max]``.

Randomness only through the generator the state carries (:func:`init` seeds it from
``Config.seed`` unless given one; :func:`step` and :func:`run` draw from a copy and return it
advanced in the new state); each step draws, in this order, the resampling uniforms (only when
it resamples) and ``K`` normals. ``run`` is a Python loop over the compiled step pieces and
equals repeated :func:`step`. Pre-filter and scaling are the grid tracker's
(:func:`vibrospeed.estimators.grid.app.prepare`).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import check_state, flat_dict, is_count
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import resampling
from vibrospeed.estimators.grid.app import prepare
from vibrospeed.estimators.grid.config import DEFAULT_R, MAX_FLOATS
from vibrospeed.estimators.kalman import predict_one, rotation_blocks, update_one
from vibrospeed.estimators.scaling import DEFAULT_SIGNAL_RMS, DEFAULT_TAU
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.types import Estimate, Recording, Track


def _paper_model(dt: float = 0.01) -> HarmonicModel:
    return HarmonicModel.from_paper_table1(dt, r=DEFAULT_R)


@dataclass(frozen=True)
class Config:
    """RBPF parameters (defaults: paper Table I).

    model : harmonic model (as :class:`vibrospeed.estimators.rbpmf.Config`).
    n_particles : K (paper: 3000). omega_min, omega_max : support in rad/s (paper grid range,
        initial particles uniform on it unless ``omega0`` is given; proposals are reflected).
    scheme : "multinomial" (paper) or "systematic". ess_threshold : resample when
        ESS < ess_threshold * K (0: never; > 1: every step, the plain bootstrap filter).
    seed : seed of the generator :func:`init` creates (recorded in the Track's params).
    level, prefilter, scaling, rms_tau, signal_rms, nyquist : as for the RBPMF.
    """

    model: HarmonicModel = field(default_factory=_paper_model)
    n_particles: int = 3000
    omega_min: float = 10.0
    omega_max: float = 120.0
    omega0: float | None = None
    omega0_std: float = 2.0
    scheme: str = "multinomial"
    ess_threshold: float = 0.5
    seed: int = 0
    level: float = 0.98
    prefilter: str = "paper-hp"
    scaling: str = "rms"
    rms_tau: float = DEFAULT_TAU
    signal_rms: float = DEFAULT_SIGNAL_RMS
    nyquist: str = "warn"

    def __post_init__(self) -> None:
        if not is_count(self.n_particles):
            raise ParameterError(f"n_particles must be a positive integer, got {self.n_particles}")
        # each particle holds 2M phasors and their (2M, 2M) covariance: n_particles or M = 1e12
        # died allocating PiB (MemoryError)
        K, M = int(self.n_particles), int(self.model.M)
        if K * (2 * M) * (2 * M + 1) > MAX_FLOATS:
            raise ParameterError(f"n_particles = {K} and M = {M} are too large: the particles' "
                                 f"phasors and covariances (n_particles * 2M * (2M + 1)) would "
                                 f"hold {K * (2 * M) * (2 * M + 1):.3g} floats, at most "
                                 f"{MAX_FLOATS:.3g} (1 GiB)")
        if not 0 <= self.omega_min <= self.omega_max < math.inf:
            raise ParameterError(
                f"support needs 0 <= omega_min <= omega_max < inf rad/s, got [{self.omega_min}, "
                f"{self.omega_max}]"
            )
        # a NaN omega0 made every output NaN; omega0_std <= 0 or NaN was used as given
        if self.omega0 is not None and not 0 <= self.omega0 < math.inf:
            raise ParameterError(f"omega0 must be finite and >= 0 rad/s (or None), got "
                                 f"{self.omega0}")
        if not 0 < self.omega0_std < math.inf:
            raise ParameterError(f"omega0_std must be finite and > 0 rad/s, got "
                                 f"{self.omega0_std}")
        resampling.get_scheme(self.scheme)
        if not self.ess_threshold >= 0:
            raise ParameterError(f"ess_threshold must be >= 0, got {self.ess_threshold}")
        if not is_count(self.seed, 0):
            raise ParameterError(f"seed must be an integer >= 0, got {self.seed}")
        for name in ("rms_tau", "signal_rms"):
            if not 0 < getattr(self, name) < math.inf:
                raise ParameterError(f"{name} must be finite and > 0, got {getattr(self, name)}")
        if not 0 < self.level < 1:
            raise ParameterError(f"level must be in (0, 1), got {self.level}")
        if self.scaling not in ("rms", "none"):
            raise ParameterError(f"scaling must be 'rms' or 'none', got '{self.scaling}'")
        if self.nyquist not in ("warn", "error"):
            raise ParameterError(f"nyquist must be 'warn' or 'error', got '{self.nyquist}'")

    @classmethod
    def from_paper_table1(cls, dt: float = 0.01, **kw) -> Config:
        """Paper Table I: 3000 particles, multinomial resampling, model as the RBPMF."""
        return cls(model=_paper_model(dt), n_particles=3000, scheme="multinomial", **kw)

    def to_dict(self) -> dict:
        """JSON-serialisable parameters (model flattened)."""
        return flat_dict(self)


class State(NamedTuple):
    """Prior for the next sample: ``omega`` (K,), ``log_w`` (K,) normalised, ``mean`` (K, 2M),
    ``cov`` (K, 2M, 2M), and ``rng`` the generator the next sample draws from (``step`` and
    ``run`` use a copy, so a state can be stepped twice with the same numbers)."""

    omega: np.ndarray
    log_w: np.ndarray
    mean: np.ndarray
    cov: np.ndarray
    rng: np.random.Generator


#: extras of :func:`step`'s :class:`~vibrospeed.types.Estimate`: predictive log-likelihood,
#: effective sample size (before resampling), whether the particles were resampled
ESTIMATE_EXTRAS = ("loglik", "ess", "resampled")


class Result(NamedTuple):
    """Batch output, arrays over samples: the columns of :func:`step`'s estimates."""

    omega: np.ndarray
    omega_std: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    loglik: np.ndarray
    ess: np.ndarray
    resampled: np.ndarray
    final: State


def init(
    config: Config, rng: np.random.Generator | None = None, *,
    particles: np.ndarray | None = None,
) -> State:
    """Initial particles: uniform on [omega_min, omega_max] (or N(omega0, omega0_std^2)
    clipped to it), or the given ``particles`` (K,); equal weights, means 0, cov var(a_0) I.
    The particles are drawn from ``rng`` (default: a generator seeded with ``config.seed``),
    which the state then carries."""
    rng = np.random.default_rng(config.seed) if rng is None else rng
    K = config.n_particles
    if particles is not None:
        om = np.array(particles, dtype=np.float64).ravel()
        if om.size != K:
            raise ParameterError(f"got {om.size} particles, config says n_particles = {K}")
    elif config.omega0 is None:
        om = rng.uniform(config.omega_min, config.omega_max, K)
    else:
        om = np.clip(rng.normal(config.omega0, config.omega0_std, K),
                     config.omega_min, config.omega_max)
    n = config.model.n_lin
    return State(om, np.full(K, -np.log(K)), np.zeros((K, n)),
                 np.broadcast_to(np.eye(n) * config.model.p0_amp, (K, n, n)).copy(), rng)


# ------------------------------------------------------------------------------------------
@njit(cache=True)
def _measure(om, lw, mean, cov, y, h, r, q_lo, q_hi, w, out):
    """Steps 1-2 in place; ``out`` = [mean, std, lo, hi, loglik, ess]."""
    K = om.size
    ph = np.empty(mean.shape[1])
    if np.isfinite(y):
        for i in range(K):
            ll, _, _ = update_one(mean[i], cov[i], h, r, y, ph)
            lw[i] += ll
    mx = -np.inf
    for i in range(K):
        if lw[i] > mx:
            mx = lw[i]
    s = 0.0
    for i in range(K):
        w[i] = np.exp(lw[i] - mx)
        s += w[i]
    ls = np.log(s)
    s2 = 0.0
    mu = 0.0
    for i in range(K):
        lw[i] = lw[i] - mx - ls
        w[i] = w[i] / s
        s2 += w[i] * w[i]
        mu += w[i] * om[i]
    var = 0.0
    for i in range(K):
        d = om[i] - mu
        var += w[i] * d * d
    order = np.argsort(om)
    acc = 0.0
    lo = om[order[K - 1]]
    hi = lo
    got_lo = False
    for k in range(K):
        i = order[k]
        acc += w[i]
        if not got_lo and acc >= q_lo:
            lo = om[i]
            got_lo = True
        if acc >= q_hi:
            hi = om[i]
            break
    # the band widened to hold the weighted mean, the reported omega: the particle posterior
    # is discrete (omega is sampled, not a Kalman state: the particles' Gaussians are of the
    # phasors alone), so when one particle carries more than ``level`` of the weight (ESS ~ 1)
    # both quantiles are that particle while the mean sits off it (cart seed 4, K = 100,
    # t = 0.17 s: band 99.063-99.063, mean 99.077). [min(lo, mu), max(hi, mu)] holds at least
    # the quantiles' mass; elsewhere it is their band, bit for bit
    if mu < lo:
        lo = mu
    if mu > hi:
        hi = mu
    out[0] = mu
    out[1] = np.sqrt(var)
    out[2] = lo
    out[3] = hi
    out[4] = mx + ls if np.isfinite(y) else 0.0
    out[5] = 1.0 / s2


@njit(cache=True)
def _propagate(om, mean, cov, z, M, T, sigma, Q, lo, hi, blocks):
    """Step 4 in place: KF time update with F(omega_i), then omega_i += sigma z_i, reflected."""
    K = om.size
    rotation_blocks(om, M, T, blocks)
    for i in range(K):
        predict_one(mean[i], cov[i], blocks[i], Q)
        v = om[i] + sigma * z[i]
        if hi > lo:
            span = hi - lo
            # reflect into [lo, hi] (period 2 span)
            u = (v - lo) % (2.0 * span)
            v = lo + (u if u <= span else 2.0 * span - u)
        else:
            v = lo
        om[i] = v


def _one(config: Config, om, lw, mean, cov, y, rng, w, out, blocks):
    m = config.model
    q = 0.5 * (1.0 - config.level)
    _measure(om, lw, mean, cov, float(y), m.H, float(m.r), q, 1.0 - q, w, out)
    resampled = False
    if out[5] < config.ess_threshold * om.size:
        idx = resampling.get_scheme(config.scheme)(w, om.size, rng)
        om[:] = om[idx]
        mean[:] = mean[idx]
        cov[:] = cov[idx]
        lw[:] = -np.log(om.size)
        resampled = True
    z = rng.standard_normal(om.size)
    _propagate(om, mean, cov, z, m.M, m.dt, float(np.sqrt(m.q_omega_step)),
               np.ascontiguousarray(m.Q_lin), float(config.omega_min), float(config.omega_max),
               blocks)
    return resampled


def _check_state(config: Config, state: State) -> None:
    """A state of another K or M would be read past its end by the compiled steps (heap
    corruption) or run with another particle count than the config says."""
    K, n = config.n_particles, config.model.n_lin
    check_state("rbpf", f"n_particles = {K} and M = {config.model.M}",
                omega=(state.omega, (K,)), log_w=(state.log_w, (K,)),
                mean=(state.mean, (K, n)), cov=(state.cov, (K, n, n)))


def step(config: Config, state: State, y: float) -> tuple[State, Estimate]:
    """Process one sample with randomness from (a copy of) the state's generator; returns
    (prior for next, posterior)."""
    _check_state(config, state)
    om, lw = state.omega.copy(), state.log_w.copy()
    mean, cov = state.mean.copy(), state.cov.copy()
    rng = copy.deepcopy(state.rng)
    out = np.empty(6)
    blocks = np.empty((om.size, config.model.M, 2, 2))
    res = _one(config, om, lw, mean, cov, y, rng, np.empty(om.size), out, blocks)
    extras = dict(zip(ESTIMATE_EXTRAS, (out[4], out[5], res), strict=True))
    return State(om, lw, mean, cov, rng), Estimate(*out[:4], extras=extras)


def run(config: Config, y: np.ndarray, state: State | None = None) -> Result:
    """Run over a whole signal; identical to repeated :func:`step` from ``state`` (default
    :func:`init`)."""
    st = init(config) if state is None else state
    _check_state(config, st)
    rng = copy.deepcopy(st.rng)
    om, lw = st.omega.copy(), st.log_w.copy()
    mean, cov = st.mean.copy(), st.cov.copy()
    y = np.asarray(y, dtype=np.float64)
    if y.ndim != 1:  # a TypeError from float() per sample before
        raise InputError(f"rbpf.run: y must be one-dimensional (n,), got shape {y.shape}")
    outs = np.empty((y.size, 6))
    flags = np.zeros(y.size, dtype=bool)
    w = np.empty(om.size)
    blocks = np.empty((om.size, config.model.M, 2, 2))
    for k in range(y.size):
        flags[k] = _one(config, om, lw, mean, cov, y[k], rng, w, outs[k], blocks)
    return Result(outs[:, 0], outs[:, 1], outs[:, 2], outs[:, 3], outs[:, 4], outs[:, 5], flags,
                  State(om, lw, mean, cov, rng))


def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Track omega on ``axis`` with the RBPF (pre-filter, running-RMS scaling as the RBPMF).

    ``params`` may set any :class:`Config` or :class:`HarmonicModel` field; ``seed`` seeds the
    generator. Extras: ``ess``, ``resampled`` (0/1), ``loglik``, ``rms``. ``progress`` shows a
    progress bar (the RBPF is the slow one: ~100 s per 1000 s of 100 Hz with 3000 particles).
    """
    from vibrospeed.estimators.common import run_in_chunks

    config, y, rms, notes = prepare(recording, axis, Config, params, _paper_model)
    parts: list[Result] = []

    def chunk(a: int, b: int) -> Result:  # the state carries the generator: one run's numbers
        parts.append(run(config, y[a:b], parts[-1].final if parts else None))
        return parts[-1]

    run_in_chunks(chunk, y.size, progress=progress, label="rbpf", chunk=5_000)
    res = Result(*(np.concatenate([getattr(p, f) for p in parts])
                   for f in Result._fields[:-1]), parts[-1].final)
    notes.append(f"RBPF seed {config.seed}, {config.n_particles} particles, {config.scheme}")
    extras = {"ess": res.ess, "resampled": res.resampled.astype(float), "loglik": res.loglik,
              "rms": rms}
    return Track.from_omega(
        recording.t, res.omega, res.omega_std, lo=res.omega_lo, hi=res.omega_hi,
        level=config.level, wheel_radius=wheel_radius or recording.wheel_radius, method="rbpf",
        params={**config.to_dict(), "axis": axis}, extras=extras, notes=notes,
    )
