"""The grid tracker product (issue 7): comb evidence, streaming == batch, harmonic-order and
engine-line behaviour, ambiguity masses for omega/3 and 3 omega."""

import dataclasses

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid, rbpmf
from vibrospeed.estimators.grid import comb
from vibrospeed.types import Recording


def _small(dt=0.01, **kw):
    tr = rbpmf.improved(rbpmf.Config.from_paper_table1(dt), n_grid=40, omega_min=10.0,
                        omega_max=60.0, temper=0.2, off_rate=0.01)
    return grid.Config(tracker=tr, comb_window=0.64, comb_hop=0.1, **kw)


def _ref_median(P, medw):
    """Running median at every max(1, medw // 8)-th bin (edges repeated), linear in between."""
    h = medw // 2
    st = max(1, medw // 8)
    pad = np.concatenate([np.full(h, P[0]), P, np.full(h, P[-1])])
    cent = sorted({min(c, P.size - 1) for c in range(0, P.size + st - 1, st)})
    med = [np.median(pad[c:c + medw]) for c in cent]
    return np.interp(np.arange(P.size), cent, med)


def _ref_comb(cfg, x, dt):
    """Comb evidence (unweighted) of one zero-mean frame sampled every dt: direct DFT sums at
    the zero-padded bins, running-median background, linear interpolation, caps and lead."""
    tr = cfg.tracker
    L = x.size
    nfft = 1 << int(np.ceil(np.log2(4 * L)))
    n = np.arange(L)
    hann = 0.5 - 0.5 * np.cos(2 * np.pi * n / (L - 1))
    P = np.array([abs(np.sum(x * hann * np.exp(-2j * np.pi * b * n / nfft))) ** 2
                  for b in range(nfft // 2 + 1)])
    bg = max(cfg.comb_bg, 6.0 / (L * tr.model.dt))  # >= 1.5 Hann main lobes
    medw = max(3, int(round(bg * dt * nfft)) | 1)
    S = P / (_ref_median(P, medw) / np.log(2))
    df = 2 * np.pi / (dt * nfft)
    a = cfg.comb_snr
    fs = 1.0 / tr.model.dt
    out = np.zeros(tr.n_grid)
    for j, om in enumerate(tr.grid):
        terms = []
        for k in range(1, tr.model.M + 1):
            w = k * om
            ws = 2 * np.pi * fs
            w = abs((w + ws / 2) % ws - ws / 2)  # alias
            p = w / df
            i0 = min(int(p), S.size - 2)
            s = S[i0] * (1 - (p - i0)) + S[i0 + 1] * (p - i0)
            terms.append(min(s * a / (1 + a) - np.log1p(a), cfg.comb_cap))
        terms = sorted(terms, reverse=True)
        if len(terms) >= 2:  # the best harmonic leads the second by <= comb_lead
            terms[0] = min(terms[0], terms[1] + cfg.comb_lead)
        out[j] = sum(terms)
    return out


def _reference_evidence(cfg, frame, centre=False):
    """Independent loop form of the comb evidence (module docstring): per relative rate b the
    frame resampled (np.interp) at the times s where tau = s + b s^2 / 2 is uniform, then
    log sum_b p_b exp(E_b)."""
    tr = cfg.tracker
    dt = tr.model.dt
    L = frame.size
    x = np.nan_to_num(frame) - np.mean(np.nan_to_num(frame))
    c = (L - 1) / 2 if centre else L - 1  # the reference time: the frame's middle or end
    s_i = (np.arange(L) - c) * dt
    ok = (lambda b: abs(b) < 1.8 / (L * dt)) if centre else (lambda b: b < 0.9 / (L * dt))
    rates = [0.0] + [b for b in cfg.comb_rates if b != 0 and ok(b)]
    p = [1.0] if len(rates) == 1 else [cfg.comb_rate_p0] + [
        (1 - cfg.comb_rate_p0) / (len(rates) - 1)] * (len(rates) - 1)
    E = []
    for b in rates:
        if b == 0:
            E.append(_ref_comb(cfg, x, dt))
            continue
        tau = np.linspace(s_i[0] + 0.5 * b * s_i[0] ** 2, s_i[-1] + 0.5 * b * s_i[-1] ** 2, L)
        # the root of b s^2 / 2 + s - tau = 0 on the frame (the other lies beyond +-1/b)
        s = np.array([min(np.roots([0.5 * b, 1.0, -t]).real, key=lambda r, t=t: abs(r - t))
                      for t in tau])
        E.append(_ref_comb(cfg, np.interp(s, s_i, x), (tau[-1] - tau[0]) / (L - 1)))
    E = np.array(E)
    out = np.zeros(tr.n_grid + 1)
    out[:-1] = np.log(np.sum(np.array(p)[:, None] * np.exp(E), axis=0))
    out[:-1] *= cfg.comb_weight
    return out


def test_frame_evidence_matches_loop_reference():
    cfg = _small()
    rng = np.random.default_rng(3)
    t = np.arange(cfg.frame_len) * 0.01
    fr = np.sin(30 * t) + 0.5 * np.sin(60 * t + 1) + 0.3 * rng.normal(size=t.size)
    fr[5] = np.nan
    got = grid.frame_evidence(cfg, fr[None, :], raw=True)[0]
    ref = _reference_evidence(cfg, fr)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(grid.frame_evidence(cfg, fr[None, :], centre=True, raw=True)[0],
                               _reference_evidence(cfg, fr, centre=True), rtol=1e-9, atol=1e-9)
    one = dataclasses.replace(cfg, comb_rates=(0.0,))  # no warps: the stationary evidence
    np.testing.assert_allclose(grid.frame_evidence(one, fr[None, :], raw=True)[0],
                               _reference_evidence(one, fr), rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("lead", [1.0, float("inf")])
def test_frame_evidence_lead_matches_loop_reference(lead):
    cfg = _small(comb_lead=lead, comb_snr=3.0)
    rng = np.random.default_rng(4)
    t = np.arange(cfg.frame_len) * 0.01
    fr = 2 * np.sin(45 * t) + 0.2 * np.sin(30 * t) + 0.3 * rng.normal(size=t.size)
    np.testing.assert_allclose(grid.frame_evidence(cfg, fr[None, :], raw=True)[0],
                               _reference_evidence(cfg, fr), rtol=1e-9, atol=1e-9)


def test_comb_beats_single_strong_line_and_single_line_scores_below_null():
    cfg = grid.Config(tracker=grid._default_tracker(0.01))
    rng = np.random.default_rng(0)
    t = np.arange(cfg.frame_len) * 0.01
    noise = 0.2 * rng.normal(size=t.size)
    comb = 0.3 * (np.sin(20 * t) + np.sin(40 * t + 1) + np.sin(60 * t + 2))
    line = 2.0 * np.sin(90 * t)
    e = grid.frame_evidence(cfg, (comb + line + noise)[None, :])[0]
    g = cfg.tracker.grid
    assert abs(g[np.argmax(e[:-1])] - 20) < 1.0  # the comb, not the strong line (or line/k)
    e1 = grid.frame_evidence(cfg, (line + noise)[None, :])[0]
    # a single line, however strong, is worth at most comb_lead more than its best companion:
    # the line's hypotheses (90, 45, 30 rad/s) score below the "no line" state (0), the weak
    # comb well above it; without the lead limit they would score the capped line
    js = [int(np.argmin(abs(g - w))) for w in (90.0, 45.0, 30.0)]
    assert np.all(e1[js] < 0.0) and np.max(e[:-1]) > 2.0
    assert e1[-1] == 0.0
    e1_free = grid.frame_evidence(dataclasses.replace(cfg, comb_lead=np.inf),
                                  (line + noise)[None, :])[0]
    assert np.all(e1_free[js] > 0.0)


def test_step_equals_run_with_nan_and_chunks():
    cfg = _small()
    rng = np.random.default_rng(1)
    t = np.arange(300) * 0.01
    y = 0.5 * np.sin(35 * t) + 0.3 * np.sin(70 * t) + 0.2 * rng.normal(size=t.size)
    y[50:53] = np.nan
    st = grid.init(cfg)
    om = []
    for v in y:
        st, e = grid.step(cfg, st, v)
        om.append(e.omega)
    res = grid.run(cfg, y)
    assert res.frames.size == 1 + (300 - cfg.frame_len) // cfg.hop_len
    np.testing.assert_array_equal(np.array(om), res.filt.omega)
    np.testing.assert_array_equal(st.grid.log_w, res.final.grid.log_w)
    np.testing.assert_array_equal(st.buf, res.final.buf)
    a = grid.run(cfg, y[:137])
    b = grid.run(cfg, y[137:], a.final)
    np.testing.assert_array_equal(np.concatenate([a.filt.omega, b.filt.omega]), res.filt.omega)


def test_zero_comb_weight_is_the_rbpmf():
    cfg = _small(comb_weight=0.0)
    rng = np.random.default_rng(2)
    y = rng.normal(size=200)
    np.testing.assert_array_equal(grid.run(cfg, y).filt.omega,
                                  rbpmf.run(cfg.tracker, y).omega)


def test_bad_params():
    with pytest.raises(ParameterError):
        grid.Config(comb_hop=0.0)
    with pytest.raises(ParameterError):
        rbpmf.Config(temper=0.0)


def test_third_and_triple_masses():
    cfg = rbpmf.Config(n_grid=111, omega_min=10.0, omega_max=120.0)
    g = cfg.grid
    w = np.zeros(g.size)
    j30, j10, j90 = (int(np.argmin(abs(g - x))) for x in (30.0, 10.0, 90.0))
    w[j30], w[j10], w[j90] = 0.6, 0.25, 0.15
    out = np.zeros(rbpmf.N_OUT_FIXED)
    k = cfg.kern
    rbpmf._summary(w, 0.0, k.widths / k.widths.sum(), g, k.edges, 0.01, 0.99, 0.05, 1.5,
                   np.empty(g.size), out, 1.0, np.full(1, -1, np.int64))
    assert out[2] == g[j30]
    assert out[9] == pytest.approx(0.25) and out[10] == pytest.approx(0.15)
    assert out[7] == 0.0 and out[8] == 0.0


def test_cart_third_harmonic_not_taken_even_with_the_paper_prefilter():
    """Issue 7 failure: lines at 10, 20, 30 rad/s and a 13 Hz resonance; the improved RBPMF with
    the paper's 8 Hz high-pass locked on ~28 rad/s. The grid tracker must stay on 10."""
    from vibrospeed import sim

    rec = sim.simulate("cart", seed=1, duration=60.0)
    tru = rec["omega_true"]
    mov = tru > 5
    p = {"omega_min": 2.0, "omega_max": 30.0, "prefilter": "paper-hp"}
    old = rbpmf.estimate(rec, params={**p, "improved": True})
    new = grid.estimate(rec, params=p)
    ok_old = np.mean(np.abs(old.omega - tru)[mov] <= np.maximum(2, 0.1 * tru[mov]))
    ok_new = np.mean(np.abs(new.omega - tru)[mov] <= np.maximum(2, 0.1 * tru[mov]))
    assert ok_old < 0.7 and ok_new > 0.8
    assert any("passes only" in n for n in old.notes)


def test_wheel_comb_tracked_next_to_stronger_engine_line():
    """Car-like low speed: a comb of three weak wheel harmonics around 25 rad/s and an engine
    line 2.5 times stronger at 150 rad/s (= 6 omega: hypotheses 50 and 75 explain it). The
    improved RBPMF follows the line's sub-multiples part of the time; the grid tracker the comb."""
    rng = np.random.default_rng(6)
    t = np.arange(0, 40, 0.01)
    om = 25.0 + 5 * np.sin(0.2 * t)
    ph = np.cumsum(om) * 0.01
    ay = (0.1 * (np.sin(ph) + np.sin(2 * ph + 1) + np.sin(3 * ph + 2))
          + 0.25 * np.sin(150 * t) + 0.1 * rng.normal(size=t.size))
    rec = Recording(t, {"ay": ay})
    old = rbpmf.estimate(rec, params={"improved": True, "prefilter": "thesis-hp"})
    ok_old = np.mean(np.abs(old.omega - om)[1000:] < 2.0)
    for sm in ("none", "fb"):
        tr = grid.estimate(rec, params={"smooth": sm})
        ok = np.mean(np.abs(tr.omega - om)[1000:] < 2.0)
        assert ok > 0.9 and ok > ok_old + 0.1, (sm, ok, ok_old)


def test_config_roundtrip_params():
    rec = Recording(np.arange(0, 5, 0.01), {"ay": np.sin(40 * np.arange(0, 5, 0.01))})
    tr = grid.estimate(rec, params={"comb_weight": 0.25, "n_grid": 50, "smooth": "none"})
    assert tr.params["comb_weight"] == 0.25 and tr.params["n_grid"] == 50
    assert tr.params["temper"] == grid.GRID_DEFAULTS["temper"]
    assert tr.method == "grid"
    assert dataclasses.is_dataclass(grid.Config())


def test_claim_level_per_smoothing_mode():
    """has_signal = (1 - p_null >= level) with the level of CLAIM_LEVEL for the mode unless
    given; the streaming Config (causal) claims at the causal level."""
    t = np.arange(0, 12, 0.01)
    rng = np.random.default_rng(3)
    ay = 0.3 * np.sin(40 * t) + 0.2 * np.sin(80 * t) + 0.3 * rng.normal(size=t.size)
    rec = Recording(t, {"ay": ay})
    assert grid.CLAIM_LEVEL["none"] > grid.CLAIM_LEVEL["lag"] > grid.CLAIM_LEVEL["fb"]
    assert grid.Config().tracker.claim_level == grid.CLAIM_LEVEL["none"]
    for sm, given in (("none", None), ("lag", None), ("fb", None), ("none", 0.6)):
        p = {"smooth": sm, "n_grid": 60}
        if given is not None:
            p["claim_level"] = given
        tr = grid.estimate(rec, params=p)
        level = grid.CLAIM_LEVEL[sm] if given is None else given
        assert tr.params["claim_level"] == level
        p_line = 1.0 - tr.extras["p_null"]
        moving = tr.extras["standstill"] < 0.5
        np.testing.assert_array_equal(tr.extras["has_signal"][moving] > 0.5,
                                      p_line[moving] >= level)


def test_default_walk_in_proportion_to_the_range():
    """q_omega defaults to 16 omega_max / 120 (rad/s)^2/s: the car's 10-120 rad/s keeps the
    paper's 16, a cart's 2-30 gets 4, a kart's 20-300 40; a given q_omega (or a preset's) is
    kept; the aided tracker on the grid uses the grid product's walk for its range."""
    from vibrospeed.estimators import aided

    t = np.arange(0, 6, 0.005)
    rec = Recording(t, {"ay": np.sin(20 * t), "ax": 0.1 * np.cos(3 * t), "az": 0 * t})
    rec.wheel_radius = 0.2

    def q(params):
        return grid.config_for(rec, params=params).tracker.model.q_omega

    assert q({}) == 16.0
    assert q({"omega_min": 2, "omega_max": 30}) == 4.0
    assert q({"omega_min": 20, "omega_max": "300"}) == 40.0
    assert q({"omega_min": 2, "omega_max": 30, "q_omega": 9}) == 9.0
    assert grid.q_omega_for(120.0) == 16.0
    cart = {"omega_min": 2.0, "omega_max": 30.0, "n_grid": 40}
    a = aided.estimate(rec, wheel_radius=0.2, params={**cart, "tracker": "grid"})
    assert a.params["q_omega"] == 4.0
    g = grid.estimate(rec, params=dict(cart))
    assert g.params["q_omega"] == 4.0


def test_mixture_null_gets_no_time_domain_evidence():
    """null_model="mixture": the "no line" state's emission is the signal part's predictive
    mixture, so without extra evidence p_null follows the two-state switching chain alone
    (analytic: started stationary, it stays off / (off + on)) whatever the data, here a pure
    strong sinusoid that the white null would reject at once."""
    tr = rbpmf.improved(rbpmf.Config.from_paper_table1(0.01), n_grid=40, omega_min=10.0,
                        omega_max=60.0, off_rate=0.2, on_rate=0.5, null_model="mixture")
    t = np.arange(400) * 0.01
    y = np.sin(30 * t)
    y[100:103] = np.nan
    res = rbpmf.run(tr, y)
    _, p_off, p_on, _ = tr.rates()
    ref = np.empty(y.size)  # the two-state chain's prior, = the posterior (no evidence)
    p = 0.2 / 0.7  # init: off / (off + on)
    for k in range(y.size):
        ref[k] = p
        p = p_off * (1 - p) + (1 - p_on) * p
    np.testing.assert_allclose(res.p_null, ref, rtol=1e-9)
    # the data still place omega (on the line or a sub-multiple the 3-harmonic model allows)
    assert min(abs(np.median(res.omega[200:]) - 30 / k) for k in (1, 2, 3)) < 1.0
    white = rbpmf.run(dataclasses.replace(tr, null_model="white"), y)
    assert white.p_null[-1] < 0.01 < 0.2 < res.p_null[-1]
    st = rbpmf.init(tr)
    for v in y[:150]:
        st, e = rbpmf.step(tr, st, v)
    assert e.p_null == pytest.approx(res.p_null[149], rel=1e-12)
    with pytest.raises(ParameterError):
        rbpmf.Config(null_model="ar")


def test_single_engine_line_is_no_signal_and_a_comb_is():
    """Issue 7 standstill: an idling-engine line (84 rad/s) alone must read "no signal"; a
    wheel comb at 40 rad/s next to the same line must read "signal" and be tracked."""
    rng = np.random.default_rng(8)
    t = np.arange(0, 24, 0.01)
    eng = 0.3 * np.sin(83.8 * t + 0.5) + 0.1 * rng.normal(size=t.size)
    comb = 0.15 * (np.sin(40 * t) + np.sin(80 * t + 1) + np.sin(120 * t + 2))
    for y, line in ((eng, False), (eng + comb, True)):
        tr = grid.estimate(Recording(t, {"ay": y}), params={"smooth": "none"})
        hs = tr.extras["has_signal"][600:]
        if line:
            assert hs.mean() > 0.9
            assert np.median(np.abs(tr.omega[600:] - 40)) < 1.0
        else:
            assert hs.mean() < 0.1


def test_growing_start_frames_match_reference_and_stream():
    cfg = _small(comb_min_window=0.2)  # frames of 20, 30, ..., 60 samples, then full (64)
    rng = np.random.default_rng(5)
    t = np.arange(200) * 0.01
    y = 0.5 * np.sin(35 * t) + 0.3 * np.sin(70 * t) + 0.2 * rng.normal(size=t.size)
    y[25:27] = np.nan
    idx, vals = grid.evidence(cfg, y)
    L, H = cfg.frame_len, cfg.hop_len
    grow = np.arange(19, L - 1, H)
    full = np.arange(L - 1, y.size, H)
    np.testing.assert_array_equal(idx, np.r_[grow, full])
    for e, v in zip(idx, vals, strict=True):  # each frame: the (up to L) samples up to e
        fr = y[max(0, e - L + 1):e + 1]  # centred on what white noise gives each grid point
        ref = _reference_evidence(cfg, fr)
        ref[:-1] -= cfg.comb_weight * comb.noise_offsets(cfg, fr.size)
        np.testing.assert_allclose(v, ref, rtol=1e-7, atol=1e-7)
    # streaming == batch, split inside the growing phase
    res = grid.run(cfg, y)
    st = grid.init(cfg)
    om = []
    for v in y:
        st, est = grid.step(cfg, st, v)
        om.append(est.omega)
    np.testing.assert_array_equal(np.array(om), res.filt.omega)
    a = grid.run(cfg, y[:33])
    b = grid.run(cfg, y[33:], a.final)
    np.testing.assert_array_equal(np.r_[a.filt.omega, b.filt.omega], res.filt.omega)
    # comb_min_window >= comb_window: no growing frames (the earlier behaviour)
    idx2, _ = grid.evidence(dataclasses.replace(cfg, comb_min_window=1.0), y)
    np.testing.assert_array_equal(idx2, full)


def test_frame_ends_at_is_where_the_evidence_has_a_frame():
    """frame_ends_at (the step's shortcut) against the batch evidence's frame ends, growing
    frames included, over hop / window / start-frame combinations and a weight of 0."""
    y = np.random.default_rng(2).normal(size=260)
    for kw in ({}, {"comb_min_window": 0.2}, {"comb_min_window": 0.25, "comb_hop": 0.07},
               {"comb_min_window": 1.0}, {"comb_weight": 0.0}):
        cfg = dataclasses.replace(_small(), **kw)
        idx, _ = grid.evidence(cfg, y)
        got = np.flatnonzero([grid.frame_ends_at(cfg, g) for g in range(y.size)])
        np.testing.assert_array_equal(got, idx)


def test_short_start_frame_scores_a_clean_comb_in_full():
    """A 1 s start frame's Hann main lobe is 4 Hz wide: with a 2 Hz background the line
    would fill the running median and whiten itself away (each harmonic then scores ~0 instead
    of the cap). The background is at least 1.5 main lobes, so a clean comb scores every
    harmonic at the cap, exactly where it is."""
    cfg = grid.Config()
    rng = np.random.default_rng(8)
    t = np.arange(100) * 0.01  # 1 s: the first growing frame
    fr = (np.sin(50 * t) + 0.7 * np.sin(100 * t + 1) + 0.5 * np.sin(150 * t + 2)
          + 0.05 * rng.normal(size=t.size))
    E = grid.frame_evidence(cfg, fr[None, :], raw=True)[0, :-1]
    g = cfg.tracker.grid
    top = g[E >= E.max() - 0.01]  # the capped plateau around the comb
    assert abs(0.5 * (top.min() + top.max()) - 50.0) < 1.0 and np.ptp(top) < 6.0
    # every harmonic at the cap; the warped rates (which smear a steady comb) cost at most
    # log p0 in the rate average
    full = cfg.comb_weight * (cfg.tracker.model.M * cfg.comb_cap + np.log(cfg.comb_rate_p0))
    assert E[np.argmin(abs(g - 50.0))] >= full - 0.05


def test_warped_evidence_scores_an_accelerating_comb_at_its_current_frequency():
    # a comb accelerating linearly 40 -> 70 rad/s over a 3 s frame (relative rate at the end
    # 10 / 70 = 0.14 1/s): unwarped, the evidence peaks near the frame's mean frequency and the
    # line is smeared; warped, it peaks at the end frequency, higher
    tr = rbpmf.improved(rbpmf.Config.from_paper_table1(0.01), n_grid=200, omega_min=10.0,
                        omega_max=120.0)
    t = np.arange(300) * 0.01
    om = 40 + 10 * t
    th = 40 * t + 5 * t ** 2
    x = sum(a * np.cos(k * th) for k, a in ((1, 1.0), (2, 0.8), (3, 0.5)))
    x = x + 0.5 * np.random.default_rng(0).normal(size=t.size)
    g = tr.grid
    # (an SNR of 2 in the comb's likelihood ratio: the margin below was measured with it)
    warped = grid.frame_evidence(grid.Config(tracker=tr, comb_snr=2.0), x[None, :])[0, :-1]
    flat = grid.frame_evidence(grid.Config(tracker=tr, comb_rates=(0.0,), comb_snr=2.0),
                               x[None, :])[0, :-1]
    assert abs(g[np.argmax(warped)] - om[-1]) < 2.0
    assert abs(g[np.argmax(flat)] - om[-1]) > 10.0
    assert warped.max() > flat.max() + 1.0
    # and a steady comb keeps (nearly) its evidence: the warps only add alternatives
    xs = sum(a * np.cos(k * 55 * t) for k, a in ((1, 1.0), (2, 0.8), (3, 0.5)))
    xs = xs + 0.5 * np.random.default_rng(1).normal(size=t.size)
    ws = grid.frame_evidence(grid.Config(tracker=tr), xs[None, :], raw=True)[0, :-1]
    fs_ = grid.frame_evidence(grid.Config(tracker=tr, comb_rates=(0.0,)), xs[None, :],
                              raw=True)[0, :-1]
    assert abs(g[np.argmax(ws)] - 55) < 1.0
    assert ws.max() > fs_.max() + np.log(0.5) * 0.5 - 1e-9  # at worst the prior weight


def test_comb_rates_parameter():
    assert grid.Config(comb_rates="0.1:-0.1").comb_rates == (0.1, -0.1)
    assert grid.Config(comb_rates="0.1,-0.2").comb_rates == (0.1, -0.2)
    with pytest.raises(ParameterError):
        grid.Config(comb_rates="fast")
    with pytest.raises(ParameterError):
        grid.Config(comb_rate_p0=0.0)
    # rates whose warp would fold over a frame are left out (beta < 0.9 / W)
    cfg = grid.Config(comb_rates=(0.1, 0.5))
    np.testing.assert_array_equal(cfg.rates_in_frame(300), [0.0, 0.1])


def test_centre_referred_evidence_sits_mid_frame_and_scores_the_middle_frequency():
    tr = rbpmf.improved(rbpmf.Config.from_paper_table1(0.01), n_grid=200, omega_min=10.0,
                        omega_max=120.0)
    # a comb sweeping 40 -> 70 rad/s in the frame scores only ~0.2 nats mid-frame; with the
    # default SNR of 1 (softer cost of an empty harmonic) a 3/2 alias ties with it, so the
    # placement is checked with an SNR of 2
    cfg = grid.Config(tracker=tr, comb_snr=2.0)
    t = np.arange(300) * 0.01
    th = 40 * t + 5 * t ** 2  # omega = 40 + 10 t: 55 rad/s at the frame's middle
    x = sum(a * np.cos(k * th) for k, a in ((1, 1.0), (2, 0.8), (3, 0.5)))
    x = x + 0.5 * np.random.default_rng(0).normal(size=t.size)
    e = grid.frame_evidence(cfg, x[None, :], centre=True)[0, :-1]
    assert abs(tr.grid[np.argmax(e)] - 55.0) < 2.0
    y = np.random.default_rng(1).normal(size=2000)
    i_end, v_end = grid.evidence(cfg, y)
    i_mid, v_mid = grid.evidence(cfg, y, centre=True)
    full = i_end >= cfg.frame_len - 1
    assert np.isin(i_end[full] - (cfg.frame_len - 1) // 2, i_mid).all()
    assert np.all(np.diff(i_mid) > 0) and i_mid[0] >= 0
    # shrinking frames cover the end: the last evidence sits half a minimal frame from it
    half_min = int(round(cfg.comb_min_window / 0.01)) // 2
    assert y.size - 1 - i_mid[-1] <= half_min + cfg.hop_len
    # white noise: the smoother says "no line" up to the very end (without the shrinking
    # frames the last 1.5 s drifted to the switching chain's prior, "line")
    tr_n = grid.estimate(Recording(np.arange(y.size) * 0.01, {"ay": y}))
    assert tr_n.extras["has_signal"][-150:].max() == 0.0
    with pytest.raises(ValueError):
        grid.evidence(cfg, y, grid.init(cfg), centre=True)


@pytest.mark.parametrize("lag", [1.0, 2.5])
def test_grid_fixed_lag_uses_no_data_beyond_two_lags(lag):
    # with the evidence placed mid-frame the fixed-lag blocks shrink by half a frame, so a
    # sample's estimate must not change when data more than 2 lag s after it change
    rng = np.random.default_rng(7)
    t = np.arange(2400) * 0.01
    ay = np.sin(40 * t) + 0.5 * np.sin(80 * t) + 0.4 * rng.normal(size=t.size)
    ay2 = ay.copy()
    cut = 1600
    ay2[cut:] = rng.normal(size=t.size - cut)  # a different future from 16 s on
    p = {"smooth": "lag", "lag": lag, "omega_min": 10.0, "omega_max": 80.0, "n_grid": 80}
    a = grid.estimate(Recording(t, {"ay": ay}), params=p)
    b = grid.estimate(Recording(t, {"ay": ay2}), params=p)
    horizon = 2 * lag - 1.5 if lag > 1.5 else 2 * lag  # the note's "up to lag..2 lag - W/2"
    safe = t < t[cut] - horizon - 0.01
    np.testing.assert_array_equal(a.omega[safe], b.omega[safe])
    assert not np.array_equal(a.omega, b.omega)
    assert a.params["lag"] == lag  # the delay asked for is recorded
    if lag > 1.5:
        assert any("mid-frame" in n for n in a.notes)


@pytest.mark.parametrize("fs", [104.4, 100.0, 89.0, 44.0, 6.0])
def test_centre_evidence_indices_strictly_increase_at_any_rate(fs):
    # 104.4 Hz (a phone): the last growing frame (312 samples) and the first full one (313)
    # share their middle sample; the smoother needs strictly increasing evidence indices
    n = int(40 * fs)
    rec = Recording(np.arange(n) / fs, {"ay": np.random.default_rng(0).normal(size=n)})
    p = {"n_grid": 40, "omega_min": 2.0, "omega_max": min(120.0, 0.9 * np.pi * fs)}
    cfg, y, _, _ = grid._prepare(rec, "y", p)  # (6 Hz: hop of 2 samples, a 1 s growing step)
    idx, vals = grid.evidence(cfg, y, centre=True)
    assert np.all(np.diff(idx) > 0) and idx[0] >= 0 and idx.size == vals.shape[0]
    tr = grid.estimate(rec, params=p)  # the smoother runs
    assert tr.omega.shape == (n,)


def test_grid_is_scale_invariant():
    # a phone in g or in m/s^2, a car sensor cluster or a cart: the same track for a signal and
    # 1e-3 times it (running-RMS normalisation before the filter; whitened comb spectra)
    rng = np.random.default_rng(11)
    t = np.arange(1500) * 0.01
    om = 30 + 0.8 * t  # accelerating: the warped evidence is used
    th = np.cumsum(om) * 0.01
    ay = np.cos(th) + 0.6 * np.cos(2 * th) + 0.5 * rng.normal(size=t.size)
    p = {"n_grid": 60, "omega_min": 10.0, "omega_max": 70.0}
    a = grid.estimate(Recording(t, {"ay": ay}), params=p)
    b = grid.estimate(Recording(t, {"ay": 1e-3 * ay}), params=p)
    np.testing.assert_allclose(b.omega, a.omega, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(b.omega_hi, a.omega_hi, rtol=1e-9, atol=1e-9)
    assert abs(np.median(a.omega[-300:] - om[-300:])) < 1.0


# ------------------------------------------------------------------------------------------
# several comb axes (comb_axes)
# ------------------------------------------------------------------------------------------
def test_comb_axes_parsing():
    assert grid.Config(comb_axes="xyz").comb_axes == ("x", "y", "z")
    assert grid.Config(comb_axes="x:z").comb_axes == ("x", "z")
    assert grid.Config(comb_axes=("ay", "vib2")).comb_axes == ("ay", "vib2")
    assert grid.Config(comb_axes="all").comb_axes == ("all",)
    assert grid.Config().n_axes == 1 and grid.Config(comb_axes="xyz").n_axes == 3
    for bad in ("x:x", "all:x"):
        with pytest.raises(ParameterError, match="comb_axes"):
            grid.Config(comb_axes=bad)


def test_identical_axes_scale_the_evidence_exactly():
    """Per harmonic the axes' terms are summed before the cap (A cap) and the lead (A lead):
    A copies of one frame give A times its terms, so (one rate, no rate average) the
    evidence is A x axes_weight(A) times the single axis' evidence, at every grid point."""
    cfg = _small(comb_rates=())
    rng = np.random.default_rng(11)
    t = np.arange(cfg.frame_len) * 0.01
    fr = (0.5 * np.sin(35 * t) + 0.3 * np.sin(70 * t + 1) + 3.0 * np.sin(52 * t)
          + 0.2 * rng.normal(size=t.size))[None, :]
    e1 = grid.frame_evidence(cfg, fr, raw=True)
    for A in (2, 3):
        eA = grid.frame_evidence(cfg, np.stack([fr] * A), raw=True)
        np.testing.assert_allclose(eA, A * cfg.axes_weight(A) * e1, rtol=1e-12, atol=1e-12)
    assert cfg.axes_weight(1) == 1.0 and 0.3 < cfg.axes_weight(3) < 1.0 / np.sqrt(3)


def test_harmonics_split_over_two_axes_make_one_comb():
    """y carries only the fundamental, z only the 2nd and 3rd harmonics (a wheel's harmonics
    reach the axes with different gains): each axis alone is a single line or a pair that
    other combs explain as well; the two axes together score the wheel's comb highest."""
    cfg = grid.Config(tracker=grid._default_tracker(0.01))
    rng = np.random.default_rng(12)
    t = np.arange(cfg.frame_len) * 0.01
    y = 0.4 * np.sin(40 * t) + 0.3 * rng.normal(size=t.size)
    z = 0.3 * np.sin(80 * t + 1) + 0.3 * np.sin(120 * t + 2) + 0.3 * rng.normal(size=t.size)
    g = cfg.tracker.grid
    j = int(np.argmin(abs(g - 40.0)))
    ey = grid.frame_evidence(cfg, y[None, :])[0, :-1]
    e2 = grid.frame_evidence(cfg, np.stack([y[None, :], z[None, :]]))[0, :-1]
    assert ey[j] < 0.0  # one line alone scores below "no line"
    assert abs(g[np.argmax(e2)] - 40.0) < 1.0 and e2[j] > 1.0


def test_multi_axis_step_equals_run_and_single_axis_is_unchanged():
    cfg = dataclasses.replace(_small(comb_min_window=0.2), comb_axes=("ay", "az"))
    rng = np.random.default_rng(13)
    t = np.arange(260) * 0.01
    Y = np.column_stack([0.5 * np.sin(35 * t) + 0.2 * rng.normal(size=t.size),
                         0.3 * np.sin(70 * t) + 0.2 * rng.normal(size=t.size)])
    Y[40:43, 1] = np.nan
    res = grid.run(cfg, Y)
    st = grid.init(cfg)
    assert st.buf.shape == (cfg.frame_len, 2)
    om = []
    for row in Y:
        st, est = grid.step(cfg, st, row)
        om.append(est.omega)
    np.testing.assert_array_equal(np.array(om), res.filt.omega)
    np.testing.assert_array_equal(st.buf, res.final.buf)
    a = grid.run(cfg, Y[:101])
    b = grid.run(cfg, Y[101:], a.final)
    np.testing.assert_array_equal(np.r_[a.filt.omega, b.filt.omega], res.filt.omega)
    with pytest.raises(ValueError, match="axes"):
        grid.run(cfg, Y[:, 0], a.final)
    # one named axis (the tracked one) is the single-axis tracker, bit for bit
    rec = Recording(t, {"ay": Y[:, 0] + 9.8, "az": np.nan_to_num(Y[:, 1])})
    p = {"n_grid": 40, "omega_min": 10, "omega_max": 60, "smooth": "none"}
    one = grid.estimate(rec, axis="y", params=p)
    np.testing.assert_array_equal(grid.estimate(rec, axis="y", params={**p, "comb_axes": "y"})
                                  .omega, one.omega)
    two = grid.estimate(rec, axis="y", params={**p, "comb_axes": "all"})
    assert two.params["comb_axes"] == ["ay", "az"] or two.params["comb_axes"] == ("ay", "az")
    assert any("comb evidence from axes ay, az" in n for n in two.notes)
    with pytest.raises(ParameterError, match="comb_axes: channel 'ax' is missing"):
        grid.estimate(rec, axis="y", params={**p, "comb_axes": "xy"})


def test_comb_axes_improve_the_simulated_car_where_one_axis_fades():
    """Simulated car (its harmonics reach x, y, z with independent slow gain wander): the
    causal filter with all three axes in the comb evidence is within tolerance at least as
    more often than with y alone and reads the standstill as "no line" more often
    (docs/trackers.md follow-up 5: +2 points on 3 seeds, standstill 28 -> 13 %). Measured with
    the settings of that time (thesis high-pass, temper 0.2, comb SNR 2), the comb's "no line"
    state read before the standstill stage (``confidence``)."""
    from vibrospeed import sim

    rec = sim.simulate("car", seed=1, duration=120)
    truth = rec["omega_true"]
    moving = truth > 5
    ok, still = {}, {}
    for name, extra in (("y", {}), ("xyz", {"comb_axes": "xyz"})):
        tr = grid.estimate(rec, axis="y", params={"smooth": "none", "prefilter": "thesis-hp",
                                                  "temper": 0.2, "comb_snr": 2.0, **extra})
        err = np.abs(tr.omega - truth)
        ok[name] = np.mean(err[moving] < np.maximum(2.0, 0.1 * truth[moving]))
        still[name] = np.mean(np.asarray(tr.extras["confidence"] >= 0.5)[~moving])
    assert ok["xyz"] >= ok["y"] + 0.005  # measured 87.8 -> 89.3 %
    assert still["xyz"] < 0.75 * still["y"]  # measured 63 -> 35 % of the standing samples


def test_a_dead_or_gappy_axis_drops_out_of_the_comb_evidence():
    """An axis whose frame is more than half NaN (a dead channel, a dropout on one axis) gives
    no evidence and does not count among the axes: the evidence is that of the others."""
    cfg = _small(comb_rates=(0.1,))
    rng = np.random.default_rng(14)
    t = np.arange(cfg.frame_len) * 0.01
    y = (0.5 * np.sin(35 * t) + 0.3 * np.sin(70 * t + 1) + 0.2 * rng.normal(size=t.size))
    z = 0.3 * np.sin(35 * t + 2) + 0.2 * rng.normal(size=t.size)
    dead = np.full(t.size, np.nan)
    gappy = z.copy()
    gappy[: t.size // 2 + 2] = np.nan
    one = grid.frame_evidence(cfg, y[None, :])
    two = grid.frame_evidence(cfg, np.stack([y[None, :], z[None, :]]))
    np.testing.assert_array_equal(grid.frame_evidence(cfg, np.stack([y[None, :], dead[None, :]])),
                                  one)
    np.testing.assert_array_equal(
        grid.frame_evidence(cfg, np.stack([y[None, :], gappy[None, :]])), one)
    np.testing.assert_array_equal(
        grid.frame_evidence(cfg, np.stack([dead[None, :], z[None, :], y[None, :]])),
        grid.frame_evidence(cfg, np.stack([z[None, :], y[None, :]])))
    assert not np.array_equal(two, one)
    assert np.all(grid.frame_evidence(cfg, np.stack([dead[None, :]] * 2)) == 0.0)


def test_comb_axes_all_leaves_an_all_nan_axis_out_and_says_so():
    rng = np.random.default_rng(15)
    t = np.arange(400) * 0.01
    ay = 0.5 * np.sin(35 * t) + 0.2 * rng.normal(size=t.size)
    ax = 0.3 * np.sin(70 * t) + 0.2 * rng.normal(size=t.size)
    p = {"n_grid": 40, "omega_min": 10, "omega_max": 60, "smooth": "none", "comb_axes": "all"}
    with_dead = grid.estimate(Recording(t, {"ax": ax, "ay": ay, "az": np.full(t.size, np.nan)}),
                              axis="y", params=p)
    without = grid.estimate(Recording(t, {"ax": ax, "ay": ay}), axis="y", params=p)
    np.testing.assert_array_equal(with_dead.omega, without.omega)
    assert "comb_axes=all: az all NaN, left out" in with_dead.notes


def test_standstill_is_a_state_of_the_default_tracker():
    """Stops of a simulated car (random family) read as omega = 0 with ``standstill`` = 1."""
    from vibrospeed import sim

    rec = sim.simulate("random", seed=4, duration=60, fs=100.0, vehicle="car", level=3.0)
    lo, hi = rec.meta["omega_range"]
    tr = grid.estimate(rec, params={"omega_min": lo, "omega_max": hi})
    st = tr.extras["standstill"] > 0.5
    still = rec["omega_true"] <= 0
    inner = np.convolve(still, np.ones(201), "same") >= 201  # 1 s away from motion
    assert inner.sum() > 300
    assert st[inner].mean() > 0.95
    assert st[~still].mean() < 0.02
    assert np.all(tr.omega[st] == 0) and np.all(tr.omega_hi[st] == 0)
    assert np.all(tr.extras["has_signal"][st] == 0)
    assert any("standstill on" in n for n in tr.notes)


def test_comb_evidence_is_centred_on_white_noise():
    """On white noise the raw comb evidence favours the bottom of a 2-30 rad/s range (its
    harmonics read correlated bins there); centred (:func:`comb.noise_offsets`), its mean per
    grid point over independent noise frames is flat up to the Monte Carlo errors, and the
    offsets are the raw evidence's mean on their own noise, less its grid average."""
    tr = rbpmf.improved(rbpmf.Config.from_paper_table1(0.01), n_grid=60, omega_min=2.0,
                        omega_max=30.0)
    cfg = grid.Config(tracker=tr)
    L = cfg.frame_len
    noise = np.random.default_rng(99).standard_normal((1, 256, L))
    raw = grid.frame_evidence(cfg, noise, raw=True)[:, :-1].mean(axis=0) / cfg.comb_weight
    got = grid.frame_evidence(cfg, noise)[:, :-1].mean(axis=0) / cfg.comb_weight
    g = tr.grid
    bottom = g < 4.5
    gap = raw[bottom].mean() - raw[~bottom].mean()  # the bias being removed: ~0.15 nats
    assert gap > 0.1
    # (within the Monte Carlo errors: ~0.04 nats per grid point of the offsets' 64 frames,
    # ~0.02 of these 256)
    assert abs(got[bottom].mean() - got[~bottom].mean()) < 0.5 * gap
    assert np.ptp(got) < 0.5 * np.ptp(raw)
    own = np.random.default_rng(L).standard_normal((1, comb.NOISE_FRAMES, L))
    m = grid.frame_evidence(cfg, own, raw=True)[:, :-1].mean(axis=0) / cfg.comb_weight
    np.testing.assert_allclose(comb.noise_offsets(cfg, L), m - m.mean(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(got, raw - comb.noise_offsets(cfg, L), atol=1e-12)


@pytest.mark.parametrize("lag", [float("inf"), float("nan"), 0.0, -1.0])
def test_a_fixed_lag_must_be_finite_and_positive(lag):
    from vibrospeed.sim import simulate

    rec = simulate("cart", seed=1, duration=5)
    with pytest.raises(ParameterError, match="lag must be a finite number > 0 s"):
        grid.estimate(rec, params={"smooth": "lag", "lag": lag})
