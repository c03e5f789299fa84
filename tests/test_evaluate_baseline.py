"""``vibrospeed evaluate --baseline``: every estimate scored beside the plain 3 s STFT harmonic
sum on the recording it was made from (:func:`vibrospeed.eval.baseline.stft_track`)."""

import json
import re

import numpy as np
import pytest

from cli_runner import one_line_error as _err
from cli_runner import run as _run
from vibrospeed import io, sim
from vibrospeed.eval.baseline import stft_harmonic_sum, stft_track
from vibrospeed.eval.metrics import evaluate
from vibrospeed.signal import prefilter as pf
from vibrospeed.types import Recording, Track

SHARE = re.compile(r"share within max\(2 rad/s, 10 %\): estimate ([\d.]+)% vs plain STFT "
                   r"([\d.]+)%( \(the estimate loses to the plain baseline here\))?")


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """A 20 s cart drive on disk and as read back."""
    path = tmp_path_factory.mktemp("baseline") / "cart.csv"
    io.write(sim.simulate("cart", seed=1, duration=20), path)
    return path, io.read(path)


def _estimate(rec, path, out, params, *, t_shift=0.0, wheel_radius=0.08):
    """An estimate file made from ``path``: the truth plus a 3 rad/s error on every fifth
    sample (so that the plain STFT beats it somewhere), with ``params`` in its sidecar."""
    w = rec["omega_true"].copy()
    w[::5] += 3.0
    track = Track.from_omega(rec.t + t_shift, w, np.full(w.size, 0.5), method="test",
                             params=params, wheel_radius=wheel_radius)
    io.write_track(track, out, input_path=path)
    return out


def _independent(rec, lo, hi, causal, r=0.08):
    """The benchmarks' baseline (benchmarks/robustness: stft / stft-causal) scored directly."""
    y = pf.apply(pf.design("thesis-hp", rec.fs), np.nan_to_num(rec["ay"]))
    om = stft_harmonic_sum(y, 1.0 / rec.fs, lo, hi, causal=causal)
    return om, evaluate(Track.from_omega(rec.t, om, wheel_radius=r), rec)


def test_printed_share_and_json_equal_the_benchmarks_baseline_scored_directly(drive, tmp_path):
    path, rec = drive
    est = _estimate(rec, path, tmp_path / "est.csv",
                    {"axis": "y", "omega_min": 2.0, "omega_max": 30.0, "smooth": "fb"})
    res = _run("evaluate", est, "--truth", path, "--baseline", path, "--json",
               tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    assert "STFT 3 s" in res.stdout and "2-30 rad/s, offline" in res.stderr
    _, ref = _independent(rec, 2.0, 30.0, causal=False)
    m_est = evaluate(io.read_track(est), rec)
    got = SHARE.search(res.stdout)
    assert got, res.stdout
    assert float(got[1]) == pytest.approx(100 * m_est.ok_share, abs=0.05)
    assert float(got[2]) == pytest.approx(100 * ref.ok_share, abs=0.05)
    # a fifth of the samples 3 rad/s off: below the baseline's share, and said so
    assert m_est.ok_share < ref.ok_share and got[3]
    doc = json.loads((tmp_path / "m.json").read_text())
    assert set(doc["baseline"]) == set(doc) - {"baseline"}
    assert doc["baseline"]["ok_share"] == pytest.approx(ref.ok_share, rel=1e-12)
    assert doc["baseline"]["rmse"] == pytest.approx(ref.rmse, rel=1e-12)
    assert doc["baseline"]["rmse_speed"] == pytest.approx(ref.rmse_speed, rel=1e-12)
    assert doc["baseline"]["coverage"] is None and doc["ok_share"] == m_est.ok_share


@pytest.mark.parametrize("causal_param", [{"smooth": "none"}, {"online": True}])
def test_a_causal_estimate_is_compared_with_the_causal_baseline(drive, tmp_path,
                                                                causal_param):
    path, rec = drive
    est = _estimate(rec, path, tmp_path / "est.csv",
                    {"axis": "ay", "omega_min": 2.0, "omega_max": 30.0, **causal_param})
    res = _run("evaluate", est, "--truth", path, "--baseline", path, "--json",
               tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    assert "causal" in res.stderr
    causal_om, causal = _independent(rec, 2.0, 30.0, causal=True)
    offline_om, offline = _independent(rec, 2.0, 30.0, causal=False)
    assert np.isnan(causal_om[:299]).all() and not np.isnan(offline_om).any()
    assert causal.rmse != pytest.approx(offline.rmse, rel=1e-3)  # they differ here
    base = json.loads((tmp_path / "m.json").read_text())["baseline"]
    assert base["rmse"] == pytest.approx(causal.rmse, rel=1e-12)
    assert base["n"] == causal.n and base["ok_share"] == pytest.approx(causal.ok_share,
                                                                        rel=1e-12)


def test_a_method_without_a_search_range_gets_the_grids_and_a_note(drive, tmp_path):
    path, rec = drive
    est = _estimate(rec, path, tmp_path / "est.csv", {"axis": "y"})
    res = _run("evaluate", est, "--truth", path, "--baseline", path, "--json",
               tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    assert "no search range" in res.stderr and "default 10-120 rad/s" in res.stderr
    _, ref = _independent(rec, 10.0, 120.0, causal=False)
    base = json.loads((tmp_path / "m.json").read_text())["baseline"]
    assert base["rmse"] == pytest.approx(ref.rmse, rel=1e-12)


def test_a_recording_without_the_axis_is_one_line(drive, tmp_path):
    path, rec = drive
    bare = tmp_path / "bare.csv"
    io.write(Recording(rec.t, {k: rec[k] for k in ("ax", "az", "omega_true")},
                       wheel_radius=0.08), bare)
    est = _estimate(rec, bare, tmp_path / "est.csv", {"axis": "y", "omega_min": 2.0,
                                                      "omega_max": 30.0})
    line = _err(_run("evaluate", est, "--truth", path, "--baseline", bare, "--json",
                     tmp_path / "m.json"))
    assert "channel 'ay' is missing" in line and str(bare) in line
    assert not (tmp_path / "m.json").exists()


def test_a_recording_from_another_time_is_one_line(drive, tmp_path):
    path, rec = drive
    later = tmp_path / "later.csv"  # the truth of the shifted estimate
    io.write(Recording(rec.t + 1000.0, {"omega_true": rec["omega_true"]}), later)
    est = _estimate(rec, path, tmp_path / "est.csv", {"axis": "y"}, t_shift=1000.0)
    line = _err(_run("evaluate", est, "--truth", later, "--baseline", path))
    assert line == (f"vibrospeed: error: {path}: its time span (0-19.99 s) does not overlap "
                    f"the estimate {est} (1000-1019.99 s): --baseline takes the recording the "
                    "estimate was made from")
    other = _estimate(rec, later, tmp_path / "other.csv", {"axis": "y"})
    assert "not from" in _err(_run("evaluate", other, "--truth", path, "--baseline", path))


def test_stft_track_is_the_baseline_as_a_track(drive):
    _, rec = drive
    om, _ = _independent(rec, 2.0, 30.0, causal=False)
    tr = stft_track(rec, axis="y", omega_min=2.0, omega_max=30.0, wheel_radius=0.08)
    assert tr.method == "stft" and np.array_equal(tr.t, rec.t)
    np.testing.assert_array_equal(tr.omega, om)
    np.testing.assert_allclose(tr.speed, 0.08 * om, rtol=1e-15)
    assert np.isnan(tr.omega_lo).all() and np.isnan(tr.omega_hi).all()
    assert np.isnan(stft_track(rec, omega_min=2.0, omega_max=30.0).speed).all()


def test_a_speed_estimate_without_radius_gets_a_speed_baseline_on_y(drive, tmp_path):
    # gps-riss: speeds only, its axis the longitudinal one; the baseline reads ay, converted
    # with the recording's radius (0.08 m), and both are scored in m/s
    path, rec = drive
    est = tmp_path / "sp.csv"
    io.write_track(Track.from_speed(rec.t, 1.05 * rec["speed_true"], method="gps-riss",
                                    params={"axis": "x"}), est, input_path=path)
    res = _run("evaluate", est, "--truth", path, "--baseline", path, "--json",
               tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    assert "default vibration axis y" in res.stderr and "share within max(2 m/s" in res.stdout
    y = pf.apply(pf.design("thesis-hp", rec.fs), np.nan_to_num(rec["ay"]))
    om = stft_harmonic_sum(y, 1.0 / rec.fs, 10.0, 120.0)
    ref = evaluate(Track.from_speed(rec.t, 0.08 * om), rec)
    base = json.loads((tmp_path / "m.json").read_text())["baseline"]
    assert ref.unit == base["unit"] == "m/s"
    assert base["rmse"] == pytest.approx(ref.rmse, rel=1e-12) and base["n"] == ref.n


def test_a_recording_shorter_than_the_window_is_one_line(drive, tmp_path):
    # 2.5 s of a moving drive: no 3 s window fits, every baseline value is NaN (the table's
    # STFT column was nan throughout, the share "nan%")
    path, rec = drive
    k = (rec.t >= 10.0) & (rec.t < 12.5)
    short = tmp_path / "short.csv"
    io.write(Recording(rec.t[k], {c: rec[c][k] for c in ("ax", "ay", "az", "omega_true")},
                       wheel_radius=0.08), short)
    est = _estimate(io.read(short), short, tmp_path / "est.csv",
                    {"axis": "y", "omega_min": 2.0, "omega_max": 30.0})
    assert _run("evaluate", est, "--truth", short).exit_code == 0  # scored without it
    line = _err(_run("evaluate", est, "--truth", short, "--baseline", short, "--json",
                     tmp_path / "m.json"))
    assert line == (f"vibrospeed: error: {short}: 2.49 s is shorter than the STFT baseline's "
                    "3 s window: no baseline to score (leave out --baseline)")
    assert not (tmp_path / "m.json").exists()


def test_a_lagged_estimate_is_compared_with_the_baseline_of_the_same_delay(drive, tmp_path):
    """``smooth=lag``: the STFT values from the windows ended ``lag`` s after each sample (a
    device that reports that late), neither the causal nor the offline ones."""
    path, rec = drive
    est = _estimate(rec, path, tmp_path / "est.csv",
                    {"axis": "y", "omega_min": 2.0, "omega_max": 30.0, "smooth": "lag",
                     "lag": 0.8})
    res = _run("evaluate", est, "--truth", path, "--baseline", path, "--json",
               tmp_path / "m.json")
    assert res.exit_code == 0, res.output
    assert "with the estimate's 0.8 s lag" in res.stderr
    y = pf.apply(pf.design("thesis-hp", rec.fs), np.nan_to_num(rec["ay"]))
    om = stft_harmonic_sum(y, 1.0 / rec.fs, 2.0, 30.0, causal=True, lag=0.8)
    want = evaluate(Track.from_omega(rec.t, om, wheel_radius=0.08), rec)
    base = json.loads((tmp_path / "m.json").read_text())["baseline"]
    assert base["rmse"] == pytest.approx(want.rmse, rel=1e-12) and base["n"] == want.n
    causal_om, _ = _independent(rec, 2.0, 30.0, causal=True)
    assert np.isnan(om).sum() == np.isnan(causal_om).sum() - 80  # 0.8 s earlier


def test_the_lagged_baseline_is_the_latest_window_ended_then_or_the_offline_value():
    """Brute force per sample: the offline value where the windows it interpolates have ended
    within the lag, else the value of the latest window ended by then."""
    rng = np.random.default_rng(3)
    t = np.arange(0, 12, 0.01)
    ph = np.cumsum(30 + 2.0 * t) * 0.01
    y = np.sin(ph) + 0.5 * np.sin(2 * ph) + 0.3 * rng.normal(size=t.size)
    off = stft_harmonic_sum(y, 0.01, 5.0, 60.0)
    L, hop = 300, 25
    starts = np.arange(0, t.size - L + 1, hop)
    vals = {s: stft_harmonic_sum(y[s:s + L], 0.01, 5.0, 60.0)[0] for s in starts}
    for lag in (0.0, 0.4, 1.5, 1.74, 1.76, 4.0):
        got = stft_harmonic_sum(y, 0.01, 5.0, 60.0, causal=True, lag=lag)
        ahead = int(np.floor(lag / 0.01 + 1e-9))
        for i in range(0, t.size, 7):
            ended = [s for s in starts if s + L - 1 <= i + ahead]
            nxt = [s for s in starts if s + L // 2 > i]
            need = nxt[0] if nxt else starts[-1]
            if need + L - 1 <= i + ahead:
                assert got[i] == off[i]
            elif ended:
                assert got[i] == vals[ended[-1]]
            else:
                assert np.isnan(got[i])
    with pytest.raises(ValueError, match="lag must be"):
        stft_harmonic_sum(y, 0.01, 5.0, 60.0, lag=1.0)  # a lag is a causal device's
