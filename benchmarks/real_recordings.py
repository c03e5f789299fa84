"""vibrospeed's harmonic trackers (and the pitch-tracking peers) on real recordings (issue 3).

Run by hand (a few minutes on one core)::

    PYTHONPATH=src .venv/bin/python benchmarks/real_recordings.py [kart] [hungary] [comma]
        [--rbpf] [--no-peers] [--no-write]

Writes ``benchmarks/real_recordings/RESULTS.md`` (whole file) unless ``--no-write`` or only some
parts are run; tables are printed too. Data: /work/shared/datasets (README.md there).

* kart (GoPro HERO9, raw ACCL counts, 198.4 Hz, GPS speed ~18 Hz): a line proportional to
  speed, omega = k v with an unknown k. Every tracker on every axis; k fitted as the median of
  omega_est / v_gps over the GPS samples with v > 3 m/s; scored by the share of those samples
  with |omega_est - k v| < 5 % of k v, in-sample and two-fold (k from one half of the drive,
  scored on the other). The best axis is picked by the best tracker's in-sample share.
* hungary (7 phyphox drives, phone flat, 99.6 Hz; GPS speed 1 Hz) and comma (comma2k19 RAV4
  minute): no wheel line is visible, so the question is honesty: does each tracker's 98 % band
  cover the GPS-implied omega = v / r (r = 0.31 m Hungary, 0.362 m RAV4; for comma also the CAN
  wheel speeds), how wide is it, and how often is it narrow and wrong ("confident miss")?
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from vibrospeed import io
from vibrospeed.estimators import get
from vibrospeed.signal import prefilter as pf
from vibrospeed.types import Recording

sys.path.insert(0, str(Path(__file__).resolve().parent))
import peers as P  # noqa: E402  (benchmarks/peers.py: the peer wrappers and audio mapping)

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "benchmarks" / "real_recordings" / "RESULTS.md"
DATA = Path("/work/shared/datasets")
KART = DATA / "gopro_kart"
HUNGARY = DATA / "hungary_car_phyphox"
COMMA = DATA / "comma2k19_example" / "segment_40"
R_HUNGARY = 0.31
R_RAV4 = 0.362
CONFIDENT = 0.2  # a band narrower than this fraction of the true omega counts as "confident"


def _track(method: str, rec: Recording, axis: str, params: dict):
    """tracker output, or None with a printed note (trackers are under development)."""
    try:
        t0 = time.process_time()
        tr = get(method).estimate(rec, axis=axis, params=params)
        return tr, time.process_time() - t0
    except Exception as exc:  # noqa: BLE001
        print(f"  {method} on {rec.source} axis {axis} failed: {type(exc).__name__}: {exc}")
        return None, 0.0


def _prefiltered(rec: Recording, axis: str, preset: str) -> tuple[np.ndarray, float]:
    x = rec["a" + axis]
    fs = 1.0 / float(np.median(np.diff(rec.t)))
    head = x[: int(fs)][np.isfinite(x[: int(fs)])]
    return pf.apply(pf.design(preset, fs), np.nan_to_num(x),
                    level=float(np.mean(head)) if head.size else None), fs


def _peers(y: np.ndarray, fs: float, t: np.ndarray, wmin: float, wmax: float) -> dict:
    """name -> (omega on t, voiced flag on t or None, CPU s); missing peers skipped."""
    out = {}
    t0 = time.process_time()
    tf, wf = P.spectrogram_peak(y, fs, wmin, wmax)
    out["spectrogram peak"] = (P.to_samples(t - t[0], tf, wf), None, time.process_time() - t0)
    av = P.AudioView(y, fs, wmin, wmax)
    for name, fn in P.available_peers(quiet=True).items():
        try:
            t0 = time.process_time()
            tfr, wfr, voiced, _ = fn(av)
            el = time.process_time() - t0
            tt = t - t[0]
            vs = np.interp(tt, tfr, voiced.astype(float), left=0, right=0) > 0.5
            out[name] = (P.to_samples(tt, tfr, wfr), vs, el)
        except Exception as exc:  # noqa: BLE001
            print(f"  peer {name} failed: {type(exc).__name__}: {exc}")
    return out


# -- (a) GoPro kart -----------------------------------------------------------------------------

KART_RANGE = (20.0, 300.0)  # rad/s; fundamental < pi fs = 623; k unknown, so a wide range
KART_PRE = "paper-hp"  # 8 Hz HP: the line is at 18-41 Hz, c1 has a strong band below 10 Hz
KART_METHODS = [
    ("RBPMF (M=3)", "rbpmf", {}),
    ("RBPMF M=1", "rbpmf", {"M": 1}),
    ("RBPMF M=1, q_omega=100", "rbpmf", {"M": 1, "q_omega": 100.0}),
    ("RBPMF (M=3), q_omega=100", "rbpmf", {"q_omega": 100.0}),
    ("EKF (M=2)", "ekf", {"M": 2, "omega0": 160.0}),
    ("EKF M=1", "ekf", {"M": 1, "omega0": 160.0}),
    ("EKF M=1, q_omega=100", "ekf", {"M": 1, "omega0": 160.0, "q_omega": 100.0}),
    ("SHS", "shs", {}),
    ("grid (smoother, offline)", "grid", {}),
    ("grid (filter, causal)", "grid", {"smooth": "none"}),
    ("grid, q_omega=100 (smoother)", "grid", {"q_omega": 100.0}),
]


def _kfit(w: np.ndarray, v: np.ndarray) -> tuple[float, float, float]:
    """(k, in-sample share within 5 %, two-fold share within 5 %) over finite w."""
    ok = np.isfinite(w) & (v > 3.0)
    if ok.sum() < 10:
        return np.nan, np.nan, np.nan
    idx = np.flatnonzero(ok)
    k = float(np.median(w[idx] / v[idx]))
    share = float(np.mean(np.abs(w[idx] - k * v[idx]) < 0.05 * k * v[idx]))
    half = idx.size // 2
    hits = 0
    for fit, test in ((idx[:half], idx[half:]), (idx[half:], idx[:half])):
        kk = np.median(w[fit] / v[fit])
        hits += int(np.sum(np.abs(w[test] - kk * v[test]) < 0.05 * kk * v[test]))
    n_all = int((v > 3.0).sum())
    return k, share * ok.sum() / n_all, hits / n_all


def kart(rbpf: bool, with_peers: bool) -> str:
    rec = io.read(KART / "GX030410_accl_raw.csv", columns="ax=c1,ay=c2,az=c3", rate=198.4)
    gps = pd.read_csv(KART / "GX030410_gps_speed.csv")
    tg, v = gps["t_video_s"].to_numpy(float), gps["gps_speed2d_mps"].to_numpy(float)
    methods = list(KART_METHODS)
    if rbpf:
        methods.append(("RBPF K=3000 M=1", "rbpf", {"M": 1, "n_particles": 3000, "seed": 0}))
    res: dict[tuple[str, str], dict] = {}
    for axis in "xyz":
        for label, method, p in methods:
            par = {"prefilter": KART_PRE, "omega_min": KART_RANGE[0],
                   "omega_max": KART_RANGE[1], **p}
            tr, el = _track(method, rec, axis, par)
            if tr is None:
                continue
            w = np.interp(tg, tr.t, tr.omega, left=np.nan, right=np.nan)
            k, s, s2 = _kfit(w, v)
            row = {"k": k, "in": s, "cv": s2, "time": el}
            c = P.claims(tr)
            if c is not None:  # grid: has_signal at the GPS samples, scored with the same k
                cg = np.interp(tg, tr.t, c.astype(float), left=0, right=0) > 0.5
                m = (v > 3.0) & cg
                row["claimed"] = float(np.mean(cg[v > 3.0]))
                row["in_c"] = (float(np.mean(np.abs(w[m] - k * v[m]) < 0.05 * k * v[m]))
                               if m.any() else np.nan)
            if np.isfinite(tr.omega_lo).any():
                lo = np.interp(tg, tr.t, tr.omega_lo)
                hi = np.interp(tg, tr.t, tr.omega_hi)
                m = v > 3.0
                row["cover"] = float(np.mean(((lo <= k * v) & (k * v <= hi))[m]))
                row["width"] = float(np.median((hi - lo)[m]))
            res[(axis, label)] = row
            print(f"  kart {axis} {label}: k={k:.2f} within5={s:.3f} 2-fold={s2:.3f}", flush=True)
    labels = [m[0] for m in methods]
    best_axis = max("xyz", key=lambda a: max([res[(a, lb)]["in"] for lb in labels
                                              if (a, lb) in res] or [-1]))
    lines = [
        "## (a) GoPro kart: the speed-proportional line\n",
        f"`io.read(\"{KART}/GX030410_accl_raw.csv\", columns=\"ax=c1,ay=c2,az=c3\", rate=198.4)`"
        " (raw counts; c1..c3 mapped to ax..az, axis order unverified). GPS speed "
        "`GX030410_gps_speed.csv` (8292 samples, ~18 Hz); scored on the "
        f"{int((v > 3).sum())} samples with v > 3 m/s. All trackers: pre-filter `{KART_PRE}`, "
        f"range [{KART_RANGE[0]:g}, {KART_RANGE[1]:g}] rad/s (k unknown, so no narrow range), "
        "the paper's other defaults unless the row says otherwise (EKF started at 160 rad/s). "
        "k = median(omega / v); \"within 5 %\": share of GPS samples with |omega - k v| < 5 % of "
        "k v; two-fold: k fitted on one half of the drive, scored on the other.\n",
        "Every axis (k / within 5 % in-sample):\n",
        "| method | " + " | ".join(f"a{a}" for a in "xyz") + " |",
        "|---|---|---|---|",
    ]
    for lb in labels:
        cells = []
        for a in "xyz":
            r = res.get((a, lb))
            cells.append("failed" if r is None else f"k = {r['k']:.2f}, {100 * r['in']:.1f} %")
        lines.append(f"| {lb} | " + " | ".join(cells) + " |")
    lines.append(f"\nBest axis: **a{best_axis}** (c{'xyz'.index(best_axis) + 1}; highest "
                 "share of any tracker). On it, with the peers (same pre-filtered axis and "
                 "range) and an oracle:\n")
    lines += ["| method | k (r = 1/k, m) | within 5 % | two-fold within 5 % | "
              "98 % band covers k v | median band width rad/s | claims signal | "
              "within 5 % where claimed | CPU s |",
              "|---|---|---|---|---|---|---|---|---|"]
    for lb in labels:
        r = res.get((best_axis, lb))
        if r is None:
            continue
        cov = f"{100 * r['cover']:.1f} %" if "cover" in r else "-"
        wid = f"{r['width']:.1f}" if "width" in r else "-"
        cl = f"{100 * r['claimed']:.1f} %" if "claimed" in r else "-"
        inc = f"{100 * r['in_c']:.1f} %" if np.isfinite(r.get("in_c", np.nan)) else "-"
        lines.append(f"| {lb} | {r['k']:.2f} ({1 / r['k']:.4f}) | {100 * r['in']:.1f} % | "
                     f"{100 * r['cv']:.1f} % | {cov} | {wid} | {cl} | {inc} | "
                     f"{r['time']:.1f} |")
    y, fs = _prefiltered(rec, best_axis, KART_PRE)
    if with_peers:
        for name, (w_s, _, el) in _peers(y, fs, rec.t, *KART_RANGE).items():
            w = np.interp(tg, rec.t, w_s, left=np.nan, right=np.nan)
            k, s, s2 = _kfit(w, v)
            lines.append(f"| {name} (peer) | {k:.2f} ({1 / k:.4f}) | {100 * s:.1f} % | "
                         f"{100 * s2:.1f} % | - | - | - | - | {el:.1f} |")
            print(f"  kart peer {name}: k={k:.2f} within5={s:.3f}", flush=True)
    # oracle: the spectrogram peak searched only within +-20 % of the line 11.2 v (uses GPS)
    k_line = 1 / 0.089
    w_or = _oracle(y, fs, rec.t, tg, v, k_line)
    k, s, s2 = _kfit(w_or, v)
    lines.append(f"| oracle: spectrogram peak within +-20 % of {k_line:.1f} v (uses GPS) | "
                 f"{k:.2f} ({1 / k:.4f}) | {100 * s:.1f} % | {100 * s2:.1f} % | - | - | - | - "
                 "| - |")
    return "\n".join(lines) + "\n"


def _oracle(y, fs, t, tg, v, k_line, win_s=1.0):
    n = int(round(win_s * fs))
    hop = max(1, int(round(0.05 * fs)))
    starts = np.arange(0, y.size - n + 1, hop)
    frames = np.lib.stride_tricks.sliding_window_view(y, n)[starts] * np.hanning(n)
    mag = np.abs(np.fft.rfft(frames, 4096, axis=1))
    om = 2 * np.pi * np.fft.rfftfreq(4096, 1 / fs)
    tc = t[0] + (starts + (n - 1) / 2) / fs
    vc = np.interp(tc, tg, v)
    est = np.full(tc.size, np.nan)
    for i, vv in enumerate(vc):
        if vv > 3:
            b = (om > 0.8 * k_line * vv) & (om < 1.2 * k_line * vv)
            est[i] = om[b][np.argmax(mag[i, b])]
    return np.interp(tg, tc, est, left=np.nan, right=np.nan)


# -- (b), (c): band honesty where no wheel line is visible ---------------------------------------

NOLINE_METHODS = [
    ("RBPMF (thesis-hp)", "rbpmf", {"prefilter": "thesis-hp"}),
    ("RBPMF (defaults: paper-hp)", "rbpmf", {}),
    ("EKF", "ekf", {}),
    ("SHS", "shs", {"prefilter": "thesis-hp"}),
    ("grid (smoother, offline)", "grid", {}),
    ("grid (filter, causal)", "grid", {"smooth": "none"}),
]
GRID = (10.0, 120.0)  # the trackers' default grid; truth outside it is not scored


def _band_stats(omega, lo, hi, truth, mask, claim=None) -> dict:
    """Scores at the samples ``mask`` whose truth lies in the grid; with ``claim`` (the grid
    tracker's has_signal) also ``claimed`` and the coverage / point score where claimed."""
    m = mask & np.isfinite(truth) & (truth >= GRID[0]) & (truth <= GRID[1])
    n = max(int(m.sum()), 1)
    w, tr = omega[m], truth[m]
    out = {"n": int(m.sum()),
           "within": float(np.mean(np.abs(w - tr) < 0.1 * tr)) if m.any() else np.nan}
    cover = None
    if lo is not None and np.isfinite(lo[m]).any():
        cover = (lo[m] <= tr) & (tr <= hi[m])
        width = hi[m] - lo[m]
        out["cover"] = float(cover.sum() / n)
        out["width"] = float(np.median(width))
        out["width_rel"] = float(np.median(width / tr))
        out["conf_miss"] = float(np.sum(~cover & (width < CONFIDENT * tr)) / n)
    if claim is not None and m.any():
        c = np.asarray(claim, bool)[m]
        out["claimed"] = float(np.mean(c))
        if c.any():
            out["within_c"] = float(np.mean((np.abs(w - tr) < 0.1 * tr)[c]))
            if cover is not None:
                out["cover_c"] = float(np.mean(cover[c]))
    return out


def _pool(rows: list[dict]) -> dict:
    """Pool per-recording stats weighted by their scored-sample counts."""
    n = np.array([r["n"] for r in rows], float)
    out = {"n": int(n.sum())}
    for key in ("within", "cover", "width", "width_rel", "conf_miss", "voiced", "voiced_ok",
                "conf_miss_v", "claimed"):
        vals = [(r[key], r["n"]) for r in rows if key in r and np.isfinite(r[key])]
        if vals:
            a = np.array(vals)
            out[key] = float(np.sum(a[:, 0] * a[:, 1]) / max(a[:, 1].sum(), 1))
    for key in ("within_c", "cover_c"):  # weighted by the claimed samples
        vals = [(r[key], r["n"] * r["claimed"]) for r in rows
                if key in r and np.isfinite(r[key])]
        if vals:
            a = np.array(vals)
            out[key] = float(np.sum(a[:, 0] * a[:, 1]) / max(a[:, 1].sum(), 1))
    return out


def _noline_recordings(rec_list, truth_fn, axes, peer_axis, with_peers, rbpf):
    """rows[(axis, label)] -> list of per-recording stats."""
    methods = list(NOLINE_METHODS)
    if rbpf:
        methods.append(("RBPF K=3000", "rbpf", {"prefilter": "thesis-hp", "n_particles": 3000}))
    rows: dict[tuple[str, str], list[dict]] = {}
    for rec in rec_list:
        truth, mask = truth_fn(rec)
        for axis in axes:
            for label, method, p in methods:
                tr, el = _track(method, rec, axis, p)
                if tr is None:
                    continue
                st = _band_stats(tr.omega, tr.omega_lo, tr.omega_hi, truth, mask,
                                 P.claims(tr))
                st["time"] = el
                rows.setdefault((axis, label), []).append(st)
            if with_peers and axis == peer_axis:
                y, fs = _prefiltered(rec, axis, "thesis-hp")
                for name, (w, voiced, _el) in _peers(y, fs, rec.t, 10.0, 120.0).items():
                    st = _band_stats(w, None, None, truth, mask, voiced)
                    if voiced is not None:
                        m = mask & np.isfinite(truth) & (truth >= GRID[0]) & (truth <= GRID[1])
                        ok = np.abs(w - truth) < 0.1 * truth
                        st["voiced"] = float(np.mean(voiced[m]))
                        st["conf_miss_v"] = float(np.mean((voiced & ~ok)[m]))
                    rows.setdefault((axis, name + " (peer)"), []).append(st)
        print(f"  {rec.source} done", flush=True)
    return rows


def _noline_table(rows) -> str:
    out = ["| axis | method | scored samples | 98 % band covers truth | median band width rad/s "
           "(/ truth) | confident miss | point within 10 % | claims signal (peer: voiced) | "
           "voiced and wrong | band covers truth where claimed | point within 10 % where "
           "claimed |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for (axis, label), rs in rows.items():
        p = _pool(rs)

        def pc(key, p=p):
            return f"{100 * p[key]:.1f} %" if key in p else "-"

        wid = f"{p['width']:.1f} ({p['width_rel']:.2f})" if "width" in p else "-"
        claim = pc("voiced") if "voiced" in p else pc("claimed")
        out.append(f"| a{axis} | {label} | {p['n']} | {pc('cover')} | {wid} | "
                   f"{pc('conf_miss')} | {pc('within')} | {claim} | "
                   f"{pc('conf_miss_v')} | {pc('cover_c')} | {pc('within_c')} |")
    return "\n".join(out)


def hungary(rbpf: bool, with_peers: bool) -> str:
    drives = sorted(p for p in HUNGARY.iterdir() if p.is_dir())
    recs = [io.read(p, "phyphox") for p in drives]

    def truth(rec):
        g = rec["gps_speed"]
        return g / R_HUNGARY, np.isfinite(g)

    rows = _noline_recordings(recs, truth, "xyz", "z", with_peers, rbpf)
    dur = sum(float(r.t[-1] - r.t[0]) for r in recs)
    return ("## (b) Hungary phyphox drives: no visible wheel line\n\n"
            f"{len(recs)} drives ({', '.join(p.name for p in drives)}; {dur / 60:.1f} min), "
            "`io.read(folder, \"phyphox\")`, phone flat: ax lateral, ay forward, az up. Truth: "
            f"GPS speed (1 Hz, channel `gps_speed`) / r, r = {R_HUNGARY} m, scored at the GPS "
            f"samples whose implied omega lies in the default grid [{GRID[0]:g}, {GRID[1]:g}] "
            "rad/s (v > 3.1 m/s), pooled over the drives. Peers on az only.\n\n"
            + _noline_table(rows) + "\n")


def _comma_phone(path: Path, can: Recording) -> Recording:
    """The phone IMU of the segment (104 Hz, uniform; phone axes, windshield mount) with the CAN
    wheel speeds and GNSS speed interpolated onto its time stamps (truth channels)."""
    base = path / "processed_log" / "IMU" / "accelerometer"
    t = np.load(base / "t").astype(float) - float(can.meta["t0_boot_s"])  # reader's t = 0
    a = np.load(base / "value").astype(float)
    ch = {"ax": a[:, 0], "ay": a[:, 1], "az": a[:, 2]}
    wcan = np.mean([can[k] for k in can.channels if k.startswith("wheel_omega")], axis=0)
    ch["wheel_omega"] = np.interp(t, can.t, wcan, left=np.nan, right=np.nan)
    g = can["gps_speed"]
    ok = np.isfinite(g)
    ch["gps_speed"] = np.interp(t, can.t[ok], g[ok], left=np.nan, right=np.nan)
    return Recording(t=t, channels=ch, units={"wheel_omega": "rad/s"},
                     source=f"{path.name} phone IMU", wheel_radius=R_RAV4)


def comma(rbpf: bool, with_peers: bool) -> str:
    can = io.read(COMMA, "comma2k19")
    phone = _comma_phone(COMMA, can)
    can_u = dataclasses.replace(io.resample_uniform(can),
                                source="segment_40 CAN accel (resampled)")
    parts = ["## (c) comma2k19 RAV4 highway minute: no visible wheel line\n\n"
             "`io.read(segment_40, \"comma2k19\")` gives the CAN wheel speeds (truth; mean of the "
             f"four, already divided by r = {R_RAV4} m), the GNSS speed and the car's own CAN "
             "accelerations on the non-uniform CAN wheel-speed time line. Two vibration sources: "
             "(1) the phone IMU (`processed_log/IMU/accelerometer`, 104.4 Hz, uniform, phone "
             "axes, windshield mount), loaded directly because the reader keeps only the CAN "
             "signals; (2) the reader's CAN ax / ay, resampled to a uniform line "
             "(`io.resample_uniform`, 89 Hz; ay 89 Hz, ax 44 Hz at the source). Truth omega at "
             "every sample: CAN (interpolated); GNSS-implied v / r in the second table.\n"]
    for rec, axes, peer_axis in ((phone, "xyz", "z"), (can_u, "xy", "")):
        for tname, tfun in (
            ("CAN wheel speeds", lambda r: (r["wheel_omega"] if "wheel_omega" in r.channels
                                            else np.mean([r[k] for k in r.channels
                                                          if k.startswith("wheel_omega")], 0),
                                            np.ones(len(r), bool))),
            ("GNSS speed / r", lambda r: (r["gps_speed"] / R_RAV4, np.ones(len(r), bool))),
        ):
            rows = _noline_recordings([rec], tfun, axes, peer_axis,
                                      with_peers and tname.startswith("CAN"), rbpf)
            parts.append(f"### {rec.source}, truth: {tname}\n\n" + _noline_table(rows) + "\n")
    return "\n".join(parts)


INTRO = """# Harmonic trackers on real recordings

Generated by `PYTHONPATH=src .venv/bin/python benchmarks/real_recordings.py` (do not edit by
hand; rerun). Trackers are used through their public `estimate()` with the paper's defaults
unless a row says otherwise; peers (benchmarks/peers.py: spectrogram peak, librosa pyin, Praat
To Pitch shs / ac, with the same "audio" mapping and settings as benchmarks/peers/RESULTS.md) get
the same pre-filtered axis and range. {versions}

Definitions: "98 % band covers truth": share of scored samples with the truth inside
[omega_lo, omega_hi]; "confident miss": the band excludes the truth while being narrower than
{conf:g} x the true omega; "point within 10 %": |omega - truth| < 10 % of truth; for peers,
"voiced" is their own voicing decision and "voiced and wrong" the share of samples voiced but
not within 10 % (their analogue of a confident miss). **grid** is the product tracker
(`vibrospeed estimate -m grid`: improved RBPMF + harmonic-comb evidence) with its own defaults,
smoothed (offline, its default) and `smooth=none` (the causal filter); on the kart it gets the
kart's pre-filter and range like every tracker. "Claims signal": share of the scored samples
where the track's `extras["has_signal"] > 0.5` (grid; the paper's RBPMF reports 1 everywhere),
for peers their voicing; "where claimed": the same scores over those samples only (on the kart
with the k fitted on all samples). CPU times are `time.process_time` on a shared 2-core VM.
"""


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("parts", nargs="*", help="kart, hungary, comma (default: all three)")
    ap.add_argument("--rbpf", action="store_true", help="also the RBPF (slow: ~1000 samples/s)")
    ap.add_argument("--no-peers", action="store_true")
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args(argv)
    a.parts = a.parts or ["kart", "hungary", "comma"]
    bad = set(a.parts) - {"kart", "hungary", "comma"}
    if bad:
        ap.error(f"unknown part(s) {sorted(bad)}: choose from kart, hungary, comma")
    with_peers = not a.no_peers
    if with_peers:
        P.available_peers()  # prints a note per missing peer
    versions = []
    for mod in ("librosa", "parselmouth"):
        if importlib.util.find_spec(mod) is None:
            versions.append(f"{mod} not installed (skipped)")
        else:
            versions.append(f"{mod} {__import__(mod).__version__}")
    body = []
    for part, fn in (("kart", kart), ("hungary", hungary), ("comma", comma)):
        if part in a.parts:
            t0 = time.time()
            body.append(fn(a.rbpf, with_peers))
            print(body[-1])
            print(f"({part}: {time.time() - t0:.0f} s wall)", flush=True)
    text = INTRO.format(versions="; ".join(versions), conf=CONFIDENT) + "\n" + "\n".join(body)
    text += "\n" + _reading()
    if not a.no_write and len(a.parts) == 3:
        DOC.write_text(text)
        print(f"wrote {DOC.relative_to(ROOT)}")


def _reading() -> str:
    """The "## Reading" section of the existing doc (written by hand after a run, so a rerun
    keeps it), or the template below for a first run."""
    if DOC.exists():
        old = DOC.read_text()
        i = old.find("## Reading")
        if i >= 0:
            return old[i:]
    return READING


READING = """## Reading

(Written by hand after the last run; the tables above are regenerated, this text is not.)

* **Kart**: the clearest axis is **az** (c3); the line found is k ~ 11.2 (r = 1/k ~ 0.089 m, as
  the dataset README says). With the paper's defaults the trackers do poorly: q_omega = 4
  (rad/s)^2/s is far too slow for a kart braking at ~45 rad/s^2 (RBPMF M=1: 17 % within 5 %,
  band covers k v 2 % of the time: confidently wrong), and with M = 3 the RBPMF and our SHS put
  the strong line on harmonic 2 or 3 (k ~ 4). With q_omega = 100 the RBPMF (M=1) reaches 41 %
  within 5 % (two-fold 42 %), the EKF (M=1) 38 %, the plain spectrogram peak 43 %; the best
  pitch-tracking peer (Praat ac) 26 %, pyin 10 %. An oracle that searches only +-20 % around the
  GPS-predicted line gets 56 %. The **grid** tracker (with the kart's `paper-hp` pre-filter and
  range [20, 300] rad/s) does **not** find the kart line: it claims a signal on only 0.4 %
  (smoothed) / 6.6 % (causal) of the az samples, its band spans the whole range (median width
  275 rad/s, so "covers k v" 100 % says nothing), and its point estimate fits k = 7.3-7.7 with
  12-16 % within 5 % (q_omega = 100 does not help: 6 %). It is honest ("no line") but behind
  the hand-tuned RBPMF, the EKF and the spectrogram peak here; goal "share within 5 %": best
  is still the spectrogram peak (43 %) / RBPMF M=1, q_omega=100 (41 %).
* **Hungary and comma2k19** (no wheel line): the issue asks for a band that widens. The paper's
  RBPMF and the EKF do **not**: a ~3 rad/s (7-12 % of omega) 98 % band locked on body
  resonances, covering the GPS-implied omega on 0-24 % of the scored samples with 67-99 %
  "confident misses". The **grid** tracker does: where it sees no line it returns its "no
  line" state with a band over the whole grid (median width 108 rad/s, 2-3 x omega), so its
  98 % band covers the GPS / CAN omega on 97-100 % of the scored samples (Hungary 99.5-99.7 %,
  comma 97-100 %) with 0-3 % confident misses, smoothed and causal alike. It claims a signal
  rarely (Hungary 0.3-2.8 %, comma 3-33 %); where it does, its band covers the truth 84-100 %
  of the time and the point estimate is within 10 % on 7-93 % (e.g. comma phone az smoothed
  75 % on 16 % claimed, Hungary az 28-33 %), so the claims are not yet reliable on these
  drives. The peers show the same problem as the old trackers in their own terms: Praat ac
  (voicing threshold 0) calls 96 % of frames voiced and is wrong on 89-96 %; pyin and Praat shs
  call 8-32 % voiced and are wrong on almost all of them (within 10 % where voiced: 0-10 %).
  The issue's "band must widen, not lock confidently on body resonances": **met by grid**, not
  by the paper's RBPMF.
* The CAN-accel x GNSS table scores 579 samples (4441 in the previous run): the comma2k19
  reader's GNSS speed on the CAN time line changed between the runs (not a benchmark change).
"""


if __name__ == "__main__":
    sys.exit(main())
