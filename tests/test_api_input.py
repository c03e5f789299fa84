"""Bad input through the Python API: a wheel radius that is not a finite number > 0 m is a
one-line :class:`~vibrospeed.errors.ParameterError` naming the value, raised before anything is
read or written (the estimate CSV used to be written and its JSON sidecar then fail on nan);
an estimator's ``Config`` refuses values that would make its output NaN or meaningless with a
one-line ParameterError naming the parameter, while the valid edges still run."""

import importlib
import json
import math

import numpy as np
import pytest

from vibrospeed import io, sim
from vibrospeed.batch import EstimateOptions, estimate_recording
from vibrospeed.errors import InputError, ParameterError
from vibrospeed.estimators import METHODS
from vibrospeed.estimators.grid import stream
from vibrospeed.io.track import check_wheel_radius
from vibrospeed.types import Track

BAD = [math.nan, math.inf, -math.inf, 0.0, -1.0]


@pytest.fixture(scope="module")
def cart(tmp_path_factory):
    path = tmp_path_factory.mktemp("api_input") / "cart.csv"
    io.write(sim.simulate("cart", seed=1, duration=10), path)
    return path


def _message(value) -> str:
    return f"wheel_radius must be a finite number > 0 m, got {value:g}"


@pytest.mark.parametrize("value", BAD)
@pytest.mark.parametrize("method", list(METHODS))
def test_every_method_refuses_the_radius_before_reading_or_writing(tmp_path, method, value):
    missing = tmp_path / "not_there.csv"  # never read: the radius is refused first
    with pytest.raises(ParameterError) as exc:
        estimate_recording(missing, tmp_path / "est.csv",
                           EstimateOptions(method=method, wheel_radius=value))
    assert str(exc.value) == _message(value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", BAD)
def test_the_streamed_grid_estimate_refuses_the_radius_before_writing(cart, tmp_path, value):
    with pytest.raises(ParameterError) as exc:
        stream.estimate_file(cart, tmp_path / "est.csv", params={}, wheel_radius=value)
    assert str(exc.value) == _message(value)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("value", BAD)
def test_write_track_refuses_a_track_with_such_a_radius_and_writes_nothing(tmp_path, value):
    t = np.arange(5) * 0.01
    track = Track.from_omega(t, np.full(5, 10.0), np.ones(5), wheel_radius=0.3, method="ekf")
    track.wheel_radius = value  # from_omega refuses it (below); a Track changed afterwards
    out = tmp_path / "est.csv"
    with pytest.raises(ParameterError) as exc:
        io.write_track(track, out)
    assert str(exc.value) == f"{out}: {_message(value)}"
    assert list(tmp_path.iterdir()) == []


def test_write_track_makes_the_sidecar_before_the_csv(tmp_path):
    t = np.arange(5) * 0.01
    track = Track.from_omega(t, np.full(5, 10.0), np.ones(5), wheel_radius=0.3)
    track.level = math.nan  # params and meta are made JSON-safe; the level is not
    out = tmp_path / "est.csv"
    with pytest.raises(ParameterError, match="est.csv.json: cannot write the sidecar"):
        io.write_track(track, out)
    assert list(tmp_path.iterdir()) == []  # no CSV without its sidecar


def test_a_radius_that_is_not_a_number_is_named_as_given():
    with pytest.raises(ParameterError) as exc:
        EstimateOptions(wheel_radius="abc")
    assert str(exc.value) == "wheel_radius must be a number in m, got 'abc'"


def test_good_radii_pass_and_reach_the_estimate(cart, tmp_path):
    assert check_wheel_radius(None) is None
    for value, expect in ((0.31, 0.31), (np.float32(0.5), 0.5), ("0.08", 0.08), (2, 2.0)):
        assert check_wheel_radius(value) == expect
    assert check_wheel_radius(5e-324) == 5e-324  # the smallest float > 0: a radius all the same
    out = tmp_path / "est.csv"
    est = estimate_recording(cart, out, EstimateOptions(method="ekf", wheel_radius=0.2,
                                                        params={"omega_max": "30"}))
    side = json.loads((tmp_path / "est.csv.json").read_text())
    assert side["wheel_radius"] == 0.2
    track = io.read_track(out)
    np.testing.assert_allclose(track.speed, 0.2 * track.omega)
    np.testing.assert_allclose(track.omega, est.track.omega, rtol=1e-9)


@pytest.mark.parametrize("method", ["grid", "aided", "fuse"])
def test_text_parameter_that_is_not_a_number_is_a_parameter_error(method):
    """``params={"omega_max": "abc"}`` names the parameter (it used to be a bare ValueError
    from the default walk's ``float(omega_max)``); text that is a number is read as one."""
    rec = sim.simulate("cart", seed=1, duration=5)
    with pytest.raises(ParameterError, match="omega_max.*'abc'"):
        importlib.import_module(METHODS[method][0]).estimate(
            rec, wheel_radius=0.1, params={"omega_max": "abc"})


@pytest.mark.parametrize("method", ["grid", "rbpmf", "ekf", "shs"])
@pytest.mark.parametrize("value", [math.nan, math.inf, -1.0])
def test_an_estimator_refuses_a_radius_it_cannot_convert_with(method, value):
    """The estimators' own ``estimate(wheel_radius=...)`` (not only the batch entry point): a
    Track is never built with NaN speeds from a bad radius; None and 0 mean "not known"."""
    rec = sim.simulate("cart", seed=1, duration=5)
    est = importlib.import_module(METHODS[method][0]).estimate
    with pytest.raises(ParameterError, match="wheel_radius must be a finite number > 0 m"):
        est(rec, wheel_radius=value)


def test_a_known_radius_converts_and_zero_means_unknown():
    t = np.arange(5) * 0.1
    tr = Track.from_omega(t, np.full(5, 10.0), np.ones(5), wheel_radius=0.3)
    assert np.allclose(tr.speed, 3.0) and np.allclose(tr.speed_std, 0.3)
    unknown = Track.from_omega(t, np.full(5, 10.0), wheel_radius=0)
    assert np.isnan(unknown.speed).all() and unknown.wheel_radius is None
    back = Track.from_speed(t, np.full(5, 3.0), wheel_radius=0.3)
    assert np.allclose(back.omega, 10.0)


def _refused(make, name):
    """``make()`` raises a one-line ParameterError that names ``name``."""
    with pytest.raises(ParameterError) as exc:
        make()
    msg = str(exc.value)
    assert name in msg and "\n" not in msg, msg


@pytest.mark.parametrize("kw, name", [
    ({"omega0": math.nan}, "omega0"), ({"omega0": math.inf}, "omega0"),
    ({"omega0": -1.0}, "omega0"), ({"amp0": math.nan}, "amp0"), ({"amp0": math.inf}, "amp0"),
    ({"p0_omega": math.inf}, "p0_omega"), ({"p0_omega": math.nan}, "p0_omega"),
    ({"omega_min": math.nan}, "omega_min"), ({"omega_min": -1.0}, "omega_min"),
    ({"omega_min": math.inf}, "omega_min"), ({"omega_max": math.nan}, "omega_max"),
    ({"omega_min": 50.0, "omega_max": 20.0}, "omega_max"),
    ({"omega_min": 20.0, "omega_max": 20.0}, "omega_max"),
])
def test_ekf_config_refuses_what_would_give_nan_or_a_pinned_omega(kw, name):
    """These used to pass: NaN omega0 / amp0 or an infinite p0_omega made every output NaN, a
    NaN or negative omega_min clipped nothing, omega_min >= omega_max pinned omega there."""
    from vibrospeed.estimators import ekf

    _refused(lambda: ekf.Config(**kw), name)
    rec = sim.simulate("cart", seed=1, duration=2)
    _refused(lambda: ekf.estimate(rec, params=kw, wheel_radius=0.1), name)


def test_ekf_config_keeps_the_valid_edges():
    from vibrospeed.estimators import ekf

    y = np.sin(10.0 * np.arange(300) * 0.01)
    for kw in ({"omega0": 0.0}, {"omega_min": 0.0, "omega_max": math.inf}, {"amp0": -3.0},
               {"omega_min": 2.0, "omega_max": 2.5}, {"omega_max": None}):
        res = ekf.run(ekf.Config(**kw), y)
        assert np.isfinite(res.omega).all() and np.isfinite(res.omega_std).all(), kw


@pytest.mark.parametrize("kw, name", [
    ({"n_particles": math.nan}, "n_particles"), ({"n_particles": math.inf}, "n_particles"),
    ({"n_particles": 50.0}, "n_particles"), ({"omega_max": math.inf}, "omega_max"),
    ({"omega0": math.nan}, "omega0"), ({"omega0": -5.0}, "omega0"),
    ({"omega0_std": 0.0}, "omega0_std"), ({"omega0_std": -1.0}, "omega0_std"),
    ({"omega0_std": math.nan}, "omega0_std"), ({"ess_threshold": math.nan}, "ess_threshold"),
    ({"seed": -1}, "seed"), ({"seed": 1.5}, "seed"), ({"seed": 1.0}, "seed"),
    ({"rms_tau": math.nan}, "rms_tau"), ({"rms_tau": -1.0}, "rms_tau"),
    ({"signal_rms": 0.0}, "signal_rms"), ({"signal_rms": -1.0}, "signal_rms"),
    ({"signal_rms": math.nan}, "signal_rms"),
])
def test_rbpf_config_refuses_bad_values_with_a_parameter_error(kw, name):
    """These used to pass (a NaN omega0 gave NaN output, omega_max inf drew infinite
    particles, a negative signal_rms flipped the signal) or fail inside numpy (ValueError,
    TypeError, OverflowError for a NaN, float or negative count or seed)."""
    from vibrospeed.estimators import rbpf

    _refused(lambda: rbpf.Config(**{"n_particles": 20, **kw}), name)


def test_rbpf_config_keeps_the_valid_edges():
    from vibrospeed.estimators import rbpf

    y = np.sin(20.0 * np.arange(200) * 0.01)
    for kw in ({"seed": np.int64(3)}, {"n_particles": np.int64(20)}, {"omega0": 0.0},
               {"omega_min": 0.0, "omega_max": 0.0}, {"ess_threshold": 2.0}):
        res = rbpf.run(rbpf.Config(**{"n_particles": 20, **kw}), y)
        assert np.isfinite(res.omega).all() and np.isfinite(res.omega_std).all(), kw
    # text parameters are typed by the field: "-p seed=2" is the integer 2
    from vibrospeed.config import config_from_params

    assert config_from_params(rbpf.Config, {"seed": "2", "n_particles": "20"}).seed == 2


@pytest.mark.parametrize("kw, name", [
    ({"batch": math.nan}, "batch"), ({"batch": math.inf}, "batch"), ({"batch": 200.0}, "batch"),
    ({"n_fft": math.nan}, "n_fft"), ({"n_fft": 4096.5}, "n_fft"),
    ({"n_harmonics": math.nan}, "n_harmonics"), ({"n_harmonics": 2.5}, "n_harmonics"),
    ({"points_per_octave": 0}, "points_per_octave"),
    ({"points_per_octave": -1}, "points_per_octave"),
    ({"points_per_octave": math.nan}, "points_per_octave"), ({"dt": math.inf}, "dt"),
])
def test_shs_config_refuses_counts_that_are_not_integers(kw, name):
    """These used to pass the Config and fail in run (numpy's ValueError / TypeError) or, for
    points_per_octave <= 0, search one candidate or none; the estimate's params the same."""
    from vibrospeed.estimators import shs

    _refused(lambda: shs.Config(**kw), name)
    if name != "dt":  # estimate takes dt from the data
        rec = sim.simulate("car", seed=1, duration=3)
        _refused(lambda: shs.estimate(rec, params=kw), name)


def test_shs_config_counts_as_text_and_numpy_integers():
    from vibrospeed.config import config_from_params
    from vibrospeed.estimators import shs

    cfg = config_from_params(shs.Config, {"batch": "100", "n_harmonics": "3",
                                          "points_per_octave": "48"})
    assert (cfg.batch, cfg.n_harmonics, cfg.points_per_octave) == (100, 3, 48)
    y = np.sin(30.0 * np.arange(400) * 0.01)
    ref = shs.run(cfg, y).omega
    got = shs.run(shs.Config(batch=np.int64(100), n_harmonics=np.int32(3),
                             points_per_octave=np.int64(48)), y).omega
    assert np.array_equal(ref, got) and np.all(np.abs(ref - 30.0) < 1.0)


@pytest.mark.parametrize("kw, name", [
    ({"r": math.inf}, "r"), ({"L1": math.inf}, "L1"), ({"vy0": math.nan}, "vy0"),
    ({"vy0": math.inf}, "vy0"), ({"slip_sd": math.inf}, "slip_sd"),
    ({"acc_bias_sd": math.inf}, "acc_bias_sd"), ({"gyro_bias_sd": math.inf}, "gyro_bias_sd"),
    ({"slip_window": math.inf}, "slip_window"), ({"window": math.inf}, "window"),
    ({"window_d": math.inf}, "window_d"), ({"kappa": math.inf}, "kappa"),
    ({"reset_eps_x": math.nan}, "reset_eps_x"), ({"reset_eps_x": -1.0}, "reset_eps_x"),
    ({"reset_eps_y": math.nan}, "reset_eps_y"), ({"reset_eps_y": -1.0}, "reset_eps_y"),
    ({"alpha": math.nan}, "alpha"), ({"beta": math.inf}, "beta"),
    ({"reset_hold": math.nan}, "reset_hold"), ({"backtrack": math.inf}, "backtrack"),
    ({"N": math.nan}, "N"), ({"N": math.inf}, "N"), ({"N": 1.0}, "N"),
])
def test_algebraic_config_refuses_values_that_give_nan_or_fail_later(kw, name):
    """These used to pass (inf r or vy0: Vx NaN; NaN vy0: Vy NaN; inf slip_sd: Vx std inf) or
    fail in int() / numpy (ValueError, OverflowError, TypeError) or name another parameter."""
    from vibrospeed.estimators import algebraic

    _refused(lambda: algebraic.Config(**kw), name)


def test_algebraic_config_keeps_inf_thresholds_and_whole_float_counts():
    """inf thresholds mean "never" and whole-number floats count as counts, as before."""
    from vibrospeed.estimators import algebraic

    t = np.arange(300) * 0.01
    Z = np.stack([np.zeros_like(t), np.zeros_like(t), np.zeros_like(t), np.full_like(t, 40.0)],
                 axis=1)
    for kw in ({"eps1": math.inf}, {"eps2": math.inf}, {"slip_tol": math.inf},
               {"max_int": math.inf}, {"eps_k": math.inf}, {"alpha": 20.0},
               {"reset_eps_x": 0.0}, {"N": np.int64(2), "window": 0.2, "window_d": 0.3}):
        res = algebraic.run(algebraic.Config(**kw), Z)
        assert np.allclose(res.vx[50:], 0.31 * 40.0) and np.isfinite(res.vx_std).all(), kw


@pytest.mark.parametrize("kw, name", [
    *[({f: math.inf}, f) for f in ("q_speed", "q_accel", "q_offset", "q_gps", "r_gps",
                                   "r_gps_slope", "r_gps_sq", "gain", "p0_speed", "p0_accel",
                                   "p0_offset", "acc_psd", "r_acc_ins", "q_drift")],
    ({"gps_pade": math.nan}, "gps_pade"), ({"gps_pade": math.inf}, "gps_pade"),
    ({"gps_pade": 2.5}, "gps_pade"), ({"pitch_poly": (math.nan, 0.28, 0.02)}, "pitch_poly"),
    ({"e_max": math.nan}, "e_max"),
])
def test_gps_riss_config_refuses_infinite_noises_and_a_bad_pade_order(kw, name):
    """These used to pass: an infinite variance, intensity or gain made the speed and its std
    NaN; a NaN or inf gps_pade failed in int(), 2.5 was read as 2."""
    from vibrospeed.estimators import fuse, gps_riss

    _refused(lambda: gps_riss.Config(**kw), name)
    if name == "gps_pade":  # the receiver fields are fuse's too
        _refused(lambda: fuse.Config(**kw), name)


def test_gps_riss_keeps_e_max_inf_and_refuses_a_time_that_is_not_finite():
    from vibrospeed.estimators import gps_riss

    n = 200
    t = np.arange(n) * 0.01
    gps = np.full(n, np.nan)
    gps[::10] = 10.0
    s = gps_riss.Sample(t, np.zeros(n), gps, np.full(n, 9.0))
    for cfg in (gps_riss.Config(e_max=math.inf), gps_riss.Config(gps_pade=1, gps_delay=0.2)):
        res = gps_riss.run(cfg, s)
        assert np.allclose(res.speed, 10.0, atol=0.05) and np.isfinite(res.speed_std).all()
    bad = t.copy()
    bad[57] = np.nan
    with pytest.raises(InputError, match=r"t must be finite times in s, got nan at sample 57"):
        gps_riss.run(gps_riss.Config(), s._replace(t=bad))  # an IndexError before
    st = gps_riss.init(gps_riss.Config(), 10.0)
    st, _ = gps_riss.step(gps_riss.Config(), st, gps_riss.Sample(0.0, 0.0, 10.0, 9.0))
    with pytest.raises(InputError, match=r"t must be a finite time in s, got nan$"):
        gps_riss.step(gps_riss.Config(), st, gps_riss.Sample(math.nan, 0.0, math.nan, 9.0))
    with pytest.raises(InputError, match="time goes backwards"):
        gps_riss.step(gps_riss.Config(), st, gps_riss.Sample(-1.0, 0.0, math.nan, 9.0))


@pytest.mark.parametrize("method", ["ekf", "rbpf", "shs"])
def test_run_refuses_samples_that_are_not_one_dimensional(method):
    """A column vector (n, 1) or a bare number used to fail inside numba (TypingError), float()
    (TypeError) or a numpy broadcast (ValueError); float32 arrays and lists run as float64."""
    from vibrospeed.estimators import ekf, rbpf, shs

    mod, cfg = {"ekf": (ekf, ekf.Config()), "rbpf": (rbpf, rbpf.Config(n_particles=20)),
                "shs": (shs, shs.Config(batch=100))}[method]
    y = np.sin(30.0 * np.arange(300) * 0.01)
    # a bare number is one sample to the EKF (as before); the others failed on it
    for bad in (y[:, None], y[None, :]) + (() if method == "ekf" else (np.float64(0.5),)):
        with pytest.raises(InputError, match=rf"{method}.run: y must be one-dimensional"):
            mod.run(cfg, bad)
    ref = mod.run(cfg, y).omega
    for same in (y.tolist(), y.astype(np.float32).astype(np.float64)):
        assert np.array_equal(mod.run(cfg, same).omega, mod.run(cfg, np.asarray(same)).omega)
    got = mod.run(cfg, y.astype(np.float32)).omega  # rounded to float32, then float64
    assert np.allclose(got, ref, atol=1e-3, equal_nan=True)


@pytest.mark.parametrize("offset0", [math.nan, math.inf, -math.inf])
def test_gps_riss_init_refuses_an_offset_guess_that_is_not_finite(offset0):
    """It used to be taken: every speed after it was NaN (offset_mode "state") or all but the
    first ("integrator"). A finite guess still starts the filter there."""
    from vibrospeed.estimators import gps_riss

    _refused(lambda: gps_riss.init(gps_riss.Config(), 10.0, offset0=offset0), "offset0")
    st = gps_riss.init(gps_riss.Config(), 10.0, offset0=0.2)
    assert st.offset == 0.2 and st.speed == 10.0


def test_fuse_step_reads_none_as_run_does():
    """``gps_sats=None`` (or another input None) raised a TypeError from float() in step,
    while run reads a missing input as "none / unknown": the numbers now equal run's and
    those of step with NaN, bitwise."""
    from vibrospeed.estimators import fuse

    cfg = fuse.Config()
    t = np.arange(0.0, 2.0, 0.04)
    g = np.where(np.arange(t.size) % 2 == 0, 10.0 + 0.1 * t, np.nan)
    a = np.full(t.size, 0.1)
    st0 = fuse.init(cfg, 10.0)
    _, ref = fuse.run(cfg, fuse.Sample(t, accel=a, gps_speed=g, gps_sats=None), state=st0)
    st_none = st_nan = st0
    for k in range(t.size):
        st_none, e_none = fuse.step(cfg, st_none, fuse.Sample(t[k], a[k], g[k], gps_sats=None,
                                                              omega=None, omega_std=None))
        st_nan, e_nan = fuse.step(cfg, st_nan, fuse.Sample(t[k], a[k], g[k]))
        assert e_none.speed == e_nan.speed == ref.speed[k]
        assert e_none.speed_std == ref.speed_std[k]
    np.testing.assert_array_equal(st_none.P, st_nan.P)
