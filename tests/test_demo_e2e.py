"""End to end: the small demo runs every stage (generate ... dry run on the stand-in) and they all pass."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from browser import chromium, count_colour, screenshot


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    out = tmp_path_factory.mktemp("demo")
    proc = subprocess.run([sys.executable, "-m", "fabkit", "demo", "--small", "--out", str(out), "--no-render"],
                          capture_output=True, text=True, timeout=240)
    return out, proc


def test_every_stage_passes(demo):
    out, proc = demo
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    summary = json.loads((out / "summary.json").read_text())
    stages = {s["name"]: s for s in summary["stages"]}
    assert list(stages) == ["generate", "relax", "unfold", "refold", "toolpath", "check", "send"]
    assert all(s["status"] == "pass" for s in stages.values()), {k: (s["status"], s["message"]) for k, s in stages.items()}
    # the numbers behind the passes, read from each stage's own report
    relax = stages["relax"]["report"]["final"]
    assert relax["max_abs_angle_defect_rad"] <= 1e-8 and relax["max_planarity"] <= 1e-8
    dev = stages["unfold"]["report"]["development"]
    assert dev["max_relative_deviation"] <= 1e-6 and dev["flipped_faces"] == 0
    refold = stages["refold"]["report"]["summary"]
    assert refold["max_loop_residual_rad"] <= 1e-9 and refold["target_distance_rel"] <= 1e-6
    check = json.loads((out / "check.json").read_text())
    path = json.loads((out / "path.json").read_text())
    assert check["ok"] and check["toolpath_sha256"] == path["sha256"]
    send = stages["send"]["report"]
    assert send["last_completed"] == send["total"] - 1 == len(path["waypoints"]) - 1
    assert send["final_error_rad"] <= 1e-4
    for artifact in ("trifold.obj", "relaxed.obj", "flat.obj", "flat.dxf", "flat.svg", "fold.fold", "path.json",
                     "program.script", "check.json", "report.html", "send.log"):
        assert (out / artifact).is_file(), artifact


@pytest.mark.skipif(chromium() is None, reason="Debian chromium not installed (scripts/system-deps.sh installs it)")
def test_real_report_renders_in_chromium(demo, tmp_path):
    out, proc = demo
    assert proc.returncode == 0
    img = screenshot(out / "report.html", tmp_path / "shot.png", height=1800)
    blue, orange = count_colour(img, "#1f77b4"), count_colour(img, "#ff7f0e")
    assert blue > 200 and orange > 200, (blue, orange)  # the relaxation history and joint plots drew
    assert count_colour(img, "#0a7a2f", tol=0.08) > 50  # the stage table shows its passes
