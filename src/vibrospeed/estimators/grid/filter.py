"""Rao-Blackwellized point-mass filter, the chassis-vibration paper's variant (paper III-D,
Algorithm 1; METHODS.md 1.3).

A fixed grid ``omega_j`` (j = 1..N) carries weights ``w_j`` and, per grid point, a Kalman filter
(mean ``m_j`` (2M,), covariance ``P_j`` (2M, 2M)) of the phasor states of
:class:`vibrospeed.models.harmonic.HarmonicModel`. One iteration, for sample ``y_k``:

1. measurement update per grid point (:func:`vibrospeed.estimators.kalman.update_one`)::

       log w_j += log N(y_k; h m_j, h P_j h' + r);   normalise in log space

2. output: posterior mean, std, MAP and the ``level`` credible interval of omega from the grid
   posterior (each mass spread uniformly over its cell, so quantiles interpolate);
3. linear time update per *source* point i: ``m_i- = F(omega_i) m_i``,
   ``P_i- = F(omega_i) P_i F(omega_i)' + T Q_lin`` (F from ``HarmonicModel.F(grid)``);
4. transition ``w_ij = w_i K_ij`` with the random-walk kernel
   ``K_ij = N(omega_j; omega_i, T var(v^omega)) Delta_j / sum_j(...)`` (``Delta_j`` cell width,
   rows normalised over the grid so no mass leaves it), ``W_j = sum_i w_ij``;
5. moment-matching merge with ``lambda_ij = w_ij / W_j``::

       m_j = sum_i lambda_ij m_i-,   P_j = sum_i lambda_ij (P_i- + m_i- m_i-') - m_j m_j'

   valid because ``p(x^lin_{t+1} | omega_{t+1}, omega_t) = p(x^lin_{t+1} | omega_t)`` for this
   model (paper III-D): the N^2 pairwise filters are never formed, memory is O(N).

The state stored between samples is the *prior* for the next sample (as in
:mod:`vibrospeed.estimators.ekf`): ``step`` = steps 1-5. NaN samples skip step 1.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import NamedTuple

import numpy as np

import vibrospeed.estimators.grid.summary as cols
from vibrospeed.config import check_state
from vibrospeed.errors import ParameterError
from vibrospeed.estimators.grid.config import Config
from vibrospeed.estimators.grid.core import (
    Tables,
    _run,
    _step_from,
    soa_to_state,
    step_constants,
    step_work,
)
from vibrospeed.estimators.grid.summary import N_OUT_FIXED
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.types import Estimate

_tuple_item = tuple.__getitem__
_tuple_new = tuple.__new__


class State(tuple):
    """Prior for the next sample: ``log_w`` (N,) log-weights of the grid points, ``mean``
    (N, 2M), ``cov`` (N, 2M, 2M) per grid point, ``log_w_null`` log-weight of the "no line"
    state (-inf when the model has none), ``mode_j`` the mode window's grid point (hysteresis;
    -1: none yet). The weights sum to 1 over grid and null.

    A named tuple of these five fields (unpacking, indexing, ``_replace``, ``_asdict``,
    pickling). A state made by :func:`step` holds the means and covariances in the compiled
    loop's layout (one (L, N) array, L = 2M + 2M (2M + 1) / 2: the means and the covariances'
    upper triangles, the grid index innermost; :mod:`vibrospeed.estimators.grid.core`) and
    builds ``mean`` and ``cov`` when they are first read (one compiled pass; the numbers the
    loop holds): a stream of steps converts nothing between samples (about 5 us per sample
    at N = 200). From that read on, ``mean`` and ``cov`` are the state (a step reads them, so
    arrays changed in place count, as with plain arrays)."""

    _fields = ("log_w", "mean", "cov", "log_w_null", "mode_j")
    #: the means and covariances in the loop's layout while ``mean`` and ``cov`` are unbuilt
    _z = None

    def __new__(cls, log_w: np.ndarray, mean: np.ndarray, cov: np.ndarray,
                log_w_null: float = -np.inf, mode_j: int = -1) -> State:
        return tuple.__new__(cls, (log_w, mean, cov, log_w_null, mode_j))

    @classmethod
    def _in_loop_layout(cls, log_w: np.ndarray, z: np.ndarray, log_w_null: float,
                        mode_j: int) -> State:
        st = tuple.__new__(cls, (log_w, None, None, log_w_null, mode_j))
        st._z = z
        return st

    # the tuple's own slots (its __getitem__ and __iter__ below build mean and cov)
    log_w = property(lambda s: _tuple_item(s, 0), doc="(N,) log-weights of the grid points")
    log_w_null = property(lambda s: _tuple_item(s, 3), doc='log-weight of "no line"')
    mode_j = property(lambda s: _tuple_item(s, 4), doc="the mode window's grid point (-1: none)")

    def _built(self) -> tuple[np.ndarray, np.ndarray]:
        z = self._z
        if z is None:
            got = self.__dict__.get("_mc")
            return got if got is not None else (_tuple_item(self, 1), _tuple_item(self, 2))
        L, N = z.shape
        n = (math.isqrt(9 + 8 * L) - 3) // 2  # L = n + n (n + 1) / 2
        mean = np.empty((N, n))
        cov = np.empty((N, n, n))
        soa_to_state(z, mean, cov)
        self._mc = (mean, cov)
        self._z = None
        return self._mc

    @property
    def mean(self) -> np.ndarray:
        """(N, 2M) phasor means per grid point."""
        return self._built()[0]

    @property
    def cov(self) -> np.ndarray:
        """(N, 2M, 2M) phasor covariances per grid point."""
        return self._built()[1]

    def _values(self) -> tuple:
        mean, cov = self._built()
        return (self.log_w, mean, cov, self.log_w_null, self.mode_j)

    def __iter__(self) -> Iterator:
        return iter(self._values())

    def __getitem__(self, i):
        return self._values()[i]

    def _replace(self, **kw) -> State:
        bad = set(kw) - set(self._fields)
        if bad:
            raise ValueError(f"got unexpected field names: {sorted(bad)}")
        if self._z is not None and "mean" not in kw and "cov" not in kw:
            return State._in_loop_layout(kw.get("log_w", self.log_w), self._z,
                                         kw.get("log_w_null", self.log_w_null),
                                         kw.get("mode_j", self.mode_j))
        return State(*(kw[f] if f in kw else v for f, v in zip(self._fields, self._values(),
                                                               strict=True)))

    @classmethod
    def _make(cls, iterable) -> State:
        return cls(*iterable)

    def _asdict(self) -> dict:
        return dict(zip(self._fields, self._values(), strict=True))

    def __reduce__(self):
        return State, self._values()

    def __repr__(self) -> str:
        return "State(" + ", ".join(f"{f}={v!r}" for f, v in self._asdict().items()) + ")"


#: extras of the filter's :class:`~vibrospeed.types.Estimate` (rad/s or shares of the mass):
#: MAP grid point, predictive log-likelihood ``log p(y_k | y_1..k-1)``, mass of "no line",
#: masses near MAP/2, 2 MAP, MAP/3, 3 MAP, amplitudes (M,) at the MAP point, the grid
#: posterior (N,) of the signal part, the mode window's mean and its basin's mass, the
#: posterior mean (``omega`` is the mode's mean with ``point="mode"``), the spread of omega
#: within the mode's basin about the mode's mean
ESTIMATE_EXTRAS = ("omega_map", "loglik", "p_null", "p_half", "p_double", "amplitudes",
                   "posterior", "p_third", "p_triple", "omega_mode", "p_mode", "omega_mean",
                   "omega_mode_std")


class Result(NamedTuple):
    """Batch output, arrays over samples (n,) unless noted; the columns of :func:`step`'s
    :class:`~vibrospeed.types.Estimate` and its extras."""

    omega: np.ndarray
    omega_std: np.ndarray
    omega_map: np.ndarray
    omega_lo: np.ndarray
    omega_hi: np.ndarray
    loglik: np.ndarray
    p_null: np.ndarray
    p_half: np.ndarray
    p_double: np.ndarray
    amplitudes: np.ndarray  # (n, M)
    posterior: np.ndarray | None  # (n, N) float32 when asked for
    grid_loglik: np.ndarray | None  # (n, N + 1) float32 when asked for (last column: null)
    final: State
    p_third: np.ndarray | None = None  # mass near MAP/3
    p_triple: np.ndarray | None = None  # mass near 3 MAP
    omega_mode: np.ndarray | None = None  # mean of the highest-mass window (the mode)
    p_mode: np.ndarray | None = None  # the basin's share of the signal mass
    omega_mean: np.ndarray | None = None  # the posterior mean (= omega unless point="mode")
    omega_mode_std: np.ndarray | None = None  # spread within the mode's basin (rad/s)
    claim_level: float = 0.5  # the config's ``claim_level`` (:attr:`has_signal`)

    @property
    def has_signal(self) -> np.ndarray:
        """1.0 where the line probability ``1 - p_null`` is at least ``claim_level``, as
        :func:`step`'s ``has_signal``."""
        return (1.0 - self.p_null >= self.claim_level).astype(np.float64)


def concat(parts: list[Result]) -> Result:
    """The results of consecutive runs as one: the per-sample columns (``posterior`` and
    ``grid_loglik`` included where present) concatenated, ``final`` and ``claim_level`` the
    last run's."""
    if len(parts) == 1:
        return parts[0]
    return parts[-1]._replace(**{f: np.concatenate([getattr(p, f) for p in parts])
                                 for f in Result._fields
                                 if isinstance(getattr(parts[-1], f), np.ndarray)})


def init(config: Config) -> State:
    """Prior at the first sample: weights uniform in omega (or Gaussian around ``omega0``),
    phasor means 0, covariances ``var(alpha_0) I``; with a "no line" state, its stationary
    probability ``off / (off + on)``."""
    k = config.kern
    N = k.grid.size
    n = config.model.n_lin
    if config.omega0 is None:
        lw = np.log(k.widths)
    else:
        z = (k.grid - config.omega0) / config.omega0_std
        lw = -0.5 * z * z + np.log(k.widths)
    lw = lw - np.max(lw)
    lw = np.maximum(lw, -config.log_floor)
    lw -= np.log(np.sum(np.exp(lw)))
    lw0 = -np.inf
    if config.has_null:
        p0 = (config.off_rate / (config.off_rate + config.on_rate) if config.p_null0 is None
              else float(config.p_null0))
        lw = lw + np.log1p(-p0)
        lw0 = float(np.log(p0)) if p0 > 0 else -np.inf  # on_rate = inf: no "no line" mass
    mean = np.zeros((N, n))
    cov = np.broadcast_to(np.eye(n) * config.model.p0_amp, (N, n, n)).copy()
    return State(lw, mean, cov, lw0)


def _check_h(model: HarmonicModel) -> None:
    h = model.H
    if not (np.all(h[0::2] == 1.0) and np.all(h[1::2] == 0.0)):  # pragma: no cover - invariant
        raise ParameterError("rbpmf needs the harmonic model's h = [1, 0, 1, 0, ...]")


def tables(config: Config) -> Tables:
    """The constants of the compiled core for ``config``, built once per Config instance and
    kept with it (as its cached ``kern``): :func:`step` runs per sample."""
    tb = config.__dict__.get("_tables")
    if tb is None:
        tb = config.__dict__["_tables"] = _build_tables(config)
    return tb


def _build_tables(config: Config) -> Tables:
    k = config.kern
    m = config.model
    _check_h(m)
    q = 0.5 * (1.0 - config.level)
    cs = np.ascontiguousarray(np.stack([k.blocks[:, :, 0, 0], k.blocks[:, :, 0, 1]], axis=-1))
    u = k.widths / np.sum(k.widths)
    eps, p_off, p_on, nv = config.rates()
    return Tables(float(m.r), cs, float(m.dt * m.q_amp), k.kb, int(k.B), k.grid, k.edges, u,
                  float(config.log_floor), q, 1.0 - q, eps, p_off, p_on, nv, float(m.p0_amp),
                  float(config.amb_rel), float(config.amb_abs), config.temper_step,
                  config.null_model == "mixture", float(config.mode_hold))


#: summary columns of Estimate / Result after the reported omega, in their field order
_HEAD = (cols.COL_STD, cols.COL_MAP, cols.COL_LO, cols.COL_HI, cols.COL_LOGLIK, cols.COL_P_NULL,
         cols.COL_P_HALF, cols.COL_P_DOUBLE)
#: the fields after ``amplitudes, posterior`` (Estimate) / ``..., final`` (Result)
_TAIL = (cols.COL_P_THIRD, cols.COL_P_TRIPLE, cols.COL_MODE, cols.COL_P_MODE, cols.COL_MEAN,
         cols.COL_MODE_STD)


def _point_and_columns(config: Config, rows: np.ndarray) -> list:
    """The reported omega (the mode window's mean with ``point="mode"``, else the posterior
    mean) and the :data:`_HEAD` columns of a summary row (or of rows transposed)."""
    om = rows[cols.COL_MODE] if config.point == "mode" else rows[cols.COL_MEAN]
    return [om, *(rows[c] for c in _HEAD)]


def _extra_vec(config: Config, ex) -> np.ndarray:
    N = config.n_grid
    e = np.ascontiguousarray(ex, dtype=np.float64)
    if e.shape == (N,):
        e = np.append(e, 0.0)
    if e.shape != (N + 1,):
        raise ParameterError(f"extra evidence must have {N} or {N + 1} entries, got {e.shape}")
    return e


class _StepPlan(NamedTuple):
    """What :func:`step` needs of a Config per sample, built once (:func:`_plan`): the compiled
    core's constants packed as one array
    (:func:`~vibrospeed.estimators.grid.core.step_constants`), its work space
    (:func:`~vibrospeed.estimators.grid.core.step_work`), the sizes (L: rows of a state in the
    loop's layout), the summary column of the reported omega and the claim level."""

    cst: np.ndarray
    ws: np.ndarray
    N: int
    n: int
    L: int
    n_out: int
    col_omega: int
    claim_level: float


def _plan(config: Config) -> _StepPlan:
    plan = config.__dict__.get("_step_plan")
    if plan is None:
        tb = tables(config)
        N, n = config.n_grid, config.model.n_lin
        plan = config.__dict__["_step_plan"] = _StepPlan(
            step_constants(tb), step_work(tb), N, n, n + n * (n + 1) // 2,
            N_OUT_FIXED + n // 2, cols.COL_MODE if config.point == "mode" else cols.COL_MEAN,
            float(config.claim_level))
    return plan


#: summary column of each scalar extra (the rest: ``amplitudes``, ``posterior``)
_EXTRA_COLUMN = {"omega_map": cols.COL_MAP, "loglik": cols.COL_LOGLIK,
                 "p_null": cols.COL_P_NULL, "p_half": cols.COL_P_HALF,
                 "p_double": cols.COL_P_DOUBLE, "p_third": cols.COL_P_THIRD,
                 "p_triple": cols.COL_P_TRIPLE, "omega_mode": cols.COL_MODE,
                 "p_mode": cols.COL_P_MODE, "omega_mean": cols.COL_MEAN,
                 "omega_mode_std": cols.COL_MODE_STD}


class StepExtras(Mapping):
    """The extras of :func:`step`'s Estimate (:data:`ESTIMATE_EXTRAS`, in that order), read
    from the sample's summary row and posterior when asked for: a step builds no dict of 13
    entries that a caller may never read. Values as a dict of them would hold: float64
    scalars, ``amplitudes`` (M,) (a view of the row) and ``posterior`` (N,)."""

    __slots__ = ("_out", "_post")

    def __init__(self, out: np.ndarray, post: np.ndarray) -> None:
        self._out = out
        self._post = post

    def __getitem__(self, key: str):
        c = _EXTRA_COLUMN.get(key)
        if c is not None:
            return self._out[c]
        if key == "amplitudes":
            return self._out[N_OUT_FIXED:]
        if key == "posterior":
            return self._post
        raise KeyError(key)

    def __iter__(self) -> Iterator[str]:
        return iter(ESTIMATE_EXTRAS)

    def __len__(self) -> int:
        return len(ESTIMATE_EXTRAS)

    def __contains__(self, key) -> bool:
        return key in ESTIMATE_EXTRAS

    def __repr__(self) -> str:
        return repr(dict(self))

    def __reduce__(self):
        return StepExtras, (self._out, self._post)


_NO_EXTRA = np.empty(0)
_NO_Z = np.empty((0, 0))
_NO_MEAN = np.empty((0, 0))
_NO_COV = np.empty((0, 0, 0))


def step(config: Config, state: State, y: float, extra=None,
         emissions: np.ndarray | None = None) -> tuple[State, Estimate]:
    """Process one sample; returns the prior for the next sample and the posterior now.

    ``extra`` : optional (N,) or (N + 1,) log-evidence added to the grid points' (and the "no
    line" state's) log-weights with this sample (e.g. :mod:`vibrospeed.estimators.grid`).
    ``emissions`` : optional (N + 1,) float64 array that receives the sample's per-state
    log-emissions (a row of :func:`run`'s ``grid_loglik``, before its float32 rounding): what
    a streaming smoother keeps (:class:`vibrospeed.estimators.grid.lagged.LaggedTracker`).

    ``state`` is left as it is: one compiled call updates it into the next state's storage
    (the measurement update reads it, and a NaN sample copies it) and iterates there, so a
    state can be stepped again (or kept) safely. The next state keeps the
    means and covariances in the compiled loop's layout (:class:`State`), so a stream of steps
    converts nothing between samples."""
    p = config.__dict__.get("_step_plan") or _plan(config)
    lw = np.empty(p.N)
    z = np.empty((p.L, p.N))
    out = np.empty(p.n_out)
    post = np.empty(p.N)
    ex = _NO_EXTRA if extra is None else _extra_vec(config, extra)
    em = _NO_EXTRA if emissions is None else emissions
    if em.size and (em.dtype != np.float64 or em.shape != (p.N + 1,)):
        raise ValueError(f"emissions: a float64 array of {p.N + 1} entries, got {em.dtype} "
                         f"{em.shape}")
    zi = state._z if type(state) is State else None
    if zi is None:  # plain arrays (a state made by init, run or a caller)
        lw0, cur = _step_from(p.cst, p.ws, state.log_w, _NO_Z, state.mean, state.cov,
                              float(state.log_w_null), int(state.mode_j), float(y), ex, lw, z,
                              out, post, em)
    else:  # a state this function made: its fields read from the tuple's slots
        lw0, cur = _step_from(p.cst, p.ws, _tuple_item(state, 0), zi, _NO_MEAN, _NO_COV,
                              float(_tuple_item(state, 3)), int(_tuple_item(state, 4)),
                              float(y), ex, lw, z, out, post, em)
    p_null = out[cols.COL_P_NULL]
    est = _tuple_new(Estimate, (out[p.col_omega], out[cols.COL_STD], out[cols.COL_LO],
                                out[cols.COL_HI], np.nan, np.nan,
                                1.0 if 1.0 - p_null >= p.claim_level else 0.0, np.nan,
                                StepExtras(out, post)))
    nxt = _tuple_new(State, (lw, None, None, lw0, cur))  # State._in_loop_layout, inlined
    nxt._z = z
    return nxt, est


def posterior_slots(n: int, return_posterior) -> np.ndarray:
    """The posterior row of each of ``n`` samples (-1: not kept; empty: no posterior) for
    ``return_posterior``: False (none), True (every sample) or the increasing sample indices
    whose rows are kept (a consumer that reads the posterior at a few samples, e.g. fuse's
    fusion samples, then holds ``len(idx)`` rows instead of ``n``)."""
    if isinstance(return_posterior, bool | np.bool_):
        return np.arange(n, dtype=np.int64) if return_posterior else np.zeros(0, np.int64)
    idx = np.asarray(return_posterior)
    if idx.ndim != 1 or (idx.size and not np.issubdtype(idx.dtype, np.integer)):
        raise ParameterError("return_posterior: True, False or a 1-D array of sample indices")
    if idx.size and (idx[0] < 0 or idx[-1] >= n or np.any(np.diff(idx) <= 0)):
        raise ParameterError(f"return_posterior: the sample indices must increase within "
                             f"0..{n - 1}")
    slot = np.full(n, -1, dtype=np.int64)
    slot[idx] = np.arange(idx.size)
    return slot


def run(
    config: Config,
    y: np.ndarray,
    state: State | None = None,
    *,
    return_posterior: bool | np.ndarray = False,
    return_grid_loglik: bool = False,
    extra: tuple[np.ndarray, np.ndarray] | None = None,
) -> Result:
    """Run over a whole (already pre-filtered, scaled) signal; identical to repeated
    :func:`step`. ``return_posterior``: also return the grid posterior (n, N) as float32 (an
    index array: only those samples' rows, :func:`posterior_slots`);
    ``return_grid_loglik``: the per-state log-emissions (n, N + 1) float32 that
    :mod:`vibrospeed.estimators.grid_smoother` needs (last column: the "no line" state).
    ``extra = (idx, values)``: log-evidence ``values[f]`` ((N,) or (N + 1,) per row) added at
    sample ``idx[f]`` (indices into ``y``, increasing), as :func:`step`'s ``extra``."""
    st = init(config) if state is None else state
    lw = np.array(st.log_w, dtype=np.float64)
    lw0 = np.array([st.log_w_null], dtype=np.float64)
    mean = np.ascontiguousarray(st.mean, dtype=np.float64).copy()
    cov = np.ascontiguousarray(st.cov, dtype=np.float64).copy()
    ys = np.ascontiguousarray(y, dtype=np.float64)
    N = config.n_grid
    n = 2 * config.model.M
    says = f"grid and model (N = {N}, 2M = {n})"
    check_state("grid", says, log_w=(lw, (N,)), mean=(mean, (N, n)), cov=(cov, (N, n, n)))
    if not -1 <= int(st.mode_j) < N:  # the compiled loop would index past the grid
        raise ParameterError(f"grid state: mode_j {int(st.mode_j)} is off the config's {says}")
    if extra is None:
        ex_idx, ex_val = np.zeros(0, np.int64), np.zeros((0, N + 1))
    else:
        ex_idx = np.ascontiguousarray(extra[0], dtype=np.int64)
        ex_val = np.ascontiguousarray(extra[1], dtype=np.float64)
        if ex_val.ndim == 2 and ex_val.shape[1] == N:
            ex_val = np.ascontiguousarray(np.column_stack([ex_val, np.zeros(len(ex_val))]))
        if ex_val.shape != (ex_idx.size, N + 1):
            raise ParameterError(f"extra evidence must be ({ex_idx.size}, {N} or {N + 1}), "
                                 f"got {ex_val.shape}")
        if ex_idx.size > 1 and np.any(np.diff(ex_idx) <= 0):
            raise ParameterError("extra evidence indices must be strictly increasing")
    cur = np.array([st.mode_j], dtype=np.int64)
    slot = posterior_slots(ys.size, return_posterior)
    outs, posts, glls = _run(tables(config), lw, lw0, mean, cov, cur, ys, ex_idx, ex_val,
                             slot, bool(return_grid_loglik))
    if outs.shape[1] != N_OUT_FIXED + config.model.M:
        # numba's on-disk cache of core.py does not follow changes to summary.py's row layout
        raise RuntimeError(f"the compiled grid core writes {outs.shape[1]} columns per sample, "
                           f"this version reads {N_OUT_FIXED + config.model.M}: a stale numba "
                           "cache; delete the __pycache__ folders under "
                           "vibrospeed/estimators/grid")
    return Result(*_point_and_columns(config, outs.T), outs[:, N_OUT_FIXED:],
                  posts if slot.size else None, glls if return_grid_loglik else None,
                  State(lw, mean, cov, float(lw0[0]), int(cur[0])),
                  *(outs[:, c] for c in _TAIL), float(config.claim_level))
