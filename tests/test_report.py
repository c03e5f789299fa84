"""The drive report: one self-contained HTML page (embedded images, no external URLs)."""

import base64
from html.parser import HTMLParser
from pathlib import Path

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
