"""`fabkit demo --material/--thickness`: the sheet thickness the check's panel pieces get, and the
refusals before the first stage (exit 2, one line naming the option)."""
from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from fabkit.commands.demo import sheet_thickness
from fabkit.errors import InputError


def _demo(tmp_path, *extra):
    return subprocess.run([sys.executable, "-m", "fabkit", "demo", "--out", str(tmp_path / "out"), "--small",
                           "--no-render", "--no-dry-run", "-q", *extra], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("extra, option", [(("--thickness", "1mm"), "--material"),
                                           (("--material", "5052-H32"), "--thickness"),
                                           (("--material", "5052-H32", "--thickness", "1.6"), "--thickness"),
                                           (("--material", "unobtainium", "--thickness", "1mm"), "--material")])
def test_bad_sheet_options_are_refused_before_any_stage(tmp_path, extra, option):
    proc = _demo(tmp_path, *extra)
    assert proc.returncode == 2, proc.stderr
    assert option in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "out" / "trifold.obj").exists()


def test_the_material_gives_the_check_its_thickness():
    ns = argparse.Namespace(material="5052-H32", thickness="1.6 mm")
    assert sheet_thickness(ns) == pytest.approx(0.0016)
    assert sheet_thickness(argparse.Namespace(material="none", thickness=None)) is None
    with pytest.raises(InputError, match="needs a --material"):
        sheet_thickness(argparse.Namespace(material="none", thickness="1mm"))


def test_a_cell_whose_cup_fits_no_grip_face_fails_the_toolpath_stage(tmp_path):
    """A 150 mm cup is wider than the sheet around every tri-fold grip face: the planner's check
    refuses every candidate, the toolpath stage fails naming it (not "pass"), PATH.json is kept and
    no URScript is written."""
    import json
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "cells" / "ur5e_bench.toml").read_text()
    assert "cup_radius = 0.025 " in text
    cell = tmp_path / "wide_cup.toml"
    cell.write_text(text.replace("cup_radius = 0.025 ", "cup_radius = 0.075 "))
    proc = _demo(tmp_path, "--cell", str(cell))
    assert proc.returncode == 1, proc.stderr
    out = tmp_path / "out"
    stages = {s["name"]: s for s in json.loads((out / "summary.json").read_text())["stages"]}
    assert stages["toolpath"]["status"] == "fail" and stages["check"]["status"] == "skipped"
    assert "the check refuses every grip candidate that planned" in stages["toolpath"]["message"]
    assert (out / "path.json").exists() and not (out / "program.script").exists()
