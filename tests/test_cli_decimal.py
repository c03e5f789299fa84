"""``--decimal ,``: a ';'-separated European export that writes ``1,25`` read through the
command line (a canonical ``t;ay`` file or a ``--columns`` mapping) gives the estimate the same
numbers written with '.' give; the chunked reader (the streamed long-log path) and the
whole-file reader read the same float64 values; a decimal mark that is also the separator, one
that a mapping file contradicts or one that is neither '.' nor ',' is one line, exit status 2."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cli_runner import one_line_error, run
from vibrospeed import batch, io
from vibrospeed.errors import ParameterError
from vibrospeed.io.chunks import ChunkedRecording

RANGE = ("-p", "omega_min=2", "-p", "omega_max=30")


def _write(path, header, rows, sep, decimal):
    """``rows`` (tuples of floats) under ``header``, each float as ``repr`` writes it (it reads
    back to the same float64) with ``decimal`` for its point."""
    cells = (sep.join(repr(float(v)).replace(".", decimal) for v in row) for row in rows)
    path.write_text(sep.join(header) + "\n" + "".join(c + "\n" for c in cells),
                    encoding="utf-8")


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    """A 10 s simulated cart drive (t, ay) as a canonical CSV with '.', the same as a ';' file
    with ',', and its raw logger form (time in ms, ay in g) both ways; the drive itself (with
    its truth) as ``truth``."""
    from vibrospeed.sim import simulate

    d = tmp_path_factory.mktemp("decimal")
    rec = simulate("cart", seed=4, duration=10)
    t, ay = rec.t, rec["ay"]
    out = {"dir": d, "truth": d / "truth.csv"}
    io.write(rec, out["truth"])
    for name, sep, dec in (("dot", ",", "."), ("eu", ";", ",")):
        out[name] = d / f"{name}.csv"
        _write(out[name], ["t", "ay"], zip(t, ay, strict=True), sep, dec)
        out[f"raw_{name}"] = d / f"raw_{name}.csv"
        _write(out[f"raw_{name}"], ["Zeit", "AccY"],
               zip(t * 1e3, ay / 9.80665, strict=True), sep, dec)
    return out


def _estimate(src, est, *args):
    res = run("estimate", src, *RANGE, "-o", est, *args)
    assert res.exit_code == 0, res.output
    return est.read_text()


def test_a_decimal_comma_file_estimates_as_its_decimal_point_twin(logs, monkeypatch):
    d = logs["dir"]
    want = _estimate(logs["dot"], d / "dot_est.csv")
    assert len(want.splitlines()) > 100  # an estimate row per sample, not an empty table
    assert _estimate(logs["eu"], d / "eu_est.csv", "--decimal", ",") == want
    # through an inline mapping: the logger's ms and g scaled alike on both files
    cols = "t=Zeit:ms,ay=AccY:g"
    mapped = _estimate(logs["raw_dot"], d / "m_dot.csv", "--columns", cols)
    assert _estimate(logs["raw_eu"], d / "m_eu.csv", "--columns", cols, "--decimal", ",") \
        == mapped
    # a mapping file saying decimal = "," and the flag saying it too agree
    m = d / "map.toml"
    m.write_text('decimal = ","\n[columns]\nt = "Zeit"\nay = "AccY"\n')
    got = io.read(logs["raw_eu"], mapping_file=m, decimal=",")
    ref = io.read(logs["raw_dot"], columns="t=Zeit,ay=AccY")
    np.testing.assert_array_equal(got.t, ref.t)
    np.testing.assert_array_equal(got["ay"], ref["ay"])
    # the streamed path (a long log read in chunks, estimated in blocks) reads it alike
    from vibrospeed.estimators.grid import stream

    monkeypatch.setattr(stream, "STREAM_ROWS", 400)
    got = []
    for kind, dec in (("dot", "."), ("eu", ",")):
        res = run("estimate", logs[kind], *RANGE, "-o", d / f"s_{kind}.csv", "--decimal", dec)
        assert res.exit_code == 0 and "in blocks" in res.stderr, res.output
        got.append((d / f"s_{kind}.csv").read_text())
    assert got[0] == got[1]
    assert len(got[0].splitlines()) > 100


def test_batch_info_and_evaluate_take_it(logs):
    d = logs["dir"]
    want = _estimate(logs["dot"], d / "b_dot.csv")
    out = d / "out"
    res = run("batch", logs["eu"], "-o", out, "-j", 1, *RANGE, "--decimal", ",")
    assert res.exit_code == 0, res.output
    (est,) = out.glob("eu_*.csv")
    assert est.read_text() == want
    side = json.loads(est.with_name(est.name + ".json").read_text())
    assert side["meta"]["options"]["decimal"] == ","
    # options without it keep the sidecar as it was (earlier batches stay up to date)
    assert "decimal" not in batch.EstimateOptions().to_json()
    res = run("info", logs["eu"], "--decimal", ",")
    assert res.exit_code == 0, res.output
    # evaluate --baseline reads the recording with the batch sidecar's mark
    res = run("evaluate", est, "--truth", logs["truth"], "--baseline", logs["eu"])
    assert res.exit_code == 0, res.output
    assert "STFT 3 s" in res.stdout
    line = one_line_error(run("evaluate", est, "--truth", logs["truth"], "--baseline",
                              logs["eu"], "--decimal", "."))
    assert line == (f"vibrospeed: error: --decimal '.' but {est}'s sidecar says the estimate "
                    f"read {logs['eu']} with decimal ',': give one")


@settings(max_examples=25, deadline=None)
@given(values=st.lists(st.tuples(st.floats(-1e6, 1e6, allow_nan=False),
                                 st.floats(allow_nan=False, allow_infinity=False)),
                       min_size=1, max_size=40),
       chunk=st.integers(1, 7), mapped=st.booleans())
def test_chunked_and_whole_file_readers_agree_on_a_decimal_comma(tmp_path_factory, values,
                                                                 chunk, mapped):
    d = tmp_path_factory.mktemp("hyp")
    t = np.cumsum(np.abs([v[0] for v in values])) + np.arange(1, len(values) + 1)
    ay = np.array([v[1] for v in values])
    dot, eu = d / "dot.csv", d / "eu.csv"
    _write(dot, ["t", "ay"], zip(t, ay, strict=True), ",", ".")
    _write(eu, ["t", "ay"], zip(t, ay, strict=True), ";", ",")
    kw = {"columns": "t=t,ay=ay"} if mapped else {}
    whole = io.read(eu, decimal=",", **kw)
    chunks = ChunkedRecording(eu, chunk_rows=chunk, decimal=",", **kw).read()
    ref = io.read(dot, **kw)
    for r in (whole, chunks, ref):  # the values written, bit for bit
        np.testing.assert_array_equal(r.t, t)
        np.testing.assert_array_equal(r["ay"], ay)


def _refused(d, args, toml=None):
    m = d / "bad.toml"
    if toml is not None:
        m.write_text(toml)
    return one_line_error(run(*args))


def test_the_errors_are_one_line(logs):
    d = logs["dir"]
    est = d / "never.csv"
    # ',' decimals in a ',' separated file: 1,5 would be two fields
    line = _refused(d, ["estimate", logs["dot"], "-o", est, "--decimal", ","])
    assert line == (f"vibrospeed: error: {logs['dot']}, line 1: decimal mark ',' is also the "
                    "field separator: a number such as 1,5 would read as two fields (a decimal "
                    "comma needs ';' or tab separated fields)")
    line = _refused(d, ["estimate", logs["raw_eu"], "-o", est, "--mapping", d / "bad.toml",
                        "--decimal", ","], 'delimiter = ","\n[columns]\nt = "Zeit"\n'
                    'ay = "AccY"\n')
    assert line == (f"vibrospeed: error: {logs['raw_eu']}: decimal ',' and delimiter ',' are "
                    "the same mark: a number 1,5 would read as two fields")
    # the mapping file and the flag disagree: both named
    toml = 'decimal = "."\n[columns]\nt = "Zeit"\nay = "AccY"\n'
    line = _refused(d, ["estimate", logs["raw_eu"], "-o", est, "--mapping", d / "bad.toml",
                        "--decimal", ","], toml)
    assert line == (f"vibrospeed: error: {logs['raw_eu']}: --decimal ',' but {d / 'bad.toml'} "
                    "says decimal = \".\": give one of them")
    # the batch refuses it before it starts, the file name left out (the options are at fault)
    line = _refused(d, ["batch", logs["raw_eu"], "-o", d / "bout", "--mapping",
                        d / "bad.toml", "--decimal", ","], toml)
    assert line == (f"vibrospeed: error: --decimal ',' but {d / 'bad.toml'} says decimal = "
                    "\".\": give one of them")
    assert not (d / "bout").exists()
    for cmd in (["estimate", logs["eu"], "-o", est], ["batch", logs["eu"], "-o", d / "bout"],
                ["info", logs["eu"]], ["plot", logs["eu"], "-o", d / "p.png"]):
        line = _refused(d, [*cmd, "--decimal", ";"])
        assert line == "vibrospeed: error: --decimal: the decimal mark must be '.' or ',', got ';'"
    assert not est.exists() and not (d / "bout").exists()
    # a format that has no decimal mark to set
    pq = d / "x.parquet"
    with pytest.raises(ParameterError, match=r"x.parquet: format 'parquet' does not take option "
                                             r"'decimal'$"):
        ChunkedRecording(pq, decimal=",")
    # without the flag the comma file is refused with the way to read it
    line = one_line_error(run("estimate", logs["eu"], "-o", est))
    assert "(a decimal comma? give --decimal , or decimal = \",\"" in line
