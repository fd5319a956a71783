"""One panel of a production run: refold it, then program and check it, on the set-up that works.

A one-arm program clamps one end of the panel's middle row and grips the other end, so every
crease between is folded by something held (`fabkit.structure`: the clamp face is the middle-row
face of the first strip, the grip faces the others, farthest first; `fabkit refold` clamps the
same face). Which end goes on the clamp and which face of the sheet is up are free choices of the
fabricator, and the arm reaches some and not others: so the set-ups are tried in order

1. the structure's clamp face clamped, the far end gripped, the face up that makes the creases
   mountains seen from above (a panel whose creases fold mostly as valleys is laid back up);
2. the far end clamped, the structure's clamp face gripped, the same face up;
3. and 4. the same with the other face up,

and the first whose program plans and passes the check is kept (each with the refold and the
check of its own). A clamp face that the check finds the clamp cannot hold (its footprint leaves
the sheet the jaw can hold around the face, or the face bends) is not tried again with the other
face up. A set-up the program's check would refuse whatever its refold is refused before it is
refolded (`task["refuse_before_refold"]`, `refusal_before_refold`: the cup on the set-up's grip
face, from the flat pattern and the target). A panel for which none passes ends with the first
set-up's stage and reason, the others' named after it.
"""
from __future__ import annotations

import time

import numpy as np

from fabkit.errors import InputError

__all__ = ["Setup", "panel_setups", "clamp_problem", "refold_inputs", "refusal_before_refold", "refold_and_program",
           "panel_frame_of_task"]


class Setup(tuple):
    """(clamped face, gripped face, back face up)."""

    __slots__ = ()

    def __new__(cls, clamp: int, grip: int | None, back_up: bool):
        return super().__new__(cls, (int(clamp), None if grip is None else int(grip), bool(back_up)))

    clamp = property(lambda s: s[0])
    grip = property(lambda s: s[1])
    back_up = property(lambda s: s[2])

    def describe(self) -> str:
        up = "back" if self.back_up else "front"
        return f"clamp face {self.clamp}, grip face {self.grip}, {up} up"


def _meshes(task: dict):
    from fabkit.mesh import PolyMesh

    faces = np.asarray(task["faces"])
    fd = {k: np.asarray(v) for k, v in task["face_data"].items()}
    uv = np.asarray(task["uv"], dtype=np.float64)
    target = PolyMesh(np.asarray(task["relaxed"], dtype=np.float64), faces, face_data=fd)
    flat = PolyMesh(np.column_stack([uv, np.zeros(len(uv))]), faces, face_data=fd)
    return flat, target


def _mostly_valley(mesh) -> bool:
    """True when the panel's creases fold mostly as valleys (seen from its front, FOLD sign +)."""
    from fabkit.cutfiles.creases import crease_assignment

    ca = crease_assignment(mesh)
    c = np.isin(ca.edges_assignment, ("M", "V"))
    return bool(c.any() and ca.edges_fold_angle[c].sum() > 0)


def panel_setups(task: dict) -> list[Setup]:
    """The set-ups tried for a panel task, in order (module docstring)."""
    from fabkit.structure import pair_structure

    flat, target = _meshes(task)
    s = pair_structure(flat, target)
    far = int(s.grip_faces[0]) if len(s.grip_faces) else None
    rule = _mostly_valley(target)
    ends = [Setup(s.clamp_face, far, rule)]
    if far is not None:
        ends.append(Setup(far, s.clamp_face, rule))
    return ends + [Setup(e.clamp, e.grip, not rule) for e in ends]


def _panel_frame(uv: np.ndarray, faces, clamp: int, grip: int | None) -> np.ndarray:
    """The flat pattern in the panel frame: the clamped face's centroid at the fixture's origin and
    the gripped face on +y from it (a rotation; the pattern is not mirrored)."""
    c0 = uv[np.unique(faces[clamp])].mean(axis=0)
    if grip is None:
        return uv - c0
    d = uv[np.unique(faces[grip])].mean(axis=0) - c0
    a = np.pi / 2 - np.arctan2(d[1], d[0])
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    return (uv - c0) @ R.T


def panel_frame_of_task(task: dict) -> tuple[np.ndarray, Setup]:
    """(flat uv in the panel frame of the first set-up, that set-up): what the same-part grouping
    compares (`fabkit.panels.repeats`)."""
    setup = panel_setups(task)[0]
    return _panel_frame(np.asarray(task["uv"], np.float64), np.asarray(task["faces"]), setup.clamp, setup.grip), setup


def refold_inputs(task: dict, setup: Setup):
    """(flat, target) of a panel task for `setup`: the flat pattern in the panel frame and the
    relaxed panel the refold folds it into (faces reversed when the back is up)."""
    from fabkit.mesh import PolyMesh

    faces = np.asarray(task["faces"])
    fd = {k: np.asarray(v) for k, v in task["face_data"].items()}
    uv = _panel_frame(np.asarray(task["uv"], np.float64), faces, setup.clamp, setup.grip)
    if setup.back_up:  # the sheet laid back face up: mirrored across the panel frame's y axis
        faces = faces[:, ::-1]
        uv = uv * np.array([-1.0, 1.0])
    target = PolyMesh(np.asarray(task["relaxed"], np.float64), faces, face_data=fd)
    flat = PolyMesh(np.column_stack([uv, np.zeros(len(uv))]), faces, face_data=fd)
    return flat, target


def _refold_solver(task: dict, setup: Setup):
    """(RefoldSolver set up for `setup`, driven hinges, notes), or the reason it cannot be set up."""
    from fabkit.refold import NotAFoldError, RefoldSolver

    name = task["name"]
    flat, target = refold_inputs(task, setup)
    try:
        solver = RefoldSolver(flat, target, fixed_face=setup.clamp, length_rtol=task["length_tol"],
                              flat_name=f"{name} flat", target_name=f"{name} relaxed")
        driven, notes = solver.driven_hinges("middle-row")
    except (NotAFoldError, InputError) as exc:
        return str(exc)
    return solver, driven, notes


def refusal_before_refold(task: dict, setup: Setup, solver) -> str | None:
    """Why `setup` fails whatever its refold, from the flat pattern and the target alone, or None:
    `task["refuse_before_refold"](geometry, faces, cell_toml, cell_name, deviation_m=, sheet=,
    middle_row=)` (`sim.production.cup_refusal_before_refold`) on the two-state geometry of the
    set-up's solver (`fabkit.cup_before_refold`), the faces the planner may grip (the set-up's grip
    face when it is a middle-row face; every face of the panel without one, a set that holds every
    face the planner could try) and the last state's largest accepted deviation from the target."""
    from fabkit.cup_before_refold import flat_and_target_geometry
    from fabkit.refold.sequence import edge_kind_names

    refuse = task.get("refuse_before_refold")
    if refuse is None:
        return None
    middle = {int(f) for f in solver.structure.middle_row}
    if setup.grip is not None and setup.grip not in middle:  # the planner refuses it in its own words
        return None
    faces = [setup.grip] if setup.grip is not None else list(range(solver.flat.n_faces))
    p = solver.panel
    geometry = flat_and_target_geometry(solver.flat_vertices, p.tris, p.tri_face, p.edges, edge_kind_names(p),
                                        solver.target.vertices, solver.target_angles)
    return refuse(geometry, faces, task["cell_toml"], task["cell_name"],
                  deviation_m=float(task["target_tol"]) * float(solver.panel_size), sheet=task.get("sheet"),
                  middle_row=setup.grip is not None)


def _refold(task: dict, setup: Setup) -> tuple[dict | None, str | None, str]:
    """(refold summary or None, FOLD text or None, reason) of one set-up."""
    prepared = _refold_solver(task, setup)
    return (None, None, prepared) if isinstance(prepared, str) else _solve(task, *prepared)


def _solve(task: dict, solver, driven, notes) -> tuple[dict | None, str | None, str]:
    """(refold summary or None, FOLD text or None, reason) of one set-up's solver: its fold states."""
    from fabkit.fold import validate_fold_model
    from fabkit.io.fold import fold_text
    from fabkit.refold.export import to_fold_model
    from fabkit.refold.sequence import build_schedule

    name = task["name"]
    fractions, step_of_state = build_schedule(solver.panel, driven, None, int(task["frames"]))
    seq = solver.solve(fractions, driven, step_of_state, check_intersections=True, notes=notes)
    summary = seq.summary()
    rel = seq.target_distance / seq.panel_size if seq.panel_size > 0 else float("nan")
    if seq.failed_state >= 0 and seq.failure:  # states after the one that failed were not computed
        return summary, None, seq.failure
    if not seq.converged.all():
        return summary, None, next((n for n in seq.notes if "did not converge" in n), "a fold state did not converge")
    if not rel <= task["target_tol"]:
        return summary, None, (f"the last fold state is {rel:.3g} of the panel size from the relaxed panel "
                               f"(tol {task['target_tol']:g})")
    if summary["states_with_intersections"]:
        return summary, None, f"faces pass through each other in {summary['states_with_intersections']} fold states"
    model = to_fold_model(seq, title=f"fabkit refold of panel {name}", file_data={"fabkit:panel": name})
    validate_fold_model(model, source=name)
    return summary, fold_text(model), ""


def clamp_problem(check: dict | None, clamp: int) -> str | None:
    """The check's holds problem that no set-up clamping `clamp` escapes, or None: the clamp's
    footprint does not fit on the sheet the jaw can hold around the face, its centre is off the
    face, or the face bends in the fold states (not in the clamp's frame). These depend on the flat
    pattern, the cell and how far the states move the sheet around the face, which laying the
    other side up mirrors and does not change."""
    for q in (check or {}).get("problems", ()):
        d = q.get("detail", "")
        if q.get("kind") == "holds" and (f"leaves clamped face {clamp}:" in d or f"clamped face {clamp} moves" in d
                                           or f"mm off clamped face {clamp}" in d):
            return f"clamp face {clamp}: {d}"
    return None


def refold_and_program(task: dict) -> dict:
    """Refold one panel, then program and check it with `task["program"]`, set-up by set-up until
    one passes (module docstring). Pure: data in, data out."""
    t0 = time.perf_counter()
    name = task["name"]
    base = {"id": task["id"], "name": name, "stage": None, "reason": "", "fold": None, "toolpath": None,
            "check": None, "cycle_time_s": None, "grip_face": None, "refold": None, "face_up_on_fixture": None,
            "clamped_face": None, "loads": None, "setups": []}
    first = None
    unclampable: dict[int, str] = {}  # clamp face -> why the clamp cannot hold it (on any set-up)
    for setup in panel_setups(task):
        out = {**base, "face_up_on_fixture": "back" if setup.back_up else "front", "clamped_face": setup.clamp}
        if setup.clamp in unclampable:  # the face is the same flat shape with either face up: skipped
            base["setups"].append({"clamped_face": setup.clamp, "grip_face": setup.grip,
                                   "face_up_on_fixture": out["face_up_on_fixture"], "stage": "skipped",
                                   "reason": unclampable[setup.clamp]})
            continue
        prepared = _refold_solver(task, setup)
        refused = None if isinstance(prepared, str) else refusal_before_refold(task, setup, prepared[0])
        text = None
        if isinstance(prepared, str):
            out.update(stage="refold", reason=prepared)
        elif refused:  # the program's check would refuse it whatever the refold: not refolded
            out.update(stage="check", reason=refused)
        else:
            out["refold"], text, why = _solve(task, *prepared)
            if text is None:
                out.update(stage="refold", reason=why)
        if text is not None:
            out["fold"] = text
            prog = task["program"](text, f"{name}_refold.fold", task["cell_toml"], task["cell_name"],
                                   task["thickness"], grip_face=setup.grip, sheet=task.get("sheet"),
                                   tool_mass=task.get("tool_mass"))
            out.update({k: prog.get(k) for k in ("stage", "reason", "toolpath", "check", "cycle_time_s", "grip_face",
                                                 "loads")})
            if prog.get("unclampable"):  # refused by the check's clamp footprint before planning
                unclampable[setup.clamp] = f"clamp face {setup.clamp}: {prog['unclampable']}"
        base["setups"].append({"clamped_face": setup.clamp, "grip_face": setup.grip,
                               "face_up_on_fixture": out["face_up_on_fixture"], "stage": out["stage"],
                               "reason": out["reason"]})
        if out["stage"] is None:
            return {**out, "setups": base["setups"], "seconds": time.perf_counter() - t0}
        why_not = clamp_problem(out.get("check"), setup.clamp)
        if why_not and setup.clamp not in unclampable:
            unclampable[setup.clamp] = why_not
        first = first or out
    others = "; ".join(f"{Setup(s['clamped_face'], s['grip_face'], s['face_up_on_fixture'] == 'back').describe()}: "
                       f"{s['stage']}: {s['reason'][:160]}" for s in base["setups"][1:] if s["stage"] != "skipped")
    reason = first["reason"] + (f" [every set-up fails; also tried: {others}]" if others else "")
    return {**first, "reason": reason, "setups": base["setups"], "seconds": time.perf_counter() - t0}
