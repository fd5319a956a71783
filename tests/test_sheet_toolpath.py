"""The sheet hooks of `fabkit toolpath` (compensated states, PATH.json record) and the URScript payload."""
import json
import math
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main as fabkit_main
from fabkit.io.fold import load_fold
from fabkit.materials import get_material
from fabkit.sheet import programmed_angle, sheet_spec
from fabkit.sheet.creases import panel_creases

CELL = str(Path(__file__).resolve().parent.parent / "cells" / "ur5e_bench.toml")


@pytest.fixture(scope="module")
def reflect_fold(tmp_path_factory):
    """The reflect preset through generate -> unfold -> refold (the user's path)."""
    d = tmp_path_factory.mktemp("reflect")
    for argv in (["generate", "reflect", "-o", str(d / "panel.obj"), "-q"],
                 ["unfold", str(d / "panel.obj"), "-o", str(d / "flat.obj"), "-q"],
                 ["refold", str(d / "flat.obj"), str(d / "panel.obj"), "-o", str(d / "seq.fold"), "-q",
                  "--frames", "5"]):
        assert fabkit_main(argv) == 0
    return d / "seq.fold"


def _toolpath(fold, out: Path, *extra):
    path, script = out.with_suffix(".json"), out.with_suffix(".script")
    rc = fabkit_main(["toolpath", str(fold), "--cell", CELL, "-o", str(path), "--script", str(script), "-q", *extra])
    return rc, path, script


def test_material_none_gives_todays_program(reflect_fold, tmp_path):
    rc0, p0, s0 = _toolpath(reflect_fold, tmp_path / "plain")
    rc1, p1, s1 = _toolpath(reflect_fold, tmp_path / "none", "--material", "none")
    assert rc0 == rc1 == 0
    assert p0.read_bytes() == p1.read_bytes() and s0.read_bytes() == s1.read_bytes()
    assert "set_payload" not in s0.read_text() and "sheet" not in json.loads(p0.read_text())


def test_5052_program_overbends_and_sets_the_payload(reflect_fold, tmp_path):
    rc, path, script = _toolpath(reflect_fold, tmp_path / "al", "--material", "5052-H32", "--thickness", "1mm",
                                 "--tool-mass", "1.2")
    assert rc == 0
    doc = json.loads(path.read_text())
    model = load_fold(reflect_fold)
    spec = sheet_spec(get_material("5052-H32"), 1e-3)
    (crease,) = panel_creases(model)
    states = doc["sheet"]["states"]
    assert len(states) == model.n_frames
    for s, st in enumerate(states):
        design = np.asarray(model.frames[s].edges_fold_angle)[crease.edges]
        want = [programmed_angle(spec, a, crease.kappa_g, crease.panel_width) for a in design]
        row = st["creases"][0]
        assert row["crease"] == "crease 0"
        assert row["design_deg"] == pytest.approx(math.degrees(design.mean()), abs=1e-9)
        assert row["programmed_deg"] == pytest.approx(math.degrees(np.mean(want)), abs=1e-9)
        if s == len(states) - 1:
            assert row["programmed_deg"] - row["design_deg"] > 2.0  # the model's overbend, degrees
    pay = doc["payload"]
    area = model.mesh().face_areas.sum()
    assert pay["panel_mass_kg"] == pytest.approx(2680 * 1e-3 * area, rel=1e-9)
    assert pay["held_mass_kg"] == pytest.approx(1.2 + pay["panel_mass_kg"], rel=1e-12)
    # the cycle time is the motion model's with the payload rule (robot.ur_motion.joint_accel_bound)
    from robot.motion import toolpath_cycle_time
    from robot.toolpath import Toolpath

    assert doc["cycle_time_s"] == pytest.approx(toolpath_cycle_time(Toolpath.load(path)).total, rel=1e-12)
    text = script.read_text()
    lines = text.splitlines()
    pays = [i for i, line in enumerate(lines) if "set_payload(" in line]
    assert len(pays) == 3
    grip_on = next(i for i, line in enumerate(lines) if line.strip().startswith("set_tool_digital_out") and "True" in line)
    assert pays[0] < grip_on < pays[1]
    assert lines[pays[0]].strip() == "set_payload(1.2, [0.0, 0.0, 0.065])"
    assert lines[pays[1]].strip().startswith(f"set_payload({pay['held_mass_kg']!r}, ")


def test_bad_sheet_options_exit_2(reflect_fold, tmp_path, capsys):
    rc, path, _ = _toolpath(reflect_fold, tmp_path / "bare", "--material", "5052-H32", "--thickness", "1")
    assert rc == 2 and not path.exists()
    assert "--thickness" in capsys.readouterr().err
    rc, path, _ = _toolpath(reflect_fold, tmp_path / "tight", "--material", "5052-H32", "--thickness", "2mm",
                            "--bend-radius", "1mm")
    err = capsys.readouterr().err
    assert rc == 2 and not path.exists() and "crease 0" in err and "minimum 3 mm" in err
    rc, _, _ = _toolpath(reflect_fold, tmp_path / "unk", "--material", "unobtainium", "--thickness", "1mm")
    assert rc == 2 and "unknown material" in capsys.readouterr().err


def test_fold_loads_per_state_on_the_ur5e(reflect_fold, tmp_path, capsys):
    rc, path, _ = _toolpath(reflect_fold, tmp_path / "al", "--material", "5052-H32", "--thickness", "1mm")
    assert rc == 0
    loads = json.loads(path.read_text())["sheet"]["loads"]
    assert not loads["ok"] and loads["arm"] == "ur5e"
    wrist = [v for v in loads["verdicts"] if v["check"] == "wrist couple"]
    assert wrist and all(v["crease"] == "crease 0" and not v["ok"] for v in wrist)
    assert {v["state"] for v in wrist} == set(range(1, len(json.loads(path.read_text())["sheet"]["states"])))
    err = capsys.readouterr().err
    assert "warning: load check: crease 0" in err and "groove the crease" in err and "push instead of pull" in err
    rc, path, script = _toolpath(reflect_fold, tmp_path / "strict", "--material", "5052-H32", "--thickness", "1mm",
                                 "--check-loads")
    assert rc == 1 and not path.exists() and not script.exists()
    assert "FAILED: load check: crease 0" in capsys.readouterr().err
    # thin soft sheet: within the UR5e's and the 50 mm cup's ratings
    rc, path, _ = _toolpath(reflect_fold, tmp_path / "thin", "--material", "1100-H14", "--thickness", "0.5mm",
                            "--check-loads", "--tool-mass", "1")
    assert rc == 0 and json.loads(path.read_text())["sheet"]["loads"]["ok"]
