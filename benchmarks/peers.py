"""vibrospeed's harmonic trackers against pitch-tracking peers on the simulator (issue 3).

Run by hand (several minutes on one core; librosa and praat-parselmouth are the optional
``bench`` extra: ``.venv/bin/pip install librosa praat-parselmouth``)::

    PYTHONPATH=src .venv/bin/python benchmarks/peers.py [--seeds 15] [--rbpf-seeds 3]
        [--scenarios car,cart] [--no-write]

Writes ``benchmarks/peers/RESULTS.md`` (the whole file: method notes and the tables) unless
``--no-write``; the tables are also printed. A peer that is not installed is skipped with a
printed note.

Signals: ``vibrospeed.sim.simulate(scenario, seed=s)``, vibration axis ``ay``, truth
``omega_true``. Our trackers run through their public ``estimate()`` only (so the numbers
follow the current implementation); the peers get the same pre-filtered axis as the trackers
(``thesis-hp``: Butterworth HP order 2 at 4 rad/s) and the same search range. See
:data:`SETUP` and the text written to the doc for every mapping and setting.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

from vibrospeed import sim
from vibrospeed.estimators import get
from vibrospeed.signal import prefilter as pf

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "benchmarks" / "peers" / "RESULTS.md"

#: per scenario: params of the Bayesian trackers (as benchmarks/trackers.py), SHS, and the
#: search range [omega_min, omega_max] (rad/s) handed to every peer (= SHS's range)
SETUP = {
    "car": {
        "track": {"prefilter": "thesis-hp"},
        "grid": {},  # the product's defaults (thesis-hp, grid [10, 120] rad/s)
        "shs": {"prefilter": "thesis-hp"},
        "range": (10.0, 120.0),
    },
    "cart": {
        "track": {"prefilter": "thesis-hp", "omega_min": 2.0, "omega_max": 30.0},
        "grid": {"omega_min": 2.0, "omega_max": 30.0},
        # SHS needs one period of omega_min per 2 s batch
        "shs": {"prefilter": "thesis-hp", "omega_min": 4.0, "omega_max": 30.0},
        "range": (4.0, 30.0),
    },
}
#: rad/s: samples with omega_true above this are scored (as benchmarks/trackers/RESULTS.md)
MOVING = 5.0
AUDIO_SR = 16000.0  # Hz: the rate the peers are told the (time-compressed) data have
MIN_SAMPLES_PER_PERIOD = 16  # upsampling target at omega_max before handing data to the peers
HOP_S = 0.1  # s of real time between peer frames
SPEC_WIN_S = 2.0  # s: spectrogram-peak window (= SHS batch of 200 samples at 100 Hz)


# -- metrics ------------------------------------------------------------------------------------

def metrics(est: np.ndarray, truth: np.ndarray, lo: np.ndarray | None = None,
            hi: np.ndarray | None = None, claim: np.ndarray | None = None) -> dict[str, float]:
    """Scores over the moving samples (truth > MOVING); a NaN estimate counts as a miss.

    within: |e| < max(2 rad/s, 10 % of truth); wrong harmonic: not within, but within that
    tolerance of omega/2 or 2 omega; RMSE / median |e| over the moving samples with an estimate.
    With a band (``lo``, ``hi``): ``cover``, the share of moving samples with the truth in it.
    With ``claim`` (bool per sample: the grid tracker's ``has_signal > 0.5``, a peer's voicing):
    ``claimed`` (share of moving samples claimed), and ``within_c``, ``rmse_c``, ``cover_c``:
    the same scores over the claimed moving samples only.
    """
    mov = truth > MOVING
    fin = mov & np.isfinite(est)
    e = est - truth
    tol = np.maximum(2.0, 0.1 * truth)
    within = fin & (np.abs(e) < tol)
    harm = fin & ~within & ((np.abs(est - truth / 2) < tol) | (np.abs(est - 2 * truth) < tol))
    n = max(int(mov.sum()), 1)
    out = {
        "rmse": float(np.sqrt(np.mean(e[fin] ** 2))) if fin.any() else np.nan,
        "medae": float(np.median(np.abs(e[fin]))) if fin.any() else np.nan,
        "within": within.sum() / n,
        "harm": harm.sum() / n,
        "avail": fin.sum() / n,
    }
    inband = None
    if lo is not None and hi is not None and np.isfinite(lo[mov]).any():
        inband = mov & (lo <= truth) & (truth <= hi)
        out["cover"] = inband.sum() / n
    if claim is not None:
        c = mov & np.asarray(claim, bool)
        fc = c & fin
        nc = max(int(c.sum()), 1)
        out["claimed"] = c.sum() / n
        out["within_c"] = (within & c).sum() / nc if c.any() else np.nan
        out["rmse_c"] = float(np.sqrt(np.mean(e[fc] ** 2))) if fc.any() else np.nan
        if inband is not None:
            out["cover_c"] = (inband & c).sum() / nc if c.any() else np.nan
    return out


def claims(track) -> np.ndarray | None:
    """The grid tracker's claim "a line is there" (``extras["has_signal"] > 0.5``), else None."""
    hs = track.extras.get("has_signal") if track.extras else None
    return None if hs is None else np.asarray(hs, float) > 0.5


def to_samples(t: np.ndarray, t_frames: np.ndarray, w_frames: np.ndarray) -> np.ndarray:
    """Linear interpolation of frame estimates onto the sample times (NaN outside the frames)."""
    ok = np.isfinite(w_frames)
    if ok.sum() < 2:
        return np.full(t.size, np.nan)
    return np.interp(t, t_frames[ok], w_frames[ok], left=np.nan, right=np.nan)


# -- peers --------------------------------------------------------------------------------------

class AudioView:
    """The pre-filtered axis made "audio": upsampled by ``U`` (band-limited, polyphase) so the
    highest searched frequency has >= MIN_SAMPLES_PER_PERIOD samples per period, then declared to
    be sampled at AUDIO_SR, i.e. time is compressed by ``S = AUDIO_SR / (U fs)``:
    f_audio = S * omega / (2 pi), t_real = S * t_audio."""

    def __init__(self, y: np.ndarray, fs: float, omega_min: float, omega_max: float):
        from scipy.signal import resample_poly

        self.U = max(1, math.ceil(MIN_SAMPLES_PER_PERIOD * omega_max / (2 * np.pi * fs)))
        self.fs = fs
        self.S = AUDIO_SR / (self.U * fs)
        x = np.nan_to_num(y)
        self.x = resample_poly(x, self.U, 1) if self.U > 1 else x.copy()
        self.fmin = self.hz(omega_min)
        self.fmax = self.hz(omega_max)
        self.f_nyq = self.S * fs / 2  # the original Nyquist, in audio Hz
        self.hop = max(1, round(HOP_S * fs * self.U))  # audio samples per frame step

    def hz(self, omega: float) -> float:
        return self.S * omega / (2 * np.pi)

    def omega(self, f_audio: np.ndarray) -> np.ndarray:
        return 2 * np.pi * np.asarray(f_audio, float) / self.S

    def t_real(self, t_audio: np.ndarray) -> np.ndarray:
        return self.S * np.asarray(t_audio, float)


def peer_pyin(av: AudioView):
    """librosa.pyin on the audio view. frame_length: smallest power of two >= 2.2 periods of
    fmin (yin needs >= 2); hop HOP_S; max_transition_rate 4 octaves per second of real time
    (4 S in audio time; a car braking at 4 m/s^2 from 10 rad/s moves ~2 octaves/s, and it
    scored better than librosa's 35.92 octaves/s of audio time); fill_na=None so unvoiced
    frames keep pyin's best guess (the peer then always answers, as our trackers do); other
    settings librosa's defaults."""
    import librosa

    period = AUDIO_SR / av.fmin
    frame = 1 << math.ceil(math.log2(2.2 * period))
    f0, voiced, _ = librosa.pyin(av.x.astype(np.float64), fmin=av.fmin, fmax=av.fmax,
                                 sr=AUDIO_SR, frame_length=frame, hop_length=av.hop,
                                 max_transition_rate=4.0 * av.S, fill_na=None, center=True)
    tf = librosa.times_like(f0, sr=AUDIO_SR, hop_length=av.hop)
    return av.t_real(tf), av.omega(f0), voiced, f"frame {frame / (av.fs * av.U):.2f} s"


def _praat_frames(pitch, av: AudioView):
    f = pitch.selected_array["frequency"].astype(float)
    voiced = f > 0
    f[~voiced] = np.nan  # unvoiced: interpolated between the voiced neighbours (to_samples)
    return av.t_real(pitch.xs()), av.omega(f), voiced


def peer_praat_shs(av: AudioView):
    """Praat ``To Pitch (shs)`` (Hermes 1988 in Praat): minimum pitch = fmin (window 2 / fmin),
    ceiling = fmax, maximum frequency component = the original Nyquist, 15 subharmonics,
    compression 0.84, 48 points per octave (Praat's defaults otherwise)."""
    import parselmouth

    snd = parselmouth.Sound(av.x, sampling_frequency=AUDIO_SR)
    p = snd.to_pitch_shs(time_step=av.hop / AUDIO_SR, minimum_pitch=av.fmin,
                         maximum_frequency_component=0.98 * av.f_nyq, ceiling=av.fmax)
    t, w, v = _praat_frames(p, av)
    return t, w, v, f"window {2 / av.fmin * av.S:.2f} s"


def peer_praat_ac(av: AudioView):
    """Praat ``To Pitch (ac)`` (Boersma 1993): pitch floor = fmin (window 3 periods), ceiling =
    fmax, silence and voicing thresholds 0 (the vibration is never "silent"; every frame gets
    the best path candidate), Praat's defaults otherwise."""
    import parselmouth

    snd = parselmouth.Sound(av.x, sampling_frequency=AUDIO_SR)
    p = snd.to_pitch_ac(time_step=av.hop / AUDIO_SR, pitch_floor=av.fmin, pitch_ceiling=av.fmax,
                        silence_threshold=0.0, voicing_threshold=0.0)
    t, w, v = _praat_frames(p, av)
    return t, w, v, f"window {3 / av.fmin * av.S:.2f} s"


def spectrogram_peak(y: np.ndarray, fs: float, omega_min: float, omega_max: float,
                     win_s: float = SPEC_WIN_S, hop_s: float = HOP_S, nfft: int = 4096):
    """Plain peer: per centred Hann window of ``win_s``, the frequency of the largest magnitude in
    [omega_min, omega_max], refined by a parabola through the log-magnitudes of the 3 bins."""
    n = int(round(win_s * fs))
    hop = max(1, int(round(hop_s * fs)))
    x = np.nan_to_num(y)
    w = np.hanning(n)
    starts = np.arange(0, x.size - n + 1, hop)
    frames = np.lib.stride_tricks.sliding_window_view(x, n)[starts]
    frames = (frames - frames.mean(axis=1, keepdims=True)) * w
    mag = np.log(np.abs(np.fft.rfft(frames, nfft, axis=1)) + 1e-300)
    om = 2 * np.pi * np.fft.rfftfreq(nfft, 1 / fs)
    idx = np.flatnonzero((om >= omega_min) & (om <= omega_max))
    k = idx[np.argmax(mag[:, idx], axis=1)]
    k = np.clip(k, 1, om.size - 2)
    r = np.arange(k.size)
    a, b, c = mag[r, k - 1], mag[r, k], mag[r, k + 1]
    den = a - 2 * b + c
    d = np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, 1.0), 0.0)
    est = np.clip(om[k] + d * (om[1] - om[0]), omega_min, omega_max)
    return (starts + (n - 1) / 2) / fs, est


#: name -> (package needed, function of an AudioView returning (t_real (k,), omega (k,),
#: voiced (k,) bool, a note on the window)); frame times start at the first sample (t = 0)
PEERS = {
    "librosa pyin": ("librosa", peer_pyin),
    "Praat To Pitch (shs)": ("parselmouth", peer_praat_shs),
    "Praat To Pitch (ac)": ("parselmouth", peer_praat_ac),
}


def available_peers(quiet: bool = False) -> dict:
    """Installed peers; a printed note for each missing one (unless ``quiet``)."""
    out = {}
    for name, (mod, fn) in PEERS.items():
        if importlib.util.find_spec(mod) is None:
            if quiet:
                continue
            print(f"note: peer '{name}' skipped: python package '{mod}' is not installed "
                  f"(pip install librosa praat-parselmouth, the 'bench' extra)")
        else:
            out[name] = fn
    return out


# -- benchmark ----------------------------------------------------------------------------------

def voiced_on_samples(t: np.ndarray, t_frames: np.ndarray, voiced: np.ndarray) -> np.ndarray:
    """A peer's per-frame voicing on the sample times (linear interpolation > 0.5; False
    outside the frames)."""
    return np.interp(t, t_frames, np.asarray(voiced, float), left=0.0, right=0.0) > 0.5


def tracker_list(scen: str, seeds: int, rbpf_seeds: int, particles: int):
    """(label, method, params, seeds to run) of our trackers on ``scen``."""
    setup = SETUP[scen]
    return [
        ("RBPMF N=200", "rbpmf", setup["track"], seeds),
        (f"RBPF K={particles}", "rbpf", {**setup["track"], "n_particles": particles}, rbpf_seeds),
        ("grid (smoother, offline)", "grid", setup["grid"], seeds),
        ("grid (filter, causal)", "grid", {**setup["grid"], "smooth": "none"}, seeds),
        ("SHS (ours)", "shs", setup["shs"], seeds),
        ("EKF", "ekf", {}, seeds),
    ]


def run_scenario(scen: str, seeds: int, rbpf_seeds: int, particles: int, peers: dict):
    setup = SETUP[scen]
    wmin, wmax = setup["range"]
    rows: dict[str, list[dict]] = {}
    info: dict[str, str] = {}
    n_samples = 0

    def add(name, est, truth, dt_run, voiced=None, lo=None, hi=None, claim=None):
        m = metrics(est, truth, lo, hi, claim)
        m["time"] = dt_run
        m["voiced"] = np.nan if voiced is None else voiced
        rows.setdefault(name, []).append(m)

    trackers = tracker_list(scen, seeds, rbpf_seeds, particles)
    for seed in range(seeds):
        rec = sim.simulate(scen, seed=seed)
        truth = rec["omega_true"]
        n_samples = len(rec)
        fs = 1.0 / float(np.median(np.diff(rec.t)))
        for name, method, params, n_seeds in trackers:
            if seed >= n_seeds:
                continue
            p = {**params, "seed": seed} if method == "rbpf" else params
            try:
                mod = get(method)
                t0 = time.process_time()
                tr = mod.estimate(rec, axis="y", params=p)
                el = time.process_time() - t0
                c = claims(tr)
                add(name, tr.omega, truth, el, None if c is None else float(np.mean(c)),
                    tr.omega_lo, tr.omega_hi, c)
            except Exception as exc:  # noqa: BLE001 - a tracker under change must not stop the run
                print(f"  {scen} seed {seed}: {name} failed: {type(exc).__name__}: {exc}")
        # peers: the same pre-filtered axis as the trackers
        x = rec["ay"]
        head = x[: int(fs)][np.isfinite(x[: int(fs)])]
        level = float(np.mean(head)) if head.size else None
        y = pf.apply(pf.design("thesis-hp", fs), x, level=level)
        t0 = time.process_time()
        tf, wf = spectrogram_peak(y, fs, wmin, wmax)
        add("spectrogram peak", to_samples(rec.t, tf, wf), truth, time.process_time() - t0)
        av = AudioView(y, fs, wmin, wmax)
        info["audio"] = (f"U = {av.U} (upsampled to {av.U * fs:g} Hz), declared rate "
                         f"{AUDIO_SR:g} Hz, time compression S = {av.S:.4g}: "
                         f"[{wmin:g}, {wmax:g}] rad/s -> [{av.fmin:.1f}, {av.fmax:.1f}] Hz; "
                         f"hop {av.hop} samples = {HOP_S} s real")
        for name, fn in peers.items():
            try:
                t0 = time.process_time()
                tf, wf, voiced, what = fn(av)
                el = time.process_time() - t0
                info[name] = what
                add(name, to_samples(rec.t, tf, wf), truth, el, float(np.mean(voiced)),
                    claim=voiced_on_samples(rec.t, tf, voiced))
            except Exception as exc:  # noqa: BLE001
                print(f"  {scen} seed {seed}: {name} failed: {type(exc).__name__}: {exc}")
        print(f"  {scen} seed {seed} done", flush=True)
    return rows, info, n_samples


def _pct(rs: list[dict], key: str) -> str:
    v = np.array([r.get(key, np.nan) for r in rs], float)
    return f"{100 * np.nanmean(v):.1f}" if np.isfinite(v).any() else "-"


def table(rows: dict[str, list[dict]], n_samples: int) -> str:
    out = ["| method | runs | RMSE median (best / worst) rad/s | median abs err rad/s | "
           "within max(2, 10 %) % | wrong harmonic % | claims signal (voiced) % | "
           "within where claimed % | RMSE where claimed (median) | 98 % band covers truth % "
           "(where claimed) | CPU s/run | samples/s |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, rs in rows.items():
        rm = np.array([r["rmse"] for r in rs])
        tm = float(np.mean([r["time"] for r in rs]))
        rc = np.array([r.get("rmse_c", np.nan) for r in rs], float)
        rctxt = f"{np.nanmedian(rc):.2f}" if np.isfinite(rc).any() else "-"
        cov = _pct(rs, "cover")
        if cov != "-" and _pct(rs, "cover_c") != "-":
            cov += f" ({_pct(rs, 'cover_c')})"
        out.append(
            f"| {name} | {len(rs)} | {np.nanmedian(rm):.2f} ({np.nanmin(rm):.2f} / "
            f"{np.nanmax(rm):.2f}) | {np.nanmedian([r['medae'] for r in rs]):.2f} | "
            f"{100 * np.mean([r['within'] for r in rs]):.1f} | "
            f"{100 * np.mean([r['harm'] for r in rs]):.1f} | {_pct(rs, 'claimed')} | "
            f"{_pct(rs, 'within_c')} | {rctxt} | {cov} | {tm:.3f} | "
            f"{n_samples / tm if tm > 0 else float('inf'):,.0f} |")
    return "\n".join(out)


INTRO = """# Harmonic trackers vs pitch-tracking peers (simulator)

Generated by `PYTHONPATH=src .venv/bin/python benchmarks/peers.py` (do not edit by hand; rerun).
{versions}

## Setup

* Signals: `vibrospeed.sim.simulate("car" | "cart", seed=s)`, s = 0 .. {last}; the vibration axis
  `ay` (100 Hz); truth `omega_true`. Scored over the moving samples (truth > {moving:g} rad/s,
  as benchmarks/trackers/RESULTS.md).
* Metrics per run: RMSE and median |error| over the moving samples that have an estimate;
  "within": share of moving samples with |error| < max(2 rad/s, 10 % of truth); "wrong
  harmonic": share outside that tolerance but within it of omega/2 or 2 omega; "98 % band
  covers truth": share of moving samples with the truth inside the tracker's band (trackers
  with a band). "Claims signal": for the grid tracker (and any tracker reporting it) the share
  of moving samples with `extras["has_signal"] > 0.5`; for pyin and Praat the share of moving
  samples whose nearest frames are voiced (frame voicing interpolated > 0.5). "Where claimed":
  within, RMSE and band coverage over those samples only (the honest reading of a tracker that
  says "no line here"); the all-moving-time columns count every sample. Unvoiced frames are
  not dropped from the all-time scores: pyin keeps its best guess, Praat frames are
  interpolated between voiced neighbours; a sample without any estimate counts as a miss.
  Table: median RMSE over the runs (best / worst run), median of the medians, means of the
  shares, mean CPU time per run (`time.process_time`, one process on a shared 2-core VM).
* Ours through the public `get(name).estimate()`: RBPMF and RBPF with the paper's Table I
  defaults and the `thesis-hp` pre-filter (car: grid [10, 120] rad/s; cart: [2, 30]); RBPF with
  3000 particles on the first {rbpf} seeds only (about 40 s per car run); **grid** (the product,
  `vibrospeed estimate -m grid`: improved RBPMF + harmonic-comb evidence, its own defaults,
  cart grid [2, 30]) twice: smoothed (its default, **offline**, forward-backward over the
  whole recording) and `smooth=none` (the causal filter); SHS (ours, batch 200 = 2 s) with
  range car [10, 120], cart [4, 30]; EKF with its defaults (started from its default omega0).
  RBPMF, RBPF, grid (filter), SHS and EKF are **causal filters** (the estimate at t uses data
  up to t; SHS one 2 s batch).
* Peers get the same input: `ay` through the same `thesis-hp` pre-filter, and the same search
  range as our SHS (car [10, 120] rad/s, cart [4, 30] rad/s). They are **non-causal** (centred
  windows; pyin's HMM and Praat's path finder run Viterbi over the whole recording), which is an
  advantage for them.
* Making the data "audio" for pyin and Praat: vibration frequencies of 0.6..19 Hz at 100 Hz
  leave 5 samples per period at omega_max, far from what pitch trackers are built for. The
  pre-filtered signal is (1) upsampled by an integer U with `scipy.signal.resample_poly`
  (band-limited; adds no information) so that omega_max has >= {mspp} samples per period, then
  (2) declared to be sampled at {sr:g} Hz, i.e. time is compressed by S = {sr:g} / (U fs);
  every frequency is multiplied by S, every duration divided by S. Frequencies and frame times
  are mapped back (omega = 2 pi f / S, t = S t_audio) and linearly interpolated onto the 100 Hz
  sample times. Frames every {hop} s of real time.
{audio}
* Peer settings (best reasonable, from the wheel range):
  - librosa `pyin`: fmin/fmax = the mapped range; frame_length the smallest power of two
    >= 2.2 periods of fmin ({pyin}); `fill_na=None`; librosa's other defaults (beta prior,
    100 thresholds, switch probability 0.01) except the maximum transition rate: 4 octaves per
    second of real time (4 S in audio time; librosa's 35.92 octaves/s of audio time scored
    slightly worse on both scenarios).
  - Praat `To Pitch (shs)` (Hermes 1988, via parselmouth): minimum pitch = mapped omega_min
    (Praat's window is 2 / minimum pitch: {shs}), ceiling = mapped omega_max, maximum
    frequency component = the original Nyquist mapped (x 0.98), 15 subharmonics, compression
    0.84, 48 points/octave.
  - Praat `To Pitch (ac)` (Boersma 1993): pitch floor / ceiling = the mapped range (window 3
    periods of the floor: {ac}), silence and voicing thresholds 0 (every frame voiced), other
    costs Praat's defaults.
  - Spectrogram peak (ours, plain): centred Hann window of {spec:g} s (the SHS batch), FFT 4096,
    argmax of the magnitude in the range, parabolic refinement on log magnitude.
"""


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=15)
    ap.add_argument("--rbpf-seeds", type=int, default=3)
    ap.add_argument("--particles", type=int, default=3000)
    ap.add_argument("--scenarios", default="car,cart")
    ap.add_argument("--no-write", action="store_true",
                    help="print only, leave benchmarks/peers/RESULTS.md")
    a = ap.parse_args(argv)
    peers = available_peers()
    versions = [f"Python {platform.python_version()}, numpy {np.__version__}"]
    for mod in ("librosa", "parselmouth"):
        if importlib.util.find_spec(mod) is not None:
            m = __import__(mod)
            versions.append(f"{mod} {m.__version__}")
        else:
            versions.append(f"{mod} not installed (skipped)")
    body = []
    infos = {}
    for scen in a.scenarios.split(","):
        t0 = time.time()
        rows, info, n = run_scenario(scen, a.seeds, a.rbpf_seeds, a.particles, peers)
        infos[scen] = info
        lo, hi = SETUP[scen]["range"]
        body.append(f"## {scen}: {a.seeds} seeds, {n} samples ({n / 100:g} s) each, "
                    f"range [{lo:g}, {hi:g}] rad/s\n\n{table(rows, n)}\n")
        print(body[-1], flush=True)
        print(f"({scen}: {time.time() - t0:.0f} s wall)")
    car = infos.get("car") or next(iter(infos.values()))
    audio = "\n".join(f"  - {s}: {i['audio']}" for s, i in infos.items() if "audio" in i)
    text = INTRO.format(
        versions="; ".join(versions), last=a.seeds - 1, moving=MOVING, rbpf=a.rbpf_seeds,
        mspp=MIN_SAMPLES_PER_PERIOD, sr=AUDIO_SR, hop=HOP_S, audio=audio,
        pyin="; ".join(f"{s}: {i.get('librosa pyin', '-')}" for s, i in infos.items()),
        shs="; ".join(f"{s}: {i.get('Praat To Pitch (shs)', '-')}" for s, i in infos.items()),
        ac="; ".join(f"{s}: {i.get('Praat To Pitch (ac)', '-')}" for s, i in infos.items()),
        spec=SPEC_WIN_S,
    )
    del car
    text += "\n## Results\n\n" + "\n".join(body) + "\n" + READING
    if not a.no_write:
        DOC.write_text(text)
        print(f"wrote {DOC.relative_to(ROOT)}")


READING = """## Reading

(Written by hand after the last run; the tables above are regenerated, this text is not. The
grid tracker and the RBPMF were being changed while this ran (src/ edits at 05:56 and 06:03
on the day of the run): the grid rows are that day's state, benchmarks/trackers/RESULTS.md has a
later run.)

* **Car** (engine-order line, body resonances, amplitudes growing with speed): the smoothed
  **grid** tracker is ahead of every peer and of our other trackers: 74.6 % of the moving time
  within max(2 rad/s, 10 %) (RBPMF 72.8, spectrogram peak 71.0, Praat ac 62.6, pyin 51.6,
  Praat shs 40.9), median RMSE 19.6 rad/s (the lowest; best peer Praat ac 34.4), 1.0 % wrong
  harmonic. Where it claims a signal (57 % of the moving time) it is within tolerance 96.0 % of
  the time (RMSE 5.8 rad/s), against pyin 82.5 % and Praat shs 57.5 % where they call voiced,
  and its 98 % band covers the truth 97 % of the time (RBPMF 60 %). The causal grid filter
  (59.7 % within overall, 84.3 % where claimed) is behind the RBPMF over all moving time but
  ahead of every peer where it claims a signal. Median RMSEs are large for everyone because
  every method follows the engine line at low speed (benchmarks/trackers/RESULTS.md).
* **Cart** (one clean wheel line at ~10 rad/s): the grid tracker closes the gap of the paper's
  RBPMF (87.0 % within, 9 % wrong harmonic) to the peers but is **not clearly ahead of each**:
  smoothed 97.2 % within (Praat shs 97.1, pyin 96.3, Praat ac 94.7), RMSE 0.65 rad/s (Praat shs
  0.45 and Praat ac 0.60 are lower, pyin 0.77 higher), median error 0.13 vs 0.05-0.06 for the
  peers; where claimed 98.4 % (Praat shs where voiced 99.4 %). The causal grid filter: 95.5 %,
  RMSE 0.94, 98.3 % where claimed. Issue 3's "ahead of each peer on accuracy": **met on the car,
  on the cart only on the within-tolerance share (by 0.1 point over Praat shs), not on RMSE**.
* RBPF (3000 particles, 3 seeds): worse than the RBPMF on both, the paper's omega/2 failure
  mode (29 % wrong harmonic on the cart) and 30-40x slower.
* Speed (CPU time, two benchmarks sharing the 2-core VM): our SHS and EKF run at ~1 M
  samples/s, Praat at 0.1-0.6 M, the RBPMF at 18-21 k samples/s, grid at 8-14 k (smoothed /
  causal), pyin at 6-12 k samples/s.
"""


if __name__ == "__main__":
    sys.exit(main())
