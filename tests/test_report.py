"""The drive report: one self-contained HTML page (embedded images, no external URLs)."""

import base64
import html
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from vibrospeed import batch, io, sim
from vibrospeed.cli.app import app

runner = CliRunner()


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.srcs, self.hrefs, self.tags, self.text = [], [], [], []

    def handle_starttag(self, tag, attrs):
        self.tags.append(tag)
        for k, v in attrs:
            if k == "src":
                self.srcs.append(v or "")
            if k == "href":
                self.hrefs.append(v or "")

    def handle_data(self, data):
        self.text.append(data)


def _parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    page.close()
    return page


def _self_contained(page: _Page, n_images: int) -> None:
    assert len(page.srcs) == n_images
    for src in page.srcs:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    for url in page.srcs + page.hrefs:
        assert "http://" not in url and "https://" not in url and "//" not in url.split(":")[0]
    assert "script" not in page.tags and "link" not in page.tags and "iframe" not in page.tags


@pytest.fixture(scope="module")
def drive(tmp_path_factory):
    d = tmp_path_factory.mktemp("report")
    rec = sim.simulate("cart", seed=3, duration=10)
    rec.notes.append("logged by the test with a loose phone mount")
    path = d / "cart.csv"
    io.write(rec, path)
    return path


def test_report_without_estimate_runs_the_default(drive, tmp_path):
    html = tmp_path / "r.html"
    res = runner.invoke(app, ["report", str(drive), "-p", "omega_min=2", "-p", "omega_max=30",
                              "-o", str(html)])
    assert res.exit_code == 0, res.output
    page = _parse(html)
    _self_contained(page, 2)
    text = " ".join(" ".join(page.text).split())
    assert "logged by the test with a loose phone mount" in text  # the recording's note
    assert "pre-filter" in text  # the estimate's notes
    for word in ("duration", "distance", "median speed", "share with a wheel line", "grid",
                 "omega_max", "RMSE against the truth"):
        assert word in text, word
    assert "A wheel line was seen during" in text


def test_report_of_an_estimate_and_the_batch_index(drive, tmp_path):
    est = tmp_path / "est.csv"
    res = runner.invoke(app, ["estimate", str(drive), "-m", "ekf", "-o", str(est)])
    assert res.exit_code == 0, res.output
    html = tmp_path / "e.html"
    res = runner.invoke(app, ["report", str(drive), "--estimate", str(est), "-o", str(html)])
    assert res.exit_code == 0, res.output
    page = _parse(html)
    _self_contained(page, 2)
    text = " ".join(page.text)
    assert "ekf" in text and "does not say where it sees a wheel line" in text
    assert "normalised by a running RMS" in text and "loose phone mount" in text

    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "cart.csv").write_bytes(drive.read_bytes())
    (tmp_path / "in" / "cart.csv.json").write_bytes(Path(f"{drive}.json").read_bytes())
    (tmp_path / "in" / "broken.csv").write_text("t,ay\n0,x\n")
    out = tmp_path / "out"
    df = batch.run([tmp_path / "in"], out, method="shs", jobs=1, report=True)
    assert list(df["status"]) == ["error", "ok"]
    index = _parse(out / "index.html")
    _self_contained(index, 0)
    reports = [h for h in index.hrefs if h.endswith(".html")]
    assert reports == ["cart_shs.html"] and "summary.csv" in index.hrefs
    _self_contained(_parse(out / "cart_shs.html"), 2)
    assert "broken.csv" in " ".join(index.text)
    (out / "cart_shs.html").unlink()  # a resumed batch writes a missing report again
    df = batch.run([tmp_path / "in"], out, method="shs", jobs=1, report=True)
    assert list(df["status"]) == ["error", "skipped"] and (out / "cart_shs.html").is_file()


def _rows(path: Path) -> dict[str, str]:
    """The summary table of a report: its ``<th>`` names -> ``<td>`` texts."""
    import re

    text = path.read_text(encoding="utf-8")
    table = text.split("<h2>Summary</h2>", 1)[1].split("</table>", 1)[0]
    return {html.unescape(k): html.unescape(v)
            for k, v in re.findall(r"<tr><th>(.*?)</th><td>(.*?)</td></tr>", table)}


def _noise(path: Path, seed: int = 0) -> Path:
    """8 s of white noise on three axes at 400 Hz: no wheel line, no standstill, no GPS."""
    from vibrospeed.types import Recording

    rng = np.random.default_rng(seed)
    n = 8 * 400
    io.write(Recording(t=np.arange(n) / 400.0, channels={
        "ax": rng.normal(0.0, 1.0, n), "ay": rng.normal(0.0, 1.0, n),
        "az": 9.81 + rng.normal(0.0, 1.0, n)}), path)
    return path


def test_report_of_a_drive_without_a_line_shows_the_note(tmp_path):
    from vibrospeed.eval.metrics import NO_EVIDENCE_NOTE

    grid = ["-p", "omega_min=2", "-p", "omega_max=30"]
    noise = _noise(tmp_path / "noise.csv")
    res = runner.invoke(app, ["report", str(noise), *grid, "-o", str(tmp_path / "n.html")])
    assert res.exit_code == 0, res.output
    rows = _rows(tmp_path / "n.html")
    assert rows["share with a wheel line"] == "0.0 %"
    assert rows["distance"] == rows["median speed"] == rows["median omega"] == "–"
    assert rows["distance at the speed band's edges"] == "–"
    assert rows["note"] == NO_EVIDENCE_NOTE
    text = " ".join(" ".join(_parse(tmp_path / "n.html").text).split())
    assert "No wheel line was seen in this drive, and no GPS: wherever no standstill" in text

    # a simulated cart drive: numbers, no note; the reference is the estimate file itself
    cart = tmp_path / "cart.csv"
    io.write(sim.simulate("cart", seed=0, duration=8), cart)
    est = tmp_path / "cart_est.csv"
    assert runner.invoke(app, ["estimate", str(cart), *grid, "-o", str(est)]).exit_code == 0
    res = runner.invoke(app, ["report", str(cart), "--estimate", str(est),
                              "-o", str(tmp_path / "c.html")])
    assert res.exit_code == 0, res.output
    rows = _rows(tmp_path / "c.html")
    assert "note" not in rows
    table = pd.read_csv(est)
    v, t = table["speed"].to_numpy(), table["t"].to_numpy()
    assert np.isfinite(v).all()
    assert float(rows["median speed"].split()[0]) == pytest.approx(np.median(v), abs=0.006)
    dist = float(np.sum(0.5 * (v[1:] + v[:-1]) * np.diff(t)))  # trapezoids
    assert float(rows["distance"].split()[0]) == pytest.approx(dist, abs=0.06)
    lo, hi = (float(x) for x in rows["distance at the speed band's edges"][:-2].split(" – "))
    for got, edge in ((lo, table["speed_lo"].to_numpy()), (hi, table["speed_hi"].to_numpy())):
        assert got == pytest.approx(np.sum(0.5 * (edge[1:] + edge[:-1]) * np.diff(t)), abs=0.06)
    assert float(rows["median omega"].split()[0]) == pytest.approx(
        np.median(table["omega"]), abs=0.006)


def test_batch_index_and_reports_carry_the_note(tmp_path):
    from vibrospeed.eval.metrics import NO_EVIDENCE_NOTE

    src = tmp_path / "in"
    src.mkdir()
    _noise(src / "a_noise.csv")
    io.write(sim.simulate("cart", seed=0, duration=8), src / "b_cart.csv")
    out = tmp_path / "out"
    res = runner.invoke(app, ["batch", str(src), "-o", str(out), "-j", "1", "--report",
                              "-p", "omega_min=2", "-p", "omega_max=30"])
    assert res.exit_code == 0, res.output
    assert ("1 drive without a wheel line or GPS while moving: speed numbers left empty "
            "(see the note column)") in res.stderr
    summary = pd.read_csv(out / "summary.csv", keep_default_na=False)
    assert list(summary["note"]) == [NO_EVIDENCE_NOTE, ""]
    # the index: a note column, the noise drive's note in its row, none in the cart's
    text = (out / "index.html").read_text(encoding="utf-8")
    head = text.split("<tr>", 2)[1]
    assert "<th>note</th>" in head and head.index("<th>error</th>") < head.index("<th>note</th>")
    noise_row, cart_row = [ln for ln in text.splitlines() if ln.startswith("<tr><td>")]
    assert "a_noise.csv" in noise_row and html.escape(NO_EVIDENCE_NOTE) in noise_row
    assert "b_cart.csv" in cart_row and "<td class=\"muted\"></td>" in cart_row
    # each page says what its summary row says
    noise_page, cart_page = _rows(out / "a_noise_grid.html"), _rows(out / "b_cart_grid.html")
    assert noise_page["note"] == NO_EVIDENCE_NOTE and noise_page["median speed"] == "–"
    assert "note" not in cart_page
    assert float(cart_page["median speed"].split()[0]) == pytest.approx(
        float(summary.loc[1, "median_speed"]), abs=0.006)
    assert float(cart_page["distance"].split()[0]) == pytest.approx(
        float(summary.loc[1, "distance_m"]), abs=0.06)


def test_report_refuses_an_estimate_of_another_drive(drive, tmp_path):
    """``--estimate`` of another drive (its sidecar's input checksum differs) is one line,
    exit status 2, no page (nor plot): the spectrogram of one drive under another's speed would look
    plausible. The estimate of this drive, or one without a sidecar, still makes the page."""
    other = tmp_path / "other.csv"
    io.write(sim.simulate("cart", seed=5, duration=6), other)
    est = tmp_path / "est.csv"
    res = runner.invoke(app, ["estimate", str(other), "-m", "ekf", "-o", str(est)])
    assert res.exit_code == 0, res.output
    html_out = tmp_path / "r.html"
    res = runner.invoke(app, ["report", str(drive), "--estimate", str(est), "-o", str(html_out)])
    assert res.exit_code == 2 and not html_out.exists()
    assert res.stderr == (f"vibrospeed: error: {est}: estimated from {other}, not from {drive} "
                          "(the input checksum in its .json sidecar differs): give that "
                          "recording, or leave out --estimate to estimate this one\n")
    res = runner.invoke(app, ["report", str(other), "--estimate", str(est), "-o", str(html_out)])
    assert res.exit_code == 0 and html_out.is_file(), res.output
    png = tmp_path / "p.png"  # the plot command draws an estimate the same way: same check
    res = runner.invoke(app, ["plot", str(drive), "--estimate", str(est), "-o", str(png)])
    assert res.exit_code == 2 and not png.exists()
    assert res.stderr.endswith("give that recording, or an estimate of this one\n")
    Path(f"{est}.json").unlink()  # no sidecar: nothing to check against
    res = runner.invoke(app, ["report", str(drive), "--estimate", str(est), "-o",
                              str(tmp_path / "bare.html")])
    assert res.exit_code == 0, res.output


def test_batch_report_names_its_estimate_beside_it(drive, tmp_path):
    """A batch's page names its estimate relative to itself (both are in the output folder),
    so the text stays right when the folder is moved as a whole, as the fleets page says."""
    out = tmp_path / "out"
    df = batch.run([drive], out, method="ekf", jobs=1, report=True)
    assert list(df["status"]) == ["ok"]
    moved = tmp_path / "moved"
    out.rename(moved)
    rows = _rows(moved / "cart_ekf.html")
    assert rows["estimate file"] == "cart_ekf.csv" and (moved / rows["estimate file"]).is_file()


@pytest.mark.parametrize("extra", [["-p", "omega_max=30"], ["--preset", "online"],
                                   ["--wheel-radius", "0.31"]])
def test_report_with_an_estimate_refuses_options_that_would_do_nothing(drive, tmp_path, extra):
    """``-p``, ``--preset`` and ``--wheel-radius`` make an estimate; beside ``--estimate`` they
    were silently ignored (a radius asked for gave no speed): one line, exit 2, no page."""
    est = tmp_path / "est.csv"
    assert runner.invoke(app, ["estimate", str(drive), "-m", "ekf", "-o", str(est)]).exit_code == 0
    page = tmp_path / "r.html"
    res = runner.invoke(app, ["report", str(drive), "--estimate", str(est), "-o", str(page),
                              *extra])
    assert res.exit_code == 2 and not page.exists(), res.output
    assert res.stderr == (f"vibrospeed: error: {extra[0]} with --estimate: they set how the "
                          "recording is estimated, and --estimate gives the estimate; leave out "
                          "one or the other\n")
