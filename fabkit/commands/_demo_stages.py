"""The stages of `fabkit demo`, each one call of `fabkit.pipeline` plus the files the matching
subcommand writes (OBJ, DXF/SVG cut files, plots, FOLD, PATH.json, URScript, CHECK.json, renders).

A stage function takes the run's `DemoRun` and the results so far, and returns its typed result
with the stage report (the result's `to_json()` and the files written), the measure and the
tolerance for the summary table, all read from the typed results.
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import fabkit.pipeline as fk


@dataclass(frozen=True)
class DemoRun:
    """What every stage needs: the output folder, the cell file, fold states per step, the preset's
    parameters, the renders to write, and the sheet: `material` (a `fabkit materials` name or a
    .toml file; "none" = rigid) and its thickness [m] (None: the material's or the check's default)."""

    out: Path
    cell: str
    frames: int
    preset_params: dict
    renders: tuple[str, ...]
    thickness: float | None
    material: str = "none"

    def path(self, name: str) -> Path:
        return self.out / name


@dataclass(frozen=True)
class Outcome:
    result: object
    report: dict
    measure: str
    tolerance: str = ""


def fmt(x) -> str:
    return f"{x:.3g}" if isinstance(x, float) else str(x)


def generate(run: DemoRun, done: dict) -> Outcome:
    from fabkit.io import save_mesh

    panel = fk.generate("trifold", **run.preset_params)
    save_mesh(panel.mesh, run.path("trifold.obj"))
    report = {**panel.to_json(), "output": str(run.path("trifold.obj"))}
    return Outcome(panel, report, f"{panel.mesh.n_vertices} vertices, {panel.mesh.n_faces} faces")


def relax(run: DemoRun, done: dict) -> Outcome:
    from fabkit.io.save import save_panel

    relaxed = fk.relax(done["generate"])
    if relaxed.ok:
        save_panel(relaxed.mesh, run.path("relaxed.obj"))
    r, options = relaxed.result, relaxed.result.options
    report = {**relaxed.to_json(), "output": str(run.path("relaxed.obj")) if relaxed.ok else None}
    return Outcome(relaxed, report, f"max|defect| {fmt(r.max_defect)} rad, max planarity {fmt(r.max_planarity)}",
                   f"{fmt(options.tol_defect)} / {fmt(options.tol_planarity)}")


def unfold(run: DemoRun, done: dict) -> Outcome:
    from fabkit.cutfiles import cut_pattern, write_dxf, write_svg
    from fabkit.io.save import save_panel
    from fabkit.unfold.plot import plot_unfold_error

    flat = fk.unfold(done["relax"], max_error=1e-6)
    panel_id = "relaxed"  # the cut files' label: the stem of the panel they are cut for
    files = {"mesh": run.path("flat.obj"), "dxf": run.path("flat.dxf"), "svg": run.path("flat.svg"),
             "png": run.path("unfold_error.png")}
    save_panel(flat.mesh, files["mesh"], header=f"flat pattern of {run.path('relaxed.obj')} "
                                                "(isometric, metres, z = 0)")
    pattern = cut_pattern(flat.folded, flat.development.uv, flat.creases, panel_id)
    write_dxf(pattern, files["dxf"])
    write_svg(pattern, files["svg"])
    plot_unfold_error(flat.folded, flat.development, files["png"], title=f"{panel_id}: isometric development")
    s = flat.development.summary()
    report = {**flat.to_json(), "panel_id": panel_id, "outputs": {k: str(v) for k, v in files.items()}}
    return Outcome(flat, report, f"mean {fmt(s['mean_relative_deviation'])}, max {fmt(s['max_relative_deviation'])} "
                                 f"rel. length dev., {s['flipped_faces']} flipped", f"max <= {fmt(flat.max_error)}")


def _arms(run: DemoRun) -> tuple[str, ...]:
    from robot.arm_cells import arm_names
    from robot.cell import load_cell

    return arm_names(load_cell(run.cell))


def _clamp_face(run: DemoRun, done: dict):
    """A two-arm cell folds with the middle strip clamped and one arm per wing; one arm clamps an
    end of the row (refold's default)."""
    if len(_arms(run)) < 2:
        return None
    from fabkit.placement import choose_clamp_face

    return choose_clamp_face(done["unfold"].mesh)


def refold(run: DemoRun, done: dict) -> Outcome:
    from fabkit.refold.export import plot_fold_angles

    folds = fk.refold(done["unfold"], done["relax"], frames=run.frames, fixed_face=_clamp_face(run, done),
                      title="refold of flat.obj to relaxed.obj")  # the title `fabkit refold` gives these files
    report = folds.to_json()
    if folds.model is not None:
        folds.save(run.path("fold.fold"))
        report["output"] = str(run.path("fold.fold"))
    if folds.sequence is None:
        return Outcome(folds, report, "", f"target <= {fmt(folds.target_tol)}")
    plot_fold_angles(folds.sequence, run.path("fold_angles.png"))
    s = folds.sequence.summary()
    return Outcome(folds, report, f"loop closure {fmt(s['max_loop_residual_rad'])} rad, edge err "
                                  f"{fmt(s['max_edge_length_error_rel'])}, target {fmt(s['target_distance_rel'])} "
                                  f"of size", f"target <= {fmt(folds.target_tol)}")


def toolpath(run: DemoRun, done: dict) -> Outcome:
    import math

    from fabkit.io.atomic import atomic_write
    from robot.planner import PlanOptions

    program = fk.plan(done["refold"], run.cell, workdir=run.out, material=run.material,
                      thickness=None if run.material == "none" else run.thickness)
    tolerance = f"step <= {math.degrees(PlanOptions().max_joint_step):g} deg"
    report = program.to_json()
    if not program.ok:
        return Outcome(program, report, "", tolerance)
    if program.refused_by_check is not None:  # PATH.json is written for the check; no URScript
        return Outcome(program, program.report(program.path_file), "", tolerance)
    script = None
    if len(_arms(run)) == 1:  # a two-arm program runs through the lockstep send, not one URScript
        script = run.path("program.script")
        with atomic_write(script) as fh:
            fh.write(program.urscript())
    report = program.report(program.path_file, script)
    step = math.degrees(program.toolpath.extra["checks"]["max_fold_joint_step_rad"])
    return Outcome(program, report, f"{len(program.toolpath)} waypoints, max fold step {fmt(step)} deg, cycle "
                                    f"{fmt(program.plan.cycle_time)} s", tolerance)


def check(run: DemoRun, done: dict) -> Outcome:
    # a program planned for a sheet carries it (thickness, loads); a rigid one takes the slab's
    checked = fk.check(done["toolpath"], thickness=run.thickness if run.material == "none" else None)
    rendered = [fk.render(checked, run.path(name)) for name in run.renders]
    report = {**checked.to_json(), "render": rendered or None}
    r = checked.report
    clearance = (f"> {fmt(r.clearance_window_m)} m" if r.min_clearance_m is None  # nothing came that close
                 else f"{fmt(r.min_clearance_m)} m")
    return Outcome(checked, report, f"{len(r.problems)} problems in {r.configs_checked} configurations, "
                                    f"min clearance {clearance}", "0 problems")


def send(run: DemoRun, done: dict) -> Outcome:
    """The dry run: the controller stand-in on a free loopback address, the send, shut down."""
    from sim.ursim.launch import standin
    from fabkit.errors import InputError
    from fabkit.io.jsonfile import to_jsonable
    from robot.sender import SendSettings

    settings = SendSettings(host="")
    tolerance = f"all waypoints, error <= {settings.final_tol_m:g} m / {settings.final_tol_rad:g} rad"
    import contextlib

    arms = _arms(run)
    with contextlib.ExitStack() as stack:  # one stand-in per arm, each on its own loopback address
        logs = ["ursim.log" if len(arms) == 1 else f"ursim_{a}.log" for a in arms]
        hosts = [stack.enter_context(standin(run.cell, run.path(name), None if len(arms) == 1 else a))
                 for a, name in zip(arms, logs)]
        if None in hosts:
            raise InputError(f"the controller stand-in did not start (see {logs[hosts.index(None)]})", source="send")
        with open(run.path("send.log"), "w", buffering=1, encoding="utf-8") as log:
            sent = fk.send(done["toolpath"], done["check"], host=hosts[0], hosts=hosts[1:], power_on=True,
                           log=lambda event: log.write(json.dumps(to_jsonable(event)) + "\n"))
    r = sent.result
    return Outcome(sent, sent.to_json(), f"{r.last_completed + 1}/{r.total} waypoints, final error "
                                         f"{fmt(r.final_error_m)} m / {fmt(r.final_error_rad)} rad", tolerance)


STAGES = {"generate": generate, "relax": relax, "unfold": unfold, "refold": refold, "toolpath": toolpath,
          "check": check, "send": send}
