"""The compiled comb evidence against independent references: the selection network against
sorting, the sliding background against ``running_median`` (bitwise) and a sort per window,
the whole frame evidence against its array form (numpy, bitwise), and the one-sample step's
frame against the batch evidence (bitwise)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from background_reference import sorted_windows
from vibrospeed.estimators import grid
from vibrospeed.estimators.grid import comb, frames

# ------------------------------------------------------------------------------------------
# selection network


def _apply(net: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The comparators applied to the columns of X (n, V), smaller value on the first wire."""
    X = X.copy()
    for i, j in net:
        lo, hi = np.minimum(X[i], X[j]), np.maximum(X[i], X[j])
        X[i], X[j] = lo, hi
    return X


@pytest.mark.parametrize("n", [1, 2, 3, 5, 8, 13, 27, 41, 59, 64, 65])
def test_selection_network_gives_the_kth_smallest(n):
    rng = np.random.default_rng(n)
    # continuous values, heavy ties, and every 0-1 pattern with few ones or few zeros
    X = np.column_stack([rng.normal(size=(n, 200)), rng.integers(0, 3, (n, 200)),
                         np.eye(n), 1.0 - np.eye(n)])
    ref = np.sort(X, axis=0)
    for k in sorted({0, n // 2, n - 1, n // 3}):
        net = comb.selection_network(n, k)
        assert net.ndim == 2 and net.shape[1] == 2
        assert np.all(net[:, 0] < net[:, 1]) and np.all(net[:, 1] < n)
        np.testing.assert_array_equal(_apply(net, X)[k], ref[k])


def test_selection_network_is_pruned_to_its_output():
    top = comb.selection_network(41, 40)  # the maximum
    assert len(comb.selection_network(41, 20)) < 300
    rng = np.random.default_rng(0)
    X = rng.normal(size=(41, 50))
    np.testing.assert_array_equal(_apply(top, X)[40], X.max(axis=0))


# ------------------------------------------------------------------------------------------
# sliding background


def _background(row: np.ndarray, width: int, rank: int, scale: float = 1.0) -> np.ndarray:
    step = max(1, width // 8)
    n = row.size
    net = comb.selection_network(width, rank)
    nc = (n + step - 2) // step + 1
    out = np.empty(n)
    comb._background(np.ascontiguousarray(row, dtype=np.float64), width, step, rank, scale,
                     net, np.empty((width, nc)), np.empty(width), np.empty(n), out)
    return out


def _reference_order(row: np.ndarray, width: int, rank: int) -> np.ndarray:
    """The brute-force background at the evidence's step, max(1, width // 8) bins."""
    return sorted_windows(row, width, max(1, width // 8), rank)


_values = st.one_of(st.sampled_from([0.0, 1.0, 2.0, 2.5, 1e-300, 7.0]),
                    st.floats(0.0, 1e300, allow_nan=False, allow_infinity=False))


@settings(max_examples=200, deadline=None)
@given(row=hnp.arrays(np.float64, st.integers(2, 120), elements=_values),
       half=st.integers(0, 30))
def test_background_median_is_running_median_bitwise(row, half):
    width = 2 * half + 1
    got = _background(row, width, width // 2, np.log(2.0))
    ref = comb.running_median(row[None], width)[0] / np.log(2.0)
    assert np.array_equal(got.view(np.uint64), ref.view(np.uint64))


@settings(max_examples=100, deadline=None)
@given(row=hnp.arrays(np.float64, st.integers(2, 80), elements=_values),
       half=st.integers(0, 25), q=st.floats(0.0, 1.0))
def test_background_any_order_statistic_is_the_sorted_window(row, half, q):
    width = 2 * half + 1
    rank = min(width - 1, int(q * width))
    np.testing.assert_array_equal(_background(row, width, rank), _reference_order(row, width, rank))


def test_background_window_with_nan_is_nan():
    row = np.arange(60.0)
    row[30] = np.nan
    got = _background(row, 9, 4)
    ref = comb.running_median(row[None], 9)[0]
    np.testing.assert_array_equal(np.isnan(got), np.isnan(ref))
    assert np.isnan(got[30]) and np.isfinite(got[:20]).all()
    np.testing.assert_array_equal(np.nan_to_num(got), np.nan_to_num(ref))


# ------------------------------------------------------------------------------------------
# the frame evidence against its array form


def _array_form(config, frames: np.ndarray, centre: bool = False) -> np.ndarray:
    """The comb evidence written with whole-array numpy operations (module docstring of
    grid.comb): per rate the warped, windowed frames' spectra, the background (the order
    statistic of :func:`comb._background_stat` sorted out of each window), per-harmonic capped
    terms, their sum, the lead limit, the log-sum-exp over the rates."""
    tr = config.tracker
    dt = tr.model.dt
    fs = 1.0 / dt
    frames = np.asarray(frames, dtype=np.float64)
    if frames.ndim == 2:
        frames = frames[None]
    A, F, L = frames.shape
    N, M = tr.n_grid, tr.model.M
    good = np.mean(~np.isfinite(frames), axis=2) <= 0.5
    n_good = good.sum(axis=0)
    x = np.nan_to_num(frames)
    x = x - x.mean(axis=2, keepdims=True)
    rates = config.rates_in_frame(L, centre)
    logp = np.log(config.rate_prior(rates))
    weight = np.array([config.axes_weight(int(a)) for a in n_good])[:, None]
    E = np.empty((rates.size, F, N))
    for b, beta in enumerate(rates):
        i0, fr, dtau = comb._warp(L, dt, float(beta), centre)
        xb = x if i0 is None else x[:, :, i0] * (1 - fr) + x[:, :, i0 + 1] * fr
        xb = xb.reshape(A * F, L)
        nfft = 1 << int(np.ceil(np.log2(4 * L)))
        P = np.abs(np.fft.rfft(xb * np.hanning(L), nfft, axis=1)) ** 2
        f = 2 * np.pi * np.fft.rfftfreq(nfft, dtau)
        medw = max(3, int(round(config.background_hz(L) / (1.0 / (dtau * nfft))))) | 1
        rank, scale = comb._background_stat(medw)  # the median and ln 2 (running_median)
        bg = np.array([_reference_order(r, medw, rank) for r in P]) / scale
        S = P / np.maximum(bg, 1e-300 + 1e-12 * np.max(bg, axis=1, keepdims=True))
        a = config.comb_snr
        lk = np.empty((M, F, N))
        for k in range(1, M + 1):
            pos = np.interp(comb._folded(k * tr.grid, fs), f, np.arange(f.size))
            j0 = np.minimum(pos.astype(np.int64), f.size - 2)
            w = pos - j0
            s = S[:, j0] * (1 - w) + S[:, j0 + 1] * w
            terms = (s * (a / (1 + a)) - np.log1p(a)).reshape(A, F, N)
            if A == 1:
                lk[k - 1] = np.minimum(terms[0], config.comb_cap)
            else:
                cap = good.sum(axis=0)[:, None] * config.comb_cap
                lk[k - 1] = np.minimum(np.where(good[:, :, None], terms, 0.0).sum(axis=0), cap)
        e = lk.sum(axis=0)
        if M >= 2 and np.isfinite(config.comb_lead):
            top2 = -np.partition(-lk, 1, axis=0)[:2]
            e += np.minimum(top2[0], top2[1] + (n_good * config.comb_lead)[:, None]) - top2[0]
        E[b] = (e if A == 1 else e * weight) + logp[b]
    out = np.zeros((F, N + 1))
    mx = E.max(axis=0)
    out[:, :N] = mx + np.log(np.exp(E - mx).sum(axis=0))
    out[:, :N] *= config.comb_weight
    out[n_good == 0] = 0.0
    return out


def _signal(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    w = 40 + 10 * np.sin(0.3 * t)
    ph = np.cumsum(w) * 0.01
    return (np.sin(ph) + 0.5 * np.sin(2 * ph + 1) + 0.3 * np.sin(3 * ph)
            + 0.4 * rng.normal(size=n))


@pytest.mark.parametrize("centre", [False, True])
@pytest.mark.parametrize("variant", [
    {}, {"comb_rates": (0.0,)}, {"comb_lead": float("inf")}, {"comb_bg": 0.3},
    {"comb_snr": 2.5, "comb_cap": 1.0}])
def test_frame_evidence_is_its_array_form_bitwise(centre, variant):
    cfg = dataclasses.replace(grid.Config(), **variant)
    y = _signal(2000, 1)
    for L in (cfg.frame_len, 100, 137):
        fr = np.stack([y[s : s + L] for s in (0, 400, 1111)])
        fr[1, 10:30] = np.nan
        fr[2, : L // 2 + 3] = np.nan  # more than half missing: no evidence
        got = comb.frame_evidence(cfg, fr, centre, raw=True)
        np.testing.assert_array_equal(got, _array_form(cfg, fr, centre))
        assert np.all(got[2] == 0.0) and np.any(got[0] != 0.0)


def test_frame_evidence_of_several_axes_is_its_array_form_bitwise():
    cfg = dataclasses.replace(grid.Config(), comb_axes=("y", "x", "z"))
    y = _signal(1500, 2)
    z = _signal(1500, 3)
    L = cfg.frame_len
    fr = np.stack([np.stack([y[s : s + L] for s in (0, 500)]),
                   np.stack([z[s : s + L] for s in (0, 500)]),
                   np.stack([y[s + 7 : s + 7 + L] for s in (0, 500)])])
    fr[1, 0, : L // 2 + 5] = np.nan  # axis 1 drops out of frame 0
    np.testing.assert_array_equal(comb.frame_evidence(cfg, fr, raw=True), _array_form(cfg, fr))


# ------------------------------------------------------------------------------------------
# the one-sample step


@pytest.mark.parametrize("A", [1, 3])
def test_step_evidence_is_the_batch_evidence_bitwise(A):
    cfg = grid.Config() if A == 1 else dataclasses.replace(grid.Config(),
                                                           comb_axes=("y", "x", "z"))
    Y = np.column_stack([_signal(700, s) for s in range(A)])
    Y[30:40, A - 1] = np.nan
    st_ = grid.init(cfg)
    got_idx, got = [], []
    for i in range(Y.shape[0]):
        y = Y[i] if A > 1 else Y[i, 0]
        e = frames.step_evidence(cfg, st_.buf, st_.count, np.atleast_1d(y))
        if e is not None:
            got_idx.append(i)
            got.append(e)
        st_, _ = grid.step(cfg, st_, y)
    idx, vals = frames.evidence(cfg, Y if A > 1 else Y[:, 0])
    np.testing.assert_array_equal(np.array(got_idx), idx)
    np.testing.assert_array_equal(np.array(got), vals)
    assert idx[0] == cfg.min_frame_len - 1  # the growing frames are there
