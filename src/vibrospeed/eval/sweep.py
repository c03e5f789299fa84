"""Pre-filter / noise sweep of the aided tracker over a set of recordings (thesis 3.5, table 3.1).

For each number of harmonics M, measurement noise R and low-pass cut-off omega_lp of the
``thesis-hplp`` pre-filter (high-pass order 2 at 4 rad/s + low-pass order 1 at omega_lp), the
aided tracker (:mod:`vibrospeed.estimators.aided`) runs on every recording and the RMSE against
the linearly interpolated truth (thesis eq. 3.18) is taken over the samples where

* only the vibration filter is active (not in acceleration mode), and
* the truth is moving (omega > ``min_omega``), after the truth has been handed to the filter
  once, ``init_after`` s after the vehicle starts moving (the thesis gave the EKF the ground
  truth a few seconds into each data set, to keep the detectors out of the experiment).

The sweep reports the summed and the median RMSE over the recordings per (M, R, omega_lp); the
best (R, omega_lp) per M is thesis table 3.1 (thesis grid: R = 0.0001..0.002 step 0.0001,
omega_lp = 5..30 rad/s step 1; 15 data sets; best M = 2, omega_lp = 19, summed 7.32, median 0.43,
mean 0.49 rad/s).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from vibrospeed.config import config_from_params
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import aided
from vibrospeed.estimators.common import check_uniform, split_params, start_level
from vibrospeed.eval.metrics import interp_truth, truth_omega
from vibrospeed.models.harmonic import HarmonicModel
from vibrospeed.signal import prefilter as pf
from vibrospeed.types import Recording

#: thesis table 3.1 (best per M): (omega_lp rad/s, R, summed RMSE over 15 sets, median RMSE)
THESIS_TABLE_3_1 = {
    1: (12.0, 0.0008, 10.3591, 0.6001),
    2: (19.0, 0.0022, 7.3245, 0.4308),
    3: (10.0, 0.0012, 7.5726, 0.4388),
    4: (8.0, 0.0007, 8.6424, 0.5217),
}


@dataclass(frozen=True)
class SweepResult:
    """RMSE (rad/s) of every run: ``rmse[i_M, i_R, i_lp, i_rec]``; NaN where nothing counted."""

    M_values: np.ndarray
    r_values: np.ndarray
    lp_values: np.ndarray
    rmse: np.ndarray
    sources: tuple[str, ...]

    @property
    def summed(self) -> np.ndarray:
        """(n_M, n_R, n_lp) RMSE summed over the recordings."""
        return np.sum(self.rmse, axis=-1)

    @property
    def median(self) -> np.ndarray:
        """(n_M, n_R, n_lp) median RMSE over the recordings."""
        return np.median(self.rmse, axis=-1)

    def best(self) -> list[dict]:
        """Per M: the (R, omega_lp) with the lowest summed RMSE, like thesis table 3.1."""
        out = []
        s = self.summed
        n = self.rmse.shape[-1]
        for i, M in enumerate(self.M_values):
            si = np.where(np.isfinite(s[i]), s[i], np.inf)
            j, k = np.unravel_index(int(np.argmin(si)), si.shape)
            out.append({"M": int(M), "lp_cutoff": float(self.lp_values[k]),
                        "r": float(self.r_values[j]), "summed_rmse": float(s[i, j, k]),
                        "median_rmse": float(self.median[i, j, k]),
                        "mean_rmse": float(s[i, j, k] / n)})
        return out


def _first_moving(t: np.ndarray, w: np.ndarray, min_omega: float) -> int | None:
    mv = np.flatnonzero(np.isfinite(w) & (w > min_omega))
    return int(mv[0]) if mv.size else None


def sweep(
    recordings: Sequence[Recording],
    *,
    M_values: Sequence[int] = (1, 2, 3, 4),
    r_values: Sequence[float] = tuple(np.round(np.arange(1, 21) * 1e-4, 6)),
    lp_values: Sequence[float] = tuple(float(v) for v in range(5, 31)),
    axis: str = "y",
    accel_axis: str = "ax",
    params: dict | None = None,
    init_after: float = 3.0,
    min_omega: float = 1.0,
    truth: Sequence[Recording] | None = None,
) -> SweepResult:
    """RMSE of the aided tracker for every (M, R, omega_lp) and recording (module docstring).

    ``params``: further :class:`~vibrospeed.estimators.aided.Config` / model fields (not M, r).
    ``truth``: truth recordings (e.g. from :func:`vibrospeed.eval.truth.ticks_to_truth`), one per
    recording; default the recordings' own ``omega_true`` / ``speed_true``.
    """
    from vibrospeed.estimators.common import axis_channel

    if not recordings:
        raise InputError("sweep: no recordings")
    if truth is not None and len(truth) != len(recordings):
        raise ParameterError("sweep: need one truth recording per recording")
    params = dict(params or {})
    for bad in ("M", "r", "dt", "prefilter", "lp_cutoff"):
        if bad in params:
            raise ParameterError(f"sweep: '{bad}' is swept or fixed by the sweep, not a param")
    model_kw, cfg_kw = split_params(HarmonicModel, params)
    M_values = np.asarray(M_values, dtype=np.int64)
    r_values = np.asarray(r_values, dtype=np.float64)
    lp_values = np.asarray(lp_values, dtype=np.float64)
    out = np.full((M_values.size, r_values.size, lp_values.size, len(recordings)), np.nan)
    for n, rec in enumerate(recordings):
        src = rec.source or f"recording {n}"
        r_wheel = cfg_kw.get("wheel_radius") or rec.wheel_radius
        if not r_wheel:
            raise ParameterError(f"{src}: sweep needs the wheel radius")
        dt = check_uniform(rec)
        tr = rec if truth is None else truth[n]
        w_true = interp_truth(tr.t, truth_omega(tr, r_wheel), rec.t)
        k0 = _first_moving(rec.t, w_true, min_omega)
        if k0 is None:
            raise InputError(f"{src}: the truth never moves above {min_omega} rad/s")
        k_init = min(int(np.searchsorted(rec.t, rec.t[k0] + init_after)), len(rec) - 1)
        ref = np.full(len(rec), np.nan)
        ref_var = np.full(len(rec), np.nan)
        ref[k_init] = w_true[k_init]
        ref_var[k_init] = 1e-4
        x = rec.channel(axis_channel(axis))
        u = aided._channel(rec, accel_axis)
        level = start_level(x, dt)
        after = np.arange(len(rec)) >= k_init
        moving = after & np.isfinite(w_true) & (w_true > min_omega)
        for i, M in enumerate(M_values):
            for k, lp in enumerate(lp_values):
                sos = pf.design("thesis-hplp", 1.0 / dt, M=int(M), lp_cutoff=float(lp))
                y = pf.apply(sos, x, level=level)
                for j, R in enumerate(r_values):
                    model = config_from_params(HarmonicModel, model_kw,
                                               **{**aided._thesis_model().to_dict(), "M": int(M),
                                                  "r": float(R), "dt": dt})
                    cfg = config_from_params(aided.Config, cfg_kw, model=model,
                                             wheel_radius=float(r_wheel))
                    res = aided.run(cfg, y, u, ref=ref, ref_var=ref_var)
                    sel = moving & ~res.accelerating & np.isfinite(res.omega)
                    if sel.any():
                        e = res.omega[sel] - w_true[sel]
                        out[i, j, k, n] = float(np.sqrt(np.mean(e * e)))
    return SweepResult(M_values, r_values, lp_values, out,
                       tuple(r.source or f"recording {i}" for i, r in enumerate(recordings)))


def format_table(result: SweepResult, *, thesis: bool = True) -> str:
    """Markdown table of :meth:`SweepResult.best`, with thesis table 3.1 beside it."""
    lines = ["| M | omega_lp (rad/s) | R | summed RMSE | median RMSE | mean RMSE |"
             + (" thesis omega_lp / R / summed / median |" if thesis else ""),
             "|---|---|---|---|---|---|" + ("---|" if thesis else "")]
    for b in result.best():
        row = (f"| {b['M']} | {b['lp_cutoff']:g} | {b['r']:.4g} | {b['summed_rmse']:.3f} | "
               f"{b['median_rmse']:.3f} | {b['mean_rmse']:.3f} |")
        if thesis:
            th = THESIS_TABLE_3_1.get(b["M"])
            row += (f" {th[0]:g} / {th[1]:g} / {th[2]:.2f} / {th[3]:.2f} |" if th else " - |")
        lines.append(row)
    lines.append(f"\n{result.rmse.shape[-1]} recordings; thesis: 15 shelf-cart data sets "
                 "(average RMSE 0.49 rad/s for M = 2).")
    return "\n".join(lines)
