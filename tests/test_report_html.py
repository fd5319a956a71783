"""The HTML report is self-contained and renders its plots in a real headless browser."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from browser import chromium, count_colour, dump_dom, screenshot, table_rows
from fabkit.report.html import write_report_html


def _summary(out: Path) -> dict:
    it = np.arange(40)
    history = [{"iteration": int(i), "max_defect": float(1e-2 * 0.6 ** i), "max_planarity": float(3e-3 * 0.7 ** i)}
               for i in it]
    q = np.linspace([0, -1.6, 1.6, -1.6, -1.6, 0], [0.4, -1.2, 1.4, -1.8, -1.5, 0.3], 25)
    (out / "path.json").write_text(json.dumps({"waypoints": [{"q": list(r)} for r in q]}))
    (out / "check.json").write_text(json.dumps({
        "ok": True, "clearance_limit_m": 0.01, "clearance_window_m": 0.03,
        "along_path": {"waypoint": list(range(25)), "clearance_m": [None] * 5 + list(np.linspace(0.029, 0.012, 20)),
                       "joint_speed_ratio": list(np.linspace(0.1, 0.6, 25))}}))
    return {"total_seconds": 1.5, "stages": [
        {"name": "relax", "status": "pass", "seconds": 0.4, "measure": "max|defect| 1e-12", "tolerance": "1e-8",
         "message": "", "report": {"history": history, "converged": True}},
        {"name": "check", "status": "fail", "seconds": 0.1, "measure": "", "tolerance": "", "message": "x<y>",
         "report": {"ok": False}},
    ]}


def test_report_is_self_contained(tmp_path):
    page = write_report_html(tmp_path, _summary(tmp_path)).read_text()
    assert page.startswith("<!doctype html>")
    # no network: no external URLs in src/href, images embedded
    assert not re.search(r"""(src|href)=['"]https?://""", page)
    assert page.count("data:image/png;base64,") == 3  # relax history, joints, clearance
    assert "x&lt;y&gt;" in page  # stage messages are escaped
    assert "<a href='path.json'>" in page


@pytest.mark.skipif(chromium() is None, reason="Debian chromium not installed (scripts/system-deps.sh installs it)")
def test_report_renders_plots_in_chromium(tmp_path):
    write_report_html(tmp_path, _summary(tmp_path))
    img = screenshot(tmp_path / "report.html", tmp_path / "shot.png", height=2400)
    # matplotlib's first two line colours must appear: the plots rendered
    blue, orange = count_colour(img, "#1f77b4"), count_colour(img, "#ff7f0e")
    assert blue > 200 and orange > 200, (blue, orange)


@pytest.mark.skipif(chromium() is None, reason="Debian chromium not installed (scripts/system-deps.sh installs it)")
def test_report_stage_table_reads_back_from_the_dom(tmp_path):
    """What a person reads: the stage table as the browser built it, row by row."""
    write_report_html(tmp_path, _summary(tmp_path))
    rows = table_rows(dump_dom(tmp_path / "report.html"), "Stages")
    assert rows[0] == ["stage", "result", "measure", "tolerance", "time", "note"]
    assert rows[1] == ["relax", "pass", "max|defect| 1e-12", "1e-8", "0.40 s", ""]
    assert rows[2] == ["check", "fail", "", "", "0.10 s", "x<y>"]
    assert len(rows) == 3

