"""The fixed-lag smoother on a device (:class:`vibrospeed.estimators.grid.lagged.LaggedTracker`)
and the lagged standstill stream (:class:`vibrospeed.signal.standstill_stream.LagStream`): sample by
sample, the numbers of the batch ``estimate(..., smooth="lag")``."""

import pickle

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid
from vibrospeed.estimators.common import start_level
from vibrospeed.estimators.grid.lagged import LaggedTracker
from vibrospeed.signal import standstill as ss
from vibrospeed.signal import standstill_stream as sst
from vibrospeed.sim import simulate
from vibrospeed.types import Recording

#: the Track's per-sample columns an Estimate carries as fields
FIELDS = ("omega", "omega_std", "omega_lo", "omega_hi", "speed", "speed_std")


def stream(rec, params, axis="y", standstill=True, radius=None, posterior=False):
    """``(batch Track, [(k, Estimate)], tracker)`` for ``rec`` fed one sample at a time
    (``posterior``: the batch's ``return_posterior=True``, the tracker's ``posterior=True``)."""
    track = grid.estimate(rec, axis=axis, params=params, wheel_radius=radius,
                          return_posterior=posterior)
    cfg = grid.config_for(rec, axis=axis, params=params)
    comb = list(cfg.comb_axes) or ["a" + axis]
    chans = comb + [c for c in ("ax", "ay", "az") if c not in comb and c in rec]
    A = len(comb)
    trk = LaggedTracker(cfg, level=[start_level(rec[c], cfg.tracker.model.dt) for c in comb],
                        standstill=len(chans) if standstill else 0,
                        wheel_radius=radius or rec.wheel_radius,  # as the batch Track's
                        posterior=posterior)
    out = []
    for row in np.column_stack([rec[c] for c in chans]):
        out += trk.update(row[:A] if A > 1 else float(row[0]), row[A:] if standstill else ())
    return track, out + trk.finish(), trk


def assert_same(track, out):
    assert [k for k, _ in out] == list(range(len(track)))
    est = [e for _, e in out]
    for name in FIELDS:
        np.testing.assert_array_equal([getattr(e, name) for e in est], getattr(track, name))
    for name in ("has_signal", "standstill"):
        np.testing.assert_array_equal([getattr(e, name) for e in est], track.extras[name])
    for name in est[0].extras:
        want = getattr(track, name) if name in ("speed_lo", "speed_hi") else track.extras[name]
        np.testing.assert_array_equal([e.extras[name] for e in est], want, err_msg=name)


def test_the_lagged_tracker_is_the_batch_fixed_lag_estimate_with_its_stops():
    rec = simulate("stop_and_go", seed=1, duration=40)
    params = {"omega_min": 2, "omega_max": 30, "smooth": "lag", "lag": 2.0, "n_grid": 60}
    track, out, trk = stream(rec, params, radius=0.2)
    assert track.extras["standstill"].any() and (track.omega > 0).any()
    assert_same(track, out)
    est = [e for _, e in out]
    assert {"speed_lo", "speed_hi", "amp1", "omega_mode", "rms"} <= set(est[0].extras)
    # the stops zero omega and speed, not what the tracker would say were it moving
    still = track.extras["standstill"] == 1
    assert np.any(track.extras["omega_mode"][still] > 0)
    assert trk.max_delay == pytest.approx(2 * trk.B * trk.dt - trk.dt + trk.D * trk.dt)


@pytest.mark.parametrize("lag", [2.0, 0.4])  # evidence mid-frame; end-referred (blocks of lag)
def test_the_posterior_rows_are_the_batch_smoothers(lag):
    """``posterior=True``: each Estimate carries its sample's smoothed posterior row, the row of
    ``grid.estimate(..., smooth="lag", return_posterior=True)`` (float32, bit for bit), with
    the stops and a gap; without it the estimates carry none."""
    rec = simulate("stop_and_go", seed=1, duration=20)  # a stop 16.3-19.5 s
    ay = rec["ay"].copy()
    ay[300:340] = np.nan
    rec = Recording(rec.t, {"ax": rec["ax"], "ay": ay, "az": rec["az"]})
    params = {"omega_min": 2, "omega_max": 30, "smooth": "lag", "lag": lag, "n_grid": 30}
    track, out, trk = stream(rec, params, radius=0.2, posterior=True)
    assert_same(track, out)  # every extra, "posterior" with them
    post = np.array([e.extras["posterior"] for _, e in out])
    assert post.dtype == np.float32 and post.shape == (len(rec), trk.N)
    np.testing.assert_array_equal(post, track.extras["posterior"])
    assert track.extras["standstill"].any()
    # the signal part: its mass is the line's probability
    np.testing.assert_allclose(post.sum(axis=1), 1.0 - track.extras["p_null"], atol=1e-5)
    cfg = grid.config_for(rec, params=params)
    plain = LaggedTracker(cfg)
    got = [e for a in ay[:400] for e in plain.update(float(a))]
    assert got and "posterior" not in got[0][1].extras
    with pytest.raises(KeyError):
        got[0][1].extras["posterior"]


def test_each_estimate_comes_within_the_lag_bounds():
    """An estimate of sample k comes when the input reaches k + lag .. 2 lag (the smoothing
    block), and never before the data it uses."""
    rec = simulate("cart", seed=2, duration=12)
    params = {"smooth": "lag", "lag": 2.0, "n_grid": 40}
    cfg = grid.config_for(rec, params=params)
    trk = LaggedTracker(cfg, level=start_level(rec["ay"], cfg.tracker.model.dt))
    dt = cfg.tracker.model.dt
    waits = []
    for g, a in enumerate(rec["ay"]):
        waits += [g - k for k, _ in trk.update(float(a))]
    assert max(waits) * dt == pytest.approx(trk.max_delay)  # reached: the first of a block
    assert min(waits) * dt >= 2.0 - 1e-9  # the lag the user asked for, at least
    assert max(waits) * dt <= 4.0  # 2 lag at most (blocks of lag - W/2, evidence W/2 late)


@pytest.mark.parametrize("params", [
    {"smooth": "lag", "lag": 0.4, "n_grid": 40},  # shorter than half a frame: end-referred
    {"smooth": "lag", "lag": 2.5, "n_grid": 40, "comb_axes": "all", "point": "mean"},
    {"smooth": "lag", "lag": 2.0, "n_grid": 40, "comb_weight": 0},
])
def test_other_settings_and_gappy_input_give_the_batch_numbers(params):
    rec = simulate("random", seed=7, duration=14)
    ch = {c: rec[c].copy() for c in ("ax", "ay", "az")}
    rng = np.random.default_rng(0)
    for x in ch.values():
        x[rng.random(x.size) < 0.03] = np.nan
        x[200:260] = np.nan
    track, out, _ = stream(Recording(rec.t, ch), params)
    assert_same(track, out)


def test_a_recording_shorter_than_one_comb_frame():
    rec = simulate("cart", seed=3, duration=2)
    track, out, _ = stream(rec, {"smooth": "lag", "lag": 2.0, "n_grid": 40})
    assert_same(track, out)


def test_emissions_of_a_step_are_the_batch_runs():
    import vibrospeed.estimators.grid.filter as filt

    rec = simulate("cart", seed=4, duration=3)
    config, y, _, _ = grid._prepare(rec, "y", {"n_grid": 30})
    tr = config.tracker
    res = filt.run(tr, y, return_grid_loglik=True)
    st, row = filt.init(tr), np.empty(tr.n_grid + 1)
    for k in range(0, y.size, 37):
        st = filt.run(tr, y[:k], return_grid_loglik=False).final if k else filt.init(tr)
        filt.step(tr, st, float(y[k]), emissions=row)
        np.testing.assert_array_equal(row.astype(np.float32), res.grid_loglik[k])
    with pytest.raises(ValueError, match="emissions: a float64 array of 31"):
        filt.step(tr, st, 0.0, emissions=np.empty(5))


def test_refused_configs():
    rec = simulate("cart", seed=1, duration=2)
    with pytest.raises(ParameterError, match="smooth must be 'lag'"):
        LaggedTracker(grid.config_for(rec, params={"smooth": "none"}))
    with pytest.raises(ParameterError, match="needs the whole log"):
        LaggedTracker(grid.config_for(rec, params={"smooth": "lag", "fit": "r"}))


@pytest.mark.parametrize("lag", [0.0, 0.3, 1.0, 2.0, 3.3])
def test_lag_stream_is_the_batch_lagged_detector(lag):
    x = simulate("stop_and_go", seed=2, duration=60)["ay"].copy()
    x[1000:1030] = np.nan
    x[2600:2900] = np.nan
    dt, band = 0.01, (15.0, 300.0)  # a car's band: the body-motion level in use
    want = ss.standstill(x, dt, band, causal=True, lag=lag)
    st = sst.LagStream(dt, band, lag)
    got = []
    for i, v in enumerate(x):
        new = st.push(float(v))
        got += new
        # a decision never waits longer than the lag
        assert len(got) >= i + 1 - int(np.floor(lag / dt + 1e-9))
        assert len(st._flags) <= 2 + int(lag / ss.HOP_S) and len(st._final) <= 2
    got += st.finish()
    assert 0.03 < want.mean() < 0.5
    np.testing.assert_array_equal(got, want)


def test_a_tracker_pickled_mid_stream_continues_with_the_batch_numbers():
    """A device that saves the tracker (pickle) and loads it after a restart gets the batch
    numbers for the rest of the recording: three comb axes, the stop detector, a radius, the
    mean."""
    rec = simulate("stop_and_go", seed=3, duration=3.5)
    params = {"smooth": "lag", "lag": 1.8, "n_grid": 20, "comb_axes": "all", "point": "mean"}
    track = grid.estimate(rec, params=params, wheel_radius=0.2)
    cfg = grid.config_for(rec, params=params)
    dt = cfg.tracker.model.dt
    trk = LaggedTracker(cfg, level=[start_level(rec[c], dt) for c in cfg.comb_axes],
                        standstill=3, wheel_radius=0.2)
    rows = np.column_stack([rec[c] for c in cfg.comb_axes])
    half = len(rows) // 2
    out = [e for row in rows[:half] for e in trk.update(row)]
    trk = pickle.loads(pickle.dumps(trk))
    out += [e for row in rows[half:] for e in trk.update(row)] + trk.finish()
    assert (track.extras["standstill"] == 0).all() and np.isfinite(track.speed).all()
    assert_same(track, out)
    k, est = pickle.loads(pickle.dumps(out[half]))  # an Estimate with its extras, too
    assert k == half and est.p_null == track.extras["p_null"][half]


def test_numbers_ints_numpy_scalars_and_one_item_lists_are_the_same_sample():
    """Integer counts (a raw int16 accelerometer) and numpy scalars give the numbers of the
    same values as floats."""
    rec = simulate("cart", seed=5, duration=4)
    counts = np.round(rec["ay"] * 1000).astype(np.int16)
    cfg = grid.config_for(rec, params={"smooth": "lag", "lag": 1.0, "n_grid": 30})

    def run(samples):
        trk = LaggedTracker(cfg, level=0)
        out = [e for x in samples for e in trk.update(x)] + trk.finish()
        return np.array([(e.omega, e.omega_std, e.extras["p_null"]) for _, e in out])

    want = run([float(c) for c in counts])
    assert np.isfinite(want).all()
    for kind in ([int(c) for c in counts], list(counts), [np.float64(c) for c in counts],
                 [[c] for c in counts], [np.array(c) for c in counts]):
        np.testing.assert_array_equal(run(kind), want)


def test_refused_input_names_the_fault_and_leaves_no_trace():
    """Bad updates and bad trackers get one line each; the refused updates change nothing (the
    stream then gives the batch numbers); an update after finish() is refused, a second
    finish() returns nothing."""
    from vibrospeed.estimators import ekf

    rec = simulate("cart", seed=6, duration=4)
    params = {"smooth": "lag", "lag": 1.6, "n_grid": 30}
    track = grid.estimate(rec, params=params)
    cfg = grid.config_for(rec, params=params)
    dt = cfg.tracker.model.dt
    with pytest.raises(ParameterError, match="grid method's Config.*ekf.Config"):
        LaggedTracker(ekf.Config())
    cfg3 = grid.config_for(rec, params={**params, "comb_axes": "all"})
    with pytest.raises(ParameterError, match="level has 2 values.*3 comb axes"):
        LaggedTracker(cfg3, level=[0.0, 0.0])
    with pytest.raises(ValueError, match="expected 3 sample.*shape \\(\\)"):
        LaggedTracker(cfg3).update(0.1)
    trk = LaggedTracker(cfg, level=start_level(rec["ay"], dt), standstill=3,
                        wheel_radius=rec.wheel_radius)
    out = []
    for g, (a, x, z) in enumerate(zip(rec["ay"], rec["ax"], rec["az"], strict=True)):
        if g % 97 == 5:
            with pytest.raises(ValueError, match="expected 2 sample\\(s\\) in others, got 1"):
                trk.update(a, (x,))
            with pytest.raises(ValueError, match="expected 1 sample.*shape \\(2,\\)"):
                trk.update([a, x], (z,))
            with pytest.raises(ValueError, match="shape \\(1, 1\\)"):
                trk.update([[a]], (x, z))
        out += trk.update(a, (x, z))
    out += trk.finish()
    assert_same(track, out)
    assert trk.finish() == []
    with pytest.raises(RuntimeError, match="update\\(\\) after finish\\(\\)"):
        trk.update(0.0, (0.0, 0.0))
    with pytest.raises(ValueError, match="others given but standstill=0"):
        LaggedTracker(cfg).update(0.1, (0.2, 0.3))


def test_buffers_stay_bounded_on_a_long_stream():
    """What the tracker holds depends on the lag and the comb frame, not on how long it runs:
    two smoothing blocks of filter rows, a frame's evidence, stop decisions up to the delay."""
    rec = simulate("stop_and_go", seed=2, duration=20)
    cfg = grid.config_for(rec, params={"smooth": "lag", "lag": 1.6, "n_grid": 30})
    trk = LaggedTracker(cfg, standstill=3)
    wait = round(trk.max_delay / trk.dt)
    L, H = cfg.frame_len, cfg.hop_len
    most = np.zeros(4, int)
    for a, x, z in zip(rec["ay"], rec["ax"], rec["az"], strict=True):
        trk.update(a, (x, z))
        sizes = (len(trk._rows), len(trk._smoothed), len(trk._ev),
                 max(len(d) for d in trk._decided))
        most = np.maximum(most, sizes)
    assert trk._g == len(rec) and wait < 200  # many times the longest wait
    assert most[0] <= 2 * trk.B and most[1] <= 2 * trk.B
    assert most[2] <= L // H + 1 and most[3] <= wait + 1
