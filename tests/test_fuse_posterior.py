"""``fuse`` with ``vib_measure="posterior"``: the tracker's grid posterior times the
prediction's Gaussian as the wheel-frequency measurement."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import fuse, get
from vibrospeed.estimators.fuse.core import _post_product

GRID = np.linspace(10.0, 120.0, 200)
DG = GRID[1] - GRID[0]


def _peaks(centres, widths, masses, grid=GRID):
    """A grid posterior: Gaussian bumps, the signal part summing to ``sum(masses)``."""
    q = np.zeros(grid.size)
    for c, w, m in zip(centres, widths, masses, strict=True):
        b = np.exp(-0.5 * ((grid - c) / w) ** 2)
        q += m * b / b.sum()
    return q


def _numpy_product(q, grid, m, s, width=4.0):
    """Plain numpy: the product of ``q`` with N(m, s^2) on the grid points within width s,
    its mass against a flat posterior's, moment-matched mean and variance (+ one cell's)."""
    sel = np.abs(grid - m) <= width * s
    g = np.exp(-0.5 * ((grid[sel] - m) / s) ** 2)
    w = q[sel] * g
    mean = np.sum(w * grid[sel]) / np.sum(w)
    var = np.sum(w * (grid[sel] - mean) ** 2) / np.sum(w)
    dg = grid[1] - grid[0]
    return np.sum(w) / (np.sum(g) / grid.size), mean, var + dg * dg / 12.0


def test_product_against_numpy_and_the_gaussian_product():
    rng = np.random.default_rng(0)
    q = rng.random(GRID.size)
    q /= q.sum()
    for m, s in ((40.0, 3.0), (12.0, 5.0), (100.0, 0.3), (119.0, 8.0)):
        np.testing.assert_allclose(_post_product(q, GRID, m, s, 4.0),
                                   _numpy_product(q, GRID, m, s), rtol=1e-12)
    # a Gaussian posterior N(a, b^2) on a fine grid times N(m, s^2): the textbook product
    fine = np.linspace(0.0, 200.0, 20001)
    a, b, m, s = 60.0, 2.0, 63.0, 3.0
    q = np.exp(-0.5 * ((fine - a) / b) ** 2)
    q /= q.sum()
    _, mean, var = _post_product(q, fine, m, s, 12.0)
    v = 1.0 / (1.0 / b**2 + 1.0 / s**2)
    assert abs(mean - v * (a / b**2 + m / s**2)) < 1e-9
    assert abs(var - (v + (fine[1] - fine[0]) ** 2 / 12.0)) < 1e-9
    # no grid point in the window, no mass there
    assert _post_product(q, fine, 500.0, 1.0, 4.0)[0] == 0.0
    assert _post_product(np.zeros(GRID.size), GRID, 40.0, 3.0, 4.0)[0] == 0.0


def _outage_arrays(seed, T=40.0, r=0.3):
    """Fusion samples of ``v = 12 + 4 sin(2 pi t / 30)``: fixes every 2nd sample before 10 s,
    none after; a tracker posterior with the wheel's line (omega = v / r) and its 2nd harmonic,
    a line probability between 0.3 and 1; its mode the harmonic from 25 s on."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 0.04)
    v = 12.0 + 4.0 * np.sin(2 * np.pi * t / 30.0)
    a = 4.0 * 2 * np.pi / 30.0 * np.cos(2 * np.pi * t / 30.0)
    g = np.where((np.arange(t.size) % 2 == 0) & (t < 10.0), v + rng.normal(0, 0.1, t.size),
                 np.nan)
    om = v / r
    p_line = 0.3 + 0.7 * (0.5 + 0.5 * np.sin(t))
    post = np.array([_peaks((o, 2 * o), (1.0, 1.5), (0.6 * p, 0.4 * p))
                     for o, p in zip(om + rng.normal(0, 0.3, t.size), p_line, strict=True)])
    mode = np.where(t >= 25.0, 2 * om, om)
    arrays = {"t": t, "accel": a + rng.normal(0, 0.3, t.size), "gps_speed": g,
              "gps_sats": np.full(t.size, 9.0), "omega": mode, "omega_std": np.full(t.size, 1.0),
              "line": p_line >= 0.5, "still": np.zeros(t.size, bool),
              "soft": (p_line < 0.5) & (p_line >= 0.3), "posterior": post}
    arrays["line"] = arrays["line"] | arrays["soft"]
    return arrays, v


def test_step_equals_run_bitwise_with_a_posterior():
    cfg = fuse.Config(acc_psd=0.05, vib_measure="posterior")
    arrays, _ = _outage_arrays(1)
    st0 = fuse.init(cfg, 12.0, radius=0.3, radius_std=0.003)
    end, o = fuse.run(cfg, arrays, state=st0, grid=GRID)
    assert np.isfinite(o.harmonic[arrays["t"] > 10.0]).mean() > 0.5  # lines used in the outage
    st = st0
    for i in range(arrays["t"].size):
        y = fuse.Sample(*(arrays[k][i] for k in fuse._SAMPLE), posterior=arrays["posterior"][i])
        st, est = fuse.step(cfg, st, y, grid=GRID)
        assert est.speed == o.speed[i] and est.speed_std == o.speed_std[i]
        assert est.radius == o.radius[i] and est.source == o.source[i]
        assert est.harmonic == o.harmonic[i] or (math.isnan(est.harmonic)
                                                 and math.isnan(o.harmonic[i]))
    np.testing.assert_array_equal(st.x, end.x)
    np.testing.assert_array_equal(st.P, end.P)
    # without vib_measure=posterior the posterior is not read: the mode's numbers
    _, o_mode = fuse.run(replace(cfg, vib_measure="mode"), arrays, state=st0, grid=GRID)
    _, o_none = fuse.run(replace(cfg, vib_measure="mode"),
                         {k: x for k, x in arrays.items() if k != "posterior"}, state=st0)
    np.testing.assert_array_equal(o_mode.speed, o_none.speed)
    assert not np.array_equal(o_mode.speed, o.speed)


def _one_line(cfg, v_pred, post, mode, r=0.3):
    """Two fusion samples away from GPS (r known): the first sets the time, the second offers
    ``post`` with the tracker's mode ``mode``; the filter's output and its prediction there."""
    st = fuse.init(cfg, v_pred, radius=r, radius_std=1e-4, p0_speed=0.5**2)
    arrays = {"t": np.array([0.0, 0.04]), "omega": np.array([np.nan, mode]),
              "omega_std": np.array([np.nan, 1.0]), "line": np.array([False, True]),
              "posterior": np.vstack([post, post])}
    return fuse.run(cfg, arrays, state=st, grid=GRID)


def _reference_update(cfg, xp, Pp, post, mode, dt=0.04):
    """The posterior measurement by hand: per octave the numpy product of the line-conditional
    posterior with the prediction on the line, divided by that prediction (a Gaussian
    likelihood), the octave with the largest mass against a flat posterior (penalty for k !=
    1), weighted by the line probability, and a Schmidt update (r, b consider states)."""
    v, r = xp[fuse.IV], xp[fuse.IR]
    p_line = post.sum()
    q = post / p_line
    best = None
    for k in (1.0, 0.5, 2.0):
        if abs(math.log2(k * r * mode / v)) > 0.5:
            continue
        m = v / (r * k)
        h = np.zeros(xp.size)
        h[fuse.IV], h[fuse.IR] = 1.0 / (r * k), -m / r
        sp = h @ Pp @ h + DG**2
        bf, mu, vp = _numpy_product(q, GRID, m, math.sqrt(sp))
        rz = 1.0 / (1.0 / vp - 1.0 / sp)
        z = rz * (mu / vp - m / sp)
        cost = -2 * math.log(bf) + (0.0 if k == 1.0 else cfg.vib_penalty)
        if best is None or cost < best[0]:
            best = (cost, k, z, rz + (cfg.vib_rel * z) ** 2, bf)
    _, k, z, var, bf = best
    beta = p_line * bf / (p_line * bf + 1.0 - p_line)
    R = (r * k) ** 2 * var / beta * cfg.vib_corr / dt
    h = np.zeros(xp.size)
    h[fuse.IV], h[fuse.IR] = 1.0, -k * z
    S = h @ Pp @ h + R
    K = Pp @ h / S
    K[[fuse.IR, fuse.IB]] = 0.0
    x = xp + K * (0.0 - h @ xp)
    A = np.eye(xp.size) - np.outer(K, h)
    return x, A @ Pp @ A.T + R * np.outer(K, K), k


def test_the_speed_prior_picks_the_octave_of_the_posterior():
    """The tracker's posterior holds omega / 2 and omega (its mode, the larger peak: a 2nd
    harmonic above a weaker fundamental). A prediction near either reads that line at the
    octave the prediction implies; the update is the hand-made one."""
    cfg = fuse.Config(vib_measure="posterior")
    r, om = 0.3, 80.0
    post = _peaks((om / 2, om), (0.8, 0.8), (0.3, 0.6))
    for v_pred, k_exp in ((0.97 * r * om / 2, 0.5), (1.02 * r * om, 1.0)):
        _, o = _one_line(cfg, v_pred, post, om)
        assert o.harmonic[1] == k_exp
        line = r * om / 2 if k_exp == 0.5 else r * om
        assert abs(o.speed[1] - line) < abs(v_pred - line)  # moved towards the line it reads
        x, P, k = _reference_update(cfg, o.xp[1], o.Pp[1], post, om)
        assert k == k_exp
        np.testing.assert_allclose(o.xf[1], x, rtol=0, atol=1e-10)
        np.testing.assert_allclose(o.Pf[1], P, rtol=0, atol=1e-12)


def test_a_wheel_peak_away_from_the_mode_is_read():
    """The tracker's mode is a stronger line 30 % above the wheel's (a resonance); the mode
    read as the measurement is refused, the posterior's peak at the wheel's line is used and
    pulls a prediction 4 % off towards it. No posterior mass near the prediction: no update."""
    r, om = 0.3, 60.0
    post = _peaks((om, 1.3 * om), (0.8, 0.8), (0.35, 0.6))
    v_pred = 1.04 * r * om
    _, o = _one_line(fuse.Config(vib_measure="posterior"), v_pred, post, 1.3 * om)
    _, o_mode = _one_line(fuse.Config(), v_pred, post, 1.3 * om)
    assert o.harmonic[1] == 1.0 and np.isnan(o_mode.harmonic[1])
    assert abs(o.speed[1] - r * om) < 0.5 * abs(v_pred - r * om)
    far = _peaks((2.5 * om,), (0.8,), (0.95,))
    _, o_far = _one_line(fuse.Config(vib_measure="posterior"), v_pred, far, 1.3 * om)
    assert np.isnan(o_far.harmonic[1]) and o_far.xf[1, fuse.IV] == o_far.xp[1, fuse.IV]


def _drive(seed=0, T=60.0, fs=200.0, r=0.3, outage=(30.0, 45.0)):
    """A drive with a 3-harmonic wheel line on ay, its acceleration on ax and receiver fixes at
    10 Hz, withheld inside ``outage``."""
    from vibrospeed.models.gps_riss import simulate_receiver
    from vibrospeed.types import Recording

    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    v = 12.0 + 4.0 * np.sin(2 * np.pi * t / 40.0)
    phase = np.cumsum(v / r) / fs
    ay = sum(c * np.sin(k * phase) for k, c in ((1, 1.0), (2, 0.5), (3, 0.3)))
    g = np.full(t.size, np.nan)
    g[::20] = simulate_receiver(t, v, fuse.Config().lag)[::20] + rng.normal(0, 0.1, t[::20].size)
    g[(t >= outage[0]) & (t < outage[1])] = np.nan
    ch = {"ax": np.gradient(v, t) + 0.1 + 0.2 * rng.normal(size=t.size),
          "ay": ay + 0.3 * rng.normal(size=t.size), "az": 9.81 + 0.2 * rng.normal(size=t.size),
          "gps_speed": g, "gps_sats": np.full(t.size, 9.0)}
    return Recording(t, ch, source=f"drive{seed}"), v


def test_estimate_online_reads_the_posterior_at_the_fusion_samples():
    rec, v = _drive()
    on = fuse.estimate(rec, params={"online": True})
    assert on.params["vib_measure"] == "posterior"
    assert on.params["vib_sep"] == fuse.CAUSAL_VIB_SEP
    out = (rec.t >= 32.0) & (rec.t < 45.0)
    assert np.mean(on.extras["source"][out] == fuse.SRC_VIBRATION) > 0.8
    # the causal tracker's line trails the 0.6 m/s^2 of this drive: a few % at most
    err = np.abs(on.speed[out] - v[out]) / v[out]
    assert np.median(err) < 0.025 and err.max() < 0.08
    # the causal track given, with its posterior at every sample or at the fusion samples only:
    # the same numbers
    g = get("grid").estimate(rec, axis="y", params={**fuse.TRACKER_DEFAULTS, "smooth": "none"},
                             return_posterior=True)
    np.testing.assert_array_equal(fuse.estimate(rec, vibration=g, params={"online": True}).speed,
                                  on.speed)
    ends = fuse.fusion_samples(rec.t, np.isfinite(rec["gps_speed"]), fuse.Config().fuse_rate)
    g.extras["posterior"] = g.extras["posterior"][ends]
    g.extras["posterior_index"] = ends
    np.testing.assert_array_equal(fuse.estimate(rec, vibration=g, params={"online": True}).speed,
                                  on.speed)
    # rows missing at some fusion samples: refused
    g.extras["posterior_index"] = ends + 1
    with pytest.raises(InputError):
        fuse.estimate(rec, vibration=g, params={"online": True})
    # offline the mode is the default; asked for, the smoothed tracker's posterior is read
    assert fuse.estimate(rec).params["vib_measure"] == "mode"
    off = fuse.estimate(rec, params={"vib_measure": "posterior"})
    assert np.all(np.abs(off.speed[out] - v[out]) < 0.03 * v[out])
    # a track without its posterior is read by its mode online, and refused where asked for
    del g.extras["posterior"]
    assert fuse.estimate(rec, vibration=g, params={"online": True}).params["vib_measure"] == "mode"
    with pytest.raises(InputError):
        fuse.estimate(rec, vibration=g, params={"online": True, "vib_measure": "posterior"})


def test_config_checks_the_posterior_fields():
    for kw in ({"vib_measure": "mean"}, {"vib_post_width": 0.0}, {"vib_post_min": 1.5}):
        with pytest.raises(ParameterError):
            fuse.Config(**kw)
