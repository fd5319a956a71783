"""A production run: every panel relaxed, unfolded, refolded, programmed and checked, resumably.

Stages per panel: relax → unfold (with the congruency feedback of `fabkit.panels.workflow`) →
refold (§3.6: fold states from the flat pattern to the relaxed panel, the middle-row creases
driven) → program (the robot toolpath) → check (the toolpath in the MuJoCo cell). Programming and
checking live in `robot/` and `sim/`, which `fabkit` does not import: the caller passes the one
function that does both (`sim.production.program_panel`), so this module stays geometry.

Each panel ends `ok` or with the stage that stopped it and the reason. Work is resumable by
content: relax/unfold results are cached by the hash of their inputs (`fabkit.panels.cache`), and
the manifest (`manifest.json`, `fabkit.panels.manifest`) records per panel the hash of everything the later stages read
(geometry, cell text, material, options) with the SHA-256 of every file written; a panel whose hash
and files are unchanged is not recomputed. The manifest is rewritten after every finished panel, so
a run that is killed keeps every finished panel. Panels that are the same part share one refold,
program and check (`fabkit.panels.repeats`, `same_part_tol`).
"""
from __future__ import annotations

import contextlib
import hashlib
import math
import os
import time
from concurrent.futures import as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from fabkit.errors import InputError
from fabkit.panels.manifest import MANIFEST, files_intact, load_manifest, store_panel_files, write_manifest
from fabkit.panels.production_refold import panel_frame_of_task, refold_and_program, refold_inputs
from fabkit.panels.repeats import SAME_PART_TOL, relabel_fold, same_part_classes, same_part_result

__all__ = ["Stock", "stock", "ProductionOptions", "PanelStatus", "ProductionRun", "refold_inputs",
           "refold_and_program", "program_task", "same_part_result", "relabel_fold", "run_production",
           "crease_loss", "geometry_status", "MANIFEST", "STAGES"]

STAGES = ("relax", "unfold", "refold", "program", "check")
#: Code salt of the later stages' hash: bump it when their outputs change meaning.
PROGRAM_SALT = "fabkit.production.program/5"


@dataclass(frozen=True)
class Stock:
    """The sheet a run cuts: material name, thickness [m] and density [kg/m^3], from the material
    library (`fabkit.materials`), for the nesting's material and mass. The programs follow
    `ProductionOptions.sheet` (springback compensation and loads, docs/sheet.md)."""

    name: str
    thickness: float
    density: float


def stock(material: str = "5052-H32", thickness: float = 1.0e-3) -> Stock:
    """`Stock` of a library material (name or .toml path) at `thickness` [m]; the rigid `none` has
    no mass or thickness to cut, so it is refused."""
    from fabkit.materials import get_material

    m = get_material(material)
    if m.rigid:
        raise InputError("a production run cuts real sheet: name a material (`fabkit materials` lists them)",
                         source="--material")
    if not (math.isfinite(thickness) and 0 < thickness <= 0.02):
        raise InputError(f"must be in (0, 20 mm], got {thickness * 1e3:g} mm", source="--thickness")
    return Stock(m.name, float(thickness), float(m.density))


@dataclass(frozen=True)
class ProductionOptions:
    frames: int = 8                      # refold states from flat to folded (flat and target included)
    target_tol: float = 1e-5             # last refold state to the relaxed panel, relative to its size
                                         # (2 um on a 0.2 m panel; only the middle row is driven, §3.6)
    length_tol: float = 1e-6             # flat vs relaxed edge lengths a refold accepts (relative)
    overrides: dict = field(default_factory=dict)   # panel name -> {"frames": n}
    same_part_tol: float | None = SAME_PART_TOL    # panels that are the same part to this [m] share one
                                                    # refold, program and check (None: compute each panel)
    sheet: object = None                 # fabkit.sheet.SheetSpec: programs springback-compensated and their
                                         # fold loads checked, as `fabkit toolpath/check --material` (None:
                                         # the design angles, no loads)
    tool_mass: float | None = None       # gripper mass [kg] of the payload with a sheet (None: robot's default)


@dataclass(frozen=True)
class PanelStatus:
    id: int
    name: str
    ok: bool
    stage: str | None        # the stage that stopped the panel (None: ok)
    reason: str
    cycle_time_s: float | None
    unfold_max: float
    grip_face: int | None
    files: dict              # kind -> path relative to the run folder
    recomputed: bool
    same_as: str | None = None   # the panel of the same part whose refold, program and check it has


@dataclass(frozen=True)
class ProductionRun:
    panels: tuple[PanelStatus, ...]
    geometry: object          # the PanelsRun
    seconds: dict
    recomputed: dict          # stage -> panel ids computed in this run (the rest were reused)
    same_as: dict = field(default_factory=dict)   # panel name -> the panel of the same part whose
                                                  # refold, program and check it got in this run

    @property
    def ok(self) -> bool:
        return all(p.ok for p in self.panels)

    @property
    def robot_time_s(self) -> float:
        """The robot time of the run: the cycle times of the panels that passed every stage (a
        program whose check failed is not run)."""
        return float(sum(p.cycle_time_s or 0.0 for p in self.panels if p.ok))


def program_task(panel, result, options: ProductionOptions, cell_toml: str, cell_name: str, mat: Stock,
                 program: Callable, refuse_before_refold: Callable | None = None) -> dict:
    """The refold + program + check task of one panel (`refold_and_program`'s input: plain data and
    the two functions of `run_production`)."""
    frames = int(options.overrides.get(panel.name, {}).get("frames", options.frames))
    fd = {k: np.asarray(v) for k, v in panel.mesh.face_data.items() if k in ("strip", "column", "middle", "row")}
    task = {"id": panel.id, "name": panel.name, "faces": panel.mesh.topology.face_array, "face_data": fd,
            "uv": np.asarray(result.uv), "relaxed": np.asarray(result.relaxed), "frames": frames,
            "target_tol": options.target_tol, "length_tol": options.length_tol, "cell_toml": cell_toml,
            "cell_name": cell_name, "thickness": mat.thickness, "program": program, "sheet": options.sheet,
            "tool_mass": options.tool_mass}
    if refuse_before_refold is not None:
        task["refuse_before_refold"] = refuse_before_refold
    return task


def _part(task: dict) -> dict:
    """What `fabkit.panels.repeats.same_part_classes` compares of a panel task: the flat pattern in
    the panel frame of its first set-up and the relaxed panel (the set-ups follow from the tags and
    the relaxed panel's fold angles, which a rigid motion keeps)."""
    uv, setup = panel_frame_of_task(task)
    fd = {k: np.asarray(v) for k, v in task["face_data"].items()}
    exact = {"faces": np.asarray(task["faces"]), "setup": tuple(setup), **{f"tag:{k}": v for k, v in fd.items()},
             **{k: task[k] for k in ("frames", "target_tol", "length_tol", "cell_toml", "cell_name", "thickness")},
             "sheet": repr(task.get("sheet")), "tool_mass": repr(task.get("tool_mass")),
             "program": f"{task['program'].__module__}.{task['program'].__qualname__}"}
    return {"exact": exact, "flat": uv, "target": np.asarray(task["relaxed"], dtype=np.float64)}


#: A crease counts as kept when the relaxed panel's mean fold along it is at least this fraction of
#: the input surface's.
CREASE_KEPT = 0.5


def crease_loss(panel, relaxed: np.ndarray) -> str | None:
    """A reason when the relaxation flattened the panel's crease (nothing left for the robot to fold)."""
    from fabkit.cutfiles.creases import crease_assignment

    if "strip" not in panel.mesh.face_data:
        return None
    before = crease_assignment(panel.mesh)
    after = crease_assignment(panel.mesh.with_vertices(relaxed))
    c = np.isin(before.edges_assignment, ("M", "V", "U"))
    f0 = float(np.abs(before.edges_fold_angle[c]).mean())
    f1 = float(np.abs(after.edges_fold_angle[c]).mean())
    if f1 < CREASE_KEPT * f0:
        return (f"the relaxation flattened the crease: mean fold {np.degrees(f0):.1f} deg on the surface, "
                f"{np.degrees(f1):.1f} deg after")
    return None


def geometry_status(geometry, panel) -> tuple[str, str] | None:
    """(stage, reason) when the relax or unfold of `panel` misses its tolerance, else None."""
    r = geometry.results[panel.id]
    o = geometry.options
    if not r.converged:
        return "relax", r.message
    flattened = crease_loss(panel, r.relaxed)
    if flattened:
        return "relax", flattened
    why = []
    if r.unfold_max > o.tol_unfold:
        why.append(f"max deviation {r.unfold_max:.3g} > {o.tol_unfold:g}")
    if r.flipped:
        why.append(f"{r.flipped} flipped faces")
    if r.overlaps:
        why.append("the outline overlaps itself")
    cong = geometry.congruency.per_panel_max(len(geometry.results))[panel.id]
    if cong > o.tol_congruency:
        why.append(f"shared-edge incongruency {cong:.3g} > {o.tol_congruency:g}")
    return ("unfold", "; ".join(why)) if why else None


def run_production(layout, out: str | os.PathLike, *, cell_toml: str, cell_name: str, program: Callable,
                   panels_options=None, options: ProductionOptions = ProductionOptions(),
                   mat: Stock | None = None, jobs: int = 1, scheduler: str | None = None,
                   progress: Callable | None = None, timeout: float | None = None,
                   select=None, carry: Callable | None = None, executor=None,
                   refuse_before_refold: Callable | None = None) -> ProductionRun:
    """Run every stage for every panel of `layout` into folder `out` (see the module docstring).

    `program(fold_text, fold_name, cell_toml, cell_name, thickness) -> dict` plans and checks one
    panel (`sim.production.program_panel`). `progress(stage, done, total)` is called as panels
    finish a stage. Per-panel files go to `out/panels/`; the geometry files (OBJ, crease-pattern
    FOLD, DXF/SVG) are written by the caller (`fabkit.panels.output.write_run`). `select`: panel
    names to take past the unfold (None: all); the others end at stage "refold", "not selected".
    `carry(program_result, fold_text, fold_name, note) -> program_result` re-points a program and
    check at the FOLD of a panel of the same part (`sim.production.carry_over`): with it and
    `options.same_part_tol` set, only one panel per part (`fabkit.panels.repeats`) is refolded,
    programmed and checked; the others get its results, each recorded with the deviation.
    `executor`: an open `fabkit.panels.executor.panel_executor` every stage runs on (one pool of
    workers for the run: imports and caches paid once per worker), instead of one per stage.
    `refuse_before_refold(geometry, faces, cell_toml, cell_name, deviation_m=, sheet=, middle_row=)
    -> reason or None` refuses a set-up its check would refuse whatever the refold, before it is
    refolded (`sim.production.cup_refusal_before_refold`; `production_refold.refusal_before_refold`).
    """
    mat = stock() if mat is None else mat
    from fabkit.panels.cache import ResultCache
    from fabkit.panels.executor import panel_executor, single_threaded
    from fabkit.panels.workflow import PanelsOptions, run_panels

    out = Path(out)
    (out / "panels").mkdir(parents=True, exist_ok=True)
    cache = ResultCache(out / "cache" / "relax_unfold", "fabkit.panels.panel_task/1")
    n = len(layout.panels)
    seconds = {}
    t0 = time.perf_counter()
    done = [0]

    def geo_progress(k=1, **_):
        done[0] += k
        if progress:
            progress("relax+unfold", done[0], None)

    geometry = run_panels(layout, panels_options or PanelsOptions(), jobs=jobs, scheduler=scheduler,
                          progress=geo_progress, cache=cache, executor=executor)
    seconds["relax_unfold"] = time.perf_counter() - t0

    manifest = load_manifest(out)
    entries = manifest["panels"]
    t0 = time.perf_counter()
    tasks, keys, statuses, recomputed, same_as = {}, {}, {}, set(), {}
    for p in layout.panels:
        bad = geometry_status(geometry, p)
        if bad:
            statuses[p.id] = (bad[0], bad[1], {}, None, None, None)
            entries[p.name] = {"hash": None, "stage": bad[0], "reason": bad[1], "files": {}}
            continue
        if select is not None and p.name not in select:
            statuses[p.id] = ("refold", "not selected for refold, program and check in this run", {}, None, None, None)
            continue
        task = program_task(p, geometry.results[p.id], options, cell_toml, cell_name, mat, program,
                            refuse_before_refold)
        reuse = options.same_part_tol if carry is not None else None
        key = hashlib.sha256((PROGRAM_SALT + cache.key({**task, "same_part_tol": reuse})).encode()).hexdigest()
        prev = entries.get(p.name)
        if prev and prev.get("hash") == key and files_intact(out, prev):
            statuses[p.id] = (prev["stage"], prev["reason"], prev["files"], prev.get("cycle_time_s"),
                              prev.get("grip_face"), prev.get("same_as"))
        else:
            tasks[p.id], keys[p.id] = task, key
    finished = len(statuses)
    if progress:
        progress("refold+program+check", finished, n)
    if tasks:
        tol = options.same_part_tol
        t1 = time.perf_counter()
        if carry is not None and tol is not None:
            classes = same_part_classes({pid: _part(t) for pid, t in tasks.items()}, tol)
        else:
            classes = None
        reps = classes.representatives if classes else sorted(tasks)
        seconds["same_parts"] = time.perf_counter() - t1

        def finish(pid: int, r: dict) -> None:
            nonlocal finished
            files = store_panel_files(out, r)
            entries[r["name"]] = {"hash": keys[pid], "stage": r["stage"], "reason": r["reason"], "files": files,
                                  "cycle_time_s": r["cycle_time_s"], "grip_face": r["grip_face"],
                                  "refold": r["refold"], "seconds": r.get("seconds"),
                                  "face_up_on_fixture": r.get("face_up_on_fixture"),
                                  "clamped_face": r.get("clamped_face"), "setups": r.get("setups"),
                                  "loads": r.get("loads"),
                                  "same_as": r.get("same_as"), "same_part_deviation_m": r.get("same_part_deviation_m")}
            statuses[pid] = (r["stage"], r["reason"], files, r["cycle_time_s"], r["grip_face"], r.get("same_as"))
            recomputed.add(pid)
            finished += 1

        with (contextlib.nullcontext(executor) if executor is not None else panel_executor(jobs, scheduler)) as ex:
            futures = {ex.submit(single_threaded, refold_and_program, tasks[pid]): pid for pid in reps}
            for f in as_completed(futures, timeout=timeout):
                r = f.result()
                pid = futures[f]
                finish(pid, r)
                for m in (classes.members(pid) if classes else ()):
                    finish(m, same_part_result(r, tasks[m], classes.deviation[m], tol, carry))
                    same_as[tasks[m]["name"]] = r["name"]
                write_manifest(out, manifest)
                if progress:
                    progress("refold+program+check", finished, n)
    write_manifest(out, manifest)
    seconds["refold_program_check"] = time.perf_counter() - t0
    panels = []
    for p in layout.panels:
        stage, reason, files, ct, grip, same = statuses[p.id]
        panels.append(PanelStatus(id=p.id, name=p.name, ok=stage is None, stage=stage, reason=reason,
                                  cycle_time_s=ct, unfold_max=float(geometry.results[p.id].unfold_max),
                                  grip_face=grip, files={k: v["path"] for k, v in files.items()},
                                  recomputed=p.id in recomputed, same_as=same))
    return ProductionRun(panels=tuple(panels), geometry=geometry, seconds=seconds,
                         recomputed={"relax_unfold": sorted(int(i) for i in cache.computed),
                                     "refold_program_check": sorted(recomputed)},
                         same_as=same_as)

