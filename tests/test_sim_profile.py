"""Speed profiles: exact evaluation against a dense numerical reference, validation, invariants."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.errors import ParameterError
from vibrospeed.sim import Segment, SpeedProfile, Turn, build_profile

SEGS = [
    Segment("stop", duration=1.0),
    Segment("start", speed=6.0, accel=1.5),
    Segment("cruise", duration=3.0),
    Segment("accelerate", speed=9.0, duration=2.0),
    Segment("brake", speed=4.0, accel=3.0),
    Segment("cruise", duration=2.0),
    Segment("brake"),
    Segment("stop", duration=2.0),
    Segment("start", speed=2.0),
]


def _dense_reference(prof: SpeedProfile, tau: float, dt: float = 1e-4):
    """Brute force: sample a_cmd densely, moving-average it, integrate twice (trapezoid)."""
    t = np.arange(prof.t0 - 1.0, prof.t_end + 2.0, dt)
    blocks = np.searchsorted(prof.breaks, t, side="right") - 1
    a_cmd = np.where(blocks < 0, 0.0, prof.a_cmd[np.clip(blocks, 0, None)])
    w = int(round(tau / dt))
    a = np.convolve(a_cmd, np.ones(w) / w, mode="same")
    v = prof.v0 + np.concatenate(([0.0], np.cumsum((a[1:] + a[:-1]) * dt / 2)))
    x = np.concatenate(([0.0], np.cumsum((v[1:] + v[:-1]) * dt / 2)))
    x -= np.interp(prof.t0, t, x)
    return t, a, v, x


def test_exact_profile_matches_dense_reference():
    tau = 0.5
    prof = build_profile(SEGS, jerk_time=tau, accel=1.0, decel=2.0)
    t_ref, a_ref, v_ref, x_ref = _dense_reference(prof, tau)
    t = np.arange(0.0, prof.t_end + 1.0, 0.01)
    np.testing.assert_allclose(prof.speed(t), np.interp(t, t_ref, v_ref), atol=2e-3)
    np.testing.assert_allclose(prof.distance(t), np.interp(t, t_ref, x_ref), atol=5e-3)
    moving = prof.speed(t) > 0
    np.testing.assert_allclose(prof.accel(t)[moving], np.interp(t, t_ref, a_ref)[moving],
                               atol=2e-2)


def test_segment_targets_reached_and_stops_exact():
    tau = 0.4
    prof = build_profile(SEGS, jerk_time=tau)
    for seg in prof.segments:
        # after the ramp (tau/2 past the segment end) the target speed holds exactly
        if seg["kind"] in ("cruise", "stop"):
            mid = np.linspace(seg["t_start"] + tau / 2, seg["t_end"] - tau / 2, 7)
            np.testing.assert_allclose(prof.speed(mid), seg["v_end"], atol=1e-9)
            assert np.all(prof.accel(mid) == 0.0)
    stops = [s for s in prof.segments if s["kind"] == "stop"]
    for s in stops:
        mid = np.linspace(s["t_start"] + tau / 2, s["t_end"] - tau / 2, 7)
        assert np.all(prof.speed(mid) == 0.0)
    assert prof.speed(np.array([prof.t_end + 5.0]))[0] == pytest.approx(2.0)
    assert prof.speed(np.array([0.0]))[0] == 0.0


def test_jerk_limited():
    tau = 0.5
    prof = build_profile(SEGS, jerk_time=tau)
    t = np.arange(0.0, prof.t_end + 1.0, 1e-3)
    jerk = np.diff(prof.accel(t)) / 1e-3
    max_step = np.max(np.abs(np.diff(np.concatenate(([0.0], prof.a_cmd)))))
    assert np.max(np.abs(jerk)) <= max_step / tau * (1 + 1e-6)


def test_from_samples_round_trip():
    t = np.linspace(0.0, 10.0, 41)
    v = 5.0 + np.sin(t)
    prof = SpeedProfile.from_samples(t, v)
    np.testing.assert_allclose(prof.speed(t), v, atol=1e-12)
    x_trap = np.concatenate(([0.0], np.cumsum((v[1:] + v[:-1]) * np.diff(t) / 2)))
    np.testing.assert_allclose(prof.distance(t), x_trap, atol=1e-10)


def test_turn_curvature_and_yaw():
    prof = build_profile([Segment("cruise", duration=20.0)], v0=10.0, jerk_time=0.0)
    prof = prof.with_turns((Turn(5.0, 4.0, 0.02),))
    t = np.array([4.0, 7.0, 9.5])
    np.testing.assert_allclose(prof.curvature(t), [0.0, 0.02, 0.0], atol=1e-12)
    np.testing.assert_allclose(prof.yaw_rate(t), 10.0 * prof.curvature(t))
    # heading change = int kappa v dt = kappa_peak * v * duration / 2
    tt = np.linspace(0, 20, 200001)
    heading = np.trapezoid(prof.yaw_rate(tt), tt)
    assert heading == pytest.approx(0.02 * 10.0 * 4.0 / 2, rel=1e-6)


@pytest.mark.parametrize(
    ("segs", "msg"),
    [
        ([Segment("start", speed=3.0), Segment("stop", duration=1.0)], "brake to 0 first"),
        ([Segment("cruise", duration=1.0)], None),
        ([Segment("fly", duration=1.0)], "unknown kind"),
        ([Segment("start", speed=3.0), Segment("start", speed=4.0)], "not at rest"),
        ([Segment("start", speed=3.0), Segment("brake", speed=5.0)], "wrong way"),
        ([Segment("cruise")], "needs a duration"),
    ],
)
def test_profile_errors(segs, msg):
    if msg is None:
        build_profile(segs)
        return
    with pytest.raises(ParameterError, match=msg):
        build_profile(segs)


_seg = st.tuples(st.sampled_from(["cruise", "change", "stopgo"]), st.floats(0.5, 10.0),
                 st.floats(0.5, 30.0), st.floats(0.3, 4.0))


@settings(max_examples=40, deadline=None)
@given(st.lists(_seg, min_size=1, max_size=8), st.floats(0.0, 1.0))
def test_random_profiles_invariants(items, tau):
    segs = [Segment("start", speed=5.0)]
    v = 5.0
    for kind, dur, speed, acc in items:
        if kind == "cruise":
            segs.append(Segment("cruise", duration=dur))
        elif kind == "change":
            segs.append(Segment("accelerate" if speed >= v else "brake", speed=speed, accel=acc))
            v = speed
        else:
            segs += [Segment("brake", accel=acc), Segment("stop", duration=dur),
                     Segment("start", speed=speed, accel=acc)]
            v = speed
    prof = build_profile(segs, jerk_time=tau)
    t = np.linspace(0.0, prof.t_end + tau + 1.0, 4000)
    sp = prof.speed(t)
    assert np.all(sp >= 0.0)
    assert sp[-1] == pytest.approx(v, abs=1e-8)
    x = prof.distance(t)
    # non-decreasing up to the rounding of (E(t + h) - E(t - h)) / tau
    assert np.all(np.diff(x) >= -1e-13 * (1 + x[-1]) / max(prof.jerk_time, 1e-3))
    targets = np.linspace(x[0], x[-1], 50)[1:-1]
    tc = prof.crossing_times(targets, t)
    np.testing.assert_allclose(prof.distance(tc), targets[: tc.size], atol=1e-8)
