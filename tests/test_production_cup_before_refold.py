"""The cup rule before the refold: from the flat pattern and the target alone it refuses a grip face
exactly where the check's rule refuses it on the refolded states, and a production run does not
refold a set-up it refuses (the same verdict, with no refold, plan or check paid for it)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fabkit.cup_before_refold import angle_margin, cup_refused_before_refold, flat_and_target_geometry
from fabkit.grip_footprint import cup_fit
from fabkit.refold import RefoldSolver
from fabkit.refold.sequence import edge_kind_names

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "cells" / "ur5e_bench.toml"            # a 50 mm cup
NARROW = ROOT / "cells" / "ur5e_bench_40mm_cup.toml"  # the production bench's 40 mm cup


def _geometry(flat, target):
    solver = RefoldSolver(flat, target)
    p = solver.panel
    return solver, flat_and_target_geometry(solver.flat_vertices, p.tris, p.tri_face, p.edges, edge_kind_names(p),
                                            solver.target.vertices, solver.target_angles)


@pytest.fixture(scope="module")
def plain_mm_panel(tmp_path_factory):
    """What a designer brings: a plain OBJ (no tags), vertex and face order shuffled, in millimetres,
    loaded with `units="mm"`, relaxed, unfolded and refolded (5 states)."""
    import fabkit.pipeline as fk
    from structure_panels import plain, reflect_tagged, shuffled

    tmp = tmp_path_factory.mktemp("plain")
    user, _, _ = shuffled(plain(reflect_tagged(2, 60.0)), seed=3)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in user.vertices * 1000.0]
    lines += ["f " + " ".join(str(i + 1) for i in f) for f in user.faces_list()]
    (tmp / "mm.obj").write_text("\n".join(lines) + "\n")
    flat = fk.unfold(fk.relax(fk.load(tmp / "mm.obj", units="mm")))
    folds = fk.refold(flat, frames=5)
    assert folds.ok, folds.problems
    solver, geometry = _geometry(flat.mesh, flat.folded)
    return solver, geometry, folds.model


@pytest.mark.parametrize("cup_mm, refused, why, planarity_mm", [(50.0, False, "", 0.254),
                                                                  (70.0, True, "leaves its plane", 0.945),
                                                                  (900.0, True, "does not fit", None)])
def test_the_pre_test_refuses_a_plain_panel_s_grip_face_as_the_full_rule(plain_mm_panel, cup_mm, refused, why,
                                                                         planarity_mm):
    """50 mm: the cup fits and the sheet under it is planar (0.25 mm); 70 mm: it fits, but the sheet
    under it curves away by 0.95 mm in the folded states (lip 0.5 mm); 900 mm: wider than the panel."""
    solver, geometry, model = plain_mm_panel
    r = cup_mm / 2000
    full = cup_fit(model, r)
    deviation = 1e-5 * solver.panel_size
    faces = [int(f) for f in solver.structure.grip_faces]
    assert len(faces) >= 2
    for f in faces:
        pre = cup_refused_before_refold(geometry, [f], r, deviation_m=deviation)
        assert (pre is not None) is refused and (not full(f).ok) is refused, (f, pre, full(f))
        if planarity_mm is not None:  # the folded state is the worst: the target measures what the states do
            assert full(f).planarity_m == pytest.approx(planarity_mm * 1e-3, abs=0.01e-3)
        if refused:
            assert why in pre[0].problem and why in full(f).problem
        if refused and planarity_mm is not None:
            assert pre[0].planarity_m == pytest.approx(full(f).planarity_m, abs=1e-7)
        if refused and why == "does not fit":  # the flat part of the rule: the same words as the check
            assert pre[0].problem == full(f).problem
    # one face that the cup fits keeps the whole set open (the planner may grip it)
    assert cup_refused_before_refold(geometry, faces, 0.025, deviation_m=deviation) is None
    # the margins are small against the rule's own numbers: 0.5 mm of lip, 1.4 deg of join angle
    assert 4 * deviation < 0.05e-3 and angle_margin(geometry, deviation) < np.radians(0.1)


def test_a_planarity_within_the_margin_is_left_to_the_full_rule(plain_mm_panel):
    """A lip that takes just less than the target's planarity: the last state may be a little flatter
    than the target, so the pre-test does not refuse it; with no deviation allowed it does."""
    solver, geometry, _ = plain_mm_panel
    f = int(solver.structure.grip_faces[0])
    measured = cup_refused_before_refold(geometry, [f], 0.035, deviation_m=0.0)[0].planarity_m
    lip = measured - 1e-6
    assert cup_refused_before_refold(geometry, [f], 0.035, deviation_m=0.0, lip_compliance=lip) is not None
    assert cup_refused_before_refold(geometry, [f], 0.035, deviation_m=1e-6, lip_compliance=lip) is None


@pytest.fixture(scope="module")
def vault_task():
    from vault_panels import first_vault_panel

    from fabkit.panels.production import ProductionOptions, program_task, stock
    from sim.production import cup_refusal_before_refold, program_panel

    panel, geometry = first_vault_panel()
    return program_task(panel, geometry, ProductionOptions(), NARROW.read_text(), NARROW.name, stock(),
                        program_panel, cup_refusal_before_refold)


def _with_cup(task, cup_mm: float) -> dict:
    text = task["cell_toml"]
    assert "cup_radius = 0.020" in text
    return {**task, "cell_toml": text.replace("cup_radius = 0.020", f"cup_radius = {cup_mm / 2000:g}")}


@pytest.mark.slow
@pytest.mark.parametrize("cup_mm", [40.0, 100.0])
def test_a_production_set_up_s_pre_test_is_the_check_s_cup_verdict(vault_task, cup_mm, tmp_path):
    """Every set-up of a tagged vault panel: refused before its refold exactly when the check's rule
    (`sim.production.cup_refusal`) refuses its refolded FOLD file, in the same words (a disc off the
    sheet and a sheet that is not planar under it)."""
    from fabkit.panels.production_refold import _refold, _refold_solver, panel_setups, refusal_before_refold
    from sim.production import _cell, cup_refusal

    task = _with_cup(vault_task, cup_mm)
    cell = _cell(task["cell_toml"], task["cell_name"])
    verdicts = []
    for setup in panel_setups(task):
        solver = _refold_solver(task, setup)[0]
        pre = refusal_before_refold(task, setup, solver)
        _, text, why = _refold(task, setup)
        assert text is not None, why
        (tmp_path / "p.fold").write_text(text)
        full = cup_refusal(tmp_path / "p.fold", cell, setup.grip)
        assert bool(pre) is bool(full), (setup, pre, full)
        if pre:
            assert pre.startswith(f"holds: {full} (the cup check, run before the refold"), (pre, full)
        verdicts.append(bool(pre))
    # the grip faces' sheet is 78.5 and 111.8 mm across; a 100 mm cup does not fit the first and the
    # sheet under it leaves its plane by 1.3 mm on the second
    assert verdicts == [cup_mm > 50] * len(verdicts)


@pytest.mark.slow
def test_production_does_not_refold_a_set_up_the_cup_refuses(vault_task, monkeypatch):
    """A cup too wide for every set-up: without the pre-test each set-up is refolded and refused by
    the cup before planning; with it none is refolded, and the verdicts are the same."""
    from fabkit.panels.production_refold import refold_and_program

    solves = []
    real = RefoldSolver.solve
    monkeypatch.setattr(RefoldSolver, "solve", lambda self, *a, **k: solves.append(1) or real(self, *a, **k))
    task = _with_cup(vault_task, 300.0)
    without = refold_and_program({k: v for k, v in task.items() if k != "refuse_before_refold"})
    n_without = len(solves)
    with_pre = refold_and_program(task)
    assert n_without == len(without["setups"]) == 4 and len(solves) == n_without   # none refolded with it
    for a, b in zip(without["setups"], with_pre["setups"]):
        assert a["stage"] == b["stage"] == "check"
        assert a["reason"].split(" (the cup check")[0] == b["reason"].split(" (the cup check")[0]
        assert "the cup check, run before the refold" in b["reason"]
    assert with_pre["stage"] == without["stage"] == "check" and with_pre["fold"] is None
    assert with_pre["reason"].split(" (the cup check")[0] == without["reason"].split(" (the cup check")[0]
    # a cup that fits: the set-up is refolded, planned and checked as before
    solves.clear()
    fits = refold_and_program(_with_cup(vault_task, 30.0))
    assert len(solves) >= 1 and fits["fold"] is not None
