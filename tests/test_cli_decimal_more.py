"""``--decimal ,`` beyond one recording: ``evaluate --truth`` reads a truth CSV written with a
decimal comma to the same metrics its decimal-point twin gives, ``report`` and ``plot --truth``
to the same numbers (beside a CSV or a Parquet recording; each refuses it in one line without
the flag); a batch over a folder of a decimal-comma CSV and a Parquet recording applies
the mark to the CSV alone, each estimate the one ``vibrospeed estimate`` writes for it, and says
so once."""

import json

import numpy as np
import pytest

from cli_runner import one_line_error, run
from vibrospeed import io

RANGE = ("-p", "omega_min=2", "-p", "omega_max=30")
COLUMNS = ("t", "ay", "omega_true")


def _write(path, rec, sep, decimal):
    """``rec``'s :data:`COLUMNS` as a CSV with ``sep`` between fields and ``decimal`` for the
    point, each float as ``repr`` writes it (it reads back to the same float64)."""
    cols = [rec.t if c == "t" else rec[c] for c in COLUMNS]
    lines = [sep.join(COLUMNS)]
    lines += [sep.join(repr(float(v)).replace(".", decimal) for v in row)
              for row in zip(*cols, strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    """A 10 s simulated cart drive as a ',' CSV with '.', the same as a ';' CSV with ',', as
    Parquet, and the estimate of each (the ',' one read with --decimal ,)."""
    from vibrospeed.sim import simulate

    d = tmp_path_factory.mktemp("decimal_more")
    rec = simulate("cart", seed=4, duration=10)
    out = {"dir": d, "dot": d / "dot.csv", "eu": d / "eu.csv", "pq": d / "pq.parquet"}
    _write(out["dot"], rec, ",", ".")
    _write(out["eu"], rec, ";", ",")
    io.write(rec, out["pq"])
    for kind, extra in (("dot", ()), ("eu", ("--decimal", ",")), ("pq", ())):
        out[f"est_{kind}"] = d / f"est_{kind}.csv"
        res = run("estimate", out[kind], *RANGE, "-o", out[f"est_{kind}"], *extra)
        assert res.exit_code == 0, res.output
    out["est"] = out["est_dot"]
    return out


def test_a_decimal_comma_truth_scores_as_its_decimal_point_twin(drive):
    d, est = drive["dir"], drive["est"]
    docs = {}
    for kind, extra in (("dot", ()), ("eu", ("--decimal", ","))):
        res = run("evaluate", est, "--truth", drive[kind], "--json", d / f"{kind}.json", *extra)
        assert res.exit_code == 0, res.output
        docs[kind] = json.loads((d / f"{kind}.json").read_text())
    assert docs["dot"]["n"] > 500  # most of the 1000 samples move: a real comparison
    assert docs["eu"] == docs["dot"]
    # the same numbers as the library's metrics on the truth read by the canonical reader
    from vibrospeed.eval.metrics import evaluate

    m = evaluate(io.read_track(est), io.read(drive["dot"]))
    assert docs["eu"]["rmse"] == pytest.approx(m.rmse, rel=1e-12)
    # with --baseline beside a Parquet truth, the flag is the CSV baseline's: the truth's
    # reader is not given it
    res = run("evaluate", drive["est_eu"], "--truth", drive["pq"], "--baseline", drive["eu"],
              "--decimal", ",")
    assert res.exit_code == 0, res.output
    assert "STFT 3 s" in res.stdout
    # and beside a Parquet baseline, the flag is the CSV truth's: the same scores as with the
    # decimal-point truth
    both = {}
    for kind, extra in (("dot", ()), ("eu", ("--decimal", ","))):
        res = run("evaluate", drive["est_pq"], "--truth", drive[kind], "--baseline",
                  drive["pq"], "--json", d / f"b_{kind}.json", *extra)
        assert res.exit_code == 0, res.output
        both[kind] = json.loads((d / f"b_{kind}.json").read_text())
    assert both["eu"] == both["dot"]


def test_a_decimal_comma_truth_without_the_flag_is_one_line(drive):
    line = one_line_error(run("evaluate", drive["est"], "--truth", drive["eu"]))
    assert line.startswith(f"vibrospeed: error: {drive['eu']}")
    assert "give --decimal ," in line
    # a mark for a Parquet truth (no baseline to read) means nothing: refused, not ignored
    line = one_line_error(run("evaluate", drive["est"], "--truth", drive["pq"],
                              "--decimal", ","))
    assert line == (f"vibrospeed: error: {drive['pq']}: format 'parquet' does not take "
                    "option 'decimal'")


def test_a_mixed_batch_applies_the_mark_to_its_csv_files(drive):
    d = drive["dir"]
    folder = d / "fleet"
    folder.mkdir()
    for kind in ("eu", "pq"):
        (folder / drive[kind].name).write_bytes(drive[kind].read_bytes())
    want = {kind: drive[f"est_{kind}"].read_text() for kind in ("eu", "pq")}
    assert want["eu"] != want["pq"]  # the Parquet has the wheel radius: speeds the CSV lacks
    out = d / "out"
    res = run("batch", folder, "-o", out, "-j", 1, *RANGE, "--decimal", ",")
    assert res.exit_code == 0, res.output
    import pandas as pd

    df = pd.read_csv(out / "summary.csv")
    assert sorted(zip(df["format"], df["status"], strict=True)) == [("csv", "ok"),
                                                                     ("parquet", "ok")]
    for _, row in df.iterrows():  # each estimate is the single-file run's, byte for byte
        kind = "eu" if row["format"] == "csv" else "pq"
        assert (out / row["output"]).read_text() == want[kind]
    notes = [ln for ln in res.stderr.splitlines() if "--decimal" in ln]
    assert notes == ["note: --decimal ',' applies to the CSV recordings only: 1 recording of "
                     "another format (parquet 1) read without it"]
    # run again: both up to date (the Parquet's sidecar records no mark)
    res = run("batch", folder, "-o", out, "-j", 1, *RANGE, "--decimal", ",")
    assert res.exit_code == 0 and "(0 ok, 2 skipped, 0 error)" in res.stderr, res.output
    # a format named for all of them that has no decimal mark: refused before any is read
    line = one_line_error(run("batch", folder, "-o", d / "never", "--format", "parquet",
                              "--decimal", ","))
    assert line == ("vibrospeed: error: format 'parquet' does not take option 'decimal' (a "
                    "decimal mark is for the CSV formats)")
    assert not (d / "never").exists()


@pytest.fixture
def drawn(monkeypatch):
    """The page and plot writers of ``report`` and ``plot`` replaced by a recorder of what they
    are given (the recording and the truth), so a test compares those numbers without drawing
    (a drawing takes a second and is the same function of them)."""
    import vibrospeed.eval.plot as plot_mod
    import vibrospeed.eval.report as report_mod

    seen = []

    def record(path, rec, track, **kw):
        seen.append((rec, kw.get("truth")))

    monkeypatch.setattr(report_mod, "write_report", record)
    monkeypatch.setattr(plot_mod, "plot_track", record)
    return seen


@pytest.mark.parametrize("command", ["report", "plot"])
def test_report_and_plot_read_a_decimal_comma_truth_as_its_twin(drive, drawn, command):
    d = drive["dir"]
    ref = io.read(drive["pq"])  # the simulated drive through the Parquet reader, not a CSV one
    cases = [  # recording, its estimate, truth, extra flags
        ("dot", "dot", ()),
        ("eu", "eu", ("--decimal", ",")),
        ("pq", "eu", ("--decimal", ",")),  # the mark for the CSV truth alone
        ("eu", "pq", ("--decimal", ",")),  # the mark for the CSV recording alone
    ]
    for rec_kind, truth_kind, extra in cases:
        res = run(command, drive[rec_kind], "--estimate", drive[f"est_{rec_kind}"],
                  "--truth", drive[truth_kind], "-o", d / f"never.{command}.png", *extra)
        assert res.exit_code == 0, (rec_kind, truth_kind, res.output)
    assert len(drawn) == len(cases)
    for (rec, truth), (rec_kind, truth_kind, _) in zip(drawn, cases, strict=True):
        assert np.array_equal(truth.t, ref.t), (rec_kind, truth_kind)
        assert np.array_equal(truth["omega_true"], ref["omega_true"]), (rec_kind, truth_kind)
        assert np.array_equal(rec["ay"], ref["ay"]), (rec_kind, truth_kind)


@pytest.mark.parametrize("command", ["report", "plot"])
def test_report_and_plot_refuse_a_decimal_comma_truth_in_one_line(drive, drawn, command):
    d = drive["dir"]
    line = one_line_error(run(command, drive["dot"], "--estimate", drive["est_dot"],
                              "--truth", drive["eu"], "-o", d / "never.png"))
    assert line.startswith(f"vibrospeed: error: {drive['eu']}")
    assert "give --decimal ," in line
    # a mark where neither the recording nor the truth is a CSV means nothing: refused
    line = one_line_error(run(command, drive["pq"], "--estimate", drive["est_pq"],
                              "--truth", drive["pq"], "-o", d / "never.png", "--decimal", ","))
    assert line == (f"vibrospeed: error: {drive['pq']}: format 'parquet' does not take "
                    "option 'decimal'")
    assert drawn == []


def test_the_help_says_what_the_mark_applies_to():
    from typer.testing import CliRunner

    from vibrospeed.cli.app import app

    def text(command):
        res = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "300"})
        assert res.exit_code == 0, res.output
        return " ".join(res.stdout.split())  # the help, its line breaks undone

    for command in ("report", "plot"):
        assert ("decimal mark of the numbers of the CSV inputs (the recording and the --truth "
                "file, whichever is a CSV)") in text(command)
    assert ("With --decimal , the mark applies to the CSV recordings only: those of other "
            "formats (Parquet, ROS bags, phone exports) are read without it, said in one note "
            "at the end.") in text("batch")
