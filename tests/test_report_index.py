"""The batch's ``index.html`` (:func:`vibrospeed.eval.report.write_index`) from a summary table."""

import math
import re

import pandas as pd

from vibrospeed.eval.report import write_index


def _summary(**extra) -> pd.DataFrame:
    base = {
        "file": ["a.csv", "b.csv", "c.csv"], "duration_s": [20.0, 20.0, math.nan],
        "method": ["fuse", "fuse", "fuse"], "signal_share": [0.9, 0.0, math.nan],
        "median_speed": [12.0, 11.0, math.nan], "distance_m": [240.0, 220.0, math.nan],
        "status": ["ok", "ok", "error"], "error": [math.nan, math.nan, "a.csv: no rows"],
        "note": [math.nan, math.nan, math.nan], "wall_s": [1.0, 1.0, 0.1],
    }
    return pd.DataFrame({**base, **extra})


def _table(path) -> tuple[list[str], list[list[str]]]:
    text = path.read_text(encoding="utf-8")
    head = re.findall(r"<th>(.*?)</th>", text)
    rows = [re.findall(r"<td[^>]*>(.*?)</td>", ln)
            for ln in text.splitlines() if ln.startswith("<tr><td")]
    return head, rows


def test_index_has_a_wheel_radius_column_only_where_a_drive_learned_one(tmp_path):
    """One drive learned its radius (0.30571 ± 0.00368 m), one kept its prior (NaN), one failed:
    the column shows 4 decimals where learned and "–" elsewhere; a summary without values (the
    columns absent, or present and all empty) has no such column."""
    df = _summary(fitted_radius=[0.30571, math.nan, math.nan],
                  fitted_radius_std=[0.00368, math.nan, math.nan])
    head, rows = _table(write_index(tmp_path / "with.html", df))
    assert len(head) == 11 and all(len(r) == 11 for r in rows)
    i = head.index("wheel radius (m)")
    assert head[i - 1] == "with a line" and head[i + 1] == "method"
    assert [r[i] for r in rows] == ["0.3057 ± 0.0037", "–", "–"]
    # a radius without a std (a method's own fit): the radius alone
    head, rows = _table(write_index(tmp_path / "nostd.html", df.drop(columns="fitted_radius_std")))
    assert rows[0][head.index("wheel radius (m)")] == "0.3057"

    for name, frame in (("none", _summary()),
                        ("empty", _summary(fitted_radius=[math.nan] * 3,
                                           fitted_radius_std=[math.nan] * 3))):
        head, rows = _table(write_index(tmp_path / f"{name}.html", frame))
        assert "wheel radius (m)" not in head and len(head) == 10
        assert all(len(r) == 10 for r in rows)
