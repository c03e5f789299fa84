"""``fuse``: acceleration + GPS + wheel-frequency Kalman filter with a learned wheel radius."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.linalg import expm

from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import fuse
from vibrospeed.models.gps_riss import receiver_matrices, simulate_receiver
from vibrospeed.types import Recording, Track

FR = 25.0  # fusion rate of the synthetic inputs


def synth(seed=0, T=240.0, r_true=0.31, outage=None, no_line=None, bias=0.2, still=None,
          psd=0.01, om_std=0.05, cfg=None):
    """Fusion-sample inputs of a drive ``v = 15 + 5 sin(2 pi t / 60)`` (or 0 inside ``still``):
    accelerometer means with offset ``bias``, fixes of the config's receiver every 2nd sample
    (none inside ``outage``), the wheel frequency ``v / r_true`` with noise ``om_std``."""
    cfg = cfg or fuse.Config(acc_psd=psd)
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / FR)
    v = 15.0 + 5.0 * np.sin(2 * np.pi * t / 60.0)
    a = 5.0 * 2 * np.pi / 60.0 * np.cos(2 * np.pi * t / 60.0)
    stop = np.zeros(t.size, bool)
    if still is not None:
        stop = (t >= still[0]) & (t < still[1])
        # a smooth stop: v -> 0 over 10 s before, back after
        w = np.clip(np.minimum(t - still[0] + 10.0, still[1] + 10.0 - t) / 10.0, 0.0, 1.0)
        w = 0.5 - 0.5 * np.cos(np.pi * w)
        v = v * (1.0 - w)
        a = np.gradient(v, t)
    am = a + bias + rng.normal(0.0, math.sqrt(psd * FR), t.size)
    am[0] = np.nan
    rx = simulate_receiver(t, v, cfg.lag)
    g = np.full(t.size, np.nan)
    g[::2] = rx[::2] + rng.normal(0.0, 0.1, t[::2].size)
    if outage is not None:
        g[(t >= outage[0]) & (t < outage[1])] = np.nan
    if still is not None:
        g[stop & np.isfinite(g)] = np.abs(g[stop & np.isfinite(g)])
    om = v / r_true + rng.normal(0.0, om_std, t.size)
    line = ~stop
    if no_line is not None:
        line &= ~((t >= no_line[0]) & (t < no_line[1]))
    return {"t": t, "accel": am, "gps_speed": g, "gps_sats": np.full(t.size, 9.0),
            "omega": om, "omega_std": np.full(t.size, om_std), "line": line, "still": stop}, v


# -- independent reference: the module's equations with scipy and the textbook update ------------

def reference(cfg: fuse.Config, arrays: dict, state: fuse.State):
    """Plain numpy/scipy re-implementation (standard-form update, scipy expm) of the filter."""
    Ar, Br = receiver_matrices(cfg.lag)
    n = 4 + Ar.shape[0] + 1  # the last state: the receiver's extra lag
    Ac = np.zeros((n, n))
    Ac[0, 1] = 1.0
    Ac[4:-1, 4:-1] = Ar
    Ac[4:-1, 0] = Br
    q = np.array([cfg.q_speed, cfg.q_accel, cfg.q_offset, cfg.q_radius]
                 + [cfg.q_gps] * (n - 5) + [cfg.q_gps_lag])
    x, P = state.x.copy(), state.P.copy()
    t_prev = math.nan

    def upd(h, z, r):
        nonlocal x, P
        S = h @ P @ h + r
        K = P @ h / S
        x = x + K * (z - h @ x)
        P = P - np.outer(K, K) * S

    def upd_consider(h, z, r, keep):
        """Schmidt update: gain 0 on the states ``keep``; covariance by the Joseph form."""
        nonlocal x, P
        S = h @ P @ h + r
        K = P @ h / S
        if keep is not None:
            K[keep] = 0.0
        x = x + K * (z - h @ x)
        A = np.eye(n) - np.outer(K, h)
        P = A @ P @ A.T + np.outer(K, K) * r

    speeds, radii, ks = [], [], []
    t_gps = -math.inf
    acq = None  # (start, mean log ratio) of the consistent run while r is unknown
    run = None  # (start, mean gap, line speed at start) of the re-lock run
    prev = None  # (omega, k) of the line used at the previous sample
    last = None  # (t, omega, k) of the last line used
    for i in range(arrays["t"].size):
        t = arrays["t"][i]
        dt = 0.0 if math.isnan(t_prev) else t - t_prev
        t_prev = t
        if dt > 0:
            F = expm(Ac * dt)
            x = F @ x
            P = F @ P @ F.T + np.diag(q * dt)
        e = np.eye(n)
        if dt > 0 and np.isfinite(arrays["accel"][i]):
            upd(e[1] + e[2], arrays["accel"][i], cfg.acc_psd / dt)
        g = arrays["gps_speed"][i]
        if np.isfinite(g) and arrays["gps_sats"][i] >= cfg.min_sats:
            # extended Kalman row of g = x3(t - dl) ~ x3 - dl x3', x3' = Ac[4] x
            dl, d3 = x[-1], Ac[4] @ x
            h = e[4] - dl * Ac[4]
            h[-1] = -d3
            nu = g - (x[4] - dl * d3)
            E2 = min(max(nu**2 - (h @ P @ h + cfg.r_gps), 0.0), cfg.e_max**2)
            upd(h, nu + h @ x, cfg.r_gps + cfg.r_gps_sq * E2)
            t_gps = t
        k_used = math.nan
        om, s = arrays["omega"][i], arrays["omega_std"][i]
        moving = x[0] + 3 * math.sqrt(P[0, 0]) >= cfg.vib_min_speed
        fresh = t - t_gps <= cfg.learn_hold
        known = math.sqrt(P[3, 3]) < cfg.octave_rel * abs(x[3])
        if not (fresh and x[0] >= cfg.vib_min_speed):
            acq = None
        soft = bool(arrays.get("soft", np.zeros(arrays["t"].size, bool))[i])
        offered = arrays["line"][i] and moving and dt > 0 and om > 0
        if soft:  # an unclaimed line: only the re-lock's band, away from GPS, r known
            acq = None
            offered = offered and known and not fresh
        if not offered:
            if dt > 0:  # a consistency run needs a line at every sample
                acq = run = None
        else:
            ready = known
            if not known and fresh and x[0] >= cfg.vib_min_speed:
                z = math.log(x[0] / om)
                if acq is None or abs(z - acq[1]) > cfg.acq_rel:
                    acq = (t, z)
                else:
                    acq = (acq[0], acq[1] + (z - acq[1]) * min(1.0, dt / cfg.acq_time))
                ready = t - acq[0] >= cfg.acq_time
            rh = max(x[3], 1e-3)
            var = s**2 + (cfg.vib_rel * om) ** 2
            a_lag = x[1]
            if np.isfinite(arrays["accel"][i]) and abs(arrays["accel"][i] - x[2]) > abs(a_lag):
                a_lag = arrays["accel"][i] - x[2]
            vlag = (cfg.vib_lag * a_lag) ** 2
            hard = abs(a_lag) > cfg.vib_amax
            R1 = {k: (rh * k) ** 2 * var + vlag for k in (1.0, 0.5, 2.0)}  # one sample's
            R = {k: R1[k] * cfg.vib_corr / dt for k in R1}  # per correlation time
            sv3 = 3 * math.sqrt(P[0, 0])
            costs = {}
            # an unclaimed line: only where it continues the last line used (at most
            # vib_soft_hold s before the previous sample, within half an octave), at its k
            soft_cont = (soft and cfg.vib_soft_gate > 0 and last is not None
                         and t - last[0] <= dt + cfg.vib_soft_hold
                         and abs(math.log2(om / last[1])) <= 0.5)
            for k in (1.0, 0.5, 2.0) if ready and not hard and (soft_cont or not soft) else ():
                if soft and k != last[2]:
                    continue
                if not (cfg.radius_min * k * om <= x[0] + sv3
                        and x[0] - sv3 <= cfg.radius_max * k * om):
                    continue
                # with r known only the octave whose speed is nearest the filter's in ratio
                if known and not (x[0] > 0 and 2 ** -0.5 <= k * x[3] * om / x[0] <= 2 ** 0.5):
                    continue
                h = e[0] - k * om * e[3]
                S = h @ P @ h + R1[k]  # the gate: this sample's spread
                costs[k] = ((h @ x) ** 2 / S + (0 if k == 1.0 else cfg.vib_penalty), S)
            take = None
            if costs:
                kb = min(costs, key=lambda k: costs[k][0])
                # a claimed line that continues the previous sample's (same k, within half
                # an octave of its omega) keeps its octave without the decisive gate
                cont = cfg.vib_use == "line" and (soft_cont or (
                    prev is not None and kb == prev[1] and abs(math.log2(om / prev[0])) <= 0.5))
                gate = cfg.vib_soft_gate if soft else cfg.vib_gate
                if costs[kb][0] <= gate and (
                        fresh or cont or 3 * math.sqrt(P[0, 0] + (rh * kb) ** 2 * var)
                        <= cfg.vib_sep * rh * kb * om):
                    take = kb
            if ready and known and not hard and take is None:
                u = x[3] * om
                d = u - x[0]
                if run is None or t - t_gps <= cfg.vib_relock or abs(d - run[1]) > cfg.acq_rel * u:
                    run = (t, d, u, d)
                else:
                    run = (run[0], run[1] + (d - run[1]) * min(1.0, dt / cfg.acq_time), run[2],
                           run[3])
                    moved = (abs(u - run[2]) >= cfg.acq_change * u
                             and abs(run[1] - run[3]) <= 0.4 * abs(u - run[2]))
                    inside = abs(d) <= sv3 and x[0] > 0 and 2 ** -0.5 <= u / x[0] <= 2 ** 0.5
                    if t - run[0] >= cfg.vib_relock and (moved or inside):
                        gap2 = (x[0] - x[3] * om) ** 2  # soft: the band widened to the gap
                        P[0, 0] = max(P[0, 0], gap2) if soft else P[0, 0] + gap2
                        take = None if soft else 1.0
                        run = None
            if take is not None:
                k_used = take
                upd_consider(e[0] - take * om * e[3], 0.0, R[take], None if fresh else [2, 3])
                prev = (om, take)
                last = (t, om, take)
        if dt > 0 and math.isnan(k_used):
            prev = None
        speeds.append(x[0])
        radii.append(x[3])
        ks.append(k_used)
    return np.array(speeds), np.array(radii), np.array(ks)


@pytest.mark.parametrize("kw", [{}, {"vib_lag": 1.5, "gps_lag_std": 0.5}, {"vib_amax": 0.4},
                                {"vib_use": "all"}])
def test_filter_matches_independent_reference(kw):
    cfg = fuse.Config(acc_psd=0.01, **kw)
    arrays, _ = synth(seed=1, T=60.0, outage=(20.0, 40.0), no_line=(30.0, 35.0))
    # unclaimed lines, in and out of the outage: continuing the claimed line (25-27 s, with a
    # stretch 25 % off that the soft gate refuses), after a gap shorter than vib_soft_hold
    # (30.5-31 s) and after a longer one (32.5-35 s: the re-lock's band only)
    t = arrays["t"]
    arrays["soft"] = (((t >= 25.0) & (t < 27.0)) | ((t >= 30.5) & (t < 31.0))
                      | ((t >= 32.5) & (t < 35.0)) | (t < 2.0))
    arrays["line"] = arrays["line"] | arrays["soft"]
    arrays["omega"][(t >= 26.0) & (t < 26.2)] *= 1.25
    # octave errors of the tracker in places: the filter must resolve them as the reference does
    arrays["omega"][200:230] *= 2.0
    arrays["omega"][600:620] *= 0.5
    st = fuse.init(cfg, float(arrays["gps_speed"][0]), radius=0.3, radius_std=0.05)
    _, o = fuse.run(cfg, arrays, state=st)
    vs, rs, ks = reference(cfg, arrays, st)
    np.testing.assert_allclose(o.speed, vs, rtol=0, atol=1e-7)
    np.testing.assert_allclose(o.radius, rs, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(np.isnan(o.harmonic), np.isnan(ks))
    if kw.get("vib_use", "line") == "line" and "vib_amax" not in kw:
        # the unclaimed continuations are taken, the 25 % jump is not, nor the line after the
        # gap longer than vib_soft_hold
        assert np.all(np.isfinite(o.harmonic[(t >= 25.0) & (t < 26.0)]))
        assert not np.any(np.isfinite(o.harmonic[(t >= 26.0) & (t < 26.2)]))
        assert np.all(np.isfinite(o.harmonic[(t >= 30.5) & (t < 31.0)]))
        assert not np.any(np.isfinite(o.harmonic[(t >= 32.5) & (t < 35.0)]))
    # the doubled / halved stretches were read as 2 omega and omega / 2 (k = 1/2 and 2)
    assert np.nanmedian(o.harmonic[205:230]) == 0.5
    assert np.nanmedian(o.harmonic[605:620]) == 2.0


def test_step_equals_run_bitwise():
    cfg = fuse.Config(acc_psd=0.01)
    arrays, _ = synth(seed=2, T=30.0, outage=(10.0, 20.0), still=(24.0, 28.0))
    arrays["soft"] = (arrays["t"] >= 12.0) & (arrays["t"] < 15.0)
    st0 = fuse.init(cfg, 15.0)
    end, o = fuse.run(cfg, arrays, state=st0)
    st = st0
    for i in range(arrays["t"].size):
        st, est = fuse.step(cfg, st, tuple(arrays[k][i] for k in fuse._SAMPLE))
        assert est.speed == o.speed[i] and est.speed_std == o.speed_std[i]
        assert est.radius == o.radius[i] and est.source == o.source[i]
    np.testing.assert_array_equal(st.x, end.x)
    np.testing.assert_array_equal(st.P, end.P)
    # chunked runs carry the state: same numbers as one run
    half = arrays["t"].size // 2
    s1, o1 = fuse.run(cfg, {k: v[:half] for k, v in arrays.items()}, state=st0)
    _, o2 = fuse.run(cfg, {k: v[half:] for k, v in arrays.items()}, state=s1)
    np.testing.assert_array_equal(np.concatenate([o1.speed, o2.speed]), o.speed)


def test_a_sample_of_arrays_without_soft_runs_as_none_soft():
    """``run`` takes a :class:`Sample` of arrays whose later fields keep their scalar defaults
    (``soft=False`` before the field existed): the same numbers as with ``soft`` all False,
    and a given ``soft`` array is used."""
    cfg = fuse.Config(acc_psd=0.01)
    arrays, _ = synth(seed=3, T=40.0, outage=(10.0, 40.0), no_line=(10.0, 20.0))
    st0 = fuse.init(cfg, 15.0)
    sample = fuse.Sample(*(arrays[k] for k in fuse._SAMPLE[:-1]))
    assert sample.soft is False
    _, o = fuse.run(cfg, sample, state=st0)
    _, o_dict = fuse.run(cfg, {**arrays, "soft": np.zeros(arrays["t"].size, bool)}, state=st0)
    np.testing.assert_array_equal(o.speed, o_dict.speed)
    soft = (arrays["t"] >= 10.0) & (arrays["t"] < 20.0)
    _, o_soft = fuse.run(cfg, sample._replace(line=arrays["line"] | soft, soft=soft), state=st0)
    assert not np.array_equal(o_soft.speed_std, o.speed_std)


def test_radius_converges_to_truth_and_carries_the_outage():
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=3, T=240.0, r_true=0.3217, outage=(120.0, 200.0))
    _, o = fuse.run(cfg, arrays)
    t = arrays["t"]
    before = np.flatnonzero(t < 120.0)[-1]
    assert abs(o.radius[before] - 0.3217) < 3 * o.radius_std[before]
    assert abs(o.radius[before] - 0.3217) < 1e-3
    assert o.radius_std[before] < 0.001
    out = (t >= 120.0) & (t < 200.0)
    # through the outage the radius stays put and vibration carries the speed
    assert np.ptp(o.radius[out]) < 2e-3
    assert np.all(o.source[out & (t >= 121.5)] == fuse.SRC_VIBRATION)  # gps holds 1.5 s
    assert np.mean(np.abs(o.speed[out] - v[out]) <= 0.01 * v[out]) > 0.99
    # with GPS
    assert np.mean(o.source[(t > 5) & ~out] == fuse.SRC_GPS) > 0.99


def test_radius_takes_the_octave_most_updates_use():
    """A tracker locked on the second harmonic for the first 3 s teaches r / 2 (k = 1 is the
    only choice with a wide prior); once it reports the fundamental, k = 2 explains it with
    r / 2 until the octave average moves the radius to the truth. The speed is right all the
    way."""
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=9, T=120.0, r_true=0.3)
    arrays["omega"][:75] *= 2.0
    _, o = fuse.run(cfg, arrays)
    t = arrays["t"]
    assert abs(o.radius[70] - 0.15) < 0.01
    assert o.harmonic[100] == 2.0
    assert abs(o.radius[-1] - 0.3) < 0.002
    assert np.all(o.harmonic[t > 30.0] == 1.0)
    assert np.mean(np.abs(o.speed[t > 1.0] - v[t > 1.0]) < 0.02 * v[t > 1.0]) > 0.99


def test_a_class_prior_keeps_r_where_the_tracker_follows_the_2nd_harmonic():
    """The tracker follows the wheel's 2nd harmonic while GPS is good and the fundamental in
    the outage (a missing fundamental that comes back). With a car's radius prior (0.32 +-
    0.027 m: 0.28-0.36 m at 1.5 sigma) the line is read as 2 omega (k = 1/2: r / 2 is 6 sigma
    off the prior) and r is learned as the wheel's; in the outage the fundamental is then the
    octave that taught r and carries the speed. With the wide default prior the same drive
    learns the line's ratio r / 2 (k = 1 costs no octave penalty) and reads the fundamental in
    the outage as k = 2: the same speed, r at the line's octave."""
    r_true = 0.30
    arrays, v = synth(seed=13, T=200.0, r_true=r_true, outage=(120.0, 200.0))
    t = arrays["t"]
    gps = t < 120.0
    arrays["omega"][gps] *= 2.0
    arrays["omega_std"][gps] *= 2.0
    cfg = fuse.Config(acc_psd=0.01, radius0=0.32, radius_std0=0.027)
    st = fuse.init(cfg, float(arrays["gps_speed"][0]))
    _, o = fuse.run(cfg, arrays, state=st)
    before = np.flatnonzero(gps)[-1]
    assert abs(o.radius[before] - r_true) < 0.002
    assert o.radius_std[before] < 0.002
    assert np.all(o.harmonic[gps & np.isfinite(o.harmonic)] == 0.5)
    out = (t >= 121.5) & (t < 200.0)
    assert abs(o.radius[-1] - r_true) < 0.002
    assert np.all(o.harmonic[out] == 1.0)
    assert np.all(o.source[out] == fuse.SRC_VIBRATION)
    assert np.mean(np.abs(o.speed[out] - v[out]) <= 0.01 * v[out]) > 0.99
    # the wide default prior: the line's ratio
    wide = fuse.Config(acc_psd=0.01)
    _, w = fuse.run(wide, arrays, state=fuse.init(wide, float(arrays["gps_speed"][0])))
    assert abs(w.radius[before] - r_true / 2) < 0.002
    assert np.all(w.harmonic[out] == 2.0)
    assert np.mean(np.abs(w.speed[out] - v[out]) <= 0.01 * v[out]) > 0.99


def test_outage_without_line_is_inertial_and_its_band_grows():
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=4, T=200.0, outage=(100.0, 160.0), no_line=(100.0, 160.0))
    _, o = fuse.run(cfg, arrays)
    t = arrays["t"]
    out = (t >= 100.0 + 1.5) & (t < 160.0)  # gps source holds 1.5 s after the last fix
    assert np.all(o.source[out] == fuse.SRC_INERTIAL)
    assert np.all(np.diff(o.speed_std[out]) > 0)
    # the accelerometer with its learned offset keeps the speed within its band
    z = np.abs(o.speed[out] - v[out]) / o.speed_std[out]
    assert np.mean(z < 2.33) > 0.9


def test_no_jump_beyond_the_band_when_gps_returns():
    """The radius prior is off by 4 % and there is no GPS before 60 s: the speed from vibration
    is 4 % wrong; when GPS arrives the forward filter moves towards it by at most its band per
    sample (z = 2.33, 98 %) and the smoothed speed has no step there either."""
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=5, T=120.0, r_true=0.31, outage=(0.0, 60.0))
    st = fuse.init(cfg, 0.0, radius=0.31 * 1.04, radius_std=0.002)
    _, o = fuse.run(cfg, arrays, state=st)
    t = arrays["t"]
    k0 = np.flatnonzero(t >= 60.0)[0]
    assert abs(o.speed[k0 - 1] / v[k0 - 1] - 1.04) < 0.01  # wrong by the radius before
    dv = np.abs(np.diff(o.speed[k0 - 5:k0 + 200]))
    band = 2.33 * o.speed_std[k0 - 5:k0 + 199]  # the band before each step
    assert np.all(dv <= band)
    # ... and still reaches the truth within a minute
    assert abs(o.speed[-1] - v[-1]) < 0.02 * v[-1]
    assert abs(o.radius[-1] - 0.31) < 0.003
    xs, Ps = fuse.smooth(cfg, o)
    ds = np.abs(np.diff(xs[k0 - 50:k0 + 50, 0]))
    assert ds.max() < 0.1  # m per 40 ms: a 2.5 m/s^2 change at most


def test_jump_bound_holds_for_any_innovation():
    """Module notes, item 2: one fix moves v by at most sqrt(P_vv) / (2 sqrt(c (1 - c)))."""
    rng = np.random.default_rng(7)
    for c in (0.05, 0.2, 0.5, 0.9):
        cfg = fuse.Config(r_gps_sq=c, e_max=1e6)
        for _ in range(50):
            st = fuse.init(cfg, 10.0, p0_speed=float(rng.uniform(0.01, 100.0)))
            g = 10.0 + float(rng.normal(0.0, 10.0 ** rng.uniform(-2, 3)))
            new, est = fuse.step(cfg, st, (0.0, np.nan, g, 9.0, np.nan, np.nan, False, False))
            bound = math.sqrt(st.P[0, 0]) / (2 * math.sqrt(c * (1 - c)))
            assert abs(est.speed - 10.0) <= bound * (1 + 1e-9)


def test_standstill_needs_all_evidence():
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=6, T=120.0, still=(60.0, 80.0))
    _, o = fuse.run(cfg, arrays)
    t = arrays["t"]
    stop = (t >= 60.0) & (t < 80.0)
    assert np.all(o.source[stop] == fuse.SRC_STANDSTILL)
    assert np.all(np.abs(o.speed[stop]) < 0.05)
    assert not np.any(o.source[~stop] == fuse.SRC_STANDSTILL)
    # a GPS that says we move vetoes the stop the vibration reports
    a2 = dict(arrays)
    g = a2["gps_speed"].copy()
    g[stop & np.isfinite(g)] = 5.0
    a2["gps_speed"] = g
    _, o2 = fuse.run(cfg, a2)
    assert not np.any(o2.source == fuse.SRC_STANDSTILL)
    # no GPS: the stop is taken where the integrated speed agrees with it
    a3 = dict(arrays)
    a3["gps_speed"] = np.where(t >= 30.0, np.nan, arrays["gps_speed"])
    _, o3 = fuse.run(cfg, a3)
    assert np.mean(o3.source[stop] == fuse.SRC_STANDSTILL) > 0.95


def test_satellite_gate():
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=8, T=60.0, no_line=(0.0, 60.0))
    t = arrays["t"]
    bad = (t >= 20.0) & (t < 40.0)
    arrays["gps_sats"] = np.where(bad, 4.0, 9.0)
    arrays["gps_speed"] = np.where(bad & np.isfinite(arrays["gps_speed"]), 0.0,
                                   arrays["gps_speed"])  # a receiver reporting 0 in a tunnel
    _, o = fuse.run(cfg, arrays)
    inside = bad & (t >= 21.5)
    assert np.all(o.source[inside] == fuse.SRC_INERTIAL)
    # not pulled towards the 0 m/s the receiver reports; the truth inside the band
    assert np.all(np.abs(o.speed[inside] - v[inside]) < 2.33 * o.speed_std[inside])
    assert o.speed[inside].min() > 5.0


def test_radius_from_json_round_trip(tmp_path):
    from vibrospeed.io import read_track, write_track

    t = np.arange(0.0, 10.0, 0.1)
    tr = Track.from_speed(t, np.full(t.size, 10.0), np.full(t.size, 0.1), wheel_radius=0.3125,
                          method="fuse", params={"learned_radius": 0.3125,
                                                 "learned_radius_std": 0.0007})
    p = tmp_path / "est.csv"
    write_track(tr, p)
    assert fuse.radius_from_json(f"{p}.json") == (0.3125, 0.0007)
    assert read_track(p).wheel_radius == 0.3125
    q = tmp_path / "r.json"
    q.write_text(json.dumps({"wheel_radius": 0.25}))
    assert fuse.radius_from_json(q) == (0.25, 0.0025)
    q.write_text(json.dumps({"wheel_radius": -1}))
    with pytest.raises(InputError, match="positive"):
        fuse.radius_from_json(q)
    q.write_text("{")
    with pytest.raises(InputError, match="r.json"):
        fuse.radius_from_json(q)
    q.write_text(json.dumps({"x": 1}))
    with pytest.raises(InputError, match="learned_radius"):
        fuse.radius_from_json(q)


def test_config_and_input_errors():
    with pytest.raises(ParameterError, match="r_gps_sq"):
        fuse.Config(r_gps_sq=1.0)
    with pytest.raises(ParameterError, match="acc_psd"):
        fuse.Config(acc_psd=0.0)
    cfg = fuse.Config()
    with pytest.raises(InputError, match="backwards"):
        fuse.run(cfg, {"t": np.array([0.0, 1.0, 0.5])})
    with pytest.raises(InputError, match="omega"):
        fuse.run(cfg, {"t": np.arange(3.0), "omega": np.ones(2)})
    st, _ = fuse.step(cfg, fuse.init(cfg), (1.0, 0.0, np.nan, np.nan, np.nan, np.nan, 0, 0))
    with pytest.raises(InputError, match="backwards"):
        fuse.step(cfg, st, (0.5, 0.0, np.nan, np.nan, np.nan, np.nan, 0, 0))


def test_fusion_blocks_put_each_fix_at_its_own_sample():
    t = np.arange(0.0, 2.0, 0.01)
    fix = np.zeros(t.size, bool)
    fix[[7, 33, 34, 150]] = True
    ends = fuse.fusion_samples(t, fix, 25.0)
    assert set([7, 33, 34, 150]) <= set(ends.tolist())
    assert ends[-1] == t.size - 1 and np.all(np.diff(ends) > 0) and np.diff(ends).max() <= 4
    x = np.arange(t.size, dtype=float)
    x[5] = np.nan
    m = fuse._block_mean(x, ends)
    starts = np.concatenate([[0], ends[:-1] + 1])
    ref = [np.nanmean(x[a:b + 1]) for a, b in zip(starts, ends, strict=True)]
    np.testing.assert_allclose(m, ref)


def _recording_with_line(seed=0, T=120.0, fs=200.0, r=0.3, gps=True):
    """A drive with a clean 3-harmonic wheel line on ay, longitudinal acceleration on ax and
    paper-receiver GPS fixes at 10 Hz."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / fs)
    v = 12.0 + 4.0 * np.sin(2 * np.pi * t / 40.0)
    a = np.gradient(v, t)
    phase = np.cumsum(v / r) / fs
    ay = sum(c * np.sin(k * phase) for k, c in ((1, 1.0), (2, 0.5), (3, 0.3)))
    ay = ay + 0.3 * rng.normal(size=t.size)
    ax = a + 0.1 + 0.2 * rng.normal(size=t.size)
    ch = {"ax": ax, "ay": ay, "az": 9.81 + 0.2 * rng.normal(size=t.size), "speed_true": v}
    if gps:
        g = np.full(t.size, np.nan)
        g[::20] = simulate_receiver(t, v, fuse.Config().lag)[::20] + rng.normal(
            0, 0.1, t[::20].size)
        ch.update(gps_speed=g, gps_sats=np.full(t.size, 9.0))
    return Recording(t, ch, source=f"synthetic{seed}")


@pytest.mark.slow
def test_estimate_learns_the_radius_and_reuses_it_without_gps(tmp_path):
    from vibrospeed.io import write_track

    rec = _recording_with_line(seed=1, r=0.3)
    tr = fuse.estimate(rec, params={"omega_min": 10.0, "omega_max": 120.0})
    assert tr.method == "fuse"
    assert abs(tr.params["learned_radius"] - 0.3) < 0.003
    assert set(np.unique(tr.extras["source"])) <= set(fuse.SOURCES)
    v = rec["speed_true"]
    assert np.mean(np.abs(tr.speed - v) <= 0.03 * v) > 0.95
    p = tmp_path / "drive1.csv"
    write_track(tr, p)
    # a second drive of the same vehicle without GPS: m/s from vibration alone
    rec2 = _recording_with_line(seed=2, r=0.3, gps=False)
    with pytest.raises(ParameterError, match="radius"):
        fuse.estimate(rec2, params={"omega_min": 10.0, "omega_max": 120.0})
    tr2 = fuse.estimate(rec2, params={"omega_min": 10.0, "omega_max": 120.0,
                                      "radius_from": str(p) + ".json"})
    v2 = rec2["speed_true"]
    assert np.mean(np.abs(tr2.speed - v2) <= 0.03 * v2) > 0.9
    assert tr2.params["radius_prior"][0] == pytest.approx(tr.params["learned_radius"])
    assert np.mean(tr2.extras["source"] == fuse.SRC_VIBRATION) > 0.8
    # online: causal tracker, forward filter; same learned radius within its band
    tr3 = fuse.estimate(rec, params={"omega_min": 10.0, "omega_max": 120.0, "online": "true"})
    assert abs(tr3.params["learned_radius"] - 0.3) < 0.003


def test_plot_colours_speed_by_source(tmp_path):
    from vibrospeed.eval import plot

    assert {k: v[0] for k, v in plot.SOURCE_COLOURS.items()} == fuse.SOURCES
    t = np.arange(0.0, 20.0, 0.01)
    rec = Recording(t, {"ay": np.sin(40 * t), "gps_speed": np.where(t < 10, 12.0, np.nan)})
    src = np.where(t < 10, 1.0, 2.0)
    tr = Track.from_speed(t, np.full(t.size, 12.0), np.full(t.size, 0.2), wheel_radius=0.3,
                          method="fuse", extras={"source": src})
    seen = []
    orig = plot.plt.Axes.plot

    def spy(self, *a, **k):
        seen.append(k.get("label"))
        return orig(self, *a, **k)

    plot.plt.Axes.plot = spy
    try:
        out = plot.plot_track(tmp_path / "f.png", rec, tr, axis="ay")
    finally:
        plot.plt.Axes.plot = orig
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "fuse: gps" in seen and "fuse: vibration" in seen and "fuse: inertial" not in seen


@pytest.mark.slow
def test_cli_fuse_and_radius_from(tmp_path):
    from typer.testing import CliRunner

    from vibrospeed import io
    from vibrospeed.cli.app import app

    runner = CliRunner()
    rec = _recording_with_line(seed=3, T=60.0, r=0.3)
    a = tmp_path / "a.csv"
    io.write(rec, a)
    b = tmp_path / "b.csv"
    io.write(_recording_with_line(seed=4, T=60.0, r=0.3, gps=False), b)
    rng = ["-p", "omega_min=10", "-p", "omega_max=120"]
    res = runner.invoke(app, ["estimate", str(a), "-m", "fuse", *rng, "-o",
                              str(tmp_path / "e.csv")])
    assert res.exit_code == 0, res.output
    side = json.loads((tmp_path / "e.csv.json").read_text())
    assert side["method"] == "fuse" and abs(side["params"]["learned_radius"] - 0.3) < 0.005
    res = runner.invoke(app, ["estimate", str(b), "-m", "fuse", *rng, "--radius-from",
                              str(tmp_path / "e.csv.json"), "-o", str(tmp_path / "f.csv")])
    assert res.exit_code == 0, res.output
    side2 = json.loads((tmp_path / "f.csv.json").read_text())
    assert side2["params"]["radius_prior"][0] == side["params"]["learned_radius"]
    res = runner.invoke(app, ["estimate", str(b), "-m", "grid", "--radius-from",
                              str(tmp_path / "e.csv.json"), "-o", str(tmp_path / "g.csv")])
    assert res.exit_code == 2 and "--radius-from is for --method fuse" in res.output
    res = runner.invoke(app, ["estimate", str(b), "-m", "fuse", *rng, "-o",
                              str(tmp_path / "h.csv")])
    assert res.exit_code == 2 and "needs a radius" in res.output
    assert "Traceback" not in res.output


@pytest.mark.slow
def test_cli_default_method_is_fuse_where_gps_speed_is_present(tmp_path):
    """``vibrospeed estimate`` without -m: fuse (with a note naming -m grid) on a recording
    with GPS fixes and ax; grid without GPS or with a grid option (--smooth, a grid-only
    preset); a fuse preset (online) keeps fuse."""
    import pandas as pd
    from typer.testing import CliRunner

    from vibrospeed import io
    from vibrospeed.cli.app import app

    runner = CliRunner()
    rec = _recording_with_line(seed=5, T=30.0, r=0.3)
    files = {"gps": rec, "none": _recording_with_line(seed=6, T=30.0, r=0.3, gps=False)}
    # what decides (a file cannot hold an all-empty channel: the reader refuses it)
    assert fuse.suits(rec) and not fuse.suits(files["none"])
    assert not fuse.suits(rec.with_channels(gps_speed=np.full(len(rec), np.nan)))
    assert not fuse.suits(Recording(rec.t, {"ay": rec["ay"], "gps_speed": rec["gps_speed"]}))
    assert fuse.suits(Recording(rec.t, {"az": rec["ax"], "gps_speed": rec["gps_speed"]}), "z")
    for name, r in files.items():
        io.write(r, tmp_path / f"{name}.csv")
    rng = ["-p", "omega_min=10", "-p", "omega_max=120"]

    def run(name, *extra):
        out = tmp_path / f"{name}{len(extra)}.csv"
        res = runner.invoke(app, ["estimate", str(tmp_path / f"{name}.csv"), *rng, *extra,
                                  "-o", str(out)])
        assert res.exit_code == 0, res.output
        side = json.loads(out.with_name(out.name + ".json").read_text())
        return res.output, side, pd.read_csv(out)

    text, side, df = run("gps")
    assert side["method"] == "fuse" and side["params"]["online"] is False
    assert "GPS speed" in text and "method fuse" in text and "-m grid" in text
    # the fused output keeps omega (speed / learned radius) and the tracker's own omega
    for col in ("omega", "speed", "speed_lo", "speed_hi", "source", "omega_vib", "has_signal"):
        assert col in df.columns
    np.testing.assert_allclose(df["omega"], df["speed"] / side["wheel_radius"], rtol=1e-6)
    for name, extra in (("none", ()), ("gps", ("--smooth",)),
                        ("gps", ("--preset", "lock"))):
        text, side, _ = run(name, *extra)
        assert side["method"] == "grid", (name, extra)
        assert "method fuse" not in text
    text, side, _ = run("gps", "--preset", "online")
    assert side["method"] == "fuse" and side["params"]["online"] is True


def test_omega_is_empty_where_the_radius_was_never_learned(tmp_path):
    """GPS but no wheel line (ay is noise): the radius stays at its wide prior, so the output
    has no omega (speed / an unknown radius is no wheel speed), says why, and still has the
    fused speed and the tracker's columns; the plot draws it."""
    from vibrospeed.eval.plot import plot_track

    rec = _recording_with_line(seed=7, T=30.0, r=0.3)
    rng = np.random.default_rng(7)
    rec = rec.with_channels(ay=rng.normal(size=len(rec)))
    tr = fuse.estimate(rec, params={"omega_min": 10.0, "omega_max": 120.0})
    assert tr.params["learned_radius_std"] >= fuse.Config().octave_rel * tr.params[
        "learned_radius"]
    assert tr.wheel_radius is None and np.all(np.isnan(tr.omega))
    assert any("omega is left empty" in n for n in tr.notes)
    v = rec["speed_true"]
    assert np.mean(np.abs(tr.speed - v) <= 0.03 * v) > 0.9  # GPS + accelerometer
    for col in ("omega_vib", "has_signal", "standstill", "source"):
        assert tr.extras[col].shape == (len(rec),)
    assert plot_track(tmp_path / "p.png", rec, tr, axis="ay").read_bytes()[:4] == b"\x89PNG"


def test_no_radius_from_a_line_claimed_at_a_standstill():
    """GPS says 0 and the tracker claims a line (an idling engine): r must not become 0."""
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=10, T=60.0, still=(0.0, 15.0))
    arrays["line"][:] = True
    arrays["omega"] = np.where(v < 0.5, 110.0, arrays["omega"])
    arrays["still"][:] = False
    _, o = fuse.run(cfg, arrays)
    assert np.all(o.radius > 0.2)
    assert abs(o.radius[-1] - 0.31) < 0.005
    # rolling off at 1-2 m/s with the engine line still claimed: no physical radius fits
    arrays["omega"] = np.where(v < 2.0, 110.0, arrays["omega"])
    _, o = fuse.run(cfg, arrays)
    assert np.all(o.radius > 0.2)


def test_negative_speed_is_projected_onto_zero():
    """Accelerometer only, the vehicle stops but the offset is wrong: without the constraint the
    integrated speed goes below 0; with it the state is the projection (v = 0, the correlated
    states moved by P[:, v] v / P_vv, P unchanged)."""
    t = np.arange(0.0, 30.0, 0.04)
    arrays = {"t": t, "accel": np.where(t < 10, -1.0, -0.3)}
    known = {"p0_offset": 1e-6, "q_offset": 0.0}  # an offset known to be 0
    st = fuse.init(fuse.Config(**known), 10.0, p0_speed=0.01)
    _, free = fuse.run(fuse.Config(nonneg=False, **known), arrays, state=st)
    assert free.speed.min() < -3.0
    cfg = fuse.Config(**known)
    _, o = fuse.run(cfg, arrays, state=st)
    assert o.speed.min() >= 0.0
    k = int(np.argmax(free.speed < 0))
    np.testing.assert_array_equal(o.speed[:k], free.speed[:k])
    # one step by hand at the first violation
    s_prev, _ = fuse.run(cfg, {n: v[:k] for n, v in arrays.items()}, state=st)
    raw, _ = fuse.step(fuse.Config(nonneg=False, **known), s_prev,
                       (t[k], arrays["accel"][k], np.nan, np.nan, np.nan, np.nan, 0, 0))
    proj, _ = fuse.step(cfg, s_prev,
                        (t[k], arrays["accel"][k], np.nan, np.nan, np.nan, np.nan, 0, 0))
    want = raw.x - raw.P[:, 0] * raw.x[0] / raw.P[0, 0]
    np.testing.assert_allclose(proj.x, want, atol=1e-12)
    np.testing.assert_array_equal(proj.P, raw.P)


def test_relock_when_the_filter_diverged_in_an_outage():
    """A wrong offset (a false stop) makes the inertial speed run away in an outage while the
    line is gated out. The line returns at 130 s far outside the filter's band, with a constant
    gap to the filter's speed: it is taken once it has moved with the speed by acq_change (a
    constant line so far away may be an idling engine), not before."""
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=11, T=200.0, outage=(100.0, 200.0), no_line=(100.0, 130.0))
    t = arrays["t"]
    arrays["accel"] = np.where((t >= 100.0) & (t < 130.0), arrays["accel"] + 1.5,
                               arrays["accel"])  # the speed runs 45 m/s away
    _, o = fuse.run(cfg, arrays)
    _, stuck = fuse.run(fuse.Config(acc_psd=0.01, vib_relock=1e9), arrays)
    # the line's speed (= v) has moved by acq_change since it came back
    i0 = np.flatnonzero(t >= 130.0)[0]
    moved = (t >= 130.0 + cfg.vib_relock) & (np.abs(v - v[i0]) >= cfg.acq_change * v)
    t_move = t[np.flatnonzero(moved)[0]]
    assert 135.0 < t_move < 150.0
    before = (t >= 130.0) & (t < t_move - 0.5)
    assert np.all(np.abs(o.speed[before] - v[before]) > 10.0)
    late = t >= t_move + 0.5
    assert np.median(np.abs(stuck.speed[late] - v[late])) > 10.0
    assert np.all(np.abs(o.speed[late] - v[late]) < 0.03 * v[late])
    assert np.all(o.source[late] == fuse.SRC_VIBRATION)


def test_unclaimed_lines_widen_the_band_so_that_a_claimed_line_relocks():
    """A drift like the re-lock test's, with the wheel's line held but not claimed (``soft``)
    for the 10 s before its claims return at 130 s: the unclaimed lines are not taken (the
    speed stays where the accelerometer put it, the radius untouched), but their consistent
    gap widens the band to it, so the claimed line re-locks after one run of ``vib_relock`` s
    instead of waiting until it has moved with the speed by ``acq_change``. The drift (6 m/s
    on 20) keeps the line within a factor sqrt 2 of the filter's speed (farther, it lies
    nearer another octave of it and no band re-locks it:
    ``test_a_relock_never_moves_the_speed_by_an_octave``); a steady offset (``q_offset``
    small) keeps the inertial band narrow against it."""
    cfg = fuse.Config(acc_psd=0.01, q_offset=1e-5)
    arrays, v = synth(seed=11, T=200.0, outage=(100.0, 200.0), no_line=(100.0, 130.0),
                      cfg=cfg)
    t = arrays["t"]
    arrays["accel"] = np.where((t >= 100.0) & (t < 115.0), arrays["accel"] + 0.4,
                               arrays["accel"])  # the speed runs 6 m/s away
    _, hard = fuse.run(cfg, arrays)
    soft = (t >= 120.0) & (t < 130.0)
    arrays["line"] = arrays["line"] | soft
    arrays["soft"] = soft
    _, o = fuse.run(cfg, arrays)
    # not taken: the speed is as far off as without them, no vibration source, r unchanged
    np.testing.assert_array_equal(o.speed[soft], hard.speed[soft])
    np.testing.assert_array_equal(o.radius[soft], hard.radius[soft])
    assert not np.any(o.source[soft] == fuse.SRC_VIBRATION)
    assert np.all(np.abs(o.speed[soft] - v[soft]) > 4.0)
    # but the band grew by the gap: the truth is inside 3 sigma at 130 s, not without them
    i0 = np.flatnonzero(t >= 130.0)[0]
    assert abs(o.speed[i0 - 1] - v[i0 - 1]) <= 3.0 * o.speed_std[i0 - 1]
    assert abs(hard.speed[i0 - 1] - v[i0 - 1]) > 3.0 * hard.speed_std[i0 - 1]
    # without them the claimed line waits until its speed has moved by acq_change or the
    # inertial band has grown to its gap
    early = (t >= 130.0 + cfg.vib_relock + 0.5) & (t < 135.0)
    assert np.all(np.abs(o.speed[early] - v[early]) < 0.03 * v[early])
    assert np.all(np.abs(hard.speed[early] - v[early]) > 4.0)
    late = t >= 130.0 + cfg.vib_relock + 0.5
    assert np.all(np.abs(o.speed[late] - v[late]) < 0.03 * v[late])


def test_an_unclaimed_line_that_continues_the_used_one_is_taken():
    """In an outage the accelerometer reads 0.1 m/s^2 too high from 100 s on; the tracker
    claims the wheel's line until 110 s and then holds it unclaimed (``soft``) to 130 s, with
    a stretch at 118-118.2 s where its mode jumps 25 % (a resonance). Each unclaimed line that
    continues the last one used (within ``vib_soft_hold`` s, half an octave) and lies within
    the soft gate (2 sigma) of the prediction is taken: the speed stays on the wheel's line
    (within 3 %) where with ``vib_soft_gate = 0`` (none taken) it drifts by the offset's
    integral; the 25 % jump is refused and the line after it, 0.2 s later, continues the
    last one used before the jump. A line unclaimed after 2 s without any line used is not
    taken directly (no continuation)."""
    cfg = fuse.Config(acc_psd=0.01, q_offset=1e-5)
    arrays, v = synth(seed=12, T=160.0, outage=(100.0, 160.0), no_line=(110.0, 160.0),
                      cfg=cfg)
    t = arrays["t"]
    arrays["accel"] = np.where(t >= 100.0, arrays["accel"] + 0.1, arrays["accel"])
    jump = (t >= 118.0) & (t < 118.2)
    soft = ((t >= 110.0) & (t < 130.0)) | (t >= 142.0)  # 12 s without a line before 142 s
    arrays["omega"] = np.where(jump, 1.25 * arrays["omega"], arrays["omega"])
    arrays["line"] = arrays["line"] | soft
    arrays["soft"] = soft
    _, o = fuse.run(cfg, arrays)
    _, off = fuse.run(replace(cfg, vib_soft_gate=0.0), arrays)
    held = soft & (t < 130.0) & ~jump
    assert np.all(np.isfinite(o.harmonic[held]))
    assert np.all(o.source[held] == fuse.SRC_VIBRATION)
    assert not np.any(np.isfinite(o.harmonic[jump]))
    assert not np.any(np.isfinite(off.harmonic[soft]))
    assert np.all(np.abs(o.speed[held] - v[held]) < 0.03 * v[held])
    late = (t >= 125.0) & (t < 130.0)
    assert np.all(np.abs(off.speed[late] - v[late]) > 1.0)
    # after 12 s without a line the unclaimed one is no continuation
    assert not np.any(np.isfinite(o.harmonic[t >= 142.0]))


def test_a_relock_never_moves_the_speed_by_an_octave():
    """The tracker follows half the wheel's frequency while GPS is good, so r is learned at
    twice the wheel's radius (the wide prior: k = 1 costs no octave penalty). In the outage
    it claims no line for 40 s (the inertial band grows to several m/s) and then the wheel's
    own frequency: at k = 1 with that r the line says twice the speed, inside the band. The
    line lies nearer the octave below the filter's speed (within a factor sqrt 2 of it at
    k = 1/2), so no re-lock takes it at k = 1: the speed never leaves the truth by more than
    the accelerometer's drift. The same line with the r it implies (r_true: the tracker on
    the wheel's line all along) re-locks and is taken (the control)."""
    cfg = fuse.Config(acc_psd=0.01)
    r_true = 0.3
    arrays, v = synth(seed=21, T=200.0, r_true=r_true, outage=(100.0, 200.0),
                      no_line=(100.0, 140.0))
    t = arrays["t"]
    half = arrays.copy()
    half["omega"] = np.where(t < 100.0, 0.5 * arrays["omega"], arrays["omega"])
    half["omega_std"] = np.where(t < 100.0, 0.5 * arrays["omega_std"], arrays["omega_std"])
    _, o = fuse.run(cfg, half)
    before = np.flatnonzero(t < 100.0)[-1]
    assert abs(o.radius[before] - 2.0 * r_true) < 0.01  # the line's ratio
    back = t >= 140.0
    # the band at the line's return holds 2 v: a k = 1 re-lock would have been allowed
    i0 = np.flatnonzero(back)[0]
    assert abs(2.0 * v[i0] - o.speed[i0 - 1]) <= 3.0 * o.speed_std[i0 - 1]
    assert np.all(o.speed[back] < 1.3 * v[back])
    assert not np.any(o.harmonic[back] == 1.0)
    # the control: the line that taught r is the wheel's, the same outage re-locks on it
    _, c = fuse.run(cfg, arrays)
    late = t >= 150.0
    assert np.mean(c.source[late] == fuse.SRC_VIBRATION) > 0.9
    assert np.all(np.abs(c.speed[late] - v[late]) < 0.03 * v[late])


def _braking_outage(cfg, seed):
    """``(rng, t, v, a_m, gps)``: 120 s at 20 m/s braking at 3 m/s^2 over 70-74 s, the
    accelerometer with offset 0.2 m/s^2 and white noise, GPS (through the receiver lag) every
    second sample until 60 s, then an outage; ``rng`` continues the stream."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 120.0, 1.0 / FR)
    a = np.where((t >= 70.0) & (t < 74.0), -3.0, 0.0)
    v = 20.0 + np.concatenate([[0.0], np.cumsum(0.5 * (a[1:] + a[:-1]) / FR)])
    am = a + 0.2 + rng.normal(0.0, math.sqrt(1e-3 * FR), t.size)
    am[0] = np.nan
    rx = simulate_receiver(t, v, cfg.lag)
    g = np.full(t.size, np.nan)
    g[::2] = rx[::2] + rng.normal(0.0, 0.1, t[::2].size)
    g[t >= 60.0] = np.nan
    return rng, t, v, am, g


def test_a_line_an_octave_off_the_prediction_is_read_at_that_octave():
    """In a hard braking the causal tracker's line jumps to the wheel's 2nd harmonic for 2 s;
    the lag variance ``(vib_lag a)^2`` (6 m/s at 3 m/s^2) would let the doubled line in at
    k = 1. Its speed at k = 1 is twice the filter's (beyond a factor sqrt 2), so only k = 1/2
    is a hypothesis: it is read as the wheel's (harmonic 1/2) and the speed follows the
    braking; never k = 1."""
    cfg = fuse.Config(acc_psd=1e-3, vib_lag=2.0)
    rng, t, v, am, g = _braking_outage(cfg, 7)
    om = v / 0.31 + rng.normal(0.0, 0.05, t.size)
    jump = (t >= 71.0) & (t < 73.0)
    om[jump] *= 2.0
    arrays = {"t": t, "accel": am, "gps_speed": g, "gps_sats": np.full(t.size, 9.0),
              "omega": om, "omega_std": np.full(t.size, 0.05), "line": np.ones(t.size, bool)}
    _, o = fuse.run(cfg, arrays, state=fuse.init(cfg, 20.0))
    assert not np.any(o.harmonic[jump] == 1.0)
    assert np.mean(o.harmonic[jump] == 0.5) > 0.9
    braking = (t >= 70.0) & (t < 75.0)
    assert np.max(np.abs(o.speed[braking] - v[braking])) < 0.1 * 20.0
    assert np.all(np.abs(o.speed[jump] - v[jump]) < 0.5 * v[jump])


def test_no_line_is_used_beyond_vib_amax():
    """A causal tracker's line trails the speed by 2 s. In an outage the car brakes at 3 m/s^2
    from 20 to 8 m/s: with ``vib_amax`` no line is taken while the acceleration exceeds it and
    the accelerometer (its offset learned while GPS held the speed) carries the braking within
    0.3 m/s; with every line taken (weighted by the lag variance ``(vib_lag a)^2``) the lagging
    line drags the speed up (0.62 against 0.18 m/s at the defaults)."""
    cfg0 = fuse.Config(acc_psd=1e-3, vib_lag=2.0)
    rng, t, v, am, g = _braking_outage(cfg0, 6)
    v_lag = np.interp(t - 2.0, t, v)
    arrays = {"t": t, "accel": am, "gps_speed": g, "gps_sats": np.full(t.size, 9.0),
              "omega": v_lag / 0.31 + rng.normal(0.0, 0.05, t.size),
              "omega_std": np.full(t.size, 0.05), "line": np.ones(t.size, bool)}
    st = fuse.init(cfg0, 20.0)
    _, every = fuse.run(cfg0, arrays, state=st)
    _, o = fuse.run(replace(cfg0, vib_amax=1.5), arrays, state=st)
    braking = (t >= 70.3) & (t < 74.0)
    assert not np.any(np.isfinite(o.harmonic[braking]))
    assert np.mean(np.isfinite(every.harmonic[braking])) > 0.9
    # where the acceleration is small, the lines are taken as before
    calm = (t >= 80.0) & (t < 120.0)
    assert np.mean(np.isfinite(o.harmonic[calm])) > 0.95
    err = np.abs(o.speed[braking] - v[braking])
    err_every = np.abs(every.speed[braking] - v[braking])
    assert err.max() < 0.3
    assert err_every.max() > 3.0 * err.max()


def test_a_continuing_line_is_taken_without_the_decisive_gate():
    """A line that continues the one used at the previous sample keeps its octave: here the
    tracker reports a spread of 6 rad/s (12-16 % of omega), so ``3 sqrt(P_vv + (r s)^2) <=
    vib_sep r omega`` never holds away from GPS, yet the line taken with GPS at 30 s is taken
    at every sample of the outage until it stops at 40 s; when it comes back at 50 s (no line
    used just before) it waits for the re-lock run of ``vib_relock`` s and is then taken at
    every sample again."""
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=4, T=70.0, outage=(30.0, 70.0), no_line=(40.0, 50.0), cfg=cfg)
    arrays["omega_std"][:] = 6.0
    _, o = fuse.run(cfg, arrays)
    t = arrays["t"]
    u = o.radius * arrays["omega"]
    spread = 3 * np.sqrt(o.speed_std**2 + (o.radius * 6.0) ** 2)
    away = (t >= 30.04) & (t < 40.0)
    assert np.all(spread[away] > cfg.vib_sep * u[away])  # never decisive there
    assert np.all(o.harmonic[away] == 1.0)
    assert np.all(o.source[(t >= 31.6) & (t < 40.0)] == fuse.SRC_VIBRATION)
    assert np.max(np.abs(o.speed - v)[away]) < 0.5
    back = t >= 50.0
    first = t[back][np.isfinite(o.harmonic[back])][0]
    assert first == pytest.approx(50.0 + cfg.vib_relock, abs=0.05)
    assert np.all(o.harmonic[t >= first] == 1.0)


def test_a_long_stop_is_taken_even_when_the_integrated_speed_drifted():
    """In an outage a wrong offset makes the integrated speed drift before a stop; the stop
    evidence is refused at first (the speed disagrees) and taken after still_relock s."""
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=12, T=160.0, outage=(90.0, 160.0), no_line=(90.0, 160.0),
                      still=(120.0, 140.0))
    t = arrays["t"]
    arrays["accel"] = np.where((t >= 90.0) & (t < 120.0), arrays["accel"] + 1.0,
                               arrays["accel"])
    _, stuck = fuse.run(fuse.Config(acc_psd=0.01, still_relock=1e9), arrays)
    _, o = fuse.run(cfg, arrays)
    stop = (t >= 120.0) & (t < 140.0)
    first = (t >= 120.0) & (t < 126.0)
    assert np.all(stuck.source[first] != fuse.SRC_STANDSTILL)
    assert np.all(np.abs(stuck.speed[first]) > 10.0)
    late = stop & (t >= 120.0 + cfg.still_relock + 0.1)
    assert np.all(o.source[late] == fuse.SRC_STANDSTILL)
    assert np.all(np.abs(o.speed[late]) < 0.05)


def test_rts_smoother_against_a_numpy_reference():
    cfg = fuse.Config(acc_psd=0.01)
    arrays, v = synth(seed=13, T=40.0, outage=(15.0, 30.0), no_line=(18.0, 26.0))
    _, o = fuse.run(cfg, arrays)
    xs, Ps = fuse.smooth(cfg, o)
    Ac = cfg._arrays()[0]
    n = o.xf.shape[0]
    ref_x, ref_P = o.xf.copy(), o.Pf.copy()
    for k in range(n - 2, -1, -1):
        F = expm(Ac * o.dt[k + 1])
        C = np.linalg.solve(o.Pp[k + 1].T, (o.Pf[k] @ F.T).T).T
        ref_x[k] = o.xf[k] + C @ (ref_x[k + 1] - o.xp[k + 1])
        ref_P[k] = o.Pf[k] + C @ (ref_P[k + 1] - o.Pp[k + 1]) @ C.T
    np.testing.assert_allclose(xs, ref_x, atol=1e-6)
    # (the compiled smoother uses pinv, the reference solve: Pp is ill-conditioned where the
    # radius is known to 1e-4 m, so agreement is relative there)
    np.testing.assert_allclose(Ps, ref_P, rtol=1e-5, atol=1e-8)
    # the smoother also uses what comes after: never a wider spread than the filter's
    assert np.all(Ps[:, 0, 0] <= o.Pf[:, 0, 0] + 1e-12)
    np.testing.assert_array_equal(xs[-1], o.xf[-1])
