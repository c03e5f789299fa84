"""Harmonic extended Kalman filter (thesis ch. 2.3.4-2.3.5; METHODS.md 1.1).

Full-state EKF on the phasor model of :mod:`vibrospeed.models.harmonic`,
``x = [omega, alpha_1, beta_1, ..., alpha_M, beta_M]`` with

* time update ``x- = f(x)``, ``P- = F P F' + Q`` where ``F = df/dx`` (thesis eq. 2.28-2.29
  generalised to M harmonics):
  ``d/domega R(m omega T)[a, b] = m T [-sin a + cos b, -cos a - sin b]``
  (``psi = m omega T``), ``Q = T diag(q_omega, q_amp, ..., q_amp)``;
* measurement update with ``H = [0, 1, 0, 1, 0, ...]``, scalar innovation ``S = H P H' + R``,
  covariance in Joseph form ``P = (I - K H) P (I - K H)' + K R K'`` then symmetrised.

Conventions: the state stored between samples is the *prior* for the next sample; ``step``
updates with ``y_k``, returns the posterior estimate at ``t_k`` and predicts to ``t_{k+1}``.
NaN samples skip the update (prediction only). The model is symmetric under
``(omega, beta) -> (-omega, -beta)``; when an update drives omega below 0 the equivalent state
with omega >= 0 is used (and P transformed alike). Omega is clipped to ``omega_max`` (default just
below the Nyquist limit ``pi fs / M``).

Comb check (not the thesis'; :mod:`vibrospeed.signal.comb`, as in the aided tracker):
an optional per-sample input ``comb``, the speed of the strongest weighted harmonic comb in the
last 3 s (NaN between candidates). After ``COMB_COUNT`` = 2 steady candidates in a row that
differ from omega by more than ``COMB_REL`` = 10 % of the candidate, omega is *reset* to the
candidate (variance ``(COMB_REL / 2 * candidate)^2``) and the phasors restart at 0 with
variance ``p0_amp``: the way out of a lock on half or twice the wheel speed (an EKF at half the
wheel speed explains the wheel's fundamental with its 2nd phasor and stays there). With
``Config.acquire`` the start value ``omega0`` is a placeholder: the first steady candidate sets
omega (acquisition) whatever it is. Without the input (``comb`` NaN) the filter is the thesis'
EKF exactly. The comb check's state (run length, last candidate, acquired flag) is part of
:class:`State`, so ``step`` == ``run`` with the input too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

from vibrospeed.config import check_state, config_from_params, parse_flag, parse_number
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.kalman import joseph_update
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal.comb import COMB_COUNT, COMB_REL, comb_vote, restart_phasors
from vibrospeed.types import Estimate, Recording, Track


@dataclass(frozen=True)
class Config:
    """EKF parameters.

    model : the harmonic model (M, dt, q_omega, q_amp, r). Default: thesis tuning
        (:meth:`HarmonicModel.from_thesis`).
    omega0 : initial omega in rad/s (thesis: 10.2). P0_omega : its variance (thesis: 10).
    amp0 : initial value of every alpha, beta (thesis: 10, which is far from the truth on
        purpose; 0 is a neutral choice). p0_amp of the model is their variance (thesis: 20).
    omega_max : upper clip in rad/s; None = 0.98 * pi * fs / M.
    omega_min : lower clip in rad/s (default 0). Below the pre-filter's high-pass corner a
        vibration line cannot be seen, and an EKF whose omega drifts there collapses onto slow
        phasors that absorb any low-frequency residue; :func:`estimate` clips at 2 rad/s.
    acquire : ``omega0`` is a placeholder until the first steady comb candidate (the ``comb``
        input of :func:`step` / :func:`run`), which sets omega whatever it is (default False:
        ``omega0`` is trusted, the comb check only re-locks). :func:`estimate` sets it when no
        ``omega0`` (``--init-omega``) is given.
    """

    model: HarmonicModel = field(default_factory=HarmonicModel.from_thesis)
    omega0: float = 10.2
    p0_omega: float = 10.0
    amp0: float = 0.0
    omega_max: float | None = None
    omega_min: float = 0.0
    acquire: bool = False

    def __post_init__(self) -> None:
        # NaN or inf in omega0, amp0 or p0_omega makes every output NaN; a NaN bound clips
        # nothing; omega_min >= omega_max pins omega to omega_min
        if not (self.p0_omega > 0 and math.isfinite(self.p0_omega)):
            raise ParameterError(f"p0_omega must be finite and > 0 (rad/s)^2, got "
                                 f"{self.p0_omega}")
        if not (self.omega0 >= 0 and math.isfinite(self.omega0)):
            raise ParameterError(f"omega0 must be finite and >= 0 rad/s, got {self.omega0}")
        if not math.isfinite(self.amp0):
            raise ParameterError(f"amp0 must be finite, got {self.amp0}")
        if not (self.omega_min >= 0 and math.isfinite(self.omega_min)):
            raise ParameterError(f"omega_min must be finite and >= 0 rad/s, got "
                                 f"{self.omega_min}")
        if self.omega_max is not None and not self.omega_max > self.omega_min:
            raise ParameterError(f"omega_max must be > omega_min = {self.omega_min:g} rad/s "
                                 f"(or None: the Nyquist limit), got {self.omega_max}")

    @property
    def omega_limit(self) -> float:
        """Upper clip for omega in rad/s (:meth:`HarmonicModel.omega_clip`)."""
        return self.model.omega_clip(self.omega_max)

    @classmethod
    def from_thesis(cls, dt: float = 0.01, M: int = 3) -> Config:
        """Thesis 2.3.5: R = 0.003, Q = 1e-5 diag(16000, 4, ...), x0 = [10.2, 10, ...],
        P0 = diag(10, 20, ...)."""
        return cls(HarmonicModel.from_thesis(dt, M), omega0=10.2, p0_omega=10.0, amp0=10.0)


class State(NamedTuple):
    """EKF prior for the next sample: ``x`` (1+2M,), ``P`` (1+2M, 1+2M) and the comb check's
    ``[run of disagreeing candidates, last candidate, acquired]`` (None: as :func:`init`)."""

    x: np.ndarray
    P: np.ndarray
    comb: np.ndarray | None = None


#: extras of :func:`step`'s :class:`~vibrospeed.types.Estimate`: amplitudes (M,), the
#: innovation and its variance, whether omega has been acquired (always with ``acquire`` off)
ESTIMATE_EXTRAS = ("amplitudes", "innovation", "innovation_var", "acquired")


def init(config: Config) -> State:
    """Prior at the first sample."""
    m = config.model
    n = 1 + m.n_lin
    x = np.full(n, float(config.amp0))
    x[0] = config.omega0
    P = np.eye(n) * m.p0_amp
    P[0, 0] = config.p0_omega
    return State(x, P, _comb0(config))


def _comb0(config: Config) -> np.ndarray:
    return np.array([0.0, np.nan, 0.0 if config.acquire else 1.0])


@njit(cache=True)
def rotate_phasors(x, xn, F, M, T, jacobian):
    """Phasor time update ``xn[1:] = blockdiag_m R(m omega T) x[1:]`` with ``omega = x[0]``.

    Writes the rotation blocks into ``F`` and, if ``jacobian``, the omega column
    ``d/domega R(m omega T)[a, b] = m T [-sin a + cos b, -cos a - sin b]`` (thesis eq. 2.29).
    Shared by this EKF and the aided EKF (:mod:`vibrospeed.estimators.aided`).
    """
    om = x[0]
    for m in range(M):
        h = m + 1.0
        psi = h * om * T
        c = np.cos(psi)
        s = np.sin(psi)
        ia = 1 + 2 * m
        ib = 2 + 2 * m
        a = x[ia]
        b = x[ib]
        xn[ia] = c * a + s * b
        xn[ib] = -s * a + c * b
        F[ia, ia] = c
        F[ia, ib] = s
        F[ib, ia] = -s
        F[ib, ib] = c
        if jacobian:
            F[ia, 0] = h * T * (-s * a + c * b)
            F[ib, 0] = h * T * (-c * a - s * b)


@njit(cache=True)
def symmetrize_into(Pn, P):
    """``P = (Pn + Pn') / 2`` in place (keeps covariances exactly symmetric)."""
    n = P.shape[0]
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (Pn[i, j] + Pn[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True)
def harmonic_update(x, P, y, M, r, freeze_first, freeze_last):
    """Measurement update with ``y = sum_m alpha_m + e`` (thesis eq. 2.23, 2.26), in place.

    ``H`` picks the alpha entries of ``x = [omega, alpha_1, beta_1, ..., (extra states)]``;
    ``S = H P H' + r``, ``K = P H' / S``, Joseph form ``P = A P A' + r K K'`` with
    ``A = I - K H``, symmetrised. ``freeze_first`` / ``freeze_last`` zero the gain of the first /
    last state (the aided EKF's line gate holds omega and the bias). Returns ``(innov, S)``.
    """
    n = x.size
    pht = np.zeros(n)  # P H' = sum of the alpha columns
    for i in range(n):
        acc = 0.0
        for m in range(M):
            acc += P[i, 1 + 2 * m]
        pht[i] = acc
    s_var = r
    yhat = 0.0
    for m in range(M):
        s_var += pht[1 + 2 * m]
        yhat += x[1 + 2 * m]
    innov = y - yhat
    k = pht / s_var
    if freeze_first:
        k[0] = 0.0
    if freeze_last:
        k[n - 1] = 0.0
    joseph_update(x, P, k, innov, r, 1, 2, M)
    return innov, s_var


@njit(cache=True)
def _ekf_step(x, P, cv, y, comb, M, T, q_om, q_amp, r, om_min, om_max, p0_amp, out):
    """In place: update x, P with y (skip if NaN), comb check with ``comb`` (skip if NaN;
    ``cv`` its state), write outputs, predict. ``out`` (5+M,)."""
    n = x.size
    # ---- measurement update: y = sum alpha + e --------------------------------------
    innov = np.nan
    s_var = np.nan
    if np.isfinite(y):
        innov, s_var = harmonic_update(x, P, y, M, r, False, False)
    # keep omega >= 0 via the symmetry (omega, beta) -> (-omega, -beta)
    if x[0] < 0.0:
        x[0] = -x[0]
        for m in range(M):
            x[2 + 2 * m] = -x[2 + 2 * m]
        for i in range(n):
            si = -1.0 if (i == 0 or (i >= 2 and i % 2 == 0)) else 1.0
            for j in range(n):
                sj = -1.0 if (j == 0 or (j >= 2 and j % 2 == 0)) else 1.0
                P[i, j] *= si * sj
    if x[0] > om_max:
        x[0] = om_max
    if x[0] < om_min:
        x[0] = om_min
    # ---- comb check: acquisition, re-lock from half / twice the wheel speed -----------------
    if np.isfinite(comb) and comb > 0.0:
        acquired = cv[2] > 0.5
        steady, reset = comb_vote(cv[0:2], comb, x[0], COMB_REL,
                                  COMB_COUNT if acquired else 1, True)
        if steady:
            cv[2] = 1.0
        if reset:
            restart_phasors(x, P, 1, n, p0_amp)
            x[0] = min(max(comb, om_min), om_max)
            P[0, 0] = (0.5 * COMB_REL * comb) ** 2
    # ---- outputs (posterior at this sample) --------------------------------------------
    out[0] = x[0]
    out[1] = np.sqrt(max(P[0, 0], 0.0))
    out[2] = innov
    out[3] = s_var
    out[4] = cv[2]
    for m in range(M):
        a = x[1 + 2 * m]
        b = x[2 + 2 * m]
        out[5 + m] = np.sqrt(a * a + b * b)
    # ---- time update ----------------------------------------------------------------
    F = np.eye(n)
    xn = x.copy()
    rotate_phasors(x, xn, F, M, T, True)
    for i in range(n):
        x[i] = xn[i]
    Pn = F @ P @ F.T
    Pn[0, 0] += T * q_om
    for i in range(1, n):
        Pn[i, i] += T * q_amp
    symmetrize_into(Pn, P)


@njit(cache=True)
def _ekf_run(ys, combs, x, P, cv, M, T, q_om, q_amp, r, om_min, om_max, p0_amp):
    n_s = ys.size
    outs = np.empty((n_s, 5 + M))
    out = np.empty(5 + M)
    for k in range(n_s):
        _ekf_step(x, P, cv, ys[k], combs[k], M, T, q_om, q_amp, r, om_min, om_max, p0_amp,
                  out)
        outs[k] = out
    return outs


def _args(config: Config) -> tuple:
    m = config.model
    return (m.M, m.dt, m.q_omega, m.q_amp, m.r, config.omega_min, config.omega_limit, m.p0_amp)


def _comb_state(config: Config, state: State) -> np.ndarray:
    return _comb0(config) if state.comb is None else np.array(state.comb, dtype=np.float64)


def _check_state(config: Config, state: State) -> None:
    """A state of another M would be read past its end by the compiled step (memory errors).
    The message's text is made only when a shape is wrong (step calls this per sample)."""
    m = config.model
    n = 1 + m.n_lin
    check_state("ekf", "M = {}", m.M, x=(state.x, (n,)), P=(state.P, (n, n)),
                comb=(state.comb, None if state.comb is None else (3,)))


def step(config: Config, state: State, y: float, comb: float = np.nan
         ) -> tuple[State, Estimate]:
    """Process one sample ``y``; returns the prior for the next sample and the posterior now.

    ``comb``: the comb check's candidate at this sample (rad/s; NaN: none), e.g. from
    :func:`vibrospeed.signal.comb.comb_candidates`.
    """
    _check_state(config, state)
    x = state.x.copy()
    P = state.P.copy()
    cv = _comb_state(config, state)
    a = _args(config)
    out = np.empty(5 + config.model.M)
    _ekf_step(x, P, cv, float(y), float(comb), *a, out)
    extras = dict(zip(ESTIMATE_EXTRAS, (out[5:].copy(), out[2], out[3], bool(out[4] > 0.5)),
                      strict=True))
    return State(x, P, cv), Estimate(out[0], out[1], extras=extras)


class Result(NamedTuple):
    """Batch output: arrays over samples, the columns of :func:`step`'s estimates."""

    omega: np.ndarray  # (n,) rad/s
    omega_std: np.ndarray  # (n,) rad/s
    amplitudes: np.ndarray  # (n, M)
    innovation: np.ndarray  # (n,)
    innovation_var: np.ndarray  # (n,)
    acquired: np.ndarray  # (n,) bool
    final: State


def run(config: Config, y: np.ndarray, state: State | None = None,
        comb: np.ndarray | None = None) -> Result:
    """Run over a whole signal (``comb``: the comb candidates per sample, NaN: none; None: no
    comb check); identical to repeated :func:`step`."""
    st = init(config) if state is None else state
    _check_state(config, st)
    x = st.x.copy()
    P = st.P.copy()
    cv = _comb_state(config, st)
    ys = np.ascontiguousarray(y, dtype=np.float64)
    if ys.ndim != 1:  # numba's typing error before
        raise InputError(f"ekf.run: y must be one-dimensional (n,), got shape {ys.shape}")
    if comb is None:
        combs = np.full(ys.size, np.nan)
    else:
        combs = np.ascontiguousarray(comb, dtype=np.float64)
        if combs.shape != ys.shape:
            raise ParameterError(f"comb has {combs.size} samples, y has {ys.size}")
    outs = _ekf_run(ys, combs, x, P, cv, *_args(config))
    return Result(outs[:, 0], outs[:, 1], outs[:, 5:], outs[:, 2], outs[:, 3],
                  outs[:, 4] > 0.5, State(x, P, cv))


# ---------------------------------------------------------------------------------------------
#: defaults of :func:`estimate` for a running-RMS-normalised (unit power) signal: M = 2 (the
#: thesis' best, table 3.1; an EKF with more harmonics than the signal carries is easily dragged
#: off the line), measurement noise 30 % of the signal power (unmodelled harmonics, resonances
#: and road noise all count as noise), amplitude random walk 1 % of the power per second, omega
#: random walk 1 (rad/s)^2/s. Chosen on the simulated cart (benchmarks/ekf_cart.py,
#: benchmarks/ekf/RESULTS.md).
UNIT_RMS_MODEL = dict(M=2, q_omega=1.0, q_amp=0.01, r=0.3, p0_amp=1.0)


def _settings(params: dict | None, dt: float) -> tuple[Config, str, float, bool]:
    """``(config, prefilter, normalize_tau, comb)`` that :func:`estimate` runs with ``params``
    at the sample period ``dt`` (s)."""
    from vibrospeed.estimators.common import split_params

    model_kw, cfg_kw = split_params(HarmonicModel, dict(params or {}))
    model_kw.pop("dt", None)
    pre = str(cfg_kw.pop("prefilter", "thesis-hp"))
    tau = parse_number(cfg_kw.pop("normalize_tau", 5.0), "normalize_tau")
    comb_on = parse_flag(cfg_kw.pop("comb", True), "comb")
    cfg_kw.setdefault("acquire", comb_on and "omega0" not in cfg_kw)
    defaults = dict(UNIT_RMS_MODEL) if tau > 0 else HarmonicModel.from_thesis().to_dict()
    defaults.pop("dt", None)
    model = config_from_params(HarmonicModel, model_kw, **{**defaults, "dt": dt})
    cfg_kw.setdefault("omega_min", 2.0)
    cfg_kw.setdefault("omega_max", 120.0)
    return config_from_params(Config, cfg_kw, model=model), pre, tau, comb_on


def config_for(recording: Recording, *, axis: str = "y", params: dict | None = None) -> Config:
    """The :class:`Config` that :func:`estimate` runs on ``recording`` with ``params`` (its
    sample period; the unit-RMS model unless ``normalize_tau=0``), e.g. for
    :class:`~vibrospeed.estimators.online.OnlineTracker`, whose default pre-filter and
    normalisation are ``estimate``'s: pass ``prefilter=`` / ``normalize_tau=`` to it too where
    ``params`` change them. Online there is no comb check (``acquire`` is then off: the filter
    starts from ``omega0``). ``axis`` is there for the other trackers' signature: the config
    does not depend on it."""
    from vibrospeed.estimators.common import check_uniform

    return _settings({**dict(params or {}), "comb": False}, check_uniform(recording))[0]


def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Track omega on accelerometer axis ``axis`` of a uniformly sampled recording.

    ``params`` may set any :class:`Config` field (``omega0``, ``p0_omega``, ``amp0``,
    ``omega_max``), any :class:`HarmonicModel` field (``M``, ``q_omega``, ``q_amp``, ``r``,
    ``p0_amp``; ``dt`` comes from the data), ``prefilter`` (a preset of
    :mod:`vibrospeed.signal.prefilter`, default ``thesis-hp``), ``omega_min`` (default 2 rad/s),
    ``omega_max`` (default 120 rad/s, checked against
    the Nyquist limit ``M omega_max < pi fs``) and ``normalize_tau`` (s, running
    RMS normalisation; 0 = off, then the parameters are in the signal's own units and the
    thesis' values apply: ``r=0.003 q_amp=0.004 p0_amp=20``).

    Acquisition: ``comb`` (default True) feeds the comb check
    (:func:`vibrospeed.signal.comb.comb_candidates` on the raw axis, over ``max(omega_min,
    2 pi)`` .. ``omega_max``). Without ``omega0`` (``--init-omega``) the first steady comb
    candidate sets omega (until then omega is the placeholder ``omega0`` = 10.2 rad/s and the
    extra ``acquired`` is 0); with it, ``omega0`` is trusted and the comb check only re-locks
    (2 steady candidates in a row more than 10 % from omega: omega and the phasors restart
    there). ``comb=false`` is the thesis' EKF from ``omega0`` as before.

    Online: the comb check is causal (3 s frames ending at the sample) but
    :class:`~vibrospeed.estimators.online.OnlineTracker` does not compute it; it runs the EKF
    without it (what ``comb=false`` with ``omega0`` gives here). A device that wants it feeds
    :func:`step`'s ``comb`` from its own 3 s buffer.
    """
    from vibrospeed.estimators.common import (
        axis_channel,
        prepare_axis,
        run_in_chunks,
    )
    from vibrospeed.signal.comb import COMB_FRAME_S, COMB_HOP_S, comb_candidates

    config, pre, tau, comb_on = _settings(params, 1.0)  # before the data: dt unknown
    y, dt, notes = prepare_axis(recording, axis, prefilter=pre, M=config.model.M,
                                omega_max=config.omega_max, normalize_tau=tau or None)
    config = _settings(params, dt)[0]
    model = config.model
    comb = None
    if comb_on:
        comb, c_rng = comb_candidates(recording.channel(axis_channel(axis)), dt,
                                      config.omega_min, config.omega_limit)
        notes.append(f"comb check: {np.isfinite(comb).sum()} candidates from the harmonic comb "
                     f"({COMB_FRAME_S:g} s frames every {COMB_HOP_S:g} s, range "
                     f"{c_rng[0]:.3g}-{c_rng[1]:.3g} rad/s); "
                     + ("omega acquired from the first steady one, " if config.acquire else "")
                     + "reset to them after 2 disagreeing by > 10 % in a row")
    parts: list[Result] = []

    def chunk(a: int, b: int) -> Result:
        parts.append(run(config, y[a:b], parts[-1].final if parts else None,
                         comb=None if comb is None else comb[a:b]))
        return parts[-1]

    run_in_chunks(chunk, y.size, progress=progress, label="ekf")
    res = Result(*(np.concatenate([getattr(p, f) for p in parts])
                   for f in Result._fields[:-1]), parts[-1].final)
    if config.acquire and not res.acquired.any():
        notes.append("no steady comb candidate: omega never acquired (the output is the EKF "
                     f"from the placeholder omega0 = {config.omega0:g} rad/s)")
    extras = {f"amp{m + 1}": res.amplitudes[:, m] for m in range(model.M)}
    extras["nis"] = res.innovation**2 / res.innovation_var
    extras["acquired"] = res.acquired.astype(np.float64)
    return Track.from_omega(
        recording.t, res.omega, res.omega_std,
        wheel_radius=wheel_radius or recording.wheel_radius, method="ekf",
        params={**model.to_dict(), "omega0": config.omega0, "p0_omega": config.p0_omega,
                "amp0": config.amp0, "omega_min": config.omega_min,
                "omega_max": config.omega_limit, "prefilter": pre,
                "normalize_tau": tau, "axis": axis, "comb": comb_on,
                "acquire": config.acquire},
        extras=extras, notes=notes,
    )
