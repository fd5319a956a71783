"""The pipeline as functions: load/generate -> relax -> unfold -> refold -> plan -> check -> send.

Each stage is one typed function returning a frozen result (`fabkit.results`) with `ok`,
`problems` (the verdicts the CLI prints, with the CLI's default tolerances) and `to_json()`:

    panel = fk.load("panel.obj", units="mm")      # or fk.generate("trifold")
    relaxed = fk.relax(panel)
    flat = fk.unfold(relaxed)
    folds = fk.refold(flat, relaxed)
    program = fk.plan(folds, "cells/ur5e_bench.toml")
    report = fk.check(program)                    # CHECK.json, as `fabkit check` writes it
    fk.render(report, "check.png")                # a picture of the check (optional)
    fk.send(program, report, host="192.168.0.10")  # through the safety gate

A stage refuses (`InputError`) a result that is not `ok`: the CLI would have stopped there too
(relax writes no panel, refold no states, toolpath no program). Verdicts come from the library:
`fabkit.verdicts` (relax, unfold), `FoldSequence.problems` (refold), the planner's
`PlanningError` (plan), `sim.check.CheckReport` (check), `robot.sender.send_toolpath` (send).

Files: the check verifies the FOLD file a toolpath was planned from by its sha256, and the robot
side reads programs from files, so `plan` writes the fold states and the program into a working
folder - `workdir` if given, else a new temporary folder (`Program.workdir`, never removed by
fabkit) - as `fold.fold` and `path.json`, exactly what `fabkit refold -o` / `fabkit toolpath -o`
write; `check` writes `check.json` there. `fabkit check workdir/path.json` gives the same report.

Layering: this is the one module of `fabkit` besides the CLI that reaches the robot and simulation
layers, because `import fabkit` exposes every stage: `plan`, `check` and `send` import `robot` /
`sim` inside the function, so `import fabkit` loads neither (nor numpy).
"""
from __future__ import annotations

import math
import os
from pathlib import Path

from fabkit.errors import InputError
from fabkit.results import Checked, Flat, Folds, Panel, Program, Relaxed, Sent
from fabkit.verdicts import DEFAULT_MAX_ERROR, DEFAULT_MAX_MOVE, DEFAULT_TARGET_RTOL, MAX_REFOLD_FRAMES

__all__ = ["load", "generate", "relax", "unfold", "refold", "plan", "check", "render", "send", "fold_source",
           "Panel", "Relaxed", "Flat", "Folds", "Program", "Checked", "Sent"]

#: file names in the working folder (those of `fabkit demo`)
FOLD_NAME, PATH_NAME, CHECK_NAME = "fold.fold", "path.json", "check.json"


def _require_ok(result, stage: str) -> None:
    if not getattr(result, "ok", True):
        raise InputError(f"{stage} needs a result that passed; it has: " + "; ".join(result.problems),
                         source=getattr(result, "name", stage))


def load(path: str | os.PathLike, units: str | None = None) -> Panel:
    """Read a panel (.obj, .fold's last state, .3dm, .svg) into metres; `units` (m, mm, cm, in) is
    the unit of a file that does not declare one. The loader's notes are `Panel.notes`."""
    from fabkit.io.load import load_panel

    mesh, info = load_panel(path, units)
    return Panel(mesh=mesh, name=Path(path).name, loaded=info)


def generate(preset: str, **params) -> Panel:
    """A procedural panel (`fabkit generate PRESET --param value`): e.g. `generate("trifold",
    resolution=6)`; parameters in metres and degrees, see `fabkit generate --help`."""
    from fabkit.presets import build_preset

    mesh, used = build_preset(preset, **params)
    return Panel(mesh=mesh, name=f"preset {preset}", params=used)


def relax(panel: Panel, *, max_move: float = DEFAULT_MAX_MOVE, **options) -> Relaxed:
    """Dynamic relaxation toward a developable planar-quad panel. `options` are
    `fabkit.relax.RelaxOptions` fields (tol_defect, method, boundary, crease_fairness, ...); not ok
    when a tolerance is missed or a vertex moved more than `max_move` x the panel size."""
    from fabkit.relax import Relaxer, RelaxOptions
    from fabkit.verdicts import relax_problems

    _require_ok(panel, "relax")
    if not (max_move > 0):
        raise InputError(f"must be a positive share of the panel size, got {max_move}", source="max_move")
    try:
        opts = RelaxOptions(**options)
    except (TypeError, ValueError) as exc:
        raise InputError(str(exc), source="relax options") from None
    result = Relaxer(panel.mesh, opts, source=panel.name).solve()
    problems = relax_problems(result, panel.mesh.size, max_move)
    return Relaxed(mesh=result.mesh, result=result, input=panel, max_move=max_move, ok=not problems,
                   problems=tuple(problems))


def unfold(panel: Panel | Relaxed, *, method: str = "isometric", norm: float = 2.0,
           max_error: float | None = DEFAULT_MAX_ERROR, crease_angle: float | None = None) -> Flat:
    """The flat pattern (`fabkit unfold`): `method` isometric | conformal | authalic; not ok when
    the max relative length deviation exceeds `max_error`, a face flips, the outline overlaps
    itself or the solver did not converge. `crease_angle` [deg]: see `fabkit unfold --help`."""
    import numpy as np

    from fabkit.cutfiles import crease_assignment
    from fabkit.unfold import develop
    from fabkit.verdicts import development_problems

    _require_ok(panel, "unfold")
    if max_error is not None and not (math.isfinite(max_error) and max_error > 0):
        raise InputError(f"must be a positive number, got {max_error}", source="max_error")
    mesh = panel.mesh
    dev = develop(mesh, method=method, **({"norm": norm} if method == "isometric" else {}))
    creases = crease_assignment(mesh, None if crease_angle is None else np.radians(crease_angle))
    problems = development_problems(dev, max_error)
    return Flat(mesh=dev.mesh(mesh), folded=mesh, development=dev, creases=creases, name=panel.name,
                max_error=max_error, ok=not problems, problems=tuple(problems))


def refold(flat: Flat, target: Panel | Relaxed | None = None, *, frames: int = 20, drive="middle-row",
           steps=None, fixed_face: int | None = None, diagonal: str = "short", length_tol: float | None = None,
           target_tol: float = DEFAULT_TARGET_RTOL, solver: str = "direct", intersections: bool = True,
           title: str | None = None) -> Folds:
    """Fold states from `flat` to `target` (default: the panel `flat` was unfolded from), as
    `fabkit refold`: `frames` states per step, `drive` "middle-row" | "all" | hinge ids, `steps`
    e.g. "crease0,crease1". Not ok when target is not a fold of flat (edge lengths differ by more
    than `length_tol`), a state did not converge, the last state misses the target by more than
    `target_tol` of the panel size, or faces pass through each other. `title`: the FOLD file's
    `file_title` (default "refold of the flat pattern of NAME")."""
    from fabkit.refold import DEFAULT_LENGTH_RTOL, NotAFoldError, RefoldSolver
    from fabkit.refold.export import to_fold_model
    from fabkit.refold.sequence import build_schedule, parse_steps

    _require_ok(flat, "refold")
    target_mesh = flat.folded if target is None else target.mesh
    if target is not None:
        _require_ok(target, "refold")
    if not 2 <= frames <= MAX_REFOLD_FRAMES:
        raise InputError(f"must be in 2..{MAX_REFOLD_FRAMES} (flat and target included), got {frames}",
                         source="frames")
    length_tol = DEFAULT_LENGTH_RTOL if length_tol is None else length_tol
    try:
        rs = RefoldSolver(flat.mesh, target_mesh, fixed_face=fixed_face, diagonal=diagonal, length_rtol=length_tol,
                          solver=solver, flat_name=f"the flat pattern of {flat.name}",
                          target_name=flat.name if target is None else target.name)
    except NotAFoldError as exc:
        return Folds(sequence=None, model=None, name=flat.name, target_tol=target_tol, ok=False,
                     problems=(str(exc),), details={"worst_edge": list(exc.edge),
                                                    "worst_relative_length_difference": exc.relative})
    driven, notes = rs.driven_hinges(drive) if isinstance(drive, str) else (drive, [])
    if isinstance(steps, str):
        steps = parse_steps(steps, rs.panel, driven)
    fractions, step_of_state = build_schedule(rs.panel, driven, steps, frames)
    seq = rs.solve(fractions, driven, step_of_state, check_intersections=intersections, notes=notes)
    problems = seq.problems(target_tol)
    model = to_fold_model(seq, title=f"refold of the flat pattern of {flat.name}" if title is None else title)
    return Folds(sequence=seq, model=model, name=flat.name, target_tol=target_tol, ok=not problems,
                 problems=tuple(problems), details={"length_tol": length_tol, "frames_per_step": frames,
                                                    "structure": rs.structure.summary(flat.mesh),
                                                    "max_relative_length_difference": rs.max_length_mismatch})


def _workdir(workdir) -> Path:
    if workdir is None:
        import tempfile

        return Path(tempfile.mkdtemp(prefix="fabkit-"))
    path = Path(workdir)
    if path.exists() and not path.is_dir():
        raise InputError("the working folder is a file", source=str(path))
    path.mkdir(parents=True, exist_ok=True)
    return path


def fold_source(fold_file: str | os.PathLike, states: int) -> dict:
    """The provenance a toolpath records of the FOLD file it is planned from: its name (resolved
    against the PATH.json's folder when checked), sha256 and number of fold states."""
    import hashlib

    path = Path(fold_file)
    return {"file": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest(), "states": int(states)}


def plan(folds: Folds, cell: str | os.PathLike, *, workdir: str | os.PathLike | None = None,
         grip_face: int | None = None, approach: float | None = None, standoff: float | None = None,
         tool_yaw: float | None = None, fold_speed: float | None = None,
         max_joint_step: float | None = None, material="none", thickness=None, crease: str = "plain",
         ligament=None, bend_radius=None, tool_mass: float | None = None, check_loads: bool = False,
         design_surface: str = "top") -> Program:
    """A UR toolpath for `folds` in the cell file `cell` (`fabkit toolpath`). Writes the fold
    states (`fold.fold`) and the toolpath (`path.json`) into `workdir` (made if missing; default:
    a new temporary folder) and plans from the FOLD file as written, recording its sha256. Options
    as `fabkit toolpath` (metres, m/s; `tool_yaw`, `max_joint_step` in degrees); None: the
    planner's defaults.

    The sheet (`material` a name, .toml path or `fabkit.materials.Material`; `thickness`,
    `ligament`, `bend_radius` in metres or as text with a unit, "1mm"; `crease` plain | grooved |
    perforated; `tool_mass` kg; `design_surface` top | mid | bottom) as `fabkit toolpath
    --material ...`: the path follows the
    springback-compensated states, path.json carries `sheet` and `payload`, and
    `details["loads"]` the fold-load verdicts (with `check_loads`, exceeded loads make it not ok
    and write no path.json). Not ok (no path.json) when the path is unreachable, singular or
    discontinuous."""
    from dataclasses import replace

    from fabkit.frames import planning_frames
    from fabkit.io.load import load_fold_model
    from fabkit.sheet import sheet_of
    from robot.cell import load_cell
    from robot.holds_record import clamped_faces_of
    from robot.panel_placement import placed_cell, placement_for
    from robot.grip_choice import approach_variants
    from robot.sheet_program import compensated_states, sheet_records
    from sim.grip_search import checked_acceptor
    from robot.toolpath import PlanningError, PlanOptions, plan_panel
    from sim.panel import check_fold_coordinates

    _require_ok(folds, "plan")
    if tool_mass is not None and not (math.isfinite(tool_mass) and 0 <= tool_mass <= 20):
        raise InputError(f"{tool_mass} kg is not in [0, 20]", source="tool_mass")
    spec = sheet_of(material, thickness, crease, ligament=ligament, bend_radius=bend_radius)
    from fabkit.sheet import DESIGN_SURFACES

    if design_surface not in DESIGN_SURFACES or (spec.rigid and design_surface != "top"):
        raise InputError(f"must be one of {', '.join(DESIGN_SURFACES)}, with a material other than none for "
                         f"another than top; got {design_surface!r}", source="design_surface")
    cell_obj = load_cell(cell)
    folder = _workdir(workdir)
    fold_file = folds.save(folder / FOLD_NAME)
    model, _ = load_fold_model(fold_file)
    check_fold_coordinates(model, source=str(fold_file))
    design_model, compensated = model, compensated_states(model, spec, source=str(fold_file))
    if compensated is not None:
        model = compensated.model
    frames = planning_frames(model, grip_face, source=str(fold_file))
    options = PlanOptions()
    given = {"approach_distance": approach, "grip_standoff": standoff,
             "tool_yaw": None if tool_yaw is None else math.radians(tool_yaw),
             "max_joint_step": None if max_joint_step is None else math.radians(max_joint_step)}
    options = replace(options, **{k: v for k, v in given.items() if v is not None})
    if not spec.rigid:  # the cup grips the sheet's top face
        from fabkit.sheet import front_face_offset

        options = replace(options, grip_standoff=options.grip_standoff + front_face_offset(spec, design_surface))
    if fold_speed is not None:
        options = replace(options, params=replace(options.params, fold_speed=fold_speed))
    source = fold_source(fold_file, frames.n_states)
    common = dict(workdir=folder, fold_file=fold_file, cell=cell_obj, cell_file=Path(cell),
                  details={"states": int(frames.n_states), "middle_row": frames.faces.tolist()})
    try:
        placement = placement_for(cell_obj, model)   # the clamped face on the cell's clamp
        res = plan_panel(placed_cell(cell_obj, placement), frames, grip_face=grip_face, options=options,
                         source=source, clamped_faces=clamped_faces_of(model), placement=placement,
                         # grip faces tried through the check (a sheet program is checked as compensated, later)
                         accept=None if compensated is not None else checked_acceptor(cell_obj, fold_file),
                         variants=approach_variants(options) if approach is None else ())
    except PlanningError as exc:
        return Program(toolpath=None, path_file=None, plan=None, ok=False, problems=(str(exc),), **common)
    from robot.jig_holds import with_jig_holds

    tp = with_jig_holds(res.toolpath, cell_obj, model)   # the faces the cell's jigs hold (PATH.json holds.jigs)
    if compensated is not None:
        tp, loads = sheet_records(tp, spec, design_model, compensated, cell_obj, res.grip_face, tool_mass,
                                  design_surface=design_surface)
        common["details"]["loads"] = loads.summary()
        if check_loads and not loads.ok:
            return Program(toolpath=None, path_file=None, plan=None, ok=False, problems=tuple(loads.failure_lines()),
                           **common)
    path_file = folder / PATH_NAME
    tp.save(path_file)
    return Program(toolpath=tp, path_file=path_file, plan=res, ok=True, problems=(), **common)


def check(program: Program, *, use_panel: bool = True, thickness=None, material=None, crease: str = "plain",
          ligament=None, bend_radius=None) -> Checked:
    """The MuJoCo check of `program` (`fabkit check`), from its PATH.json and the FOLD file it
    names; writes `check.json` next to them. `to_json()` is that CHECK.json.

    A program planned with a material is checked for its fold loads too (not ok when one is
    exceeded; `report.loads` per state). `material` (with `thickness`, `crease`, ... as in
    `plan`) checks the loads of a program planned without one; for one planned with a material
    it must name the same sheet. Without `material`, `thickness` [m] is the panel pieces'."""
    from fabkit.io.jsonfile import write_json
    from fabkit.sheet import sheet_of
    from sim.check import CheckSettings, run_toolpath_check

    _require_ok(program, "check")
    sheet = None
    if material is not None:
        sheet, thickness = sheet_of(material, thickness, crease, ligament=ligament, bend_radius=bend_radius), None
    if thickness is not None and not 0 < thickness < 0.05:
        raise InputError(f"must be in (0, 0.05) m, got {thickness}", source="thickness")
    result = run_toolpath_check(str(program.path_file), program.cell, use_panel=use_panel, thickness=thickness,
                                settings=CheckSettings(), sheet=sheet)
    report = result.report
    check_file = program.workdir / CHECK_NAME
    write_json(check_file, report.to_json())
    problems = tuple(f"waypoint {p.waypoint}: {p.kind}: {p.detail}" for p in report.problems)
    return Checked(report=report, program=program, check_file=check_file, ok=bool(report.ok), problems=problems,
                   run=result)


def render(checked: Checked, path: str | os.PathLike, *, waypoint: int | None = None,
           size: tuple[int, int] = (640, 480), frames: int = 240) -> dict:
    """A picture of a check (`fabkit check --render`): `path` ending in .png draws `waypoint`
    (default: the first problem, else the middle of the fold) with an offending pair in red, .mp4
    plays the whole program (at most `frames` frames). Needs offscreen OpenGL (EGL or OSMesa),
    chosen before mujoco is first imported. -> what was drawn (path, waypoint or frames)."""
    from sim.render import select_gl_backend

    suffix = Path(path).suffix.lower()
    if suffix not in (".png", ".mp4"):
        raise InputError("must end in .png or .mp4", source=str(path))
    w, h = size
    if not (16 <= w <= 1280 and 16 <= h <= 960):
        raise InputError(f"{w}x{h} is outside 16x16 .. 1280x960", source="size")
    if select_gl_backend() is None:
        raise InputError("no offscreen OpenGL backend (install libegl1 libegl-mesa0 libgl1-mesa-dri, or libosmesa6; "
                         "or set MUJOCO_GL=egl before anything imports mujoco)", source=str(path))
    from sim.render_check import render_movie, render_waypoint

    cell = checked.program.cell
    if suffix == ".png":
        return render_waypoint(checked.run, cell, path, size, waypoint=waypoint)
    return render_movie(checked.run, cell, path, size, max_frames=frames)


def send(program: Program, report: Checked, *, host: str, power_on: bool = False, unlock: bool = False,
         resume_from: int = 0, chunk: int = 50, stall: float = 0.5, log=None, on_progress=None) -> Sent:
    """Send `program` to the UR controller at `host` over RTDE (`fabkit send`), through
    `robot.sender.send_toolpath`: it refuses, before any connection, unless `report` passed for this
    very toolpath, cell file and FOLD file, and runs the check again on what it sends. Refusals
    raise (`robot.interlock.CheckFailedError` for a failed check, `InterlockError`, `SendError`);
    once the controller was contacted the result says how far it got (`Sent.result.last_completed`)."""
    from robot.send_options import send_option_problem
    from robot.sender import SendSettings, send_toolpath

    _require_ok(program, "send")
    problem = send_option_problem(host, chunk, stall)
    if problem is not None:
        raise InputError(problem[1], source=problem[0])
    settings = SendSettings(host=host, chunk=chunk, resume_from=resume_from, power_on=power_on, unlock=unlock,
                            stall_s=stall)
    result = send_toolpath(program.toolpath, report.report, program.cell, settings, base_dir=program.workdir,
                           log=log, on_progress=on_progress)
    problems = () if result.ok else (f"stopped: {result.reason}; last completed waypoint {result.last_completed} "
                                     f"of {result.total - 1}",)
    return Sent(result=result, host=host, ok=bool(result.ok), problems=problems)
