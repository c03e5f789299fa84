"""The mount estimate (signal.mount) against analytic rotations and the simulator's drawn mount."""

import numpy as np
import pytest

from vibrospeed.errors import InputError
from vibrospeed.signal import mount
from vibrospeed.sim.sensors import mount_matrix

G = 9.80665
DT = 0.01


def _drive(rot: np.ndarray, seed: int = 0, n: int = 12_000, lateral: float = 0.5,
           noise: float = 0.3):
    """Sensor axes (n, 3) of a vehicle that stands for 10 s, then drives with a smooth
    longitudinal acceleration and uncorrelated lateral acceleration; ``rot`` takes vehicle
    vectors to the sensor frame. Returns (acc, omega, still, a_long) with r = 0.3 m."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    moving = t >= 10.0
    a_long = np.where(moving, 0.8 * np.sin(0.3 * (t - 10.0)) + 0.4 * np.sin(0.71 * t), 0.0)
    a_lat = np.where(moving, lateral * np.sin(0.53 * t + 1.0), 0.0)
    v = np.cumsum(a_long) * DT + np.where(moving, 5.0, 0.0)
    omega = v / 0.3
    veh = np.column_stack([a_long, a_lat, np.full(n, G)])
    acc = veh @ rot.T + noise * rng.normal(size=(n, 3)) + np.array([0.05, -0.03, 0.02])
    return acc, omega, ~moving, a_long


@pytest.mark.parametrize("angles", [(0.0, 0.0, 0.0), (0.3, -0.2, 1.1), (2.8, 0.6, -2.0),
                                    (-1.5, 0.1, 3.0)])
def test_forward_axis_of_an_analytic_rotation(angles):
    rot = mount_matrix(angles)
    acc, omega, still, a_long = _drive(rot)
    m = mount.estimate(acc, DT, omega=omega, wheel_radius=0.3, still=still)
    assert m.confident
    # the vehicle's x axis in the sensor frame, with its sign
    assert m.forward @ rot[:, 0] > 0.995
    assert abs(np.linalg.norm(m.forward) - 1.0) < 1e-12
    # gravity (plus the bias) from the standing samples
    assert np.allclose(m.gravity, rot @ [0, 0, G] + [0.05, -0.03, 0.02], atol=0.04)  # 4 sigma
    assert abs(m.slope - 1.0) < 0.1 and m.rho > 0.8
    u = mount.longitudinal(acc, m)
    moving = ~still
    assert np.sqrt(np.mean((u - a_long)[moving] ** 2)) < 0.35  # the sensor noise is 0.3


def test_plane_basis_is_orthonormal():
    for up in ([0, 0, 1], [1, 2, 3], [-5, 0.1, 0.0]):
        e1, e2 = mount.plane_basis(np.asarray(up, float))
        u = np.asarray(up, float) / np.linalg.norm(up)
        B = np.vstack([e1, e2, u])
        assert np.allclose(B @ B.T, np.eye(3), atol=1e-12)


def test_not_confident_without_a_reference_or_with_a_wrong_one():
    rot = mount_matrix((0.2, 0.1, 0.5))
    acc, omega, still, _ = _drive(rot)
    m = mount.estimate(acc, DT, still=still)
    assert not m.confident and np.all(np.isnan(m.forward))
    assert np.all(np.isnan(mount.longitudinal(acc, m)))
    # a reference unrelated to the motion: no correlation, not confident
    rng = np.random.default_rng(5)
    wrong = 20.0 + np.cumsum(rng.normal(size=omega.size)) * 0.05
    m = mount.estimate(acc, DT, omega=wrong, wheel_radius=0.3, still=still)
    assert not m.confident
    # a quarter of the wheel speed: the slope (about 4) leaves the accepted range, the axis is
    # still the right one (the direction does not depend on the reference's scale)
    m = mount.estimate(acc, DT, omega=omega / 4.0, wheel_radius=0.3, still=still)
    assert m.slope > mount.SLOPE_RANGE[1] and not m.confident
    assert m.forward @ rot[:, 0] > 0.995
    # half the wheel speed (a harmonic lock): slope 2, confident, the same axis
    m = mount.estimate(acc, DT, omega=omega / 2.0, wheel_radius=0.3, still=still)
    assert 1.5 < m.slope < mount.SLOPE_RANGE[1] and m.confident
    assert m.forward @ rot[:, 0] > 0.995


def test_bad_shapes():
    with pytest.raises(InputError, match="shape"):
        mount.estimate(np.zeros((10, 2)), DT)
    with pytest.raises(InputError, match="omega"):
        mount.estimate(np.zeros((10, 3)) + 1.0, DT, omega=np.zeros(9), wheel_radius=0.3)


def test_simulated_drive_mount():
    """The family's drawn mount (rec.meta): the forward axis from the true wheel speed."""
    from vibrospeed import sim

    rec = sim.simulate("random", seed=3, duration=60)
    rot = mount_matrix(rec.meta["drawn"]["mount"])
    A = np.column_stack([rec["ax"], rec["ay"], rec["az"]])
    m = mount.estimate(A, 1.0 / rec.fs, omega=rec["omega_true"], wheel_radius=rec.wheel_radius,
                       still=rec["omega_true"] <= 0)
    assert m.confident
    assert m.forward @ rot[:, 0] > 0.98


def test_running_mount_is_causal_and_converges():
    """The mount from the data so far: the samples up to any time are the same whether the
    log goes on or not (nothing after a sample is read for it); it is confident once enough
    motion was seen, and from then on its longitudinal acceleration is the drive's (within
    the sensor noise), its last estimate the whole-log one."""
    rot = mount_matrix((0.3, -0.2, 1.1))
    acc, omega, still, a_long = _drive(rot)
    run = mount.running(acc, DT, omega=omega, wheel_radius=0.3, still=still)
    k = 7_000
    part = mount.running(acc[:k], DT, omega=omega[:k], wheel_radius=0.3, still=still[:k])
    np.testing.assert_array_equal(part.u, run.u[:k])
    np.testing.assert_array_equal(part.confident, run.confident[:k])
    assert not run.confident[:1000].any()  # standing for 10 s: no forward axis yet
    on = np.flatnonzero(run.confident)
    assert on.size and on[0] * DT < 40.0 and run.confident[on[0]:].all()
    assert np.sqrt(np.mean((run.u[on] - a_long[on]) ** 2)) < 0.35  # the sensor noise is 0.3
    whole = mount.estimate(acc, DT, omega=omega, wheel_radius=0.3, still=still)
    assert run.mounts[-1].forward @ whole.forward > 0.9999
    # re-estimates every second at first, later every 2 % of the elapsed time
    assert np.allclose(np.diff(run.times[:5]), 1.0)
    assert run.times.size < omega.size * DT
