"""Planar body-frame kinematics and the ideal / disturbance split of the velocities.

METHODS.md section 4; seed: algebraic-velocity-estimation-paper, eq. 2-7.

Body frame x forward, y left, yaw rate ``psi_dot`` positive counter-clockwise (seen from above).
Accelerations measured in the rotating frame at the centre of gravity (eq. 2)::

    gamma_x = dVx/dt - psi_dot * Vy
    gamma_y = dVy/dt + psi_dot * Vx

or, with ``V = Vx + i Vy`` and ``gamma = gamma_x + i gamma_y`` (eq. 5)::

    dV/dt = -i psi_dot V + gamma.

Ideal terms (eq. 6): ``Rx = r * omega_mean`` (mean of the four wheel speeds) and
``Ry = -L1 * psi_dot`` (zero sideslip at the front axle, remark 1), with ``L1`` the distance from
the centre of gravity to the front axle. The disturbances ``G = V - R`` obey (eq. 7)::

    dGx/dt =  psi_dot Gy - L1 psi_dot^2 - r d(omega_mean)/dt + gamma_x
    dGy/dt = -psi_dot Gx - psi_dot r omega_mean + L1 psi_ddot + gamma_y

No vehicle parameter other than ``r`` and ``L1`` and no tyre model enters.
"""

from __future__ import annotations

import numpy as np
from numba import njit


def ideal_terms(omega_mean, yaw_rate, r: float, L1: float):
    """``(Rx, Ry) = (r * omega_mean, -L1 * yaw_rate)`` (eq. 6)."""
    return r * np.asarray(omega_mean), -L1 * np.asarray(yaw_rate)


def body_accelerations(dvx, dvy, vx, vy, yaw_rate):
    """``(gamma_x, gamma_y)`` from the velocity, its time derivative and the yaw rate (eq. 2)."""
    return dvx - yaw_rate * vy, dvy + yaw_rate * vx


@njit(cache=True)
def disturbance_rhs(gx_, gy_, yaw_rate, yaw_acc, omega_mean, omega_dot, ax, ay, r, L1):
    """Right-hand side ``(dGx/dt, dGy/dt)`` of eq. 7 at one instant."""
    dgx = yaw_rate * gy_ - L1 * yaw_rate * yaw_rate - r * omega_dot + ax
    dgy = -yaw_rate * gx_ - yaw_rate * r * omega_mean + L1 * yaw_acc + ay
    return dgx, dgy


@njit(cache=True)
def rotating_step(vx, vy, yaw_rate, ax, ay, dt):
    """One step of eq. 5 with yaw rate and acceleration held over ``dt``.

    Exact solution for constant ``psi_dot = w`` and ``gamma``:
    ``V(dt) = e^{-i w dt} V + gamma (1 - e^{-i w dt}) / (i w)`` (``-> gamma dt`` as ``w -> 0``).
    """
    c = np.cos(yaw_rate * dt)
    s = np.sin(yaw_rate * dt)
    # e^{-i w dt} V
    nvx = c * vx + s * vy
    nvy = -s * vx + c * vy
    wdt = yaw_rate * dt
    if abs(wdt) < 1e-8:
        fr = dt  # real part of (1 - e^{-i w dt}) / (i w)
        fi = -0.5 * yaw_rate * dt * dt
    else:
        fr = s / yaw_rate
        fi = (c - 1.0) / yaw_rate
    return nvx + fr * ax - fi * ay, nvy + fr * ay + fi * ax


@njit(cache=True)
def integrate_velocity(vx0, vy0, yaw_rate, ax, ay, dt):
    """Pure integration of eq. 5 from ``(vx0, vy0)``: the open-loop baseline (drifts with bias).

    Arrays ``yaw_rate, ax, ay`` (n,) sampled every ``dt``; returns ``(vx, vy)`` (n,) with
    ``vx[0] = vx0``; sample ``k`` to ``k+1`` uses the inputs of sample ``k``.
    """
    n = yaw_rate.size
    vx = np.empty(n)
    vy = np.empty(n)
    vx[0] = vx0
    vy[0] = vy0
    for k in range(n - 1):
        vx[k + 1], vy[k + 1] = rotating_step(vx[k], vy[k], yaw_rate[k], ax[k], ay[k], dt)
    return vx, vy
