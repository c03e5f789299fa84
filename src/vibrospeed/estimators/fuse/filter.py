"""The fusion filter's protocol (:mod:`vibrospeed.estimators.fuse`): the records ``State``,
``Sample``, ``Output``, ``Result``, the start state (:func:`init`, the receiver in steady state
at the initial speed), one fusion sample (:func:`step`) and the forward filter over arrays of
them (:func:`run`), both packing the state for the compiled core
(:mod:`vibrospeed.estimators.fuse.core`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.fuse.band import learn_acc_psd_causal
from vibrospeed.estimators.fuse.config import IA, IB, IG, IR, IV, Config
from vibrospeed.estimators.fuse.core import _run_core, _step_core
from vibrospeed.models.gps_riss import receiver_matrices
from vibrospeed.types import Estimate


class State(NamedTuple):
    """Filter state after the last sample.

    x, P : (n,), (n, n) mean and covariance of ``[v, a, b, r, x3, x4, d..., dl]``.
    t : time of the last sample (NaN before the first).  t_gps : time of the last accepted
    fix (-inf: none).  t_fix, v_fix : time and value of the last valid fix (for the standstill
    veto).  octave : average of log2 k over recent wheel-frequency updates (module notes, 3).
    t_run, d_run, u_run, d0_run : start, mean gap ``r omega - v``, line speed at the start
    and gap at the start of the current re-lock run (NaN: none; module notes, 3).
    t_still : start of the current run of refused stop evidence (NaN: none).
    t_acq, z_acq : start and mean log ratio
    ``ln(v / omega)`` of the current run of consistent lines while the radius is not known
    yet (NaN: none; module notes, 3).
    t_last, om_last, k_last : time, omega and k of the last wheel-frequency update, however
    long ago (NaN: none yet; a claimed line continues it if it was at the previous fusion
    sample, ``t_last == t``, an unclaimed one within ``vib_soft_hold``; module notes, 3).
    t_dis, s_dis : start time and signed fix count (+1 per fix above the filter's speed, -1
    below) of the current run of fixes that disagree with it, on one side, beyond the
    innovation's spread (NaN: none; module notes, 2).
    Pb : (n, n) the speed band's covariance (``Config.band_psd``; None: not kept yet, it
    starts as ``P``).
    """

    x: np.ndarray
    P: np.ndarray
    t: float
    t_gps: float
    t_fix: float
    v_fix: float
    octave: float = 0.0
    t_run: float = math.nan
    t_still: float = math.nan
    t_acq: float = math.nan
    z_acq: float = math.nan
    d_run: float = math.nan
    u_run: float = math.nan
    d0_run: float = math.nan
    t_last: float = math.nan
    om_last: float = math.nan
    k_last: float = math.nan
    t_dis: float = math.nan
    s_dis: float = math.nan
    Pb: np.ndarray | None = None


class Sample(NamedTuple):
    """One fusion sample, or (n,) arrays of them (:func:`step`, :func:`run`): time (s), mean
    longitudinal acceleration since the previous sample (m/s^2, NaN: none), GPS speed (m/s,
    NaN: no fix now), satellites (NaN: unknown), the tracker's omega and spread (rad/s),
    whether it claims a line, whether the vibration reports a stop, whether the line is an
    unclaimed one offered to the re-lock only (``Config.vib_soft``), and the tracker's grid
    posterior of the signal part (N,) (summing to its line probability; None: none), read with
    ``Config.vib_measure="posterior"`` on the grid :func:`step` / :func:`run` are given."""

    t: float
    accel: float = math.nan
    gps_speed: float = math.nan
    gps_sats: float = math.nan
    omega: float = math.nan
    omega_std: float = math.nan
    line: bool = False
    still: bool = False
    soft: bool = False
    posterior: np.ndarray | None = None


#: the per-sample values of :func:`step`'s Estimate besides ``speed`` / ``speed_std``: radius
#: and its std (m), accelerometer offset (m/s^2), source (:data:`SOURCES`), the harmonic k of
#: the wheel-frequency update (NaN: none)
EXTRAS = ("radius", "radius_std", "offset", "source", "harmonic")


class Output(NamedTuple):
    """:func:`run` output, (n,) arrays; ``xp, Pp, xf, Pf, dt`` kept for :func:`smooth`, and
    ``Pbp, Pbf`` the band's covariances (``Config.band_psd``; None: off) and ``Jb`` each
    sample's product of its updates' ``I - k h``; ``speed_std`` is the band's where it is
    kept."""

    speed: np.ndarray
    speed_std: np.ndarray
    radius: np.ndarray
    radius_std: np.ndarray
    offset: np.ndarray
    source: np.ndarray
    harmonic: np.ndarray
    xp: np.ndarray
    Pp: np.ndarray
    xf: np.ndarray
    Pf: np.ndarray
    dt: np.ndarray
    Pbp: np.ndarray | None = None
    Pbf: np.ndarray | None = None
    Jb: np.ndarray | None = None


class Result(NamedTuple):
    """:func:`run`'s result: the state after the last sample and the per-sample output; the
    output's columns read as attributes too (``result.speed``); unpacks as ``final, output``."""

    final: State
    output: Output

    def __getattr__(self, name):
        return getattr(self.output, name)


def init(config: Config, v0: float = 0.0, *, radius: float | None = None,
         radius_std: float | None = None, p0_speed: float | None = None) -> State:
    """Start state: speed ``v0`` (variance ``p0_speed``, default the config's), the receiver in
    steady state at ``v0``, radius prior ``radius +- radius_std`` (default the config's)."""
    lag = config.lag
    n = config.n_states
    x = np.zeros(n)
    x[IV] = v0
    r = config.radius0 if radius is None else float(radius)
    rs = config.radius_std0 if radius_std is None else float(radius_std)
    if not (r > 0 and rs > 0 and math.isfinite(r) and math.isfinite(rs)):
        raise ParameterError(f"fuse: radius prior must be > 0 with std > 0, got {r} +- {rs}")
    x[IR] = r
    Ar, Br = receiver_matrices(lag)
    m = n - 1  # the receiver chain ends here; the last state is its extra lag (0 at start)
    x[IG:m] = -np.linalg.solve(Ar, Br) * v0
    P = np.zeros((n, n))
    pv = config.p0_speed if p0_speed is None else float(p0_speed)
    P[IV, IV] = pv
    P[IA, IA] = config.p0_accel
    P[IB, IB] = config.p0_offset
    P[IR, IR] = rs * rs
    gain = -np.linalg.solve(Ar, Br)  # receiver states follow v at steady state
    P[IG:m, IV] = gain * pv
    P[IV, IG:m] = gain * pv
    P[IG:m, IG:m] = np.outer(gain, gain) * pv + np.eye(m - IG) * 1e-6
    P[m, m] = config.gps_lag_std ** 2
    return State(x, P, math.nan, -math.inf, -math.inf, math.nan)



def _unpack(state: State, n: int):
    x = np.array(state.x, dtype=np.float64)
    if x.shape != (n,):
        raise ParameterError(f"fuse: state has {x.size} states but the config's model needs {n} "
                             "(GPS delay on/off changed?)")
    P = np.array(state.P, dtype=np.float64)
    sc = np.array([state.t, state.t_gps, state.t_fix, state.v_fix, -1.0, state.octave,
                   state.t_run, state.t_still, state.t_acq, state.z_acq, state.d_run,
                   state.u_run, state.d0_run, state.t_last, state.om_last, state.k_last,
                   state.t_dis, state.s_dis])
    return x, P, sc


def _pack(x, P, sc, Pb=None) -> State:
    return State(x, P, float(sc[0]), float(sc[1]), float(sc[2]), float(sc[3]), float(sc[5]),
                 float(sc[6]), float(sc[7]), float(sc[8]), float(sc[9]), float(sc[10]),
                 float(sc[11]), float(sc[12]), float(sc[13]), float(sc[14]), float(sc[15]),
                 float(sc[16]), float(sc[17]), None if Pb is None or Pb.size == 0 else Pb)


def _band_start(state: State, P: np.ndarray) -> np.ndarray:
    """The band's covariance to continue from: the state's, or the filter's own at the start."""
    if state.Pb is None:
        return P.copy()
    Pb = np.array(state.Pb, dtype=np.float64)
    if Pb.shape != P.shape:
        raise ParameterError(f"fuse: the state's band covariance is {Pb.shape}, its P {P.shape}")
    return Pb


def _density(config: Config, band_psd) -> float:
    """The band's accelerometer density for one sample: ``max(given or the config's number,
    acc_psd)``; NaN (not learned yet) and ``"learned"`` without a value are ``acc_psd``."""
    if band_psd is None:
        b = config.band_density()
        band_psd = b if isinstance(b, float) else math.nan
    q = float(band_psd)
    return config.acc_psd if math.isnan(q) else max(q, config.acc_psd)


_SAMPLE = Sample._fields[:-1]  # the scalar fields; ``posterior`` is a row per sample
_FLAGS = ("line", "still", "soft")


def _grid_array(grid, posterior) -> np.ndarray:
    """The tracker's grid as the core reads it (empty where no posterior is given)."""
    if posterior is None:
        return np.empty(0)
    if grid is None:
        raise InputError("fuse: a posterior needs the tracker's grid (grid=)")
    g = np.ascontiguousarray(grid, dtype=np.float64)
    if g.ndim != 1 or g.size < 2 or np.shape(posterior)[-1] != g.size:
        raise InputError(f"fuse: the posterior has {np.shape(posterior)[-1]} points per sample, "
                         f"the grid {g.size}")
    return g


def step(config: Config, state: State, y, grid=None,
         band_psd: float | None = None) -> tuple[State, Estimate]:
    """One fusion sample ``y``, a :class:`Sample` or the tuple ``(t, accel, gps_speed,
    gps_sats, omega, omega_std, line, still[, soft[, posterior]])``; ``posterior`` (N,) is the
    tracker's grid posterior of the signal part (summing to its line probability) on ``grid``
    (N,), read with ``vib_measure="posterior"``; an input given as None is "none" (NaN /
    False), as in :func:`run`. The Estimate holds ``speed``, ``speed_std`` and the
    :data:`EXTRAS`. With ``config.band_psd`` not off, ``speed_std`` is the band's (the state
    carries its covariance); ``band_psd``: the density learned so far for ``"learned"`` (None:
    ``acc_psd``), or overriding the config's number."""
    t, am, g, sats, om, om_std, line, still, *rest = y
    # None: none / unknown, as run reads a missing input (TypeError from float() before)
    am, g, sats, om, om_std = (math.nan if v is None else v for v in (am, g, sats, om, om_std))
    soft = bool(rest[0]) if rest else False
    post = rest[1] if len(rest) > 1 else None
    gr = _grid_array(grid, post)
    post = (np.empty(0) if post is None
            else np.ascontiguousarray(post, dtype=np.float64).reshape(-1))
    t = float(t)
    if not math.isnan(state.t) and not t >= state.t:
        raise InputError(f"fuse: time goes backwards at t = {t} s (previous {state.t} s)")
    Ac, qc, p = config._arrays()
    x, P, sc = _unpack(state, Ac.shape[0])
    out = np.empty(7)
    n = x.size
    kb = config.band_density() != "off" or band_psd is not None
    Pb = _band_start(state, P) if kb else np.empty((0, 0))
    _step_core(Ac, qc, p, x, P, sc, np.eye(n), t, float(am), float(g), float(sats), float(om),
               float(om_std), bool(line), bool(still), soft, post, gr, out, np.empty(n),
               np.empty((n, n)), Pb, _density(config, band_psd) if kb else 0.0,
               np.empty((n, n)), np.empty((n, n)))
    est = Estimate(speed=float(out[0]), speed_std=float(out[1]),
                   extras=dict(zip(EXTRAS, (float(out[2]), float(out[3]), float(out[4]),
                                            int(out[5]), float(out[6])), strict=True)))
    return _pack(x, P, sc, Pb), est


def _as_inputs(arrays) -> list[np.ndarray]:
    if hasattr(arrays, "_fields"):  # a Sample of arrays
        arrays = arrays._asdict()
    t = np.ascontiguousarray(arrays["t"], dtype=np.float64)
    n = t.size
    out = [t]
    for name in _SAMPLE[1:]:
        v = arrays.get(name)
        if v is None:
            v = False if name in _FLAGS else np.nan
        if np.ndim(v) == 0:  # one value for every sample (a Sample's scalar default)
            v = np.full(n, v)
        v = np.ascontiguousarray(v, dtype=np.bool_ if name in _FLAGS else np.float64)
        if v.shape != (n,):
            raise InputError(f"fuse: input '{name}' has shape {v.shape}, expected ({n},)")
        out.append(v)
    if n > 1 and not np.all(np.diff(t) >= 0):
        bad = int(np.flatnonzero(np.diff(t) < 0)[0]) + 1
        raise InputError(f"fuse: time goes backwards at sample {bad}")
    return out


def run(config: Config, y, state: State | None = None, grid=None, band_psd=None) -> Result:
    """Forward filter over fusion samples; the numbers of repeated :func:`step`.

    ``y``: a :class:`Sample` of (n,) arrays, or a mapping of its names (``t``, ``accel``,
    ``gps_speed``, ``gps_sats``, ``omega``, ``omega_std``, ``line``, ``still``, ``soft``,
    ``posterior``) to arrays; a missing one is "none" (NaN / False / no posterior).
    ``posterior`` (n, N): the tracker's grid posterior per sample on ``grid`` (N,) (as
    :func:`step`). ``state`` defaults to :func:`init` at the first valid fix (or 0).
    ``band_psd``: the band's accelerometer density, a number or (n,) per sample (NaN: not
    known yet); None: the config's ``band_psd`` (``"learned"``: from the fixes so far,
    :func:`~vibrospeed.estimators.fuse.band.learn_acc_psd_causal`). Each is raised to at least
    ``acc_psd``.
    """
    ins = _as_inputs(y)
    post = y.posterior if hasattr(y, "_fields") else y.get("posterior")
    gr = _grid_array(grid, post)
    if post is None:
        post = np.empty((0, 0))
    else:
        post = np.ascontiguousarray(post, dtype=np.float64)
        if post.shape != (ins[0].size, gr.size):
            raise InputError(f"fuse: posterior has shape {post.shape}, expected "
                             f"({ins[0].size}, {gr.size})")
    t, g, s = ins[0], ins[2], ins[3]
    if state is None:
        fin = np.flatnonzero(config.valid_fixes(g, s))
        state = init(config, float(g[fin[0]]) if fin.size else 0.0)
    Ac, qc, p = config._arrays()
    x, P, sc = _unpack(state, Ac.shape[0])
    n, m = t.size, x.size
    out = np.empty((n, 7))
    xp, Pp = np.empty((n, m)), np.empty((n, m, m))
    xf, Pf = np.empty((n, m)), np.empty((n, m, m))
    dts = np.empty(n)
    mode = config.band_density()
    kb = mode != "off" or band_psd is not None
    if kb:
        if band_psd is None and mode == "learned":
            band_psd = learn_acc_psd_causal(t, ins[1], np.where(config.valid_fixes(g, s), g,
                                                                np.nan))
        q = np.broadcast_to(np.asarray(mode if band_psd is None else band_psd,
                                       dtype=np.float64), (n,))
        bands = np.where(np.isnan(q), config.acc_psd, np.maximum(q, config.acc_psd))
        Pb = _band_start(state, P)
        Pbp, Pbf, Js = np.empty((n, m, m)), np.empty((n, m, m)), np.empty((n, m, m))
    else:
        bands, Pb, Pbp, Pbf, Js = np.empty(0), np.empty((0, 0)), np.empty((0, m, m)), None, None
    none = np.empty((0, m, m))
    _run_core(Ac, qc, p, x, P, sc, *ins, post, gr, out, xp, Pp, xf, Pf, dts, Pb,
              np.ascontiguousarray(bands), Pbp, none if Pbf is None else Pbf,
              none if Js is None else Js)
    o = Output(*(np.ascontiguousarray(out[:, i]) for i in range(5)),
               out[:, 5].astype(np.int8), np.ascontiguousarray(out[:, 6]), xp, Pp, xf, Pf, dts,
               Pbp if kb else None, Pbf, Js)
    return Result(_pack(x, P, sc, Pb), o)
