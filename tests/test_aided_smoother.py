"""The aided grid smoother (issue 13): forward-backward with the acceleration shift inside the
transition (:mod:`vibrospeed.estimators.aided_grid.smoother`)."""

import dataclasses

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import aided_grid, rbpmf
from vibrospeed.estimators import grid as gridmod
from vibrospeed.estimators.aided_grid import smoother as asm
from vibrospeed.estimators.grid import smoother as gsm
from vibrospeed.models.harmonic import HarmonicModel

R_WHEEL = 0.08


def _config(**kw) -> aided_grid.Config:
    model = HarmonicModel(M=2, dt=0.01, q_omega=1.0, q_amp=0.004, r=0.25, p0_amp=0.1)
    tr = rbpmf.Config(model=model, n_grid=61, omega_min=5.0, omega_max=20.0, scaling="none",
                      prefilter="thesis-hplp", off_rate=0.05, on_rate=0.5, jump_rate=0.05,
                      null_model="mixture", point="mode", kernel_var="matched")
    return aided_grid.Config(tracker=tr, standstill="broadband", aiding="continuous",
                             wheel_radius=R_WHEEL, **kw)


def _comb(cfg: aided_grid.Config) -> gridmod.Config:
    return gridmod.Config(tracker=cfg.tracker, comb_window=1.0, comb_hop=0.1,
                          comb_min_window=0.5)


def _line(n=800, accel=0.06, seed=0):
    """A two-harmonic wheel line whose omega ramps at accel / r from 8 rad/s, in noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.01
    w = 8.0 + accel / R_WHEEL * t
    ph = np.cumsum(w) * 0.01
    y = np.sin(ph) + 0.5 * np.sin(2 * ph) + 0.5 * rng.normal(size=n)
    return y, w


def test_zero_acceleration_is_the_grid_smoother():
    """u = 0: no hop moves the posterior, the emissions are the RBPMF's and the smoothed
    columns those of the grid smoother on them (bitwise)."""
    cfg = _config()
    y, _ = _line()
    ev = gridmod.evidence(_comb(cfg), y, centre=True)
    fw = asm.forward(cfg, y, np.zeros(y.size), extra=ev)
    assert not fw.shift.any()
    ref = rbpmf.run(cfg.tracker, y, return_grid_loglik=True, extra=ev)
    np.testing.assert_array_equal(fw.filt.grid_loglik, ref.grid_loglik)
    a = asm.smooth(cfg, fw)
    b = gsm.smooth(cfg.tracker, ref.grid_loglik)
    for name in ("omega", "omega_std", "omega_lo", "omega_hi", "p_null", "omega_mode"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_forward_is_repeated_step():
    """The forward pass in hop-long RBPMF runs gives the numbers of repeated aided step (same
    end-referred comb evidence, standing samples in the hops, NaN in u)."""
    cfg = _config(aid_hop=0.05)
    comb = _comb(cfg)
    y, _ = _line(n=400)
    u = np.full(y.size, 0.06)
    u[200:207] = np.nan
    still = np.zeros(y.size)
    still[:40] = 1.0
    fw = asm.forward(cfg, y, u, still=still, extra=gridmod.evidence(comb, y))
    cfg_s = dataclasses.replace(cfg, comb=comb)
    st = aided_grid.init(cfg_s)
    for k in range(y.size):
        st, est = aided_grid.step(cfg_s, st, y[k], u[k], still=still[k])
        assert est.omega == fw.filt.omega[k] and est.omega_std == fw.filt.omega_std[k]
        assert est.omega_lo == fw.filt.omega_lo[k] and est.omega_hi == fw.filt.omega_hi[k]
    np.testing.assert_array_equal(st.grid.log_w, fw.filt.final.log_w)
    # the hops: (T / r) sum u over 5 samples, in cells, standing and NaN samples left out
    hop = cfg.aid_len
    assert hop == 5
    ends = np.flatnonzero(fw.shift)
    assert ends[0] == 44 and np.all(np.diff(ends) % hop == 0)
    np.testing.assert_allclose(fw.shift[ends[0]], 5 * 0.01 * 0.06 / R_WHEEL / cfg.dx)
    np.testing.assert_allclose(fw.shift[204], 0.0)  # 200..204: all NaN
    np.testing.assert_allclose(fw.shift[209], 3 * 0.01 * 0.06 / R_WHEEL / cfg.dx)
    # the filtered weights recomputed from the emissions and shifts are the filter's
    alpha = asm.filtered(cfg, fw)
    np.testing.assert_allclose(alpha[:, -1], fw.filt.p_null, atol=1e-6)


def _brute_force(cfg: aided_grid.Config, gll: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """Forward-backward of the aided chain with dense (N+1) x (N+1) matrices in float64:
    transition T_t = T S_t (the grid's walk, jumps and "no line" state, then the line part
    moved by shift[t] cells, split linearly between neighbours, clamped at the ends)."""
    tr = cfg.tracker
    k = tr.kern
    N, B = k.grid.size, int(k.B)
    K = np.zeros((N, N))
    for j in range(N):
        for d in range(2 * B + 1):
            i = j + d - B
            if 0 <= i < N:
                K[i, j] = k.kb[j, d]
    eps, p_off, p_on, _ = tr.rates()
    uj = k.widths / k.widths.sum()
    T = np.zeros((N + 1, N + 1))
    T[:N, :N] = (1 - eps - p_off) * K + eps * uj[None, :]
    T[:N, N] = p_off
    T[N, :N] = p_on * uj
    T[N, N] = 1 - p_on

    def S(s):
        out = np.eye(N + 1)
        if s == 0:
            return out
        out[:N, :N] = 0.0
        kk, f = int(np.floor(s)), s - np.floor(s)
        for i in range(N):
            out[i, min(max(i + kk, 0), N - 1)] += 1 - f
            out[i, min(max(i + kk + 1, 0), N - 1)] += f
        return out

    st = rbpmf.init(tr)
    prior = np.exp(np.append(st.log_w, st.log_w_null))
    prior /= prior.sum()
    lik = np.exp(gll.astype(np.float64) - gll.max(axis=1, keepdims=True))
    n = gll.shape[0]
    alpha = np.zeros((n, N + 1))
    trans = [T @ S(shift[t]) for t in range(n)]
    p = prior
    for t in range(n):
        a = p * lik[t]
        alpha[t] = a / a.sum()
        p = alpha[t] @ trans[t]
    beta = np.ones(N + 1)
    post = np.zeros((n, N + 1))
    for t in range(n - 1, -1, -1):
        if t < n - 1:
            beta = trans[t] @ (lik[t + 1] * beta)
            beta /= beta.max()
        g = alpha[t] * beta
        post[t] = g / g.sum()
    return post


def test_constant_acceleration_against_brute_force():
    """A synthetic line accelerating at a known constant rate, aided by it: the smoothed grid
    posterior equals a dense forward-backward in plain numpy over the same grid."""
    cfg = _config()
    accel = 0.06
    y, w = _line(n=600, accel=accel)
    ev = gridmod.evidence(_comb(cfg), y, centre=True)
    fw = asm.forward(cfg, y, np.full(y.size, accel), extra=ev)
    assert np.count_nonzero(fw.shift) == y.size // cfg.aid_len
    sm = asm.smooth(cfg, fw, return_posterior=True)
    ref = _brute_force(cfg, fw.filt.grid_loglik, fw.shift)
    np.testing.assert_allclose(sm.posterior, ref[:, :-1], atol=2e-5)
    np.testing.assert_allclose(sm.p_null, ref[:, -1], atol=2e-5)
    # the same chain without the shift is a different answer (the test can tell them apart)
    assert np.max(np.abs(_brute_force(cfg, fw.filt.grid_loglik, 0 * fw.shift)[:, :-1]
                         - ref[:, :-1])) > 1e-2


def test_scope_errors():
    cfg = _config()
    with pytest.raises(ParameterError, match="continuous"):
        asm.forward(dataclasses.replace(cfg, aiding="mode"), np.zeros(10))
    on_grid = dataclasses.replace(cfg, tracker=dataclasses.replace(cfg.tracker, omega_min=0.0))
    with pytest.raises(ParameterError, match="omega_min > 0"):
        asm.forward(on_grid, np.zeros(10))


def test_offline_tracker_grid_on_a_named_axis():
    """-m aided -p tracker=grid offline with the cart's a_x named: unaided (aiding=none) it is
    -m grid's smoothed estimate bitwise (the same emissions, mid-frame comb evidence and
    stops); aided, the smoother's error on the thesis' stop-and-go cart is under half of it."""
    from vibrospeed import sim
    from vibrospeed.estimators import aided

    rec = sim.simulate("stop_and_go", seed=2, duration=60)
    w = rec["omega_true"]
    p = {"omega_min": 2.0, "omega_max": 40.0, "tracker": "grid", "accel_axis": "ax"}
    un = aided.estimate(rec, params={**p, "aiding": "none"})
    ref = gridmod.estimate(rec, params={"omega_min": 2.0, "omega_max": 40.0})
    for name in ("omega", "omega_std", "omega_lo", "omega_hi"):
        np.testing.assert_array_equal(getattr(un, name), getattr(ref, name))
    for name in ("p_null", "has_signal", "standstill"):
        np.testing.assert_array_equal(un.extras[name], ref.extras[name])
    tr = aided.estimate(rec, params=p)
    assert tr.params["smoother"] == "aided-fb" and tr.params["aiding"] == "continuous"
    np.testing.assert_array_equal(tr.extras["standstill"], ref.extras["standstill"])
    err = np.sqrt(np.mean((tr.omega - w) ** 2))
    err0 = np.sqrt(np.mean((un.omega - w) ** 2))
    assert err < 0.5 * err0


def test_checkpointed_is_the_whole_log_pass():
    """The checkpointed smoother (forward state every K samples, alpha recomputed segment by
    segment from the emissions and the shifts) gives the whole-log pass's columns and
    posterior bitwise, for K that divides n or not, K = 1, K >= n, and keep = 0 / a few
    segments / the whole log; the posterior at chosen sample indices is those rows."""
    cfg = _config()
    y, _ = _line(n=600, accel=0.06, seed=3)
    u = np.full(y.size, 0.06)
    u[300:330] = -0.1
    still = np.zeros(y.size)
    still[:30] = 1.0
    fw = asm.forward(cfg, y, u, still=still, extra=gridmod.evidence(_comb(cfg), y, centre=True))
    assert np.count_nonzero(fw.shift) > 50 and np.any(fw.shift < 0)
    ref = asm.smooth(cfg, fw, return_posterior=True, checkpoint=None)
    names = [f for f in ref._fields if getattr(ref, f) is not None]
    assert "posterior" in names and "omega_mode" in names
    for K in (1, 7, 100, 150, 599, 600, 1000):
        for keep in (0, 64, 250, 10_000, None):
            got = asm.smooth(cfg, fw, return_posterior=True, checkpoint=K, keep=keep)
            for name in names:
                np.testing.assert_array_equal(getattr(got, name), getattr(ref, name),
                                              err_msg=f"{name}, checkpoint={K}, keep={keep}")
    idx = np.array([0, 99, 100, 101, 417, 599])
    part = asm.smooth(cfg, fw, return_posterior=idx, checkpoint=64, keep=100)
    np.testing.assert_array_equal(part.posterior, ref.posterior[idx])
    np.testing.assert_array_equal(part.omega, ref.omega)
    with pytest.raises(ParameterError, match="checkpoint"):
        asm.smooth(cfg, fw, checkpoint=0)
