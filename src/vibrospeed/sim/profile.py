"""Speed profiles: piecewise segments with jerk-limited transitions, evaluated exactly.

A drive is a list of :class:`Segment` (cruise, accelerate, brake, stop, start). Each segment
becomes a block of constant commanded acceleration ``a_cmd`` (0 while cruising or stopped). The
acceleration actually driven is ``a_cmd`` smoothed by a moving average of width ``jerk_time``
(``tau``)::

    a(t) = (1/tau) * int_{t - tau/2}^{t + tau/2} a_cmd(s) ds

so every change of acceleration is a linear ramp lasting ``tau`` (jerk ``|delta a| / tau``), the
speed change of each block is kept exactly (a normalised kernel preserves integrals) and a brake
to 0 ends at exactly 0. Writing ``C = int a_cmd``, ``D = int C``, ``E = int D`` (piecewise
polynomials of degree 1, 2, 3 over the block breakpoints)::

    a(t) = [C(t + tau/2) - C(t - tau/2)] / tau
    v(t) = v0 + [D(t + tau/2) - D(t - tau/2)] / tau
    x(t) = v0 (t - t0) + [E(t + tau/2) - E(t - tau/2) - E(t0 + tau/2)] / tau

are exact in continuous time, so the wheel angle ``x / r`` (harmonic phases, cog-tick times) is
exact, not a numerical integral. With ``tau = 0`` the commanded blocks are used unsmoothed.

Turns are described by the path curvature ``kappa(t)`` (1/m): yaw rate ``kappa v`` (rad/s), lateral
acceleration ``kappa v^2`` (m/s^2), both zero at standstill by construction.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vibrospeed.errors import ParameterError

SEGMENT_KINDS = ("cruise", "accelerate", "brake", "stop", "start")


@dataclass(frozen=True)
class Segment:
    """One piece of a drive.

    kind : ``cruise`` (hold speed), ``accelerate`` / ``brake`` (change speed to ``speed``),
        ``stop`` (stand still; the vehicle must already be at 0), ``start`` (from rest to
        ``speed``).
    duration : s. Required for ``cruise`` and ``stop``; for speed changes optional, in which case
        the acceleration is ``|dv| / duration`` instead of ``accel``.
    speed : m/s at the end of a speed change (``brake`` defaults to 0).
    accel : m/s^2, magnitude of the commanded acceleration of a speed change (default: the
        profile's ``accel`` for accelerate/start, ``decel`` for brake).
    """

    kind: str
    duration: float | None = None
    speed: float | None = None
    accel: float | None = None


@dataclass(frozen=True)
class Turn:
    """A turn: curvature ``kappa(t) = kappa_peak sin^2(pi (t - t_start) / duration)``.

    t_start : s; duration : s; kappa_peak : 1/m (positive = left turn, yaw rate > 0, a_y > 0).
    """

    t_start: float
    duration: float
    kappa_peak: float


class SpeedProfile:
    """Exact continuous-time speed profile built from constant-acceleration blocks.

    Parameters
    ----------
    breaks : (K+1,) s, block boundaries, increasing.
    a_cmd : (K,) m/s^2, commanded acceleration in each block (0 after the last break).
    v0 : m/s, speed before the first break.
    jerk_time : s, width ``tau`` of the moving-average smoothing (0: none; below 1 ms treated as 0).
    turns : curvature events, see :class:`Turn`.
    segments : descriptive list kept for metadata.
    """

    def __init__(
        self,
        breaks: np.ndarray,
        a_cmd: np.ndarray,
        *,
        v0: float = 0.0,
        jerk_time: float = 0.0,
        turns: tuple[Turn, ...] = (),
        segments: list[dict] | None = None,
    ) -> None:
        b = np.asarray(breaks, dtype=np.float64)
        a = np.asarray(a_cmd, dtype=np.float64)
        if b.ndim != 1 or a.shape != (b.size - 1,) or b.size < 2:
            raise ParameterError("speed profile: need K+1 breaks for K acceleration blocks")
        if np.any(np.diff(b) < 0):
            raise ParameterError("speed profile: breaks must be non-decreasing")
        if not jerk_time >= 0:
            raise ParameterError(f"speed profile: jerk_time must be >= 0, got {jerk_time}")
        self.breaks = b
        self.a_cmd = np.append(a, 0.0)  # block K: after the last break, a = 0
        self.v0 = float(v0)
        # below 1 ms the moving average would only cost precision ((D(t+h) - D(t-h)) / tau)
        self.jerk_time = float(jerk_time) if jerk_time >= 1e-3 else 0.0
        self.turns = tuple(turns)
        self.segments = list(segments or [])
        # cumulative integrals at the breaks: C = int a, D = int C, E = int D (from breaks[0])
        h = np.diff(b)
        n = b.size
        C = np.zeros(n)
        D = np.zeros(n)
        E = np.zeros(n)
        for i in range(n - 1):  # K is small (tens of blocks)
            ai, s = a[i], h[i]
            C[i + 1] = C[i] + ai * s
            D[i + 1] = D[i] + C[i] * s + ai * s * s / 2.0
            E[i + 1] = E[i] + D[i] * s + C[i] * s * s / 2.0 + ai * s**3 / 6.0
        self._C, self._D, self._E = C, D, E
        self._x_off = self._cum(np.array([b[0] + self.jerk_time / 2.0]), 3)[0]

    @property
    def t0(self) -> float:
        """Time of the first break (s); distance is counted from here."""
        return float(self.breaks[0])

    @property
    def t_end(self) -> float:
        """Time of the last break (s)."""
        return float(self.breaks[-1])

    @classmethod
    def from_samples(cls, t: np.ndarray, v: np.ndarray) -> SpeedProfile:
        """Profile through sampled speeds, linear between samples (piecewise-constant accel)."""
        t = np.asarray(t, dtype=np.float64)
        v = np.asarray(v, dtype=np.float64)
        if t.shape != v.shape or t.size < 2 or np.any(np.diff(t) <= 0):
            raise ParameterError("speed profile: need increasing t and v of the same length >= 2")
        return cls(t, np.diff(v) / np.diff(t), v0=float(v[0]), jerk_time=0.0)

    def with_turns(self, turns: tuple[Turn, ...]) -> SpeedProfile:
        """Same speed profile with the given turns."""
        return SpeedProfile(self.breaks, self.a_cmd[:-1], v0=self.v0, jerk_time=self.jerk_time,
                            turns=tuple(turns), segments=self.segments)

    # -- exact evaluation ---------------------------------------------------------------------
    def _cum(self, t: np.ndarray, order: int) -> np.ndarray:
        """``int^order a_cmd`` from breaks[0] to t; order 1 -> C, 2 -> D, 3 -> E."""
        return self._cums(t, order)[order]

    def _cums(self, t: np.ndarray, top: int) -> list[np.ndarray]:
        """``[a_cmd, C, D, E][:top + 1]`` at t (0 before breaks[0]), one block search."""
        t = np.asarray(t, dtype=np.float64)
        b = self.breaks
        i = np.searchsorted(b, t, side="right") - 1
        before = i < 0
        i = np.maximum(i, 0)
        s = np.where(before, 0.0, t - b[i])
        a = np.where(before, 0.0, self.a_cmd[i])
        out = [a]
        if top >= 1:
            C = self._C[i]
            out.append(C + a * s)
        if top >= 2:
            D = self._D[i]
            out.append(D + s * (C + a * s / 2.0))
        if top >= 3:
            out.append(self._E[i] + s * (D + s * (C / 2.0 + a * s / 6.0)))
        return out

    def _smoothed(self, t: np.ndarray, order: int) -> np.ndarray:
        tau = self.jerk_time
        if tau == 0.0:
            return self._cum(t, order - 1)
        h = tau / 2.0
        return (self._cum(t + h, order) - self._cum(t - h, order)) / tau

    def accel(self, t: np.ndarray) -> np.ndarray:
        """Longitudinal acceleration dv/dt (m/s^2); 0 wherever the vehicle stands still."""
        t = np.asarray(t, dtype=np.float64)
        return np.where(self.speed(t) > 0.0, self._smoothed(t, 1), 0.0)

    def speed(self, t: np.ndarray) -> np.ndarray:
        """Speed (m/s), >= 0; exactly 0 while stopped (rounding below 1e-9 m/s snapped to 0)."""
        v = self.v0 + self._smoothed(np.asarray(t, dtype=np.float64), 2)
        return np.where(v < 1e-9, 0.0, v)

    def distance(self, t: np.ndarray) -> np.ndarray:
        """Distance travelled since ``t0`` (m)."""
        t = np.asarray(t, dtype=np.float64)
        if self.jerk_time == 0.0:
            return self.v0 * (t - self.t0) + self._cum(t, 2)
        h = self.jerk_time / 2.0
        e = self._cum(t + h, 3) - self._cum(t - h, 3) - self._x_off
        return self.v0 * (t - self.t0) + e / self.jerk_time

    def _speed_distance(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(speed(t), distance(t))`` sharing the block searches."""
        if self.jerk_time == 0.0:
            return self.speed(t), self.distance(t)
        h = self.jerk_time / 2.0
        up = self._cums(t + h, 3)
        dn = self._cums(t - h, 3)
        tau = self.jerk_time
        v = self.v0 + (up[2] - dn[2]) / tau
        x = self.v0 * (t - self.t0) + (up[3] - dn[3] - self._x_off) / tau
        return np.where(v < 1e-9, 0.0, v), x

    def curvature(self, t: np.ndarray) -> np.ndarray:
        """Path curvature kappa (1/m), sum of the turns' sin^2 windows."""
        t = np.asarray(t, dtype=np.float64)
        k = np.zeros_like(t)
        for turn in self.turns:
            s = (t - turn.t_start) / turn.duration
            inside = (s > 0.0) & (s < 1.0)
            k = k + np.where(inside, turn.kappa_peak * np.sin(np.pi * s) ** 2, 0.0)
        return k

    def yaw_rate(self, t: np.ndarray) -> np.ndarray:
        """Yaw rate kappa * v (rad/s), positive turning left."""
        return self.curvature(t) * self.speed(t)

    def crossing_times(self, targets: np.ndarray, t_grid: np.ndarray) -> np.ndarray:
        """Times at which the distance first reaches each of the increasing ``targets`` (m).

        Bracketed on ``t_grid`` (where the sampled distance is monotone), then refined by
        Newton steps on the exact ``x(t)`` (derivative ``v``), kept inside the bracket.
        Targets beyond the grid's last distance are dropped.
        """
        targets = np.asarray(targets, dtype=np.float64)
        x = np.maximum.accumulate(self.distance(t_grid))
        targets = targets[(targets > x[0]) & (targets <= x[-1])]
        if targets.size == 0:
            return targets
        j = np.searchsorted(x, targets, side="left")  # x[j-1] < target <= x[j]
        lo, hi = t_grid[j - 1], t_grid[j]
        xl, xh = x[j - 1], x[j]
        frac = (targets - xl) / np.where(xh > xl, xh - xl, 1.0)
        tt = lo + frac * (hi - lo)
        for _ in range(3):  # quadratic convergence from a 1/fs bracket
            v, x_t = self._speed_distance(tt)
            step = np.where(v > 0.0, (x_t - targets) / np.where(v > 0.0, v, 1.0), 0.0)
            tt = np.clip(tt - step, lo, hi)
        return tt


# -- building profiles from segments ---------------------------------------------------------
def build_profile(
    segments: list[Segment] | tuple[Segment, ...],
    *,
    v0: float = 0.0,
    t0: float = 0.0,
    accel: float = 1.0,
    decel: float = 2.0,
    jerk_time: float = 0.5,
    turns: tuple[Turn, ...] = (),
) -> SpeedProfile:
    """Turn a list of segments into an exact :class:`SpeedProfile`.

    ``accel`` / ``decel`` (m/s^2) are the default magnitudes for speed changes; ``jerk_time`` (s)
    the ramp time of every acceleration change (see the module docstring). A cruise or stop shorter
    than ``jerk_time`` is allowed but its plateau is eaten by the neighbouring ramps. Segments
    are laid end to end from ``t0 + jerk_time / 2`` (a hold at ``v0`` first), so that the
    smoothing ramps never reach before ``t0`` and ``speed(t0) == v0`` exactly.
    """
    if not segments:
        raise ParameterError("speed profile: no segments")
    v = float(v0)
    # a hold of jerk_time/2 first, so the smoothing does not reach before t0: v(t0) = v0 exactly
    t = float(t0) + jerk_time / 2.0
    breaks = [float(t0), t]
    acc: list[float] = [0.0]
    meta: list[dict] = []
    for k, seg in enumerate(segments):
        where = f"segment {k} ('{seg.kind}')"
        if seg.kind not in SEGMENT_KINDS:
            raise ParameterError(f"{where}: unknown kind (choose from {', '.join(SEGMENT_KINDS)})")
        if seg.kind in ("cruise", "stop"):
            if seg.duration is None or not seg.duration >= 0:
                raise ParameterError(f"{where}: needs a duration >= 0 s")
            if seg.kind == "stop" and v != 0.0:
                raise ParameterError(f"{where}: vehicle is at {v:.3g} m/s; brake to 0 first")
            a, dur, v_end = 0.0, float(seg.duration), v
        else:
            if seg.kind == "start" and v != 0.0:
                raise ParameterError(f"{where}: vehicle is at {v:.3g} m/s, not at rest")
            target = 0.0 if (seg.kind == "brake" and seg.speed is None) else seg.speed
            if target is None or not target >= 0:
                raise ParameterError(f"{where}: needs a target speed >= 0 m/s")
            dv = float(target) - v
            if (seg.kind == "brake" and dv > 0) or (seg.kind != "brake" and dv < 0):
                raise ParameterError(
                    f"{where}: target {target:.3g} m/s is the wrong way from {v:.3g} m/s"
                )
            if seg.duration is not None:
                if not seg.duration > 0:
                    raise ParameterError(f"{where}: duration must be > 0 s")
                dur = float(seg.duration)
                a = dv / dur
            else:
                mag = seg.accel if seg.accel is not None else (decel if dv < 0 else accel)
                if not mag > 0:
                    raise ParameterError(f"{where}: acceleration must be > 0 m/s^2")
                dur = abs(dv) / mag
                a = np.sign(dv) * mag
            v_end = float(target)
        meta.append({"kind": seg.kind, "t_start": t, "t_end": t + dur, "v_end": v_end})
        t += dur
        breaks.append(t)
        acc.append(float(a))
        v = v_end
    return SpeedProfile(
        np.array(breaks), np.array(acc), v0=v0, jerk_time=jerk_time, turns=turns, segments=meta
    )
