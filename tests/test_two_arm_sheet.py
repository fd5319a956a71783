"""Two-arm sheet programs (`robot.arms_sheet`) on cells/dual_ur10e.toml: the middle-clamped
tri-fold in 0.5 mm 1100-H14. Each crease gets its one-arm overbend, the panel's mass is split among
the clamp and the arms (the shares sum to it), each arm carries the loads of the crease between the
clamp and its wing with its own payload, the program checks, and it runs on two stand-ins with
each controller declaring its own arm's payload."""
from __future__ import annotations

import dataclasses
import random

import numpy as np
import pytest

import fabkit.pipeline as fk
from fabkit.sheet import panel_mass, sheet_of
from robot.cell import load_cell, pose_to_matrix
from tests._ursim import ROOT, StandIn, external_host, free_loopback_hosts

DUAL = ROOT / "cells" / "dual_ur10e.toml"
SHEET = dict(material="1100-H14", thickness="0.5mm")


@pytest.fixture(scope="module")
def folds():
    flat = fk.unfold(fk.relax(fk.generate("trifold")))
    return fk.refold(flat, frames=3, fixed_face=4)


@pytest.fixture(scope="module")
def planned(folds, tmp_path_factory):
    """Planned at the cell's TCP speed limit (a shorter dry run) and checked."""
    program = fk.plan(folds, DUAL, workdir=tmp_path_factory.mktemp("dualsheet"), fold_speed=0.25, **SHEET)
    assert program.ok, program.problems
    checked = fk.check(program)
    assert checked.ok, checked.problems
    return program, checked


def _spec():
    return sheet_of(SHEET["material"], SHEET["thickness"], "plain")


def _strip_of(model, face: int) -> int:
    """The strip of panel face `face` (a polygon id, as grip faces are)."""
    from fabkit.frames import face_groups

    groups = face_groups(model.faces_vertices, model.faces_data)
    return int(groups.strip[groups.index_of(face)])


def test_each_crease_gets_the_overbend_of_a_one_arm_program(planned, folds, tmp_path):
    """The programmed (compensated) angle of every crease in every state is the one a one-arm
    program of the same FOLD file gets (ur10e_fold_table), and both are the springback model's
    (`fabkit.sheet.compensate`); the overbend is not zero."""
    from fabkit.sheet.compensate import compensate_sequence

    two = planned[0].toolpath.extra["sheet"]["states"]
    one = fk.plan(folds, ROOT / "cells" / "ur10e_fold_table.toml", workdir=tmp_path, **SHEET)
    assert one.ok, one.problems
    assert two == one.toolpath.extra["sheet"]["states"]
    assert two == compensate_sequence(folds.model, _spec()).summary()["states"]
    last = {c["crease"]: c for c in two[-1]["creases"]}
    assert set(last) == {"crease 0", "crease 1"}
    for c in last.values():
        assert abs(c["programmed_deg"]) > abs(c["design_deg"]) + 0.01  # overbent, on the crease's side


def test_the_panel_mass_is_split_among_the_clamp_and_the_arms(planned, folds):
    """Each arm's share is its wing (the strip it grips), the clamp's the middle strip; the shares
    sum to the panel's mass; each arm declares its tool + its share, with the share's centre of
    mass where the placed panel has it at the grip."""
    program, _ = planned
    atp = program.toolpath
    spec, model = _spec(), folds.model
    rec = atp.extra["sheet"]
    split, whole = rec["panel_split"], rec["panel_kg"]
    flat = model.mesh()
    tris, tri_face = flat.triangulate()
    assert whole == pytest.approx(panel_mass(spec, flat.vertices, tris).mass, rel=1e-12)
    assert sum(s["panel_kg"] for s in split.values()) == pytest.approx(whole, rel=1e-12)
    strip = np.asarray(model.faces_data["strip"])
    grips = atp.source["grip_faces"]
    cell = load_cell(DUAL)
    placed = pose_to_matrix(atp.extra["placement"]["fixture"])
    from robot.arm_cells import arm_cell

    for holder, s in (("clamp", 1), *((arm, _strip_of(model, grips[arm])) for arm in ("a", "b"))):
        part = panel_mass(spec, flat.vertices, tris[strip[tri_face] == s])
        assert split[holder]["panel_kg"] == pytest.approx(part.mass, rel=1e-12) and split[holder]["strips"] == {str(s): 1.0}
        if holder == "clamp":
            continue
        tp = atp.arm(holder)
        pay = tp.extra["payload"]
        assert pay["held_mass_kg"] == pytest.approx(pay["tool_mass_kg"] + part.mass, rel=1e-12)
        # back from the declared CoG to the share's centre in the base frame, at the grip
        share_flange = (pay["held_mass_kg"] * np.array(pay["held_cog_m"])
                        - pay["tool_mass_kg"] * np.array(pay["tool_cog_m"])) / part.mass
        grip = next(w for w in tp.waypoints if w.op == "grip")
        ac = arm_cell(cell, holder)
        flange = pose_to_matrix(grip.pose) @ np.linalg.inv(np.asarray(ac.tool.tcp))
        want = ac.world_to_base @ placed @ np.append(part.cog, 1.0)
        np.testing.assert_allclose((flange @ np.append(share_flange, 1.0))[:3], want[:3], atol=1e-9)
    assert {_strip_of(model, grips["a"]), _strip_of(model, grips["b"])} == {0, 2}


def test_each_arm_carries_the_crease_to_its_wing_with_its_own_payload(planned, folds):
    """The load verdicts of arm X are the one-arm model's (`robot.loads.toolpath_loads`) for X's
    grip face with X's payload, limited to the crease between the clamp and X's wing, with the same
    numbers (the remedies do not offer "two arms sharing the fold"); the check recomputes the same
    numbers per arm."""
    from fabkit.sheet.creases import panel_creases
    from robot.arm_cells import arm_cell
    from robot.loads import toolpath_loads

    program, checked = planned
    atp = program.toolpath
    spec, model = _spec(), folds.model
    loads = atp.extra["sheet"]["loads"]
    cell = load_cell(DUAL)
    for arm, face in atp.source["grip_faces"].items():
        one = toolpath_loads(spec, model, panel_creases(model), face, arm_cell(cell, arm),
                             atp.arm(arm).extra["payload"]["held_mass_kg"])
        numbers = lambda vs: [{k: v[k] for k in ("state", "crease", "check", "demand", "capacity", "ok")}  # noqa: E731
                              for v in vs]
        assert numbers(loads["arms"][arm]["verdicts"]) == numbers(one.summary()["verdicts"]) and one.verdicts
        assert not any("two arms" in v["remedy"] for v in loads["arms"][arm]["verdicts"])
        assert all("two arms sharing the fold" in v.remedy for v in one.verdicts)
        crease = f"crease {min(_strip_of(model, face), 1)}"  # the row between the middle strip and the wing
        assert {v["crease"] for v in loads["verdicts"] if v["arm"] == arm} == {f"arm {arm}: {crease}"}
        got = checked.report.loads["arms"][arm]
        assert [(c["crease"], c["demand"]) for st in got["states"] for c in st["checks"]] == \
            [(v.crease, v.demand) for v in one.verdicts]
    assert checked.report.loads["ok"] and checked.report.loads["arm"] == "ur10e+ur10e"
    from fabkit.report.sheet import sheet_section

    html = sheet_section(atp.to_json(), checked.report.to_json())
    for arm in ("a", "b"):
        held = atp.arm(arm).extra["payload"]["held_mass_kg"]
        assert f"arm {arm}: payload declared: tool 1.000 kg, tool + its share of the panel {held:.3f} kg" in html
        assert f"<td>arm {arm}: crease " in html


def test_a_crease_nearer_another_arms_grip_is_that_arms(folds):
    """With the clamp on an end strip and the arms on the two others, the far arm folds only the
    crease beyond the near arm's grip (`toolpath_loads(other_grips=)`)."""
    from fabkit.sheet.creases import panel_creases
    from robot.loads import toolpath_loads

    from fabkit.frames import face_groups

    model = folds.model
    groups = face_groups(model.faces_vertices, model.faces_data)
    end, near, far = (int(groups.ids[groups.strip == s][0]) for s in (0, 1, 2))
    model = dataclasses.replace(model, file_data={**model.file_data, "fabkit:fixed_face": end})
    cell, spec, creases = load_cell(DUAL), _spec(), panel_creases(model)
    alone = {v.crease for v in toolpath_loads(spec, model, creases, far, cell, 1.0).verdicts}
    shared = {v.crease for v in toolpath_loads(spec, model, creases, far, cell, 1.0, other_grips=(near,)).verdicts}
    nearer = {v.crease for v in toolpath_loads(spec, model, creases, near, cell, 1.0, other_grips=(far,)).verdicts}
    assert alone == {"crease 0", "crease 1"} and shared == {"crease 1"} and nearer == {"crease 0"}


def test_exceeded_loads_name_the_arm(folds, tmp_path):
    """1 mm 5052-H32 with plain creases: each arm's pull is over its rating; `check_loads` refuses
    the program naming each arm, its crease and the groove remedy."""
    program = fk.plan(folds, DUAL, workdir=tmp_path, material="5052-H32", thickness="1mm", check_loads=True)
    assert not program.ok and program.toolpath is None
    assert any(p.startswith("arm a: load check: crease 0,") and "groove the crease" in p for p in program.problems)
    assert any(p.startswith("arm b: load check: crease 1,") for p in program.problems), program.problems


@pytest.mark.skipif(external_host() is not None, reason="two stand-ins")
def test_the_sheet_program_runs_on_two_stand_ins(planned, tmp_path):
    """The dry run: both arms fold in lockstep to the end, and each controller was told its own
    arm's payload (tool, tool + its share at the grip, tool after the release)."""
    program, checked = planned
    atp = program.toolpath
    hosts = free_loopback_hosts(random.Random())[:2]
    arms = {}
    try:
        for arm, host in zip(("a", "b"), hosts):
            arms[arm] = StandIn("--cell", str(DUAL), "--arm", arm, "--unlock-delay", "0.2",
                                log=tmp_path / f"ursim_{arm}.log", host=host)
        sent = fk.send(program, checked, host=hosts[0], hosts=(hosts[1],), power_on=True)
        assert sent.ok, sent.problems
        for arm, s in arms.items():
            pay = atp.arm(arm).extra["payload"]
            masses = [c["mass"] for c in s.admin("record")["commands"] if c["command"] == "set_payload"]
            steps = [m for i, m in enumerate(masses) if i == 0 or m != masses[i - 1]]
            assert steps == pytest.approx([pay["tool_mass_kg"], pay["held_mass_kg"], pay["tool_mass_kg"]], abs=1e-9)
            np.testing.assert_allclose(s.state()["q"], atp.arm(arm).waypoints[-1].q, atol=1e-6)
        print(f"two-arm sheet dry run: {len(atp)} waypoints per arm, cycle {atp.extra['cycle_time_s']:.1f} s")
    finally:
        for s in arms.values():
            s.stop()


def test_a_plain_and_a_permuted_obj_get_the_same_split_and_loads(tmp_path):
    """The tri-fold as a plain OBJ (no tags) and the same with its vertices and faces renumbered and
    each face's corners rotated, refolded and planned with the material as a user would: the same
    panel split, the same payload per arm (CoG within 1e-9 m) and the same load verdicts."""
    import json

    from holds_panels import trifold_pair
    from structure_panels import shuffled

    from fabkit.cli import main
    from fabkit.io.obj import save_obj
    from fabkit.mesh import PolyMesh
    from fabkit.placement import choose_clamp_face

    flat, target = trifold_pair()

    def plain(mesh):   # untagged
        return PolyMesh(mesh.vertices, mesh.faces_list())

    def renumbered(mesh):   # the same permutation of both meshes (same seed, same counts)
        return shuffled(plain(mesh), seed=5)[0]

    out = {}
    for name, make in {"plain": plain, "permuted": renumbered}.items():
        d = tmp_path / name
        d.mkdir()
        f, t = make(flat), make(target)
        save_obj(f, d / "flat.obj")
        save_obj(t, d / "target.obj")
        assert main(["refold", str(d / "flat.obj"), str(d / "target.obj"), "-o", str(d / "s.fold"), "--frames",
                     "3", "--fixed-face", str(choose_clamp_face(f)), "-q"]) == 0
        assert main(["toolpath", str(d / "s.fold"), "--cell", str(DUAL), "-o", str(d / "p.json"), "-q",
                     "--material", SHEET["material"], "--thickness", SHEET["thickness"]]) == 0
        out[name] = json.loads((d / "p.json").read_text())
    ref, got = out["plain"], out["permuted"]
    for holder, share in ref["sheet"]["panel_split"].items():
        assert got["sheet"]["panel_split"][holder]["strips"] == share["strips"]
        assert got["sheet"]["panel_split"][holder]["panel_kg"] == pytest.approx(share["panel_kg"], rel=1e-12)
    for a, b in zip(ref["arms"], got["arms"]):
        assert b["payload"]["held_mass_kg"] == pytest.approx(a["payload"]["held_mass_kg"], rel=1e-12)
        np.testing.assert_allclose(b["payload"]["held_cog_m"], a["payload"]["held_cog_m"], atol=1e-9, rtol=0)
    key = lambda v: (v["crease"], v["state"], v["check"])  # noqa: E731
    for a, b in zip(sorted(ref["sheet"]["loads"]["verdicts"], key=key), sorted(got["sheet"]["loads"]["verdicts"], key=key)):
        assert key(a) == key(b) and b["demand"] == pytest.approx(a["demand"], rel=1e-9)


def test_a_strip_between_two_holders_is_split_and_an_untagged_panel_is_not(folds):
    """`holder_shares` with the clamp on an end strip and one arm on the other end: the middle strip
    is as near to both, so each carries half of it (known answer from the strips' own masses); a
    panel without strip tags is not split (None: each arm then declares the whole panel)."""
    from fabkit.frames import face_groups
    from robot.arms_sheet import holder_shares

    model, spec = folds.model, _spec()
    groups = face_groups(model.faces_vertices, model.faces_data)
    end, far = (int(groups.ids[groups.strip == s][0]) for s in (0, 2))
    shares = holder_shares(model, spec, {"a": far}, fixed_face=end)
    flat = model.mesh()
    tris, tri_face = flat.triangulate()
    strip = np.asarray(model.faces_data["strip"])[tri_face]
    part = [panel_mass(spec, flat.vertices, tris[strip == s]).mass for s in (0, 1, 2)]
    assert shares["clamp"].mass == pytest.approx(part[0] + part[1] / 2, rel=1e-12)
    assert shares["a"].mass == pytest.approx(part[2] + part[1] / 2, rel=1e-12)
    assert shares["a"].strips == {1: 0.5, 2: 1.0} and shares["clamp"].strips == {0: 1.0, 1: 0.5}
    untagged = dataclasses.replace(model, faces_data={k: v for k, v in model.faces_data.items() if k != "strip"})
    assert holder_shares(untagged, spec, {"a": far}, fixed_face=end) is None
