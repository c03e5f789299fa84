"""Estimator parameters that made the output NaN, or failed deep inside ``run`` with numpy's or
Python's own error, are one-line :class:`~vibrospeed.errors.ParameterError` naming the
parameter and the value when the ``Config`` is built; the valid edges (0, inf where it means
"never" or "no limit") still run and give finite numbers."""

import math
import re

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.models.harmonic import HarmonicModel

nan, inf = math.nan, math.inf


def _refused(make, name, value):
    """``make()`` raises a one-line ParameterError naming ``name`` and ``value``."""
    with pytest.raises(ParameterError) as exc:
        make()
    msg = str(exc.value)
    assert name in msg and str(value) in msg and "\n" not in msg, msg


@pytest.mark.parametrize("kw", [
    {"q_omega": inf}, {"q_amp": inf}, {"r": inf}, {"p0_amp": inf}, {"dt": inf},
    {"q_omega": nan}, {"dt": nan}, {"M": nan}, {"M": inf}, {"M": 2.0}, {"M": np.float64(2.0)},
    {"M": True},
])
def test_harmonic_model_refuses_infinite_noise_period_or_prior(kw):
    """Each of these made every EKF / aided output NaN (or int() failed on M; a whole float M
    such as 2.0 passed and then failed inside ``ekf.run`` / ``rbpf.run`` with numpy's
    TypeError)."""
    (name, value), = kw.items()
    _refused(lambda: HarmonicModel(**kw), name, value)


def test_harmonic_model_keeps_the_valid_edges():
    from vibrospeed.estimators import ekf

    y = np.sin(10.0 * np.arange(300) * 0.01)
    for kw in ({"q_omega": 0.0}, {"M": np.int64(2)}, {"q_amp": 1e-12, "r": 1e3}):
        res = ekf.run(ekf.Config(model=HarmonicModel(**kw)), y)
        assert np.isfinite(res.omega).all() and np.isfinite(res.omega_std).all(), kw
    # the probe model some estimators build before the recording's period is known
    assert HarmonicModel(dt=1.0).q_omega_step == 4.0
    # "-p M=2" (or M=2.0) on the command line is read as the int 2 by the field's type
    from vibrospeed.config import config_from_params

    for text in ("2", "2.0"):
        m = config_from_params(HarmonicModel, {"M": text})
        assert type(m.M) is int and m.M == 2 and m.n_lin == 4


@pytest.mark.parametrize("kw", [
    {"omega0": nan}, {"omega0": inf}, {"omega_max": inf}, {"off_rate": inf}, {"n_grid": nan},
    {"n_grid": inf}, {"n_grid": 40.0}, {"rms_tau": nan}, {"rms_tau": -1.0}, {"rms_tau": inf},
    {"signal_rms": nan}, {"signal_rms": -1.0}, {"signal_rms": 0.0},
])
def test_grid_config_refuses_what_gave_nan_or_failed_in_int(kw):
    """A NaN / infinite omega0, an infinite omega_max or off_rate made every rbpmf output
    NaN; a NaN / infinite n_grid failed in int() (ValueError / OverflowError), a float one in
    numpy's linspace (TypeError); a NaN or negative rms_tau / signal_rms was taken (NaN or
    sign-flipped scaled signal)."""
    from vibrospeed.estimators.grid.config import Config

    (name, value), = kw.items()
    _refused(lambda: Config(**kw), name, value)


def test_grid_config_keeps_the_valid_edges():
    """A jump rate of inf (every step re-acquires), omega0 at the grid's ends, a numpy count, and
    text parameters as the CLI passes them."""
    from vibrospeed.config import config_from_params
    from vibrospeed.estimators import rbpmf
    from vibrospeed.estimators.grid.config import Config

    y = np.sin(20.0 * np.arange(300) * 0.01)
    for kw in ({"omega0": 0.0}, {"omega0": 120.0}, {"n_grid": np.int64(40)},
               {"jump_rate": inf}, {"off_rate": 1e6}, {"omega_min": 0.0}):
        res = rbpmf.run(Config(**{"n_grid": 40, **kw}), y)
        assert np.isfinite(res.omega).all() and np.isfinite(res.omega_std).all(), kw
    with pytest.raises(ParameterError, match="^omega0 must be finite rad/s"):
        config_from_params(Config, {"omega0": "nan"})
    assert config_from_params(Config, {"n_grid": "40"}).n_grid == 40


def test_grid_on_rate_inf_is_an_immediate_return_to_the_line():
    """``on_rate = inf`` means every "no line" sample returns to the line at the next step
    (``p_on = 1``): its stationary share, the first sample's "no line" mass, is 0, which
    ``log(0)`` computed with "divide by zero" warnings. It runs without a warning and gives the
    numbers of a finite rate already past ``p_on = 1`` in float64 (1e300/s: the share 5e-302
    leaves ``1 - p0`` at 1 and its mass is gone by the first update)."""
    import warnings

    from vibrospeed.estimators import rbpmf
    from vibrospeed.estimators.grid.config import Config

    y = np.sin(20.0 * np.arange(300) * 0.01) + 0.3 * np.random.default_rng(0).normal(size=300)
    kw = {"n_grid": 40, "off_rate": 0.05, "scaling": "none"}
    cfg = Config(**kw, on_rate=inf)
    assert cfg.rates()[2] == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        state = rbpmf.init(cfg)
        res = rbpmf.run(cfg, y)
    assert state.log_w_null == -inf and np.exp(state.log_w).sum() == pytest.approx(1.0, abs=1e-12)
    ref = rbpmf.run(Config(**kw, on_rate=1e300), y)
    for name in ("omega", "omega_std", "p_null"):
        np.testing.assert_array_equal(getattr(res, name), getattr(ref, name), err_msg=name)
    assert np.isfinite(res.omega).all() and (res.p_null > 0).all()


@pytest.mark.parametrize("kw", [
    {"amp0": nan}, {"amp0": inf}, {"p0_omega": inf}, {"q_bias": inf}, {"p0_bias": inf},
    {"q_omega_accel": inf}, {"r_ss": inf}, {"omega0": inf}, {"ss_n": nan}, {"ss_n": inf},
    {"mode_n": nan}, {"mode_n": inf}, {"comb_count": nan}, {"comb_count": inf},
    {"ss_window": inf}, {"mode_window": inf}, {"cusum_h": inf}, {"cusum_nu": nan},
])
def test_aided_config_refuses_what_gave_nan_or_failed_in_run(kw):
    """A NaN / infinite amp0, an infinite p0_omega, q_bias, p0_bias or r_ss made the output
    NaN (q_omega_accel = inf: most of it); a NaN or infinite count failed in int(), an
    infinite window, cusum_h or a NaN cusum_nu in run (int() of the hold)."""
    from vibrospeed.estimators import aided

    (name, value), = kw.items()
    _refused(lambda: aided.Config(**kw), name, value)


def test_aided_config_keeps_the_valid_edges():
    """Thresholds of inf (the window test always passes, never acceleration mode, a CUSUM
    drift that never alarms), counts as whole floats, zero noise: finite output, and the
    detectors read as documented."""
    from vibrospeed.estimators import aided

    rng = np.random.default_rng(0)
    y = np.sin(20.0 * np.arange(400) * 0.01) + 0.1 * rng.normal(size=400)
    u = np.where(np.arange(400) % 100 < 50, 1.0, 0.0)
    for kw in ({"ss_mu": inf}, {"mode_mu": inf}, {"cusum_sigma": inf, "standstill": "cusum"},
               {"ss_n": 20.0, "mode_n": 20.0, "comb_count": 3.0}, {"q_bias": 0.0},
               {"q_omega_accel": 0.0}, {"q_omega_accel": None},
               {"cusum_nu": inf, "standstill": "cusum"}):
        res = aided.run(aided.Config(**kw), y, u)
        assert np.isfinite(res.omega).all() and np.isfinite(res.omega_std).all(), kw
        if kw.get("mode_mu") == inf:
            assert not res.accelerating.any()
        if kw.get("cusum_nu") == inf:
            assert not res.standstill.any()
    # whole-float counts are the integer ones
    a = aided.run(aided.Config(ss_n=20.0, mode_n=20.0, comb_count=3.0), y, u)
    b = aided.run(aided.Config(ss_n=20, mode_n=20, comb_count=3), y, u)
    np.testing.assert_array_equal(a.omega, b.omega)


@pytest.mark.parametrize("kw", [
    {"ss_n": nan}, {"ss_n": inf}, {"mode_n": nan}, {"ss_window": inf}, {"mode_window": inf},
    {"aid_hop": inf}, {"q_omega_accel": inf}, {"q_omega_still": inf},
])
def test_aided_grid_config_refuses_what_failed_in_int_or_flattened_the_grid(kw):
    """A NaN / infinite count failed in int() building the config, an infinite window or hop
    in run; an infinite walk flattened the grid posterior on every such sample (omega was the
    grid's centre whatever the data)."""
    from vibrospeed.estimators import aided_grid

    (name, value), = kw.items()
    _refused(lambda: aided_grid.Config(**kw), name, value)


def test_aided_grid_config_keeps_the_valid_edges():
    from vibrospeed.estimators import aided_grid

    rng = np.random.default_rng(0)
    y = np.sin(20.0 * np.arange(300) * 0.01) + 0.1 * rng.normal(size=300)
    u = np.where(np.arange(300) % 100 < 50, 1.0, 0.0)
    a = aided_grid.run(aided_grid.Config(ss_n=20.0, mode_n=20.0), y, u)
    b = aided_grid.run(aided_grid.Config(ss_n=20, mode_n=20), y, u)
    np.testing.assert_array_equal(a.omega, b.omega)
    for kw in ({"q_omega_accel": None}, {"q_omega_still": 0.0}, {"mode_mu": inf},
               {"aid_hop": 0.01, "aiding": "continuous"}):
        res = aided_grid.run(aided_grid.Config(**kw), y, u)
        assert np.isfinite(res.omega).all(), kw


FUSE_FINITE = ("q_speed", "q_accel", "q_offset", "q_gps", "q_radius", "acc_psd", "r_gps",
               "vib_rel", "vib_corr", "vib_gate", "vib_lag", "r_still", "r_still_acc",
               "p0_speed", "p0_accel", "p0_offset", "radius0", "radius_std0")


@pytest.mark.parametrize("name", FUSE_FINITE)
def test_fuse_config_refuses_an_infinite_noise_prior_or_gate(name):
    """Each of these at inf left at most 3 % of the speeds finite (the priors: none)."""
    from vibrospeed.estimators import fuse

    _refused(lambda: fuse.Config(**{name: inf}), name, inf)


def test_fuse_config_keeps_inf_where_it_means_no_limit():
    """``vib_amax`` (the default), ``e_max`` and the holds take inf as "none"; zero noise is
    valid: every speed finite on a GPS drive with an outage."""
    from vibrospeed.estimators import fuse

    t = np.arange(0.0, 20.0, 0.04)
    v = 10.0 + np.sin(t / 3.0)
    g = np.where((t > 8.0) & (t < 12.0), nan, v)
    y = {"t": t, "accel": np.cos(t / 3.0) / 3.0, "gps_speed": g, "gps_sats": np.full(t.size, 9.0)}
    for kw in ({"vib_amax": inf}, {"e_max": inf}, {"gps_hold": inf, "source_hold": inf},
               {"q_speed": 0.0, "q_radius": 0.0, "vib_lag": 0.0}):
        res = fuse.run(fuse.Config(**kw), y)
        assert np.isfinite(res.speed).all() and np.isfinite(res.speed_std).all(), kw


def test_check_state_formats_its_text_only_when_a_shape_is_wrong():
    """``config_says`` with values after it is a format string they complete (``step`` calls
    the check per sample, the text is needed only for the error): not formatted while the
    shapes fit, in the message as the same text given whole; text alone is used as given."""
    from vibrospeed.config import check_state

    class Counted:
        calls = 0

        def __format__(self, spec: str) -> str:
            Counted.calls += 1
            return "2"

    check_state("m", "M = {}", Counted(), x=(np.zeros(4), (4,)), b=(None, None))
    assert Counted.calls == 0
    for args in (("M = {}", Counted()), ("M = 2",)):
        with pytest.raises(ParameterError) as exc:
            check_state("m", *args, x=(np.zeros(6), (4,)), b=(None, None))
        assert str(exc.value) == ("m state: x, b ((6,), None) do not match the config's M = 2 "
                                  "(wanted ((4,), None))")
    assert Counted.calls == 1
    with pytest.raises(ParameterError, match=r"config's \{M\} \(wanted"):  # braces as given
        check_state("m", "{M}", x=(np.zeros(6), (4,)))


def test_aided_step_and_run_refuse_a_state_of_another_config():
    """A state of another M (or other detector windows) ran silently, with numbers from the
    wrong arrays (omega 0.0 from both here); a state of the config itself still gives step ==
    run."""
    from vibrospeed.estimators import aided

    c2 = aided.Config()
    c3 = aided.Config(model=HarmonicModel(M=3, dt=0.01, q_omega=0.5, q_amp=0.004, r=0.0022))
    y = np.sin(20.0 * np.arange(100) * 0.01)
    u = np.zeros(100)
    for cfg, other in ((c2, c3), (c3, c2), (c2, aided.Config(ss_window=0.5)),
                       (c2, aided.Config(mode_n=7))):
        st = aided.init(other)
        with pytest.raises(ParameterError, match="^aided state: .* do not match") as exc:
            aided.step(cfg, st, 0.3, 0.0)
        assert "\n" not in str(exc.value)
        with pytest.raises(ParameterError, match="^aided state: .* do not match"):
            aided.run(cfg, y, u, state=st)
    res = aided.run(c3, y, u, state=aided.init(c3))
    st = aided.init(c3)
    for k in range(y.size):
        st, est = aided.step(c3, st, y[k], u[k])
        assert est.omega == res.omega[k]


def test_aided_grid_step_and_run_refuse_detector_windows_of_another_config():
    """A state with a 0.5 s standstill window ran with it under a 0.2 s config (omega 20.0
    from step, 10.2 from run here); the config's own state still gives step == run."""
    from vibrospeed.estimators import aided_grid

    cfg = aided_grid.Config()
    y = np.sin(20.0 * np.arange(60) * 0.01)
    u = np.zeros(60)
    for other in (aided_grid.Config(ss_window=0.5), aided_grid.Config(mode_n=7)):
        st = aided_grid.init(other)
        with pytest.raises(ParameterError, match="^aided_grid state: .* do not match"):
            aided_grid.step(cfg, st, 0.3, 0.0)
        with pytest.raises(ParameterError, match="^aided_grid state: .* do not match"):
            aided_grid.run(cfg, y, u, state=st)
    res = aided_grid.run(cfg, y, u)
    st = aided_grid.init(cfg)
    for k in range(y.size):
        st, est = aided_grid.step(cfg, st, y[k], u[k])
        assert est.omega == res.omega[k]


@pytest.mark.parametrize("method", ["grid", "aided"])
@pytest.mark.parametrize("value", ["inf", "nan", "0", "-5"])
def test_a_search_range_that_is_no_number_is_named_as_omega_max(method, value):
    """The default walk is derived from ``omega_max`` (``grid.method.q_omega_for``) before the
    config is built: the error names ``omega_max``, not the derived ``q_omega``."""
    from vibrospeed import sim
    from vibrospeed.estimators import get

    rec = sim.simulate("cart", seed=1, duration=2)
    with pytest.raises(ParameterError, match="^omega_max must be a finite number > 0 rad/s"):
        get(method).estimate(rec, params={"omega_max": value}, wheel_radius=0.2)


@pytest.mark.parametrize(("params", "says"), [
    # given as values (not text) these were a TypeError deep in the Config, or taken
    ({"omega_min": [1, 2]}, "parameter 'omega_min': cannot use [1, 2] as"),
    ({"omega_max": None}, "parameter 'omega_max': cannot use None as"),
    ({"omega_min": True}, "parameter 'omega_min': cannot use True as"),
    ({"M": 2.5}, "parameter 'M': cannot use 2.5 as"),
    ({"smooth": 3}, "parameter 'smooth': cannot use 3 as"),
])
def test_a_value_of_the_wrong_kind_given_through_the_api_is_one_line(params, says):
    from vibrospeed.errors import ParameterError
    from vibrospeed.estimators import grid
    from vibrospeed.sim import simulate

    rec = simulate("cart", seed=1, duration=5)
    with pytest.raises(ParameterError, match=re.escape(says)):
        grid.estimate(rec, params=params)


def test_values_of_the_right_kind_pass_as_given():
    import numpy as np

    from vibrospeed.config import parse_value

    assert parse_value(2, float) == 2 and parse_value(np.float32(2.5), float) == 2.5
    assert parse_value(3.0, int) == 3.0 and parse_value(np.int64(4), int) == 4
    assert parse_value(1, bool) == 1 and parse_value(np.bool_(True), bool)
    assert parse_value((1, 2.5), tuple[float, ...]) == (1, 2.5)
    assert parse_value(None, float | None) is None
