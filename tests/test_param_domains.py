"""Every ``-p NAME=VALUE`` either runs or is refused in one line: values a sweep over inf, nan,
-1, 0 and 1e12 of every numeric parameter of every method found dying with an internal error
(OverflowError converting inf to a sample count, MemoryError allocating TiB, a run of hours)
are a :class:`ParameterError` naming the parameter, the domain and the value."""

import pytest

from vibrospeed import estimators, sim
from vibrospeed.errors import ParameterError
from vibrospeed.estimators import grid, shs
from vibrospeed.estimators.grid.config import Config as GridFilter

TOO_LARGE = r"n_grid = {n} and M = {M} are too large: .* at most 1\.34e\+08 \(1 GiB\)"
PARTICLES = r"n_particles = {K} and M = {M} are too large: .* at most 1\.34e\+08 \(1 GiB\)"
WINDOW_INF = r"{0} must be a finite number > 0 s, got inf"
#: 2^22 samples at the recording's 100 Hz
SAMPLES = r"must be at most 4194304 samples \(4\.194e\+04 s at 100 Hz\), got "
WINDOW_BIG = r"comb_window " + SAMPLES + r"1000000000000\.0 s"
BG = r"comb_bg must be > 0 Hz and at most the Nyquist frequency 50 Hz \(the whole spectrum\), got "
BIG = 1_000_000_000_000

FINDINGS = [
    ("grid", "M", "1e12", TOO_LARGE.format(n=200, M=BIG)),
    ("rbpmf", "M", "1e12", TOO_LARGE.format(n=200, M=BIG)),
    ("aided", "M", "1e12", TOO_LARGE.format(n=200, M=BIG)),
    ("fuse", "M", "1e12", r"n_grid = \d+ and M = 1000000000000 are too large"),
    ("rbpmf", "n_grid", "1e12", TOO_LARGE.format(n=BIG, M=3)),
    ("grid", "n_grid", "1e12", r"n_grid = 1000000000000 and M = \d+ are too large"),
    ("aided", "n_grid", "1e12", r"n_grid = 1000000000000 and M = \d+ are too large"),
    ("fuse", "n_grid", "1e12", r"n_grid = 1000000000000 and M = \d+ are too large"),
    ("rbpf", "M", "1e12", PARTICLES.format(K=3000, M=BIG)),
    ("rbpf", "n_particles", "1e12", PARTICLES.format(K=BIG, M=3)),
    ("grid", "comb_window", "inf", WINDOW_INF.format("comb_window")),
    ("aided", "comb_window", "inf", WINDOW_INF.format("comb_window")),
    ("fuse", "comb_window", "inf", WINDOW_INF.format("comb_window")),
    ("grid", "comb_window", "1e12", WINDOW_BIG),
    ("fuse", "comb_window", "1e12", WINDOW_BIG),
    ("grid", "comb_min_window", "inf", WINDOW_INF.format("comb_min_window")),
    ("fuse", "comb_min_window", "inf", WINDOW_INF.format("comb_min_window")),
    ("grid", "comb_bg", "inf", BG + "inf"),
    ("aided", "comb_bg", "1e12", BG + r"1000000000000\.0"),
    ("fuse", "comb_bg", "1e12", BG + r"1000000000000\.0"),
    ("aided", "wheel_radius", "inf", r"wheel_radius must be finite and > 0 m, got inf"),
    ("aided", "ss_n", "1e12", r"ss_window / ss_n " + SAMPLES + r"ss_n = 1000000000000"),
    ("aided:ekf", "mode_window", "1e12",
     r"mode_window / mode_n " + SAMPLES + r"mode_window = 1e\+12 s"),
    ("aided:ekf", "M", "1e12", r"M = 1000000000000 is too large: the aided EKF's covariance "
                               r"\(\(2M \+ 2\)\^2\) would hold 4e\+24 floats"),
    ("aided:ekf", "lp_cutoff", "nan",
     r"lp_cutoff must be finite and > 0 rad/s \(or none: the pre-filter's own cut-off\), "
     r"got nan"),
    ("aided", "lp_cutoff", "0", r"lp_cutoff must be finite and > 0 .*, got 0\.0"),
    ("aided", "lp_cutoff", "inf", r"lp_cutoff must be finite and > 0 .*, got inf"),
    ("aided", "wheelbase", "-1", r"wheelbase must be finite and > 0 m \(or none\), got -1\.0"),
    ("aided", "accel_detrend", "nan", r"accel_detrend must be >= 0 s \(0: off\), got nan"),
    ("grid", "omega0", "-1", r"omega0 must be >= 0 rad/s \(or None\), got -1\.0"),
    ("aided", "omega0", "-1", r"omega0 must be >= 0 rad/s \(or None\), got -1\.0"),
    ("algebraic", "r", "0", r"algebraic: r must be in \(0, 3\] m, got 0\.0"),
    ("algebraic", "L1", "0", r"algebraic: L1 must be in \(0, 10\] m, got 0\.0"),
    ("shs", "n_fft", "1e12", r"n_fft must be at most 16777216 \(2\^24\), got 1000000000000"),
    ("shs", "n_harmonics", "1e12", r"n_harmonics must be at most 1000, got 1000000000000"),
    ("shs", "points_per_octave", "1e12",
     r"points_per_octave must be at most 100000, got 1000000000000"),
]


@pytest.fixture(scope="module")
def car():
    """4 s of the simulated car at 100 Hz (GPS, wheel speeds, yaw rate: every method runs)."""
    return sim.simulate("car", seed=1, duration=4)


@pytest.mark.parametrize(("method", "name", "value", "message"), FINDINGS,
                         ids=[f"{m}-{n}={v}" for m, n, v, _ in FINDINGS])
def test_a_value_outside_the_domain_is_refused_in_one_line(car, method, name, value, message):
    assert car.fs == pytest.approx(100.0)  # the messages' 50 Hz and 4194304 samples = 4.194e4 s
    method, _, tracker = method.partition(":")  # aided:ekf is -m aided -p tracker=ekf
    params = {name: value, **({"tracker": tracker} if tracker else {})}
    with pytest.raises(ParameterError, match=message):
        estimators.get(method).estimate(car, wheel_radius=car.wheel_radius, params=params)


def test_the_bounds_keep_the_values_on_them():
    """The bounds are inclusive and sized by the arrays: the Nyquist frequency itself is a
    valid background width, 2^22 samples a valid frame, 2^27 floats a valid grid (N = 2^27 /
    36 rows of M = 3), the shs counts' maxima valid."""
    dt = 0.01
    grid.Config(comb_bg=0.5 / dt, comb_window=(1 << 22) * dt)
    n = (1 << 27) // 36
    GridFilter(n_grid=n)
    with pytest.raises(ParameterError, match=f"n_grid = {n + 1} and M = 3 are too large"):
        GridFilter(n_grid=n + 1)
    shs.Config(n_harmonics=1000, n_fft=1 << 24, points_per_octave=100_000)
