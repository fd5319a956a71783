"""The plan stage: a FOLD file of fold states -> a UR toolpath, for `fk.plan` and `fabkit toolpath`.

`plan_fold_file(fold_file, cell_file, settings)` does everything between reading the FOLD file and
holding a planned `robot.toolpath.Toolpath`: it checks the options (`PlanSettings.check`, the
messages name the CLI options, as every verdict of the API does), reads the cell and the FOLD file,
follows the springback-compensated states for a sheet, chooses the grip face through the MuJoCo
check (`sim.grip_search`), and for a sheet adds the `sheet` and `payload` records and the fold-load
verdicts (`robot.sheet_program`; for a cell with two arms a payload and the fold loads per arm,
`robot.arms_sheet`). It writes nothing: `fk.plan` saves path.json into its working folder, the CLI into `-o`.

`PlanSettings` is the one record of the planning options; `fk.plan(**fields)` and the CLI's options
(`--grip-face` is the field `grip_face`) both become one, so an option added here reaches both.

Layering: like `fabkit.pipeline`, this module imports `robot` and `sim` inside its functions only
(`import fabkit` loads neither); it is the one place in `fabkit` that runs the planner.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields
from pathlib import Path

from fabkit.errors import InputError

__all__ = ["PlanSettings", "plan_fold_file", "fold_source", "check_progress_register", "cli_option"]


#: `PlanSettings.grip_side`: the side the cup grips, or "any" (front first).
GRIP_SIDE_CHOICES = ("any", "front", "back")


def cli_option(field_name: str) -> str:
    """The command-line option of a settings field: `grip_face` -> `--grip-face`."""
    return "--" + field_name.replace("_", "-")


@dataclass(frozen=True)
class PlanSettings:
    """The options of the plan stage (None: the planner's default). Lengths in metres, speeds in
    m/s, `tool_yaw` and `max_joint_step` in degrees; the sheet as `fabkit.sheet.sheet_of`
    (`material` a name, .toml path or `Material`; lengths in metres or text with a unit)."""

    grip_face: int | None = None         # default: chosen among the middle-row faces, through the check
    grip_side: str = "any"               # front | back | any (every face's front first, then the back)
    approach: float | None = None        # approach/retract distance [m], (0, 0.5]; default 0.08 (+ variants)
    standoff: float | None = None        # TCP distance from the face when gripping [m], [0, 0.1]; default 0
    tool_yaw: float | None = None        # [deg]; default automatic for axial tools
    fold_speed: float | None = None      # TCP speed while folding [m/s], > 0; default 0.05, capped by the cell
    max_joint_step: float | None = None  # largest joint change between fold waypoints [deg], [0.1, 30]; default 5
    material: object = "none"
    thickness: object = None
    crease: str = "plain"
    ligament: object = None
    bend_radius: object = None
    tool_mass: float | None = None       # gripper mass for the payload [kg], [0, 20]; default 1.0 (noted)
    check_loads: bool = False            # exceeded fold loads make the plan fail (default: warnings)
    design_surface: str = "top"          # which sheet surface the FOLD's faces are: top | mid | bottom

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    def check(self) -> None:
        """Refuse values out of range (`InputError` naming the CLI option)."""
        def bad(name, text):
            raise InputError(text, source=cli_option(name))

        def finite(v):
            return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)

        if self.grip_face is not None and not (isinstance(self.grip_face, int) and self.grip_face >= 0):
            bad("grip_face", f"{self.grip_face!r} is not a face id")
        if self.grip_side not in GRIP_SIDE_CHOICES:
            bad("grip_side", f"{self.grip_side!r} is not one of {', '.join(GRIP_SIDE_CHOICES)}")
        if self.approach is not None and not (finite(self.approach) and 0.0 < self.approach <= 0.5):
            bad("approach", f"{self.approach} m is not in (0, 0.5]")
        if self.standoff is not None and not (finite(self.standoff) and 0.0 <= self.standoff <= 0.1):
            bad("standoff", f"{self.standoff} m is not in [0, 0.1]")
        if self.fold_speed is not None and not (finite(self.fold_speed) and self.fold_speed > 0):
            bad("fold_speed", f"{self.fold_speed} m/s must be > 0")
        if self.max_joint_step is not None and not (finite(self.max_joint_step) and 0.1 <= self.max_joint_step <= 30):
            bad("max_joint_step", f"{self.max_joint_step} deg is not in [0.1, 30]")
        if self.tool_yaw is not None and not finite(self.tool_yaw):
            bad("tool_yaw", "must be a finite angle")
        if self.tool_mass is not None and not (finite(self.tool_mass) and 0 <= self.tool_mass <= 20):
            bad("tool_mass", f"{self.tool_mass} kg is not in [0, 20]")

    def sheet(self):
        """The `fabkit.sheet.SheetSpec` these settings name; `InputError` for a design surface other
        than top without a material."""
        from fabkit.sheet import DESIGN_SURFACES, sheet_of

        spec = sheet_of(self.material, self.thickness, self.crease, ligament=self.ligament,
                        bend_radius=self.bend_radius)
        if self.design_surface not in DESIGN_SURFACES:
            raise InputError(f"must be one of {', '.join(DESIGN_SURFACES)}, got {self.design_surface!r}",
                             source="--design-surface")
        if spec.rigid and self.design_surface != "top":
            raise InputError("needs a --material other than none", source="--design-surface")
        return spec


def check_progress_register(register: int | None) -> None:
    """The URScript progress register must be an output integer register (0..47)."""
    if register is not None and not (isinstance(register, int) and 0 <= register <= 47):
        raise InputError(f"{register} is outside 0..47", source="--progress-register")


def fold_source(fold_file: str | os.PathLike, states: int) -> dict:
    """The provenance a toolpath records of the FOLD file it is planned from: its name (resolved
    against the PATH.json's folder when checked), sha256 and number of fold states."""
    import hashlib

    path = Path(fold_file)
    return {"file": path.name, "sha256": hashlib.sha256(path.read_bytes()).hexdigest(), "states": int(states)}


def _planner_options(settings: PlanSettings, spec):
    """`robot.planner.PlanOptions` from the settings; a sheet's cup grips its top face, so the
    standoff grows by `fabkit.sheet.front_face_offset`."""
    from dataclasses import replace

    from robot.toolpath import PlanOptions

    options = PlanOptions()
    given = {"approach_distance": settings.approach, "grip_standoff": settings.standoff,
             "tool_yaw": None if settings.tool_yaw is None else math.radians(settings.tool_yaw),
             "max_joint_step": None if settings.max_joint_step is None else math.radians(settings.max_joint_step)}
    options = replace(options, **{k: v for k, v in given.items() if v is not None})
    if not spec.rigid:
        from fabkit.sheet import front_face_offset

        options = replace(options, grip_standoff=options.grip_standoff + front_face_offset(spec, settings.design_surface))
    if settings.fold_speed is not None:
        options = replace(options, params=replace(options.params, fold_speed=settings.fold_speed))
    return options


def _grip_side_options(options, settings: PlanSettings, spec):
    """(first `PlanOptions`, further variants) for `settings.grip_side`: "any" tries the front side
    (with approach variants when no approach is given), then the back; "front" or "back" that side
    only."""
    from dataclasses import replace

    from robot.grip_choice import GRIP_SIDES, approach_variants, grip_variants

    vary = settings.approach is None
    if settings.grip_side == "back":
        options = replace(options, grip_side="back", grip_standoff=_back_standoff(settings, spec))
        return options, approach_variants(options) if vary else ()
    sides = GRIP_SIDES if settings.grip_side == "any" else ("front",)
    return options, grip_variants(options, vary_approach=vary, back_standoff=_back_standoff(settings, spec),
                                  sides=sides)


def _back_standoff(settings: PlanSettings, spec) -> float:
    """The TCP standoff of a cup on the sheet's back face: behind the design surface by
    `fabkit.sheet.back_face_offset` (0 for a rigid panel of no thickness)."""
    from fabkit.sheet import back_face_offset
    from robot.toolpath import PlanOptions

    standoff = PlanOptions().grip_standoff if settings.standoff is None else settings.standoff
    return standoff + (0.0 if spec.rigid else back_face_offset(spec, settings.design_surface))


def plan_fold_file(fold_file: str | os.PathLike, cell_file: str | os.PathLike,
                   settings: PlanSettings = PlanSettings(), *, units: str | None = None, workdir=None):
    """Plan the FOLD file `fold_file` in the cell file `cell_file` (module docstring) ->
    `fabkit.results.Program` with `path_file` None (nothing is written). Not ok when the path is
    unreachable, singular or discontinuous, or (with `check_loads`) a fold load is exceeded.
    `units`: the FOLD file's unit when it declares none. Bad input raises `InputError`."""
    from fabkit.frames import planning_frames
    from fabkit.io.load import load_fold_model
    from fabkit.results import Program
    from robot.cell import load_cell
    from robot.plan_cell import plan_in_cell
    from robot.sheet_program import compensated_states, sheet_records
    from robot.toolpath import PlanningError
    from sim.grip_search import checked_acceptor
    from sim.panel import check_fold_coordinates

    settings.check()
    spec = settings.sheet()
    cell = load_cell(cell_file)
    fold_file = Path(fold_file)
    source_name = str(fold_file)
    model, loaded = load_fold_model(fold_file, units)
    check_fold_coordinates(model, source=source_name)  # a vertex at 1e300 is bad input, not a motion
    if model.n_frames == 0:
        raise InputError("has no fold states (no file_frames)", source=source_name)
    design_model, compensated = model, compensated_states(model, spec, source=source_name)
    if compensated is not None:
        model = compensated.model
    frames = planning_frames(model, settings.grip_face, source=source_name)
    options = _planner_options(settings, spec)
    notes = []  # the stage's own; the loader's are `loaded.notes`
    common = dict(workdir=Path(workdir) if workdir is not None else fold_file.parent, fold_file=fold_file,
                  cell=cell, cell_file=Path(cell_file), loaded=loaded,
                  details={"states": int(frames.n_states), "middle_row": frames.faces.tolist()})
    options, variants = _grip_side_options(options, settings, spec)
    try:
        res = plan_in_cell(cell, model, frames, grip_face=settings.grip_face, options=options,
                           source=fold_source(fold_file, frames.n_states),
                           # grip faces tried through the check (a sheet program is checked as compensated, later)
                           accept=None if compensated is not None else checked_acceptor(cell, str(fold_file)),
                           variants=variants,
                           sheet=compensated is not None, fold_file=fold_file)
    except PlanningError as exc:
        if compensated is not None and len(cell.arms) == 1:   # robot.phased_planner: rigid programs only
            notes.append("no regrip in phases was tried: springback between a release and the regrip is not "
                         "modelled for a sheet")
        return Program(toolpath=None, path_file=None, plan=None, ok=False, problems=(str(exc),),
                       records=(exc.as_problem(),), notes=tuple(notes), **common)
    from robot.jig_holds import with_jig_holds

    tp, loads = with_jig_holds(res.toolpath, cell, model), None   # the faces the cell's jigs hold (holds.jigs)
    if compensated is not None:  # angles, payload and fold loads into PATH.json
        if settings.tool_mass is None:
            notes.append("payload with an assumed 1.0 kg gripper (give --tool-mass)")
        if hasattr(tp, "arms"):  # two arms: a payload and fold loads per arm (robot.arms_sheet)
            from robot.arms_sheet import arms_sheet_records

            tp, loads = arms_sheet_records(tp, spec, design_model, compensated, cell, res.grips, settings.tool_mass,
                                           design_surface=settings.design_surface)
        else:
            tp, loads = sheet_records(tp, spec, design_model, compensated, cell, res.grip_face, settings.tool_mass,
                                      design_surface=settings.design_surface)
        common["details"]["loads"] = loads.summary()
        if settings.check_loads and not loads.ok:
            return Program(toolpath=None, path_file=None, plan=None, ok=False, problems=tuple(loads.failure_lines()),
                           records=tuple(loads.summary()["problems"]), notes=tuple(notes), loads=loads, **common)
    return Program(toolpath=tp, path_file=None, plan=res, ok=True, problems=(), notes=tuple(notes), loads=loads,
                   refused_by_check=getattr(res, "refusal", None), **common)
