"""Where the comb evidence's frames lie in a recording, and the walkers that cut them:
:func:`evidence` over a whole signal (or continuing a stream's state), :func:`step_evidence`
for one sample of a stream, :func:`frame_ends_at` to know whether a frame ends at a sample.
Each frame's spectrum and its evidence are :func:`vibrospeed.estimators.grid.comb.frame_evidence`.

Frames of ``frame_len`` samples end every ``hop_len`` samples. Before ``frame_len`` samples
have been seen, *growing* frames (every sample so far, from ``comb_min_window`` s) give the
start its evidence; with ``centre`` (whole recordings, the smoother) each frame's evidence is
placed at its middle sample, and *shrinking* frames (every sample to the end) the mirror of
the growing ones, give the last W/2 s theirs.
"""

from __future__ import annotations

import numpy as np

from vibrospeed.estimators.grid.comb import frame_evidence, ring_evidence


def _frame_plan(config) -> tuple[int, int, int, bool]:
    """``(frame_len, hop_len, min_frame_len, comb on)`` of ``config``, kept with it."""
    plan = config.__dict__.get("_frame_plan")
    if plan is None:
        plan = config.__dict__["_frame_plan"] = (config.frame_len, config.hop_len,
                                                 config.min_frame_len, config.comb_weight != 0)
    return plan


def frame_ends_at(config, g: int) -> bool:
    """Whether a frame (full or growing, :func:`_frames_of`, :func:`_growing_frames`) ends at
    the sample of global index ``g``: a one-sample step without one has no comb evidence."""
    L, H, L0, on = _frame_plan(config)
    if not on:
        return False
    if g >= L - 1:
        return (g - (L - 1)) % H == 0
    return g + 1 >= L0 and (g + 1 - L0) % H == 0


def step_evidence(config, buf: np.ndarray, count: int, y: np.ndarray) -> np.ndarray | None:
    """The (N + 1,) comb evidence at the sample ``y`` ((A,), one value per axis) that follows
    ``count`` samples whose last ``L`` are in the ring buffer ``buf`` ((L,) or (L, A), oldest
    at ``count % L``), or None where no frame ends there: what :func:`evidence` gives for this
    one sample (the same frame, its samples laid out in memory as there, so that the frame's
    mean is summed in the same order), without its batch machinery; one axis is read from the
    ring in place (:func:`~vibrospeed.estimators.grid.comb.ring_evidence`)."""
    if not frame_ends_at(config, count):
        return None
    L = buf.shape[0]
    m = min(count, L - 1)  # samples before y in the frame (full: L - 1; growing: all seen)
    p = (count - m) % L  # the oldest of them
    if buf.ndim == 1:  # one axis: read in place from the ring
        return ring_evidence(config, buf, p, m, float(y[0]))
    hist = buf
    full = np.empty((m + 1, hist.shape[1]))
    k = min(m, L - p)
    full[:k] = hist[p : p + k]
    full[k:m] = hist[: m - k]
    full[m] = y
    return frame_evidence(config, full.T[:, None, :])[0]


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
