"""The algebraic method's entry point (:func:`estimate`, ``-m algebraic``): a recording's yaw
rate, accelerations and four wheel speeds (their mean) in, Vx and Vy as a Track out; a
non-uniform time line is resampled to its median period and the results interpolated back."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from vibrospeed.config import config_from_params, parse_number
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators.algebraic.config import OUTPUTS, Config, _domain_text
from vibrospeed.estimators.algebraic.filter import run
from vibrospeed.estimators.common import check_time
from vibrospeed.types import WHEEL_CHANNELS, Recording, Track, check_wheel_radius

#: s, a slip episode longer than this gets a note: no tyre slips that long (a stop from 35 m/s
#: at 0.3 g takes 12 s); the longest in 200 drives of the simulated family is 8.4 s, on the
#: F1/10 RC car's five runs 39-115 s (docs/algebraic.md, Limits)
SLIP_NOTE_S = 20.0


def _longest_slip(slip: np.ndarray, t: np.ndarray) -> float:
    """s, the longest run of samples in slip mode."""
    on = np.nan_to_num(slip) > 0.5
    d = np.diff(np.concatenate([[0], on.astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    return float(np.max(t[ends] - t[starts])) if starts.size else 0.0


def _slip_note(longest: float, out: np.ndarray, cfg: Config) -> str:
    """The note for a drive integrated for longer than any tyre slips: where the filtered
    accelerometer noise moves the dead-reckoned speed by more than ``slip_tol`` in a
    ``slip_window`` (the F1/10 RC car: sd 3.7 m/s^2 after the 0.1 s filter, 98-100 % of its
    samples in slip mode, Vx off by 9-143 m/s RMSE), the wheels are never trusted again and
    Vx is the integral of that noise; ``max_int`` caps each episode."""
    slip = np.nan_to_num(out[:, OUTPUTS.index("slip_mode")]) > 0.5
    sd = float(np.nanstd(out[:, OUTPUTS.index("ax")]))
    return (f"algebraic: one slip episode lasted {longest:.3g} s ({slip.mean():.0%} of the "
            f"samples in slip mode; filtered a_x sd {sd:.2g} m/s^2 against slip_tol "
            f"{cfg.slip_tol:g} m/s in {cfg.slip_window:g} s): Vx is integrated acceleration "
            "and may drift far; on noisy sensors cap the episodes: -p max_int=0.5 -p eps_k=3")


def _uniform_grid(recording: Recording) -> tuple[np.ndarray, bool]:
    t = recording.t
    if recording.is_uniform(0.05):
        return t, False
    dt = recording.dt
    n = int(np.ceil((t[-1] - t[0]) / dt - 1e-9)) + 1  # the grid covers the last time stamp
    return t[0] + dt * np.arange(n), True


def _interp_finite(tq: np.ndarray, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Linear interpolation over the finite samples, edge values held outside them."""
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return np.full(tq.shape, np.nan)
    return np.interp(tq, t[ok], x[ok])


def estimate(
    recording: Recording,
    *,
    axis: str | None = None,
    wheel_radius: float | None = None,
    params: dict | None = None,
    progress: bool = False,
    return_posterior: bool = False,
) -> Track:
    """Vx (``speed``) and Vy (``extras['vy']``) of a recording with ``gz, ax, ay`` and the four
    ``wheel_omega_*`` channels.

    ``wheel_radius``: argument, else ``recording.wheel_radius``, else ``meta['wheel_radius']``.
    ``params`` may set any :class:`Config` field; ``L1`` defaults to ``meta['L1']``. ``axis`` is
    not used (the channels are fixed). A non-uniform time line is resampled (linear
    interpolation) to its median period and the results interpolated back.
    """
    del axis, progress
    src = recording.source or "recording"
    params = dict(params or {})
    recording.require("gz", "ax", "ay", *WHEEL_CHANNELS)
    r = check_wheel_radius(wheel_radius) if wheel_radius else None
    # -p r is the same radius: popped whichever is given (left in params it replaced the
    # argument's in the filter while the Track converted with the argument's)
    r_param = parse_number(params.pop("r", None), "r", optional=True)
    L1 = parse_number(params.pop("L1", None), "L1", optional=True)
    for name, v in (("r", r_param), ("L1", L1)):  # 0 was dropped without a word (falsy)
        if v is not None and not v > 0:
            raise ParameterError(f"algebraic: {name} must be {_domain_text(name)}, got {v}")
    if r and r_param and r_param != r:
        raise ParameterError(f"{src}: the wheel radius is given twice, --wheel-radius {r:g} m "
                             f"and -p r={r_param:g}: give one")
    r = r or r_param or recording.wheel_radius
    r = r or recording.meta.get("wheel_radius")
    if not r:
        raise ParameterError(f"{src}: the algebraic method needs the wheel radius (--wheel-radius)")
    L1 = L1 or recording.meta.get("L1")
    if not L1:
        raise ParameterError(f"{src}: the algebraic method needs L1, the CG to front axle "
                             "distance in m (--param L1=...)")
    if len(recording) < 3:
        raise InputError(f"{src}: fewer than 3 samples")
    check_time(recording)
    tg, resampled = _uniform_grid(recording)
    dt = float(np.median(np.diff(tg)))
    cfg = config_from_params(Config, params, r=float(r), L1=float(L1), dt=dt)
    W = np.stack([recording.channel(c) for c in WHEEL_CHANNELS], axis=1)
    fin = np.isfinite(W)
    cnt = fin.sum(axis=1)
    wm = np.full(len(recording), np.nan)
    wm[cnt > 0] = np.where(fin, W, 0.0).sum(axis=1)[cnt > 0] / cnt[cnt > 0]  # mean of finite
    cols = [recording.channel("gz"), recording.channel("ax"), recording.channel("ay"), wm]
    if resampled:
        cols = [_interp_finite(tg, recording.t, c) for c in cols]
    _, out = run(cfg, np.stack(cols, axis=1))
    notes = [f"algebraic: r = {cfg.r:g} m, L1 = {cfg.L1:g} m, Ts = {dt * 1e3:.4g} ms, windows "
             f"{cfg.window:g} / {cfg.window_d:g} s, N = {cfg.N}"]
    longest = _longest_slip(out[:, OUTPUTS.index("slip_mode")], tg)
    if longest > SLIP_NOTE_S and not np.isfinite(cfg.max_int):
        notes.append(_slip_note(longest, out, cfg))
    if resampled:
        notes.append(f"non-uniform time line resampled to {dt * 1e3:.4g} ms and back (linear)")
        out = np.stack([_interp_finite(recording.t, tg, out[:, j]) for j in range(out.shape[1])],
                       axis=1)
    extras = {name: out[:, j].copy() for j, name in enumerate(OUTPUTS)
              if name not in ("vx", "vx_std")}
    return Track.from_speed(
        recording.t, out[:, 0], out[:, OUTPUTS.index("vx_std")], wheel_radius=float(r),
        method="algebraic",
        params={k: v for k, v in asdict(cfg).items()}, extras=extras, notes=notes,
    )
