"""The offline grid tracker over a long recording in blocks: memory bounded by a block, not by
the log.

The whole-log estimate (:func:`vibrospeed.estimators.grid.method.estimate`) keeps, per sample,
the filter's emissions (N + 1 float32), its output columns and the comb evidence: about 1.5 kB
per sample, 12 GiB for a day at 100 Hz. Here the log is cut into blocks of ``block_s`` s:

- the comb evidence is computed for the frames placed in the samples the filter is about to
  process (the same frames, batched as the whole-log pass batches them: bitwise its values);
- the forward filter runs once over the log, its state carried from block to block (exactly
  the whole-log filter: its columns ``loglik``, ``amp*`` are bitwise the whole log's);
- each block is smoothed over the block plus a look-ahead of ``lookahead_s`` s, whose
  emissions are kept as the start of the next block: the forward recursion is carried
  exactly from block to block; the backward recursion starts (beta = 1) at the end of the
  look-ahead instead of the end of the log. That is the one approximation: a sample's
  marginal ignores the data more than ``lookahead_s`` s after it (the grid chain forgets its
  start within a few seconds: random walk, jumps, "no line" switches, so two minutes change
  nothing measurable, benchmarks/scale/RESULTS.md); the last block, whose look-ahead reaches the
  log's end, is the whole-log smoother's exactly;
- each block's columns (the Track's, with the standstill and the causal columns) are handed
  out before the next block starts (:meth:`Blocks.__iter__`).

The fixed-lag smoother (``smooth="lag"``) is causal with a delay: its sub-blocks of ``L`` samples
(:func:`vibrospeed.estimators.grid.smoother.fixed_lag`) each need the data up to ``L`` samples
past their end and nothing later, so a block (a whole number of sub-blocks) is smoothed with a
look-ahead of exactly ``L`` samples, its forward recursion carried from the block before, the
same operations on the same emissions: bitwise the whole-log fixed-lag estimate, no
approximation.

The pre-filter, the scaling and the standstill detector run on the whole tracked signal
(float64 arrays of the log's length, ~70 MB per channel for 24 h at 100 Hz), as in the whole-log
estimate.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np

import vibrospeed.estimators.grid.app as _app
import vibrospeed.estimators.grid.comb as _comb
import vibrospeed.estimators.grid.frames as _frames
import vibrospeed.estimators.grid.method as _method
import vibrospeed.estimators.grid.smoother as _sm
from vibrospeed.errors import ParameterError
from vibrospeed.estimators.grid.filter import Result, concat, init, run
from vibrospeed.estimators.grid.kernel import check_grid_spacing
from vibrospeed.types import Recording, Track

#: s, samples per block (the unit of memory) and the smoother's look-ahead past each block
BLOCK_S = 600.0
LOOKAHEAD_S = 120.0
#: frames per batch of the comb evidence: the whole-log pass's (:func:`frames.evidence`)
_CHUNK = 128


class _EvidencePlan:
    """Where :func:`vibrospeed.estimators.grid.frames.evidence` (whole log, from the start) places
    each frame's evidence, and its values for a range of samples on demand: the growing frames
    at the start, the full frames (batched ``_CHUNK`` at a time from the first, as there) and,
    with ``centre``, the shrinking frames at the end, near-duplicate places dropped as there."""

    def __init__(self, config, Y: np.ndarray, centre: bool):
        self.config, self.centre = config, centre
        self.Y = np.ascontiguousarray(_frames._as_signal(Y))
        n = self.Y.shape[0]
        L, H, L0 = config.frame_len, config.hop_len, config.min_frame_len
        g = np.arange(n)
        if config.comb_weight == 0:
            ends = g_ends = np.zeros(0, np.int64)
        else:
            ends = np.flatnonzero((g >= L - 1) & ((g - (L - 1)) % H == 0))
            g_ends = np.flatnonzero((g + 1 >= L0) & (g < L - 1) & ((g + 1 - L0) % H == 0))
        self.ends = ends
        c = 1 if centre else 0  # centre: each frame's evidence at its middle sample
        idx = [g_ends - c * (g_ends // 2), ends - c * ((L - 1) // 2)]
        kind = [np.zeros(g_ends.size, np.int8), np.ones(ends.size, np.int8)]
        key = [g_ends, np.arange(ends.size)]
        if ends.size and centre:
            s0 = np.arange(ends[-1] - L + 1 + H, n - L0 + 1, H)
            idx.append(s0 + (n - s0 - 1) // 2)
            kind.append(np.full(s0.size, 2, np.int8))
            key.append(s0)
        self.idx = np.concatenate(idx).astype(np.int64)
        self.kind = np.concatenate(kind)
        self.key = np.concatenate(key).astype(np.int64)
        if centre and self.idx.size > 1:
            keep = np.r_[True, self.idx[1:] > np.maximum.accumulate(self.idx)[:-1]]
            self.idx, self.kind, self.key = self.idx[keep], self.kind[keep], self.key[keep]
        self._cache: tuple[int, np.ndarray] | None = None

    def _chunk(self, c: int) -> np.ndarray:
        if self._cache is None or self._cache[0] != c:
            e = self.ends[c * _CHUNK : (c + 1) * _CHUNK]
            L = self.config.frame_len
            win = np.lib.stride_tricks.sliding_window_view(self.Y, L, axis=0)
            fr = np.moveaxis(win[e - L + 1], 1, 0)
            self._cache = (c, _comb.frame_evidence(self.config, fr, self.centre))
        return self._cache[1]

    def rows(self, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
        """``(idx, values)`` of the evidence placed in samples ``lo <= idx < hi``."""
        a, b = np.searchsorted(self.idx, [lo, hi])
        N1 = self.config.tracker.n_grid + 1
        vals = np.zeros((b - a, N1))
        for r in range(a, b):
            k, key = self.kind[r], int(self.key[r])
            if k == 1:
                vals[r - a] = self._chunk(key // _CHUNK)[key % _CHUNK]
            elif k == 0:
                vals[r - a] = _comb.frame_evidence(self.config, self.Y[: key + 1].T[:, None, :],
                                                   self.centre)[0]
            else:
                vals[r - a] = _comb.frame_evidence(self.config, self.Y[key:].T[:, None, :],
                                                   self.centre)[0]
        return self.idx[a:b].copy(), vals


def _rows(res: Result, a: int, b: int) -> Result:
    """Rows ``a:b`` of the filter's per-sample columns (``grid_loglik`` included)."""
    return res._replace(**{f: getattr(res, f)[a:b] for f in Result._fields
                           if f != "posterior" and isinstance(getattr(res, f), np.ndarray)})


class Blocks:
    """The offline grid estimate of ``recording`` block by block (module docstring).

    Iterating yields one :class:`~vibrospeed.types.Track` per block (its rows of the log, in
    order, each with the whole-log estimate's columns and extras, ``standstill`` included);
    ``notes``, ``params``, ``level``, ``wheel_radius`` are the whole-log Track's (the notes
    are complete once the iteration has ended). :meth:`track` puts the blocks together.
    Smoothing ``fb`` (the default), ``lag`` (the fixed-lag smoother: blocks rounded to a whole
    number of its sub-blocks, its own look-ahead; exactly the whole-log estimate) or ``none``
    (the causal filter: exactly the whole-log estimate); no parameter fit. ``block_s``,
    ``lookahead_s`` (``fb`` only): default :data:`BLOCK_S`, :data:`LOOKAHEAD_S`;
    ``progress(done, total)`` is called after each block.
    """

    def __init__(self, recording: Recording, *, axis: str = "y",
                 wheel_radius: float | None = None, params: dict | None = None,
                 block_s: float | None = None, lookahead_s: float | None = None,
                 progress=None):
        block_s = BLOCK_S if block_s is None else float(block_s)
        lookahead_s = LOOKAHEAD_S if lookahead_s is None else float(lookahead_s)
        config, Y, rms, notes = _method._prepare(recording, axis, params)
        tr = config.tracker
        if tr.fit_names:
            raise ParameterError("block mode: no parameter fit (fit= needs the whole log)")
        if not (block_s > 0 and lookahead_s >= 0):
            raise ParameterError(f"block mode: block_s > 0 and lookahead_s >= 0 s, got "
                                 f"{block_s:g} and {lookahead_s:g}")
        dt = tr.model.dt
        # as the whole-log estimate (grid.method.estimate): smoothing places each frame's
        # evidence at its middle; the fixed-lag smoother then runs sub-blocks of lag - W/2 s
        half = 0.5 * config.frame_len * dt
        centre = tr.smooth == "fb" or (tr.smooth == "lag" and tr.lag >= half + dt)
        comb = {k: getattr(config, k) for k in _method._COMB}
        if tr.smooth == "lag" and centre:
            comb["lag"] = tr.lag  # the delay the user asked for, recorded as such
            config = dataclasses.replace(config, tracker=dataclasses.replace(tr,
                                                                             lag=tr.lag - half))
            notes.append(f"comb evidence placed mid-frame: fixed-lag blocks of "
                         f"{tr.lag - half:g} s (= lag - {half:g} s), each sample uses data up "
                         f"to {tr.lag:g}..{2 * tr.lag - half:g} s after it")
            tr = config.tracker
        self.recording, self.config, self.axis = recording, config, axis
        self.Y, self.rms = Y, rms
        self.y = Y if Y.ndim == 1 else np.ascontiguousarray(Y[:, 0])
        self.nb = max(1, int(round(block_s / dt)))
        self.la = max(0, int(round(lookahead_s / dt))) if tr.smooth == "fb" else 0
        #: samples per fixed-lag sub-block (0: not fixed-lag); blocks hold whole sub-blocks
        self.L = max(1, int(round(tr.lag / dt))) if tr.smooth == "lag" else 0
        if self.L:
            self.nb = max(self.L, self.nb // self.L * self.L)
            self.la = self.L
        self.progress = progress
        self.plan = _EvidencePlan(config, Y, centre=centre)
        L = config.frame_len
        if config.comb_weight > 0:
            notes.append(f"harmonic-comb evidence: {config.comb_window:g} s frames every "
                         f"{config.comb_hop:g} s, weight {config.comb_weight:g}, SNR "
                         f"{config.comb_snr:g}, cap {config.comb_cap:g} nats "
                         f"({self.plan.idx.size} frames; full {L}-sample frames, growing ones "
                         f"from {config.comb_min_window:g} s before)")
        for note in (check_grid_spacing(tr), _app.prefilter_note(tr, 1.0 / dt)):
            if note:
                notes.append(note)
        if tr.kern.B > 0:
            notes.append(f"banded kernel: B = {tr.kern.B}, discarded row mass <= "
                         f"{tr.kern.tail:.2g}")
        if tr.smooth == "fb":
            notes.append("forward-backward smoother on the grid; omega_map = the smoothed "
                         "posterior's MAP")
        elif tr.smooth == "lag":
            notes.append(f"fixed-lag smoother, lag {tr.lag:g} s (delay <= 2 lag)")
        if tr.point == "mode":
            notes.append("omega = mean of the MAP mode (point='mode'); the posterior mean is "
                         "in extras['omega_mean']")
        notes.append(f"block mode: {self.nb * dt:g} s blocks"
                     + (f", each smoothed with {self.la * dt:g} s of look-ahead"
                        if tr.smooth == "fb" else "")
                     + (", the fixed-lag smoother exactly as on the whole log" if self.L
                        else ""))
        self.notes = notes
        self.params = {**tr.to_dict(), **comb, "axis": axis}
        self.level = tr.level
        self.wheel_radius = wheel_radius or recording.wheel_radius
        self.still = self._standstill()

    def _standstill(self) -> np.ndarray:
        from vibrospeed.estimators.common import axis_channel

        rec, tr = self.recording, self.config.tracker
        fs = 1.0 / tr.model.dt
        band = (tr.omega_min, min(tr.model.M * tr.omega_max, np.pi * fs))
        ax = axis_channel(self.axis)
        chans = [ax] + [c for c in ("ax", "ay", "az")
                        if c != ax and c in rec and np.isfinite(rec.channel(c)).any()]
        # per axis (standing where every axis says so, as ss.standstill of the (n, A) array),
        # each axis in pieces: the same decision, smaller temporaries
        causal = tr.smooth != "fb"
        lag = self.params.get("lag", tr.lag) if tr.smooth == "lag" else 0.0  # the user's lag
        still = standstill(rec.channel(chans[0]), tr.model.dt, band, causal=causal, lag=lag)
        for c in chans[1:]:
            still &= standstill(rec.channel(c), tr.model.dt, band, causal=causal, lag=lag)
        self._still_chans = chans
        self._still_detector = _method.detector_name(causal, lag)
        return still

    def __len__(self) -> int:
        return int(self.y.size)

    def __iter__(self) -> Iterator[Track]:
        cfg = self.config.tracker
        n, nb, la = self.y.size, self.nb, self.la
        lw, fwd, cmn = _sm._chain(cfg)
        grid = cmn[2]
        N1 = grid.size + 1
        lw_f = lw.copy()  # forward recursion: log predicted weights before the block
        a_s, pr = np.empty(N1), np.empty(N1)
        fstate = init(cfg)
        pending: list[Result] = []  # filter rows from (block start - 1) on
        pos = 0  # next sample for the filter
        smooth = cfg.smooth == "fb"
        L = self.L  # fixed lag: sub-blocks of L samples, each smoothed with the next L
        alpha_l = np.empty((min(L, n), N1), dtype=np.float32) if L else None
        for a in range(0, n, nb):
            b = min(a + nb, n)
            e = min(b + la, n)
            if e > pos:  # filter up to the look-ahead's end, carrying its state
                idx, vals = self.plan.rows(pos, e)
                res = run(cfg, self.y[pos:e], fstate, return_grid_loglik=smooth or L > 0,
                          extra=(idx - pos, vals))
                fstate = res.final
                pending.append(res)
                pos = e
                del res
            rows = concat(pending)  # rows [a - off, e)
            pending = []  # (the pieces' arrays are freed: one copy of the rows at a time)
            off = 1 if a > 0 else 0
            blk = _rows(rows, off, off + b - a)
            omap = blk.omega_map
            sm = None
            if smooth:
                gll = _sm._emissions(rows.grid_loglik, grid.size)
                m = gll.shape[0]
                alpha = np.empty((b - a, N1), dtype=np.float32)
                _sm._forward_range(gll, off, off + b - a, lw_f, *fwd, alpha, a_s, pr)
                outs = np.zeros((m, _sm.N_OUT_FIXED))
                posts = np.zeros((0, grid.size), dtype=np.float32)
                _sm._smooth_range(alpha, off, gll, m - 1, off, off + b - a, np.ones(N1), *cmn,
                                  outs, posts, np.zeros(0, np.int64))
                sm = _sm._result(outs[off:off + b - a], None)
                omap = sm.omega_map
            elif L:  # grid.smoother.fixed_lag's sub-blocks from a, rows counted from a - off
                gll = _sm._emissions(rows.grid_loglik, grid.size)
                base = a - off
                outs = np.zeros((gll.shape[0], _sm.N_OUT_FIXED))
                posts = np.zeros((0, grid.size), dtype=np.float32)
                no_slot = np.zeros(0, np.int64)
                for s0 in range(a, b, L):
                    s1 = min(s0 + L, n)
                    _sm._forward_range(gll, s0 - base, s1 - base, lw_f, *fwd, alpha_l, a_s, pr)
                    t_end = min(s0 + 2 * L, n) - 1 - base
                    _sm._smooth_range(alpha_l, s0 - base, gll, t_end, s0 - base, s1 - base,
                                      np.ones(N1), *cmn, outs, posts, no_slot)
                sm = _sm._result(outs[off:off + b - a], None)
                omap = sm.omega_map
                del gll, outs
            (omega, std, lo, hi), extras = _app.columns(cfg, blk, sm, omap, self.rms[a:b])
            track = Track.from_omega(self.recording.t[a:b], omega, std, lo=lo, hi=hi,
                                     level=self.level, wheel_radius=self.wheel_radius,
                                     method="grid", params=self.params, extras=extras,
                                     notes=self.notes)
            _method.apply_standstill(track, self.still[a:b])
            # the rows from b - 1 on (copied: the block's arrays are freed before the next)
            last = _rows(rows, off + b - a - 1, rows.omega.size)
            pending = [last._replace(**{f: getattr(last, f).copy() for f in Result._fields
                                        if isinstance(getattr(last, f), np.ndarray)})]
            del rows, blk, last
            if smooth:
                del gll, alpha, outs
            if self.progress is not None:
                self.progress(b, n)
            yield track
        share = self.still.mean() if n else 0.0
        if self.still.any():
            self.notes.append(
                f"standstill on {100 * share:.1f} % of the samples (vibration and body motion "
                f"at their floors on {', '.join(self._still_chans)}; "
                f"{self._still_detector} detector): omega = 0 there")

    def track(self) -> Track:
        """The blocks put together in one Track (for tests and comparisons)."""
        parts = list(self)
        first = parts[0]
        cat = {f: np.concatenate([getattr(p, f) for p in parts])
               for f in ("t", "omega", "omega_std", "omega_lo", "omega_hi", "speed",
                         "speed_std", "speed_lo", "speed_hi")}
        extras = {k: np.concatenate([p.extras[k] for p in parts]) for k in first.extras}
        return dataclasses.replace(first, **cat, extras=extras, notes=list(self.notes))


# ---- the standstill detector in pieces ---------------------------------------------------------
#: frames / samples per piece of the detector below
_PIECE_FRAMES = 8192
_PIECE = 1 << 18


def _motion_level(x: np.ndarray, dt: float, ends: np.ndarray, upper_hz: float) -> np.ndarray:
    """:func:`vibrospeed.signal.standstill.motion_level` (``MOTION_FRAME_S`` frames) with its
    running sums made a piece at a time: the cumulative sums are carried from piece to piece
    (the same additions in the same order) and read only at the frames' ends and starts."""
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.signal import standstill as ss

    n = x.size
    y = pf.apply(pf.butter_sos("lowpass", upper_hz, 1.0 / dt, 2),
                 np.where(np.isfinite(x), x, np.nan))
    ok = np.isfinite(y)
    mean = np.nanmean(y) if ok.any() else None
    L = max(3, int(round(ss.MOTION_FRAME_S / dt)))
    a = np.maximum(ends + 1 - L, 0)
    e = ends + 1
    # c[j] = v[0] + ... + v[j - 1] (c[0] = 0) for the six running sums, at a and e
    at = np.zeros((6, a.size))
    et = np.zeros((6, e.size))
    carry = None
    for p0 in range(0, n, _PIECE):
        p1 = min(p0 + _PIECE, n)
        okp = ok[p0:p1]
        yp = y[p0:p1]
        y0 = np.where(okp, yp - mean if mean is not None else 0.0, 0.0)
        t0 = np.where(okp, np.arange(p0, p1, dtype=np.float64), 0.0)
        vs = (okp.astype(float), y0, y0 * y0, t0, t0 * t0, t0 * y0)
        sums = np.stack([np.cumsum(v) if carry is None else np.cumsum(np.r_[carry[i], v])[1:]
                         for i, v in enumerate(vs)])
        carry = sums[:, -1].copy()
        for idx, dest in ((a, at), (e, et)):  # c[j] for p0 < j <= p1 is sums[:, j - p0 - 1]
            lo, hi = np.searchsorted(idx, [p0 + 1, p1 + 1])
            dest[:, lo:hi] = sums[:, idx[lo:hi] - p0 - 1]
    return ss.line_residual(et, at, L)


def standstill(x: np.ndarray, dt: float, band: tuple[float, float], *,
               causal: bool = False, lag: float = 0.0) -> np.ndarray:
    """:func:`vibrospeed.signal.standstill.standstill` of one axis ``x`` (n,), the same
    decision, in bounded temporaries: the frames' broadband levels a ``_PIECE_FRAMES`` batch at
    a time (each frame's level is its own), the body-motion level by :func:`_motion_level`, the
    per-sample decision a ``_PIECE`` of samples at a time. Temporaries of about 80 bytes per
    sample at the peak instead of 120 (tracemalloc; the causal pre- and low-pass filters of the
    whole axis are what is left)."""
    from vibrospeed.signal import prefilter as pf
    from vibrospeed.signal import standstill as ss

    x = np.asarray(x, dtype=np.float64)
    n = x.size
    band = ss._band(band)
    hp, upper = ss._filters(dt, band)
    xh = pf.apply(hp, x)
    L = max(8, int(round(ss.FRAME_S / dt)))
    hop = max(1, int(round(ss.HOP_S / dt)))
    if n < L:
        return np.zeros(n, bool)
    starts = np.arange(0, n - L + 1, hop)
    ends = starts + L - 1
    level = np.concatenate([
        ss.broadband_level(xh[starts[i]: starts[min(i + _PIECE_FRAMES, starts.size) - 1] + L],
                           dt, band)[1]
        for i in range(0, starts.size, _PIECE_FRAMES)])
    del xh
    motion = None
    if upper:
        motion = _motion_level(x, dt, ss.motion_ends(ends, L, n, dt, causal=causal, lag=lag),
                               upper)
    return ss.decide(ends, level, motion, n, dt, causal=causal, lag=lag, piece=_PIECE)
