"""The suction cup's footprint on the grip face of a rigid program: measured on the sheet up to the
creases and outline, planar to the lip compliance in every fold state, reported in CHECK.json and
refused by the check (a holds problem naming the face); the planner tries the faces that carry the
cup first."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from holds_panels import reflect_two_crease_pair, trifold_sequence
from refold_panels import reflect_pair

from fabkit.grip_footprint import cup_footprint_record, pad_footprint
from fabkit.refold import refold

ROOT = Path(__file__).resolve().parent.parent
CUP = 0.035     # a 70 mm cup (the cells' is 50 mm)


def _middle(seq):
    mid = np.asarray(seq.face_data["middle"]) != 0
    return sorted(set(np.asarray(seq.face_data["polygon"])[mid].tolist()))


@pytest.fixture(scope="module")
def reflect_one():
    flat, target = reflect_pair(1)
    return refold(flat, target, frames=6)


def test_one_face_is_too_narrow_but_the_sheet_across_the_rulings_is_measured(reflect_one):
    for face in _middle(reflect_one):
        alone = pad_footprint(reflect_one, face, CUP)               # the grip region: hinges under 0.8 deg
        assert not alone.ok and alone.inscribed_m * 2 == pytest.approx(0.0436, abs=5e-4)
        assert "does not fit" in alone.problem
        sheet = pad_footprint(reflect_one, face, CUP, rulings_join=True)
        assert sheet.inscribed_m > CUP                              # the disc lies inside the sheet
        # the sheet under a flat 70 mm lip curves away by 0.95 mm over the fold states (lip: 0.5 mm)
        assert sheet.planarity_m == pytest.approx(0.95e-3, abs=0.05e-3)
        assert not sheet.ok and "leaves its plane by 0.9" in sheet.problem


def test_the_two_crease_panel_and_the_trifold_carry_the_cup():
    flat, target = reflect_two_crease_pair()
    for seq in (refold(flat, target, frames=6), trifold_sequence(6)):
        for face in _middle(seq):
            c = pad_footprint(seq, face, CUP, rulings_join=True)
            assert c.ok and c.inscribed_m > CUP and 0.1e-3 < c.planarity_m < 0.35e-3, (face, c)


def _cell_with_cup(tmp_path, diameter_mm: float) -> Path:
    text = (ROOT / "cells" / "ur5e_bench.toml").read_text()
    assert "cup_radius = 0.025 " in text
    cell = tmp_path / f"cup_{diameter_mm:g}.toml"
    cell.write_text(text.replace("cup_radius = 0.025 ", f"cup_radius = {diameter_mm / 2000:g} "))
    return cell


def test_the_check_refuses_a_grip_whose_cup_does_not_fit(tmp_path, capsys):
    import json

    import fabkit.pipeline as fk
    from fabkit.cli import main as fabkit_main
    from fabkit.io.obj import save_obj
    from structure_panels import reflect_tagged

    save_obj(reflect_tagged(2, 60.0), tmp_path / "p.obj")
    folds = fk.refold(fk.unfold(fk.relax(fk.load(tmp_path / "p.obj"))), frames=5)
    # the bench's 50 mm lip crosses the rulings beside the grip face (43.6 mm across) and the sheet
    # curves away under it by 0.25 mm; under a 70 mm lip by 0.95 mm (the lip takes 0.5)
    for cell, fits in ((ROOT / "cells" / "ur5e_bench.toml", True), (_cell_with_cup(tmp_path, 70), False)):
        prog = fk.plan(folds, str(cell), workdir=tmp_path / cell.stem)
        # the planner says so itself when it kept a program its check refuses
        assert (prog.refused_by_check is None) is fits, prog.refused_by_check
        assert fits or "leaves its plane by 0.9" in prog.refused_by_check
        if not fits:  # the library writes no pendant program for it either
            from fabkit.errors import ToleranceError

            with pytest.raises(ToleranceError, match="no URScript: the check refuses every grip candidate"):
                prog.urscript()
        check = fk.check(prog)
        rec = check.report.holds["cup_footprint"]
        assert rec["enforced"] is True and rec["cup_mm"] == pytest.approx(50.0 if fits else 70.0)
        rows = rec["faces"]
        assert all(r["ok"] is fits and r["room_mm"] > rec["cup_mm"] for r in rows)
        cup = [p for p in check.report.problems if p.subject.startswith("cup")]
        assert check.ok is fits and bool(cup) is not fits, check.problems
        # the production run's refusal before planning says the same as the full check
        from robot.cell import load_cell
        from sim.production import cup_refusal

        before = cup_refusal(folds.save(tmp_path / f"{cell.stem}.fold"), load_cell(cell))
        assert (before is None) is fits and (fits or "no middle-row face carries the 70 mm cup" in before), before
        if fits:
            assert all(r["planarity_mm"] == pytest.approx(0.254, abs=0.01) for r in rows)
            continue
        # every face that plans fails the cup: the first is refused, named, from its first grip
        (p,) = cup
        assert p.kind == "holds" and p.subject == f"cup × face_{rows[0]['face']}" and p.waypoint >= 0
        assert "leaves its plane by 0.9" in p.detail and "the cup cannot hold it" in p.detail, p.detail
        assert rows[0]["planarity_mm"] == pytest.approx(0.95, abs=0.05)
        # the CLI: exit 1, the problem in CHECK.json
        out = tmp_path / "CHECK.json"
        code = fabkit_main(["check", str(prog.path_file), "--cell", str(cell), "-o", str(out), "--quiet"])
        assert code == 1
        data = json.loads(out.read_text())
        assert any(q["subject"] == p.subject and q["kind"] == "holds" for q in data["problems"])
        # `fabkit toolpath` exits 1 naming the refusal; PATH.json is kept for the check, no URScript
        path, script, report = tmp_path / "t.json", tmp_path / "t.script", tmp_path / "t.report.json"
        argv = ["toolpath", str(prog.fold_file), "--cell", str(cell), "-o", str(path), "--script", str(script),
                "--report", str(report), "--quiet"]
        assert fabkit_main(argv) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "FAILED: the check refuses every grip candidate that planned" in err, err
        assert path.exists() and not script.exists()
        rep = json.loads(report.read_text())
        assert rep["ok"] is False and "leaves its plane by 0.9" in rep["refused_by_check"]


def test_no_cup_in_the_cell_or_no_grip_no_record():
    assert cup_footprint_record(None, {"arms": {"a": [1, None]}}, None) is None
    assert cup_footprint_record(None, {"arms": {"a": [None, None]}}, CUP) is None


def test_a_regrip_face_too_narrow_for_the_cup_is_not_tried(tmp_path):
    """The one-crease 175 deg panel: the regrip face that travels farthest is 43.6 mm across with
    the sheet beside it folded away, so the 50 mm cup does not fit it; the regrip faces leave it out
    (without the cup rule it would be tried first) and take the next face that carries the cup."""
    import fabkit.pipeline as fk
    from fabkit.io.obj import save_obj
    from robot.cell import load_cell
    from robot.plan_cell import cup_footprint_of
    from robot.regrip_choice import regrip_faces
    from structure_panels import reflect_tagged

    save_obj(reflect_tagged(1, 175.0), tmp_path / "p.obj")
    folds = fk.refold(fk.unfold(fk.relax(fk.load(tmp_path / "p.obj"))), frames=5)
    model = folds.model
    clamped = [int(model.file_data["fabkit:fixed_face"])]
    footprint = cup_footprint_of(load_cell(ROOT / "cells" / "ur5e_bench.toml"), model)
    plain_order = regrip_faces(model, clamped)
    with_cup = regrip_faces(model, clamped, footprint=footprint)
    misfits = [f for f in plain_order if footprint(f) is not None]
    assert misfits and plain_order[0] == misfits[0], (plain_order, misfits)
    assert "does not fit" in footprint(misfits[0]) and "43.6 mm across" in footprint(misfits[0])
    assert with_cup and all(footprint(f) is None for f in with_cup), with_cup
    assert [f for f in plain_order if f not in misfits] == with_cup[:len(plain_order) - len(misfits)]
    # a cell that declares no cup: no order by it
    text = (ROOT / "cells" / "ur5e_bench.toml").read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("cup_radius"))
    (tmp_path / "no_cup.toml").write_text(text.replace(line, ""))
    assert cup_footprint_of(load_cell(tmp_path / "no_cup.toml"), model) is None


def test_the_cup_verdict_is_the_same_for_a_plain_shuffled_panel_in_millimetres(tmp_path):
    """What a designer brings: the same panel as a plain OBJ (no tags), vertex and face order
    shuffled, in millimetres (`--units mm`: an OBJ declares no unit). The check measures the same
    sheet under the cup and gives the same verdicts as on fabkit's own tagged panel."""
    import fabkit.pipeline as fk
    from structure_panels import plain, reflect_tagged, shuffled

    user, _, _ = shuffled(plain(reflect_tagged(2, 60.0)), seed=5)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in user.vertices * 1000.0]   # as Rhino writes it
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in user.faces_list()]
    (tmp_path / "mm.obj").write_text("\n".join(lines) + "\n")
    folds = fk.refold(fk.unfold(fk.relax(fk.load(tmp_path / "mm.obj", units="mm"))), frames=5)
    for cell, fits, planarity in ((ROOT / "cells" / "ur5e_bench.toml", True, 0.254),
                                  (_cell_with_cup(tmp_path, 70), False, 0.95)):
        check = fk.check(fk.plan(folds, str(cell), workdir=tmp_path / cell.stem))
        rows = check.report.holds["cup_footprint"]["faces"]
        assert rows and all(r["ok"] is fits for r in rows), rows
        assert all(r["planarity_mm"] == pytest.approx(planarity, abs=0.05) for r in rows), rows
        cup = [p for p in check.report.problems if p.subject.startswith("cup × face_")]
        assert check.ok is fits and bool(cup) is not fits, check.problems
