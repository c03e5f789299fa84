"""A bad column mapping stops ``vibrospeed batch`` before it starts with the line
``vibrospeed estimate`` prints for one recording: one set of rules
(:func:`vibrospeed.io.mapped.mapping_options`), worded once; the batch leaves out the file name
estimate puts first where the options, not a recording, are at fault."""

import pytest
from typer.testing import CliRunner

from vibrospeed import batch
from vibrospeed.cli.app import app
from vibrospeed.errors import ParameterError, ReaderError

LOG = "time,acc_y\n0.00,0.5\n0.01,-0.25\n0.02,1.0\n0.03,0.0\n"
OTHER = "units for it: m/s^2, m/s2, g, mg, or counts"

# (name, options, mapping file text or None, the line without a file name, whose file it names)
CASES = [
    ("unit of another quantity", ["--columns", "t=time,ay=acc_y:m/s"], None,
     f"column mapping 'ay': unit 'm/s' gives m/s, but ay is in m/s^2 ({OTHER})", "log"),
    ("t column beside --rate", ["--columns", "t=time,ay=acc_y", "--rate", "100"], None,
     "give either a time column 't' or a sample rate, not both", "log"),
    ("t column beside the file's rate", [], 'rate = 100\n[columns]\nt = "time"\nay = "acc_y"\n',
     "give either a time column 't' or a sample rate, not both", "log"),
    ("neither time nor rate", ["--columns", "ay=acc_y"], None,
     "no time column mapped; map one (t=COLUMN) or give the sample rate (rate=Hz)", "log"),
    ("unknown unit", [], '[columns]\nt = "time"\nay = { column = "acc_y", unit = "furlong" }\n',
     "columns.ay: unknown unit 'furlong' (known: m/s^2, m/s2, g, mg, rad/s, deg/s, rpm, m/s, "
     "km/h, kmh, mph, kn, s, ms, us, ns, rad, deg, m, 1, counts)", "map"),
    ("file unit of another quantity", [], '[columns]\nt = "time"\nay = { column = "acc_y", '
     'unit = "deg/s" }\n', f"column mapping 'ay': unit 'deg/s' gives rad/s, but ay is in "
     f"m/s^2 ({OTHER})", "map"),
    ("bad encoding", [], 'encoding = "klingon"\n[columns]\nt = "time"\nay = "acc_y"\n',
     "unknown encoding 'klingon' (e.g. utf-8, cp1252, latin-1)", "map"),
    ("missing mapping file", [], None, "mapping file not found", "map"),
]


def _stderr_line(res) -> str:
    """The one error line of a refused command (exit 2)."""
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in res.output, res.stderr
    return lines[0]


@pytest.mark.parametrize(("opts", "toml", "line", "named"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])
def test_a_bad_mapping_stops_the_batch_with_estimates_line(tmp_path, opts, toml, line, named):
    log, m, out = tmp_path / "log.csv", tmp_path / "map.toml", tmp_path / "out"
    log.write_text(LOG)
    if toml is not None:
        m.write_text(toml, encoding="utf-8")
    if not opts:
        opts = ["--mapping", str(m)]
    est = _stderr_line(CliRunner().invoke(app, ["estimate", str(log), "-o",
                                                str(tmp_path / "e.csv"), *opts]))
    bat = _stderr_line(CliRunner().invoke(app, ["batch", str(log), "-o", str(out), "-j", "1",
                                                *opts]))
    assert not out.exists() and not (tmp_path / "e.csv").exists()
    if named == "map":  # the mapping file is at fault: both name it
        assert est == bat == f"vibrospeed: error: {m}: {line}"
    else:  # the options: estimate names its one recording, the batch none
        assert est == f"vibrospeed: error: {log}: {line}"
        assert bat == f"vibrospeed: error: {line}"
    # from Python: the same error, before the output folder is made
    kw = {"columns": None, "mapping": None, "rate": None}
    for flag, value in zip(opts[::2], opts[1::2], strict=True):
        key = flag.removeprefix("--")
        kw[key] = float(value) if key == "rate" else value
    with pytest.raises((ParameterError, ReaderError)) as exc:
        batch.run([log], out, options=batch.EstimateOptions(**kw), jobs=1)
    assert f"vibrospeed: error: {exc.value}" == bat and not out.exists()


def test_a_unit_suffix_the_header_may_hold_is_each_recordings_error_as_estimates(tmp_path):
    """``ay=acc_y:furlong`` may name a column ``acc_y:furlong``: only the header tells, so the
    batch reads each recording and its error row is estimate's line for it."""
    log, out = tmp_path / "log.csv", tmp_path / "out"
    log.write_text(LOG)
    opts = ["--columns", "t=time,ay=acc_y:furlong"]
    est = _stderr_line(CliRunner().invoke(app, ["estimate", str(log), "-o",
                                                str(tmp_path / "e.csv"), *opts]))
    assert est.startswith(f"vibrospeed: error: {log}: column mapping 'ay=acc_y:furlong': "
                          "unknown unit 'furlong' (known: ")
    res = CliRunner().invoke(app, ["batch", str(log), "-o", str(out), "-j", "1", *opts])
    assert res.exit_code == 2 and (out / "summary.csv").is_file(), res.output
    assert est in res.stderr.splitlines()
