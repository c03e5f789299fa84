"""The summary numbers of a track given in pieces (a log estimated in blocks) against those of
the whole track (:func:`vibrospeed.eval.metrics.track_summary`, the batch row's)."""

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from vibrospeed.eval.metrics import NO_EVIDENCE_NOTE, SummaryAccumulator, track_summary
from vibrospeed.types import Track


def _track(seed: int, n: int, *, claims: bool, radius) -> Track:
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.02, n))
    omega = rng.uniform(5, 80, n)
    omega[rng.random(n) < 0.1] = np.nan  # gaps, as a NaN-laden log gives
    tr = Track.from_omega(t, omega, np.ones(n), wheel_radius=radius)
    sig = (rng.random(n) < 0.3).astype(float) if claims else np.zeros(n)
    sig[rng.random(n) < 0.05] = np.nan
    tr.extras["has_signal"] = sig
    tr.extras["standstill"] = (rng.random(n) < (0.05 if seed % 3 else 0.0)).astype(float)
    if claims and seed % 2:  # a fuse track says what each sample's speed rests on
        src = rng.integers(0, 4, n).astype(float)
        src[rng.random(n) < 0.05] = np.nan
        tr.extras["source"] = src
    return tr


def _pieces(tr: Track, cuts: list[int]) -> list[Track]:
    edges = [0, *sorted(set(cuts)), len(tr)]
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        if b > a:
            out.append(Track.from_omega(tr.t[a:b], tr.omega[a:b], tr.omega_std[a:b],
                                        wheel_radius=tr.wheel_radius))
            out[-1].extras.update({k: np.asarray(v)[a:b] for k, v in tr.extras.items()})
    return out


def _same(a: dict, b: dict) -> None:
    assert a["note"] == b["note"]
    assert a["source_shares"].keys() == b["source_shares"].keys()
    for k in a["source_shares"]:
        assert math.isclose(a["source_shares"][k], b["source_shares"][k], rel_tol=1e-12)
    for k in ("signal_share", "distance_m", "distance_lo_m", "distance_hi_m", "fitted_radius"):
        assert (math.isnan(a[k]) and math.isnan(b[k])) or math.isclose(a[k], b[k], rel_tol=1e-12)
    for k in ("median_speed", "median_omega"):  # float32 copies in the pieces' sum
        assert (math.isnan(a[k]) and math.isnan(b[k])) or math.isclose(a[k], b[k], rel_tol=1e-6)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 400),
       cuts=st.lists(st.integers(0, 400), max_size=8), claims=st.booleans(),
       radius=st.sampled_from([None, 0.3]))
def test_pieces_give_the_whole_tracks_summary(seed, n, cuts, claims, radius):
    tr = _track(seed, n, claims=claims, radius=radius)
    acc = SummaryAccumulator()
    for piece in _pieces(tr, [c for c in cuts if c < n]):
        acc.add(piece)
    whole = track_summary(tr)
    _same(acc.result(), whole)
    _same(whole, _direct(tr))  # track_summary itself against the plain numpy figures


def _direct(tr: Track) -> dict:
    """The summary from its definition, written out with numpy over the whole track."""
    sig = np.asarray(tr.extras["has_signal"])
    sig = sig[np.isfinite(sig)]
    v, t = tr.speed, tr.t
    ok = np.isfinite(v[:-1]) & np.isfinite(v[1:])

    def integral(x):
        fin = np.isfinite(x[:-1]) & np.isfinite(x[1:])
        return float(np.sum((0.5 * (x[:-1] + x[1:]) * np.diff(t))[fin])) if fin.any() \
            else math.nan

    src = np.asarray(tr.extras.get("source", []), dtype=float)
    src = src[np.isfinite(src)]
    out = {"distance_lo_m": integral(tr.speed_lo), "distance_hi_m": integral(tr.speed_hi),
           "source_shares": {name: float(np.mean(src == k)) for k, name in enumerate(
               ("accelerometer", "gps", "vibration", "standstill"))} if src.size else {},
           "signal_share": float(np.mean(sig > 0.5)) if sig.size else math.nan,
           "median_speed": float(np.median(v[np.isfinite(v)])) if np.isfinite(v).any()
           else math.nan,
           "median_omega": float(np.median(tr.omega[np.isfinite(tr.omega)]))
           if np.isfinite(tr.omega).any() else math.nan,
           "distance_m": float(np.sum((0.5 * (v[:-1] + v[1:]) * np.diff(t))[ok]))
           if ok.any() else math.nan,
           "fitted_radius": math.nan, "note": ""}
    moving = np.nan_to_num(np.asarray(tr.extras["has_signal"])) > 0.5
    standing = np.nan_to_num(np.asarray(tr.extras["standstill"])) > 0.5
    if "source" in tr.extras:  # fuse: GPS (1) or vibration (2) while moving, 3 standing
        src = np.nan_to_num(np.asarray(tr.extras["source"]), nan=0.0)
        moving |= (src == 1) | (src == 2)
        standing |= src == 3
    if not moving.any() and not (moving | standing).all():
        out.update(median_speed=math.nan, median_omega=math.nan, distance_m=math.nan,
                   distance_lo_m=math.nan, distance_hi_m=math.nan, note=NO_EVIDENCE_NOTE)
    return out


def test_no_claim_leaves_the_speed_numbers_empty_as_a_whole_track_does():
    tr = _track(1, 200, claims=False, radius=0.3)
    acc = SummaryAccumulator()
    for piece in _pieces(tr, [50, 120]):
        acc.add(piece)
    got = acc.result()
    assert got["note"] and math.isnan(got["median_speed"]) and math.isnan(got["distance_m"])
    assert got["signal_share"] == 0.0


def test_source_names_follow_fuses_codes():
    from vibrospeed.estimators.fuse.config import (
        SRC_GPS,
        SRC_INERTIAL,
        SRC_STANDSTILL,
        SRC_VIBRATION,
    )
    from vibrospeed.eval.metrics import SOURCE_NAMES

    assert [SOURCE_NAMES[k] for k in (SRC_INERTIAL, SRC_GPS, SRC_VIBRATION, SRC_STANDSTILL)] \
        == ["accelerometer", "gps", "vibration", "standstill"]


def test_summary_line_says_what_the_speed_rests_on_and_the_band_distances():
    from vibrospeed.cli.estimate import summary_line

    base = {"signal_share": 0.25, "median_speed": 12.0, "median_omega": 40.0,
            "distance_m": 1234.4, "distance_lo_m": 1000.2, "distance_hi_m": 1500.7,
            "fitted_radius": math.nan, "source_shares": {}, "note": ""}
    line = summary_line(base)
    assert line.startswith("summary: a wheel line claimed on 25.0 % of the samples (elsewhere")
    assert line.endswith("distance 1234 m (1000-1501 m at the edges of the speed band)")
    fused = {**base, "source_shares": {"accelerometer": 0.0004, "gps": 0.7496,
                                       "vibration": 0.2, "standstill": 0.05}}
    line = summary_line(fused)
    assert line.startswith("summary: speed from GPS on 75.0 %, the wheel line on 20.0 %, the "
                           "accelerometer alone on < 0.1 %, a standstill on 5.0 % of the samples;")
    assert "claimed" not in line and "guess" not in line
    nan_band = {**base, "distance_lo_m": math.nan}
    assert summary_line(nan_band).endswith("distance 1234 m")


def test_a_standstill_alone_does_not_make_the_moving_guesses_measured():
    tr = _track(3, 300, claims=False, radius=0.3)
    tr.extras["standstill"] = np.zeros(300)
    tr.extras["standstill"][:40] = 1.0  # a stop found, no line claimed anywhere
    got = track_summary(tr)
    assert got["note"] == NO_EVIDENCE_NOTE and math.isnan(got["distance_m"])
    assert math.isnan(got["median_speed"]) and math.isnan(got["distance_hi_m"])
    parked = _track(3, 300, claims=False, radius=0.3)
    parked.extras["standstill"] = np.ones(300)  # a standstill everywhere: the 0 m/s measured
    parked.speed[:] = 0.0
    got = track_summary(parked)
    assert got["note"] == "" and got["distance_m"] == 0.0 and got["median_speed"] == 0.0
