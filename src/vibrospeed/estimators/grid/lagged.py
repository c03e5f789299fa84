"""The fixed-lag smoother on a device: raw samples in, each sample's estimate ``lag`` to
``2 lag`` s later, the numbers of the batch ``estimate(..., params={"smooth": "lag"})``.

A device that may report late (a forklift's positioning that can wait 2 s, a logger that writes
with a delay) gets the smoothed tracker's accuracy and its stops without the whole log
(``docs/grid.md``: on the randomised family, lag 2 s finds 55 % of the stop time against the
causal tracker's 39 %). :class:`LaggedTracker` chains what the batch path does, one sample at a
time and in bounded memory:

1. the pre-filter, whitener and running-RMS scaling of :class:`~vibrospeed.estimators.online.
   OnlineTracker` (the same per-sample code as the batch run);
2. the comb evidence of each frame placed at the frame's middle sample (as the batch smoother
   places it, :func:`vibrospeed.estimators.grid.frames.evidence` with ``centre``; growing
   frames at the start, shrinking ones at the end), so the filter runs ``(L - 1) // 2 + 1``
   samples behind the input (L = the comb frame; the shrinking frames, known only at the
   end, land up to that far back);
3. the grid filter's step (:func:`vibrospeed.estimators.grid.filter.step`) with that evidence,
   its per-state emissions kept for one smoothing block and the next;
4. the block smoother of :func:`vibrospeed.estimators.grid.smoother.fixed_lag`: blocks of
   ``lag - W/2`` s, each smoothed once the next block's emissions are in;
5. the causal standstill detector with the same delay
   (:class:`vibrospeed.signal.standstill_stream.LagStream`) on the raw accelerometer axes;
6. the Track's columns for each sample (:func:`vibrospeed.estimators.grid.app.columns`).

A ``lag`` shorter than half a comb frame plus a sample keeps the evidence at the frame's end
(no delay) and uses blocks of ``lag``, as the batch path does.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

import vibrospeed.estimators.grid.filter as _filt
import vibrospeed.estimators.grid.smoother as _sm
import vibrospeed.estimators.grid.summary as cols
from vibrospeed.errors import ParameterError
from vibrospeed.estimators.grid.comb import frame_evidence
from vibrospeed.estimators.online import OnlineTracker
from vibrospeed.signal import standstill_stream as sst
from vibrospeed.types import Estimate

#: the per-sample extras of the batch Track that a lagged estimate carries (where they apply)
_SCALARS = (("omega_map", cols.COL_MAP), ("p_null", cols.COL_P_NULL),
            ("p_half", cols.COL_P_HALF), ("p_double", cols.COL_P_DOUBLE),
            ("p_third", cols.COL_P_THIRD), ("p_triple", cols.COL_P_TRIPLE),
            ("omega_mode", cols.COL_MODE), ("p_mode", cols.COL_P_MODE),
            ("omega_mode_std", cols.COL_MODE_STD))
_COLUMN = dict(_SCALARS)


class LaggedExtras(Mapping):
    """The extras of a :class:`LaggedTracker` Estimate, the batch Track's extras at its sample,
    read from the sample's smoothed and filtered rows when asked for (a device that reads
    ``omega`` alone builds no dict of ~25 entries per sample); ``posterior`` the sample's
    smoothed posterior row (N,) float32 where the tracker keeps them."""

    __slots__ = ("_keys", "_sm", "_row", "_rms", "_r", "_still", "_tr", "_post")

    def __init__(self, keys, sm, row, rms, r, still, tr, post=None) -> None:
        self._keys, self._sm, self._row, self._rms = keys, sm, row, rms
        self._r, self._still, self._tr, self._post = r, still, tr, post

    def __getitem__(self, key: str) -> float:
        sm, tr = self._sm, self._tr
        c = _COLUMN.get(key)
        if c is not None:
            return float(sm[c])
        if key not in self._keys:
            raise KeyError(key)
        if key == "loglik":
            return float(self._row[cols.COL_LOGLIK])
        if key == "confidence":
            return 1.0 - float(sm[cols.COL_P_NULL])
        if key == "ambiguous":
            amb = max(sm[cols.COL_P_HALF], sm[cols.COL_P_DOUBLE], sm[cols.COL_P_THIRD],
                      sm[cols.COL_P_TRIPLE])
            return 1.0 if amb >= 0.05 else 0.0
        if key == "rms":
            return self._rms
        if key == "posterior":
            return self._post
        if key == "multimodal":
            return 1.0 if sm[cols.COL_P_MODE] < tr.mode_share else 0.0
        if key == "omega_mean":
            return float(sm[cols.COL_MEAN])
        if key.startswith("amp"):
            m = int(key[3:]) - 1
            return float(self._row[cols.N_OUT_FIXED + m]) * (self._rms / tr.signal_rms)
        v = self._r * float(sm[cols.COL_LO if key == "speed_lo" else cols.COL_HI])
        return 0.0 if self._still and math.isfinite(v) else v

    def __iter__(self) -> Iterator[str]:
        return iter(self._keys)

    def __len__(self) -> int:
        return len(self._keys)

    def __contains__(self, key) -> bool:
        return key in self._keys

    def __repr__(self) -> str:
        return repr(dict(self))


class LaggedTracker(OnlineTracker):
    """Streaming fixed-lag grid tracker: :meth:`update` takes one raw sample (one per comb axis
    with several ``comb_axes``) and returns the estimates that became final, as ``(k,
    Estimate)`` pairs (k: the sample's index from 0, oldest first); :meth:`finish` returns the
    rest at the end of the recording.

    Parameters
    ----------
    config : the grid method's Config with ``smooth="lag"`` and its ``lag`` (s), e.g.
        ``grid.config_for(rec, params={"smooth": "lag", "lag": 2})``; a parameter fit
        (``fit=...``) needs the whole log and is refused.
    level, wheel_radius : as :class:`~vibrospeed.estimators.online.OnlineTracker`.
    standstill : 0: no stops (``standstill`` NaN); k: the causal standstill detector with the
        same delay on k raw accelerometer axes (the samples given to :meth:`update` and its
        ``others``); ``estimate()`` reads every accelerometer axis (give all 3 for its
        numbers).
    posterior : True: each Estimate's ``extras["posterior"]`` holds its sample's smoothed
        posterior of omega on the grid (N,) float32, the signal part, the row of
        ``estimate(..., return_posterior=True)`` (``p(omega_t = j | y_1..end of block b+1)``,
        the "no line" mass left out), e.g. for ``fuse``'s ``vib_measure="posterior"``.

    Each Estimate has the batch Track's columns at its sample: ``omega`` (the smoothed mode or
    mean, per ``point``), its std and band, ``has_signal``, ``standstill``, ``speed`` with a
    radius, and the extras (``p_null``, ``p_half``, ..., ``omega_map``, ``omega_mode``,
    ``confidence``, ``ambiguous``, ``multimodal``, ``rms``, ``loglik``, ``amp1``...).
    :attr:`max_delay` (s) is the longest wait between a sample and its estimate. The
    tracker pickles: one saved mid-stream and loaded continues with the same numbers (save
    the object: unlike :class:`~vibrospeed.estimators.online.OnlineTracker`'s, its ``state`` is
    current for the pre-filters only; the filter, smoother and stops are in its buffers).

    Examples
    --------
    >>> from vibrospeed import sim
    >>> from vibrospeed.estimators import grid
    >>> rec = sim.simulate("cart", seed=1, duration=8)
    >>> trk = LaggedTracker(grid.config_for(rec, params={"smooth": "lag", "lag": 2.0}))
    >>> out = [e for a in rec["ay"] for e in trk.update(float(a))] + trk.finish()
    >>> len(out) == len(rec) and [k for k, _ in out] == list(range(len(rec)))
    True
    """

    #: whether the estimates carry their posterior row (a class default: a tracker pickled
    #: before the option existed loads without it)
    posterior = False

    def __init__(self, config: Any, *, level=None, standstill: int = 0,
                 wheel_radius: float | None = None, posterior: bool = False) -> None:
        import vibrospeed.estimators.grid.method as _grid

        tr = getattr(config, "tracker", None)
        if tr is None or not hasattr(config, "comb_weight"):
            raise ParameterError(f"LaggedTracker: needs the grid method's Config "
                                 f"(grid.config_for(rec, params={{'smooth': 'lag'}})), got "
                                 f"{type(config).__module__}.{type(config).__name__}")
        if tr.smooth != "lag":
            raise ParameterError(f"LaggedTracker: the config's smooth must be 'lag', got "
                                 f"{tr.smooth!r} (smooth='none': OnlineTracker)")
        if tr.fit_names:
            raise ParameterError("LaggedTracker: a parameter fit (fit=...) needs the whole log; "
                                 "fit offline and pass the fitted values")
        n_axes = int(getattr(config, "n_axes", 1))
        if level is not None and np.size(level) not in (1, n_axes):
            raise ParameterError(f"LaggedTracker: level has {np.size(level)} values, the config "
                                 f"{n_axes} comb axes {tuple(config.comb_axes)}: one per axis")
        super().__init__(_grid, config, level=level, wheel_radius=wheel_radius)
        dt = tr.model.dt
        L = config.frame_len
        half = 0.5 * L * dt
        self.centre = tr.lag >= half + dt  # as grid.estimate: the evidence mid-frame
        block_lag = tr.lag - half if self.centre else tr.lag
        self.B = max(1, int(round(block_lag / dt)))  # samples per smoothing block
        # the filter's delay behind the input: a frame's middle, and one more sample for the
        # shrinking frames that finish() places at the recording's end
        self.D = (L - 1) // 2 + 1 if self.centre else 0
        self.N = tr.n_grid
        self.grid_cfg = tr
        self.comb_on = config.comb_weight != 0
        # the input history (the last L samples per axis) for the comb frames
        self._ys = np.zeros((L, self.n_axes))
        self._rms = np.full(L, np.nan)
        self._rms_last = math.nan
        self._g = 0  # samples in
        self._t = 0  # samples filtered
        self._placed = -1  # the last sample given evidence (centred: near-duplicates dropped)
        self._last_end = -1  # the last full frame's end
        self._ev: dict[int, np.ndarray] = {}
        self._fs = self.state[1].grid  # the grid method's init: the filter's prior
        N1 = self.N + 1
        self._gll = np.zeros((2 * self.B, N1), dtype=np.float32)
        self._rows: list[tuple[np.ndarray, float]] = []  # the filter's row and the rms, per sample
        self._s0 = 0  # first sample of the block being filled
        lw, self._fwd, self._common = _sm._chain(tr)
        self._lw = lw.copy()
        self._alpha = np.empty((self.B, N1), dtype=np.float32)
        self._scratch = (np.empty(N1), np.empty(N1))
        self._no_post = np.zeros((0, self.N), dtype=np.float32)
        self._no_slot = np.zeros(0, np.int64)
        self.posterior = bool(posterior)
        if self.posterior:  # a block's rows: slot t -> row t of the block's posterior array
            self._slots = np.arange(self.B, dtype=np.int64)
            self._posts: list[np.ndarray] = []  # posterior rows not yet emitted
        self._em = np.empty(N1)
        self._smoothed: list[np.ndarray] = []  # smoothed rows not yet emitted
        self._emitted = 0
        self._done = False  # finish() was called: the recording has ended
        self.n_still = int(standstill)
        self._stops: list[sst.LagStream] = []
        self._decided: list[list[bool]] = []
        if self.n_still:
            if self.n_still < self.n_axes:
                raise ValueError(f"standstill needs at least the {self.n_axes} comb axis/axes, "
                                 f"got {standstill} axes")
            band = (tr.omega_min, min(tr.model.M * tr.omega_max, math.pi / dt))
            self._stops = [sst.LagStream(dt, band, tr.lag) for _ in range(self.n_still)]
            self._decided = [[] for _ in range(self.n_still)]
        self._col_omega = cols.COL_MODE if tr.point == "mode" else cols.COL_MEAN
        self._keys = (tuple(name for name, _ in _SCALARS)
                      + ("loglik", "confidence", "ambiguous", "rms", "multimodal")
                      + (("omega_mean",) if tr.point == "mode" else ())
                      + tuple(f"amp{m + 1}" for m in range(tr.model.M))
                      + (("speed_lo", "speed_hi") if self.wheel_radius else ())
                      + (("posterior",) if self.posterior else ()))
        self.max_delay = max(2 * self.B - 1 + self.D,
                             int(np.floor(tr.lag / dt + 1e-9)) if self.n_still else 0) * dt

    # -- comb evidence at the frames' middles --------------------------------------------------
    def _frame(self, first: int, last: int) -> np.ndarray:
        """Samples ``first..last`` (global, within the last L) as (m, A), oldest first."""
        L = self._ys.shape[0]
        idx = np.arange(first, last + 1) % L
        return self._ys[idx]

    def _place(self, p: int, frame: np.ndarray) -> None:
        if self.centre and p <= self._placed:
            return  # a growing frame shares the first full frame's middle: the first is kept
        self._ev[p] = frame_evidence(self.config, frame.T[:, None, :], self.centre)[0]
        self._placed = p

    def _evidence_at(self, g: int) -> None:
        """The evidence of the frame (full or growing) that ends at sample ``g``, if any."""
        cfg = self.config
        L, H, L0 = cfg.frame_len, cfg.hop_len, cfg.min_frame_len
        if not self.comb_on:
            return
        if g >= L - 1:
            if (g - (L - 1)) % H == 0:
                self._last_end = g
                self._place(g - (L - 1) // 2 if self.centre else g, self._frame(g - L + 1, g))
        elif g + 1 >= L0 and (g + 1 - L0) % H == 0:
            self._place(g - g // 2 if self.centre else g, self._frame(0, g))

    # -- filter, smoother, output ----------------------------------------------------------
    def _filter(self, upto: int) -> None:
        """Filter the samples up to ``upto`` (exclusive), smoothing each block once the next
        one is in."""
        while self._t < upto:
            t = self._t
            y = float(self._ys[t % self._ys.shape[0], 0])
            ex = self._ev.pop(t, None)
            self._fs, est = _filt.step(self.grid_cfg, self._fs, y, extra=ex, emissions=self._em)
            self._gll[t - self._s0] = self._em
            self._rows.append((est.extras._out, float(self._rms[t % self._rms.size])))
            self._t = t + 1
            if self._t - self._s0 == 2 * self.B:
                self._smooth(2 * self.B)

    def _smooth(self, rows: int) -> None:
        """Smooth the block at the start of the emission buffer (``rows`` of it filled)."""
        n = min(self.B, rows)
        a, pr = self._scratch
        _sm._forward_range(self._gll, 0, n, self._lw, *self._fwd, self._alpha, a, pr)
        outs = np.zeros((n, _sm.N_OUT_FIXED))
        if self.posterior:  # as the batch fixed_lag's return_posterior rows
            posts, slot = np.zeros((n, self.N), dtype=np.float32), self._slots
            self._posts.extend(posts)
        else:
            posts, slot = self._no_post, self._no_slot
        _sm._smooth_range(self._alpha, 0, self._gll, rows - 1, 0, n, np.ones(self.N + 1),
                          *self._common, outs, posts, slot)
        self._smoothed.extend(outs)
        self._gll[: rows - n] = self._gll[n:rows]
        self._s0 += n

    def _estimate(self, sm: np.ndarray, row: np.ndarray, rms: float, still: bool | None,
                  post: np.ndarray | None = None) -> Estimate:
        """One sample's Estimate from its smoothed row, the filter's row, the rms and its
        posterior row (None: not kept)."""
        tr = self.grid_cfg
        r = self.wheel_radius or math.nan
        omega = float(sm[self._col_omega])
        std, lo, hi = float(sm[cols.COL_STD]), float(sm[cols.COL_LO]), float(sm[cols.COL_HI])
        vals = [omega, std, lo, hi, r * omega, r * std]
        has = (1.0 if 1.0 - sm[cols.COL_P_NULL] >= tr.claim_level else 0.0) if tr.has_null \
            else math.nan
        stand = math.nan
        if still is not None:
            stand = 1.0 if still else 0.0
            if still:
                vals = [0.0 if math.isfinite(v) else v for v in vals]
                has = 0.0 if math.isfinite(has) else has
        return Estimate(*vals, has, stand, LaggedExtras(self._keys, sm, row, rms, r, bool(still),
                                                        tr, post))

    def _emit(self) -> list[tuple[int, Estimate]]:
        """The samples whose smoothed row (and stop decision) are both in."""
        n = len(self._smoothed)
        if self.n_still:
            n = min(n, *(len(d) for d in self._decided))
        out = []
        posts = self._posts if self.posterior else None
        for i in range(n):
            still = all(d[i] for d in self._decided) if self.n_still else None
            row, rms = self._rows[i]
            out.append((self._emitted + i, self._estimate(self._smoothed[i], row, rms, still,
                                                          posts[i] if posts else None)))
        del self._smoothed[:n], self._rows[:n]
        if posts:
            del posts[:n]
        for d in self._decided:
            del d[:n]
        self._emitted += n
        return out

    def update(self, sample, others=()) -> list[tuple[int, Estimate]]:  # type: ignore[override]
        """One raw sample (one per comb axis, the tracked axis first; NaN = missing) and, with
        ``standstill`` k, the further raw accelerometer axes in ``others``; returns the
        ``(k, Estimate)`` of the samples now final, oldest first (often none). A sample of
        the wrong shape or ``others`` of the wrong count is refused before anything changes;
        an update after :meth:`finish` raises (the comb frames shrank to the old end)."""
        if self._done:
            raise RuntimeError("LaggedTracker: update() after finish(): the recording has "
                               "ended; start a new tracker for the next one")
        g = self._g
        L = self._ys.shape[0]
        one = self.n_axes == 1 and isinstance(sample, (float, int))  # one axis: no arrays
        if one:
            xs = (float(sample),)
        else:
            xs = np.asarray(sample, dtype=np.float64)
            if xs.ndim > 1 or xs.size != self.n_axes:
                raise ValueError(f"LaggedTracker: expected {self.n_axes} sample(s) per update "
                                 f"(one per comb axis), got shape {xs.shape}")
            xs = np.atleast_1d(xs)
        if self.n_still:  # checked before anything changes: a refused update leaves no trace
            raw = [*(float(x) for x in xs), *(float(x) for x in np.atleast_1d(others))]
            if len(raw) != self.n_still:
                raise ValueError(f"LaggedTracker: standstill reads {self.n_still} axes: expected "
                                 f"{self.n_still - self.n_axes} sample(s) in others, got "
                                 f"{len(raw) - self.n_axes}")
        elif len(others) if isinstance(others, (tuple, list)) else np.size(others):
            raise ValueError("LaggedTracker: others given but standstill=0 (no detector reads "
                             "them): make the tracker with standstill=k for k axes")
        if one:
            st, y, rms = self._front(self.state[0][0], xs[0])
            self.state = ((st,),) + self.state[1:]
            self._ys[g % L, 0] = y
        else:
            outs = [self._front(st, float(x)) for st, x in zip(self.state[0], xs, strict=True)]
            self.state = (tuple(o[0] for o in outs),) + self.state[1:]
            self._ys[g % L] = [o[1] for o in outs]
            rms = outs[0][2]
        if not math.isfinite(rms):
            rms = self._rms_last  # a missing sample keeps the last rms (the batch column's)
        self._rms_last = rms
        self._rms[g % L] = rms
        self._g = g + 1
        if self.n_still:
            for st, d, x in zip(self._stops, self._decided, raw, strict=True):
                d.extend(st.push(x))
        self._evidence_at(g)
        self._filter(max(self._g - self.D, 0))
        return self._emit()

    def finish(self) -> list[tuple[int, Estimate]]:
        """The estimates of the samples left at the end of the recording: the last comb frames
        shrink to its end (as the batch run's), the last blocks are smoothed up to it. A
        second call returns [] (nothing is left)."""
        if self._done:
            return []  # all given out by the first finish()
        self._done = True
        cfg = self.config
        n = self._g
        if self.centre and self.comb_on and self._last_end >= 0:
            L, H, L0 = cfg.frame_len, cfg.hop_len, cfg.min_frame_len
            for a in range(self._last_end - L + 1 + H, n - L0 + 1, H):
                self._place(a + (n - a - 1) // 2, self._frame(a, n - 1))
        self._filter(n)
        while self._t > self._s0:
            self._smooth(self._t - self._s0)
        for st, d in zip(self._stops, self._decided, strict=True):
            d.extend(st.finish())
        return self._emit()
