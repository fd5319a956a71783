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

import os
from pathlib import Path

from fabkit.errors import InputError
from fabkit.results import Checked, Flat, Folds, Panel, Program, Relaxed, Sent
from fabkit.verdicts import DEFAULT_MAX_ERROR, DEFAULT_MAX_MOVE, DEFAULT_TARGET_RTOL

__all__ = ["load", "generate", "relax", "unfold", "refold", "plan", "check", "render", "send", "check_sheet", "check_render", "fold_source", "PlanSettings",
           "Panel", "Relaxed", "Flat", "Folds", "Program", "Checked", "Sent"]

#: file names in the working folder (those of `fabkit demo`)
FOLD_NAME, PATH_NAME, CHECK_NAME = "fold.fold", "path.json", "check.json"


def __getattr__(name: str):
    """`PlanSettings` and `fold_source` (fabkit.toolpath_stage), imported on first use so that
    the stages that do not plan (a no-op `fabkit relax`) do not load it."""
    if name in ("PlanSettings", "fold_source"):
        import fabkit.toolpath_stage as stage

        return getattr(stage, name)
    raise AttributeError(f"module 'fabkit.pipeline' has no attribute {name!r}")


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
           max_error: float | None = DEFAULT_MAX_ERROR, crease_angle: float | None = None, material="none",
           thickness=None, crease: str = "plain", ligament=None, bend_radius=None,
           design_surface: str = "top") -> Flat:
    """The flat pattern (`fabkit unfold`): `method` isometric | conformal | authalic; not ok when
    the max relative length deviation exceeds `max_error`, a face flips, the outline overlaps
    itself or the solver did not converge. `crease_angle` [deg]: see `fabkit unfold --help`.
    With a sheet (`material`, `thickness`, ... as in `plan`) the pattern is the sheet's neutral
    surface, `design_surface` (top | mid | bottom) the surface of the sheet the panel is; a fold
    tighter than the material's minimum radius is refused (`InputError` naming the crease)."""
    import numpy as np

    from fabkit.cutfiles import crease_assignment
    from fabkit.sheet import sheet_of
    from fabkit.unfold import develop
    from fabkit.verdicts import check_unfold_options, development_problems

    _require_ok(panel, "unfold")
    check_unfold_options(method, norm, max_error, crease_angle)
    spec = sheet_of(material, thickness, crease, ligament=ligament, bend_radius=bend_radius)
    mesh = panel.mesh
    norm_kw = {"norm": norm} if method == "isometric" else {}
    try:
        dev = develop(mesh, method=method, **norm_kw)
    except InputError as exc:
        raise exc.with_source(panel.name) from None
    creases = crease_assignment(mesh, None if crease_angle is None else np.radians(crease_angle))
    if not spec.rigid:  # the neutral surface of a thick sheet (fabkit.unfold.neutral, docs/sheet.md)
        from fabkit.sheet import check_bend_radius
        from fabkit.unfold.neutral import neutral_development

        folded = np.isin(creases.edges_assignment, ["M", "V"])
        if np.any(folded):
            e = int(np.flatnonzero(folded)[0])
            check_bend_radius(spec, f"crease edge {e} {tuple(int(v) for v in mesh.edges[e])}")
        dev = neutral_development(mesh, dev, spec, folded, design_surface, **norm_kw)
    problems = development_problems(dev, max_error)
    return Flat(mesh=dev.mesh(mesh), folded=mesh, development=dev, creases=creases, name=panel.name,
                max_error=max_error, ok=not problems, problems=tuple(problems), method=method,
                sheet=None if spec.rigid else spec, design_surface=design_surface, loaded=panel.loaded)


def refold(flat: Flat, target: Panel | Relaxed | None = None, *, frames: int = 20, drive="middle-row",
           steps=None, fixed_face: int | None = None, diagonal: str = "short", length_tol: float | None = None,
           target_tol: float = DEFAULT_TARGET_RTOL, solver: str = "direct", intersections: bool = True,
           title: str | None = None) -> Folds:
    """Fold states from `flat` to `target` (default: the panel `flat` was unfolded from), as
    `fabkit refold` (`fabkit.refold_stage.refold_meshes`): `frames` states per step, `drive`
    "middle-row" | "all" | hinge ids | a JSON drive file, `steps` e.g. "crease0,crease1" or a JSON
    schedule file. Not ok when target is not a fold of flat (edge lengths differ by more than
    `length_tol`), a state did not converge, the last state misses the target by more than
    `target_tol` of the panel size, or faces pass through each other. `title`: the FOLD file's
    `file_title` (default "refold of the flat pattern of NAME")."""
    from fabkit.refold_stage import refold_meshes

    _require_ok(flat, "refold")
    if target is not None:
        _require_ok(target, "refold")
    return refold_meshes(flat.mesh, flat.folded if target is None else target.mesh, frames=frames, drive=drive,
                         steps=steps, fixed_face=fixed_face, diagonal=diagonal, length_tol=length_tol,
                         target_tol=target_tol, solver=solver, intersections=intersections,
                         flat_name=f"the flat pattern of {flat.name}",
                         target_name=flat.name if target is None else target.name,
                         title=f"refold of the flat pattern of {flat.name}" if title is None else title)


def _workdir(workdir) -> Path:
    if workdir is None:
        import tempfile

        return Path(tempfile.mkdtemp(prefix="fabkit-"))
    path = Path(workdir)
    if path.exists() and not path.is_dir():
        raise InputError("the working folder is a file", source=str(path))
    path.mkdir(parents=True, exist_ok=True)
    return path


def plan(folds: Folds, cell: str | os.PathLike, *, workdir: str | os.PathLike | None = None,
         settings=None, **options) -> Program:
    """A UR toolpath for `folds` in the cell file `cell` (`fabkit toolpath`). Writes the fold
    states (`fold.fold`) and the toolpath (`path.json`) into `workdir` (made if missing; default:
    a new temporary folder) and plans from the FOLD file as written, recording its sha256.

    `options` are the fields of `fabkit.toolpath_stage.PlanSettings` (or pass `settings`), the
    options of `fabkit toolpath`: `grip_face`, `approach`, `standoff` [m], `tool_yaw` [deg],
    `fold_speed` [m/s], `max_joint_step` [deg]; the sheet `material` (a name, .toml path or
    `fabkit.materials.Material`), `thickness`, `ligament`, `bend_radius` (metres or text with a
    unit, "1mm"), `crease` plain | grooved | perforated, `tool_mass` [kg], `design_surface` top |
    mid | bottom, `check_loads`. With a material the path follows the springback-compensated
    states, path.json carries `sheet` and `payload`, and `details["loads"]` / `loads` the fold-load
    verdicts (with `check_loads`, exceeded loads make it not ok and write no path.json). Not ok (no
    path.json) when the path is unreachable, singular or discontinuous."""
    from dataclasses import replace

    from fabkit.toolpath_stage import PlanSettings, plan_fold_file

    _require_ok(folds, "plan")
    unknown = sorted(set(options) - set(PlanSettings.field_names()))
    if unknown:
        raise InputError(f"unknown option(s) {', '.join(unknown)}; options: {', '.join(PlanSettings.field_names())}",
                         source="plan")
    settings = replace(settings or PlanSettings(), **options)
    settings.check()
    settings.sheet()  # refuse bad sheet options before anything is written
    folder = _workdir(workdir)
    fold_file = folds.save(folder / FOLD_NAME)
    program = plan_fold_file(fold_file, cell, settings, workdir=folder)
    if not program.ok:
        return program
    path_file = folder / PATH_NAME
    program.toolpath.save(path_file)
    return replace(program, path_file=path_file)


def check_sheet(material=None, thickness=None, crease: str = "plain", ligament=None, bend_radius=None):
    """The sheet options of a check (`fabkit check --material ...`, `check(material=...)`) ->
    (`SheetSpec` or None, slab thickness [m] or None). With `material` the fold loads are checked
    for that sheet; without, `thickness` (metres, or text with a unit) is only the panel pieces'
    thickness, and the crease options are refused."""
    from fabkit.sheet import sheet_of

    if material is not None:
        return sheet_of(material, thickness, crease, ligament=ligament, bend_radius=bend_radius), None
    if crease != "plain" or ligament is not None or bend_radius is not None:
        raise InputError("--crease, --ligament and --bend-radius need --material", source="--material")
    if thickness is None:
        return None, None
    if isinstance(thickness, str):
        from fabkit.materials import parse_length

        return None, parse_length(thickness, "--thickness")
    if isinstance(thickness, bool) or not isinstance(thickness, (int, float)) or not 0 < thickness < 0.05:
        raise InputError(f"must be in (0, 0.05) m, got {thickness!r}", source="--thickness")
    return None, float(thickness)


def check(program: Program, *, use_panel: bool = True, thickness=None, material=None, crease: str = "plain",
          ligament=None, bend_radius=None) -> Checked:
    """The MuJoCo check of `program` (`fabkit check`), from its PATH.json and the FOLD file it
    names; writes `check.json` next to them. `to_json()` is that CHECK.json.

    A program planned with a material is checked for its fold loads too (not ok when one is
    exceeded; `report.loads` per state). `material` (with `thickness`, `crease`, ... as in
    `plan`) checks the loads of a program planned without one; for one planned with a material
    it must name the same sheet. Without `material`, `thickness` [m] is the panel pieces'
    (`check_sheet`)."""
    from fabkit.io.jsonfile import write_json
    from sim.check import CheckSettings, run_toolpath_check

    _require_ok(program, "check")
    sheet, thickness = check_sheet(material, thickness, crease, ligament, bend_radius)
    result = run_toolpath_check(str(program.path_file), program.cell, use_panel=use_panel, thickness=thickness,
                                settings=CheckSettings(), sheet=sheet)
    report = result.report
    check_file = program.workdir / CHECK_NAME
    write_json(check_file, report.to_json())
    problems = tuple(f"waypoint {p.waypoint}: {p.kind}: {p.detail}" for p in report.problems)
    return Checked(report=report, program=program, check_file=check_file, ok=bool(report.ok), problems=problems,
                   run=result)


def check_render(path: str | os.PathLike, size: tuple[int, int]) -> None:
    """Refuse a render `fabkit check --render` / `render` cannot make: a name not ending in .png or
    .mp4, a size outside 16x16 .. 1280x960, no offscreen OpenGL (EGL or OSMesa; chosen here, before
    mujoco is first imported)."""
    from sim.render import select_gl_backend

    if Path(path).suffix.lower() not in (".png", ".mp4"):
        raise InputError("must end in .png or .mp4", source="--render")
    w, h = size
    if not (16 <= w <= 1280 and 16 <= h <= 960):
        raise InputError(f"{w}x{h} is outside 16x16 .. 1280x960", source="--size")
    if select_gl_backend() is None:
        raise InputError("no offscreen OpenGL backend (install libegl1 libegl-mesa0 libgl1-mesa-dri, or libosmesa6; "
                         "or set MUJOCO_GL=egl before anything imports mujoco)", source="--render")


def render(checked: Checked, path: str | os.PathLike, *, waypoint: int | None = None,
           size: tuple[int, int] = (640, 480), frames: int = 240) -> dict:
    """A picture of a check (`fabkit check --render`): `path` ending in .png draws `waypoint`
    (default: the first problem, else the middle of the fold) with an offending pair in red, .mp4
    plays the whole program (at most `frames` frames). Needs offscreen OpenGL (EGL or OSMesa),
    chosen before mujoco is first imported. -> what was drawn (path, waypoint or frames)."""
    check_render(path, size)
    from sim.render_check import render_movie, render_waypoint

    suffix = Path(path).suffix.lower()

    cell = checked.program.cell
    if suffix == ".png":
        return render_waypoint(checked.run, cell, path, size, waypoint=waypoint)
    return render_movie(checked.run, cell, path, size, max_frames=frames)


def send(program: Program, report: Checked, *, host: str | None = None, power_on: bool = False, unlock: bool = False,
         resume_from: int = 0, chunk: int = 50, stall: float = 0.5, log=None, on_progress=None, hosts=()) -> Sent:
    """Send `program` to the UR controller at `host` over RTDE (`fabkit send`), through
    `robot.sender.send_toolpath`: it refuses, before any connection, unless `report` passed for this
    very toolpath, cell file and FOLD file, and runs the check again on what it sends. Refusals
    raise (`robot.interlock.CheckFailedError` for a failed check, `InterlockError`, `SendError`);
    once the controller was contacted the result says how far it got (`Sent.result.last_completed`).
    A two-arm program goes to `host` (arm a) and `hosts` (the further arms), in lockstep. Without
    `host`, the controllers are the cell's (`host` of every arm), else `$FABKIT_UR_HOST`, as for
    `fabkit send` (`robot.send_options.controller_hosts`). A stopped two-arm send names its resume
    in `Sent.result.resume` (`robot.lockstep.ResumePoint`)."""
    import os

    from robot.send_options import controller_hosts, send_option_problem
    from robot.sender import SendSettings, send_toolpath

    _require_ok(program, "send")
    names = getattr(program.toolpath, "arm_names", ("a",))
    (host, *hosts), _ = controller_hosts((host, *hosts) if host else hosts, program.cell, names,
                                         os.environ.get("FABKIT_UR_HOST"))
    for each in (host, *hosts):
        problem = send_option_problem(each, chunk, stall)
        if problem is not None:
            raise InputError(problem[1], source=problem[0])
    settings = SendSettings(host=host, chunk=chunk, resume_from=resume_from, power_on=power_on, unlock=unlock,
                            stall_s=stall, hosts=tuple(hosts))
    result = send_toolpath(program.toolpath, report.report, program.cell, settings, base_dir=program.workdir,
                           log=log, on_progress=on_progress)
    problems = () if result.ok else (f"stopped: {result.reason}; last completed waypoint {result.last_completed} "
                                     f"of {result.total - 1}",)
    return Sent(result=result, host=host, ok=bool(result.ok), problems=problems)
