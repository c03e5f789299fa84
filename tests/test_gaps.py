"""A time line with a gap through the Python API: every vibration estimator refuses it in one
line naming the gap (stepping sample by sample, it would join the two sides as if no time had
passed), and :func:`vibrospeed.io.resample_uniform`, which the CLI applies itself, makes it an
estimable recording with NaN samples across the gap."""

import numpy as np
import pytest

from vibrospeed import io, sim
from vibrospeed.errors import InputError
from vibrospeed.estimators import get
from vibrospeed.estimators.common import GAP_FACTOR, check_uniform
from vibrospeed.types import Recording

METHODS = ("grid", "rbpmf", "ekf", "rbpf", "shs", "aided")


@pytest.fixture(scope="module")
def gappy():
    rec = sim.simulate("cart", seed=2, duration=20.0)
    keep = (rec.t < 8.0) | (rec.t >= 13.0)  # 5 s of samples missing after t = 8 s
    return Recording(rec.t[keep], {k: v[keep] for k, v in rec.channels.items()}, source="g.csv")


def test_check_uniform_names_the_longest_gap(gappy):
    with pytest.raises(InputError) as e:
        check_uniform(gappy)
    msg = str(e.value)
    assert msg.startswith("g.csv: time line has 1 gap(s) longer than 3 periods")
    assert "the longest 5.01 s after t = 7.99 s" in msg and "resample_uniform" in msg
    assert "\n" not in msg
    # jitter and a gap of up to GAP_FACTOR periods (a dropped sample or two) stay accepted
    t = np.arange(1000) * 0.01
    t = np.delete(t, [300, 301])  # one period of GAP_FACTOR = 3 periods: two samples dropped
    assert GAP_FACTOR == 3
    assert check_uniform(Recording(t, {"ay": np.zeros(t.size)})) == pytest.approx(0.01)


@pytest.mark.parametrize("method", METHODS)
def test_every_vibration_estimator_refuses_a_gap_and_runs_once_resampled(gappy, method):
    p = {"omega_min": 4.0, "omega_max": 30.0}
    with pytest.raises(InputError, match="gap"):
        get(method).estimate(gappy, params=p, wheel_radius=0.2)
    rec = io.resample_uniform(gappy)
    tr = get(method).estimate(rec, params=p, wheel_radius=0.2)
    # the grid point of the first sample after the gap lies ~1e-11 s before 13 s: it is that
    # sample, not the gap
    gap = (rec.t > 8.0) & (rec.t < 13.0 - 1e-6)
    assert np.isnan(rec.channel("ay")[gap]).all()  # NaN across the gap, bridged by prediction
    first = int(np.argmax(gappy.t >= 13.0 - 1e-6))
    assert rec.channel("ay")[np.argmin(np.abs(rec.t - gappy.t[first]))] == gappy["ay"][first]
    # outside the gap finite (shs: its 2 s batches that touch the gap are NaN)
    assert len(tr) == len(rec) and np.isfinite(tr.omega[~gap]).mean() > (
        0.9 if method == "shs" else 0.99)
