"""Walkthrough of the algebraic Vx / Vy estimator as a tyre / ABS tester: parameter domains,
the thesis' low-pass table, a motor-speed "wheel" on an RC car."""

import numpy as np
import pytest
from scipy import signal as sps

from vibrospeed.errors import ParameterError
from vibrospeed.estimators import algebraic as A
from vibrospeed.signal import prefilter as pf


# -- parameter domains ------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "value", "says"), [
    ("L1", 1e9, r"L1 must be in \(0, 10\] m"),
    ("r", 1e9, r"r must be in \(0, 3\] m"),
    ("window", 1e9, r"window must be in \(0, 10\] s"),  # was a 745 GiB kernel (MemoryError)
    ("window_d", 0.0, r"window_d must be in \(0, 10\] s"),
    ("slip_window", 1e6, r"slip_window must be in \(0, 10\] s"),
    ("N", 50, r"N must be an integer in \[1, 10\]"),
    ("alpha", 10**8, r"alpha must be at most 6000 samples \(60 s at Ts = 0.01 s\)"),
    ("backtrack", 10**8, r"backtrack must be at most 6000 samples"),
    ("noise_tau", 1e-9, r"noise_tau must be >= Ts = 0.01 s"),
    ("vy0", 1e9, r"vy0 must be in \[-100, 100\] m/s"),
    ("slip_sd", 2.0, r"slip_sd must be in \[0, 1\]"),
    ("eps_k", -1.0, r"eps_k must be in \[0, 100\]"),
    ("L1", float("nan"), r"L1 must be in \(0, 10\] m, got nan"),
    ("eps1", 0.0, r"eps1 must be > 0 m/s\^2 \(inf: never\)"),
])
def test_out_of_domain_parameter_is_one_line_naming_it(name, value, says):
    with pytest.raises(ParameterError, match=r"^algebraic: " + says) as exc:
        A.Config(**{name: value})
    assert "\n" not in str(exc.value)


def test_domain_edges_and_never_thresholds_are_accepted():
    A.Config(L1=10.0, r=3.0, window=10.0, window_d=10.0, N=10, slip_window=10.0, vy0=-100.0,
             alpha=6000, eps1=np.inf, eps2=np.inf, slip_tol=np.inf, max_int=np.inf)


def test_window_too_short_for_the_degree_names_the_windows():
    with pytest.raises(ParameterError, match=r"^algebraic: window = 0.02 s / window_d = 0.2 s "
                                             r"at Ts = 0.01 s: window must hold at least"):
        A.Config(window=0.02, N=3)


# -- thesis table 3.1 -------------------------------------------------------------------------
def test_thesis_lowpass_table_is_table_3_1():
    """Thesis (indoor-vehicle-vibration-ekf-thesis) table 3.1, best omega_lp per M:
    M = 1: 12, M = 2: 19, M = 3: 10, M = 4: 8 rad/s (the code had 25 for M = 1 and 10 for
    M >= 4); the -3 dB point of the designed low-pass is there."""
    table = {1: 12.0, 2: 19.0, 3: 10.0, 4: 8.0}
    assert pf.THESIS_LP_CUTOFF == table
    for M, wc in {**table, 6: 8.0}.items():
        lp = pf.design("thesis-hplp", 100.0, M=M)[-1:]
        _, h = sps.sosfreqz(lp, worN=[wc], fs=2 * np.pi * 100.0)
        assert abs(h[0]) == pytest.approx(1 / np.sqrt(2), rel=0.02)
