"""The aided EKF as a filter: :class:`State`, :func:`init`, :func:`step`, :func:`run` on the
compiled core (:mod:`vibrospeed.estimators.aided.core`), and :func:`omega_shift`.

Conventions as in :mod:`vibrospeed.estimators.ekf`: the stored state is the prior for the next
sample; ``step`` updates with sample k, returns the posterior at ``t_k`` and predicts to
``t_{k+1}``; NaN inputs skip what needs them. ``run`` equals repeated ``step`` exactly.

Wrapping other trackers: the aiding acts through three hooks, all on omega only -- the time
update's shift ``(T / r)(u + b)``, the boost, and scalar omega measurements (standstill,
reference fixes). A grid tracker (the RBPMF of :mod:`vibrospeed.estimators.rbpmf`) gains the
same aiding by shifting its grid posterior by ``(T / r)(u + b)`` per sample and multiplying the
grid weights by the omega likelihoods; :func:`omega_shift` computes the shift such a wrapper
applies (benchmarks/aided/RESULTS.md).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from vibrospeed.config import check_state
from vibrospeed.errors import InputError
from vibrospeed.estimators.aided.config import STANDSTILL_KINDS, Config
from vibrospeed.estimators.aided.core import N_OUT, _aided_run, _aided_step
from vibrospeed.estimators.aiding import Sample, input_arrays
from vibrospeed.signal import detectors as det
from vibrospeed.types import Estimate


class State(NamedTuple):
    """Prior for the next sample plus the detectors' states.

    x (2+2M,) ``[omega, alpha_1, beta_1, ..., b]``, P (2+2M, 2+2M), window / cusum / mode:
    detector states (:mod:`vibrospeed.signal.detectors`); line (6,): [running mean of the
    EKF input's square, samples in it, 1.0 once omega is known (``init_ref``), running mean
    of the explained share, comb candidates in a row disagreeing with omega, last candidate].
    """

    x: np.ndarray
    P: np.ndarray
    window: det.WindowState
    cusum: det.CusumState
    mode: det.ModeState
    line: np.ndarray


#: extras of :func:`step`'s :class:`~vibrospeed.types.Estimate`: bias (m/s^2, estimated b
#: added to a_x), acceleration / boost modes, ubar (m/s^2, mean of the last ``mode_n`` a_x),
#: the vibration innovation (EKF units; NaN without a vibration update) and its variance, the
#: explained power share of the prior (the gate's statistic), whether the vibration update
#: was allowed to move omega, amplitudes (M,)
ESTIMATE_EXTRAS = ("bias", "accelerating", "boost", "ubar", "innovation", "innovation_var",
                   "line_share", "locked", "amplitudes")


def init(config: Config) -> State:
    """Prior at the first sample and empty detectors."""
    m = config.model
    n = config.n_state
    x = np.full(n, float(config.amp0))
    x[0] = config.omega0
    x[-1] = 0.0
    P = np.eye(n) * m.p0_amp
    P[0, 0] = config.p0_omega
    P[-1, -1] = config.p0_bias
    line = np.array([0.0, 0.0, 0.0 if config.init_ref else 1.0, 0.0, 0.0, 0.0])
    return State(x, P, det.window_init(config.ss_len), det.cusum_init(),
                 det.mode_init(config.mode_len), line)


def _args(config: Config) -> tuple:
    m = config.model
    q_acc = m.q_omega if config.q_omega_accel is None else config.q_omega_accel
    fp = np.array([m.dt, m.q_omega, q_acc, m.q_amp, m.r, config.wheel_radius, config.q_bias,
                   config.omega_limit, config.ss_mu, config.r_ss, config.cusum_sigma,
                   config.cusum_nu, config.cusum_threshold, config.mode_mu, config.line_min,
                   config.line_tau, config.line_omega_min, config.comb_count,
                   config.comb_rel, m.p0_amp])
    boost_on = 1 if (config.boost and not config.aid_always) else 0
    flags = np.array([boost_on, 1 if config.aid_always else 0,
                      det.cusum_hold(config.cusum_threshold, config.cusum_nu),
                      1 if config.release_on_accel else 0], dtype=np.int64)
    return (m.M, STANDSTILL_KINDS[config.standstill], float(config.mode_len), flags, fp)


def _check_state(config: Config, state: State) -> None:
    """A state made for another M or other detector windows ran silently (omega 0 or NaN):
    the compiled core takes the sizes from the config for some arrays, from the state for
    others."""
    n = config.n_state
    check_state("aided", f"M = {config.model.M} and windows", x=(state.x, (n,)),
                P=(state.P, (n, n)), window=(state.window.buf, (config.ss_len,)),
                mode=(state.mode.buf, (config.mode_len,)), line=(state.line, (6,)))


def _unpack(state: State) -> list:
    return [state.x.copy(), state.P.copy(), state.window.buf.copy(),
            state.window.pos_count.copy(), state.window.flag.copy(),
            np.array([state.cusum.g, state.cusum.since]), state.mode.buf.copy(),
            state.mode.pos_count.copy(), state.mode.flag.copy(), state.line.copy()]


def _pack(a: list) -> State:
    return State(a[0], a[1], det.WindowState(a[2], a[3], a[4]),
                 det.CusumState(float(a[5][0]), float(a[5][1])), det.ModeState(a[6], a[7], a[8]),
                 a[9])


def step(
    config: Config,
    state: State,
    y: float | Sample,
    u: float = np.nan,
    *,
    gain: float = 1.0,
    ref: float = np.nan,
    ref_var: float = np.nan,
    still: float = np.nan,
    comb: float = np.nan,
) -> tuple[State, Estimate]:
    """Process one sample: a :class:`~vibrospeed.estimators.aiding.Sample` of the inputs
    below, or ``y`` and the others as arguments.

    y : pre-filtered vibration sample in m/s^2 (the standstill tests read it in these units).
    u : longitudinal acceleration a_x in m/s^2 (NaN: no aiding on this sample).
    gain : factor applied to ``y`` before the EKF update (running-RMS normalisation; 1 = off).
    ref, ref_var : an omega fix (rad/s) and its variance ((rad/s)^2); NaN: none.
    still : the standstill decision for this sample (1 standing, 0 or NaN moving), read with
        ``standstill='broadband'`` (:func:`standstill_flags` computes it).
    comb : the harmonic comb's omega candidate (rad/s; NaN: none), :func:`comb_fixes`; after
        ``comb_count`` candidates in a row that disagree with omega by more than ``comb_rel``
        of the candidate, omega is measured as the candidate (std ``comb_rel / 2`` of it).
    """
    if isinstance(y, Sample):
        y, u, gain, ref, ref_var, still, comb = y
    _check_state(config, state)
    a = _unpack(state)
    out = np.empty(N_OUT + config.model.M)
    _aided_step(a[0], a[1], float(y), float(u), float(gain), float(ref), float(ref_var),
                float(still), float(comb), *a[2:], *_args(config), out)
    return _pack(a), _estimate(out)


def _estimate(o: np.ndarray) -> Estimate:
    extras = dict(zip(ESTIMATE_EXTRAS, (
        float(o[2]), bool(o[4]), bool(o[5]), float(o[6]), float(o[7]), float(o[8]),
        float(o[9]), bool(o[10] > 0.5), o[N_OUT:].copy()), strict=True))
    return Estimate(float(o[0]), float(o[1]), standstill=float(bool(o[3])), extras=extras)


class Result(NamedTuple):
    """Batch output over samples: the columns of :func:`step`'s estimates."""

    omega: np.ndarray  # (n,) rad/s
    omega_std: np.ndarray  # (n,) rad/s
    bias: np.ndarray  # (n,) m/s^2
    standstill: np.ndarray  # (n,) bool
    accelerating: np.ndarray  # (n,) bool
    boost: np.ndarray  # (n,) bool
    ubar: np.ndarray  # (n,) m/s^2
    innovation: np.ndarray  # (n,)
    innovation_var: np.ndarray  # (n,)
    line_share: np.ndarray  # (n,)
    locked: np.ndarray  # (n,) bool
    amplitudes: np.ndarray  # (n, M)
    final: State


def run(
    config: Config,
    y: np.ndarray | Sample,
    u: np.ndarray | None = None,
    *,
    gain: np.ndarray | None = None,
    ref: np.ndarray | None = None,
    ref_var: np.ndarray | None = None,
    still: np.ndarray | None = None,
    comb: np.ndarray | None = None,
    state: State | None = None,
) -> Result:
    """Run over whole signals (see :func:`step` for the inputs; ``y`` may be a
    :class:`~vibrospeed.estimators.aiding.Sample` of arrays); identical to repeated step."""
    if isinstance(y, Sample):  # scalars (the defaults) hold for every sample
        n = np.size(y.y)
        y, u, gain, ref, ref_var, still, comb = (
            np.full(n, v, dtype=np.float64) if np.ndim(v) == 0 else v for v in y)
    y = np.ascontiguousarray(y, dtype=np.float64)
    n = y.size
    u, gain, ref, ref_var = input_arrays(n, u, gain, ref, ref_var)
    extra = []
    for name, v in (("still", still), ("comb", comb)):
        v = np.full(n, np.nan) if v is None else np.ascontiguousarray(v, dtype=np.float64)
        if v.shape != (n,):
            raise InputError(f"aided.run: '{name}' has shape {v.shape}, expected ({n},) like y")
        extra.append(v)
    if state is None:
        state = init(config)
    _check_state(config, state)
    a = _unpack(state)
    o = _aided_run(y, u, gain, ref, ref_var, *extra, *a, *_args(config))
    return Result(o[:, 0], o[:, 1], o[:, 2], o[:, 3] > 0.5, o[:, 4] > 0.5, o[:, 5] > 0.5,
                  o[:, 6], o[:, 7], o[:, 8], o[:, 9], o[:, 10] > 0.5, o[:, N_OUT:], _pack(a))


# ---------------------------------------------------------------------------------------------
def omega_shift(config: Config, u: float, bias: float, accelerating: bool) -> float:
    """Omega increment (rad/s) the aiding adds in one time update: ``(T / r)(u_eff + b)``.

    ``u_eff`` is ``u`` in acceleration mode (or always with ``aid_always``), else 0. A grid
    tracker wrapped by the aiding shifts its posterior over omega by this amount per sample.
    """
    ue = u if (accelerating or config.aid_always) and np.isfinite(u) else 0.0
    return config.model.dt * (ue + bias) / config.wheel_radius
