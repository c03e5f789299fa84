"""Calibrate the simulator on real recordings (issue 13, part 1): what a vibration simulator
must reproduce, measured the same way on real recordings and on simulated drives.

Run by hand from the repository root (single process; ~1-2 min on a shared 2-core VM)::

    PYTHONPATH=src .venv/bin/python benchmarks/calibration/calibration.py [--no-write]
        [--car-seeds 5] [--random-seeds 20]

Prints Markdown tables and a dict of the key numbers, and writes
``benchmarks/calibration/RESULTS.md`` (unless ``--no-write``). Statistics
(``vibrospeed.eval.spectra_stats``), all from the same estimators on every source:

1. **wheel-line amplitude** of harmonic k = 1..3 in 4 s Hann frames (hop 1 s), amplitude-correct
   (``2 |X| / sum(w)``): (a) *order-tracked*, on every moving frame: the frame demodulated with
   the wheel angle ``theta = int omega dt`` (omega from the truth, CAN, or speed / r) and the
   peak searched over orders ``k (1 +- tol)`` (``tol`` per source, at least 0.25 Hz; 4x
   zero-padded grid), which at constant speed is exactly the frequency spectrum's peak at
   ``k omega / 2 pi`` and keeps a line sharp while the speed changes within the frame (a
   kart never holds its speed for 4 s); (b) *plain*: the peak of the 8x zero-padded frequency
   spectrum within ``[k w_min, k w_max] / 2 pi`` widened the same way, on "steady" frames
   only (wheel speed range < 4 % of its mean). Where no line is visible the number is an
   **upper bound** on a line there. Power law ``A ~ v^p`` over the frames (Theil-Sen on logs);
2. **local noise floor**: the median of the plain spectrum over the search band +-2 Hz without
   the band itself +-0.5 Hz (and without the other harmonics' bands);
3. **body resonances**: peaks (>= 3 dB prominence, -3 dB width >= 0.5 Hz) of the Welch PSD
   (4 s Hann segments wholly in moving time, smoothed over 0.75 Hz) between 3 Hz and 0.45 fs;
   "stationary" when the same band (within half its width or 0.75 Hz) is found in the PSD of
   each speed tercile; level: prominence (dB above the surrounding minima) and the band's
   excess rms within +-1 FWHM;
4. **low-frequency dynamics** per axis: std below 2 Hz (mean removed, zero-phase Butterworth
   order 4), moving vs standing, pooled over the drives (range over drives in brackets), and
   the moving Welch PSD (20 s segments) from 0.1 to 2 Hz fitted in log-log: one slope, and a
   two-piece fit (slope below / above a knee);
5. **broadband**: std above 2 Hz (to Nyquist) moving vs standing, and its power law in speed
   over the 4 s frames.

Sources: /work/shared/datasets (README.md there): gopro_kart (raw int16 counts scaled by the
1 g gravity magnitude measured at standstill; line constant k fitted to GPS),
hungary_car_phyphox (r = 0.31 m), comma2k19_example (phone IMU + CAN wheel speeds),
f1tenth_frictionmaps (r = 0.05 m, IMU 18-44 Hz resampled to its median rate); simulated:
``simulate("car", seed)`` and, when registered, ``simulate("random", seed)`` (truth
``omega_true``, ``wheel_radius``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: the machine is shared

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from vibrospeed import io, sim  # noqa: E402
from vibrospeed.eval import spectra_stats as ss  # noqa: E402
from vibrospeed.types import Recording  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
RESULTS = HERE / "RESULTS.md"
DATA = Path("/work/shared/datasets")
G0 = 9.80665

WIN_S, HOP_S = 4.0, 1.0  # line / floor spectra
TOL_HZ = 0.25  # least search band widening, Hz
FLOOR_HW, FLOOR_GAP = 2.0, 0.5  # floor band half-width beyond the search band, gap around it
STEADY = 0.04  # steady frame: (w_max - w_min) / w_mean below this
LF_HZ = 2.0  # low / broadband split
LF_SEG_S = 20.0  # Welch segment of the low-frequency spectrum
RES_SEG_S = 4.0  # Welch segment of the resonance search
HARM = (1, 2, 3)
SPEED_BINS = (0.0, 1.0, 2.0, 5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 40.0)
MIN_STAND_LF_S, MIN_STAND_HP_S = 10.0, 1.0  # least standing time for the standing stds

# issue 13: a real car, phone, motorway, 20-30 m/s
ISSUE = {"line": (0.09, 0.05, 0.02), "floor": 0.01, "lf_std_horizontal": (0.2, 1.5)}


# -- sources -----------------------------------------------------------------------------------
@dataclass
class Drive:
    """One recording on a uniform time line: accelerometer axes in m/s^2, speed (m/s) and the
    wheel (or line) speed omega (rad/s) per sample, NaN where unknown."""

    name: str
    fs: float
    acc: dict[str, np.ndarray]
    speed: np.ndarray
    omega: np.ndarray
    v_move: float = 1.0  # moving: speed >= v_move
    v_stand: float = 0.3  # standing: speed < v_stand
    meta: dict = field(default_factory=dict)


@dataclass
class Source:
    label: str
    drives: list[Drive]
    roles: dict[str, str]  # axis -> "long" / "lat" / "vert" / "?"
    line_visible: bool
    notes: list[str] = field(default_factory=list)
    group: str = "real"
    tol: float = 0.03  # relative half-width of the line search (speed / radius uncertainty)


def _interp(tq, t, x):
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return np.full(np.shape(tq), np.nan)
    return np.interp(tq, t[ok], x[ok], left=np.nan, right=np.nan)


def _fs(t) -> float:
    return 1.0 / float(np.median(np.diff(t)))


def _roles_by_gravity(acc: dict[str, np.ndarray], long_axis: str | None,
                      lat_axis: str | None = None) -> dict[str, str]:
    vert = max(acc, key=lambda a: abs(np.nanmean(acc[a])))
    roles = {a: "?" for a in acc}
    roles[vert] = "vert"
    if long_axis:
        roles[long_axis] = "long"
    if lat_axis:
        roles[lat_axis] = "lat"
    rest = [a for a in acc if roles[a] == "?"]
    if len(rest) == 1 and "lat" not in roles.values():
        roles[rest[0]] = "lat"
    return roles


def _corr_lp(x, y, fs, fc=0.5):
    a = ss.filtered(x, fs, hi=fc, order=2)
    b = ss.filtered(y, fs, hi=fc, order=2)
    m = np.isfinite(a) & np.isfinite(b)
    return float(np.corrcoef(a[m], b[m])[0, 1]) if m.sum() > 10 else 0.0


def kart() -> Source:
    path = DATA / "gopro_kart"
    rec = io.read(path / "GX030410_accl_raw.csv", columns="ax=c1,ay=c2,az=c3", rate=198.4)
    gps = pd.read_csv(path / "GX030410_gps_speed.csv")
    tg, vg = gps["t_video_s"].to_numpy(float), gps["gps_speed2d_mps"].to_numpy(float)
    v = _interp(rec.t, tg, vg)
    counts = np.stack([rec[c] for c in ("ax", "ay", "az")])
    stand = v < 0.3
    g_counts = float(np.linalg.norm(counts[:, stand].mean(axis=1)))
    lp = np.stack([ss.filtered(c, 198.4, hi=0.5, order=2) + np.mean(c) for c in counts])
    g_moving = float(np.median(np.linalg.norm(lp, axis=0)))
    scale = G0 / g_counts
    fs = _fs(rec.t)
    acc = {c: rec[c] * scale for c in ("ax", "ay", "az")}
    dv = np.gradient(ss.filtered(v, fs, hi=0.5, order=2), 1.0 / fs)
    corr = {a: _corr_lp(acc[a], dv, fs) for a in acc}
    vert = max(acc, key=lambda a: abs(np.mean(acc[a])))
    horiz = [a for a in acc if a != vert]
    long_axis = max(horiz, key=lambda a: abs(corr[a]))
    d = Drive("kart", fs, acc, v, np.full(v.size, np.nan), meta={"tg": tg, "vg": vg})
    k, k_info = _fit_kart_k(d)
    d.omega = k * v
    tol = 0.08
    notes = [
        f"kart: ax, ay, az = ACCL c1, c2, c3 (axis order unverified); the raw int16 counts are "
        f"scaled by the gravity magnitude at standstill (GPS < 0.3 m/s, "
        f"{stand.sum() / fs:.1f} s at the end of the video): |g| = {g_counts:.0f} counts, "
        f"so 1 count = {scale * 1e3:.3f} mm/s^2 (cross-check: the median |a| below 0.5 Hz while "
        f"driving is {g_moving:.0f} counts = {g_moving * scale / G0:.2f} g, gravity plus "
        "cornering)",
        f"axis roles: {vert} carries gravity (vertical); corr(a below 0.5 Hz, dv/dt of GPS): "
        + ", ".join(f"{a} {corr[a]:+.2f}" for a in acc)
        + f", so {long_axis} is longitudinal ({'braking' if corr[long_axis] < 0 else 'forward'}"
        " +), the other lateral",
        f"line constant k = {k:.2f} rad/m (effective radius 1/k = {1 / k:.4f} m), fitted to GPS "
        f"as the median over {k_info['n']} frames with v > 5 m/s of the order-tracked peak "
        f"(searched within +-15 % of v / 0.089) on {k_info['axis']}; halves of the drive: "
        f"{k_info['k_a']:.2f} / {k_info['k_b']:.2f}; the peak's order scatters by "
        f"{100 * k_info['iqr']:.1f} % (IQR) from frame to frame (GPS speed error, ACCL time "
        f"line spread uniformly over the video), so the kart's line is searched within "
        f"+-{100 * tol:.0f} %",
    ]
    d.meta.update(k=k, scale=scale, g_counts=g_counts)
    return Source("GoPro kart (line k v, k fitted)", [d], _roles_by_gravity(acc, long_axis),
                  True, notes, tol=tol)


def _theta(omega: np.ndarray, fs: float) -> np.ndarray:
    """Wheel angle (rad), trapezoidal integral of omega; NaN where omega is NaN."""
    w = np.nan_to_num(omega)
    th = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1])) / fs))
    return np.where(np.isfinite(omega), th, np.nan)


def _fit_kart_k(d: Drive) -> tuple[float, dict]:
    """k (rad/m) of the speed-proportional line, fitted to GPS: per moving frame with
    v > 5 m/s, the order-tracked peak within +-15 % of the line v / 0.089 on each axis; the axis
    with the highest median peak / floor; k = (1 / 0.089) * median(order of the peak)."""
    k0 = 1.0 / 0.089
    theta = _theta(k0 * d.speed, d.fs)
    best = None
    for a, x in d.acc.items():
        fr = ss.frame_spectra(x, d.fs, win_s=WIN_S, hop_s=HOP_S, fmax=0.5 * d.fs)
        vm, vlo, vhi = _frame_range(d.speed, fr)
        ok = (vlo > 5.0) & (1.15 * k0 * vhi / (2 * np.pi) < 0.95 * d.fs / 2)
        idx = np.flatnonzero(ok)
        peak, order = ss.order_peaks(x, theta, fr.start[idx], fr.n, 0.85, 1.15, pad=4)
        lo, hi = 0.85 * k0 * vlo[idx] / (2 * np.pi), 1.15 * k0 * vhi[idx] / (2 * np.pi)
        floor = ss.band_median(fr.f, fr.A[idx], lo - 2.0, hi + 2.0, exclude=[(lo, hi)])
        snr = float(np.nanmedian(peak / floor))
        kk = k0 * order
        if best is None or snr > best[0]:
            h = kk.size // 2
            q25, q75 = np.percentile(kk, [25, 75])
            best = (snr, float(np.median(kk)), {"axis": a, "n": int(kk.size), "snr": snr,
                                                "k_a": float(np.median(kk[:h])),
                                                "k_b": float(np.median(kk[h:])),
                                                "iqr": float((q75 - q25) / np.median(kk))})
    return best[1], best[2]


def hungary() -> Source:
    drives = []
    folder = DATA / "hungary_car_phyphox"
    for p in sorted(q for q in folder.iterdir() if q.is_dir()):
        rec = io.read(p, "phyphox")
        v = _interp(rec.t, rec.t, rec["gps_speed"])
        acc = {c: rec[c] for c in ("ax", "ay", "az")}
        drives.append(Drive(p.name, _fs(rec.t), acc, v, v / 0.31))
    return Source("Hungary car, phone flat (r 0.31 m)", drives,
                  {"ax": "lat", "ay": "long", "az": "vert"}, False,
                  ["Hungary: 7 phyphox drives, GPS speed (1 Hz) interpolated; wheel line "
                   "predicted at k v / (2 pi 0.31 m), searched within +-5 % (radius and GPS "
                   "uncertainty); axes as in SOURCE.md (x lateral, y forward, z up)"], tol=0.05)


def comma() -> Source:
    seg = DATA / "comma2k19_example" / "segment_40"
    can = io.read(seg, "comma2k19")
    base = seg / "processed_log" / "IMU" / "accelerometer"
    t = np.load(base / "t").astype(float) - float(can.meta["t0_boot_s"])
    a = np.load(base / "value").astype(float)
    fs = _fs(t)
    w_can = np.mean([can[c] for c in can.channels if c.startswith("wheel_omega")], axis=0)
    omega = _interp(t, can.t, w_can)
    v = _interp(t, can.t, can["speed_true"])
    acc = {"a0": a[:, 0], "a1": a[:, 1], "a2": a[:, 2]}
    dv = np.gradient(ss.filtered(v, fs, hi=0.5, order=2), 1.0 / fs)
    corr = {k: _corr_lp(x, dv, fs) for k, x in acc.items()}
    long_axis = max((k for k in acc if k != "a2"), key=lambda k: abs(corr[k]))
    return Source("comma2k19 RAV4, windshield phone (CAN omega)",
                  [Drive("segment_40", fs, acc, v, omega)],
                  _roles_by_gravity(acc, long_axis), False,
                  [f"comma2k19: phone IMU (processed_log/IMU/accelerometer, {fs:.1f} Hz, phone "
                   "axes a0..a2) read directly as benchmarks/real_recordings.py does (the reader "
                   "keeps the CAN signals); wheel line at k * mean(CAN wheel omega) / (2 pi) "
                   f"(r = {can.wheel_radius} m), searched within +-4 %; roles: a2 carries "
                   "gravity (vertical), corr(a below 0.5 Hz, dv/dt of CAN speed) "
                   + ", ".join(f"{k} {c:+.2f}" for k, c in corr.items())
                   + f", so {long_axis} is longitudinal, the other lateral"], tol=0.04)


def f1tenth() -> Source:
    drives = []
    for p in sorted(q for q in (DATA / "f1tenth_frictionmaps").glob("DS*") if q.is_dir()):
        rec = io.resample_uniform(io.read(p, "f1tenth"))
        v = np.abs(rec["speed_true"])
        drives.append(Drive(p.name, _fs(rec.t), {"ax": rec["ax"], "ay": rec["ay"]}, v,
                            v / 0.05, v_move=0.3, v_stand=0.1))
    rates = ", ".join(f"{d.name} {d.fs:.0f} Hz" for d in drives)
    return Source("F1/10 RC car (r 0.05 m)", drives, {"ax": "long", "ay": "lat"}, False,
                  [f"F1/10: IMU resampled to its median rate ({rates}); speed = |particle-"
                   "filter speed|; wheel line at k v / (2 pi 0.05 m) searched within +-8 % "
                   "(nominal radius); ax forward, ay lateral (reader), no vertical axis; moving "
                   ">= 0.3 m/s, standing < 0.1 m/s"], tol=0.08)


def simulated(scenario: str, seeds: range) -> list[Drive]:
    out = []
    for s in seeds:
        rec: Recording = sim.simulate(scenario, seed=s)
        acc = {c: rec[c] for c in ("ax", "ay", "az") if c in rec.channels}
        drawn = rec.meta.get("drawn", {})
        out.append(Drive(f"{scenario} seed {s}", _fs(rec.t), acc, rec["speed_true"],
                         rec["omega_true"], v_move=0.1, v_stand=0.01,
                         meta={"vehicle": drawn.get("vehicle", scenario), "drawn": drawn,
                               "r": rec.wheel_radius}))
    return out


# -- measurements ------------------------------------------------------------------------------
def _frame_range(x: np.ndarray, fr: ss.FrameSpectra):
    """(mean, min, max) of x over each frame (NaN if any sample is NaN)."""
    if fr.start.size == 0:
        e = np.zeros(0)
        return e, e, e
    view = np.lib.stride_tricks.sliding_window_view(x, fr.n)[fr.start]
    return view.mean(axis=1), view.min(axis=1), view.max(axis=1)


def _frame_std(y: np.ndarray, fr: ss.FrameSpectra) -> np.ndarray:
    if fr.start.size == 0:
        return np.zeros(0)
    return np.lib.stride_tricks.sliding_window_view(y, fr.n)[fr.start].std(axis=1)


class Acc:
    """Pooled sums of one statistic over drives: mean / std of samples, per-drive values."""

    def __init__(self):
        self.s = self.s2 = self.n = 0.0
        self.per = []

    def add(self, y: np.ndarray):
        y = y[np.isfinite(y)]
        if y.size >= 2:
            self.s += y.sum()
            self.s2 += (y * y).sum()
            self.n += y.size
            self.per.append(float(y.std()))

    def std(self) -> float:
        if self.n < 2:
            return float("nan")
        m = self.s / self.n
        return float(np.sqrt(max(self.s2 / self.n - m * m, 0.0)))


class PsdAcc:
    def __init__(self):
        self.f = None
        self.P = None
        self.n = 0

    def add(self, f, P, n):
        if n == 0:
            return
        if self.P is None:
            self.f, self.P, self.n = f, P * n, n
        elif f.size == self.f.size and np.allclose(f, self.f):
            self.P = self.P + P * n
            self.n += n
        else:  # another rate: interpolate onto the first frequency line
            self.P = self.P + np.interp(self.f, f, P, right=np.nan) * n
            self.n += n

    def psd(self):
        return (None, None) if self.P is None else (self.f, self.P / self.n)


def measure(src: Source) -> dict:
    """Every statistic of the module docstring for one source, per axis."""
    axes = list(src.drives[0].acc)
    moving_v = np.concatenate([d.speed[d.speed >= d.v_move] for d in src.drives])
    terc = np.nanpercentile(moving_v, [100 / 3, 200 / 3]) if moving_v.size else None
    v_terc = ([float(np.median(moving_v[(moving_v >= lo) & (moving_v < hi)]))
               for lo, hi in ((-np.inf, terc[0]), (terc[0], terc[1]), (terc[1], np.inf))]
              if terc is not None else [np.nan] * 3)
    res = {"axes": axes, "v_median": float(np.nanmedian(moving_v)) if moving_v.size else np.nan,
           "v_range": (float(np.nanmin(moving_v)), float(np.nanmax(moving_v)))
           if moving_v.size else (np.nan, np.nan),
           "fs": sorted({round(d.fs, 1) for d in src.drives}),
           "moving_s": float(sum(np.sum(d.speed >= d.v_move) / d.fs for d in src.drives)),
           "standing_s": float(sum(np.sum(d.speed < d.v_stand) / d.fs for d in src.drives)),
           "per_axis": {}, "v_terc": v_terc, "noise": _noise_ratio(src)}
    for a in axes:
        fr_rows = []
        lf_mov, lf_std, hp_mov, hp_std = Acc(), Acc(), Acc(), Acc()
        psd_lf_m, psd_res = PsdAcc(), PsdAcc()
        psd_terc = [PsdAcc(), PsdAcc(), PsdAcc()]
        for d in src.drives:
            x = d.acc[a]
            mov = d.speed >= d.v_move
            stand = d.speed < d.v_stand
            lo_sig = ss.filtered(x, d.fs, hi=LF_HZ)
            hi_sig = ss.filtered(x, d.fs, lo=LF_HZ)
            lf_mov.add(lo_sig[mov] - np.nanmean(lo_sig[mov]) if mov.any() else lo_sig[:0])
            lf_std.add(lo_sig[stand] - np.nanmean(lo_sig[stand]) if stand.sum() > 1
                       else lo_sig[:0])
            hp_mov.add(hi_sig[mov])
            hp_std.add(hi_sig[stand])
            psd_lf_m.add(*ss.welch_psd(x, d.fs, seg_s=LF_SEG_S, mask=mov))
            psd_res.add(*ss.welch_psd(x, d.fs, seg_s=RES_SEG_S, mask=mov))
            if terc is not None:
                edges = [d.v_move, terc[0], terc[1], np.inf]
                for j in range(3):
                    m = (d.speed >= edges[j]) & (d.speed < edges[j + 1])
                    psd_terc[j].add(*ss.welch_psd(x, d.fs, seg_s=RES_SEG_S, mask=m))
            fr_rows.append(_line_frames(d, x, hi_sig, src.tol))
        frames = {k: np.concatenate([r[k] for r in fr_rows]) for k in fr_rows[0]}
        stand_s = res["standing_s"]
        res["per_axis"][a] = {
            "frames": frames,
            "lf_moving": lf_mov.std(), "lf_moving_per": lf_mov.per,
            "lf_standing": lf_std.std() if stand_s >= MIN_STAND_LF_S else np.nan,
            "hp_moving": hp_mov.std(),
            "hp_standing": hp_std.std() if stand_s >= MIN_STAND_HP_S else np.nan,
            "hp_moving_per": hp_mov.per,
            "lf_psd": psd_lf_m.psd(), "lf_segments": psd_lf_m.n,
            "bands": _bands(psd_res, psd_terc, max(d.fs for d in src.drives), v_terc),
        }
        f, P = psd_lf_m.psd()
        res["per_axis"][a]["knee"] = ss.loglog_knee(f, P, 0.1, LF_HZ) if f is not None else None
    return res


def _line_frames(d: Drive, x: np.ndarray, hi_sig: np.ndarray, tol: float) -> dict:
    """Per 4 s frame: speed, steadiness, line peak (order-tracked on moving frames, plain on
    steady ones), its order, the floor per harmonic, and the std above 2 Hz."""
    nyq = d.fs / 2
    fr = ss.frame_spectra(x, d.fs, win_s=WIN_S, hop_s=HOP_S, fmax=nyq)
    vm, _, _ = _frame_range(d.speed, fr)
    wm, wlo, whi = _frame_range(d.omega, fr)
    moving = vm >= d.v_move
    rot = np.isfinite(wm) & (wm > 0)
    steady = moving & rot & ((whi - wlo) < STEADY * np.where(rot, wm, 1.0))
    theta = _theta(d.omega, d.fs)
    wm_s = np.where(rot, wm, np.nan)
    bands = {}
    for k in HARM:
        f_lo, f_hi = k * wlo / (2 * np.pi), k * whi / (2 * np.pi)
        lo = f_lo - np.maximum(tol * f_lo, TOL_HZ)
        hi = f_hi + np.maximum(tol * f_hi, TOL_HZ)
        bands[k] = (lo, hi)
    out = {"v": vm, "moving": moving, "steady": steady, "hp": _frame_std(hi_sig, fr)}
    ex = [(np.nan_to_num(bands[j][0] - FLOOR_GAP), np.nan_to_num(bands[j][1] + FLOOR_GAP))
          for j in HARM]
    for k in HARM:
        lo, hi = bands[k]
        valid = moving & rot & (lo >= 1.0) & (hi <= 0.95 * nyq)
        idx = np.flatnonzero(valid)
        half = np.maximum(tol * k, 2 * np.pi * TOL_HZ / wm_s[idx])
        pk, order = ss.order_peaks(x, theta, fr.start[idx], fr.n, k - half, k + half, pad=4)
        peak = np.full(vm.size, np.nan)
        where = np.full(vm.size, np.nan)
        peak[idx], where[idx] = pk, order
        plain = np.where(valid & steady,
                         ss.band_max(fr.f, fr.A, np.nan_to_num(lo), np.nan_to_num(hi)), np.nan)
        flo = np.maximum(np.maximum(lo - FLOOR_HW, 0.5 * lo), 1.0)
        fhi = np.minimum(hi + FLOOR_HW, 0.95 * nyq)
        floor = np.where(valid, ss.band_median(fr.f, fr.A, np.nan_to_num(flo),
                                               np.nan_to_num(fhi), exclude=ex), np.nan)
        hw = np.full(vm.size, np.nan)
        hw[idx] = half
        out[f"peak{k}"], out[f"order{k}"], out[f"half{k}"] = peak, where, hw
        out[f"plain{k}"], out[f"floor{k}"] = plain, floor
    return out


def _bands(psd: PsdAcc, terc: list[PsdAcc], fs: float, v_terc: list[float]) -> list[dict]:
    """Bands of the moving PSD; per speed tercile the nearest band within +-30 % (at least
    3 Hz). "stationary": found in >= 2 terciles, all within max(FWHM / 2, 0.75 Hz) of the
    pooled centre; "moves with speed": found in >= 2 terciles, f / v (tercile median speed)
    within 15 % of each other, f not; else "unclear" (e.g. only at the highest speeds)."""
    f, P = psd.psd()
    if f is None:
        return []
    fmax = 0.45 * fs
    found = ss.spectral_bands(f, P, 3.0, fmax, min_fwhm=0.5, smooth_hz=0.75)
    per_terc = []
    for t in terc:
        ft, Pt = t.psd()
        per_terc.append(None if ft is None or t.n < 3 else
                        ss.spectral_bands(ft, Pt, 3.0, fmax, min_prominence_db=2.0,
                                          min_fwhm=0.3, max_bands=12, smooth_hz=0.75))
    out = []
    for b in found:
        tol = max(0.5 * b.fwhm, 0.75)
        fs_t = []
        for bt in per_terc:
            near = [] if bt is None else [x.f for x in bt
                                          if abs(x.f - b.f) <= max(0.3 * b.f, 3.0)]
            fs_t.append(min(near, key=lambda q: abs(q - b.f)) if near else None)
        got = [(q, v) for q, v in zip(fs_t, v_terc, strict=True) if q is not None]
        kind = "unclear"
        if len(got) >= 2:
            fq = np.array([q for q, _ in got])
            ratio = np.array([q / v for q, v in got])
            if np.all(np.abs(fq - b.f) <= tol):
                kind = "stationary"
            elif np.ptp(ratio) < 0.15 * np.mean(ratio):
                kind = "moves with speed"
        out.append({"f": b.f, "fwhm": b.fwhm, "prom_db": b.prominence_db, "rms": b.rms,
                    "stationary": kind == "stationary", "kind": kind, "terciles": fs_t})
    return out


# -- summaries -----------------------------------------------------------------------------------
def _line_summary(frames: dict, sel: np.ndarray | None = None, plain: bool = False) -> dict:
    """Medians over the frames (order-tracked: moving frames; plain: steady frames) of the
    peak, the floor and their ratio per harmonic, and the power laws in speed."""
    base = frames["steady"] if plain else frames["moving"]
    if sel is not None:
        base = base & sel
    key = "plain" if plain else "peak"
    out = {"n": int(base.sum())}
    for k in HARM:
        p, fl, v = frames[f"{key}{k}"][base], frames[f"floor{k}"][base], frames["v"][base]
        ok = np.isfinite(p) & np.isfinite(fl)
        out[k] = {"peak": float(np.median(p[ok])) if ok.any() else np.nan,
                  "floor": float(np.median(fl[ok])) if ok.any() else np.nan,
                  "ratio": float(np.median(p[ok] / fl[ok])) if ok.any() else np.nan,
                  "n": int(ok.sum())}
        if not plain:  # where in the search band the peak lies: a line keeps it in one place
            u = (frames[f"order{k}"][base][ok] - k) / frames[f"half{k}"][base][ok]
            out[k]["spread"] = (float(np.subtract(*np.percentile(u, [75, 25]))) if ok.sum() >= 10
                                else np.nan)
        out[k]["gamma"] = ss.power_law(v[ok], p[ok])[0] if ok.sum() >= 10 else np.nan
        out[k]["floor_gamma"] = ss.power_law(v[ok], fl[ok])[0] if ok.sum() >= 10 else np.nan
        both = frames["steady"] & np.isfinite(frames[f"plain{k}"]) & np.isfinite(
            frames[f"peak{k}"])
        out[k]["tracked_over_plain"] = (float(np.median(frames[f"peak{k}"][both]
                                                        / frames[f"plain{k}"][both]))
                                        if both.sum() >= 5 else np.nan)
    return out


def _best_line_axis(res: dict) -> str:
    """The axis with the highest median peak / floor of any harmonic."""
    def score(a):
        s = _line_summary(res["per_axis"][a]["frames"])
        r = [s[k]["ratio"] for k in HARM if np.isfinite(s[k]["ratio"])]
        return max(r) if r else -1.0

    return max(res["axes"], key=score)


def _noise_ratio(src: Source) -> float:
    """Median peak / floor (k = 1) of the same estimators on white noise at the source's rate,
    typical line frequency and search tolerance: the value of a frame without a line."""
    d0 = src.drives[0]
    w = np.concatenate([d.omega[(d.speed >= d.v_move) & np.isfinite(d.omega)]
                        for d in src.drives])
    w0 = float(np.median(w)) if w.size else 2 * np.pi * 10.0
    n = int(120 * d0.fs)
    x = np.random.default_rng(0).standard_normal(n)
    d = Drive("noise", d0.fs, {"x": x}, np.full(n, 10.0), np.full(n, w0))
    fr = _line_frames(d, x, x, src.tol)
    ok = np.isfinite(fr["peak1"]) & np.isfinite(fr["floor1"])
    return float(np.median(fr["peak1"][ok] / fr["floor1"][ok])) if ok.any() else np.nan


def g3(x, nd=3) -> str:
    if x is None or not np.isfinite(x):
        return "-"
    if x == 0:
        return "0"
    return f"{x:.{nd}g}" if abs(x) >= 1e-3 else f"{x:.1e}"


def _rng(vals) -> str:
    vals = [v for v in vals if np.isfinite(v)]
    if len(vals) < 2:
        return ""
    return f" ({g3(min(vals), 2)}-{g3(max(vals), 2)})"


def _bands_text(bands: list[dict], top: int = 3) -> str:
    bs = [b for b in bands if b["kind"] == "stationary"]
    bs = sorted(bs, key=lambda b: -b["prom_db"])[:top]
    if not bs:
        return "none"
    return "; ".join(f"{b['f']:.1f} ({b['fwhm']:.1f}, {b['prom_db']:.0f} dB)"
                     for b in sorted(bs, key=lambda b: b["f"]))


def summary_row(src: Source, res: dict) -> dict:
    best = _best_line_axis(res)
    pa = res["per_axis"]
    fr = pa[best]["frames"]
    car_speed = (fr["v"] >= 20) & (fr["v"] <= 30)
    ls2030 = _line_summary(fr, car_speed) if (car_speed & fr["moving"]).sum() >= 5 else None
    horiz = [a for a in res["axes"] if src.roles.get(a) != "vert"]
    hp_fr = np.concatenate([pa[a]["frames"]["hp"][pa[a]["frames"]["moving"]] for a in horiz])
    v_fr = np.concatenate([pa[a]["frames"]["v"][pa[a]["frames"]["moving"]] for a in horiz])
    return {"best": best, "line": _line_summary(fr), "line_2030": ls2030, "horiz": horiz,
            "knees": {a: pa[a]["knee"] for a in res["axes"]},
            "hp_gamma": ss.power_law(v_fr, hp_fr)[0]}


def _axis_label(src: Source, a: str) -> str:
    r = src.roles.get(a, "?")
    return f"{a} ({r})" if r != "?" else a


def _amps(ls: dict, visible: bool, nd: int = 2) -> str:
    pre = "" if visible else "<= "
    return " / ".join(pre + g3(ls[k]["peak"], nd) if np.isfinite(ls[k]["peak"]) else "-"
                      for k in HARM)


def table_summary(rows) -> str:
    head = ("| source | fs Hz | moving / standing min | speed m/s median (range) | line search "
            "+- | line axis | line A1 / A2 / A3 m/s^2 (order-tracked, median over moving "
            "frames; <= : upper bound, no line) | A1-3 at 20-30 m/s | peak / floor k = 1..3 "
            "(white noise: k = 1) | peak position spread k = 1..3 (noise: 1) | local floor "
            "k=1 m/s^2 | A ~ v^p: p for k = 1..3 | stationary bands Hz (FWHM, prominence) | "
            "std < 2 Hz moving, horizontal axes m/s^2 (drives) | "
            "std < 2 Hz standing | PSD slope 0.1-2 Hz, horizontal | std > 2 Hz moving / "
            "standing, line axis | std > 2 Hz ~ v^p |")
    ncol = head.count("|") - 1
    out = [head, "|" + "---|" * ncol]
    iss = " / ".join(str(x) for x in ISSUE["line"])
    out.append(f"| real car, phone, motorway (issue figures) | - | - | 20-30 | - | - | {iss} | "
               f"{iss} | ~9 / 5 / 2 | - | {ISSUE['floor']} | - | - | 0.2-1.5 | - | - | - | - |")
    for src, res, sm in rows:
        pa = res["per_axis"]
        ls = sm["line"]
        vis = src.line_visible
        a2030 = "-" if sm["line_2030"] is None else _amps(sm["line_2030"], vis)
        ratio = " / ".join(g3(ls[k]["ratio"], 2) for k in HARM) + f" ({g3(res['noise'], 2)})"
        gam = " / ".join(g3(ls[k]["gamma"], 2) for k in HARM) if vis else "- (no line)"
        bands = "; ".join(f"{a}: {_bands_text(pa[a]['bands'])}" for a in res["axes"])
        lfm = ", ".join(f"{a} {g3(pa[a]['lf_moving'], 2)}{_rng(pa[a]['lf_moving_per'])}"
                        for a in sm["horiz"])
        lfs = ", ".join(f"{a} {g3(pa[a]['lf_standing'], 2)}" for a in sm["horiz"])
        slopes = ", ".join(f"{a} {g3(sm['knees'][a].slope, 2)}" if sm["knees"][a] else f"{a} -"
                           for a in sm["horiz"])
        b = sm["best"]
        hp = f"{g3(pa[b]['hp_moving'], 2)} / {g3(pa[b]['hp_standing'], 2)}"
        mv, stn = res["moving_s"] / 60, res["standing_s"] / 60
        out.append(
            f"| {src.label} | {'/'.join(f'{x:g}' for x in res['fs'])} | {mv:.1f} / {stn:.1f} | "
            f"{res['v_median']:.1f} ({res['v_range'][0]:.1f}-{res['v_range'][1]:.1f}) | "
            f"{100 * src.tol:.0f} % | {_axis_label(src, b)} | {_amps(ls, vis)} | {a2030} | "
            f"{ratio} | {' / '.join(g3(ls[k]['spread'], 2) for k in HARM)} | "
            f"{g3(ls[1]['floor'], 2)} | {gam} | {bands} | {lfm} | {lfs} | {slopes} | "
            f"{hp} | {g3(sm['hp_gamma'], 2)} |")
    return "\n".join(out)


def table_line_vs_speed(rows) -> str:
    out = ["| source | axis | speed bin m/s | moving frames | A1 / A2 / A3 order-tracked | "
           "steady frames | A1 / A2 / A3 plain (steady) | floor k = 1 / 2 / 3 | std > 2 Hz |",
           "|---|---|---|---|---|---|---|---|---|"]
    for src, res, sm in rows:
        a = sm["best"]
        fr = res["per_axis"][a]["frames"]
        for lo, hi in zip(SPEED_BINS[:-1], SPEED_BINS[1:], strict=True):
            sel = (fr["v"] >= lo) & (fr["v"] < hi)
            ls = _line_summary(fr, sel)
            if ls[1]["n"] + ls[2]["n"] + ls[3]["n"] < 5:
                continue
            lp = _line_summary(fr, sel, plain=True)
            hp = float(np.median(fr["hp"][sel & fr["moving"]]))
            out.append(f"| {src.label} | {_axis_label(src, a)} | {lo:g}-{hi:g} | {ls['n']} | "
                       f"{_amps(ls, src.line_visible)} | {lp['n']} | "
                       f"{_amps(lp, src.line_visible)} | "
                       + " / ".join(g3(ls[k]["floor"], 2) for k in HARM) + f" | {g3(hp, 2)} |")
    return "\n".join(out)


def table_line_axes(rows) -> str:
    out = ["| source | axis | moving frames | A1 / A2 / A3 order-tracked | peak / floor | "
           "peak position spread (1: uniform, as noise; << 1: a line) | "
           "p in A ~ v^p (k = 1..3) | steady frames | A1 / A2 / A3 plain (steady) | tracked / "
           "plain on steady frames (k = 1..3) | floor k=1 ~ v^p |",
           "|---|---|---|---|---|---|---|---|---|---|---|"]
    for src, res, _ in rows:
        for a in res["axes"]:
            fr = res["per_axis"][a]["frames"]
            ls, lp = _line_summary(fr), _line_summary(fr, plain=True)
            vis = src.line_visible
            out.append(f"| {src.label} | {_axis_label(src, a)} | {ls['n']} | {_amps(ls, vis)} | "
                       + " / ".join(g3(ls[k]["ratio"], 2) for k in HARM) + " | "
                       + " / ".join(g3(ls[k]["spread"], 2) for k in HARM) + " | "
                       + " / ".join(g3(ls[k]["gamma"], 2) for k in HARM)
                       + f" | {lp['n']} | {_amps(lp, vis)} | "
                       + " / ".join(g3(ls[k]["tracked_over_plain"], 3) for k in HARM)
                       + f" | {g3(ls[1]['floor_gamma'], 2)} |")
    return "\n".join(out)


def table_bands(rows) -> str:
    out = ["| source | axis | band Hz | FWHM Hz | Q | prominence dB | excess rms m/s^2 | "
           "kind (nearest band per speed tercile, Hz; tercile median speeds) |",
           "|---|---|---|---|---|---|---|---|"]
    for src, res, _ in rows:
        vt = ", ".join(f"{v:.1f}" for v in res["v_terc"])
        for a in res["axes"]:
            for b in res["per_axis"][a]["bands"]:
                ter = ", ".join("-" if q is None else f"{q:.1f}" for q in b["terciles"])
                out.append(f"| {src.label} | {_axis_label(src, a)} | {b['f']:.1f} | "
                           f"{b['fwhm']:.1f} | {b['f'] / b['fwhm']:.0f} | {b['prom_db']:.1f} | "
                           f"{g3(b['rms'], 2)} | {b['kind']} ({ter}; {vt} m/s) |")
    return "\n".join(out)


def _asd_at(psd, f0):
    f, P = psd
    if f is None:
        return np.nan
    m = (f >= f0 / 1.25) & (f <= f0 * 1.25)
    return float(np.sqrt(np.mean(P[m]))) if m.any() else np.nan


def table_lowfreq(rows) -> str:
    out = ["| source | axis | std < 2 Hz moving m/s^2 (drives) | std < 2 Hz standing | "
           "PSD slope 0.1-2 Hz | two-piece: slope below / knee Hz / slope above (fit gain) | "
           "ASD at 0.2 / 0.5 / 1 / 1.6 Hz m/s^2/sqrt(Hz) | 20 s segments |",
           "|---|---|---|---|---|---|---|---|"]
    for src, res, _ in rows:
        for a in res["axes"]:
            p = res["per_axis"][a]
            k = p["knee"]
            two = ("-" if k is None or not np.isfinite(k.slope) else
                   f"{k.slope_lo:.1f} / {k.f_knee:.2f} / {k.slope_hi:.1f} ({k.gain:.2f})")
            asd = " / ".join(g3(_asd_at(p["lf_psd"], f0), 2) for f0 in (0.2, 0.5, 1.0, 1.6))
            out.append(f"| {src.label} | {_axis_label(src, a)} | {g3(p['lf_moving'], 2)}"
                       f"{_rng(p['lf_moving_per'])} | {g3(p['lf_standing'], 2)} | "
                       f"{g3(k.slope if k else np.nan, 2)} | {two} | {asd} | "
                       f"{p['lf_segments']} |")
    return "\n".join(out)


def table_broadband(rows) -> str:
    out = ["| source | axis | std > 2 Hz moving m/s^2 (drives) | standing | moving / standing |"
           " std > 2 Hz ~ v^p: p (4 s frames) | floor k=1 ~ v^p |",
           "|---|---|---|---|---|---|---|"]
    for src, res, _ in rows:
        for a in res["axes"]:
            p = res["per_axis"][a]
            fr = p["frames"]
            pl = ss.power_law(fr["v"][fr["moving"]], fr["hp"][fr["moving"]])[0]
            ls = _line_summary(fr)
            ratio = p["hp_moving"] / p["hp_standing"] if p["hp_standing"] > 0 else np.nan
            out.append(f"| {src.label} | {_axis_label(src, a)} | {g3(p['hp_moving'], 2)}"
                       f"{_rng(p['hp_moving_per'])} | {g3(p['hp_standing'], 2)} | "
                       f"{g3(ratio, 2)} | {g3(pl, 2)} | {g3(ls[1]['floor_gamma'], 2)} |")
    return "\n".join(out)


def table_random(drives_res) -> str:
    out = ["| seed | vehicle | r m | fs Hz | speed m/s median | line axis | A1 / A2 / A3 "
           "measured | drawn harmonic_amps x largest axis gain (at omega_ref) | p (k=1) "
           "measured / gamma drawn | floor k=1 | std < 2 Hz moving x / y / z | PSD slope "
           "0.1-2 Hz x / y / z | std > 2 Hz moving / standing |", "|" + "---|" * 13]
    for d, src, res in drives_res:
        sm = summary_row(src, res)
        pa = res["per_axis"]
        ls = sm["line"]
        dr = d.meta.get("drawn", {})
        ha, gain = dr.get("harmonic_amps"), dr.get("axis_gain")
        drawn = "-" if ha is None or gain is None else " / ".join(
            g3(h * max(gain), 2) for h in ha[:3])
        b = sm["best"]
        out.append(
            f"| {d.name.split()[-1]} | {d.meta.get('vehicle')} | {d.meta.get('r', np.nan):.3f} "
            f"| {d.fs:g} | {res['v_median']:.1f} | {b} | {_amps(ls, True)} | {drawn} | "
            f"{g3(ls[1]['gamma'], 2)} / {g3(dr.get('gamma', np.nan), 2)} | "
            f"{g3(ls[1]['floor'], 2)} | "
            + " / ".join(g3(pa[a]["lf_moving"], 2) for a in res["axes"]) + " | "
            + " / ".join(g3(sm["knees"][a].slope if sm["knees"][a] else np.nan, 2)
                         for a in res["axes"])
            + f" | {g3(pa[b]['hp_moving'], 2)} / {g3(pa[b]['hp_standing'], 2)} |")
    return "\n".join(out)


def _short(label: str) -> str:
    """A short dict key for a source label."""
    for pre, key in (("GoPro", "kart"), ("Hungary", "hungary_car"), ("comma", "comma_rav4"),
                     ("F1/10", "f1tenth"), ("sim car", "sim_car")):
        if label.startswith(pre):
            return key
    if label.startswith("sim random, "):
        return "sim_random_" + label.split(", ")[1].split(" ")[0]
    return label


def key_numbers(rows) -> dict:
    """The numbers a simulator author copies: per source, per axis where it matters."""
    out = {"issue_car_phone_20_30mps": {"line_amp_k1_3": ISSUE["line"], "floor_4s": ISSUE[
        "floor"], "lf_std_horizontal": ISSUE["lf_std_horizontal"]}}

    def r3(x):
        return None if x is None or not np.isfinite(x) else float(f"{x:.3g}")

    for src, res, sm in rows:
        pa = res["per_axis"]
        ls = sm["line"]
        b = sm["best"]
        key = {"line_axis": f"{b}_{src.roles.get(b, '?')}", "v_median": r3(res["v_median"])}
        key["line_amp_k1_3" if src.line_visible else "line_upper_bound_k1_3"] = tuple(
            r3(ls[k]["peak"]) for k in HARM)
        key["peak_over_floor_k1_3"] = tuple(r3(ls[k]["ratio"]) for k in HARM)
        key["peak_over_floor_noise"] = r3(res["noise"])
        key["floor_4s_k1_3"] = tuple(r3(ls[k]["floor"]) for k in HARM)
        if src.line_visible:
            key["line_speed_exponent_k1_3"] = tuple(r3(ls[k]["gamma"]) for k in HARM)
            fr = pa[b]["frames"]
            bins = {}
            for lo, hi in zip(SPEED_BINS[:-1], SPEED_BINS[1:], strict=True):
                lb = _line_summary(fr, (fr["v"] >= lo) & (fr["v"] < hi))
                amps = tuple(r3(lb[k]["peak"]) for k in HARM)
                if lb["n"] >= 10 and any(x is not None for x in amps):
                    bins[f"{lo:g}-{hi:g}"] = amps
            key["line_amp_by_speed_bin_mps"] = bins
        key["bands_hz_fwhm_db"] = {
            f"{a}_{src.roles.get(a, '?')}": [(r3(x["f"]), r3(x["fwhm"]), r3(x["prom_db"]))
                                             for x in pa[a]["bands"] if x["kind"] == "stationary"]
            for a in res["axes"]}
        names = {a: f"{a}_{src.roles.get(a, '?')}" for a in res["axes"]}
        knees = {a: sm["knees"][a] for a in res["axes"]}
        key["lf_std_moving"] = {names[a]: r3(pa[a]["lf_moving"]) for a in names}
        if any(np.isfinite(pa[a]["lf_standing"]) for a in names):
            key["lf_std_standing"] = {names[a]: r3(pa[a]["lf_standing"]) for a in names}
        key["lf_psd_slope"] = {names[a]: r3(knees[a].slope) if knees[a] else None
                               for a in names}
        key["lf_knee_hz_slope_lo_hi"] = {
            names[a]: (r3(knees[a].f_knee), r3(knees[a].slope_lo), r3(knees[a].slope_hi))
            if knees[a] else None for a in names}
        key["hp_std_moving"] = {names[a]: r3(pa[a]["hp_moving"]) for a in names}
        key["hp_std_standing"] = {names[a]: r3(pa[a]["hp_standing"]) for a in names}
        key["hp_speed_exponent"] = r3(sm["hp_gamma"])
        if src.drives[0].meta.get("k"):
            key["k_rad_per_m"] = r3(src.drives[0].meta["k"])
            key["counts_per_g"] = r3(src.drives[0].meta["g_counts"])
        out[_short(src.label)] = key
    return out


def format_dict(d: dict) -> str:
    """``CALIBRATION = {...}``: one line per source entry (readable, copyable)."""
    lines = ["CALIBRATION = {"]
    for src, entry in d.items():
        lines.append(f"    {src!r}: {{")
        for k, v in entry.items():
            lines.append(f"        {k!r}: {v!r},")
        lines.append("    },")
    lines.append("}")
    return "\n".join(lines)


# -- main ----------------------------------------------------------------------------------------
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--car-seeds", type=int, default=5)
    ap.add_argument("--random-seeds", type=int, default=20)
    a = ap.parse_args(argv)
    t_start = time.time()
    sources: list[Source] = []
    for fn in (kart, hungary, comma, f1tenth):
        t0 = time.time()
        sources.append(fn())
        print(f"  loaded {sources[-1].label} ({time.time() - t0:.1f} s)", flush=True)
    car = simulated("car", range(a.car_seeds))
    sources.append(Source(f"sim car, seeds 0-{a.car_seeds - 1}", car,
                          {"ax": "long", "ay": "lat", "az": "vert"}, True,
                          group="sim"))
    random_note = ""
    random_drives: list[Drive] = []
    if "random" not in sim.SCENARIOS:
        random_note = ("scenario \"random\" is not registered yet (vibrospeed.sim.SCENARIOS): "
                       "its rows are skipped")
        print(f"note: {random_note}", flush=True)
    else:
        try:
            random_drives = simulated("random", range(a.random_seeds))
        except Exception as exc:  # noqa: BLE001  (the scenario is under development)
            random_note = f"scenario \"random\" failed: {type(exc).__name__}: {exc}; skipped"
            print(f"note: {random_note}", flush=True)
        by_class: dict[str, list[Drive]] = {}
        for d in random_drives:
            by_class.setdefault(d.meta["vehicle"], []).append(d)
        for cls, ds in sorted(by_class.items()):
            seeds = ", ".join(d.name.split()[-1] for d in ds)
            sources.append(Source(f"sim random, {cls} (seeds {seeds})", ds,
                                  {"ax": "long", "ay": "lat", "az": "vert"}, True,
                                  group="sim"))
    rows = []
    for src in sources:
        t0 = time.time()
        res = measure(src)
        rows.append((src, res, summary_row(src, res)))
        print(f"  measured {src.label} ({time.time() - t0:.1f} s)", flush=True)
    rand_rows = []
    for d in random_drives:
        src = Source(d.name, [d], {"ax": "long", "ay": "lat", "az": "vert"}, True)
        rand_rows.append((d, src, measure(src)))
    runtime = time.time() - t_start

    notes = [n for s in sources for n in s.notes]
    cmd = "PYTHONPATH=src .venv/bin/python benchmarks/calibration/calibration.py"
    parts = [
        "# Simulator calibration: real recordings vs simulated drives (issue 13, part 1)\n",
        f"Generated by `{cmd}` (single process, {runtime:.0f} s wall on the shared 2-core VM; "
        "do not edit by hand, rerun). Method: the docstring of "
        "`benchmarks/calibration/calibration.py`; statistics in "
        "`src/vibrospeed/eval/spectra_stats.py`. Amplitudes in m/s^2 from a 4 s Hann amplitude "
        "spectrum (`2 |X| / sum(w)`): a sinusoid of amplitude a reads a. Floor: the median of "
        "that spectrum near the line; white noise of density S (m/s^2/sqrt(Hz)) gives a floor "
        f"of {ss.floor_from_asd(1.0):.3f} S, so a floor of 0.01 m/s^2 is "
        f"{ss.asd_from_floor(0.01):.4f} m/s^2/sqrt(Hz) (std "
        f"{ss.asd_from_floor(0.01) * np.sqrt(50):.3f} m/s^2 over 0-50 Hz at 100 Hz). "
        "Axis roles: long(itudinal), lat(eral), vert(ical); simulated drives: the simulator's "
        "x, y, z (the \"random\" family may rotate its mount). Peak / floor on white noise "
        "(same estimators, rate, line frequency and search width) is given in brackets: a "
        "source near it shows no line.\n",
        "Notes:\n",
        *[f"* {n}" for n in notes],
    ]
    parts.append(f"* standing statistics need >= {MIN_STAND_LF_S:g} s of standstill below 2 Hz "
                 f"and >= {MIN_STAND_HP_S:g} s above (\"-\" otherwise); sim car: seeds "
                 f"0-{a.car_seeds - 1} of `simulate(\"car\")`")
    if random_drives:
        parts.append("* sim random: `simulate(\"random\", seed)` for seeds "
                     f"0-{a.random_seeds - 1} as registered in the working tree when this ran "
                     "(grouped by the drawn vehicle class; per seed at the end)")
    if random_note:
        parts.append(f"* {random_note}")
    parts += [
        "\n## Real vs simulated (summary)\n",
        table_summary(rows),
        "\n## Line amplitude and floor vs speed (line axis of each source)\n",
        table_line_vs_speed(rows),
        "\n## Line amplitude per axis\n",
        table_line_axes(rows),
        "\n## Spectral bands (body resonances) in the moving PSD\n",
        table_bands(rows),
        "\n## Low-frequency dynamics (below 2 Hz) per axis\n",
        table_lowfreq(rows),
        "\n## Broadband (above 2 Hz) per axis\n",
        table_broadband(rows),
    ]
    if rand_rows:
        parts += ["\n## sim random, per seed\n", table_random(rand_rows)]
    keys = key_numbers(rows)
    text = "\n".join(parts) + "\n"
    dict_text = format_dict(keys)
    text += "\n## Key numbers\n\n```python\n" + dict_text + "\n```\n"
    print(text)
    if not a.no_write:
        old = RESULTS.read_text() if RESULTS.exists() else ""
        i = old.find("## Reading")
        text += "\n" + (old[i:] if i >= 0 else "")
        RESULTS.write_text(text)
        print(f"wrote {RESULTS.relative_to(ROOT)}")
    print(f"({runtime:.0f} s wall)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
