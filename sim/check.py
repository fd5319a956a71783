"""Check a robot program in the MuJoCo cell model before it may be sent.

Every waypoint and the motion between waypoints is checked at interpolated configurations
(`sim.interpolate`: steps of `CheckSettings.step_joint_rad` joint motion, `step_tcp_m` TCP travel,
`step_rot_rad` tool rotation) with the panel posed at the fold state interpolated alongside, for
reach, joint limits, singularities, collisions, clearance and speeds (`sim.check_events`). Blended
moves are checked on the path the controller drives (`robot.ur_motion`'s blends, which cut each
corner by less than its radius `r`), and the cycle time is that model's.

Problems found at interpolated configurations belong to the move's target waypoint (the move
instruction that causes them); problems at a waypoint's own configuration belong to it. Runs of
the same problem are merged (`sim.problems`).

`check_toolpath(toolpath, cell)` is the check of a PATH.json: it loads the panel from the FOLD file
the toolpath names (verifying its sha256), and its `CheckReport` is exactly what `fabkit check`
writes as CHECK.json (`fabkit.check/2`, recording the toolpath hash, the cell file hash and the
FOLD file used). `robot.sender.send_toolpath` runs it again before sending.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from fabkit.errors import InputError
from sim.check_events import (along_path, collision_events, limit_events, singular_events, speed_events,
                              waypoint_events)
from sim.interpolate import CheckSettings, Dense, Program, interpolate_program
from sim.panel import PanelModel
from sim.problems import KINDS, Event, Problem, merge_events
from sim.toolpath_program import (fold_file_of, fold_progress, grip_face_of, load_source_fold, program_from_toolpath,
                                  source_panel)

__all__ = ["CheckSettings", "Problem", "Event", "CheckReport", "Program", "Dense", "ToolpathCheck",
           "interpolate_program", "check_program", "check_toolpath", "run_toolpath_check", "program_from_toolpath",
           "fold_progress", "fold_file_of", "grip_face_of", "program_cycle_time", "KINDS", "FORMAT"]

FORMAT = "fabkit.check/2"


@dataclass(frozen=True)
class CheckReport:
    """Result of a check (CHECK.json, format `fabkit.check/2`). `ok` iff there are no problems.

    `toolpath_sha256`: the hash of the toolpath checked; `cell_sha256`: of the cell file checked
    in; `fold`: `{"path", "sha256"}` of the FOLD file whose panel was checked (None: no panel)."""

    toolpath_sha256: str
    ok: bool
    problems: tuple[Problem, ...]
    min_clearance_m: float | None
    cycle_time_s: float
    waypoints: int
    configs_checked: int
    min_clearance_pair: tuple[str, str] | None = None
    clearance_limit_m: float = 0.0
    clearance_window_m: float = 0.0
    panel_window_m: float = 0.0
    cell: str = ""
    robot: str = ""
    panel_faces: int = 0
    notes: tuple[str, ...] = ()
    along_path: dict = field(default_factory=dict)  # per-waypoint clearance and joint-speed ratio
    cell_sha256: str = ""
    fold: dict | None = None
    loads: dict | None = None  # the sheet's fold-load verdicts per state (`sim.check_loads`)
    holds: dict | None = None            # sim.check_holds: per-state hold proofs (None: no panel)
    panel_collisions: dict | None = None  # sim.check_panel_collisions (None: no panel)
    arms: dict | None = None      # a program for several arms: per arm (`sim.check_arms`); None for one arm
    lockstep: dict | None = None  # a program for several arms: sync, timing, arm against arm
    phases: dict | None = None    # a one-arm program in phases: per phase (`sim.check_phases`); None for one

    def to_json(self) -> dict:
        multi = {} if self.arms is None else {"arms": self.arms, "lockstep": self.lockstep}
        multi.update({} if self.phases is None else {"phases": self.phases})
        return {**multi, 
            "format": FORMAT,
            "toolpath_sha256": self.toolpath_sha256,
            "cell_sha256": self.cell_sha256,
            "fold": None if self.fold is None else dict(self.fold),
            "ok": bool(self.ok),
            "problems": [p.to_json() for p in self.problems],
            "min_clearance_m": self.min_clearance_m,
            "cycle_time_s": float(self.cycle_time_s),
            "min_clearance_pair": list(self.min_clearance_pair) if self.min_clearance_pair else None,
            "clearance_limit_m": self.clearance_limit_m,
            "clearance_window_m": self.clearance_window_m,
            "panel_window_m": self.panel_window_m,
            "waypoints": self.waypoints,
            "configs_checked": self.configs_checked,
            "cell": self.cell,
            "robot": self.robot,
            "panel_faces": self.panel_faces,
            "notes": list(self.notes),
            "along_path": self.along_path,
            "loads": self.loads,
            "holds": self.holds,
            "panel_collisions": self.panel_collisions,
        }



def program_cycle_time(prog: Program, dwell=None) -> float:
    """A checked program's duration [s]: `robot.motion.cycle_time` (the controller model the
    planner and the stand-in share) at full speed slider, with the payload's joint acceleration
    bound, plus per-waypoint dwell; NaN when it cannot be timed (reported by the check)."""
    from robot.motion import cycle_time
    from robot.ur_motion import JOINT_ACCEL_MAX

    if len(prog) < 2 or not np.isfinite(prog.q).all():
        return math.nan
    r = prog.r if prog.r is not None else np.zeros(len(prog))
    bound = JOINT_ACCEL_MAX if prog.accel_bound is None else prog.accel_bound
    try:
        return cycle_time(np.asarray(prog.moves), prog.poses[:, :3, 3], prog.poses[:, :3, :3], prog.q, prog.v, prog.a,
                          r, 0.0 if dwell is None else dwell, bound).total
    except ValueError:  # overlapping blends or a zero speed
        return math.nan


def check_program(prog: Program, cell, panel: PanelModel | None = None,
                  settings: CheckSettings = CheckSettings(), on_progress=None) -> tuple[CheckReport, Dense]:
    """Check a program (arrays) in the cell; returns the report and the configurations checked.

    `on_progress(done, total)`: called now and then while the configurations go through MuJoCo.
    """
    model = cell.model
    dense = interpolate_program(model, prog, settings)
    events: list[Event] = list(dense.events)
    events += waypoint_events(model, prog, cell, settings)
    events += limit_events(model, dense)
    events += singular_events(model, dense, settings)
    events += speed_events(model, cell, dense)
    col, min_d, min_pair, names, nearest = collision_events(cell, panel, dense, on_progress=on_progress)
    events += col
    problems = tuple(merge_events(events))
    notes = []
    if panel is None:
        notes.append("no panel geometry: the robot was checked against the cell's obstacles only")
    if prog.r is not None and len(prog.r) and float(np.max(prog.r)) > 0:
        notes.append(f"blended moves checked on the blended path the controller drives (corners cut by up to "
                     f"r = {float(np.max(prog.r)) * 1e3:.1f} mm)")
    if panel is not None and panel.fit_residual is not None and panel.fit_residual.size:
        notes.append(f"panel faces follow their fold states rigidly to {panel.fit_residual.max() * 1e3:.3f} mm")
    report = CheckReport(
        toolpath_sha256=prog.sha256, ok=not problems, problems=problems, min_clearance_m=min_d,
        cycle_time_s=program_cycle_time(prog, prog.dwell), waypoints=len(prog), configs_checked=len(dense.q),
        min_clearance_pair=min_pair, clearance_limit_m=float(cell.limits.clearance),
        clearance_window_m=float(names.margins["environment_m"]),
        panel_window_m=float(names.margins.get("panel_m", 0.0)), cell=cell.name, robot=model.name,
        panel_faces=0 if panel is None else len(panel.pieces), notes=tuple(notes),
        along_path=along_path(model, cell, dense, nearest, len(prog)), cell_sha256=getattr(cell, "sha256", ""))
    return report, dense


@dataclass(frozen=True, eq=False)
class ToolpathCheck:
    """A toolpath check with what it was made of: the `report`, the configurations checked
    (`dense`), the `program` arrays, the `panel` and the FOLD file it came from (for renders)."""

    report: CheckReport
    dense: Dense
    program: Program
    panel: PanelModel | None
    fold_path: Path | None


def run_toolpath_check(toolpath, cell, *, fold: str | Path | None = None, use_panel: bool = True,
                       thickness: float | None = None, settings: CheckSettings = CheckSettings(),
                       on_progress=None, sheet=None, panel_checks: bool = True) -> ToolpathCheck:
    """Check a `robot.toolpath.Toolpath` (or a PATH.json path) in `cell` with its panel.

    The panel comes from `fold`, else from the FOLD file the toolpath's source names (relative
    names resolve against the PATH.json's folder); its sha256 must equal the one recorded at
    planning. `use_panel=False` checks against the cell's obstacles only (noted in the report).

    A toolpath with a `sheet` record (or a `sheet`, a `fabkit.sheet.SheetSpec`, given for one
    planned rigid) is also checked for its fold loads per state (`sim.check_loads`); its panel is
    posed in the compensated states the program follows, `thickness` (default: the sheet's) thick.

    A program for several arms (`robot.arms_toolpath.ArmsToolpath`, PATH.json `fabkit.toolpath/3`)
    is checked by `sim.check_arms.run_arms_check`. `panel_checks=False` leaves out the holds, the
    panel's own collisions and the clamp footprint (that check runs them once for all arms).
    """
    from robot.arms_toolpath import ArmsToolpath, load_toolpath
    from robot.toolpath import Toolpath

    base_dir = None
    if isinstance(toolpath, (Toolpath, ArmsToolpath)):
        tp = toolpath
    else:
        tp, base_dir = load_toolpath(toolpath), Path(toolpath).parent
    if isinstance(tp, ArmsToolpath):
        if sheet is not None:
            raise InputError("a sheet's fold loads are checked for one-arm programs only", source="PATH.json")
        from sim.check_arms import run_arms_check

        return run_arms_check(tp, cell, fold=fold, use_panel=use_panel, thickness=thickness, settings=settings,
                              on_progress=on_progress, base_dir=base_dir)
    from sim.check_loads import check_sheet_loads, fold_states_model, resolve_sheet, slab_offset

    sha = tp.sha256
    cell = _placed(tp, cell)
    prog = program_from_toolpath(tp, cell, sha256=sha)
    spec, recorded = resolve_sheet(tp, sheet)
    model, fold_path, fold_sha = (load_source_fold(tp, fold, base_dir=base_dir) if use_panel or spec is not None
                                  else (None, None, None))
    if spec is not None and model is None:
        raise InputError("the toolpath folds a sheet: its fold loads need the FOLD file it was planned from "
                         "(pass --fold)", source="PATH.json")
    panel = None
    t = thickness or (spec.thickness if spec is not None else None)
    if use_panel and model is not None:
        states = fold_states_model(model, spec, recorded, str(fold_path))
        panel = source_panel(tp, cell, states, fold_path, t, slab_offset(tp, spec, t))
    report, dense = check_program(prog, cell, panel, settings, on_progress=on_progress)
    if spec is not None:
        loads = check_sheet_loads(tp, spec, model, cell, recorded=recorded)
        problems = tuple(sorted(report.problems + loads.problems,
                                key=lambda p: (p.waypoint, KINDS.index(p.kind), p.subject)))
        report = replace(report, problems=problems, ok=not problems, loads=loads.record,
                         notes=report.notes + loads.notes)
    notes = report.notes
    if tp.cell != cell.name or tp.cell_sha256 != getattr(cell, "sha256", ""):
        notes += (f"the toolpath was planned for cell {tp.cell!r} (cell file sha256 {tp.cell_sha256[:12]}…) and "
                  f"checked in {cell.name!r} ({getattr(cell, 'sha256', '')[:12]}…)",)
    report = replace(report, notes=notes,
                     fold=None if fold_path is None else {"path": str(fold_path), "sha256": fold_sha})
    if panel_checks:
        report = _with_panel_checks(report, tp, prog, cell, model if use_panel else None, fold_path, t)

    return ToolpathCheck(report=report, dense=dense, program=prog, panel=panel, fold_path=fold_path)


def _placed(tp, cell):
    """The cell with the panel where the toolpath was planned: its `placement` record
    (`robot.panel_placement`), else the cell's fixture."""
    from fabkit.errors import InputError
    from robot.panel_placement import placed_cell, placement_of

    try:
        return placed_cell(cell, placement_of(tp.extra))
    except ValueError as exc:
        raise InputError(str(exc)) from None


def _with_panel_checks(report: CheckReport, tp, prog: Program, cell, model, fold_path: Path | None,
                       thickness: float | None) -> CheckReport:
    """The report with the checks of the panel itself added (`model`: the verified FOLD file's
    `FoldModel`, None without a panel): its holds (`sim.check_holds`) and its collisions with the
    cell and itself (`sim.check_panel_collisions`)."""
    if model is None:
        return replace(report, notes=report.notes + ("no panel: the holds and the panel's own collisions were not "
                                                     "checked",))
    from sim.check_holds import check_holds, clamp_problems
    from sim.check_panel_collisions import check_panel_collisions_of_fold

    from sim.check_jigs import extend_holds

    holds = check_holds(tp, model, prog.states, source=str(fold_path))
    holds, jig_holds, jig_problems = extend_holds(holds, model, cell, prog.states)  # jigs, what folds each crease
    panel = check_panel_collisions_of_fold(model, cell, prog.states, holds.record["clamped_faces"],
                                           thickness=thickness, jig_holds=jig_holds)
    from sim.check_cup import cup_problems

    # a sheet program's pad footprint is checked with its loads (sim.check_loads); a rigid one's cup here
    cup_radius = None if report.loads is not None else getattr(cell.tool, "cup_radius", None)
    cup, cup_found = cup_problems(model, holds.record, lambda arm: cup_radius)
    problems = tuple(sorted(report.problems + holds.problems + panel.problems + jig_problems + tuple(cup_found) +
                            clamp_problems(model, cell, holds.record["clamped_faces"], len(tp)),
                            key=lambda p: (p.waypoint, KINDS.index(p.kind), p.subject)))
    record = holds.record if cup is None else {**holds.record, "cup_footprint": cup}
    report = replace(report, problems=problems, ok=not problems, holds=record,
                     panel_collisions=panel.record, notes=report.notes + holds.notes)
    from sim.check_phases import phases_check

    phases, phase_problems = phases_check(tp, report)   # a program in phases: per phase (None: one)
    if phases is None:
        return report
    problems = tuple(sorted(report.problems + phase_problems, key=lambda p: (p.waypoint, KINDS.index(p.kind),
                                                                               p.subject)))
    return replace(report, problems=problems, ok=not problems, phases=phases)


def check_toolpath(toolpath, cell, *, fold: str | Path | None = None, use_panel: bool = True,
                   thickness: float | None = None, settings: CheckSettings = CheckSettings(),
                   on_progress=None, sheet=None) -> CheckReport:
    """The check report of a toolpath in `cell` (`run_toolpath_check`); `report.to_json()` is the
    CHECK.json `fabkit check` writes for the same inputs."""
    return run_toolpath_check(toolpath, cell, fold=fold, use_panel=use_panel, thickness=thickness,
                              settings=settings, on_progress=on_progress, sheet=sheet).report
