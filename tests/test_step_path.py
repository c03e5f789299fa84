"""The per-sample step paths: states left as they are, extras equal to the batch columns, the
online pipeline equal to its stages chained by hand."""

import pickle

import numpy as np
import pytest

from vibrospeed.estimators import grid, rbpmf
from vibrospeed.estimators.grid import filter as gf
from vibrospeed.estimators.online import OnlineTracker
from vibrospeed.signal import normalize as nz
from vibrospeed.signal import prefilter as pf
from vibrospeed.signal import whiten as wh
from vibrospeed.types import Recording


def _signal(n=400, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 100.0
    y = np.cos(30.0 * t) + 0.5 * np.cos(60.0 * t) + 0.3 * rng.normal(size=n)
    y[50:53] = np.nan
    return y


def _small_cfg():
    return grid.Config(tracker=grid.config_for(
        Recording(np.arange(200) / 100.0, {"ay": np.zeros(200)}), axis="y",
        params={"n_grid": 40, "smooth": "none"}).tracker, comb_window=1.0)


def test_filter_step_leaves_the_state_and_repeats_bitwise():
    cfg = _small_cfg().tracker
    y = _signal()
    st = gf.init(cfg)
    for v in y[:120]:
        st, _ = gf.step(cfg, st, v)
    kept = [np.array(a, copy=True) for a in (st.log_w, st.mean, st.cov)]
    a1, e1 = gf.step(cfg, st, y[120], extra=np.linspace(-1.0, 1.0, cfg.n_grid))
    a2, e2 = gf.step(cfg, st, y[120], extra=np.linspace(-1.0, 1.0, cfg.n_grid))
    for old, now in zip(kept, (st.log_w, st.mean, st.cov), strict=True):
        assert np.array_equal(old, now)  # the stepped state is unchanged
    for f in ("log_w", "mean", "cov", "log_w_null", "mode_j"):
        assert np.array_equal(getattr(a1, f), getattr(a2, f))
    assert a1.mean is not st.mean and a1.cov is not a2.cov  # fresh storage each time
    assert e1[:8] == e2[:8] and dict(e1.extras).keys() == dict(e2.extras).keys()
    # a state built from views and other layouts steps as its contiguous copy
    odd = gf.State(st.log_w[::-1][::-1], np.asfortranarray(st.mean), st.cov.copy(),
                   st.log_w_null, st.mode_j)
    b, eb = gf.step(cfg, odd, y[121])
    c, ec = gf.step(cfg, st, y[121])
    assert np.array_equal(b.cov, c.cov) and eb.omega == ec.omega
    with pytest.raises(ValueError, match="do not match"):
        gf.step(cfg, st._replace(mean=st.mean[:-1]), 0.1)


def test_step_extras_are_the_run_columns():
    cfg = _small_cfg().tracker
    y = _signal(n=200, seed=1)
    res = gf.run(cfg, y, return_posterior=True)
    st = gf.init(cfg)
    for k, v in enumerate(y):
        st, est = gf.step(cfg, st, v)
        ex = est.extras
        assert tuple(ex) == gf.ESTIMATE_EXTRAS and len(ex) == len(gf.ESTIMATE_EXTRAS)
        for name in gf.ESTIMATE_EXTRAS:
            if name == "posterior":
                assert np.array_equal(ex[name].astype(np.float32), res.posterior[k])
            elif name == "amplitudes":
                assert np.array_equal(ex[name], res.amplitudes[k])
            else:
                assert ex[name] == getattr(res, name)[k], (k, name)
            assert name in ex
        assert est.has_signal == cfg.claims(res.p_null[k])
        assert est.omega == res.omega[k] and est.omega_std == res.omega_std[k]
        assert np.isnan(est.speed) and np.isnan(est.standstill)
    assert "omega" not in ex and ex.get("nothing") is None
    with pytest.raises(KeyError):
        ex["nothing"]
    back = pickle.loads(pickle.dumps(est))
    assert back.p_null == est.p_null and np.array_equal(back.posterior, est.posterior)
    assert repr(ex).startswith("{'omega_map': ")


def test_grid_step_with_a_number_or_an_array_the_same():
    cfg = _small_cfg()
    y = _signal(n=260, seed=2)
    s1 = s2 = grid.init(cfg)
    for v in y:
        s1, e1 = grid.step(cfg, s1, float(v))
        s2, e2 = grid.step(cfg, s2, np.array([v]))
        assert e1.omega == e2.omega or (np.isnan(e1.omega) and np.isnan(e2.omega))
    assert np.array_equal(s1.buf, s2.buf, equal_nan=True) and s1.count == s2.count == y.size
    assert np.array_equal(s1.grid.cov, s2.grid.cov)
    res = grid.run(cfg, y)
    assert np.array_equal(res.omega[-1], e1.omega) and np.array_equal(res.final.buf, s1.buf,
                                                                       equal_nan=True)


def test_prefilter_step_keeps_old_states_and_checks_the_state():
    sos = pf.design("thesis-hplp", 100.0, M=2)
    x = np.random.default_rng(3).normal(size=50) + 9.8
    st = pf.init(sos)
    for v in x[:20]:
        st, _ = pf.step(sos, st, v)
    zi = st.zi.copy()
    a, ya = pf.step(sos, st, x[20])
    b, yb = pf.step(sos, st, x[20])
    assert ya == yb and np.array_equal(a.zi, b.zi) and np.array_equal(st.zi, zi)
    # the same sections as a nested list
    _, yc = pf.step(sos.tolist(), st, x[20])
    assert yc == ya
    with pytest.raises(ValueError, match="n_sections"):
        pf.step(sos, pf.PrefilterState(np.zeros((1, 2)), True), 1.0)


def _chained(trk, sample_states, x):
    """The pipeline's stages called one by one, as OnlineTracker documents them."""
    fs, ns, ws = sample_states
    fs, y = pf.step(trk.sos, fs, x)
    if trk.whiten:
        ws, y = wh.step(ws, y, 1.0 / trk.dt)
    if trk.tau:
        ns, y = nz.step(ns, y, trk.dt, trk.tau)
        y = trk.target * y
    return (fs, ns, ws), (y if np.isfinite(y) else np.nan)


@pytest.mark.parametrize("mod", [grid, rbpmf])
def test_online_tracker_equals_its_stages_by_hand_bitwise(mod):
    rng = np.random.default_rng(4)
    n = 500
    t = np.arange(n) / 100.0
    ay = 0.2 * np.cos(30.0 * t) + 0.1 * np.cos(60.0 * t) + 0.05 * rng.normal(size=n) + 9.8
    ay[200:204] = np.nan
    rec = Recording(t, {"ay": ay})
    params = {"n_grid": 40, "smooth": "none", "comb_window": 1.0} if mod is grid else {
        "n_grid": 40}
    cfg = mod.config_for(rec, axis="y", params=params)
    trk = OnlineTracker(mod, cfg, level=9.8)
    (front,), es = trk.state
    for v in ay:
        est = trk.update(float(v))
        front, y = _chained(trk, front, v)
        es, ref = mod.step(cfg, es, y)
        assert (est.omega == ref.omega and est.omega_std == ref.omega_std
                and est.p_null == ref.p_null), v
    assert np.array_equal(trk.state[1].grid.cov if mod is grid else trk.state[1].cov,
                          es.grid.cov if mod is grid else es.cov)


def test_algebraic_step_takes_exactly_its_four_inputs():
    """``step`` handed 3 values used to read past them (a speed of 3.5e-321 from whatever lay
    in memory) and 5 values dropped the last silently; ``run`` already refused such rows."""
    from vibrospeed.errors import ParameterError
    from vibrospeed.estimators import algebraic

    cfg = algebraic.Config()
    st = algebraic.init(cfg)
    for y in ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 40.0, 99.0], 40.0, np.zeros((1, 4))):
        with pytest.raises(ParameterError, match=r"algebraic.step expects 4 inputs"):
            algebraic.step(cfg, st, y)
    for y in ([0, 0, 0, 40], (0.0, 0.0, 0.0, 40.0), np.array([0, 0, 0, 40], np.float32)):
        _, est = algebraic.step(cfg, st, y)
        assert est.speed == algebraic.run(cfg, np.array([[0.0, 0.0, 0.0, 40.0]])).speed[0]
        assert abs(est.speed - cfg.r * 40.0) < 1e-9


#: child code's helper: each call's outcome, 'ran' or the name of what it raised
_OUTCOMES = (
    "def outcomes(calls):\n"
    "    out = []\n"
    "    for call in calls:\n"
    "        try:\n"
    "            call()\n"
    "            out.append('ran')\n"
    "        except Exception as exc:\n"
    "            out.append(type(exc).__name__)\n"
    "    return out\n")


def _in_a_child(code: str) -> str:
    """Runs ``code`` in a fresh interpreter (a read past an array can abort the process), with
    :data:`_OUTCOMES`' ``outcomes`` defined, and returns its last output line."""
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-c", _OUTCOMES + code], capture_output=True, text=True,
                         timeout=300)
    lines = (res.stdout + res.stderr).strip().splitlines()
    return lines[-1] if lines else f"exit status {res.returncode}"


def test_ekf_refuses_a_state_of_another_model():
    """An M = 3 state handed to an M = 2 filter (and the reverse) used to run: the compiled
    step read and wrote past the arrays (heap corruption, "malloc(): mismatching
    next->prev_size") or returned numbers from whatever lay in memory."""
    code = (
        "import numpy as np\n"
        "from vibrospeed.models.harmonic import HarmonicModel\n"
        "from vibrospeed.estimators import ekf\n"
        "c2, c3 = (ekf.Config(HarmonicModel.from_thesis(M=m)) for m in (2, 3))\n"
        "out = []\n"
        "for a, b in ((c3, c2), (c2, c3)):\n"
        "    out += outcomes((lambda: ekf.step(b, ekf.init(a), 0.1),\n"
        "                     lambda: ekf.run(b, np.full(50, 0.1), state=ekf.init(a))))\n"
        "print(','.join(out))\n")
    assert _in_a_child(code) == "ParameterError,ParameterError,ParameterError,ParameterError"
    from vibrospeed.errors import ParameterError
    from vibrospeed.estimators import ekf

    cfg = ekf.Config()
    with pytest.raises(ParameterError, match=r"ekf state: .* do not match the config's M = 3"):
        ekf.step(cfg, ekf.init(cfg)._replace(comb=np.zeros(2)), 0.1)
    st = ekf.init(cfg)._replace(comb=None)  # None: the comb check as init makes it
    assert ekf.step(cfg, st, 0.1)[1].omega == ekf.step(cfg, ekf.init(cfg), 0.1)[1].omega


def test_rbpf_refuses_a_state_of_another_particle_count_or_model():
    """An M = 2 state in an M = 3 filter used to corrupt the heap ("double free or
    corruption"); a state of 20 particles ran in a filter configured for 30."""
    code = (
        "from vibrospeed.models.harmonic import HarmonicModel\n"
        "from vibrospeed.estimators import rbpf\n"
        "m2 = rbpf.Config(n_particles=20, model=HarmonicModel.from_thesis(M=2))\n"
        "m3 = rbpf.Config(n_particles=20)\n"
        "k30 = rbpf.Config(n_particles=30)\n"
        "out = []\n"
        "for cfg, st in ((m3, rbpf.init(m2)), (m2, rbpf.init(m3)), (k30, rbpf.init(m3))):\n"
        "    out += outcomes((lambda: rbpf.step(cfg, st, 0.1),\n"
        "                     lambda: rbpf.run(cfg, [0.1] * 5, st)))\n"
        "print(','.join(out))\n")
    assert _in_a_child(code) == ",".join(["ParameterError"] * 6)


def test_shs_and_algebraic_refuse_a_state_made_for_another_config():
    """shs: a state of 200-sample batches in a 100-sample config gave a batch of the wrong
    length or numpy's broadcast error; algebraic: a state for other windows gave NaN (step) or
    shifted numbers (run)."""
    from vibrospeed.errors import ParameterError
    from vibrospeed.estimators import algebraic, shs

    s100, s200 = shs.Config(batch=100), shs.Config(batch=200)
    part = shs.run(s100, np.zeros(90)).final
    for cfg, st in ((s100, shs.init(s200)), (s200, shs.init(s100)), (s200, part)):
        with pytest.raises(ParameterError, match=r"shs state: .* batch = "):
            shs.step(cfg, st, 0.1)
        with pytest.raises(ParameterError, match=r"shs state: .* batch = "):
            shs.run(cfg, np.zeros(150), state=st)
    assert shs.run(s100, np.zeros(30), state=part).final.count == 20  # its own config: fine
    a1 = algebraic.Config()
    for a2 in (algebraic.Config(window=0.3, window_d=0.5),
               algebraic.Config(detect="seed", alpha=80)):
        with pytest.raises(ParameterError, match=r"algebraic state: .* do not match"):
            algebraic.step(a2, algebraic.init(a1), [0.0, 0.0, 0.0, 40.0])
        with pytest.raises(ParameterError, match=r"algebraic state: .* do not match"):
            algebraic.run(a2, np.tile([0.0, 0.0, 0.0, 40.0], (20, 1)), state=algebraic.init(a1))


def test_gps_riss_step_takes_unknown_satellites_as_none():
    """``Sample`` documents ``gps_sats`` None as "unknown" (``run`` takes it); ``step`` raised
    TypeError: float() argument must be ... not 'NoneType'."""
    from vibrospeed.estimators import gps_riss

    cfg = gps_riss.Config()
    n = 60
    t = np.arange(n) * 0.01
    gps = np.where(np.arange(n) % 10 == 0, 10.0 + 0.1 * t, np.nan)
    ax = np.full(n, 0.1)
    res = gps_riss.run(cfg, gps_riss.Sample(t, ax, gps, None), state=gps_riss.init(cfg, 10.0))
    st = gps_riss.init(cfg, 10.0)
    for k in range(n):
        st, est = gps_riss.step(cfg, st, gps_riss.Sample(t[k], ax[k], gps[k], None))
        assert est.speed == res.speed[k] and est.speed_std == res.speed_std[k]


def test_algebraic_state_shapes_are_the_documented_ones():
    """The State docstring said ``hist`` (3, backtrack + 2) and ``s`` (41,); init makes
    (4, n_back + 2) and (42,), the shapes step and run check."""
    from vibrospeed.estimators import algebraic

    for cfg in (algebraic.Config(), algebraic.Config(detect="seed", alpha=80)):
        st = algebraic.init(cfg)
        assert st.buf.shape == (4, cfg.taps()[0].size)
        assert st.hist.shape == (4, cfg.n_back + 2) and st.s.shape == (42,)
        doc = algebraic.State.__doc__
        assert "``hist`` (4, ``n_back`` + 2)" in doc and "``s`` (42,)" in doc


def test_is_count_and_check_state_the_shared_checks():
    from vibrospeed.config import check_state, is_count
    from vibrospeed.errors import ParameterError

    assert is_count(3) and is_count(np.int64(3)) and is_count(0, 0)
    assert not any(is_count(v) for v in (0, -1, 3.0, True, np.float64(3), "3", None))
    check_state("m", "M = 2", x=(np.zeros(4), (4,)), b=(None, None))
    with pytest.raises(ParameterError) as e:
        check_state("m", "M = 2", x=(np.zeros(6), (4,)), P=(np.zeros((4, 4)), (4, 4)))
    assert str(e.value) == ("m state: x, P ((6,), (4, 4)) do not match the config's M = 2 "
                            "(wanted ((4,), (4, 4)))")
