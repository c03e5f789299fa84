"""Estimator parameters that made the output NaN, or failed deep inside ``run`` with numpy's or
Python's own error, are one-line :class:`~vibrospeed.errors.ParameterError` naming the
parameter and the value when the ``Config`` is built; the valid edges (0, inf where it means
"never" or "no limit") still run and give finite numbers."""

import math

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
    {"q_omega": nan}, {"dt": nan}, {"M": nan}, {"M": inf},
])
def test_harmonic_model_refuses_infinite_noise_period_or_prior(kw):
    """Each of these made every EKF / aided output NaN (or int() failed on M)."""
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
