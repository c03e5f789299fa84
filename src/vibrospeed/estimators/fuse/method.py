"""A recording in, a fused Track out (:func:`estimate`): the radius prior (given, or read back
from an earlier estimate by :func:`radius_from_json`), the vibration tracker, the reduction of
the recording to fusion samples (:func:`fusion_samples`, block means), the forward filter and
the smoother, and the interpolation back to the recording's time line; :func:`suits` says
whether a recording feeds ``fuse`` without a radius."""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, fields, replace
from pathlib import Path

import numpy as np

from vibrospeed.config import config_from_params, parse_flag
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.common import (
    axis_channel,
    check_time,
    gps_no_fix_as_nan,
    signed_axis,
)
from vibrospeed.estimators.fuse.band import learn_acc_psd, learn_acc_psd_causal
from vibrospeed.estimators.fuse.config import (
    CAUSAL_VIB_AMAX,
    CAUSAL_VIB_LAG,
    CAUSAL_VIB_MEASURE,
    CAUSAL_VIB_SEP,
    CAUSAL_VIB_SOFT,
    IB,
    IR,
    IV,
    SOURCES,
    SRC_STANDSTILL,
    SRC_VIBRATION,
    TRACKER_DEFAULTS,
    Config,
)
from vibrospeed.estimators.fuse.filter import init, run
from vibrospeed.estimators.fuse.smoother import smooth, smooth_band
from vibrospeed.types import Recording, Track, check_wheel_radius

# -- radius round trip ---------------------------------------------------------------------------

def radius_from_json(path: str | os.PathLike[str]) -> tuple[float, float]:
    """``(radius, std)`` in m from an earlier ``fuse`` estimate's sidecar (``est.csv.json``:
    ``params.learned_radius`` / ``params.learned_radius_std``), or from any JSON object with
    ``wheel_radius`` and optionally ``wheel_radius_std`` (default 1 % of it)."""
    return _read_radius(path)[:2]


def _read_radius(path: str | os.PathLike[str]) -> tuple[float, float, str]:
    """:func:`radius_from_json` and what the radius is: ``"learned"`` (a fuse sidecar), ``""``
    (a wheel radius), or the method of another estimate's sidecar (a radius it was given)."""
    p = Path(path)
    try:
        side = json.loads(p.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"{p}: cannot read the radius file ({exc})") from None
    if not isinstance(side, dict):
        raise InputError(f"{p}: the radius file must hold a JSON object")
    par = side.get("params") if isinstance(side.get("params"), dict) else {}
    # another method's estimate sidecar: its wheel_radius is the one it was given, not learned
    what = str(side["method"]) if side.get("kind") == "track" and "method" in side else ""
    if "learned_radius" in par:
        r, s = par.get("learned_radius"), par.get("learned_radius_std")
        what = "learned"
    elif what and side.get("wheel_radius") is None:
        raise InputError(f"{p}: a {what} estimate's sidecar holds no learned radius (only fuse "
                         "learns one) and no wheel radius")
    elif "wheel_radius" in side:
        r = side.get("wheel_radius")
        s = side.get("wheel_radius_std", None)
        s = 0.01 * r if s is None and isinstance(r, (int, float)) else s
    else:
        raise InputError(f"{p}: no learned_radius (a fuse estimate's sidecar) or wheel_radius "
                         "in the radius file")
    ok = all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
             and v > 0 for v in (r, s))
    if not ok:
        raise InputError(f"{p}: radius and its std must be positive numbers, got {r!r}, {s!r}")
    return float(r), float(s), what


# -- recording -> fusion samples ------------------------------------------------------------------

def fusion_samples(t: np.ndarray, fix: np.ndarray, rate: float) -> np.ndarray:
    """End indices (inclusive) of the fusion blocks: every ``round(fs / rate)`` samples and at
    every sample carrying a GPS fix, so that a fix is fused at its own time."""
    n = t.size
    dt = float(np.median(np.diff(t))) if n > 1 else 1.0
    m = max(1, int(round(1.0 / (rate * dt))))
    ends = np.union1d(np.arange(m - 1, n, m), np.flatnonzero(fix))
    if ends.size == 0 or ends[-1] != n - 1:
        ends = np.append(ends, n - 1)
    return ends.astype(np.int64)


def _block_mean(x: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Mean of the finite samples of ``x`` in each block ``(ends[k-1], ends[k]]`` (NaN: none)."""
    ok = np.isfinite(x)
    cs = np.concatenate([[0.0], np.cumsum(np.where(ok, x, 0.0))])
    cn = np.concatenate([[0], np.cumsum(ok)])
    starts = np.concatenate([[0], ends[:-1] + 1])
    s = cs[ends + 1] - cs[starts]
    c = cn[ends + 1] - cn[starts]
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(c > 0, s / np.maximum(c, 1), np.nan)


def _block_all(x: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """True where every sample of the block is true."""
    cn = np.concatenate([[0], np.cumsum(~x)])
    starts = np.concatenate([[0], ends[:-1] + 1])
    return (cn[ends + 1] - cn[starts]) == 0


_TRACKER_OWN = {"online", "lag", "radius_from", "accel_axis", "vib_method"}


def _split(params: dict) -> tuple[dict, dict, dict]:
    names = {f.name for f in fields(Config)}
    fuse_kw = {k: v for k, v in params.items() if k in names}
    own = {k: v for k, v in params.items() if k in _TRACKER_OWN}
    rest = {k: v for k, v in params.items() if k not in names and k not in _TRACKER_OWN}
    return fuse_kw, own, rest


def _lag_of(value) -> float | None:
    """``params["lag"]`` read: None (not given) or the fixed lag in s (> 0, finite)."""
    if value is None:
        return None
    try:
        lag = float(value)
    except (TypeError, ValueError):
        lag = math.nan
    if not (lag > 0 and math.isfinite(lag)) or isinstance(value, bool):
        raise ParameterError(f"fuse: lag must be a delay in s > 0 (the fixed-lag tracker's), "
                             f"got {value!r}")
    return lag


def estimate(recording: Recording, *, axis: str = "y", wheel_radius: float | None = None,
             params: dict | None = None, progress: bool = False,
             return_posterior: bool = False,
             radius_from: str | os.PathLike[str] | None = None,
             vibration: Track | None = None) -> Track:
    """Fused speed of a recording: vibration tracker on ``axis``, then the filter.

    ``params``: :class:`Config` fields; ``accel_axis`` (longitudinal accelerometer channel, a
    leading ``-`` negates it, a note names it and one says where it looks backwards,
    default ``ax``); ``online`` (true: the causal grid tracker and the forward filter only;
    default false: the smoothed grid tracker and the RTS smoother; online also ``vib_lag`` =
    :data:`CAUSAL_VIB_LAG`, ``vib_spread="mode"``, ``vib_amax``, ``vib_soft`` and
    ``vib_measure`` = :data:`CAUSAL_VIB_MEASURE` with ``vib_sep`` = :data:`CAUSAL_VIB_SEP`
    unless given); ``lag`` (s, > 0: a device that can wait ``lag`` s: the grid tracker's
    fixed-lag smoother, ``smooth="lag"`` with that lag, whose lines do not trail the speed,
    read with the offline settings by the forward filter; the batch numbers of
    :class:`~vibrospeed.estimators.fuse.device.FuseTracker` with a lag); ``radius_from`` (a JSON
    file, :func:`radius_from_json`, seeding the radius prior; also a keyword); every other
    name goes to the grid tracker (e.g. ``omega_min``, ``omega_max``). A given ``wheel_radius``
    seeds the prior with 1 % spread. ``gps_speed`` / ``gps_sats`` are used where present;
    without GPS the radius prior must come from ``radius_from`` or ``wheel_radius``.
    ``return_posterior``: the vibration tracker's omega posterior in ``extras["posterior"]``.
    ``vibration``: a grid track of this recording already at hand (then no tracker runs; it
    must be the causal one for ``online``; with ``vib_measure="posterior"`` it must hold its
    ``posterior`` and ``grid``, at every sample or at the fusion samples of the recording
    with all its fixes, ``posterior_index``; online without a posterior it is read by its
    mode). With ``vib_measure="posterior"`` the tracker keeps its posterior at the fusion
    samples only (``grid.estimate``'s ``return_posterior`` with their indices).

    Columns: speed and its band (from the fused std); omega = speed / learned radius where
    the radius is known at the end (relative std below ``octave_rel``; else empty, with a
    note); extras ``source`` (:data:`SOURCES` codes), ``radius``, ``radius_std``, ``offset``,
    ``harmonic`` (k of the wheel-frequency update), ``standstill`` (1 where fuse took a stop
    from all evidence: ``source`` 3) and the tracker's ``omega_vib``, ``has_signal`` and
    ``standstill_vib`` (its own stop detector, which GPS may have vetoed). The
    learned radius and its std (the filter's at the end of the log) are in
    ``params["learned_radius"]``, ``params["learned_radius_std"]`` (the JSON sidecar).
    """
    from vibrospeed.estimators import get

    params = dict(params or {})
    fuse_kw, own, rest = _split(params)
    cfg = config_from_params(Config, fuse_kw)
    online = parse_flag(own.get("online", False), "online")
    lag = _lag_of(own.get("lag"))
    causal = online and lag is None  # the causal tracker's lines trail the speed
    online = online or lag is not None  # the forward filter only
    if causal and "vib_lag" not in fuse_kw:
        cfg = replace(cfg, vib_lag=CAUSAL_VIB_LAG)
    if causal and "vib_spread" not in fuse_kw:
        cfg = replace(cfg, vib_spread="mode")
    if causal and "vib_amax" not in fuse_kw:
        cfg = replace(cfg, vib_amax=CAUSAL_VIB_AMAX)
    if causal and "vib_soft" not in fuse_kw:
        cfg = replace(cfg, vib_soft=CAUSAL_VIB_SOFT)
    if causal and "vib_measure" not in fuse_kw and cfg.vib_use == "line":
        # a given track without its posterior is read by its mode
        if vibration is None or "posterior" in vibration.extras:
            cfg = replace(cfg, vib_measure=CAUSAL_VIB_MEASURE)
    if causal and cfg.vib_measure == "posterior" and "vib_sep" not in fuse_kw:
        cfg = replace(cfg, vib_sep=CAUSAL_VIB_SEP)
    rf = radius_from if radius_from is not None else own.get("radius_from")
    acc_ch, acc_sign = signed_axis(str(own.get("accel_axis", "x")))
    acc_spec = ("-" if acc_sign < 0 else "") + acc_ch
    name = recording.source or "recording"
    if len(recording) < 2:
        raise InputError(f"{name}: fewer than 2 samples")
    check_time(recording)
    recording.require(acc_ch)
    recording, notes = gps_no_fix_as_nan(recording)
    has_gps = "gps_speed" in recording and np.isfinite(recording.channel("gps_speed")).any()
    if rf is not None:
        r0, rs0, what = _read_radius(rf)
        given = f" (the wheel radius given to that {what} run, not learned)" \
            if what not in ("", "learned") else ""
        notes.append(f"radius prior {r0:.4f} +- {rs0:.4f} m from {os.fspath(rf)}{given}")
        if rs0 >= cfg.octave_rel * r0:  # fuse's own test of a known radius (omega column)
            unknown = (f"{os.fspath(rf)}: {r0:.4f} +- {rs0:.4f} m is no learned radius (a "
                       f"spread of {rs0 / r0:.0%}, octave_rel {cfg.octave_rel:g}: that drive "
                       "never showed a wheel line while GPS was good)")
            if not has_gps:
                raise ParameterError(f"{unknown}; fuse without gps_speed needs a radius")
            notes.append(f"{unknown}: GPS teaches it here")
    elif wheel_radius:
        r0 = check_wheel_radius(wheel_radius)
        rs0 = 0.01 * r0
        notes.append(f"radius prior {r0:.4f} +- {rs0:.4f} m (the given wheel radius, 1 %)")
    elif has_gps:
        r0, rs0 = cfg.radius0, cfg.radius_std0
    else:
        raise ParameterError(f"{name}: fuse without gps_speed needs a radius: radius_from= an "
                             "earlier fuse estimate's .json, or --wheel-radius")
    if not cfg.radius_min <= r0 <= cfg.radius_max:  # no line would ever be read with it
        raise ParameterError(f"{name}: radius prior {r0:.4g} m is outside radius_min.."
                             f"radius_max ({cfg.radius_min:g}-{cfg.radius_max:g} m), where fuse "
                             "reads wheel lines (-p radius_min= / radius_max= to widen it)")
    # 1. the vibration tracker (offline smoothed / online causal); none on a log too slow to
    # carry a wheel line in the tracker's default range (GPS and the accelerometer still fuse)
    slow = _too_slow(recording, rest) if vibration is None else None
    if slow is not None:
        if not has_gps:
            raise ParameterError(f"{name}: {slow} and the recording has no GPS speed: fuse "
                                 "would integrate the accelerometer alone")
        notes.append(f"{slow}: fuse runs on GPS and the accelerometer, its vibration part off "
                     "(no wheel line, no stop evidence from vibration)")
        cfg = replace(cfg, vib_measure="mode")
        nan = np.full(len(recording), np.nan)
        vibration = Track.from_omega(recording.t, nan, nan, method="none",
                                     extras={"has_signal": np.zeros(len(recording))})
    tparams = {**TRACKER_DEFAULTS, **rest}
    if lag is not None:
        tparams.update(smooth="lag", lag=lag)
    elif online:
        tparams["smooth"] = "none"
    want_post = cfg.vib_measure == "posterior"
    t = recording.t
    g = recording.channels.get("gps_speed", np.full(t.size, np.nan))
    s = recording.channels.get("gps_sats", np.full(t.size, np.nan))
    fix = np.isfinite(g)
    ends = fusion_samples(t, fix, cfg.fuse_rate)
    if vibration is None:
        # the posterior only where fuse reads it (its fusion samples), unless asked for whole
        post = True if return_posterior else (ends if want_post else False)
        vib = get("grid").estimate(recording, axis=axis, params=tparams, progress=progress,
                                   return_posterior=post)
    elif len(vibration) != len(recording):
        raise InputError(f"{name}: the vibration track has {len(vibration)} samples, the "
                         f"recording {len(recording)}")
    else:
        vib = vibration
    claim = np.nan_to_num(vib.extras.get("has_signal", np.ones(len(vib)))) > 0.5
    still = (np.nan_to_num(vib.extras.get("standstill", np.zeros(len(vib)))) > 0.5) & ~claim
    line = claim if cfg.vib_use == "line" else (np.nan_to_num(vib.omega) > 0) & ~still
    # the line's spread: within the tracker's mode where it claims a line (the spread of omega
    # given that there is one), else (vib_use=all) its whole posterior's, "no line" and all
    spread = vib.omega_std
    if cfg.vib_spread == "mode" and "omega_mode_std" in vib.extras:
        spread = np.where(claim, np.asarray(vib.extras["omega_mode_std"], dtype=np.float64),
                          spread)
    # lines the tracker does not claim but holds at a line probability of at least vib_soft:
    # its mode, with the spread within the mode, offered to the re-lock only
    soft = np.zeros(len(vib), dtype=bool)
    if cfg.vib_soft < 1.0 and cfg.vib_use == "line" and "p_null" in vib.extras:
        p_line = 1.0 - np.nan_to_num(np.asarray(vib.extras["p_null"], dtype=np.float64),
                                     nan=1.0)
        soft = ~line & ~still & (p_line >= cfg.vib_soft) & (np.nan_to_num(vib.omega) > 0)
        if "omega_mode_std" in vib.extras:
            spread = np.where(soft, np.asarray(vib.extras["omega_mode_std"], dtype=np.float64),
                              spread)
        line = line | soft
    # where the vibration axis has no sample the tracker only predicts (its line there is its
    # past, or offline its interpolation between both sides, not a measurement): no line, no
    # stop evidence
    seen = np.isfinite(recording.channel(axis_channel(axis))) if slow is None else line
    line, still, soft = line & seen, still & seen, soft & seen
    # 2. fusion samples (ends, above)
    arrays = {
        "t": t[ends], "accel": acc_sign * _block_mean(recording.channel(acc_ch), ends),
        "gps_speed": g[ends], "gps_sats": s[ends], "omega": vib.omega[ends],
        "omega_std": spread[ends], "line": line[ends], "still": _block_all(still, ends),
        "soft": soft[ends],
    }
    notes.append(f"longitudinal acceleration: '{acc_ch}'"
                 + (" negated (pointing backwards)" if acc_sign < 0 else " as it points")
                 + " (-p accel_axis; a leading - negates)")
    corr, nwin = accel_gps_correlation(arrays["t"], arrays["accel"],
                                       np.where(cfg.valid_fixes(g, s), g, np.nan)[ends])
    if corr <= SIGN_CORR:
        other = acc_ch if acc_sign < 0 else "-" + acc_ch
        notes.append(f"the speed changes integrated from '{acc_spec}' anti-correlate with the "
                     f"GPS speed's (correlation {corr:.2f} over {nwin} windows of "
                     f"{SIGN_WINDOW:g} s): the accelerometer looks mounted backwards; "
                     f"-p accel_axis={other} reads it the right way round")
    elif corr < WEAK_CORR:
        gv = np.where(cfg.valid_fixes(g, s), g, np.nan)[ends]
        notes.extend(_better_axis(recording, ends, gv, acc_ch, acc_spec, corr, nwin))
    grid = None
    if want_post:
        arrays["posterior"], grid = _posterior_rows(vib, ends, name)
    fin = np.flatnonzero(cfg.valid_fixes(g, s))
    v0 = float(g[fin[0]]) if fin.size else 0.0
    cfg = replace(cfg, radius0=r0, radius_std0=rs0)  # the prior the octave changes respect
    state0 = init(cfg, v0, radius=r0, radius_std=rs0)
    # the speed band's accelerometer density (Config.band_psd): offline learned from the whole
    # drive's fixes, online (run's own) from the fixes so far
    band = q = None
    if cfg.band_density() == "learned":
        gv = np.where(cfg.valid_fixes(g, s), g, np.nan)[ends]
        if online:
            band = learn_acc_psd_causal(arrays["t"], arrays["accel"], gv)
            q = float(band[-1]) if band.size and np.isfinite(band[-1]) else None
        else:
            q = learn_acc_psd(arrays["t"], arrays["accel"], gv)
            band = math.nan if q is None else q
        notes.append("speed band: accelerometer density "
                     + ("not learned (too few GPS fix pairs): acc_psd" if q is None else
                        f"{q:.3g} (m/s^2)^2 s learned from the GPS fixes"
                        + (" (at the end; the fixes so far before)" if online else ""))
                     + f"; the filter's gains use acc_psd {cfg.acc_psd:g} (-p band_psd)")
    end, o = run(cfg, arrays, state=state0, grid=grid, band_psd=band)
    r_fin, rs_fin = float(o.radius[-1]), float(o.radius_std[-1])
    if online:
        v, vs, rr, rrs, off = o.speed, o.speed_std, o.radius, o.radius_std, o.offset
    else:
        xs, Ps = smooth(cfg, o)
        Pbs = smooth_band(cfg, o)
        v, vs = xs[:, IV], np.sqrt(np.maximum((Ps if Pbs is None else Pbs)[:, IV, IV], 0.0))
        rr, rrs = xs[:, IR], np.sqrt(np.maximum(Ps[:, IR, IR], 0.0))
        off = xs[:, IB]
    # 3. back to the recording's time line: linear between fusion samples, source per block
    tb = t[ends]
    blk = np.minimum(np.searchsorted(ends, np.arange(t.size)), ends.size - 1)

    def back(x):
        return np.interp(t, tb, x)

    speed = back(v)
    speed_std = back(vs)
    shares = {SOURCES[c]: float(np.mean(o.source == c)) for c in SOURCES}
    notes.append("fused speed rests on " + ", ".join(f"{k} {100 * x:.1f} %"
                                                     for k, x in shares.items()) +
                 f" of the fusion samples ({'forward filter' if online else 'RTS smoothed'})")
    if rf is not None or wheel_radius:
        notes.extend(_prior_mismatch(arrays, cfg.valid_fixes(g, s)[ends], r0, rs0))
        claimed, used = float(np.mean(arrays["line"])), float(np.mean(o.source == SRC_VIBRATION))
        if not has_gps and claimed >= 0.1 and used < 0.01:  # nothing to tell which is wrong
            notes.append(f"the tracker claims a line on {claimed:.0%} of the fusion samples but "
                         f"none fits the radius {r0:.4f} m with the accelerometer's speed "
                         "(a radius of another vehicle or mount?): the speed is the "
                         "accelerometer's integral")
    if slow is None:  # with the vibration off there is no radius to learn
        notes.append(f"learned wheel radius {r_fin:.4f} +- {rs_fin:.4f} m"
                     + ("" if has_gps else " (no GPS: the prior, kept)"))
    known = rs_fin < cfg.octave_rel * r_fin
    if not known and slow is None:
        notes.append("the wheel radius is not known (no wheel line while GPS was good): omega "
                     "is left empty; the vibration tracker's own omega is omega_vib")
    pdict = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(cfg).items()}
    pdict.update({"online": online, "lag": lag, "accel_axis": acc_spec, "axis": axis,
                  "learned_radius": r_fin, "learned_radius_std": rs_fin,
                  "learned_gps_lag": cfg.lag.lag + float(end.x[-1]),
                  "learned_gps_lag_std": math.sqrt(max(float(end.P[-1, -1]), 0.0)),
                  "learned_band_psd": q,
                  "radius_prior": [r0, rs0], "tracker": vib.method, **{
                      f"tracker_{k}": v for k, v in rest.items()}})
    extras = {
        "source": o.source.astype(np.float64)[blk], "radius": back(rr),
        "radius_std": back(rrs), "offset": back(off), "harmonic": o.harmonic[blk],
        "omega_vib": vib.omega, "has_signal": claim.astype(np.float64),
    }
    # the stop fuse took from all evidence (source 3): the tracker's own detector (vibration
    # and body motion at their floors) also fires in a smooth cruise that GPS says is moving,
    # and a standstill column of 1 beside a speed of 7.7 m/s read as a fuse decision
    extras["standstill"] = (o.source == SRC_STANDSTILL).astype(np.float64)[blk]
    if "standstill" in vib.extras:
        extras["standstill_vib"] = np.asarray(vib.extras["standstill"], dtype=np.float64)
    if return_posterior and "posterior" in vib.extras:  # the vibration tracker's omega posterior
        extras["posterior"] = vib.extras["posterior"]
        for key in ("grid", "posterior_index"):
            if key in vib.extras:
                extras[key] = vib.extras[key]
    return Track.from_speed(t, speed, speed_std, wheel_radius=r_fin if known else None,
                            method="fuse",
                            params=pdict, extras=extras, notes=[*vib.notes, *notes])


def _too_slow(recording: Recording, rest: dict) -> str | None:
    """Why the recording's rate carries no wheel line in the grid tracker's default range
    (:func:`vibrospeed.io.timebase.fundamental_shortfall`: a 16.7 Hz phone log does not reach
    a car's 120 rad/s), with the ``-p omega_max`` that would track the lines below it, or None
    where it does or where ``omega_max`` was given (then the tracker's own error tells what
    was asked for)."""
    from vibrospeed.estimators.grid.config import Config as GridConfig
    from vibrospeed.io.timebase import fundamental_shortfall

    if "omega_max" in rest:
        return None
    fs = recording.fs
    lower = math.floor(math.pi * fs) - 1
    hint = (f"-p omega_max={lower} tracks the lines below it" if
            lower > float(rest.get("omega_min", GridConfig.omega_min)) else "")
    return fundamental_shortfall(fs, float(GridConfig.omega_max), hint)


#: the share of the radius prior within which the lines seen with GPS must place the radius
PRIOR_MISMATCH_REL = 0.1


def _prior_mismatch(arrays: dict, fixes: np.ndarray, r0: float, rs0: float) -> list[str]:
    """A note where the wheel lines seen with a good fix (spanning at least 1 s) place the
    radius (GPS speed / line, their median, at the line's octaves 1/2, 1, 2) further from a
    given prior than :data:`PRIOR_MISMATCH_REL` of it plus 3 of its std: a radius of another
    vehicle or mount, with which the filter rejects those lines and keeps the prior."""
    om = np.asarray(arrays["omega"], dtype=np.float64)
    use = arrays["line"] & fixes & (np.nan_to_num(om) > 0) & (arrays["gps_speed"] > 1.0)
    tf = arrays["t"][use]
    if tf.size < 2 or tf[-1] - tf[0] < 1.0:
        return []
    q = float(np.median(arrays["gps_speed"][use] / om[use]))
    near = min(abs(q / h - r0) for h in (0.5, 1.0, 2.0))
    if near <= PRIOR_MISMATCH_REL * r0 + 3.0 * rs0:
        return []
    return [f"the wheel lines seen with GPS put the radius at {q:.4f} m (GPS speed / line, "
            f"median of {tf.size} fusion samples), not near the prior {r0:.4f} +- {rs0:.4f} m: "
            "a radius of another vehicle or mount? Lines that disagree with it are not used"]


def _posterior_rows(vib: Track, ends: np.ndarray, name: str) -> tuple[np.ndarray, np.ndarray]:
    """The tracker's grid posterior (signal part) at the fusion samples ``ends`` and its grid:
    ``vib.extras["posterior"]`` holds a row per sample, or rows at the samples
    ``extras["posterior_index"]`` (a track kept at the fusion samples only)."""
    post, grid = vib.extras.get("posterior"), vib.extras.get("grid")
    if post is None or grid is None:
        raise InputError(f"{name}: vib_measure=posterior needs the tracker's posterior and grid "
                         "(a grid track estimated with return_posterior)")
    idx = vib.extras.get("posterior_index")
    if idx is None:
        rows = ends
    else:
        idx = np.asarray(idx, dtype=np.int64)
        rows = np.searchsorted(idx, ends)
        if np.any(rows >= idx.size) or np.any(idx[np.minimum(rows, idx.size - 1)] != ends):
            raise InputError(f"{name}: the tracker's posterior is not kept at every fusion "
                             "sample (posterior_index)")
    return np.asarray(post[rows], dtype=np.float64), np.asarray(grid, dtype=np.float64)


def suits(recording: Recording, accel_axis: str = "x") -> bool:
    """Whether ``recording`` feeds ``fuse`` without a radius given: a ``gps_speed`` channel
    with at least one finite fix and the longitudinal accelerometer channel (``accel_axis``).
    ``vibrospeed estimate`` without ``--method`` picks ``fuse`` for such a recording."""
    if "gps_speed" not in recording or signed_axis(accel_axis)[0] not in recording:
        return False
    return bool(np.isfinite(recording.channel("gps_speed")).any())


#: s, the windows over which :func:`accel_gps_correlation` compares speed changes
SIGN_WINDOW = 5.0
#: the correlation at or below which the accelerometer is taken to point backwards
SIGN_CORR = -0.5


#: below this correlation of the speed changes (:func:`accel_gps_correlation`) the axis hardly
#: follows the GPS speed: on the Hungary phone drives the longitudinal ``ay`` gives 0.24-0.88,
#: the lateral ``ax`` (fuse's default) -0.45-0.34, the kart's tilted GoPro -0.49
WEAK_CORR = 0.5
#: how much better another axis must follow the GPS speed to be named
BETTER_BY = 0.3


def _better_axis(recording: Recording, ends: np.ndarray, gps: np.ndarray, acc_ch: str,
                 acc_spec: str, corr: float, nwin: int) -> list[str]:
    """A note where the accelerometer axis ``acc_spec`` hardly follows the GPS speed (its
    correlation ``corr`` below :data:`WEAK_CORR`) and another of ``ax``, ``ay``, ``az`` (either
    sign) follows it at :data:`WEAK_CORR` or more and :data:`BETTER_BY` better: a phone lying
    flat has its longitudinal axis in ``y``, not fuse's default ``x``, and with a lateral axis
    the fused speed left a 1 Hz GPS by up to 11.7 m/s (Hungary drive rsq_q3_00)."""
    t = recording.t[ends]
    best, spec = -math.inf, ""
    for ch in ("ax", "ay", "az"):
        if ch == acc_ch or ch not in recording:
            continue
        c, _ = accel_gps_correlation(t, _block_mean(recording.channel(ch), ends), gps)
        if math.isfinite(c) and abs(c) > best:
            best, spec = abs(c), ("-" if c < 0 else "") + ch
    if not (best >= WEAK_CORR and best >= corr + BETTER_BY):
        return []
    return [f"the speed changes integrated from '{acc_spec}' hardly follow the GPS speed's "
            f"(correlation {corr:.2f} over {nwin} windows of {SIGN_WINDOW:g} s), those of "
            f"'{spec}' do ({best:.2f}): is '{acc_spec}' the longitudinal axis? -p "
            f"accel_axis={spec} if '{spec}' points forward"]


def accel_gps_correlation(t: np.ndarray, accel: np.ndarray, gps: np.ndarray,
                          window: float = SIGN_WINDOW) -> tuple[float, int]:
    """Pearson correlation, over consecutive windows of ``window`` s, of the speed change the
    accelerometer integrates (``sum accel dt``; a constant offset shifts every window alike and
    leaves the correlation) with the GPS speed's change over the same window (its valid fixes,
    NaN elsewhere, interpolated at the window edges; an edge without a fix within 1 s, or a
    window with a sample without acceleration, is left out). A longitudinal axis that points
    backwards gives a correlation near -1. Returns ``(correlation, windows used)``; NaN with
    fewer than 10 windows or where the GPS speed changes by less than 0.5 m/s (std)."""
    fin = np.isfinite(gps)
    if fin.sum() < 2:
        return math.nan, 0
    tg, vg = t[fin], gps[fin]
    edges = np.arange(tg[0], tg[-1], window)
    near = np.abs(tg[np.clip(np.searchsorted(tg, edges), 0, tg.size - 1)] - edges) <= 1.0
    near |= np.abs(tg[np.clip(np.searchsorted(tg, edges) - 1, 0, tg.size - 1)] - edges) <= 1.0
    dts = np.diff(t, prepend=t[0])
    ok = np.isfinite(accel)
    cum = np.concatenate([[0.0], np.cumsum(np.where(ok, accel, 0.0) * dts)])
    nbad = np.concatenate([[0], np.cumsum(~ok)])
    i = np.searchsorted(t, edges, side="right")  # samples (i[j], i[j+1]] end in window j
    dv_acc = cum[i[1:]] - cum[i[:-1]]
    dv_gps = np.diff(np.interp(edges, tg, vg))
    use = near[1:] & near[:-1] & (nbad[i[1:]] == nbad[i[:-1]])
    if use.sum() < 10 or np.std(dv_gps[use]) < 0.5:
        return math.nan, int(use.sum())
    c = np.corrcoef(dv_acc[use], dv_gps[use])[0, 1]
    return float(c), int(use.sum())
