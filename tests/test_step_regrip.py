"""A letter fold folded crease by crease by one arm with a regrip: the right flap 60 deg down (a
mountain) while a jig pad holds the left flap flat, release, regrip the left flap and fold it 60 deg
up (a valley) while a second pad holds the right flap where it lies folded.

The panel is made here (0.6 m x 0.2 m, three 0.2 m strips, straight creases), refolded step by step
(crease 1, then crease 0) with the middle strip clamped, and planned by `fabkit toolpath` with
nothing else given: no single grip holds both flaps, so the planner folds one phase per step
(`robot.phased_planner.step_phases`). A folded crease is not assumed to stay folded: in the cell
with only the flat flap's pad the same program is refused naming the crease left free.
"""
import json
from pathlib import Path

import numpy as np
import pytest

from fabkit.cli import main
from fabkit.mesh import PolyMesh

ROOT = Path(__file__).resolve().parent.parent
CELL = str(ROOT / "cells" / "ur10e_letter_jigs.toml")
ONE_JIG = str(ROOT / "cells" / "ur10e_jig.toml")


def mixed_letter_fold(angle: float, nx: int = 6, ny: int = 2, size: float = 0.6):
    """(FLAT, TARGET): a strip with straight creases at x = -size/6 and size/6; the left flap folds
    `angle` up (valley), the right flap `angle` down (mountain). Tagged: strips, columns, middle row."""
    from fabkit.generate.reflect import grid_faces

    xs, ys = np.linspace(-size / 2, size / 2, nx + 1), np.linspace(0.0, size * ny / nx, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    faces = grid_faces(nx, ny + 1)
    fcol = np.repeat(np.arange(nx), ny)
    column = (np.arange(len(faces)) % ny).astype(np.int64)
    fd = {"strip": np.digitize(fcol, [nx // 3, 2 * nx // 3]).astype(np.int64), "column": column,
          "middle": ((column == 1) & np.isin(fcol, [1, 2, 4])).astype(np.int64)}
    a, b = xs[nx // 3], xs[2 * nx // 3]
    T = V.copy()
    left, right = V[:, 0] < a - 1e-12, V[:, 0] > b + 1e-12
    T[left, 0], T[left, 2] = a - np.cos(angle) * (a - V[left, 0]), np.sin(angle) * (a - V[left, 0])
    T[right, 0], T[right, 2] = b + np.cos(angle) * (V[right, 0] - b), -np.sin(angle) * (V[right, 0] - b)
    return PolyMesh(V, faces, face_data=fd), PolyMesh(T, faces, face_data=fd)


@pytest.fixture(scope="module")
def stepped(tmp_path_factory):
    """(dir, FOLD file, flat mesh): refolded crease 1 then crease 0, the middle strip's face 5 clamped."""
    from fabkit.io.fold import save_fold
    from fabkit.refold import refold
    from fabkit.refold.export import to_fold_model

    d = tmp_path_factory.mktemp("step_regrip")
    flat, target = mixed_letter_fold(np.radians(60.0))
    seq = refold(flat, target, frames=4, steps="crease1,crease0", fixed_face=5)
    assert list(seq.step) == [-1, 0, 0, 0, 1, 1, 1] and bool(np.all(seq.converged))
    save_fold(to_fold_model(seq), d / "seq.fold")
    return d, d / "seq.fold", flat


def test_one_arm_folds_the_letter_crease_by_crease_with_two_jigs(stepped):
    from fabkit.holds import hold_analysis
    from fabkit.io.fold import load_fold
    from fabkit.hold_model_fold import hold_model_from_fold

    d, fold, flat = stepped
    strip = np.asarray(flat.face_data["strip"])
    path, report, check = d / "path.json", d / "toolpath.json", d / "check.json"
    assert main(["toolpath", str(fold), "--cell", CELL, "-o", str(path), "--report", str(report), "-q"]) == 0
    doc = json.loads(path.read_text())
    ph = doc["phases"]
    assert [(int(strip[p["face"]]), p["side"], p["states"]) for p in ph] == [(2, "front", [0, 3]), (0, "front", [3, 6])]
    ops = [w["op"] for w in doc["waypoints"]]
    assert ops.count("grip") == 2 and ops.count("release") == 2
    jigs = doc["holds"]["jigs"]
    flat_pad = {f for f in jigs["wing_pad"] if f is not None}
    folded_pad = {f for f in jigs["folded_pad"] if f is not None}
    assert len(flat_pad) == len(folded_pad) == 1
    (f_flat,), (f_folded,) = flat_pad, folded_pad
    assert int(strip[f_flat]) == 0 and int(strip[f_folded]) == 2
    # the flat pad holds the left flap until phase 1 lifts it; the folded pad holds the right flap
    # from the end of phase 0 on
    lo0, hi0 = ph[0]["waypoints"]
    lo1, hi1 = ph[1]["waypoints"]
    assert all(jigs["wing_pad"][i] == f_flat for i in range(lo0, lo1 + 2))
    assert all(jigs["folded_pad"][i] == f_folded for i in range(hi0, hi1 + 1))
    assert all(jigs["folded_pad"][i] is None for i in range(lo0, hi0 - 3))

    assert main(["check", str(path), "--cell", CELL, "-o", str(check), "-q"]) == 0
    rep = json.loads(check.read_text())
    assert rep["ok"] and rep["holds"]["ok"] and rep["phases"]["ok"] and rep["panel_collisions"]["ok"]
    assert all(e["holds_proven"] and e["hold_states"] > 0 for e in rep["phases"]["phases"])
    clamp = rep["holds"]["clamped_faces"][0]
    held = {tuple(s["held_faces"]) for s in rep["holds"]["states"]}
    assert held == {tuple(sorted((f_flat, clamp, ph[0]["face"]))), tuple(sorted((f_folded, clamp, ph[1]["face"])))}
    assert all(s["nullity"] == 0 for s in rep["holds"]["states"])

    # between the phases the arm is off the panel: clamp and both pads hold it in the regrip state
    model, angles = hold_model_from_fold(load_fold(fold))
    assert len(angles) == 7 and np.abs(angles[0]).max() == 0.0            # state 0 is the flat pattern
    assert hold_analysis(model, angles[3], [clamp, f_flat, f_folded]).ok
    assert not hold_analysis(model, angles[3], [clamp, f_flat]).ok          # the folded flap alone is free


def test_without_the_folded_flaps_pad_the_regrip_is_refused(stepped):
    """With only the pad under the flat flap nothing holds the right flap once the arm lets go of it:
    its crease is a hinge (folded or not), so the regrip per step is refused naming crease 1."""
    d, fold, _ = stepped
    path, report = d / "one_jig.json", d / "one_jig_report.json"
    main(["toolpath", str(fold), "--cell", ONE_JIG, "-o", str(path), "--report", str(report), "-q"])
    tried = json.loads(report.read_text())["faces_tried"]
    step = [t["problem"] for t in tried if t["problem"].startswith("regrip per fold step")]
    assert step and "crease 1" in step[0] and "folded by nothing held" in step[0] and "fold states 3-6" in step[0]
    assert main(["check", str(path), "--cell", ONE_JIG, "-o", str(d / "one_jig_check.json"), "-q"]) == 1


def test_the_tool_is_excluded_from_the_face_each_phase_holds(stepped):
    """With a cup holder reaching 2 mm short of the TCP, the tool sits within the clearance of the
    face it holds in both phases: excluded move by move with the phase's face. A PATH.json whose
    second phase names the first phase's face leaves the held face unexcluded, and the check names it."""
    import tomllib

    from robot.cell import parse_cell
    from robot.toolpath import Toolpath, document_sha256
    from sim.check import check_toolpath

    d, fold, _ = stepped
    path = d / "path.json"
    if not path.exists():
        assert main(["toolpath", str(fold), "--cell", CELL, "-o", str(path), "-q"]) == 0
    text = Path(CELL).read_text()
    holder = "pose = [0.0, 0.0, 0.129, 0.0, 0.0, 0.0]\nradius = 0.025\nhalf_length = 0.009"
    assert holder in text
    cell = parse_cell(tomllib.loads(text.replace(holder, "pose = [0.0, 0.0, 0.1355, 0.0, 0.0, 0.0]\nradius = 0.025\n"
                                                         "half_length = 0.0125")), source="long_cup.toml")
    rep = check_toolpath(Toolpath.load(path), cell, fold=fold)
    assert rep.ok, [p.detail for p in rep.problems]
    doc = json.loads(path.read_text())
    held = doc["phases"][1]["face"]
    doc["phases"][1]["face"] = doc["phases"][0]["face"]
    doc["sha256"] = document_sha256(doc)
    wrong = d / "wrong_face.json"
    wrong.write_text(json.dumps(doc))
    rep = check_toolpath(Toolpath.load(wrong), cell, fold=fold)
    assert any(p.kind in ("clearance", "collision") and p.pair == ("suction_cup", f"face_{held}")
               for p in rep.problems), [p.detail for p in rep.problems]
