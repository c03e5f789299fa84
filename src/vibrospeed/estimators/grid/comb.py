"""The harmonic-comb evidence of the grid method: the log-evidence of a longer window's
spectrum for the comb of M harmonics of each grid point, added to the tracker every
``comb_hop`` s.

Why a comb evidence
-------------------
The RBPMF's per-sample likelihood rewards a grid point for any power it can explain with *any*
of its harmonics, so a strong single line (an engine order, a body resonance, the 3rd wheel
harmonic) is as good as a wheel's comb: omega locks on the line, on line/2 or line/3 (the
cart at 28 rad/s = 3 x truth; the car on the engine line below ~30 rad/s). A wheel,
however, produces M harmonics whose amplitudes vary slowly together; an interfering line is one
line. The comb evidence scores that structure on the whitened spectrum of the last ``W`` s
(Hann window, 4x zero padding; background = running median over ``comb_bg`` Hz divided by
ln 2, the median of an exponential; so ``S(f) ~ Exp(1)`` where there is no line). The
background spans at least 1.5 Hann main lobes (``6 / w`` Hz for a frame of ``w`` s: a short
start-up frame's line would otherwise fill the median's window and whiten itself away;
benchmarks/trackers/RESULTS.md). Per harmonic
k, with the line modelled as a complex Gaussian of SNR ``a`` (``comb_snr``) against the
background, the log likelihood ratio "line at k omega" vs "background" is::

    l_k(omega) = S(k omega) a / (1 + a) - log(1 + a)

(S exponential with mean 1 + a vs mean 1). An *empty* harmonic costs ``log(1 + a) - S a /
(1 + a)`` > 0 nats, which is what penalises single-line hypotheses; each l_k is capped at
``comb_cap`` nats (robust likelihood: a harmonic's power beyond what a wheel comb makes is
explained by "some other source", so one strong line cannot outvote the missing companions).
A comb needs at least two harmonics (M >= 2): the best harmonic's term may exceed the second
best's by at most ``comb_lead`` nats (``l_(1) <- min(l_(1), l_(2) + comb_lead)``), so a single
line (the idling engine, a resonance) scores *below* the "no line" state, whose evidence is 0.
With ``null_model="mixture"`` (:class:`vibrospeed.estimators.rbpmf.Config`, the default here)
the time-domain data do not favour "line" over "no line" at all, so this evidence and the
switching rates alone decide ``has_signal``: at a car's standstill the engine line no longer
reads as a turning wheel (benchmarks/beyond/RESULTS.md).
Accelerating combs: over a 3 s frame a car accelerating at 8 rad/s^2 moves its 3rd harmonic by
72 rad/s, so a stationary spectrum smears the comb and peaks at the frame's *mean* frequency,
1.5 s behind the filter's present. Each frame is therefore also resampled in a warped time
``tau = s + beta s^2 / 2`` (s <= 0 the time before the frame's end) for a few relative rates
``beta = (d omega / dt) / omega`` (``comb_rates``, 1/s; computed order tracking): a comb whose
speed changes linearly, ``omega(s) = omega_e (1 + beta s)``, is a stationary comb at its
frequency ``omega_e`` at the frame's end in tau, for every omega at once. The evidence is the
average over the rates in probability, ``E = log sum_b p_b exp(E_b)`` with ``comb_rate_p0`` on
beta = 0, so a steady comb loses at most ``log p0`` and an accelerating one is scored sharp, at
its current frequency (measured: benchmarks/beyond/RESULTS.md).
Where the evidence is placed: a causal filter can only add a frame's evidence at the frame's
end (and the warps refer to that end). The forward-backward smoother (``smooth="fb"``) instead
refers each frame to its middle sample (warps about the middle, :func:`evidence` ``centre``)
and adds the evidence there, where a stationary spectrum describes the comb: a stop or a
braking is then not attributed 1.5 s late (benchmarks/beyond/RESULTS.md). The fixed-lag
smoother does the same when ``lag >= W/2`` and shrinks its blocks to ``lag - W/2`` s, so a
sample still uses data at most ``lag..2 lag - W/2`` s after it.
Aliasing is folded like the rotation model (k omega above Nyquist appears at its alias). The
grid point's evidence ``E(omega) = comb_weight * sum_k l_k(omega)`` (the "no line" state: 0)
is added to the log-weights at the end of every frame (``rbpmf.step(..., extra=E)``). The
weight ``comb_weight`` < 1 accounts for overlapping frames (hop 0.25 s, window 3 s) sharing
data. Because the time-domain evidence is also over-confident for a misspecified model
(resonances, interfering lines), it is tempered (``temper``, the coarsened likelihood
c-posterior of Miller & Dunson 2019) so the two views are balanced. Both values and the noise
levels come from the sweeps in benchmarks/beyond/RESULTS.md.

Several axes (``comb_axes``, beyond the paper): a wheel's harmonic reaches each accelerometer
axis with its own gain, and these gains wander, so one axis can lose a harmonic for a while that
another still carries. With A axes each frame's spectrum is whitened per axis and the
per-harmonic terms are summed over the axes, ``l_k = min(sum_j l_k^(j), A comb_cap)``, the lead
limit is ``A comb_lead`` and the evidence is weighted ``A ** -0.834`` (0.4 for three axes: the
axes' noise is neither independent, weight 1, nor one signal seen A times, 1 / A; chosen on the
simulated car's transient). The time-domain likelihood stays on the tracked axis (measured:
benchmarks/trackers/RESULTS.md).

``config`` and ``state`` below are the grid method's
:class:`~vibrospeed.estimators.grid.method.Config` and ``State`` (that module imports this one).
"""

from __future__ import annotations

import numpy as np
from numba import njit


def _folded(x: np.ndarray, fs: float) -> np.ndarray:
    """Apparent angular frequency of ``x`` rad/s after sampling at ``fs`` Hz (aliasing)."""
    w_s = 2 * np.pi * fs
    return np.abs((x + 0.5 * w_s) % w_s - 0.5 * w_s)


def _warp(L: int, dt: float, beta: float, centre: bool = False):
    """Linear-interpolation positions ``(i0, frac, dtau)`` that resample a frame of ``L``
    samples uniformly in the warped time ``tau = s + beta s^2 / 2``, where s is the time from
    the frame's end (``s_i = (i - L + 1) dt``) or, with ``centre``, from its middle: a line
    whose frequency changes linearly over the frame, ``omega(s) = omega_e (1 + beta s)``, has
    phase ``omega_e tau``, so in tau it is a stationary line at its frequency ``omega_e`` at
    the reference time (computed order tracking with a relative rate ``beta`` =
    (d omega / dt) / omega, 1/s)."""
    c = 0.5 * (L - 1) if centre else L - 1.0
    if beta == 0.0:
        return None, None, dt
    s_a, s_b = -c * dt, (L - 1 - c) * dt
    tau = np.linspace(s_a + 0.5 * beta * s_a * s_a, s_b + 0.5 * beta * s_b * s_b, L)
    s = (np.sqrt(np.maximum(1.0 + 2.0 * beta * tau, 0.0)) - 1.0) / beta
    pos = np.clip(s / dt + c, 0.0, L - 1.0)
    i0 = np.minimum(pos.astype(np.int64), L - 2)
    return i0, pos - i0, (tau[-1] - tau[0]) / (L - 1)


@njit(cache=True)
def _kth(a: np.ndarray, k: int) -> float:
    """The ``k``-th smallest (0-based) of ``a`` (no NaN), partly reordering ``a`` in place:
    Hoare's selection (the value is that of any exact order statistic: sorting, partition)."""
    lo = 0
    hi = a.size - 1
    while lo < hi:
        x = a[k]
        i = lo
        j = hi
        while i <= j:
            while a[i] < x:
                i += 1
            while x < a[j]:
                j -= 1
            if i <= j:
                tmp = a[i]
                a[i] = a[j]
                a[j] = tmp
                i += 1
                j -= 1
        if j < k:
            lo = i
        if k < i:
            hi = j
    return a[k]


@njit(cache=True)
def _window_medians(Pp: np.ndarray, starts: np.ndarray, width: int, out: np.ndarray) -> None:
    """``out[r, c]`` = median of ``Pp[r, starts[c] : starts[c] + width]``, as ``np.median``:
    the middle order statistic (odd ``width``), the mean ``(lo + hi) / 2`` of the two middle
    ones (even), NaN when the window holds a NaN."""
    buf = np.empty(width)
    h = width // 2
    for r in range(Pp.shape[0]):
        row = Pp[r]
        for c in range(starts.size):
            s0 = starts[c]
            nan = False
            for i in range(width):
                v = row[s0 + i]
                if v != v:
                    nan = True
                buf[i] = v
            if nan:
                out[r, c] = np.nan
                continue
            hi = _kth(buf, h)
            if width % 2 == 1:
                out[r, c] = hi
            else:  # buf[:h] now holds the h smallest: the lower middle is their maximum
                lo = buf[0]
                for i in range(1, h):
                    if buf[i] > lo:
                        lo = buf[i]
                out[r, c] = (lo + hi) / 2.0
    return


def running_median(P: np.ndarray, width: int) -> np.ndarray:
    """Running median of each row of ``P`` over ``width`` (odd) bins, edges extended
    ("nearest"), evaluated every ``max(1, width // 8)`` bins and linearly interpolated between
    (the background is smooth on that scale; ~8x cheaper than the exact filter, which it
    equals for ``width < 16``). The medians are those of ``np.median`` on each window,
    computed by a compiled selection per window (:func:`_window_medians`)."""
    P = np.asarray(P, dtype=np.float64)
    F, n = P.shape
    h = width // 2
    st = max(1, width // 8)
    Pp = np.concatenate([np.repeat(P[:, :1], h, 1), P, np.repeat(P[:, -1:], h, 1)], axis=1)
    cent = np.arange(0, n + st - 1, st)
    cent = np.minimum(cent, n - 1)
    med = np.empty((F, cent.size))
    _window_medians(np.ascontiguousarray(Pp), cent.astype(np.int64), int(width), med)
    if st == 1:
        return med
    i = np.arange(n)
    j = np.minimum(i // st, cent.size - 2)
    fr = (i - cent[j]) / np.maximum(cent[j + 1] - cent[j], 1)
    return med[:, j] * (1.0 - fr) + med[:, j + 1] * fr


def _comb_terms(config, x: np.ndarray, dt: float,
                good: np.ndarray | None = None) -> np.ndarray:
    """(M, F, N) capped per-harmonic log likelihood ratios of the (A, F, L) zero-mean frames
    of A axes sampled every ``dt`` (their tau spacing when warped); the terms of the axes
    ``good`` (A, F) (default: all) are summed per harmonic before the cap ``A_f comb_cap``,
    ``A_f`` the frame's number of good axes."""
    tr = config.tracker
    fs = 1.0 / tr.model.dt
    A, F, L = x.shape
    x = x.reshape(A * F, L)
    nfft = 1 << int(np.ceil(np.log2(4 * L)))
    P = np.abs(np.fft.rfft(x * np.hanning(L), nfft, axis=1)) ** 2
    f = 2 * np.pi * np.fft.rfftfreq(nfft, dt)
    bg_hz = config.background_hz(L)  # >= 1.5 main lobes: a line never fills the window
    medw = max(3, int(round(bg_hz / (1.0 / (dt * nfft)))) | 1)
    bg = running_median(P, medw) / np.log(2.0)
    S = P / np.maximum(bg, 1e-300 + 1e-12 * np.max(bg, axis=1, keepdims=True))
    a = config.comb_snr
    la = np.log1p(a)
    grid = tr.grid
    M = tr.model.M
    lk = np.empty((M, F, grid.size))
    for k in range(1, M + 1):
        fk = _folded(k * grid, fs)
        pos = np.interp(fk, f, np.arange(f.size))
        i0 = np.minimum(pos.astype(np.int64), f.size - 2)
        fr = pos - i0
        s = S[:, i0] * (1 - fr) + S[:, i0 + 1] * fr
        terms = (s * (a / (1 + a)) - la).reshape(A, F, grid.size)
        if A == 1:
            lk[k - 1] = np.minimum(terms[0], config.comb_cap)
        else:
            g = np.ones((A, F), bool) if good is None else good
            cap = g.sum(axis=0)[:, None] * config.comb_cap
            lk[k - 1] = np.minimum(np.where(g[:, :, None], terms, 0.0).sum(axis=0), cap)
    return lk


def frame_evidence(config, frames: np.ndarray, centre: bool = False) -> np.ndarray:
    """(F, N + 1) comb log-evidence of the (F, L) sample frames, or of the (A, F, L) frames
    of A axes (``comb_axes``), per the module docstring; NaN samples count as 0; frames with
    more than half NaN give no evidence (zeros). With several ``comb_rates`` the frame is also
    warped for each relative rate (:func:`_warp`) and the evidences are averaged over the
    rates with their prior weights (in probability: ``E = log sum_b p_b exp(E_b)``), so an
    accelerating comb scores at its *current* frequencies instead of being smeared over the
    frame."""
    tr = config.tracker
    dt = tr.model.dt
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim == 2:
        frames = frames[None]
    A, F, L = frames.shape
    N = tr.n_grid
    M = tr.model.M
    out = np.zeros((F, N + 1))
    if F == 0:
        return out
    good = np.mean(~np.isfinite(frames), axis=2) <= 0.5  # (A, F): an axis' frame is usable
    n_good = good.sum(axis=0)  # (F,) axes per frame (a dead or gappy axis drops out)
    bad = n_good == 0
    x = np.nan_to_num(frames)
    x = x - x.mean(axis=2, keepdims=True)
    rates = config.rates_in_frame(L, centre)
    logp = np.log(config.rate_prior(rates))
    lead = (n_good * config.comb_lead)[:, None]  # (F, 1)
    weight = (np.array([config.axes_weight(int(a)) for a in n_good])[:, None] if A > 1
              else None)
    E = np.empty((rates.size, F, N))
    for b, beta in enumerate(rates):
        i0, fr, dtau = _warp(L, dt, float(beta), centre)
        xb = x if i0 is None else x[:, :, i0] * (1 - fr) + x[:, :, i0 + 1] * fr
        lk = _comb_terms(config, xb, dtau, good)
        e = lk.sum(axis=0)
        if M >= 2 and np.isfinite(config.comb_lead):
            top2 = -np.partition(-lk, 1, axis=0)[:2]  # best, second best per (frame, point)
            e += np.minimum(top2[0], top2[1] + lead) - top2[0]
        E[b] = (e if A == 1 else e * weight) + logp[b]
    mx = E.max(axis=0)  # (one rate: log p = 0 and this is E[0] exactly)
    out[:, :N] = mx + np.log(np.exp(E - mx).sum(axis=0))
    out[:, :N] *= config.comb_weight
    out[bad] = 0.0
    return out


def frame_ends_at(config, g: int) -> bool:
    """Whether a frame (full or growing, :func:`_frames_of`, :func:`_growing_frames`) ends at
    the sample of global index ``g``: a one-sample step without one has no comb evidence."""
    if config.comb_weight == 0:
        return False
    L, H, L0 = config.frame_len, config.hop_len, config.min_frame_len
    if g >= L - 1:
        return (g - (L - 1)) % H == 0
    return g + 1 >= L0 and (g + 1 - L0) % H == 0


def _frames_of(config, history: np.ndarray, y: np.ndarray, count0: int):
    """Frame-end indices into ``y`` and the frames (A, F, L), given the ``L`` samples before
    ``y`` (``history`` (L, A), oldest first), ``y`` (n, A) and the number of samples seen
    before ``y``."""
    L, H = config.frame_len, config.hop_len
    n, A = y.shape
    g = count0 + np.arange(n)  # global index of each new sample
    ends = np.flatnonzero((g >= L - 1) & ((g - (L - 1)) % H == 0))
    if ends.size == 0 or config.comb_weight == 0:
        return np.zeros(0, np.int64), np.zeros((A, 0, L))
    full = np.concatenate([history, y])
    win = np.lib.stride_tricks.sliding_window_view(full, L, axis=0)  # (n + 1, A, L)
    # frame ending at y[e] covers full[e + 1 .. e + L] (history has L samples)
    return ends.astype(np.int64), np.moveaxis(win[ends + 1], 1, 0)


def _growing_frames(config, history: np.ndarray, y: np.ndarray, count0: int):
    """The growing start-up frames (``comb_min_window``): frame-end indices into ``y`` and,
    per end, the (A, 1, g + 1) frame of every sample seen up to it (global index g < L - 1)."""
    L, H = config.frame_len, config.hop_len
    L0 = config.min_frame_len
    g = count0 + np.arange(y.shape[0])
    ends = np.flatnonzero((g + 1 >= L0) & (g < L - 1) & ((g + 1 - L0) % H == 0))
    if ends.size == 0 or config.comb_weight == 0:
        return np.zeros(0, np.int64), []
    full = np.concatenate([history, y])
    # sample y[e] is full[e + L]; the g + 1 samples seen so far end there
    return ends.astype(np.int64), [full[e + L - g[e] : e + L + 1].T[:, None, :] for e in ends]


def _shrinking_frames(config, y: np.ndarray, last_end: int):
    """The recording's end, for centre-referred evidence (the mirror of the growing frames):
    every hop after the start of the last full frame (ending at ``last_end``), a frame over all
    samples to the end while at least ``comb_min_window`` s remain; returns their middle
    samples and the (A, 1, length) frames, so the last W/2 s are not left without evidence."""
    L, H = config.frame_len, config.hop_len
    L0 = config.min_frame_len
    n = y.shape[0]
    starts = np.arange(last_end - L + 1 + H, n - L0 + 1, H)
    return starts + (n - starts - 1) // 2, [y[a:].T[:, None, :] for a in starts]


def _as_signal(y: np.ndarray) -> np.ndarray:
    """(n, A) float64 view of a signal (n,) or (n, A)."""
    y = np.asarray(y, dtype=np.float64)
    return y[:, None] if y.ndim == 1 else y


def evidence(config, y: np.ndarray, state=None, *,
             centre: bool = False):
    """``(idx, values)`` comb evidence for ``y`` (n,) or, with several comb axes, (n, A)
    (indices into ``y``), continuing ``state``.

    ``centre`` (offline, whole recordings only: no ``state``): each frame's evidence refers to
    and is placed at the frame's middle sample instead of its end, which is where a stationary
    spectrum describes the comb (the forward-backward smoother uses it; a causal filter
    cannot). The last W/2 s then get shrinking frames (all samples to the end, every hop, down
    to ``comb_min_window`` s), the mirror of the growing frames at the start."""
    if centre and state is not None:
        raise ValueError("centre-referred evidence is for whole recordings (no state)")
    y = _as_signal(y)
    if state is None:  # the start: an empty (zero) history, as the method's init
        hist, count = np.zeros((config.frame_len, y.shape[1])), 0
    else:
        hist, count = _as_signal(_ordered(state)), state.count
    if hist.shape[1] != y.shape[1]:
        raise ValueError(f"the state holds {hist.shape[1]} axes, the signal {y.shape[1]}")
    idx, fr = _frames_of(config, hist, y, count)
    vals = np.zeros((0, config.tracker.n_grid + 1))
    if idx.size:
        chunk = 128  # frames per batch: bounds the spectra and median temporaries (~35 MB)
        vals = np.concatenate([frame_evidence(config, fr[:, i:i + chunk], centre)
                               for i in range(0, idx.size, chunk)])
        if centre:
            s_idx, s_fr = _shrinking_frames(config, y, int(idx[-1]))
            idx = idx - (config.frame_len - 1) // 2
            if s_idx.size:
                idx = np.concatenate([idx, s_idx])
                vals = np.concatenate([vals, *[frame_evidence(config, f, True)
                                               for f in s_fr]])
    g_idx, g_fr = _growing_frames(config, hist, y, count)
    if g_idx.size:  # all before the first full frame
        g_vals = np.concatenate([frame_evidence(config, f, centre) for f in g_fr])
        if centre:
            g_idx = g_idx - np.array([(f.shape[2] - 1) // 2 for f in g_fr], np.int64)
        idx, vals = np.concatenate([g_idx, idx]), np.concatenate([g_vals, vals])
    if centre and idx.size > 1:
        # a growing frame a few samples shorter than the first full one can share its middle
        # sample (e.g. 104.4 Hz: 312 and 313 samples); keep the first of such near-duplicates
        keep = np.r_[True, idx[1:] > np.maximum.accumulate(idx)[:-1]]
        idx, vals = idx[keep], vals[keep]
    return idx, vals


def _ordered(state) -> np.ndarray:
    L = state.buf.shape[0]
    p = state.count % L
    return np.concatenate([state.buf[p:], state.buf[:p]])
