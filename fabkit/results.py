"""The typed, frozen results of the pipeline stages (`fabkit.pipeline`).

Every result has `ok` (the stage met its tolerances), `problems` (a tuple of the one-line verdicts
the CLI prints for the same inputs, empty when ok) and `to_json()` (a JSON-ready dict: the stage's
report, the same numbers the CLI's `--report` holds). Arrays and meshes are kept as they are
(`eq=False`: results compare by identity); `to_json()` turns them into lists.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # annotations only: importing a result type loads no numpy, robot or sim
    from fabkit.cutfiles.creases import CreaseAssignment
    from fabkit.fold import FoldModel
    from fabkit.io.load import LoadInfo
    from fabkit.mesh import PolyMesh
    from fabkit.refold.sequence import FoldSequence
    from fabkit.relax.options import RelaxResult
    from fabkit.sheet import SheetSpec
    from fabkit.unfold.development import Development
    from robot.cell import Cell
    from robot.loads import LoadReport
    from robot.planner import PlanResult
    from robot.sender import SendResult
    from robot.toolpath import Toolpath
    from sim.check import CheckReport, ToolpathCheck


def _jsonable(data: dict) -> dict:
    from fabkit.io.jsonfile import to_jsonable

    return to_jsonable(data)


@dataclass(frozen=True, eq=False)
class Panel:
    """A panel mesh (metres) as loaded or generated: `mesh` (`fabkit.mesh.PolyMesh`), `name` (the
    file name or `preset NAME`), `loaded` (`fabkit.io.load.LoadInfo`, None for a preset: units,
    welds, notes), `params` (a preset's parameters, defaults filled in)."""

    mesh: PolyMesh
    name: str
    loaded: LoadInfo | None = None
    params: dict = field(default_factory=dict)
    ok: bool = True
    problems: tuple[str, ...] = ()

    @property
    def notes(self) -> tuple[str, ...]:
        """What the loader did that can change the result (unit guessed, vertices welded, ...)."""
        return tuple(self.loaded.notes) if self.loaded is not None else ()

    def to_json(self) -> dict:
        from fabkit import measures

        return _jsonable({"name": self.name, "ok": self.ok, "problems": list(self.problems),
                          **measures.summary(self.mesh), "unit": "m", "params": dict(self.params),
                          "loaded": None if self.loaded is None else self.loaded.to_report()})


@dataclass(frozen=True, eq=False)
class Relaxed:
    """`fk.relax()`: `mesh` the relaxed panel (the input's vertex order, faces and tags),
    `result` the solver's `fabkit.relax.RelaxResult`, `input` the `Panel` relaxed, `max_move`
    the share of the panel size a vertex may move."""

    mesh: PolyMesh
    result: RelaxResult
    input: Panel | Relaxed
    max_move: float
    ok: bool
    problems: tuple[str, ...]

    @property
    def name(self) -> str:
        return self.input.name

    @property
    def loaded(self) -> LoadInfo | None:
        """How the first panel of the chain was read (None for a preset)."""
        return self.input.loaded

    def to_json(self) -> dict:
        """The report `fabkit relax --report` writes (without the file names)."""
        from fabkit.verdicts import moved_too_far

        r, size = self.result, self.input.mesh.size
        return _jsonable({"input": self.input.name, "ok": self.ok, "problems": list(self.problems),
                          "input_summary": {"vertices": self.input.mesh.n_vertices, "faces": self.input.mesh.n_faces,
                                            "interior_vertices": int(self.input.mesh.interior_vertex_mask.sum())},
                          **r.to_report(), "unit": "m",
                          "loaded": None if self.loaded is None else self.loaded.to_report(),
                          "max_move": {"share": self.max_move, "limit_m": self.max_move * size,
                                       "moved_m": r.max_displacement,
                                       "ok": not moved_too_far(r, size, self.max_move)}})


@dataclass(frozen=True, eq=False)
class Flat:
    """`fk.unfold()`: `mesh` the flat pattern (z = 0, the panel's vertex order and tags),
    `folded` the panel it unfolds (the refold target), `development` (`fabkit.unfold.Development`:
    uv, length deviations), `creases` (`fabkit.cutfiles.CreaseAssignment`: M/V/U per edge),
    `method`; for a sheet `sheet` (`fabkit.sheet.SheetSpec`: the pattern is its neutral surface)
    and `design_surface`; `loaded` how the first panel of the chain was read."""

    mesh: PolyMesh
    folded: PolyMesh
    development: Development
    creases: CreaseAssignment
    name: str
    max_error: float | None
    ok: bool
    problems: tuple[str, ...]
    method: str = "isometric"
    sheet: SheetSpec | None = None
    design_surface: str = "top"
    loaded: LoadInfo | None = None

    def sheet_summary(self) -> dict | None:
        """The `sheet` record of the unfold report (None without a sheet)."""
        if self.sheet is None:
            return None
        return {**self.sheet.summary(), "surface": "neutral", "design_surface": self.design_surface,
                "face_up": f"{self.design_surface} face of the design (cut files are seen from it)",
                "crease_strip_mm": self.development.details.get("crease_strip_mm")}

    def cut_pattern(self, panel_id: str, label_edges: bool = False):
        """The cut files' geometry (`fabkit.cutfiles.cut_pattern`) labelled `panel_id`, with the
        sheet's note (thickness, material, design surface, groove side) for a sheet."""
        from fabkit.cutfiles import cut_pattern

        note = ""
        if self.sheet is not None:
            spec = self.sheet
            note = (f"{spec.thickness * 1000:g} mm {spec.material.name}, design surface {self.design_surface}"
                    + ("; grooves on the inside of each fold: valleys front, mountains back"
                       if spec.prep.kind == "grooved" else ""))
        return cut_pattern(self.folded, self.development.uv, self.creases, panel_id, label_edges=label_edges,
                           sheet_note=note)

    def save(self, path: str | Path, header: str = "") -> None:
        """Write the flat pattern by suffix (`fabkit unfold -o`): .obj / .3dm the mesh (z = 0), .fold
        the crease pattern with the folded panel as its fold state (flat + folded, what `fabkit
        refold FLAT.fold` reads). Not atomic: the caller gives the (temporary) path."""
        if str(path).lower().endswith(".fold"):
            from fabkit.fold import FoldFrame, FoldModel
            from fabkit.io.fold import save_fold

            angle = self.creases.edges_fold_angle
            model = FoldModel.from_mesh(self.mesh, self.creases.edges_assignment, angle, title=header,
                                        frames=(FoldFrame(self.folded.vertices, angle),))
            save_fold(model, path)
            return
        from fabkit.io.save import save_panel

        save_panel(self.mesh, path, header=header)

    def to_json(self) -> dict:
        """The report `fabkit unfold --report` writes (without the file names)."""
        out = {"format": "fabkit.unfold/1", "input": self.name, "ok": self.ok, "problems": list(self.problems),
               "max_error": self.max_error, "development": self.development.summary(),
               "creases": {"source": self.creases.source, **self.creases.counts()},
               "units": {"mesh": "m", "cut_files": "mm"}, "unit": "m",
               "loaded": None if self.loaded is None else self.loaded.to_report()}
        if self.sheet is not None:
            out["sheet"] = self.sheet_summary()
        return _jsonable(out)


@dataclass(frozen=True, eq=False)
class Folds:
    """`fk.refold()`: `sequence` (`fabkit.refold.sequence.FoldSequence`: every fold state and
    its diagnostics; None when the target is not a fold of the flat pattern), `model` the FOLD
    animation (`fabkit.fold.FoldModel`, what `fabkit refold -o SEQ.fold` writes), `target_tol`."""

    sequence: FoldSequence | None
    model: FoldModel | None
    name: str
    target_tol: float
    ok: bool
    problems: tuple[str, ...]
    details: dict = field(default_factory=dict)

    def save(self, path: str | Path) -> Path:
        """Write the FOLD animation to `path` (atomically) -> the path."""
        from fabkit.io.atomic import atomic_path
        from fabkit.io.fold import save_fold

        if self.model is None:
            from fabkit.errors import InputError

            raise InputError("there are no fold states to write: " + "; ".join(self.problems), source=str(path))
        with atomic_path(path) as tmp:
            save_fold(self.model, tmp)
        return Path(path)

    def to_json(self) -> dict:
        """The report `fabkit refold --report` writes (without the output files): summary, driven
        edges, notes, tolerances and one record per state."""
        import math

        out = {"format": "fabkit.refold/1", "target": self.name, "ok": self.ok, "problems": list(self.problems),
               "target_tol": self.target_tol, **self.details}
        if self.sequence is not None:
            seq = self.sequence
            out.update({"summary": seq.summary(), "driven_edges": seq.edges[seq.driven], "notes": list(seq.notes),
                        "states": [{"state": s, "step": int(seq.step[s]), "loop_residual_rad": seq.residual[s],
                                    "edge_length_error": seq.edge_length_error[s],
                                    "corner_mismatch_m": seq.corner_mismatch[s],
                                    "newton_iterations": int(seq.newton_iterations[s]),
                                    "converged": bool(seq.converged[s]), "intersections": int(seq.intersections[s]),
                                    "driven_angles_deg": [math.degrees(a) for a in seq.angles[s, seq.driven]]}
                                   for s in range(seq.n_states)]})
        return _jsonable(out)


def plan_report(plan: PlanResult, toolpath: Toolpath) -> dict:
    """What the planner measured, for the toolpath report (`fabkit toolpath --report`,
    `Program.to_json()`); `toolpath` is the one written (the planned one, or with the sheet record)."""
    import math

    return {"toolpath_sha256": toolpath.sha256, "waypoints": len(toolpath), "grip_face": plan.grip_face,
            "branch": plan.branch, "cycle_time_s": plan.cycle_time,
            "max_fold_joint_step_deg": math.degrees(toolpath.extra["checks"]["max_fold_joint_step_rad"]),
            "joint_speed_ratio": plan.joint_speed_ratio, "min_singularity": plan.min_singularity,
            "faces_tried": [{"face": f, "problem": str(e)} for f, e in plan.tried]}


@dataclass(frozen=True, eq=False)
class Program:
    """`fk.plan()`: `toolpath` (`robot.toolpath.Toolpath`, None when planning failed), the
    files it was planned from and written to (`fold_file`, `path_file` in `workdir`; None when not
    written), the `cell` (`robot.cell.Cell`) and `cell_file`, the planner's `plan`
    (`robot.planner.PlanResult`), how the FOLD file was read (`loaded`), `notes` (the stage's notes,
    besides the loader's in `loaded.notes`), `records` (the problems as the report writes them: the planner's
    CHECK.json-style problem, or the exceeded fold loads), for a sheet, `loads`
    (`robot.loads.LoadReport`), and `refused_by_check`: when the planner's check refused every grip
    candidate, the problem of the program kept (the first that planned; still `ok`, written so
    that `fabkit check` can show it, and refused by that check), else None."""

    toolpath: Toolpath | None
    workdir: Path
    fold_file: Path
    path_file: Path | None
    cell: Cell
    cell_file: Path
    plan: PlanResult | None
    ok: bool
    problems: tuple[str, ...]
    details: dict = field(default_factory=dict)
    loaded: LoadInfo | None = None
    notes: tuple[str, ...] = ()
    records: tuple = ()
    loads: LoadReport | None = None
    refused_by_check: str | None = None

    @property
    def refusal_line(self) -> str | None:
        """One line saying that the planner's check refused every grip candidate, or None."""
        if self.refused_by_check is None:
            return None
        faces = list(dict.fromkeys(str(f) for f, _ in self.plan.tried))
        return (f"the check refuses every grip candidate that planned (tried {', '.join(faces)}); the program "
                f"kept is grip {self.plan.grip_face}'s, refused for: {self.refused_by_check}")

    def _refuse_urscript(self) -> None:
        """A pendant program passes no check gate: none is written for a program the check refuses."""
        if self.refused_by_check is not None:
            from fabkit.errors import ToleranceError

            raise ToleranceError(f"no URScript: {self.refusal_line}")

    def urscript(self, progress_register: int | None = None) -> str:
        """The URScript program (`fabkit toolpath --script`) of this toolpath (`ToleranceError` when
        the check refused it: `refused_by_check`)."""
        from fabkit.toolpath_stage import check_progress_register
        from robot.urscript import PROGRESS_REGISTER, write_urscript

        self._refuse_urscript()
        check_progress_register(progress_register)
        reg = PROGRESS_REGISTER if progress_register is None else progress_register
        return write_urscript(self.toolpath, program_name=f"fold_{self.cell.name}", progress_register=reg)

    def urscripts(self, script_path, progress_register: int | None = None, handshake_timeout: float | None = None) \
            -> dict:
        """{path: URScript program text} that `fabkit toolpath --script script_path` writes: the
        one program at `script_path` for one arm; for several arms one per arm
        (`robot.arms_urscript`, `handshake_timeout` s or its default), at `script_path` with
        `_<arm>` before its suffix (`ToleranceError` when the check refused the program)."""
        from fabkit.toolpath_stage import check_progress_register
        from robot.arms_urscript import arm_script_path, write_arm_urscripts
        from robot.urscript import PROGRESS_REGISTER

        self._refuse_urscript()
        if not hasattr(self.toolpath, "arms"):
            if handshake_timeout is not None:
                from fabkit.errors import InputError

                raise InputError("a one-arm program has no handshake between arms", source="--handshake-timeout")
            return {Path(script_path): self.urscript(progress_register)}
        check_progress_register(progress_register)
        reg = PROGRESS_REGISTER if progress_register is None else progress_register
        return {arm_script_path(script_path, arm): text
                for arm, text in write_arm_urscripts(self.toolpath, progress_register=reg,
                                                      timeout_s=handshake_timeout).items()}

    def report(self, output=None, script=None) -> dict:
        """The report `fabkit toolpath --report` writes, naming `output` (the PATH.json written)
        and `script` (the URScript file, or None)."""
        out = {"command": "toolpath", "input": str(self.fold_file), "cell": self.cell.name,
               "robot": self.cell.model.name, **self.details, "ok": self.ok and self.refused_by_check is None}
        if self.refused_by_check is not None:
            out["refused_by_check"] = self.refused_by_check
        if self.plan is not None:
            out.update({"output": None if output is None else str(output),
                        "script": None if script is None else (str(script) if isinstance(script, (str, Path))
                                                               else [str(x) for x in script]),
                        **plan_report(self.plan, self.toolpath)})
        out["problems"] = list(self.records)
        return _jsonable(out)

    def to_json(self) -> dict:
        """The report `fabkit toolpath --report` writes for `path_file`."""
        return self.report(self.path_file)


@dataclass(frozen=True, eq=False)
class Checked:
    """`fk.check()`: `report` (`sim.check.CheckReport`), written as `check_file`; `to_json()`
    is CHECK.json (`fabkit.check/2`), the very report `fabkit check` writes for the same PATH.json.
    `run` (`sim.check.ToolpathCheck`) holds the configurations checked, which `fk.render` draws."""

    report: CheckReport
    program: Program
    check_file: Path
    ok: bool
    problems: tuple[str, ...]
    run: ToolpathCheck | None = None

    def to_json(self) -> dict:
        return self.report.to_json()


@dataclass(frozen=True, eq=False)
class Sent:
    """`fk.send()`: `result` (`robot.sender.SendResult`: last completed waypoint, reason,
    final pose error); `ok` when every waypoint was reached."""

    result: SendResult
    host: str
    ok: bool
    problems: tuple[str, ...]

    def to_json(self) -> dict:
        """The report `fabkit send --report` writes."""
        return _jsonable({"ok": self.ok, "sent": True, "host": self.host, "problems": list(self.problems),
                          **self.result.to_json()})
