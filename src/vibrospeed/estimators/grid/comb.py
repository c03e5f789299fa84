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
refers each frame to its middle sample (warps about the middle;
:func:`vibrospeed.estimators.grid.frames.evidence` with ``centre``) and adds the evidence
there, where a stationary spectrum describes the comb: a stop or a braking is then not
attributed 1.5 s late (benchmarks/beyond/RESULTS.md). The fixed-lag smoother does the same when
``lag >= W/2`` and shrinks its blocks to ``lag - W/2`` s, so a sample still uses data at most
``lag..2 lag - W/2`` s after it.
Each grid point's evidence is centred on what white noise gives it (:func:`noise_offsets`).
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

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from numba import njit

# numba caches this file's compiled functions on this file alone: a change of background.py's
# _background must come with a change here (stale caches are then rebuilt)
from vibrospeed.estimators.grid.background import (  # noqa: F401 (re-exported)
    _background,
    _background_stat,
    _kth,
    _sort_columns,
    _window_medians,
    running_median,
    selection_network,
)
from vibrospeed.signal._whiten_kernels import _pairwise as _pairwise_sum  # numpy's sum


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


class _FrameTables(NamedTuple):
    """What the evidence of ``L``-sample frames needs besides the samples, per usable rate
    ``b`` (:meth:`Config.rates_in_frame`; ``b = 0`` unwarped): its log prior ``logp`` (R,),
    the warp's interpolation positions ``w_i0``, ``w_fr`` (R, L) (:func:`_warp`), the Hann
    window, the FFT length, the background's window ``widths``, evaluation ``steps`` and order
    statistics ``ranks`` (R,) and ``scale`` (:func:`_background_stat`), the comparators
    ``net`` (C, 2) of each rate's selection network (rate b's: rows ``net_at[b]`` to
    ``net_at[b + 1]``, :func:`selection_network`), per harmonic k the interpolation
    positions ``h_i0``, ``h_fr`` (R, M, N) of the grid points' (folded) ``k omega`` among the
    rate's spectrum bins, and the background's interpolation between its windows ``ij``
    (int32) and ``ifr`` (R, nfft / 2 + 1) (:func:`_interp_tables`; ``1 - ifr`` is made per
    call)."""

    logp: np.ndarray
    w_i0: np.ndarray
    w_fr: np.ndarray
    hann: np.ndarray
    nfft: int
    widths: np.ndarray
    steps: np.ndarray
    ranks: np.ndarray
    scale: float
    net: np.ndarray
    net_at: np.ndarray
    h_i0: np.ndarray
    h_fr: np.ndarray
    ij: np.ndarray
    ifr: np.ndarray


def _frame_tables(config, L: int, centre: bool) -> _FrameTables:
    """The :class:`_FrameTables` of ``L``-sample frames, built once per Config instance and
    frame length and kept with the Config (as the core's tables): the causal step asks for
    them at every frame."""
    cache = config.__dict__.setdefault("_frame_tables", {})
    tb = cache.get((L, centre))
    if tb is None:
        tb = cache[(L, centre)] = _build_frame_tables(config, L, centre)
    return tb


@lru_cache(maxsize=64)
def _network(n: int, k: int) -> np.ndarray:
    """:func:`selection_network` ``(n, k)``, made once per process (every rate of every frame
    length asks for it; it is Python and most of a frame table's cost); read-only."""
    net = selection_network(n, k)
    net.flags.writeable = False
    return net


def _build_frame_tables(config, L: int, centre: bool) -> _FrameTables:
    tr = config.tracker
    dt = tr.model.dt
    fs = 1.0 / dt
    grid = tr.grid
    M = tr.model.M
    rates = config.rates_in_frame(L, centre)
    R = rates.size
    nfft = 1 << int(np.ceil(np.log2(4 * L)))
    bg_hz = config.background_hz(L)  # >= 1.5 main lobes: a line never fills the window
    w_i0 = np.zeros((R, L), np.int64)
    w_fr = np.zeros((R, L))
    widths = np.empty(R, np.int64)
    ranks = np.empty(R, np.int64)
    h_i0 = np.empty((R, M, grid.size), np.int64)
    h_fr = np.empty((R, M, grid.size))
    scale = 1.0
    for b, beta in enumerate(rates):
        i0, fr, dtau = _warp(L, dt, float(beta), centre)
        if i0 is not None:
            w_i0[b], w_fr[b] = i0, fr
        f = 2 * np.pi * np.fft.rfftfreq(nfft, dtau)
        widths[b] = max(3, int(round(bg_hz / (1.0 / (dtau * nfft))))) | 1
        ranks[b], scale = _background_stat(int(widths[b]))
        for k in range(1, M + 1):
            pos = np.interp(_folded(k * grid, fs), f, np.arange(f.size))
            i0k = np.minimum(pos.astype(np.int64), f.size - 2)
            h_i0[b, k - 1], h_fr[b, k - 1] = i0k, pos - i0k
    steps = np.maximum(1, widths // 8)
    nets = [_network(int(w), int(k)) for w, k in zip(widths, ranks, strict=True)]
    net_at = np.cumsum([0] + [len(c) for c in nets]).astype(np.int64)
    nb = nfft // 2 + 1
    ij = np.empty((R, nb), np.int64)
    ifr = np.empty((R, nb))
    ifr1 = np.empty(nb)
    for b in range(R):
        st = int(steps[b])
        _interp_tables(nb, st, (nb + st - 2) // st + 1, ij[b], ifr[b], ifr1)
    return _FrameTables(np.log(config.rate_prior(rates)), w_i0, w_fr, np.hanning(L), nfft,
                        widths, steps, ranks, scale, np.concatenate(nets), net_at, h_i0, h_fr,
                        ij.astype(np.int32), ifr)


@njit(cache=True)
def _windowed(x: np.ndarray, w_i0: np.ndarray, w_fr: np.ndarray, hann: np.ndarray,
              out: np.ndarray) -> None:
    """``out[b, a, f]`` = frame ``x[a, f]`` of the (A, F, L) frames resampled at rate ``b``'s
    warp positions (linear interpolation; ``b = 0``: as it is) times the Hann window."""
    R = out.shape[0]
    A, F, L = x.shape
    for b in range(R):
        for a in range(A):
            for f in range(F):
                row = x[a, f]
                o = out[b, a, f]
                if b == 0:
                    for i in range(L):
                        o[i] = row[i] * hann[i]
                else:
                    for i in range(L):
                        j = w_i0[b, i]
                        fr = w_fr[b, i]
                        o[i] = (row[j] * (1 - fr) + row[j + 1] * fr) * hann[i]


@njit(cache=True)
def _interp_tables(n: int, step: int, nc: int, ij: np.ndarray, ifr: np.ndarray,
                   ifr1: np.ndarray) -> None:
    """The linear interpolation of :func:`_background` between its evaluated windows, for a
    spectrum of ``n`` bins, windows every ``step`` bins (``nc`` of them): bin i lies between
    windows ``ij[i]`` and ``ij[i] + 1`` with weights ``ifr1[i]`` = 1 - fr and ``ifr[i]`` = fr
    (each computed as there, so the products are the same)."""
    for i in range(n):
        j = min(i // step, nc - 2)
        c0 = min(j * step, n - 1)
        c1 = min((j + 1) * step, n - 1)
        fr = (i - c0) / max(c1 - c0, 1)
        ij[i] = j
        ifr[i] = fr
        ifr1[i] = 1.0 - fr


@njit(cache=True, inline="always")
def _frame_background(row: np.ndarray, width: int, step: int, rank: int, scale: float,
                      net: np.ndarray, mat: np.ndarray, buf: np.ndarray, med: np.ndarray,
                      ph: np.ndarray, ij: np.ndarray, ifr: np.ndarray, ifr1: np.ndarray,
                      out: np.ndarray) -> None:
    """:func:`_background` (the running ``rank``-th smallest of ``row`` over ``width`` bins,
    every ``step`` bins, interpolated, divided by ``scale``), bitwise, with its windows built
    from contiguous copies: window c is ``Pp[c step : c step + width]`` of the row extended by
    ``h = width // 2`` edge values either side (``Pp``; the last window's centre clipped to
    ``n - 1``), so its wire i is phase ``i % step`` of ``Pp`` at ``i // step + c``; the phases
    ``ph[p, m] = Pp[p + step m]`` are read once (``n + 2 h`` values instead of ``width`` per
    window) and each wire's row of ``mat`` is a slice of one of them. The network, the order
    statistic and the interpolation (positions ``ij``, ``ifr``, ``ifr1`` from
    :func:`_interp_tables`) are those of :func:`_background`. A row holding a NaN goes through
    :func:`_background` itself (its windows with NaN give NaN)."""
    n = row.size
    h = width // 2
    nc = (n + step - 2) // step + 1
    nan = False
    for i in range(n):
        nan |= row[i] != row[i]
    if nan:
        _background(row, width, step, rank, scale, net, mat, buf, med, out)
        return
    m_n = nc + (width - 1) // step + 1
    for p in range(step):
        pr = ph[p]
        for m in range(m_n):
            pr[m] = row[min(max(p + step * m - h, 0), n - 1)]
    for i in range(width):  # indexed in two dimensions: compiled as a vector copy
        p = i % step
        o = i // step
        for c in range(nc):
            mat[i, c] = ph[p, o + c]
    cl = min((nc - 1) * step, n - 1)
    if cl != (nc - 1) * step:  # the last window's centre is clipped to the last bin
        for i in range(width):
            mat[i, nc - 1] = row[min(max(cl - h + i, 0), n - 1)]
    _sort_columns(mat, net, nc)
    mk = mat[rank]
    if step == 1:
        for i in range(n):
            out[i] = mk[i] / scale
        return
    for i in range(n):
        j = ij[i]
        out[i] = (mk[j] * ifr1[i] + mk[j + 1] * ifr[i]) / scale


@njit(cache=True)
def _rate_evidence(P: np.ndarray, good: np.ndarray, lead: np.ndarray, weight: np.ndarray,
                   widths: np.ndarray, steps: np.ndarray, ranks: np.ndarray, scale: float,
                   net: np.ndarray, net_at: np.ndarray, h_i0: np.ndarray, h_fr: np.ndarray,
                   ij_t: np.ndarray, ifr_t: np.ndarray, c_s: float,
                   c_0: float, cap: float, logp: np.ndarray, use_lead: bool,
                   E: np.ndarray) -> None:
    """``E[b, f, j]`` = the comb log-evidence of grid point j in frame f at rate b (module
    docstring) before the mixture over the rates, from the (R, A, F, nb) power spectra ``P``:
    per axis the whitened spectrum ``S = P / max(bg, 1e-300 + 1e-12 max(bg))``
    (:func:`_background`, computed as :func:`_frame_background` does, rate b's selection
    network: ``net[net_at[b]:net_at[b + 1]]``); per harmonic k the term
    ``S(k omega) c_s - c_0`` (``c_s = a / (1 + a)``, ``c_0 = log(1 + a)``; S interpolated at
    ``h_i0``, ``h_fr``; the background's interpolation ``ij_t``, ``ifr_t`` (R, nb),
    :func:`_interp_tables`, and ``1 - ifr_t`` as it computes it), summed over the ``good``
    (A, F) axes and capped at ``A_f cap``; their sum over k, the best term's lead over the
    second best limited to ``lead`` (F,) (``use_lead``), times ``weight`` (F,) with several
    axes, plus the rate's log prior ``logp`` (R,). The operations and their order are those
    of the array form (numpy), so the numbers are the same to the last bit."""
    R, A, F, n = P.shape
    M = h_i0.shape[1]
    N = h_i0.shape[2]
    wmax = 1
    size = 1
    for b in range(R):
        wmax = max(wmax, widths[b])
        size = max(size, widths[b] * ((n + steps[b] - 2) // steps[b] + 1))
    med = np.empty(n)
    buf = np.empty(wmax)
    flat = np.empty(size)
    bg = np.empty(n)
    S = np.empty(n)
    acc = np.empty((M, N))
    ifr1 = np.empty(n)
    ph = np.empty((wmax, n // max(1, steps.min()) + wmax + 2))
    for b in range(R):
        w = widths[b]
        nc = (n + steps[b] - 2) // steps[b] + 1
        mat = flat[: w * nc].reshape((w, nc))
        net_b = net[net_at[b] : net_at[b + 1]]
        ij = ij_t[b]
        ifr = ifr_t[b]
        for i in range(n):
            ifr1[i] = 1.0 - ifr[i]
        for f in range(F):
            ng = 0
            for a in range(A):
                if good[a, f]:
                    ng += 1
            capf = cap if A == 1 else ng * cap
            for a in range(A):
                row = P[b, a, f]
                _frame_background(row, w, steps[b], ranks[b], scale, net_b, mat, buf[:w],
                                  med, ph, ij, ifr, ifr1, bg)
                mx = bg[0]
                for i in range(n):  # np.max: NaN if any is
                    v = bg[i]
                    if v != v:
                        mx = v
                        break
                    if v > mx:
                        mx = v
                thr = 1e-300 + 1e-12 * mx
                for i in range(n):  # np.maximum: NaN if either is
                    v = bg[i]
                    d = v if (v >= thr or v != v) else thr
                    if thr != thr:
                        d = thr
                    S[i] = row[i] / d
                use = good[a, f]
                for k in range(M):
                    for j in range(N):
                        i0 = h_i0[b, k, j]
                        fr = h_fr[b, k, j]
                        t = (S[i0] * (1 - fr) + S[i0 + 1] * fr) * c_s - c_0
                        if A == 1:
                            acc[k, j] = t
                        else:  # numpy's sum over the axes: 0 + t_0 + t_1 + ...
                            if a == 0:
                                acc[k, j] = 0.0
                            acc[k, j] += t if use else 0.0
            for j in range(N):
                e = 0.0
                t1 = -np.inf
                t2 = -np.inf
                for k in range(M):
                    v = acc[k, j]
                    lk = capf if v > capf else v  # np.minimum: NaN stays NaN
                    e += lk
                    if lk > t1:
                        t2 = t1
                        t1 = lk
                    elif lk > t2:
                        t2 = lk
                if use_lead:
                    e += min(t1, t2 + lead[f]) - t1
                if A > 1:
                    e = e * weight[f]
                E[b, f, j] = e + logp[b]


def frame_evidence(config, frames: np.ndarray, centre: bool = False, *,
                   raw: bool = False) -> np.ndarray:
    """(F, N + 1) comb log-evidence of the (F, L) sample frames, or of the (A, F, L) frames
    of A axes (``comb_axes``), per the module docstring; NaN samples count as 0; frames with
    more than half NaN give no evidence (zeros). With several ``comb_rates`` the frame is also
    warped for each relative rate (:func:`_warp`) and the evidences are averaged over the
    rates with their prior weights (in probability: ``E = log sum_b p_b exp(E_b)``), so an
    accelerating comb scores at its *current* frequencies instead of being smeared over the
    frame. Each grid point's evidence is centred on what white noise gives it
    (:func:`noise_offsets`; ``raw``: not centred). One FFT call for every rate, axis and frame,
    the rest compiled (:func:`_windowed`, :func:`_rate_evidence`) with the constants of the
    frame length built once (:func:`_frame_tables`); one frame of one axis goes through
    :func:`ring_evidence` (the same numbers)."""
    tr = config.tracker
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim == 2:
        frames = frames[None]
    A, F, L = frames.shape
    if A == 1 and F == 1:  # one frame of one axis: the same numbers without the batch's arrays
        row = np.ascontiguousarray(frames[0, 0])
        return ring_evidence(config, row, 0, L - 1, float(row[L - 1]), centre, raw)[None]
    N = tr.n_grid
    out = np.zeros((F, N + 1))
    if F == 0:
        return out
    good = np.mean(~np.isfinite(frames), axis=2) <= 0.5  # (A, F): an axis' frame is usable
    n_good = good.sum(axis=0)  # (F,) axes per frame (a dead or gappy axis drops out)
    # a missing sample (NaN or inf) counts 0 (nan_to_num made an inf 1.8e308: an overflow
    # and NaN evidence for every frame holding it)
    x = np.where(np.isfinite(frames), frames, 0.0)
    x = np.ascontiguousarray(x - x.mean(axis=2, keepdims=True))
    tb = _frame_tables(config, L, centre)
    win = np.empty((tb.logp.size, A, F, L))
    _windowed(x, tb.w_i0, tb.w_fr, tb.hann, win)
    P = np.abs(np.fft.rfft(win, tb.nfft, axis=-1)) ** 2
    a = config.comb_snr
    use_lead = tr.model.M >= 2 and bool(np.isfinite(config.comb_lead))
    lead = (n_good * config.comb_lead).astype(np.float64) if use_lead else np.zeros(F)
    weight = (np.array([config.axes_weight(int(g)) for g in n_good]) if A > 1
              else np.ones(F))
    E = np.empty((tb.logp.size, F, N))
    _rate_evidence(P, good, lead, weight, tb.widths, tb.steps, tb.ranks, tb.scale, tb.net,
                   tb.net_at, tb.h_i0, tb.h_fr, tb.ij, tb.ifr, a / (1 + a),
                   float(np.log1p(a)), float(config.comb_cap), tb.logp, use_lead, E)
    mx = E.max(axis=0)  # (one rate: log p = 0 and this is E[0] exactly)
    out[:, :N] = mx + np.log(np.exp(E - mx).sum(axis=0))
    if not raw:  # centred for the axes each frame uses (a dead axis drops out)
        for g in np.unique(n_good[n_good > 0]):
            out[n_good == g, :N] -= noise_offsets(config, L, centre, int(g))
    out[:, :N] *= config.comb_weight
    out[n_good == 0] = 0.0
    return out




@njit(cache=True)
def _ring_windowed(src: np.ndarray, start: int, m: int, y: float, w_i0: np.ndarray,
                   w_fr: np.ndarray, hann: np.ndarray, win: np.ndarray) -> int:
    """The frame of the ``m`` values of the ring ``src`` from ``start`` on (wrapping) and then
    ``y``, its missing (non-finite) samples 0 and its mean removed, resampled and windowed per
    rate into ``win`` (R, 1, 1, m + 1) (:func:`_windowed`); returns the number of missing
    samples. The steps of :func:`frame_evidence` for one frame, in its order."""
    Ls = src.size
    n = m + 1
    x = np.empty(n)
    bad = 0
    for i in range(n):
        v = src[(start + i) % Ls] if i < m else y
        if not np.isfinite(v):
            v = 0.0
            bad += 1
        x[i] = v
    mu = (0.0 + _pairwise_sum(x, 0, n)) / n
    for i in range(n):
        x[i] = x[i] - mu
    _windowed(x.reshape((1, 1, n)), w_i0, w_fr, hann, win)
    return bad


@njit(cache=True)
def _one_frame_rates(P: np.ndarray, good: np.ndarray, lead: np.ndarray, weight: np.ndarray,
                     widths: np.ndarray, steps: np.ndarray, ranks: np.ndarray, scale: float,
                     net: np.ndarray, net_at: np.ndarray, h_i0: np.ndarray, h_fr: np.ndarray,
                     ij: np.ndarray, ifr: np.ndarray, c_s: float,
                     c_0: float, cap: float, logp: np.ndarray, use_lead: bool, E: np.ndarray,
                     mx: np.ndarray) -> None:
    """One frame's per-rate evidence ``E`` (R, 1, N) from its magnitude spectra ``P``
    (R, 1, 1, nb), squared here (``np.abs(...) ** 2``), through :func:`_rate_evidence`; then
    ``mx`` (N,) the largest over the rates (``np.max``: NaN if any is) and ``E - mx`` in
    ``E``: the log-sum-exp's steps before its exponential."""
    R = P.shape[0]
    nb = P.shape[3]
    for b in range(R):
        row = P[b, 0, 0]
        for i in range(nb):
            row[i] = row[i] * row[i]
    _rate_evidence(P, good, lead, weight, widths, steps, ranks, scale, net, net_at, h_i0, h_fr,
                   ij, ifr, c_s, c_0, cap, logp, use_lead, E)
    N = E.shape[2]
    for j in range(N):
        v = E[0, 0, j]
        for b in range(1, R):
            e = E[b, 0, j]
            if not (v >= e or v != v):  # np.maximum: NaN if either is
                v = e
        mx[j] = v
    for b in range(R):
        for j in range(N):
            E[b, 0, j] = E[b, 0, j] - mx[j]


@njit(cache=True)
def _sum_rates(E: np.ndarray, s: np.ndarray) -> None:
    """``s`` = the sum of ``E`` (R, 1, N) over the rates, in their order (numpy's sum over the
    outer axis)."""
    R, _, N = E.shape
    for j in range(N):
        s[j] = 0.0 + E[0, 0, j]
    for b in range(1, R):
        for j in range(N):
            s[j] = s[j] + E[b, 0, j]


@njit(cache=True)
def _finish(mx: np.ndarray, ls: np.ndarray, off: np.ndarray, w: float, out: np.ndarray) -> None:
    """``out[:N] = (mx + ls - off) w`` (``off`` empty: not centred), each step rounded as the
    array form's."""
    N = mx.size
    for j in range(N):
        e = mx[j] + ls[j]
        if off.size:
            e = e - off[j]
        out[j] = e * w


def _rfft_even_gufunc():
    """numpy's gufunc behind ``np.fft.rfft`` for even lengths (the length is the output's:
    the input is zero-padded to it), called directly without ``np.fft.rfft``'s per-call Python
    work; None where this numpy has none that gives ``np.fft.rfft``'s numbers."""
    try:
        from numpy.fft import _pocketfft_umath as pfu

        f = pfu.rfft_n_even
        a = np.linspace(-1.0, 2.0, 14).reshape(2, 7) ** 2
        got = f(a, 1, out=np.empty((2, 9), np.complex128))
        return f if got.tobytes() == np.fft.rfft(a, 16, axis=-1).tobytes() else None
    except Exception:  # another numpy: its public rfft
        return None


_RFFT_EVEN = _rfft_even_gufunc()
_GOOD = np.ones((1, 1), dtype=np.bool_)
_ONE = np.ones(1)
_NO_OFFSET = np.empty(0)


def _one_frame_consts(config) -> tuple:
    """``(c_s, c_0, cap, use_lead, lead (1,), comb_weight)`` of one single-axis frame's
    evidence (:func:`ring_evidence`), kept with the Config."""
    c = config.__dict__.get("_one_frame_consts")
    if c is None:
        a = config.comb_snr
        use_lead = config.tracker.model.M >= 2 and bool(np.isfinite(config.comb_lead))
        lead = (np.array([1]) * config.comb_lead).astype(np.float64) if use_lead else np.zeros(1)
        c = config.__dict__["_one_frame_consts"] = (
            a / (1 + a), float(np.log1p(a)), float(config.comb_cap), use_lead, lead,
            config.comb_weight)
    return c


def ring_evidence(config, src: np.ndarray, start: int, m: int, y: float,
                  centre: bool = False, raw: bool = False) -> np.ndarray:
    """(N + 1,) comb evidence of one single-axis frame: the ``m`` values of the ring ``src``
    (1-D) from index ``start`` on (wrapping at its end) followed by ``y``. The numbers of
    :func:`frame_evidence` of that (1, 1, m + 1) frame, bitwise: the same operations in the
    same order, without its handling of several axes and frames and its array temporaries
    (three compiled passes; numpy's FFT, ``abs``, ``exp`` and ``log``, whose numpy forms the
    compiled code does not reproduce to the last bit)."""
    N = config.tracker.n_grid
    n = m + 1
    tb = _frame_tables(config, n, centre)
    R = tb.logp.size
    win = np.empty((R, 1, 1, n))
    bad = _ring_windowed(src, start, m, y, tb.w_i0, tb.w_fr, tb.hann, win)
    out = np.zeros(N + 1)
    if not bad / n <= 0.5:  # the frame is more than half missing: no evidence
        return out
    c_s, c_0, cap, use_lead, lead, w = _one_frame_consts(config)
    if _RFFT_EVEN is None:  # pragma: no cover - another numpy
        C = np.fft.rfft(win, tb.nfft, axis=-1)
    else:  # np.fft.rfft's own call (nfft is a power of 2)
        C = _RFFT_EVEN(win, 1, out=np.empty((R, 1, 1, tb.nfft // 2 + 1), np.complex128))
    P = np.abs(C)
    E = np.empty((R, 1, N))
    mx = np.empty(N)
    _one_frame_rates(P, _GOOD, lead, _ONE, tb.widths, tb.steps, tb.ranks, tb.scale, tb.net,
                     tb.net_at, tb.h_i0, tb.h_fr, tb.ij, tb.ifr, c_s, c_0, cap,
                     tb.logp, use_lead, E, mx)
    np.exp(E, out=E)
    s = np.empty(N)
    _sum_rates(E, s)
    np.log(s, out=s)
    _finish(mx, s, _NO_OFFSET if raw else noise_offsets(config, n, centre, 1), w, out)
    return out


#: white-noise frames behind :func:`noise_offsets` (measured Monte Carlo error ~0.04 nats per
#: grid point, against offsets of up to ~0.4 nats at the bottom of a 2-30 rad/s range)
NOISE_FRAMES = 64


def noise_offsets(config, L: int, centre: bool = False, A: int = 1) -> np.ndarray:
    """(N,) what the comb evidence gives each grid point, on average, where there is no line:
    its mean over ``NOISE_FRAMES`` frames of white noise (``L`` samples, ``A`` axes; a fixed
    seed per length), less that mean's average over the grid. :func:`frame_evidence`
    subtracts it, so that data without a line favour no part of the range: where a grid
    point's harmonics lie closer together than the frame's resolution (the bottom of the
    range: 2-4.5 rad/s on a 3 s frame), they read correlated bins, which the per-harmonic cap
    and the lead limit then score higher on average (+0.1 nats per frame on white noise), and
    "no line" drives would otherwise sit at the bottom of the range. The grid's average is
    kept, so the balance with the "no line" state (evidence 0) does not move. Built once per
    Config and frame shape and kept with the Config (the causal step asks at every frame)."""
    cache = config.__dict__.setdefault("_noise_offsets", {})
    key = (int(L), bool(centre), int(A))
    off = cache.get(key)
    if off is None:
        noise = np.random.default_rng(L).standard_normal((A, NOISE_FRAMES, L))
        w = config.comb_weight
        m = frame_evidence(config, noise, centre, raw=True)[:, :-1].mean(axis=0)
        m = m / w if w != 0 else np.zeros_like(m)
        off = cache[key] = m - m.mean()
        off.flags.writeable = False
    return off
