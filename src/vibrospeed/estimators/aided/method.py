"""The aided method's entry point (:func:`estimate`, ``-m aided``): a recording in, a Track out.
The vibration axis pre-filtered, the aiding inputs (:mod:`vibrospeed.estimators.aiding`:
a_x, reference fixes), the broadband standstill flags, the accelerometer offset while standing
and the comb candidates computed before the loop, then :func:`vibrospeed.estimators.aided.run`;
``tracker=grid`` / ``rbpmf`` go to :mod:`vibrospeed.estimators.aided_grid`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from vibrospeed.config import config_from_params, parse_flag, parse_number, parse_value
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import ACCEL_OFFSET, TRACKER
from vibrospeed.estimators.aided.config import Config, _thesis_model, check_inputs
from vibrospeed.estimators.aided.filter import run
from vibrospeed.estimators.aiding import (
    aiding_inputs,
    running_gain,
    standstill_band,
    standstill_flags,
    standstill_offset,
)
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal.comb import COMB_FRAME_S, COMB_HOP_S, comb_candidates
from vibrospeed.types import Recording, Track, check_wheel_radius

#: vibration tracker of :func:`estimate` when ``params`` names none: the grid tracker, aided
#: (:func:`vibrospeed.estimators.aided_grid.estimate`; offline the aided forward-backward
#: smoother). On the randomised family it is at or above ``-m grid`` on 59 of 60 tuning seeds
#: (the aided EKF's moving-within median is a tenth of it) and on the thesis' simulated cart
#: within 1.7x of the thesis EKF's RMSE on stop-and-go and below it on sudden-change
#: (benchmarks/robustness/AIDED.md); ``tracker=ekf`` / ``--preset paper`` is the thesis' EKF.
DEFAULT_TRACKER = "grid"

#: s, causal offset of a_x: a standing sample counts once its stop flag has held this long
#: after it. The causal detector lets go of a stop only when a frame sees the motion, so its
#: stops run into the start (stop_and_go seeds 0-7: flagged for a median 1.24 s, at most
#: 1.70 s, after the vehicle moved off), and the start's acceleration (0.4-0.8 m/s^2) pushed
#: the running mean while standing, so the offset removed, up by about 0.2 m/s^2.
OFFSET_SETTLE_S = 2.0


def settled_offset(u: np.ndarray, still: np.ndarray, dt: float,
                   settle_s: float = OFFSET_SETTLE_S) -> np.ndarray:
    """Causal offset of ``u`` (:func:`standstill_offset` with ``causal=True``) from the
    standing samples whose flag still held ``settle_s`` later: at sample k the mean over the
    samples j <= k - d (d = ``settle_s / dt`` samples) flagged over all of j .. j + d, so it
    reads no sample after k; before the first such sample, :func:`standstill_offset`'s causal
    value. Why: see :data:`OFFSET_SETTLE_S`."""
    u = np.asarray(u, dtype=np.float64)
    n = u.size
    d = max(1, int(round(settle_s / dt)))
    st = np.asarray(still) > 0.5
    held = np.convolve(st.astype(np.int64), np.ones(d + 1, np.int64))[d:d + n] == d + 1
    ok = held & np.isfinite(u)
    cnt = np.concatenate((np.zeros(d), np.cumsum(ok)))[:n]
    tot = np.concatenate((np.zeros(d), np.cumsum(np.where(ok, u, 0.0))))[:n]
    return np.where(cnt > 0, tot / np.maximum(cnt, 1), standstill_offset(u, still, causal=True))


def estimate(
    recording: Recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Aided tracking of omega from vibration axis ``axis`` and longitudinal acceleration.

    ``params``: any :class:`Config` field; any :class:`HarmonicModel` field (``dt`` comes from
    the data); ``accel_axis`` (default ``ax``; ``y``/``ay``, a leading ``-`` negates, e.g.
    ``-ay``); ``prefilter`` (default ``thesis-hplp``, low-pass cut-off per M) and ``lp_cutoff``
    (rad/s); ``normalize_tau`` (s, running-RMS normalisation of the EKF input; default 0 = off,
    then the model is in m/s^2 units as in the thesis); ``reference`` ('none', 'bump', 'turn',
    'both': speed fixes from :mod:`vibrospeed.signal.reference` fed as measurements) and
    ``wheelbase`` (m, for bump fixes); ``accel_detrend`` (s; subtract a causal running mean of
    a_x with this time constant, for a tilted phone whose a_x carries a large gravity offset that
    would hold the mode detector in acceleration mode; default 0 = off, as in the thesis).
    ``tracker``: 'grid' (default, :data:`DEFAULT_TRACKER`: the grid product's filter aided by
    the longitudinal acceleration of the phone's estimated mount, offline the aided
    forward-backward smoother; where the mount is not known well enough to aid it, the grid
    tracker's own estimate; see :func:`vibrospeed.estimators.aided_grid.estimate`), 'ekf' (the
    thesis' aided EKF, this function; ``--preset paper`` with the thesis' tests) or 'rbpmf'
    (the aiding around the paper's grid filter on the thesis cart's grid); the grid trackers go
    to :func:`vibrospeed.estimators.aided_grid.estimate`. The parameters below are the EKF's.
    ``return_posterior`` is accepted for the common signature and ignored: the aided trackers
    give no posterior image (``-m grid`` does).

    Defaults not in the thesis (measured in benchmarks/aided/RESULTS.md):
    ``standstill='broadband'`` (the
    broadband-level detector on the vibration axis, whole-log; ``causal=True`` for the causal
    detector, as a device would run it; 'window' / 'cusum' are the thesis' tests);
    ``accel_offset='standstill'`` (the mean of a_x while standing is removed from it; 'none'
    keeps a_x as it is); ``comb`` (default True: the comb check of :func:`comb_fixes` with
    ``comb_clarity`` 3) over ``omega_min`` (rad/s, default 2 pi) .. ``omega_max``.

    The wheel radius comes from ``wheel_radius`` or ``recording.wheel_radius``.
    """
    from vibrospeed.estimators.common import axis_channel, check_uniform, split_params, start_level
    from vibrospeed.io.timebase import check_nyquist
    from vibrospeed.signal import prefilter as pf

    params = dict(params or {})
    # one of estimators.TRACKER, read as a batch reads it before it starts
    tracker = parse_value(str(params.pop("tracker", DEFAULT_TRACKER)), TRACKER, "tracker")
    if tracker in ("rbpmf", "grid"):
        from vibrospeed.estimators import aided_grid

        return aided_grid.estimate(recording, axis=axis, wheel_radius=wheel_radius,
                                   params=params, progress=progress, kind=tracker)
    del progress  # one compiled pass; nothing to report
    r = check_wheel_radius(wheel_radius) if wheel_radius else recording.wheel_radius
    if not r:
        raise ParameterError(
            f"{recording.source or 'recording'}: the aided tracker needs the wheel radius "
            "(pass wheel_radius=... / --wheel-radius, or use a recording that knows it)"
        )
    params = dict(params or {})
    model_kw, cfg_kw = split_params(HarmonicModel, params)
    model_kw.pop("dt", None)
    accel_axis = str(cfg_kw.pop("accel_axis", "ax"))
    pre = str(cfg_kw.pop("prefilter", "thesis-hplp"))
    lp = parse_number(cfg_kw.pop("lp_cutoff", None), "lp_cutoff", optional=True)
    tau = parse_number(cfg_kw.pop("normalize_tau", 0.0), "normalize_tau")
    reference = str(cfg_kw.pop("reference", "none"))
    wheelbase = parse_number(cfg_kw.pop("wheelbase", None), "wheelbase", optional=True)
    detrend = parse_number(cfg_kw.pop("accel_detrend", 0.0), "accel_detrend")
    check_inputs(lp, wheelbase, detrend)
    causal = parse_flag(cfg_kw.pop("causal", False), "causal")
    offset_kind = parse_value(str(cfg_kw.pop("accel_offset", "standstill")), ACCEL_OFFSET,
                              "accel_offset")
    om_min = parse_number(cfg_kw.pop("omega_min", None), "omega_min", optional=True)
    cfg_kw.setdefault("standstill", "broadband")
    # the causal stop flags reach into the start: the acceleration ends them (Config)
    cfg_kw.setdefault("release_on_accel", causal)
    cfg_kw_comb = cfg_kw.pop("comb", True)
    comb_clarity = parse_number(cfg_kw.pop("comb_clarity", 3.0), "comb_clarity")
    dt = check_uniform(recording)
    defaults = _thesis_model().to_dict()
    if tau > 0:  # unit-power signal: the EKF's defaults for normalised input
        from vibrospeed.estimators.ekf import UNIT_RMS_MODEL

        defaults.update(UNIT_RMS_MODEL)
        defaults.update(M=2, q_omega=0.5)
    defaults["dt"] = dt
    model = config_from_params(HarmonicModel, model_kw, **defaults)
    config = config_from_params(Config, cfg_kw, model=model, wheel_radius=float(r))
    if om_min is not None and not (0 <= om_min < np.inf and (
            config.omega_max is None or om_min <= config.omega_max)):
        # a range upside down ran and reported a standing vehicle (omega_min 30, omega_max 2:
        # 1 m of a 48 m drive); NaN, inf and negative were dropped without a word
        top = "unset" if config.omega_max is None else f"{config.omega_max:g}"
        raise ParameterError(f"aided (tracker=ekf) needs 0 <= omega_min <= omega_max < inf "
                             f"rad/s, got [{om_min:g}, {top}]")
    src = recording.source or "recording"
    nyq_note = None
    if config.omega_max is not None and om_min is not None \
            and model.M * config.omega_max >= np.pi / dt:
        # a search range given with omega_min (as to the grid trackers): its top is clipped to
        # what the sample rate allows instead of refused
        nyq_note = (f"omega_max {config.omega_max:g} rad/s above what {1 / dt:g} Hz allows for "
                    f"M = {model.M}: clipped to {model.omega_clip(None):.4g} rad/s")
        config = dataclasses.replace(config, omega_max=None)
    if config.omega_max is not None:
        check_nyquist(1.0 / dt, model.M, config.omega_max, src)
    vib_name = axis_channel(axis)
    recording.require(vib_name)
    x = recording.channel(vib_name)
    rng = None
    if pre == "range":
        if om_min is None or config.omega_max is None:
            raise ParameterError("pre-filter 'range' needs omega_min and omega_max")
        rng = (om_min, config.omega_max)
    sos = pf.design(pre, 1.0 / dt, M=model.M, lp_cutoff=lp, omega_range=rng)
    y = pf.apply(sos, x, level=start_level(x, dt))
    u, ref, ref_var, more = aiding_inputs(recording, dt, float(r), accel_axis=accel_axis,
                                          detrend=detrend, reference=reference,
                                          wheelbase=wheelbase)
    still = None
    notes = [f"pre-filter '{pre}' on '{vib_name}' at fs = {1 / dt:.4g} Hz"]
    if config.standstill == "broadband":
        band = standstill_band(dt, model.M, om_min, config.omega_max)
        # the vibration axis and every other accelerometer axis (as the grid tracker does)
        chans = [vib_name] + [c for c in ("ax", "ay", "az") if c != vib_name and c in recording
                              and np.isfinite(recording.channel(c)).any()]
        X = np.column_stack([recording.channel(c) for c in chans])
        still = standstill_flags(X, dt, band, causal=causal)
        notes.append(f"standstill: broadband vibration level at its floor "
                     f"({'causal' if causal else 'whole-log'} detector, band "
                     f"{band[0]:.3g}-{band[1]:.3g} rad/s), on {100 * still.mean():.1f} % of "
                     "the samples")
    else:
        notes.append(f"standstill test '{config.standstill}'")
    notes += more
    if nyq_note:
        notes.append(nyq_note)
    comb = parse_flag(cfg_kw_comb, "comb")
    c_om = None
    if comb:
        c_om, c_rng = comb_candidates(x, dt, om_min, config.omega_limit, still=still,
                                      clarity=comb_clarity)
        notes.append(f"comb check: {np.isfinite(c_om).sum()} candidates from the harmonic comb "
                     f"({COMB_FRAME_S:g} s frames every {COMB_HOP_S:g} s, clarity >= "
                     f"{comb_clarity:g}, range {c_rng[0]:.3g}-{c_rng[1]:.3g} rad/s); omega is "
                     f"reset to it after {config.comb_count} disagreeing by > "
                     f"{100 * config.comb_rel:g} % in a row")
    if offset_kind == "standstill":
        flags = still if still is not None else np.zeros(u.size)
        off = (settled_offset(u, flags, dt) if causal
               else standstill_offset(u, flags, causal=False))
        u = u - off
        notes.append(f"'{accel_axis}' offset removed: its mean while standing "
                     f"({f'running, stops held {OFFSET_SETTLE_S:g} s' if causal else 'whole log'}; "
                     f"{off[-1]:.3g} m/s^2 at the end)")
    gain = None
    if tau > 0:
        gain = running_gain(y, dt, tau)
        notes.append(f"EKF input normalised by a running RMS (tau = {tau:g} s)")
    res = run(config, y, u, gain=gain, ref=ref, ref_var=ref_var, still=still, comb=c_om)
    extras = {f"amp{m + 1}": res.amplitudes[:, m] for m in range(model.M)}
    extras.update(
        standstill=res.standstill.astype(np.float64),
        accelerating=res.accelerating.astype(np.float64),
        boost=res.boost.astype(np.float64),
        bias=res.bias,
        ubar=res.ubar,
        nis=res.innovation**2 / res.innovation_var,
        line_share=res.line_share,
        locked=res.locked.astype(np.float64),
    )
    out_params = {**model.to_dict(), **{k: getattr(config, k) for k in (
        "omega0", "p0_omega", "amp0", "q_bias", "p0_bias", "q_omega_accel", "standstill",
        "ss_window", "ss_mu", "r_ss", "release_on_accel", "cusum_sigma", "cusum_nu", "cusum_h",
        "cusum_fs",
        "mode_window", "mode_mu", "boost", "aid_always", "line_min", "line_tau",
        "line_omega_min", "init_ref")},
        "ss_n": config.ss_len, "mode_n": config.mode_len,
        "omega_max": config.omega_limit, "wheel_radius": float(r),
        "prefilter": pre, "lp_cutoff": lp, "normalize_tau": tau, "accel_detrend": detrend,
        "accel_offset": offset_kind, "causal": causal, "omega_min": om_min,
        "axis": axis,
        "accel_axis": accel_axis, "reference": reference, "tracker": "ekf"}
    return Track.from_omega(recording.t, res.omega, res.omega_std, wheel_radius=float(r),
                            method="aided", params=out_params, extras=extras, notes=notes)
