"""Fold loads against the UR ratings and the cell's vacuum cup (robot/loads.py)."""
from pathlib import Path

import numpy as np
import pytest

from fabkit.materials import get_material
from fabkit.sheet import fold_moment, panel_mass, sheet_spec
from robot.cell import load_cell
from robot.kinematics import fk_tcp
from robot.loads import CreaseLoad, arm_rating, check_fold_loads, cup_of_cell, joint_torques

CELLS = Path(__file__).resolve().parents[1] / "cells"
MM = 1e-3
TOOL_MASS = 1.0  # kg, gripper estimate


def _report(spec, cell_name, pull=False, lever=0.2):
    cell = load_cell(CELLS / f"{cell_name}.toml")
    V = np.array([[0, 0, 0], [0.6, 0, 0], [0.6, 0.2, 0], [0, 0.2, 0]])
    panel = panel_mass(spec, V, [[0, 1, 2], [0, 2, 3]])
    loads = [[], [CreaseLoad(fold_moment(spec, 0.6, "crease 0"), lever=lever, pull=pull)]]
    return check_fold_loads(loads, arm_rating(cell.model.name), cup_of_cell(cell), payload_mass=TOOL_MASS + panel.mass,
                            material=spec.material)


def test_unscored_600_mm_crease_fails_on_the_ur5e_and_names_crease_and_remedy():
    rep = _report(sheet_spec(get_material("5052-H32"), 1 * MM), "ur5e_bench")
    assert not rep.ok
    texts = [v.text() for v in rep.failures]
    wrist = next(v for v in rep.failures if v.check == "wrist couple")
    assert wrist.crease == "crease 0" and wrist.state == 1
    assert wrist.demand == pytest.approx(36.5, abs=0.1) and wrist.capacity == 28.0
    assert "groove the crease to a ligament of at most" in wrist.remedy and "ur10e" in wrist.remedy
    assert any("fold force" in t and "EXCEEDED" in t for t in texts)
    assert all("crease 0" in t for t in texts)


def test_the_same_crease_grooved_to_0_4_mm_passes_on_the_ur5e():
    rep = _report(sheet_spec(get_material("5052-H32"), 1 * MM, "grooved", ligament=0.4 * MM), "ur5e_bench")
    assert rep.ok, rep.summary()["problems"]
    assert {v.check for v in rep.verdicts} == {"wrist couple", "fold force + payload weight"}


def test_the_remedy_ligament_passes_and_the_ur10e_wrist_takes_the_plain_crease_couple():
    spec = sheet_spec(get_material("5052-H32"), 1 * MM)
    rep = _report(spec, "ur5e_bench")
    wrist = next(v for v in rep.failures if v.check == "wrist couple")
    lig = float(wrist.remedy.split("at most ")[1].split(" mm")[0]) * MM
    assert _report(sheet_spec(spec.material, 1 * MM, "grooved", ligament=lig), "ur5e_bench").ok
    assert not _report(sheet_spec(spec.material, 1 * MM, "grooved", ligament=lig + 0.02 * MM), "ur5e_bench").ok
    rep10 = _report(spec, "ur10e_fold_table")
    assert next(v for v in rep10.verdicts if v.check == "wrist couple").ok  # 36.5 of 54 N m (68 %)


def test_pulling_with_the_cup_fails_and_names_push_instead():
    rep = _report(sheet_spec(get_material("5052-H32"), 1 * MM, "grooved", ligament=0.4 * MM), "ur5e_bench",
                  pull=True, lever=0.1)
    cup = next(v for v in rep.verdicts if v.check == "cup pull")
    # 50 mm cup at 60 kPa, S = 2.5: 47 N usable; 5.8 N m at 0.1 m = 58 N + the payload's weight
    assert cup.capacity == pytest.approx(47.1, abs=0.1) and not cup.ok
    assert "push instead of pull" in cup.remedy


def test_6061_t6_remedy_is_perforation_not_grooving():
    rep = _report(sheet_spec(get_material("6061-T6"), 1 * MM), "ur5e_bench")
    wrist = next(v for v in rep.failures if v.check == "wrist couple")
    assert wrist.remedy.startswith("perforate the crease to at most 14 % uncut") and "groove the" not in wrist.remedy


def test_joint_torques_are_the_jacobian_transpose_of_the_wrench():
    from robot.kinematics import fk, jacobian

    q = np.array([0.3, -1.2, 1.4, -1.8, -1.5708, 0.2])
    flange = fk("ur5e", q)
    w = np.array([12.0, -30.0, -100.0, 1.5, -0.7, 3.0])
    tau = joint_torques("ur5e", q, flange[:3, 3], w[:3], w[3:])
    np.testing.assert_allclose(tau, jacobian("ur5e", q).T @ w, atol=1e-12)
    # a vertical force makes no torque about the vertical base axis; a couple about z is all the base's
    T = fk_tcp("ur5e", q)
    assert abs(joint_torques("ur5e", q, T[:3, 3], [0, 0, -100.0])[0]) < 1e-9
    assert joint_torques("ur5e", q, T[:3, 3], [0, 0, 0], [0, 0, 7.0])[0] == pytest.approx(7.0)


def test_arm_folds_only_the_creases_between_clamp_and_grip():
    from fabkit.refold import refold
    from fabkit.refold.export import to_fold_model
    from fabkit.sheet.creases import arm_folds, panel_creases
    from tests.refold_panels import reflect_pair

    flat, target = reflect_pair(2, columns=12, rows=3)
    model = to_fold_model(refold(flat, target, frames=3))
    creases = panel_creases(model)
    fixed = int(model.file_data["fabkit:fixed_face"])
    strip = np.asarray(flat.face_data["strip"])
    fixed_strip = int(strip[fixed])
    mid = np.flatnonzero(np.asarray(flat.face_data["middle"]) != 0)
    for face in mid:
        s = int(strip[face])
        folds = arm_folds(model, creases, int(face), fixed)
        lo, hi = sorted((s, fixed_strip))
        assert {f.crease.name for f in folds} == {f"crease {k}" for k in range(lo, hi)}
        for f in folds:
            assert f.lever > 0 and f.state >= 1
            assert f.pull == (f.crease.name == "crease 0")  # crease 0 is the +60 deg valley
