"""The grid tracker on a recording: pre-filter, scaling and the config (:func:`prepare`), then
the optional parameter fit, the causal filter or a smoother, and the Track (:func:`track`)."""

from __future__ import annotations

import numpy as np

import vibrospeed.estimators.grid.fit as _fit
import vibrospeed.estimators.grid.smoother as grid_smoother
from vibrospeed.config import config_from_params
from vibrospeed.estimators import scaling as _scaling
from vibrospeed.estimators.grid.config import Config
from vibrospeed.estimators.grid.filter import Result, concat, init, run
from vibrospeed.estimators.grid.kernel import check_grid_spacing
from vibrospeed.io.timebase import check_fundamental
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.types import Recording, Track


def prepare(recording: Recording, axis: str, config_cls, params: dict | None, default_model):
    """Shared by the harmonic trackers: pre-filter, Nyquist check, scaling and the config.

    Returns ``(config, y_scaled, rms, notes)``; ``config.model.dt`` is the recording's period.
    """
    from vibrospeed.estimators.common import check_nyquist, prepare_axis, split_params

    params = dict(params or {})
    model_kw, cfg_kw = split_params(HarmonicModel, params)
    model_kw.pop("dt", None)
    base = default_model(1.0).to_dict()
    base.pop("dt")
    probe = config_from_params(config_cls, cfg_kw,
                               model=config_from_params(HarmonicModel, model_kw, dt=1.0, **base))
    y, dt, notes = prepare_axis(recording, axis, prefilter=probe.prefilter, M=probe.model.M,
                                normalize_tau=None,
                                omega_range=(probe.omega_min, probe.omega_max))
    fs = 1.0 / dt
    src = recording.source or "recording"
    om_max = float(probe.omega_max)
    M = probe.model.M
    check_fundamental(fs, om_max, src)
    if probe.nyquist == "error":
        check_nyquist(fs, M, om_max, src)
    elif M * om_max >= np.pi * fs:
        notes.append(
            f"harmonics alias above omega = {np.pi * fs / M:.4g} rad/s (M = {M}, fs = "
            f"{fs:.4g} Hz); the rotation model describes the aliased lines exactly"
        )
    model = config_from_params(HarmonicModel, model_kw, dt=dt, **base)
    config = config_from_params(config_cls, cfg_kw, model=model)
    if config.scaling == "rms":
        y, rms = _scaling.normalise(y, dt, tau=config.rms_tau, target=config.signal_rms)
        notes.append(f"running-RMS normalisation to {config.signal_rms} (tau {config.rms_tau} s)")
    else:
        rms = np.full_like(y, config.signal_rms)
    return config, y, rms, notes


#: gain of the paper's high-pass (order 2) below which a note warns that the pre-filter
#: suppresses the low end of the grid (and with it the fundamental of slow wheels)
_PREFILTER_NOTE_GAIN = 0.5


def prefilter_note(config: Config, fs: float) -> str | None:
    """A note when the pre-filter's high-pass attenuates ``omega_min`` by more than half: e.g.
    ``paper-hp`` (8 Hz = 50 rad/s) on a 10 rad/s cart leaves the fundamental at 4 % and the
    2nd harmonic at 16 % of their amplitudes, so a body resonance wins."""
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.signal.dsp import sosfreqz

    try:
        sos = pf.design(config.prefilter, fs, M=config.model.M,
                        omega_range=(config.omega_min, config.omega_max))
    except Exception:  # pragma: no cover - preset validated in prepare
        return None
    _, h = sosfreqz(sos, worN=[config.omega_min / (2 * np.pi)], fs=fs)
    g = float(np.abs(h[0]))
    if g < _PREFILTER_NOTE_GAIN:
        return (f"pre-filter '{config.prefilter}' passes only {100 * g:.0f} % of the amplitude at "
                f"omega_min = {config.omega_min:g} rad/s: slow wheels' low harmonics are "
                "suppressed (use -p prefilter=thesis-hp for slow vehicles)")
    return None


def fit_for_track(config: Config, y: np.ndarray, extra, notes: list) -> Config:
    """``config`` with ``config.fit_names`` fitted by marginal likelihood on ``y`` (with the
    causal filter's ``extra`` evidence); the fitted values and any warnings go to ``notes``."""
    fr = _fit.fit(config, y, names=config.fit_names, extra=extra)
    notes.append("fitted by marginal likelihood: " + ", ".join(
        f"{k} = {v:.4g}" for k, v in fr.values.items()) + f" (log p(y) {fr.loglik:.6g})")
    notes.extend(f"fit: {w}" for w in fr.warnings)
    return fr.config


def track(recording: Recording, config: Config, y: np.ndarray, rms: np.ndarray, notes: list,
          *, axis: str, wheel_radius: float | None, progress: bool = False,
          return_posterior: bool | np.ndarray = False, method: str = "rbpmf",
          extra: tuple[np.ndarray, np.ndarray] | None = None,
          extra_params: dict | None = None) -> Track:
    """The part of :func:`estimate` after :func:`prepare` (shared with
    :mod:`vibrospeed.estimators.grid`): optional fit, filter or smoother, Track with extras.
    ``extra``: log-evidence per :func:`run`. ``return_posterior``: the posterior in the
    extras, at every sample (True) or at the increasing sample indices given (then also
    ``extras["posterior_index"]``)."""
    if config.fit_names:
        config = fit_for_track(config, y, extra, notes)
    for note in (check_grid_spacing(config), prefilter_note(config, 1.0 / config.model.dt)):
        if note:
            notes.append(note)
    if config.kern.B > 0:
        notes.append(f"banded kernel: B = {config.kern.B}, discarded row mass <= "
                     f"{config.kern.tail:.2g}")
    sm = None
    if config.smooth == "none":
        res = _run_chunked(config, y, return_posterior, progress, extra)
        omap, post = res.omega_map, res.posterior
    else:
        res = run(config, y, return_grid_loglik=True, extra=extra)
        if config.smooth == "fb":
            sm = grid_smoother.smooth(config, res.grid_loglik, return_posterior=return_posterior)
            omap = sm.omega_map
            notes.append("forward-backward smoother on the grid; omega_map = the smoothed "
                         "posterior's MAP")
        else:
            sm = grid_smoother.fixed_lag(config, res.grid_loglik, lag=config.lag,
                                         return_posterior=return_posterior)
            omap = sm.omega_map
            notes.append(f"fixed-lag smoother, lag {config.lag:g} s (delay <= 2 lag)")
        post = sm.posterior
    if config.point == "mode":
        notes.append("omega = mean of the MAP mode (point='mode'); the posterior mean is in "
                     "extras['omega_mean']")
    (omega, std, lo, hi), extras = columns(config, res, sm, omap, rms)
    every = isinstance(return_posterior, bool | np.bool_)
    if not every or return_posterior:
        extras["posterior"] = post
        extras["grid"] = config.grid.copy()
        if not every:
            extras["posterior_index"] = np.asarray(return_posterior, dtype=np.int64)
    return Track.from_omega(
        recording.t, omega, std, lo=lo, hi=hi,
        level=config.level, wheel_radius=wheel_radius or recording.wheel_radius, method=method,
        params={**config.to_dict(), **(extra_params or {}), "axis": axis}, extras=extras,
        notes=notes,
    )


def columns(config: Config, res: Result, sm, omap: np.ndarray,
            rms: np.ndarray) -> tuple[tuple[np.ndarray, ...], dict[str, np.ndarray]]:
    """``(omega, omega_std, omega_lo, omega_hi)`` and the extras of the Track from the filter's
    result ``res`` and, when smoothed, the smoother's ``sm`` (None: the causal filter's own
    columns), the MAP path ``omap`` and the scaling ``rms``, row for row (so that a block of
    rows gives that block's columns)."""
    if sm is None:  # res.omega is already the chosen point estimate
        omega, std, lo, hi = res.omega, res.omega_std, res.omega_lo, res.omega_hi
        p_null, p_half, p_double = res.p_null, res.p_half, res.p_double
        p_third, p_triple = res.p_third, res.p_triple
        o_mode, p_mode, o_mean = res.omega_mode, res.p_mode, res.omega_mean
        o_mode_std = res.omega_mode_std
    else:
        omega, std, lo, hi = sm.omega, sm.omega_std, sm.omega_lo, sm.omega_hi
        p_null, p_half, p_double = sm.p_null, sm.p_half, sm.p_double
        p_third, p_triple = sm.p_third, sm.p_triple
        o_mode, p_mode, o_mean = sm.omega_mode, sm.p_mode, sm.omega
        o_mode_std = sm.omega_mode_std
        if config.point == "mode":
            omega = o_mode
    conf = 1.0 - p_null
    amb = np.maximum(np.maximum(p_half, p_double), np.maximum(p_third, p_triple))
    extras: dict[str, np.ndarray] = {
        "omega_map": omap, "loglik": res.loglik, "p_null": p_null, "p_half": p_half,
        "p_double": p_double, "p_third": p_third, "p_triple": p_triple, "confidence": conf,
        "ambiguous": (amb >= 0.05).astype(np.float64), "rms": rms,
        "omega_mode": o_mode, "p_mode": p_mode, "omega_mode_std": o_mode_std,
        "multimodal": (p_mode < config.mode_share).astype(np.float64),
    }
    if config.has_null:  # without a "no line" state (the paper's filter) nothing is claimed:
        extras["has_signal"] = config.claims(p_null)  # the line is assumed at every sample
    if config.point == "mode":
        extras["omega_mean"] = o_mean
    for m in range(config.model.M):
        extras[f"amp{m + 1}"] = res.amplitudes[:, m] * rms / config.signal_rms
    # a copy: the stops zero the Track's omega in place (apply_standstill), and omega is often
    # the very array of omega_mode or omega_mean, which stay the tracker's there
    return (np.array(omega, dtype=np.float64), std, lo, hi), extras


def _run_chunked(config: Config, y: np.ndarray, return_posterior, progress: bool,
                 extra=None) -> Result:
    if not progress or extra is not None:
        return run(config, y, return_posterior=return_posterior, extra=extra)
    from rich.progress import Progress

    chunk = 20000
    parts = []
    state = init(config)
    with Progress(transient=True) as bar:
        task = bar.add_task("rbpmf", total=y.size)
        for k0 in range(0, y.size, chunk):
            if isinstance(return_posterior, bool | np.bool_):
                want = return_posterior
            else:  # the chunk's own indices
                idx = np.asarray(return_posterior)
                want = idx[(idx >= k0) & (idx < k0 + chunk)] - k0
            res = run(config, y[k0 : k0 + chunk], state, return_posterior=want)
            parts.append(res)
            state = res.final
            bar.update(task, advance=min(chunk, y.size - k0))
    return concat(parts)
