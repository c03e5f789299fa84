"""The aided grid tracker's entry point (:func:`estimate`; ``-m aided -p tracker=rbpmf`` or
``tracker=grid``): a recording in, a Track out. ``tracker=rbpmf`` builds the thesis cart's grid
at the log's rate; ``tracker=grid`` the grid product's tracker, pre-filter, scaling and comb
evidence (:data:`GRID_TRACKER`), aided by the longitudinal acceleration of the mount estimate
(:mod:`vibrospeed.signal.mount`) where that is confident (offline the aided forward-backward
smoother of :mod:`vibrospeed.estimators.aided_grid.smoother`, causally the aided filter on the
mount known so far), else the grid tracker's own estimate."""

from __future__ import annotations

import dataclasses

import numpy as np

from vibrospeed.config import flat_names, parse_number, parse_value, unknown
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import ACCEL_OFFSET, rbpmf
from vibrospeed.estimators import grid as gridmod
from vibrospeed.estimators.aided.config import check_inputs
from vibrospeed.estimators.aided_grid.config import Config, _cart_tracker
from vibrospeed.estimators.aided_grid.filter import run
from vibrospeed.estimators.aiding import (
    aiding_inputs,
    running_gain,
    standstill_band,
    standstill_flags,
    standstill_offset,
)
from vibrospeed.estimators.grid.method import CLAIM_LEVEL, GRID_DEFAULTS, q_omega_for
from vibrospeed.io.timebase import check_fundamental
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.types import Track, check_wheel_radius

#: parameters of :func:`estimate` that are neither Config, rbpmf.Config nor HarmonicModel fields
INPUT_PARAMS = ("accel_axis", "lp_cutoff", "reference", "wheelbase", "accel_detrend",
                "accel_offset", "causal")

#: ``tracker=grid``: the grid product's tracker and model settings
#: (:data:`vibrospeed.estimators.grid.method.GRID_DEFAULTS`: jumps, "no line" state with the
#: mixture null model, likelihood tempered to 0.2 per 10 ms, whitening pre-filter, running-RMS
#: scaling, mode estimate; r, q_amp of the product, its q_omega for the range) plus its comb
#: evidence (:class:`vibrospeed.estimators.grid.Config` defaults); the aiding: broadband standstill
#: flags, continuous aiding, a_x from the mount estimate (:mod:`vibrospeed.signal.mount`).
GRID_TRACKER = {**{k: v for k, v in GRID_DEFAULTS.items() if k not in ("smooth", "q_omega")},
                "scaling": "rms", "standstill": "broadband", "aiding": "continuous",
                "accel_axis": "mount"}
#: comb-evidence parameters accepted by :func:`estimate` (grid.Config fields)
COMB_PARAMS = tuple(f.name for f in dataclasses.fields(gridmod.Config) if f.name != "tracker")


def _product_model(dt: float) -> HarmonicModel:
    """The grid product's harmonic model at period ``dt`` (paper Table I with the product's
    r, q_amp, q_omega)."""
    mkw = {k: GRID_DEFAULTS[k] for k in ("r", "q_amp", "q_omega") if k in GRID_DEFAULTS}
    return dataclasses.replace(rbpmf.Config.from_paper_table1(dt).model, **mkw)


def _vibration(recording, vib_name: str, tracker: rbpmf.Config, lp: float | None,
               dt: float) -> np.ndarray:
    """The pre-filtered vibration axis (adaptive presets whitened after their SOS)."""
    from vibrospeed.estimators.common import start_level
    from vibrospeed.signal import prefilter as pf

    x = recording.channel(vib_name)
    sos = pf.design(tracker.prefilter, 1.0 / dt, M=tracker.model.M, lp_cutoff=lp,
                    omega_range=(max(tracker.omega_min, 1e-3), tracker.omega_max))
    y = pf.apply(sos, x, level=start_level(x, dt))
    if tracker.prefilter in pf.ADAPTIVE:
        from vibrospeed.signal import whiten

        y = whiten.apply(y, 1.0 / dt)
    return y


def _standstill_input(recording, vib_name: str, dt: float, band, causal: bool,
                      on_grid: bool) -> np.ndarray:
    """Broadband standstill flags on the vibration axis and every other accelerometer axis;
    ``on_grid`` (the tracker holds omega = 0 while standing): each stop shortened at both ends
    (:func:`vibrospeed.estimators.aiding.standstill_flags`), else the detector's stops as
    :func:`vibrospeed.estimators.grid.method.with_standstill` reports them."""
    from vibrospeed.signal import standstill as ss

    chans = [vib_name] + [c for c in ("ax", "ay", "az") if c != vib_name and c in recording
                          and np.isfinite(recording.channel(c)).any()]
    X = np.column_stack([recording.channel(c) for c in chans])
    if on_grid:
        return standstill_flags(X, dt, band, causal=causal)
    return ss.standstill(X, dt, band, causal=causal).astype(np.float64)


def estimate(
    recording,
    *,
    axis: str = "y",
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    kind: str = "rbpmf",
):
    """Aided RBPMF tracking of omega (``--method aided -p tracker=rbpmf``, the thesis cart's
    grid, or ``kind="grid"``: ``-p tracker=grid``, the grid product's settings
    (:data:`GRID_TRACKER`) with harmonic-comb evidence (``comb_*`` params, defaults of
    :class:`vibrospeed.estimators.grid.Config`)).

    ``params``: any :class:`Config` field, any :class:`rbpmf.Config` field (grid ``n_grid``,
    ``omega_max``, ``prefilter``, ``scaling``, ``off_rate`` ...), any :class:`HarmonicModel`
    field (``dt`` from the data), and the inputs shared with the EKF version (``accel_axis``,
    ``lp_cutoff``, ``reference``, ``wheelbase``, ``accel_detrend``, ``accel_offset``,
    ``causal``; see :func:`vibrospeed.estimators.aided.estimate`).

    ``kind="grid"``: the grid product's grid, pre-filter and scaling
    (:func:`vibrospeed.estimators.rbpmf.prepare`, ``omega_min`` / ``omega_max`` the search
    range); standstill from the broadband detector (whole log, ``causal=true``: the causal
    one) over the search band, omega = 0 on its stops (reported from the flags: the grid need
    not contain 0). ``accel_axis='mount'`` (default): first the grid product's own estimate
    (:func:`vibrospeed.estimators.grid.estimate`, smoothed offline, ``smooth=none`` with
    ``causal=true``); the mount estimate of :mod:`vibrospeed.signal.mount` on ``ax, ay, az``,
    referenced to its speed where it claims a line (whole-log offline; with ``causal=true`` the
    mount from the data so far, :func:`vibrospeed.signal.mount.running`). With a confident
    mount, offline: the aided forward-backward smoother on the grid product's config, emissions
    and mid-frame comb evidence (:func:`_smoothed`); causally: the aided filter. Without one the
    grid estimate is the result (no trustworthy axis to aid with). A named axis (``ax``,
    ``-ay`` ...) is used as given, minus its mean while standing
    (``accel_offset='standstill'``), in the same smoother or causal filter; the smoother needs
    ``aiding='continuous'`` (or ``'none'``: then it is ``-m grid``'s smoother), a search range
    above 0 and no reference fixes (with fixes the causal filter runs).
    The Track's band is the grid posterior's credible interval (``level``).
    """
    from vibrospeed.config import config_from_params, parse_flag
    from vibrospeed.estimators.common import axis_channel, check_uniform, split_params

    del progress
    r = check_wheel_radius(wheel_radius) if wheel_radius else recording.wheel_radius
    if not r:
        raise ParameterError(
            f"{recording.source or 'recording'}: the aided tracker needs the wheel radius "
            "(pass wheel_radius=... / --wheel-radius, or use a recording that knows it)")
    if kind not in ("rbpmf", "grid"):
        raise ParameterError(f"tracker must be 'ekf', 'rbpmf' or 'grid', got '{kind}'")
    params = dict(params or {})
    src = recording.source or "recording"
    dt = check_uniform(recording)
    if kind == "grid":
        params = {**GRID_TRACKER, **params}
        # the grid product's walk for this range (grid.method.q_omega_for)
        params.setdefault("q_omega", q_omega_for(parse_value(params.get("omega_max", 120.0), float,
                                                              "omega_max")))
    inp = {k: params.pop(k) for k in INPUT_PARAMS if k in params}
    comb_kw = {k: params.pop(k) for k in COMB_PARAMS if k in params}
    if comb_kw and kind != "grid":
        raise ParameterError(f"{', '.join(comb_kw)}: comb evidence needs tracker=grid")
    model_kw, rest = split_params(HarmonicModel, params)
    model_kw.pop("dt", None)
    tr_names = {f.name for f in dataclasses.fields(rbpmf.Config)} - {"model"}
    tr_kw = {k: v for k, v in rest.items() if k in tr_names}
    cfg_kw = {k: v for k, v in rest.items() if k not in tr_names}
    own = sorted({"smooth", "lag"} & set(tr_kw)) if kind == "grid" else []
    if own:  # set below from `causal`: a value given here was dropped without a word
        raise ParameterError(f"{own[0]}: the aided tracker smooths offline and is causal with "
                             "-p causal=true (--preset online); it takes no smooth or lag")
    # Config's fields that hold a nested Config (the tracker, the comb evidence) are built
    # here from their own names, never given: -p comb=false is the EKF tracker's switch
    # (aided.estimate), unknown here (the CLI names the tracker that takes it), not text read
    # as a Config
    unknown_here = sorted(set(cfg_kw) - flat_names(Config))
    if unknown_here:
        raise unknown(unknown_here[0], Config.__name__, flat_names(Config))
    lp = parse_number(inp.get("lp_cutoff"), "lp_cutoff", optional=True)
    # the inputs shared with the EKF tracker, read as aided.estimate reads them (a value it
    # refuses is refused here alike; the Track's params hold the values read, not the text)
    if "wheelbase" in inp:
        inp["wheelbase"] = parse_number(inp["wheelbase"], "wheelbase", optional=True)
    if "accel_detrend" in inp:
        inp["accel_detrend"] = parse_number(inp["accel_detrend"], "accel_detrend")
    check_inputs(lp, inp.get("wheelbase"), inp.get("accel_detrend", 0.0))
    if "accel_offset" in inp:
        inp["accel_offset"] = parse_value(str(inp["accel_offset"]), ACCEL_OFFSET,
                                          "accel_offset")
    vib_name = axis_channel(axis)
    recording.require(vib_name)
    gain = None
    if kind == "grid":
        # the grid product's pre-filter, scaling and Nyquist checks on the same config
        # the aided filter is causal: it claims at the causal grid filter's level
        tracker, y, _, notes = rbpmf.prepare(recording, axis, rbpmf.Config,
                                             {"claim_level": CLAIM_LEVEL["none"], **model_kw,
                                              **tr_kw, "smooth": "none"},
                                             _product_model)
    else:
        base = _cart_tracker(dt)
        tdef = {f.name: getattr(base, f.name) for f in dataclasses.fields(rbpmf.Config)
                if f.name in ("n_grid", "omega_min", "omega_max", "prefilter", "scaling",
                              "kernel_var")}
        mdef = base.model.to_dict()
        mdef["dt"] = dt
        model = config_from_params(HarmonicModel, model_kw, **mdef)
        tracker = config_from_params(rbpmf.Config, tr_kw, model=model, **tdef)
        check_fundamental(1.0 / dt, tracker.omega_max, src)
        y = _vibration(recording, vib_name, tracker, lp, dt)
        notes = [f"pre-filter '{tracker.prefilter}' on '{vib_name}' at fs = {1 / dt:.4g} Hz"]
        if tracker.scaling == "rms":
            gain = tracker.signal_rms * running_gain(y, dt, tracker.rms_tau)
            notes.append(f"RBPMF input normalised by a running RMS (tau = "
                         f"{tracker.rms_tau:g} s)")
    model = tracker.model
    comb = (config_from_params(gridmod.Config, comb_kw, tracker=tracker) if kind == "grid"
            else None)
    config = config_from_params(Config, cfg_kw, tracker=tracker, wheel_radius=float(r),
                                comb=comb)
    causal = parse_flag(inp.get("causal", False), "causal")
    notes.append(f"aided rbpmf: {tracker.n_grid} grid points on [{tracker.omega_min:g}, "
                 f"{tracker.omega_max:g}] rad/s, standstill test '{config.standstill}', "
                 f"aiding '{config.aiding}'")
    accel_axis = str(inp.get("accel_axis", "ax"))
    still = None
    if config.standstill == "broadband" and accel_axis != "mount":
        band = standstill_band(dt, model.M, tracker.omega_min if kind == "grid" else None,
                               tracker.omega_max)
        still = _standstill_input(recording, vib_name, dt, band, causal, config.ss_on_grid)
        notes.append(f"standstill: broadband vibration and body motion at their floors "
                     f"({'causal' if causal else 'whole-log'} detector, band "
                     f"{band[0]:.3g}-{band[1]:.3g} rad/s), on {100 * still.mean():.1f} % of "
                     "the samples")
    ref = ref_var = None
    mount_info = {}
    if accel_axis == "mount":
        if inp.get("reference", "none") != "none":
            raise ParameterError("reference fixes need a named accel_axis (e.g. ax) with "
                                 "tracker=grid")
        # the grid product's estimate on the same settings: the mount's reference and,
        # where the mount is not confident, the result
        gparams = {**model_kw, **tr_kw, **comb_kw, "smooth": "none" if causal else "fb"}
        base_tr = gridmod.estimate(recording, axis=axis, wheel_radius=float(r),
                                   params=gparams)
        u, mount_info, note = _mount_input(recording, base_tr, dt, float(r), causal=causal)
        if u is None:
            base_params = {**base_tr.params, "tracker": kind, "accel_axis": accel_axis,
                           "causal": causal, **mount_info}
            return dataclasses.replace(
                base_tr, method="aided", params=base_params,
                notes=[*base_tr.notes, f"{note}: the grid tracker's estimate (-m grid"
                       f"{'' if not causal else ' -p smooth=none'})"])
        still = np.asarray(base_tr.extras["standstill"], dtype=np.float64)
        more = [note]
        if not causal:
            return _smoothed(recording, axis, float(r), gparams, cfg_kw, u, still, more,
                             {"tracker": kind, "accel_axis": accel_axis, "causal": causal,
                              **mount_info})
    else:
        u, ref, ref_var, more = aiding_inputs(
            recording, dt, float(r), accel_axis=accel_axis,
            detrend=inp.get("accel_detrend", 0.0), reference=str(inp.get("reference", "none")),
            wheelbase=inp.get("wheelbase"))
        if inp.get("accel_offset", "none" if kind == "rbpmf" else "standstill") \
                == "standstill" and still is not None:
            off = standstill_offset(u, still, causal=causal)
            u = u - off
            more.append(f"'{accel_axis}' offset removed: its mean while standing "
                        f"({off[-1]:.3g} m/s^2 at the end)")
        if kind == "grid" and not causal and still is not None and ref is None:
            gparams = {**model_kw, **tr_kw, **comb_kw, "smooth": "fb"}
            return _smoothed(recording, axis, float(r), gparams, cfg_kw, u, still, more,
                             {"tracker": kind, "accel_axis": accel_axis, "causal": causal,
                              **{k: inp.get(k) for k in INPUT_PARAMS
                                 if k not in ("accel_axis", "causal")}})
    if comb is not None:
        notes.append(f"tracker=grid: 'no line' state (off {tracker.off_rate:g}/s, on "
                     f"{tracker.on_rate:g}/s, null model '{tracker.null_model}'), jumps "
                     f"{tracker.jump_rate:g}/s, temper {tracker.temper:g}, point "
                     f"'{tracker.point}'; harmonic-comb evidence ({comb.comb_window:g} s frames "
                     f"every {comb.comb_hop:g} s, weight {comb.comb_weight:g})")
    res = run(config, y, u, gain=gain, ref=ref, ref_var=ref_var, still=still)
    notes += more
    omega, std, lo, hi = res.omega.copy(), res.omega_std.copy(), res.omega_lo.copy(), \
        res.omega_hi.copy()
    if still is not None:
        st = still > 0.5
        for a in (omega, std, lo, hi):
            a[st] = 0.0
    extras = {f"amp{m + 1}": res.amplitudes[:, m] for m in range(model.M)}
    has_signal = tracker.claims(res.p_null)
    if still is not None:
        has_signal[still > 0.5] = 0.0
    extras.update(standstill=res.standstill.astype(np.float64),
                  accelerating=res.accelerating.astype(np.float64),
                  boost=res.boost.astype(np.float64), ubar=res.ubar, omega_map=res.omega_map,
                  p_null=res.p_null, has_signal=has_signal)
    out_params = {**tracker.to_dict(), **{f.name: getattr(config, f.name)
                                          for f in dataclasses.fields(Config)
                                          if f.name not in ("tracker", "comb")},
                  **({k: getattr(comb, k) for k in COMB_PARAMS} if comb is not None else {}),
                  "ss_n": config.ss_len, "mode_n": config.mode_len,
                  "tracker": kind, "axis": axis, "lp_cutoff": lp,
                  **mount_info,
                  **{k: inp.get(k) for k in INPUT_PARAMS if k != "lp_cutoff"}}
    out_params["accel_axis"] = accel_axis
    return Track.from_omega(recording.t, omega, std, lo=lo, hi=hi, level=tracker.level,
                            wheel_radius=float(r), method="aided", params=out_params,
                            extras=extras, notes=notes)


def _mount_input(recording, base: Track, dt: float, r: float, *, causal: bool = False
                 ) -> tuple[np.ndarray | None, dict, str]:
    """``accel_axis='mount'``: the longitudinal acceleration from the mount estimate of
    :mod:`vibrospeed.signal.mount` on ``ax, ay, az``, referenced to the grid tracker's track
    ``base`` where it claims a line; None when the mount is not confident. ``causal``: the
    mount from the data so far (:func:`vibrospeed.signal.mount.running`; ``base`` is then the
    causal tracker's with the causal stops), NaN (nothing aided) until it is confident.
    Returns ``(u or None, mount params, note)``."""
    from vibrospeed.signal import mount as mountmod

    chans = ("ax", "ay", "az")
    if not all(c in recording and np.isfinite(recording.channel(c)).any() for c in chans):
        return None, {"mount_confident": False}, "not aided (the mount needs ax, ay and az)"
    A = np.column_stack([recording.channel(c) for c in chans])
    kw = dict(omega=np.asarray(base.omega, dtype=np.float64), wheel_radius=r,
              still=base.extras.get("standstill"), usable=base.extras.get("has_signal"))
    if causal:
        run = mountmod.running(A, dt, **kw)
        m = run.mounts[-1] if run.mounts else mountmod.estimate(A, dt, **kw)
        on = run.confident
        info = {"mount_confident": bool(on.any()), "mount_slope": m.slope, "mount_rho": m.rho,
                "mount_t": m.t, "mount_forward": [float(v) for v in m.forward],
                "mount_running": True}
        if not on.any():
            return None, info, ("not aided: the mount from the data so far (causal) was never "
                                "confident")
        first = float(np.flatnonzero(on)[0] * dt)
        return run.u, info, (f"aided by the longitudinal acceleration of the mount known so far "
                             f"(re-estimated {run.times.size} times, confident on "
                             f"{100 * on.mean():.0f} % of the samples, first after {first:.0f} s"
                             f"; last: forward axis {np.round(m.forward, 3).tolist()}, "
                             f"correlation {m.rho:.2f}, slope {m.slope:.2f})")
    m = mountmod.estimate(A, dt, **kw)
    info = {"mount_confident": m.confident, "mount_slope": m.slope, "mount_rho": m.rho,
            "mount_t": m.t,
            "mount_forward": [float(v) for v in m.forward]}
    desc = (f"mount: forward axis {np.round(m.forward, 3).tolist()} in the sensor frame "
            f"(correlation {m.rho:.2f}, t = {m.t:.1f}, slope {m.slope:.2f} against r d omega/dt of "
            f"the grid tracker, {m.used_s:.0f} s used)")
    if not m.confident:
        return None, info, f"not aided: {desc} not confident"
    return mountmod.longitudinal(A, m), info, f"aided by the longitudinal acceleration, {desc}"


def _smoothed(recording, axis: str, r: float, gparams: dict, cfg_kw: dict, u: np.ndarray,
              still: np.ndarray, more: list, extra_params: dict) -> Track:
    """``tracker=grid`` offline with an aiding input: the grid product's pre-filter, config and
    mid-frame comb evidence (:func:`vibrospeed.estimators.grid.method._prepare`, as ``-m grid``
    builds them), the aided filter's forward pass and the aided forward-backward smoother
    (:mod:`vibrospeed.estimators.aided_grid.smoother`), the Track's columns as ``-m grid``'s
    (:func:`vibrospeed.estimators.grid.app.columns`; ``omega_map`` the smoothed marginal's MAP,
    not a Viterbi path) and the stops ``still`` (whole-log detector) declared as ``-m grid``
    declares them."""
    import vibrospeed.estimators.aided_grid.smoother as asm
    from vibrospeed.config import config_from_params
    from vibrospeed.estimators.grid.app import columns
    from vibrospeed.estimators.grid.method import apply_standstill

    gconfig, Y, rms, notes = gridmod._prepare(recording, axis, gparams)
    tr = gconfig.tracker
    if tr.fit_names:
        raise ParameterError("fit: the aided grid smoother takes the noise levels as given "
                             "(fit them with -m grid, or use causal=true)")
    y = Y if Y.ndim == 1 else np.ascontiguousarray(Y[:, 0])
    ev = gridmod.evidence(gconfig, Y, centre=True)
    config = config_from_params(Config, cfg_kw, tracker=dataclasses.replace(tr, smooth="none"),
                                wheel_radius=r, comb=None)
    fw = asm.forward(config, y, u, still=still, extra=ev)
    sm = asm.smooth(config, fw)
    (omega, std, lo, hi), extras = columns(tr, fw.filt, sm, sm.omega_map, rms)
    moved = np.abs(fw.shift).sum() * config.dx
    notes += [f"harmonic-comb evidence: {gconfig.comb_window:g} s frames every "
              f"{gconfig.comb_hop:g} s, weight {gconfig.comb_weight:g} (mid-frame)",
              f"aided forward-backward smoother on the grid: the posterior shifted by "
              f"(T / r) sum a_x every {config.aid_hop:g} s inside the forward and the backward "
              f"pass ({moved:.3g} rad/s moved in all); omega_map = the smoothed marginal's MAP",
              *more]
    params = {**gconfig.to_dict(), **{f.name: getattr(config, f.name)
                                       for f in dataclasses.fields(Config)
                                       if f.name not in ("tracker", "comb")},
              "axis": axis, "smoother": "aided-fb", **extra_params}
    track = Track.from_omega(recording.t, omega, std, lo=lo, hi=hi, level=tr.level,
                             wheel_radius=r, method="aided", params=params, extras=extras,
                             notes=notes)
    st = np.asarray(still) > 0.5
    apply_standstill(track, st)
    if st.any():
        track.notes.append(f"standstill on {100 * st.mean():.1f} % of the samples (whole-log "
                           "detector): omega = 0 there")
    return track
