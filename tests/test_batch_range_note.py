"""``vibrospeed batch`` gives the note ``vibrospeed estimate`` prints where the default wheel
speed range was searched, word for word, in the summary's note column (and once on stderr)."""

import numpy as np
import pandas as pd

from cli_runner import run as _run
from vibrospeed import io, sim
from vibrospeed.eval.metrics import NO_EVIDENCE_NOTE
from vibrospeed.types import Recording

#: the grid's default range 10-120 rad/s; on the cart's r = 0.08 m: 0.08 * 10 = 0.8 m/s and
#: 0.08 * 120 = 9.6 m/s
ADVICE = ("the default: for another vehicle give its range, v / r (a cart or forklift on "
          "r = 0.08 m: -p omega_min=2 -p omega_max=30)")
CART = f"searched wheel speeds 10-120 rad/s (0.8-9.6 m/s at wheel radius 0.08 m), {ADVICE}"
NOISE = f"searched wheel speeds 10-120 rad/s, {ADVICE}"  # no radius: rad/s alone


def _joined(text: str) -> str:
    """Console output with its wrapped lines joined back."""
    return " ".join(text.split())


def test_batch_gives_estimates_default_range_note(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    io.write(sim.simulate("cart", seed=2, duration=8), src / "b_cart.csv")
    rng = np.random.default_rng(0)
    n = 8 * 400  # white noise, no wheel radius: no wheel line, no speeds in the note
    io.write(Recording(t=np.arange(n) / 400.0, channels={
        "ax": rng.normal(0.0, 1.0, n), "ay": rng.normal(0.0, 1.0, n),
        "az": 9.81 + rng.normal(0.0, 1.0, n)}), src / "a_noise.csv")
    # what estimate prints for each recording
    for name, want in (("b_cart.csv", CART), ("a_noise.csv", NOISE)):
        res = _run("estimate", src / name, "-m", "grid", "-o", tmp_path / f"{name}.est.csv")
        assert res.exit_code == 0, res.output
        assert f"note: {want}" in _joined(res.stderr), res.stderr
    out = tmp_path / "out"
    for status in ("ok", "skipped"):  # a skipped row says it too (from the sidecar)
        res = _run("batch", src, "-o", out, "-m", "grid", "-j", 1)
        assert res.exit_code == 0, res.output
        summary = pd.read_csv(out / "summary.csv", keep_default_na=False)
        assert list(summary["status"]) == [status, status]
        assert list(summary["note"]) == [f"{NO_EVIDENCE_NOTE}; {NOISE}", CART]
        lines = res.stderr.splitlines()
        assert ("1 drive without a wheel line or GPS while moving: speed numbers left empty "
                "(see the note column)") in lines
        assert f"note: {CART} (1 recording, see the note column)" in lines
        assert f"note: {NOISE} (1 recording, see the note column)" in lines
    # a range given: no note, in estimate or batch
    res = _run("batch", src / "b_cart.csv", "-o", tmp_path / "given", "-m", "grid", "-j", 1,
               "-p", "omega_min=2", "-p", "omega_max=30")
    assert res.exit_code == 0, res.output
    summary = pd.read_csv(tmp_path / "given" / "summary.csv", keep_default_na=False)
    assert list(summary["note"]) == [""] and "searched wheel speeds" not in res.stderr


def test_streamed_estimate_returns_the_parameters_its_sidecar_holds(tmp_path):
    """The streamed path's note is made from what :func:`estimate_file` returns (no sidecar
    read back): the same parameters and radius as the sidecar it wrote."""
    import json

    from vibrospeed.estimators.grid import stream
    from vibrospeed.estimators.params import range_note

    io.write(sim.simulate("cart", seed=3, duration=6), tmp_path / "cart.csv")
    est = tmp_path / "est.csv"
    st = stream.estimate_file(tmp_path / "cart.csv", est, params={}, chunk_rows=500)
    side = json.loads((tmp_path / "est.csv.json").read_text(encoding="utf-8"))
    assert st.params == side["params"] and st.wheel_radius == side["wheel_radius"] == 0.08
    assert (st.params["omega_min"], st.params["omega_max"]) == (10.0, 120.0)
    assert range_note("grid", {}, st.params, st.wheel_radius) == CART
