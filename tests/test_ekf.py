"""Harmonic EKF: validation signal (thesis eq. 2.6, table 2.1), exact cases, step == run."""

import dataclasses

import numpy as np
import pytest

from vibrospeed.estimators import ekf
from vibrospeed.models.harmonic import HarmonicModel

W0 = 1.45 * 2 * np.pi  # thesis eq. 2.6 fundamental, rad/s


def _eq26(seed: int, n: int = 3000, fs: float = 100.0) -> np.ndarray:
    """Thesis eq. 2.6 with e2, e3 read as standard deviations 0.01 rad and 0.04."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    return sum(
        (0.4 + k / 10 + rng.uniform(-0.2, 0.2, n)) * np.cos(k * W0 * t + rng.normal(0, 0.01, n))
        for k in (1, 2, 3)
    ) + rng.normal(0, 0.04, n)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_validation_signal_converges_like_thesis_table_2_1(seed):
    # R matched to the signal's noise (thesis 2.3.5 tunes R from the residual variance)
    model = dataclasses.replace(HarmonicModel.from_thesis(), p0_amp=0.1, r=0.04)
    res = ekf.run(ekf.Config(model, omega0=10.2), _eq26(seed))
    om = res.omega[-1000:].mean()
    amps = res.amplitudes[-1000:].mean(axis=0)
    assert abs(om - W0) < 0.15  # thesis got 9.22 against 9.11
    np.testing.assert_allclose(amps, [0.5, 0.6, 0.7], atol=0.08)


def test_clean_tone_exact_frequency_and_amplitudes():
    t = np.arange(3000) / 100
    y = 1.0 * np.cos(9.11 * t) + 0.6 * np.cos(2 * 9.11 * t + 0.3)
    model = dataclasses.replace(HarmonicModel.from_thesis(), M=2, p0_amp=1.0)
    res = ekf.run(ekf.Config(model, omega0=10.2), y)
    assert abs(res.omega[-1] - 9.11) < 1e-3
    np.testing.assert_allclose(res.amplitudes[-1], [1.0, 0.6], atol=5e-3)
    # consistent: the error over the converged part stays well inside the reported std
    err = np.abs(res.omega[1000:] - 9.11)
    assert np.all(err < 3 * res.omega_std[1000:])


def test_step_equals_run_with_nans():
    rng = np.random.default_rng(5)
    y = _eq26(5, n=400)
    y[50:60] = np.nan
    cfg = ekf.Config.from_thesis()
    res = ekf.run(cfg, y)
    st = ekf.init(cfg)
    om, sd = [], []
    for v in y:
        st, e = ekf.step(cfg, st, v)
        om.append(e.omega)
        sd.append(e.omega_std)
    assert np.array_equal(np.array(om), res.omega)
    assert np.array_equal(np.array(sd), res.omega_std)
    np.testing.assert_array_equal(st.P, res.final.P)
    assert rng is not None


def test_covariance_symmetric_psd_and_chunked_run():
    y = _eq26(7, n=1500)
    cfg = ekf.Config.from_thesis()
    whole = ekf.run(cfg, y)
    first = ekf.run(cfg, y[:700])
    second = ekf.run(cfg, y[700:], state=first.final)
    assert np.array_equal(np.concatenate([first.omega, second.omega]), whole.omega)
    P = whole.final.P
    assert np.array_equal(P, P.T)
    assert np.linalg.eigvalsh(P).min() > 0


def test_nan_only_predicts():
    cfg = ekf.Config.from_thesis()
    st = ekf.init(cfg)
    st2, e = ekf.step(cfg, st, float("nan"))
    assert np.isnan(e.innovation)
    # prediction inflates the omega variance by T * q_omega exactly when F keeps omega
    assert st2.P[0, 0] == pytest.approx(st.P[0, 0] + cfg.model.dt * cfg.model.q_omega)


def test_omega_stays_nonnegative_under_symmetry():
    # a negative start is mapped onto the equivalent positive state
    t = np.arange(2000) / 100
    y = np.cos(9.11 * t)
    model = dataclasses.replace(HarmonicModel.from_thesis(), M=1, p0_amp=1.0)
    res = ekf.run(ekf.Config(model, omega0=0.5, p0_omega=100.0), y)
    assert np.all(res.omega >= 0)


def test_step_makes_the_state_check_message_only_for_a_wrong_state(monkeypatch):
    """``step`` checks the state against its config at every sample; the message's text (an
    f-string, ~0.1-0.2 us a call) was formatted each time. It now passes a format string and
    its value, formatted by the check only when a shape is wrong."""
    from vibrospeed.config import check_state
    from vibrospeed.errors import ParameterError

    given = []

    def spy(method, config_says, *says, **fields):
        given.append((config_says, says))
        check_state(method, config_says, *says, **fields)

    monkeypatch.setattr(ekf, "check_state", spy)
    cfg = ekf.Config(HarmonicModel.from_thesis(M=2))
    st = ekf.init(cfg)
    for v in (0.1, -0.2, 0.3):
        st, _ = ekf.step(cfg, st, v)
    assert given == [("M = {}", (2,))] * 3  # no text made per sample
    wrong = ekf.init(ekf.Config(HarmonicModel.from_thesis(M=3)))
    with pytest.raises(ParameterError) as exc:
        ekf.step(cfg, wrong, 0.1)
    assert str(exc.value) == ("ekf state: x, P, comb ((7,), (7, 7), (3,)) do not match the "
                              "config's M = 2 (wanted ((5,), (5, 5), (3,)))")


def test_normalize_tau_is_read_as_a_number_and_text_that_is_not_one_is_named():
    """``normalize_tau`` given as text (the CLI's ``-p``) is the number it spells: ``0`` is the
    thesis model in the signal's units, ``5`` the unit-RMS one (UNIT_RMS_MODEL); other text is
    one :class:`ParameterError` naming it (was an internal ValueError from ``float``)."""
    from vibrospeed.errors import ParameterError
    from vibrospeed.types import Recording

    t = np.arange(400) / 100.0
    rec = Recording(t=t, channels={"ay": np.cos(W0 * t)}, wheel_radius=0.1)
    thesis = HarmonicModel.from_thesis()
    assert ekf.config_for(rec, params={"normalize_tau": "0"}).model.r == thesis.r
    assert ekf.config_for(rec, params={"normalize_tau": "5"}).model.r \
        == ekf.UNIT_RMS_MODEL["r"] == ekf.config_for(rec).model.r
    with pytest.raises(ParameterError) as err:
        ekf.estimate(rec, params={"normalize_tau": "abc"})
    assert str(err.value) == "parameter 'normalize_tau': cannot read 'abc' as float (a number)"


def test_sidecar_params_rerun_the_estimate():
    """Every value the estimate reads is in its params: run again from them (``axis`` as the
    argument, ``dt`` from the data) it gives the same omega, and ``omega_min`` = 8 and 12,
    which give different tracks, are told apart (the params left out omega_min)."""
    from vibrospeed import sim

    rec = sim.simulate("cart", seed=1, duration=20)
    tracks = {}
    for lo in (8.0, 12.0):
        tr = ekf.estimate(rec, params={"omega_min": str(lo)})
        assert tr.params["omega_min"] == lo
        again_params = {k: v for k, v in tr.params.items() if k not in ("axis", "dt")}
        again = ekf.estimate(rec, axis=tr.params["axis"], params=again_params)
        np.testing.assert_array_equal(again.omega, tr.omega)
        tracks[lo] = tr
    assert not np.array_equal(tracks[8.0].omega, tracks[12.0].omega)
