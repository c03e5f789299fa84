"""Inputs of the aided trackers (the aided EKF :mod:`vibrospeed.estimators.aided` and the aided
grid filter :mod:`vibrospeed.estimators.aided_grid`): the longitudinal acceleration channel and
its detrending, the signal gain, reference-speed fixes (:mod:`vibrospeed.signal.reference`),
standstill flags and the accelerometer offset while standing."""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from vibrospeed.errors import InputError
from vibrospeed.types import Recording


class Sample(NamedTuple):
    """The inputs of one sample of an aided tracker (or, as arrays, of a signal): ``y`` the
    pre-filtered vibration (m/s^2), ``u`` the longitudinal acceleration (m/s^2; NaN: no
    aiding), ``gain`` on ``y`` before the update, ``ref``, ``ref_var`` an omega fix (rad/s)
    and its variance, ``still`` the standstill decision (1 standing), ``comb`` the harmonic
    comb's omega candidate (rad/s); NaN / None: none."""

    y: Any
    u: Any = math.nan
    gain: Any = 1.0
    ref: Any = math.nan
    ref_var: Any = math.nan
    still: Any = math.nan
    comb: Any = math.nan


def input_arrays(n: int, u, gain, ref, ref_var, where: str = "aided.run") -> tuple:
    """``(u, gain, ref, ref_var)`` as (n,) float64 arrays; None -> NaN (gain: 1). Shared by the
    aided EKF and the aided grid filter; a wrong shape is an :class:`InputError`."""
    out = []
    for name, v, fill in (("u", u, np.nan), ("gain", gain, 1.0), ("ref", ref, np.nan),
                          ("ref_var", ref_var, np.nan)):
        if v is None:
            out.append(np.full(n, fill))
            continue
        a = np.ascontiguousarray(v, dtype=np.float64)
        if a.shape != (n,):
            raise InputError(f"{where}: '{name}' has shape {a.shape}, expected ({n},) like y")
        out.append(a)
    return tuple(out)


#: rad/s, lower edge of the standstill detector's band when no search range is given (the
#: lowest wheel speed of the family's slow vehicles)
BROADBAND_LO = 2.0


def standstill_band(dt: float, M: int, omega_min: float | None = None,
                    omega_max: float | None = None) -> tuple[float, float]:
    """rad/s band of the standstill detector (:func:`vibrospeed.signal.standstill.standstill`
    reads it as the search band): ``omega_min`` (default, or at most 0: 2 rad/s) up to
    ``M omega_max`` (default Nyquist), clipped to Nyquist."""
    nyq = np.pi / dt
    lo = BROADBAND_LO if omega_min is None or omega_min <= 0 else float(omega_min)
    hi = nyq if omega_max is None else min(nyq, M * float(omega_max))
    return min(lo, 0.5 * hi), hi


#: s, each whole-log stop is shortened by this much at both ends (see :func:`standstill_flags`)
STILL_EDGE_S = 0.5


def standstill_flags(x: np.ndarray, dt: float, band: tuple[float, float], *,
                     causal: bool = False) -> np.ndarray:
    """Per-sample standstill flags (float 0/1) from the raw accelerometer axis ``x`` (n,) or
    axes (n, A): :func:`vibrospeed.signal.standstill.standstill` (whole-log decision by
    default, ``causal=True`` as a device would decide), each stop shortened by
    ``STILL_EDGE_S`` at both ends: the tracker holds omega at 0 while standing, so a stop must
    end before the vehicle moves off. Fed to :func:`run` as ``still`` with
    ``standstill='broadband'``."""
    from vibrospeed.signal import standstill as ss

    x = np.asarray(x, dtype=np.float64)
    return ss.standstill(x, dt, band, causal=causal, edge_s=STILL_EDGE_S).astype(np.float64)


def standstill_offset(u: np.ndarray, still: np.ndarray, *, causal: bool = False) -> np.ndarray:
    """Per-sample offset of the longitudinal accelerometer: its mean over the samples flagged
    standing (gravity leaking in through a tilted mount, the sensor's bias). Offline one value,
    the mean over every standing sample (over all samples when none stands); causally the
    mean over the standing samples so far, and before the first one the mean of all samples so
    far (a drive starts at rest more often than not). NaN samples are skipped."""
    u = np.asarray(u, dtype=np.float64)
    fin = np.isfinite(u)
    st = (np.asarray(still) > 0.5) & fin
    if not causal:
        sel = st if st.any() else fin
        val = float(np.mean(u[sel])) if sel.any() else 0.0
        return np.full(u.size, val)
    uz = np.where(fin, u, 0.0)
    n_all = np.cumsum(fin)
    m_all = np.cumsum(uz) / np.maximum(n_all, 1)
    n_st = np.cumsum(st)
    m_st = np.cumsum(np.where(st, uz, 0.0)) / np.maximum(n_st, 1)
    return np.where(n_st > 0, m_st, np.where(n_all > 0, m_all, 0.0))


def _channel(recording: Recording, spec: str) -> np.ndarray:
    """'ax', 'x', '-ay' (negated)... -> channel values (:func:`~vibrospeed.estimators.common.
    signed_axis`)."""
    from vibrospeed.estimators.common import signed_axis

    name, sign = signed_axis(spec)
    recording.require(name)
    return sign * recording.channel(name)


def running_mean(u: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """Causal exponential running mean (time constant ``tau`` s, plain mean while ``t < tau``);
    NaN samples keep the previous value."""
    out = np.empty_like(u, dtype=np.float64)
    m = 0.0
    cnt = 0.0
    a = min(1.0, dt / tau)
    for k, v in enumerate(np.asarray(u, dtype=np.float64)):
        if np.isfinite(v):
            cnt += 1.0
            m += (v - m) * max(a, 1.0 / cnt)
        out[k] = m if cnt else np.nan
    return out


def running_gain(y: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """Factor ``g_k`` with ``g_k y_k`` = running-RMS-normalised y (:mod:`signal.normalize`)."""
    from vibrospeed.signal.normalize import running_rms_normalize

    yn = running_rms_normalize(y, dt, tau)
    with np.errstate(divide="ignore", invalid="ignore"):
        g = np.where(np.abs(y) > 0, yn / y, np.nan)
    # forward fill where y = 0 exactly (the gain only scales the CUSUM residual there)
    ok = np.isfinite(g)
    if not ok.any():
        return np.ones_like(y)
    idx = np.where(ok, np.arange(g.size), 0)
    np.maximum.accumulate(idx, out=idx)
    g = g[idx]
    first = int(np.flatnonzero(ok)[0])
    g[:first] = g[first]
    return g


def aiding_inputs(recording: Recording, dt: float, wheel_radius: float, *,
                  accel_axis: str = "ax", detrend: float = 0.0, reference: str = "none",
                  wheelbase: float | None = None) -> tuple:
    """Aiding inputs shared by both trackers: ``(u, ref, ref_var, notes)``.

    ``u`` = the ``accel_axis`` channel (m/s^2), minus a causal running mean with time constant
    ``detrend`` s when ``detrend > 0``; ``ref``, ``ref_var``: per-sample omega fixes from
    :mod:`vibrospeed.signal.reference` (None when ``reference == 'none'``).
    """
    u = _channel(recording, accel_axis)
    notes = [f"aided by '{accel_axis}' (wheel radius {wheel_radius:g} m)"]
    if detrend > 0:
        u = u - running_mean(u, dt, detrend)
        notes.append(f"'{accel_axis}' detrended by a causal running mean (tau = {detrend:g} s)")
    ref = ref_var = None
    if reference != "none":
        from vibrospeed.signal import reference as refmod

        fixes = refmod.detect(recording, kinds=reference, wheelbase=wheelbase)
        ref, ref_var = refmod.fixes_to_omega(fixes, recording.t, wheel_radius)
        notes.append(f"{len(fixes)} reference-speed fixes ({reference}) fed as measurements")
    return u, ref, ref_var, notes
