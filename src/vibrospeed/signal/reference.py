"""Reference speeds from events: bump crossings and steady turns (thesis 4.2.4; METHODS.md 2).

Sparse speed fixes with an uncertainty, usable to check a tracker or to feed the aided filter
(:mod:`vibrospeed.estimators.aided`, ``params={'reference': 'both'}``).

* Bump crossing (thesis eq. 4.2): a bump or pothole hits the vertical axis twice, the front axle
  first and the rear axle ``dT`` later; ``v = L / dT`` with wheelbase ``L``. Detection: ``az``
  high-passed (order 2, ``bump_hp`` Hz), events where ``|az_hp|`` exceeds
  ``max(min_peak, k_mad * 1.4826 MAD)``; consecutive events with
  ``L / v_max <= dT <= L / v_min`` form a pair, and ``dT`` is refined by cross-correlating the
  two shock waveforms (both hits ring alike) with a parabolic sub-sample peak.
  ``sigma_v = v * sigma_T / dT`` with ``sigma_T = sqrt(2) * t_res`` (``t_res`` = timing error of
  one event, default a quarter of a sample period).
* Steady turn (thesis eq. 4.3): ``v_x = a_y / yaw_rate``. Both ``ay`` and ``gz`` pass the same
  causal Butterworth low-pass (order 4, ``turn_lp`` Hz; it removes the wheel vibrations on ``ay``)
  so that their ratio is not distorted by the filter; offsets of both are removed with running
  means over the straight stretches seen so far (``|gz_lp| < gz_min / 3``; causal). A fix every
  ``fix_interval`` s while ``|gz_lp| > gz_min`` and the yaw rate is steady
  (``|d gz_lp / dt| < steady * |gz_lp|`` per s). The fix is timed ``delay`` (the low-pass group
  delay at 0 Hz) before the sample it is computed on. ``sigma_v = sqrt(sigma_a^2 +
  (v sigma_g)^2) / |gz_lp|``.

Fixes carry ``t`` (the time the speed refers to), ``t_detect`` (when a causal detector knows it),
``speed`` and ``speed_std`` (m/s) and ``kind`` ('bump' or 'turn').
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import signal as sps

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.types import Recording


class Fixes(NamedTuple):
    """Sparse speed fixes, all arrays of the same length (sorted by ``t_detect``)."""

    t: np.ndarray  # s, the time the speed refers to
    t_detect: np.ndarray  # s, the time the fix becomes available
    speed: np.ndarray  # m/s
    speed_std: np.ndarray  # m/s
    kind: np.ndarray  # 'bump' or 'turn'

    def __len__(self) -> int:  # type: ignore[override]
        return int(self.t.size)


def _empty() -> Fixes:
    z = np.zeros(0)
    return Fixes(z, z, z, z, np.zeros(0, dtype="<U4"))


def _concat(*fs: Fixes) -> Fixes:
    parts = [f for f in fs if len(f)]
    if not parts:
        return _empty()
    out = Fixes(*[np.concatenate([getattr(f, k) for f in parts]) for k in Fixes._fields])
    order = np.argsort(out.t_detect, kind="stable")
    return Fixes(*[a[order] for a in out])


def _uniform(recording: Recording, *names: str) -> float:
    recording.require(*names)
    dt = recording.dt
    if not recording.is_uniform(0.05):
        raise InputError(f"{recording.source or 'recording'}: reference detectors need a uniform "
                         "time line; resample first")
    return dt


# ---------------------------------------------------------------------------------------------
def _highpass(az: np.ndarray, fs: float, cutoff: float) -> np.ndarray:
    x = np.nan_to_num(np.asarray(az, dtype=np.float64) - np.nanmedian(az))
    sos = sps.butter(2, cutoff, btype="highpass", fs=fs, output="sos")
    return sps.sosfilt(sos, x, zi=sps.sosfilt_zi(sos) * x[0])[0]


def bump_events(az: np.ndarray, fs: float, *, bump_hp: float = 5.0, min_peak: float = 0.5,
                k_mad: float = 8.0, event_len: float = 0.15) -> np.ndarray:
    """Sample indices where vertical shocks in ``az`` (m/s^2) begin (first sample above the
    threshold; a new event needs ``event_len`` s below it first)."""
    e = np.abs(_highpass(az, fs, bump_hp))
    mad = 1.4826 * np.median(np.abs(e - np.median(e)))
    thr = max(min_peak, k_mad * mad)
    above = np.flatnonzero(e > thr)
    if above.size == 0:
        return np.zeros(0, dtype=np.int64)
    n_ev = max(1, int(round(event_len * fs)))
    return above[np.concatenate([[True], np.diff(above) > n_ev])]


def _xcorr_delay(x: np.ndarray, i0: int, i1: int, n: int, search: int = 3) -> float:
    """Sub-sample delay (samples) of the event at ``i1`` against the one at ``i0``: maximum of
    their cross-correlation over lags ``i1 - i0 +- search``, refined by a parabola."""
    a0 = max(i0 - 2, 0)
    seg0 = x[a0 : a0 + n]
    best = []
    lags = np.arange(-search, search + 1)
    for lag in lags:
        a1 = a0 + (i1 - i0) + lag
        seg1 = x[a1 : a1 + seg0.size] if a1 >= 0 else np.zeros(0)
        best.append(float(np.dot(seg0, seg1)) if seg1.size == seg0.size else -np.inf)
    c = np.asarray(best)
    j = int(np.argmax(c))
    off = 0.0
    if 0 < j < c.size - 1 and np.all(np.isfinite(c[j - 1 : j + 2])):
        den = c[j - 1] - 2 * c[j] + c[j + 1]
        off = 0.5 * (c[j - 1] - c[j + 1]) / den if den != 0 else 0.0
    return float(i1 - i0 + lags[j] + off)


def bump_fixes(recording: Recording, wheelbase: float | None = None, *, v_min: float = 0.1,
               v_max: float = 40.0, t_res: float | None = None, bump_hp: float = 5.0,
               event_len: float = 0.15, **kw) -> Fixes:
    """Speed fixes ``v = L / dT`` from pairs of ``az`` shocks (thesis eq. 4.2).

    ``dT`` is the lag maximising the cross-correlation of the two (alike) shock waveforms,
    refined to a fraction of a sample.
    """
    L = wheelbase if wheelbase is not None else recording.meta.get("wheelbase")
    if not L or not L > 0:
        raise ParameterError(f"{recording.source or 'recording'}: bump fixes need the wheelbase "
                             "(wheelbase=... in m)")
    if not 0 < v_min < v_max:
        raise ParameterError(f"bump fixes: need 0 < v_min < v_max, got {v_min}, {v_max}")
    dt = _uniform(recording, "az")
    fs = 1.0 / dt
    az = recording.channel("az")
    ev = bump_events(az, fs, bump_hp=bump_hp, event_len=event_len, **kw)
    x = _highpass(az, fs, bump_hp)
    n_ev = max(3, int(round(event_len * fs)))
    t_res = 0.25 * dt if t_res is None else t_res
    t0 = recording.t[0]
    out_t, out_d, out_v, out_s = [], [], [], []
    i = 0
    while i < ev.size - 1:
        d = (ev[i + 1] - ev[i]) * dt
        if L / v_max <= d <= L / v_min:
            d = _xcorr_delay(x, int(ev[i]), int(ev[i + 1]), n_ev) * dt
            v = L / d
            out_t.append(t0 + ev[i] * dt + 0.5 * d)
            out_d.append(t0 + ev[i + 1] * dt + event_len)  # known once the 2nd shock is over
            out_v.append(v)
            out_s.append(v * np.sqrt(2.0) * t_res / d)
            i += 2
        else:
            i += 1
    n = len(out_t)
    return Fixes(np.array(out_t), np.array(out_d), np.array(out_v), np.array(out_s),
                 np.full(n, "bump"))


def turn_fixes(recording: Recording, *, turn_lp: float = 0.4, gz_min: float = 0.2,
               steady: float = 0.3, fix_interval: float = 0.5, sigma_a: float = 0.02,
               sigma_g: float = 0.005, lat_axis: str = "ay", yaw_axis: str = "gz") -> Fixes:
    """Speed fixes ``v = a_y / yaw_rate`` in steady turns (thesis eq. 4.3), causal."""
    dt = _uniform(recording, lat_axis, yaw_axis)
    fs = 1.0 / dt
    if not 0 < turn_lp < fs / 2:
        raise ParameterError(f"turn fixes: turn_lp must lie in (0, {fs / 2:g}) Hz, got {turn_lp}")
    sos = sps.butter(4, turn_lp, fs=fs, output="sos")
    ay = np.asarray(recording.channel(lat_axis), dtype=np.float64)
    gz = np.asarray(recording.channel(yaw_axis), dtype=np.float64)
    ok = np.isfinite(ay) & np.isfinite(gz)
    ay_f = np.where(ok, ay, 0.0)
    gz_f = np.where(ok, gz, 0.0)
    a0 = ay_f[ok][0] if ok.any() else 0.0
    g0 = gz_f[ok][0] if ok.any() else 0.0
    zi = sps.sosfilt_zi(sos)
    a_lp = sps.sosfilt(sos, ay_f, zi=zi * a0)[0]
    g_lp = sps.sosfilt(sos, gz_f, zi=zi * g0)[0]
    # group delay of the low-pass at 0 Hz (s)
    w, gd = sps.group_delay(sps.sos2tf(sos), w=[1e-4], fs=fs)
    delay = float(gd[0]) / fs
    # causal offsets: running means over straight samples seen so far
    straight = ok & (np.abs(g_lp) < gz_min / 3.0)
    cnt = np.cumsum(straight)
    a_off = np.cumsum(np.where(straight, a_lp, 0.0)) / np.maximum(cnt, 1)
    g_off = np.cumsum(np.where(straight, g_lp, 0.0)) / np.maximum(cnt, 1)
    a_c = a_lp - a_off
    g_c = g_lp - g_off
    dg = np.gradient(g_c, dt)
    settle = int(np.ceil(3 * delay * fs))  # ignore the filter's start
    turning = (np.abs(g_c) > gz_min) & (np.abs(dg) < steady * np.abs(g_c)) & (cnt > 0)
    turning[:settle] = False
    step = max(1, int(round(fix_interval * fs)))
    idx = []
    last = -step
    for k in np.flatnonzero(turning):
        if k - last >= step:
            idx.append(k)
            last = k
    idx = np.asarray(idx, dtype=np.int64)
    if idx.size == 0:
        return _empty()
    v = a_c[idx] / g_c[idx]
    keep = v > 0
    idx, v = idx[keep], v[keep]
    s = np.sqrt(sigma_a**2 + (v * sigma_g) ** 2) / np.abs(g_c[idx])
    t = recording.t[idx]
    return Fixes(t - delay, t, v, s, np.full(idx.size, "turn"))


def detect(recording: Recording, kinds: str = "both", *, wheelbase: float | None = None) -> Fixes:
    """Fixes of the kinds 'bump', 'turn' or 'both', sorted by detection time."""
    if kinds not in ("bump", "turn", "both"):
        raise ParameterError(f"reference kinds must be bump, turn or both, got '{kinds}'")
    parts = []
    if kinds in ("bump", "both"):
        if kinds == "both" and not (wheelbase or recording.meta.get("wheelbase")):
            pass  # no wheelbase: bump fixes silently unavailable when both are asked for
        else:
            parts.append(bump_fixes(recording, wheelbase))
    if kinds in ("turn", "both") and "gz" in recording.channels:
        parts.append(turn_fixes(recording))
    return _concat(*parts)


def fixes_to_omega(fixes: Fixes, t: np.ndarray, wheel_radius: float, *,
                   causal: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Per-sample omega fixes (rad/s) and variances on time line ``t``; NaN where none.

    Each fix goes to the first sample at or after its ``t_detect`` (``causal``) or nearest to
    its ``t``; two fixes on one sample are combined by inverse-variance weighting.
    """
    t = np.asarray(t, dtype=np.float64)
    ref = np.full(t.size, np.nan)
    var = np.full(t.size, np.nan)
    if not len(fixes):
        return ref, var
    when = fixes.t_detect if causal else fixes.t
    idx = np.clip(np.searchsorted(t, when, side="left"), 0, t.size - 1)
    w = fixes.speed / wheel_radius
    v = (fixes.speed_std / wheel_radius) ** 2
    for i, wi, vi in zip(idx, w, v, strict=True):
        if np.isfinite(ref[i]):
            p = 1 / var[i] + 1 / vi
            ref[i] = (ref[i] / var[i] + wi / vi) / p
            var[i] = 1 / p
        else:
            ref[i], var[i] = wi, vi
    return ref, var
