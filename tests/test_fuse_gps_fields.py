"""The GPS receiver and satellite-gate fields that ``fuse`` and ``gps-riss`` share
(:class:`vibrospeed.estimators.gps_riss.GpsFields`): one definition, the same gate."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import fuse, gps_riss
from vibrospeed.models.gps_riss import GpsLagModel

NAMES = ("gps_a", "gps_b", "gps_delay", "gps_pade", "min_sats")


@pytest.mark.parametrize("cls", [fuse.Config, gps_riss.Config])
def test_both_configs_take_the_shared_fields(cls):
    assert issubclass(cls, gps_riss.GpsFields)
    names = [f.name for f in dataclasses.fields(cls)]
    assert tuple(names[:5]) == NAMES  # first, in this order
    assert len(set(names)) == len(names)
    c = cls(gps_delay=0.1, gps_pade=1, min_sats=5.0)
    assert c.lag == GpsLagModel(a=(0.0, 1.0, -1427.2, -114.2), b=(0.0, 1427.2), delay=0.1,
                                pade=1)
    assert c.min_sats == 5.0
    # the gate: finite speed and not fewer than min_sats satellites (an unknown count passes)
    g = np.array([3.0, np.nan, 4.0, 5.0, 6.0])
    s = np.array([5.0, 9.0, 4.0, np.nan, 4.999])
    assert c.valid_fixes(g, s).tolist() == [True, False, False, True, False]
    assert c.valid_fixes(g, None).tolist() == [True, False, True, True, True]


def test_defaults_are_one_definition():
    a, b = fuse.Config(), gps_riss.Config()
    for n in NAMES:
        assert getattr(a, n) == getattr(b, n) == getattr(gps_riss.GpsFields(), n)


def test_bad_shared_fields_are_refused_with_the_method_named():
    with pytest.raises(ParameterError, match="^fuse: min_sats must be >= 0"):
        fuse.Config(min_sats=-1.0)
    with pytest.raises(ParameterError, match="^min_sats must be >= 0"):
        gps_riss.Config(min_sats=-1.0)
    for cls in (fuse.Config, gps_riss.Config):
        with pytest.raises(ParameterError):
            cls(gps_pade=3)
