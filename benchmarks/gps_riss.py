"""Benchmark of the GPS/RISS fusion (issue 5; METHODS.md section 3): simulated scenarios with 15
seeds each, the comma2k19 minute (CAN wheel-speed truth) and GPS-drop windows on the Hungary
phyphox drives. Writes docs/gps_riss.md.

Run by hand (about a minute):  PYTHONPATH=src .venv/bin/python benchmarks/gps_riss.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vibrospeed.estimators import gps_riss as gr
from vibrospeed.models.gps_riss import GpsLagModel
from vibrospeed.sim import gps as sg

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT.parent / "shared" / "datasets"
SEEDS = range(15)


# -- metrics -------------------------------------------------------------------------------------

def _hold(t, g, ok):
    """Last valid fix at every sample (the raw GPS speed as a user would read it)."""
    idx = np.flatnonzero(ok)
    j = np.searchsorted(t[idx], t, side="right") - 1
    return np.where(j >= 0, g[idx[np.maximum(j, 0)]], np.nan)


def _xcorr_lag(ref, est, fs, maxlag=0.5):
    """Lag (s, + = est late) at the cross-correlation peak of the smoothed derivatives."""
    n = max(int(0.25 * fs), 1)
    k = np.ones(n) / n
    a = np.gradient(np.convolve(ref, k, "same"))[n:-n]
    b = np.gradient(np.convolve(est, k, "same"))[n:-n]
    L = int(maxlag * fs)
    c = np.array([np.dot(a[L:-L], b[L + s: b.size - L + s]) for s in range(-L, L + 1)])
    i = int(np.clip(np.argmax(c), 1, c.size - 2))
    d = 0.5 * (c[i - 1] - c[i + 1]) / (c[i - 1] - 2 * c[i] + c[i + 1])
    return (i - L + d) / fs


def _rmse(e):
    return float(np.sqrt(np.nanmean(np.asarray(e) ** 2)))


def _lag_of(rec):
    m = rec.meta["gps_lag"]
    return GpsLagModel(a=tuple(m["a"]), b=tuple(m["b"]), delay=m.get("delay", 0.0))


Z98 = 2.3263  # two-sided 98 % normal quantile


def _cover(e, std):
    return float(np.mean(np.abs(e) <= Z98 * std))


# -- simulation ----------------------------------------------------------------------------------

def sim_table() -> tuple[str, dict]:
    rows = []
    figs: dict[str, list] = {}
    # identify the braking scenario's (underdamped) receiver once, from a separate drive
    cal = sg.braking(np.random.default_rng(1000))
    lag_id, info = gr.identify_lag_recording(cal)
    figs["identified"] = info
    # a receiver with a 0.4 s pure delay on top: identified (with fit_delay) on a calibration drive
    cal_d = sg.braking(np.random.default_rng(1001), gps_delay=0.4)
    lag_d, info_d = gr.identify_lag_recording(cal_d, fit_delay=True)
    lag_d0, info_d0 = gr.identify_lag_recording(cal_d)
    figs["identified_delay"] = info_d
    figs["identified_delay_none"] = info_d0
    names = [*sg.SCENARIOS, "gps_braking_delay"]
    for name in names:
        acc: dict[str, list] = {}
        for seed in SEEDS:
            if name == "gps_braking_delay":
                rec = sg.braking(np.random.default_rng(seed), gps_delay=0.4)
            else:
                rec = sg.scenario(name, np.random.default_rng(seed))
            moto = name == "gps_motorcycle"
            cfg = gr.Config.with_lag(_lag_of(rec), pitch_compensation=moto)
            _, o = gr.run(cfg, rec.t, rec["ax"], rec["gps_speed"], rec["gps_sats"])
            v, t = rec["speed_true"], rec.t
            ok = np.isfinite(rec["gps_speed"]) & (rec["gps_sats"] >= 7)
            raw = _hold(t, rec["gps_speed"], ok)
            m = t > 2.0
            r = {"raw": _rmse(raw[m] - v[m]), "fused": _rmse(o.speed[m] - v[m]),
                 "lag_raw": _xcorr_lag(v[m], raw[m], rec.fs),
                 "lag_fused": _xcorr_lag(v[m], o.speed[m], rec.fs),
                 "cover": _cover(o.speed[m] - v[m], o.speed_std[m])}
            _, opp = gr.run(gr.Config.paper(pitch_compensation=moto).using_lag(_lag_of(rec)), t,
                            rec["ax"], rec["gps_speed"], rec["gps_sats"])
            r["fused_paper"] = _rmse(opp.speed[m] - v[m])
            r["cover_paper"] = _cover(opp.speed[m] - v[m], opp.speed_std[m])
            if name == "gps_braking_delay":
                for key, L in (("fused_id_delay", lag_d), ("fused_id_nodelay", lag_d0),
                               ("fused_nodelay", GpsLagModel(a=_lag_of(rec).a,
                                                             b=_lag_of(rec).b))):
                    _, oi = gr.run(gr.Config.with_lag(L), t, rec["ax"], rec["gps_speed"],
                                   rec["gps_sats"])
                    r[key] = _rmse(oi.speed[m] - v[m])
                    r["lag_" + key] = _xcorr_lag(v[m], oi.speed[m], rec.fs)
            if name == "gps_braking":
                _, oi = gr.run(gr.Config.with_lag(lag_id), t, rec["ax"], rec["gps_speed"],
                               rec["gps_sats"])
                _, op = gr.run(gr.Config(), t, rec["ax"], rec["gps_speed"], rec["gps_sats"])
                r["fused_identified"] = _rmse(oi.speed[m] - v[m])
                r["fused_paper_lag"] = _rmse(op.speed[m] - v[m])
            if name == "gps_tunnel":
                a, b = rec.meta["tunnel"]
                w = (t >= a) & (t <= b + 1.0)
                r["tunnel_max"] = float(np.max(np.abs(o.speed[w] - v[w])))
                r["tunnel_end"] = float(abs(o.speed[np.searchsorted(t, b)] - v[np.searchsorted(t, b)]))
                r["tunnel_hold_max"] = float(np.max(np.abs(raw[w] - v[w])))
            if name == "gps_hilly":
                e = np.abs(o.offset - rec.meta["offset_true"])
                late = t > 30.0
                r["off_med"] = float(np.median(e[late]))
                r["off_within10"] = float(np.mean(e[late] < 0.05))
                r["off_t10"] = float(t[np.argmax(e < 0.05)])
                r["speed_max"] = float(np.max(np.abs(o.speed - v)[t > 5.0]))
                _, on = gr.run(gr.Config.with_lag(_lag_of(rec), offset_mode="off"), t,
                               rec["ax"], rec["gps_speed"], rec["gps_sats"])
                r["fused_no_offset"] = _rmse(on.speed[m] - v[m])
                _, oi = gr.run(gr.Config.with_lag(_lag_of(rec), offset_mode="integrator"), t,
                               rec["ax"], rec["gps_speed"], rec["gps_sats"])
                r["fused_integrator"] = _rmse(oi.speed[m] - v[m])
                r["off_med_integrator"] = float(np.median(
                    np.abs(oi.offset - rec.meta["offset_true"])[late]))
            if name == "gps_jump":
                _, of = gr.run(gr.Config.with_lag(_lag_of(rec), adaptive=False), t, rec["ax"],
                               rec["gps_speed"], rec["gps_sats"])
                _, os_ = gr.run(gr.Config.with_lag(_lag_of(rec), error_mode="kf2"), t,
                                rec["ax"], rec["gps_speed"], rec["gps_sats"])
                r["fused_fixed"] = _rmse(of.speed[m] - v[m])
                r["fused_kf2"] = _rmse(os_.speed[m] - v[m])
                r["max_adaptive"] = float(np.max(np.abs(o.speed - v)[m]))
                r["max_fixed"] = float(np.max(np.abs(of.speed - v)[m]))
            if moto:
                _, on = gr.run(gr.Config.with_lag(_lag_of(rec)), t, rec["ax"], rec["gps_speed"],
                               rec["gps_sats"])
                r["fused_no_pitch"] = _rmse(on.speed[m] - v[m])
            for k, val in r.items():
                acc.setdefault(k, []).append(val)
        figs[name] = {k: np.array(v) for k, v in acc.items()}
        a = figs[name]
        rows.append(
            f"| {name} | {a['raw'].mean():.3f} | {a['fused'].mean():.3f} | "
            f"{(a['raw'] / a['fused']).min():.1f} / {(a['raw'] / a['fused']).mean():.1f} | "
            f"{a['lag_raw'].mean():.3f} | {np.abs(a['lag_fused']).max():.3f} | "
            f"{100 * a['cover'].mean():.1f} ({100 * a['cover'].min():.1f}) | "
            f"{a['fused_paper'].mean():.3f} | {100 * a['cover_paper'].mean():.1f} |"
        )
    head = ("| scenario | raw GPS RMSE (m/s) | fused RMSE (m/s) | ratio min / mean | "
            "raw lag (s) | max abs fused lag (s) | 98 % band coverage mean (min), % | "
            "paper constants: fused RMSE | paper constants: coverage, % |\n"
            "|---|---|---|---|---|---|---|---|---|\n")
    return head + "\n".join(rows), figs


# -- comma2k19 -------------------------------------------------------------------------------------

def _load_comma():
    seg = DATA / "comma2k19_example" / "segment_40" / "processed_log"

    def ld(p):
        return np.load(seg / p / "t"), np.load(seg / p / "value")

    ta, acc = ld("IMU/accelerometer")
    tg, gnss = ld("GNSS/live_gnss_ublox")  # columns: lat, lon, speed (m/s), utc ms, alt, ...
    tw, ws = ld("CAN/wheel_speed")  # 4 wheel speeds, m/s
    return ta, acc, tg, gnss[:, 2], tw, ws.mean(axis=1)


def _merge(ta, a, tg, g):
    """Accelerometer time line with each GPS fix placed on the nearest later accelerometer sample."""
    gps = np.full(ta.size, np.nan)
    idx = np.clip(np.searchsorted(ta, tg), 0, ta.size - 1)
    gps[idx] = g
    return gps


def comma_table() -> tuple[str, dict]:
    ta, acc, tg, g, tw, truth = _load_comma()
    t0 = ta[0]
    # longitudinal axis from the GNSS alone: regress d(GNSS speed)/dt on the three IMU axes
    dg = np.gradient(g, tg)
    A = np.column_stack([np.interp(tg, ta, acc[:, i]) for i in range(3)] + [np.ones(tg.size)])
    coef = np.linalg.lstsq(A, dg, rcond=None)[0]
    u = coef[:3] / np.linalg.norm(coef[:3])
    along = acc @ u
    offset0 = float(np.mean(along) - np.mean(dg))  # gravity leaking into the tilted axis
    gps = _merge(ta, along, tg, g)
    v = np.interp(ta, tw, truth)
    t = ta - t0
    out = {"axis": u.tolist(), "offset0": offset0}
    raw = _hold(t, gps, np.isfinite(gps))
    m = (t > 5.0) & np.isfinite(raw)
    lines = []
    lines.append(f"| raw u-blox GNSS (held) | {_rmse(raw[m] - v[m]):.3f} | "
                 f"{np.mean(raw[m] - v[m]):+.3f} | "
                 f"{_xcorr_lag(v[m], raw[m], 1 / np.median(np.diff(t))):.3f} |")
    out["raw"] = _rmse(raw[m] - v[m])
    lag_id, info = gr.identify_lag(t, gps, v, wn0=5.0, zeta0=0.8, fit_gain=True)
    out["identified"] = info
    for label, cfg in [
        ("fused, paper lag model", gr.Config()),
        ("fused, lag model identified on this minute (in-sample)", gr.Config.with_lag(lag_id)),
    ]:
        st = gr.init(cfg, float(g[0]), offset0=offset0)
        _, o = gr.run(cfg, t, along, gps, None, state=st)
        e = _rmse(o.speed[m] - v[m])
        out[label] = e
        lines.append(f"| {label} | {e:.3f} | {np.mean(o.speed[m] - v[m]):+.3f} | "
                     f"{_xcorr_lag(v[m], o.speed[m], 1 / np.median(np.diff(t))):.3f} |")
    head = ("| speed | RMSE vs CAN wheel speeds (m/s) | mean error (m/s) | lag vs CAN (s) |\n"
            "|---|---|---|---|\n")
    return head + "\n".join(lines), out


# -- Hungary ---------------------------------------------------------------------------------------

def _load_phyphox(d: Path):
    """Accelerometer (t, 3 axes) and the valid 1 Hz fixes of one phyphox drive."""
    a = pd.read_csv(d / "Accelerometer.csv").to_numpy(float)
    loc = pd.read_csv(d / "Location.csv")
    tl = loc["Time (s)"].to_numpy(float)
    vl = loc["Velocity (m/s)"].to_numpy(float)
    keep = (vl >= 0) & np.concatenate([[True], np.diff(tl) > 0.05])  # -1 = no fix; duplicates
    return a[:, 0], a[:, 1:4], tl[keep], vl[keep]


def _along_track(ta, acc, tg, g):
    """Unit forward axis u from the GPS alone: least squares of d(GPS speed)/dt on the axes."""
    dg = np.gradient(g, tg)
    A = np.column_stack([np.interp(tg, ta, acc[:, i]) for i in range(3)] + [np.ones(tg.size)])
    c = np.linalg.lstsq(A, dg, rcond=None)[0]
    return c[:3] / np.linalg.norm(c[:3])


HUNGARY_CONFIGS = {
    "default": {},
    "q_offset = 1e-3": {"q_offset": 1e-3},
}


def hungary_table() -> tuple[str, dict]:
    rows = []
    summary: dict[str, dict[str, list]] = {}
    drives = sorted(p for p in (DATA / "hungary_car_phyphox").iterdir() if p.is_dir())
    for d in drives:
        ta, acc, tl, vl = _load_phyphox(d)
        for axis_label, sig in (("y", acc[:, 1]), ("aligned", acc @ _along_track(ta, acc, tl, vl))):
            gps = _merge(ta, sig, tl, vl)
            fix = np.flatnonzero(np.isfinite(gps))
            for cname, params in HUNGARY_CONFIGS.items():
                if axis_label == "y" and cname != "default":
                    continue
                cfg = gr.Config(**params)
                ends, rmss, holds = [], [], []
                for w0 in np.arange(ta[0] + 60.0, ta[-1] - 15.0, 30.0):
                    w1 = w0 + 10.0
                    inside = np.isfinite(gps) & (ta >= w0) & (ta < w1)
                    if inside.sum() < 8:
                        continue
                    seg = (ta >= w0 - 120.0) & (ta < w1)  # 2 min of history is plenty
                    g2 = np.where(inside, np.nan, gps)
                    _, o = gr.run(cfg, ta[seg], sig[seg], g2[seg], None)
                    err = o.speed[inside[seg]] - gps[inside]
                    before = fix[ta[fix] < w0]
                    ends.append(abs(err[-1]))
                    rmss.append(_rmse(err))
                    holds.append(abs(gps[before[-1]] - gps[inside][-1]))
                key = f"{axis_label}, {cname}"
                acc_ = summary.setdefault(key, {"end": [], "rms": [], "hold": []})
                acc_["end"] += ends
                acc_["rms"] += rmss
                acc_["hold"] += holds
                rows.append(f"| {d.name} | {key} | {len(ends)} | {np.mean(rmss):.2f} | "
                            f"{np.median(ends):.2f} | {np.median(holds):.2f} |")
    out = {}
    for key, a in summary.items():
        a = {k: np.array(v) for k, v in a.items()}
        out[key] = a
        rows.append(f"| **all** | {key} | {a['end'].size} | {a['rms'].mean():.2f} | "
                    f"{np.median(a['end']):.2f} | {np.median(a['hold']):.2f} |")
    head = ("| drive | axis, config | windows | mean RMS coasting error (m/s) | "
            "median error at 10 s (m/s) | median error at 10 s, holding the last fix (m/s) |\n"
            "|---|---|---|---|---|---|\n")
    return head + "\n".join(rows), out


def main() -> int:
    t0 = time.time()
    sim_md, f = sim_table()
    print(sim_md)
    comma_md, c = comma_table()
    print(comma_md)
    hun_md, h = hungary_table()
    print(hun_md)
    br, tu, hi, ju, mo = (f[k] for k in ("gps_braking", "gps_tunnel", "gps_hilly", "gps_jump",
                                        "gps_motorcycle"))
    idf = f["identified"]
    text = f"""# GPS/RISS fusion: results

Method: `vibrospeed.estimators.gps_riss` (METHODS.md section 3; O'Kane & Ringwood's GPS/RISS
paper). Generated by `benchmarks/gps_riss.py` ({time.time() - t0:.0f} s); numbers change only
when the code or the seeds change.

## What is implemented

* 4-state model `[speed, accel, GPS speed, GPS accel]` with the receiver lag as a parameter
  (paper eq. 3-4 by default), exact discretisation `expm(A_c dt)` at every accelerometer sample
  (irregular sampling allowed); KF1 (INS/GPS) on samples with a new valid fix, KF (INS) otherwise.
* Satellite gate (default 7), KF2 with fixed R = diag(3.5, 40) for the GPS error E and
  R22 = 72 E + 40 (E clipped to 0..5), the drift/offset integrator KF, pitch compensation by the
  paper's polynomial (degrees; off by default, it was fitted on a motorcycle) and a calibration gain.
* `identify_lag`: least-squares fit of (wn, zeta[, gain]) of the second-order receiver model.

## Choices where the paper is silent (all overridable)

* **Units of Q.** The paper's Q = diag(5, 4, 1, 1) has no units or rate. Read literally as a
  per-step covariance at 400 Hz, the speed state is nearly free (5 (m/s)^2 per 2.5 ms) and the
  filter ignores the accelerometer almost entirely (on the jump scenario it followed every GPS jump).
  We read it as a white-noise intensity per second, Q_k = diag(q) dt (`q_rate = 1`); `q_rate = 400`
  restores the literal reading.
* **GPS error E.** The paper's definition, KF2's x3 against KF2's x1 passed through the lag model
  (`error_mode="states"`), stays small because KF2 moves x1 with the GPS as fast as x3. The default
  `error_mode="innovation"` compares the new fix with KF2's lagged speed *before* KF2 absorbs it.
  Jump scenario (15 seeds): fused RMSE adaptive/innovation {ju['fused'].mean():.3f} m/s,
  adaptive/states {ju['fused_states'].mean():.3f} m/s, fixed R22 = 40 {ju['fused_fixed'].mean():.3f} m/s.
* **Drift filter.** It observes integral(a) - x1 only at valid fixes (during an outage x1 is the
  accelerometer integral itself, so the measurement carries no information), with its variance
  scaled by R22/40 like the GPS; q_offset = 1e-2 (m/s^2)^2/s, r_drift = 0.1 (m/s)^2.
* **Discretisation.** The paper's eq. 7 holds x1 constant over a step (F[2:, 1] = 0); we keep the
  exact ramp term, identical at 400 Hz and better at low rates.

## Simulated scenarios (15 seeds each, 400 Hz accelerometer, 12.5 Hz GPS)

Raw GPS = last valid fix held; lag = cross-correlation peak of the smoothed derivatives of truth
and estimate (positive = late). The filter uses the scenario's receiver model; the braking
scenario's receiver is underdamped (wn = 6 rad/s, zeta = 0.5: overshoot after braking), the
others use the paper's. Motorcycle: pitch compensation on.

{sim_md}

* **Braking / acceleration**: with the receiver model identified from a separate calibration drive
  (wn = {idf['wn']:.2f} rad/s, zeta = {idf['zeta']:.3f}; true 6, 0.5) fused RMSE
  {br['fused_identified'].mean():.3f} m/s; with the paper's (wrong) lag model
  {br['fused_paper_lag'].mean():.3f} m/s, against {br['raw'].mean():.3f} m/s raw.
* **Tunnel (5 s, satellites 0, receiver reports 0 m/s, 0.1 m/s^2 accelerometer bias)**: max error
  in the tunnel and 1 s after it {tu['tunnel_max'].mean():.3f} m/s mean, {tu['tunnel_max'].max():.3f}
  m/s worst of 15 (holding the last fix: {tu['tunnel_hold_max'].mean():.2f} m/s).
* **Hilly course with 0.5 m/s^2 accelerometer bias + grades to 4 %**: after 30 s the offset estimate
  is within 10 % (0.05 m/s^2) of the true total offset {100 * hi['off_within10'].mean():.0f} % of the
  time (median error {hi['off_med'].mean():.3f} m/s^2; first within 10 % at
  t = {hi['off_t10'].mean():.1f} s on average); speed error bounded: max
  {hi['speed_max'].max():.3f} m/s over all seeds. Without the drift filter the fused RMSE is
  {hi['fused_no_offset'].mean():.3f} m/s (with: {hi['fused'].mean():.3f}).
* **GPS jumps (3 jumps of 2.4-3.6 m/s, 0.4-1 s)**: adaptive weighting RMSE {ju['fused'].mean():.3f}
  m/s vs fixed {ju['fused_fixed'].mean():.3f} m/s (lower on {int(np.sum(ju['fused'] < ju['fused_fixed']))}
  of 15 seeds); max error {ju['max_adaptive'].mean():.2f} vs {ju['max_fixed'].mean():.2f} m/s.
* **Motorcycle (pitch by paper eq. 14)**: fused RMSE {mo['fused'].mean():.3f} m/s with pitch
  compensation, {mo['fused_no_pitch'].mean():.3f} m/s without.

## comma2k19 (60 s, RAV4 on a highway, u-blox 10 Hz, phone IMU ~104 Hz)

Truth: mean of the four CAN wheel speeds. The longitudinal axis is found from the GNSS alone (least
squares of d(GNSS speed)/dt on the three accelerometer axes: u = {np.round(c['axis'], 3).tolist()}),
the drift filter starts from the gravity leak that regression gives ({c['offset0']:.3f} m/s^2).
No satellite count in this log: every fix is valid.

{comma_md}

Identified receiver: wn = {c['identified']['wn']:.2f} rad/s, zeta = {c['identified']['zeta']:.2f},
gain = {c['identified']['gain']:.4f} (residual {c['identified']['rmse']:.3f} m/s). On this minute the fusion does not beat the raw GNSS: the GNSS reads
above the CAN mean wheel speed (see mean error) and arrives ~0.46 s late against CAN, partly log
time-stamp latency, which a second-order lag model represents poorly; the fusion removes part of
the lag but adds accelerometer-offset error on a 60 s clip too short for the drift filter. Which
sensor carries the scale error (tyre radius vs GNSS) is not known.

## Hungary phyphox drives (1 Hz GPS, ~100 Hz accelerometer, phone flat, y forward)

From 60 s into each drive, every 30 s, the GPS fixes of a 10 s window are withheld and the filter
coasts on the accelerometer; the error is measured against the withheld fixes. Axis "y" is the
phone's y axis as recorded; "aligned" projects the three axes on the forward direction found from
the GPS speed derivative (the phone is not exactly square to the car, and lateral acceleration in
bends leaks into y). Baseline: holding the last fix before the window. The paper's lag model is
used unchanged (this receiver's lag was not identified: there is no independent speed reference).
With 1 Hz fixes and a consumer phone accelerometer the offset estimate is the limit: a residual
0.2 m/s^2 gives 2 m/s after 10 s; a slower offset filter (q_offset = 1e-3) coasts better here but
tracks grade changes worse on the simulated hilly course.

{hun_md}

## Reproduce

    PYTHONPATH=src .venv/bin/python benchmarks/gps_riss.py
"""
    (ROOT / "docs" / "gps_riss.md").write_text(text)
    print(f"wrote docs/gps_riss.md in {time.time() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
