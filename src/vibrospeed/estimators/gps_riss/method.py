"""A recording in, a Track out (:func:`estimate`: the longitudinal accelerometer channel and
``gps_speed``, the ``paper`` preset) and the identification of the receiver's lag model from a
reference speed (:func:`identify_lag`, :func:`identify_lag_recording`)."""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np

from vibrospeed.config import config_from_params
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.common import gps_no_fix_as_nan
from vibrospeed.estimators.gps_riss.config import Config
from vibrospeed.estimators.gps_riss.filter import Sample, _run_progress, run
from vibrospeed.models.gps_riss import GpsLagModel, simulate_receiver
from vibrospeed.types import Recording, Track

_AXIS_CHANNEL = {"x": "ax", "y": "ay", "z": "az"}


def estimate(recording: Recording, *, axis: str = "x", wheel_radius: float | None = None,
             params: dict | None = None, progress: bool = False,
             return_posterior: bool = False) -> Track:
    """Fused speed for a recording with an accelerometer channel and ``gps_speed``.

    ``axis`` names the longitudinal accelerometer channel: "x" -> ``ax`` (phones often have "y"
    forward -> ``ay``); a channel name may be given directly. ``gps_speed`` must be finite only at
    samples carrying a new fix (NaN between fixes). ``params`` overrides :class:`Config` fields.
    ``progress`` shows a progress bar (the recording is filtered in chunks of 200 000 samples;
    same numbers). The Track's ``speed_std`` is sqrt(P11) (an honest 1-sigma when the noise
    parameters match the sensors; 98 % band by default); extras hold ``offset``, ``offset_std``,
    ``gps_error``, ``accel``, ``gps_model``, ``mode``. ``params["preset"] = "paper"`` starts from
    :meth:`Config.paper` (the paper's noise constants) instead of the calibrated defaults.
    """
    params = dict(params or {})
    preset = str(params.pop("preset", "default")).lower()
    if preset not in ("default", "paper"):
        raise ParameterError(f"unknown gps-riss preset '{preset}' (choose default or paper)")
    base = asdict(Config.paper()) if preset == "paper" else {}
    cfg = config_from_params(Config, params, **base)
    ch = _AXIS_CHANNEL.get(axis, axis)
    recording.require(ch, "gps_speed")
    recording, notes = gps_no_fix_as_nan(recording)
    sats = recording.channels.get("gps_sats")
    args = (cfg, recording.t, recording.channel(ch), recording.channel("gps_speed"), sats)
    if progress:
        end: list = []
        o = _run_progress(*args, end=end)
        final = end[0]
    else:
        res = run(cfg, Sample(*args[1:]))
        o, final = res.output, res.final
    params_out = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()}
    # the receiver's lag, the model's and the learned extra one, at the end of the log
    params_out["learned_gps_lag"] = cfg.lag.lag + float(final.x[-1])
    params_out["learned_gps_lag_std"] = math.sqrt(max(float(final.P[-1, -1]), 0.0))
    return Track.from_speed(
        recording.t, o.speed, o.speed_std, wheel_radius=wheel_radius or recording.wheel_radius,
        method="gps-riss", params=params_out,
        extras={"offset": o.offset, "offset_std": o.offset_std, "gps_error": o.gps_error,
                "accel": o.accel, "gps_model": o.gps_model, "mode": o.mode.astype(np.float64)},
        notes=notes,
    )


# -- identification ----------------------------------------------------------------------------

def identify_lag(t, gps_speed, speed_ref, *, wn0: float = 10.0, zeta0: float = 0.8,
                 fit_gain: bool = False, fit_delay: bool = False, delay0: float = 0.2,
                 pade: int = 2) -> tuple[GpsLagModel, dict[str, float]]:
    """Fit the receiver model (paper section IV-b: second-order lag; optionally a gain and a pure
    delay in front, Pade order ``pade`` as the filter uses it) to GPS fixes. With ``fit_delay``
    the fit starts from the delays 0, ``delay0`` and ``2 delay0`` and keeps the best.

    Simulates ``x3`` driven by the reference speed (taken piecewise linear) for candidate
    ``(wn, zeta[, gain][, delay])`` and minimises the squared difference to ``gps_speed`` at its
    finite samples (scipy ``least_squares``; wn, zeta on a log scale). Returns the model and a dict
    with ``wn, zeta, gain, delay, rmse`` (m/s residual) and ``rmse_identity`` (residual of
    ``x3 = speed``).

    Parameters
    ----------
    t : (n,) s.  gps_speed : (n,) m/s, NaN between fixes.  speed_ref : (n,) m/s finite reference.
    """
    from scipy.optimize import least_squares

    t = np.asarray(t, float)
    g = np.asarray(gps_speed, float)
    v = np.asarray(speed_ref, float)
    if not (t.shape == g.shape == v.shape and t.ndim == 1):
        raise InputError("identify_lag: t, gps_speed and speed_ref must be 1-D of equal length")
    ok = np.isfinite(v)
    if not ok.all():
        t, g, v = t[ok], g[ok], v[ok]
    fix = np.isfinite(g)
    if fix.sum() < 10:
        raise InputError(f"identify_lag: need >= 10 GPS fixes with a reference, got {fix.sum()}")

    def model(theta):
        wn, zeta = np.exp(theta[0]), np.exp(theta[1])
        gain = theta[2] if fit_gain else 1.0
        delay = theta[-1] if fit_delay else 0.0
        return GpsLagModel.from_wn_zeta(wn, zeta, gain, delay=delay if delay > 1e-4 else 0.0,
                                        pade=pade)

    def resid(theta):
        return simulate_receiver(t, v, model(theta))[fix] - g[fix]

    lo = [np.log(0.05), np.log(0.05)] + ([0.5] if fit_gain else []) + ([0.0] if fit_delay else [])
    hi = [np.log(500.0), np.log(20.0)] + ([1.5] if fit_gain else []) + (
        [2.0] if fit_delay else [])
    # the delay trades off against the lag (near-equal residuals): start from several delays and
    # keep the best fit
    sol = None
    for d0 in ((0.0, delay0, 2.0 * delay0) if fit_delay else (None,)):
        x0 = [np.log(wn0), np.log(zeta0)] + ([1.0] if fit_gain else []) + (
            [d0] if fit_delay else [])
        cand = least_squares(resid, x0, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4)
        if sol is None or cand.cost < sol.cost - 1e-9 * max(sol.cost, 1e-12):
            sol = cand
    lag = model(sol.x)
    info = {"wn": lag.wn, "zeta": lag.zeta, "gain": lag.dc_gain, "delay": lag.delay,
            "rmse": float(np.sqrt(np.mean(sol.fun**2))),
            "rmse_identity": float(np.sqrt(np.mean((v[fix] - g[fix]) ** 2)))}
    return lag, info


def identify_lag_recording(recording: Recording, *, reference: str = "speed_true", **kw
                           ) -> tuple[GpsLagModel, dict[str, float]]:
    """:func:`identify_lag` on a recording's ``gps_speed`` against its ``reference`` channel."""
    recording.require("gps_speed", reference)
    return identify_lag(recording.t, recording.channel("gps_speed"),
                        recording.channel(reference), **kw)
