"""The grid core's structure-of-arrays loop (:mod:`vibrospeed.estimators.grid.core`) against
the per-point loop it replaced, kept here as the reference (``_iterate_ref``, ``_run_ref``):
summary rows, posteriors, log-emissions and final states agree to rounding (1e-9 relative;
the sums are taken in the same order, so they are in fact bitwise equal) on simulated drives
with the "no line" state on and off, white and mixture null models, a two-component kernel,
the exact (full-row) kernel, no jumps, NaN samples inside and extra evidence rows; and the
compiled step equals the run sample by sample."""

import dataclasses

import numpy as np
import pytest
from numba import njit

from vibrospeed import sim
from vibrospeed.estimators import grid
from vibrospeed.estimators.grid import filter as gf
from vibrospeed.estimators.grid.core import LOG_2PI
from vibrospeed.estimators.grid.method import _prepare
from vibrospeed.estimators.grid.summary import COL_LOGLIK, N_OUT_FIXED, _summary


@njit
def _iterate_ref(lw, lw0, mean, cov, y, r, cs, qd, kb, B, grid, edges, u, log_floor, q_lo, q_hi,
             eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold, cur, ex,
             w, v, X, acc, out, post, gll):
    """The per-point loop of the grid core before its structure-of-arrays form (98952ac),
    kept as the reference: every grid point in turn."""
    N = grid.size
    n = mean.shape[1]
    M = n // 2
    has_null = p_off > 0.0
    finite = np.isfinite(y)
    ph = acc[:n]
    # ---- 1. measurement update per grid point: log w_j += log N(y; h m_j, S_j) ----------
    if finite:
        for j in range(N):
            mj = mean[j]
            Pj = cov[j]
            yhat = 0.0
            for a in range(M):
                yhat += mj[2 * a]
            for i in range(n):
                s_ = 0.0
                for a in range(M):
                    s_ += Pj[i, 2 * a]
                ph[i] = s_
            S = r
            for a in range(M):
                S += ph[2 * a]
            nu = y - yhat
            inv = 1.0 / S
            g = nu * inv
            for i in range(n):
                mj[i] += ph[i] * g
            for i in range(n):
                pi = ph[i] * inv
                for k in range(i, n):
                    val = Pj[i, k] - pi * ph[k]
                    Pj[i, k] = val
                    Pj[k, i] = val
            ll = -0.5 * (LOG_2PI + np.log(S) + nu * nu * inv) * temper
            if null_mix:
                v[j] = lw[j]  # prior log-weight
                w[j] = lw[j] + ll  # prior times (tempered) predictive
            if ex.size > 0:
                ll += ex[j]
            lw[j] += ll
            if gll.size > 0:
                gll[j] = ll
        if has_null:
            if null_mix:
                # log sum_j p_j l_j - log sum_j p_j (signal part's predictive mixture)
                ma = -np.inf
                mb = -np.inf
                for j in range(N):
                    if w[j] > ma:
                        ma = w[j]
                    if v[j] > mb:
                        mb = v[j]
                sa = 0.0
                sb = 0.0
                for j in range(N):
                    sa += np.exp(w[j] - ma)
                    sb += np.exp(v[j] - mb)
                ll0 = ma + np.log(sa) - mb - np.log(sb)
            else:
                ll0 = -0.5 * (LOG_2PI + np.log(null_var) + y * y / null_var) * temper
            if ex.size > 0:
                ll0 += ex[N]
            lw0[0] += ll0
            if gll.size > 0:
                gll[N] = ll0
    else:
        if ex.size > 0:
            for j in range(N):
                lw[j] += ex[j]
            if has_null:
                lw0[0] += ex[N]
        if gll.size > 0:
            for j in range(N + 1):
                gll[j] = ex[j] if ex.size > 0 else 0.0
    mx = lw0[0] if has_null else -np.inf
    for j in range(N):
        if lw[j] > mx:
            mx = lw[j]
    # floor at log_floor nats below the best state, then normalise (one exp per point)
    s = 0.0
    for j in range(N):
        d = lw[j] - mx
        if d < -log_floor:
            d = -log_floor
        w[j] = np.exp(d)
        s += w[j]
    w0 = 0.0
    if has_null:
        d = lw0[0] - mx
        if d < -log_floor:
            d = -log_floor
        w0 = np.exp(d)
        s += w0
    pred_ll = mx + np.log(s)
    inv_s = 1.0 / s
    for j in range(N):
        w[j] *= inv_s
    w0 *= inv_s
    # ---- 2. outputs ---------------------------------------------------------------------
    jmap = _summary(w, w0, u, grid, edges, q_lo, q_hi, amb_rel, amb_abs, v, out, hold, cur)
    out[COL_LOGLIK] = pred_ll if finite else 0.0
    for a in range(M):
        al = mean[jmap, 2 * a]
        be = mean[jmap, 2 * a + 1]
        out[N_OUT_FIXED + a] = np.sqrt(al * al + be * be)
    if post.size == N:
        for j in range(N):
            post[j] = w[j]
    # ---- 3. linear time update per source point i (in place: m = F m, P = F P F' + Q),
    #         packed into X[i] = [m_i-, upper(P_i- + m_i- m_i-')] -------------------------
    for i in range(N):
        m = mean[i]
        P = cov[i]
        for a in range(M):
            c = cs[i, a, 0]
            sn = cs[i, a, 1]
            x0 = m[2 * a]
            x1 = m[2 * a + 1]
            m[2 * a] = c * x0 + sn * x1
            m[2 * a + 1] = -sn * x0 + c * x1
        for a in range(M):
            a0 = 2 * a
            ca = cs[i, a, 0]
            sa = cs[i, a, 1]
            for b in range(a, M):
                c0 = 2 * b
                cb = cs[i, b, 0]
                sb = cs[i, b, 1]
                p00 = P[a0, c0]
                p01 = P[a0, c0 + 1]
                p10 = P[a0 + 1, c0]
                p11 = P[a0 + 1, c0 + 1]
                # R_a P_ab, R = [[c, s], [-s, c]]
                t00 = ca * p00 + sa * p10
                t01 = ca * p01 + sa * p11
                t10 = -sa * p00 + ca * p10
                t11 = -sa * p01 + ca * p11
                # (R_a P_ab) R_b'
                r00 = t00 * cb + t01 * sb
                r01 = -t00 * sb + t01 * cb
                r10 = t10 * cb + t11 * sb
                r11 = -t10 * sb + t11 * cb
                if b == a:
                    r01 = 0.5 * (r01 + r10)
                    r10 = r01
                    r00 += qd
                    r11 += qd
                P[a0, c0] = r00
                P[a0, c0 + 1] = r01
                P[a0 + 1, c0] = r10
                P[a0 + 1, c0 + 1] = r11
        Xi = X[i]
        c = n
        for a in range(n):
            ma = m[a]
            Xi[a] = ma
            for b in range(a, n):
                Xi[c] = P[a, b] + ma * m[b]
                c += 1
    # ---- 4.-5. transition (random walk, jumps, null) and moment-matching merge ----------
    L = X.shape[1]
    rw = 1.0 - eps - p_off
    J = eps * (1.0 - w0) + p_on * w0  # mass redistributed uniformly with the prior
    for j in range(N):
        lo = max(0, j - B)
        hi = min(N - 1, j + B)
        for c in range(L):
            acc[c] = 0.0
        W = 0.0
        for i in range(lo, hi + 1):
            lam = w[i] * kb[j, i - j + B]
            W += lam
            Xi = X[i]
            for c in range(L):
                acc[c] += lam * Xi[c]
        if rw != 1.0:
            W *= rw
            for c in range(L):
                acc[c] *= rw
        Ju = J * u[j]
        if Ju > 0.0:
            W += Ju
            # prior: mean 0, second moment p0 I
            c = n
            for a in range(n):
                acc[c] += Ju * p0
                c += n - a
        inv = 1.0 / W
        # m_j = sum lam m_i- / W ;  P_j = sum lam (P_i- + m_i- m_i-') / W - m_j m_j'
        mj = mean[j]
        Pj = cov[j]
        for a in range(n):
            mj[a] = acc[a] * inv
        c = n
        for a in range(n):
            for b in range(a, n):
                val = acc[c] * inv - mj[a] * mj[b]
                Pj[a, b] = val
                Pj[b, a] = val
                c += 1
        lw[j] = np.log(W)
    if has_null:
        lw0[0] = np.log(p_off * (1.0 - w0) + (1.0 - p_on) * w0)



@njit
def _run_ref(tb, lw, lw0, mean, cov, cur, ys, ex_idx, ex_val, want_post, want_gll):
    """The loop over a signal of the per-point form (98952ac)."""
    r, cs, qd, kb, B = tb.r, tb.cs, tb.qd, tb.kb, tb.B
    grid, edges, u, log_floor = tb.grid, tb.edges, tb.u, tb.log_floor
    q_lo, q_hi, eps, p_off, p_on = tb.q_lo, tb.q_hi, tb.eps, tb.p_off, tb.p_on
    null_var, p0, amb_rel, amb_abs = tb.null_var, tb.p0, tb.amb_rel, tb.amb_abs
    temper, null_mix, hold = tb.temper, tb.null_mix, tb.hold
    n_s = ys.size
    N = grid.size
    n = mean.shape[1]
    M = n // 2
    outs = np.empty((n_s, N_OUT_FIXED + M))
    posts = np.empty((n_s if want_post else 0, N), dtype=np.float32)
    glls = np.empty((n_s if want_gll else 0, N + 1), dtype=np.float32)
    post = np.empty(N if want_post else 0)
    gll = np.empty(N + 1 if want_gll else 0)
    w = np.empty(N)
    v = np.empty(N)
    L = n + n * (n + 1) // 2
    X = np.empty((N, L))
    acc = np.empty(L)
    no_ex = np.empty(0)
    f = 0
    n_ex = ex_idx.size
    for k in range(n_s):
        while f < n_ex and ex_idx[f] < k:
            f += 1
        ex = ex_val[f] if (f < n_ex and ex_idx[f] == k) else no_ex
        _iterate_ref(lw, lw0, mean, cov, ys[k], r, cs, qd, kb, B, grid, edges, u, log_floor, q_lo,
                 q_hi, eps, p_off, p_on, null_var, p0, amb_rel, amb_abs, temper, null_mix, hold,
                 cur, ex, w, v, X, acc, outs[k], post, gll)
        if want_post:
            for j in range(N):
                posts[k, j] = post[j]
        if want_gll:
            for j in range(N + 1):
                glls[k, j] = gll[j]
    return outs, posts, glls


@pytest.fixture(scope="module")
def drive():
    """A 20 s car drive's pre-filtered tracked axis (a NaN burst and lone NaNs inside, one of
    them on an evidence row), its comb evidence rows and the causal grid tracker's config."""
    rec = sim.simulate("car", seed=3, duration=20.0)
    config, Y, _, _ = _prepare(rec, "y", {"n_grid": 60, "smooth": "none"})
    y = np.array(Y if Y.ndim == 1 else Y[:, 0], dtype=np.float64)
    idx, vals = grid.evidence(config, Y)
    y[700:730] = np.nan
    y[int(idx[5])] = np.nan
    y[1501] = np.nan
    return config.tracker, y, np.asarray(idx, dtype=np.int64), np.asarray(vals)


VARIANTS = {
    "default": {},
    "white null": {"null_model": "white"},
    "no null state": {"off_rate": 0.0},
    "no null, no jumps": {"off_rate": 0.0, "jump_rate": 0.0},
    "two-component kernel": {"p_fast": 0.05, "q_omega_fast": 400.0},
    "exact kernel": {"kernel": "exact"},
    "mode hold, M = 2": {"mode_hold": 2.0, "M": 2},
    "M = 4, paper temper": {"M": 4, "temper": 1.0, "temper_fs": None},
}


def _variant(tr, name):
    kw = dict(VARIANTS[name])
    M = kw.pop("M", None)
    if M is not None:
        kw["model"] = dataclasses.replace(tr.model, M=M)
    return dataclasses.replace(tr, **kw)


def _reference(tr, y, idx, vals):
    st = gf.init(tr)
    lw = np.array(st.log_w, dtype=np.float64)
    lw0 = np.array([st.log_w_null])
    mean = np.array(st.mean, dtype=np.float64)
    cov = np.array(st.cov, dtype=np.float64)
    cur = np.array([st.mode_j], dtype=np.int64)
    N = tr.n_grid
    ex = np.zeros((idx.size, N + 1))
    ex[:, : vals.shape[1]] = vals
    outs, posts, glls = _run_ref(gf.tables(tr), lw, lw0, mean, cov, cur, y, idx, ex, True, True)
    return outs, posts, glls, lw, float(lw0[0]), mean, cov, int(cur[0])


def _close(a, b, rtol):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape
    assert np.array_equal(np.isnan(a), np.isnan(b))
    assert np.array_equal(a[np.isinf(b)], b[np.isinf(b)])  # log(0) where there is no state
    f = np.isfinite(b)
    scale = np.maximum(np.abs(b[f]), 1e-300)
    err = np.abs(a[f] - b[f])
    # relative, or absolute against the array's size where an entry is near 0 by cancellation
    ok = (err <= rtol * scale) | (err <= rtol * 1e-6 * np.max(np.abs(b[f]), initial=1.0))
    assert ok.all(), f"largest relative difference {np.max(err / scale):.3g}"


@pytest.mark.parametrize("name", list(VARIANTS))
@pytest.mark.parametrize("with_extra", [True, False])
def test_structure_of_arrays_loop_equals_the_per_point_loop(drive, name, with_extra):
    tr0, y, idx, vals = drive
    tr = _variant(tr0, name)
    if not with_extra:
        idx, vals = idx[:0], vals[:0]
    res = gf.run(tr, y, return_posterior=True, return_grid_loglik=True, extra=(idx, vals))
    outs, posts, glls, lw, lw0, mean, cov, cur = _reference(tr, y, idx, vals)
    assert res.amplitudes.shape[1] == tr.model.M
    assert np.isfinite(res.omega).all() and np.any(np.isnan(y))
    _close(res.omega, outs[:, 0] if tr.point == "mean" else outs[:, 11], 1e-9)
    _close(res.omega_lo, outs[:, 3], 1e-9)
    _close(res.omega_hi, outs[:, 4], 1e-9)
    _close(res.p_null, outs[:, 6], 1e-9)
    _close(res.loglik, outs[:, COL_LOGLIK], 1e-9)
    _close(res.amplitudes, outs[:, N_OUT_FIXED:], 1e-9)
    _close(res.posterior, posts, 1e-9)
    _close(res.grid_loglik[:, :-1], glls[:, :-1], 1e-9)
    if tr.has_null:  # without the state, the reference left the last column unwritten
        _close(res.grid_loglik[:, -1], glls[:, -1], 1e-9)
    else:
        ex_last = np.zeros(y.size)
        ex_last[idx] = vals[:, -1] if vals.shape[1] == tr.n_grid + 1 else 0.0
        assert np.array_equal(res.grid_loglik[:, -1], ex_last.astype(np.float32))
    fin = res.final
    _close(fin.log_w, lw, 1e-9)
    _close(fin.log_w_null, lw0, 1e-9)
    _close(fin.mean, mean, 1e-9)
    _close(fin.cov, cov, 1e-9)
    assert fin.mode_j == cur


@pytest.mark.parametrize("name", ["default", "exact kernel", "mode hold, M = 2"])
def test_compiled_step_equals_the_run(drive, name):
    tr0, y, idx, vals = drive
    tr = _variant(tr0, name)
    n = 260  # past the first evidence rows and into the NaN burst's neighbourhood
    y = np.concatenate([y[:n - 20], y[700:720]])
    keep = idx < n
    idx, vals = idx[keep], vals[keep]
    res = gf.run(tr, y, return_posterior=True, extra=(idx, vals))
    st = gf.init(tr)
    rows = dict(zip(idx.tolist(), vals, strict=True))
    for k in range(n):
        st, est = gf.step(tr, st, y[k], extra=rows.get(k))
        assert np.isclose(est.omega, res.omega[k], rtol=1e-12, atol=0.0)
        assert np.allclose(est.extras["posterior"], res.posterior[k], rtol=1e-6, atol=1e-12)
        assert np.isclose(est.extras["loglik"], res.loglik[k], rtol=1e-12, atol=1e-300)
    _close(st.mean, res.final.mean, 1e-12)
    _close(st.cov, res.final.cov, 1e-12)
    _close(st.log_w, res.final.log_w, 1e-12)
