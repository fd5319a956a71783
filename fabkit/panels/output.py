"""Write a multi-panel run to a folder: per-panel OBJ/FOLD/DXF/SVG, band layout, plots, JSON report.

Everything is written into a hidden staging folder next to the target and moved into place only
when every file succeeded, so a failed run leaves no partial output behind.
"""
from __future__ import annotations

import contextlib

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from fabkit.io.jsonfile import to_jsonable, write_json
from fabkit.panels.workflow import PanelsRun

__all__ = ["write_run", "run_report", "band_layout", "panel_file_texts"]


def band_layout(run: PanelsRun, gap: float = 0.05) -> list[dict]:
    """Adjacency bands (paper §3.4, Fig. 17): each band's developments laid side by side.

    Neighbouring panels of a band are placed so their shared side edge coincides (a rigid 2D fit of
    the shared vertices, Kabsch), bands stacked with `gap` metres between them. Returns per panel
    {"id", "band", "rotation" (2x2), "translation" (2,)}: flat-layout = uv @ R.T + t.
    """
    layout = run.layout
    placements: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    y_cursor = 0.0
    bands = sorted({p.band for p in layout.panels})
    for b in bands:
        members = sorted((p for p in layout.panels if p.band == b), key=lambda p: p.index)
        band_pts = []
        for k, p in enumerate(members):
            uv = run.results[p.id].uv
            if k == 0:
                R, t = _orient_band_start(uv, p)
            else:
                q = members[k - 1]
                Rq, tq = placements[q.id]
                # shared side: last station column of q == first station column of p
                src = uv[np.arange(len(p.rows)) * len(p.stations)]
                dst_local = run.results[q.id].uv[np.arange(len(q.rows)) * len(q.stations) + len(q.stations) - 1]
                dst = dst_local @ Rq.T + tq
                R, t = _kabsch_2d(src, dst)
            placements[p.id] = (R, t)
            band_pts.append(uv @ R.T + t)
        pts = np.vstack(band_pts)
        shift = np.array([-pts[:, 0].min(), y_cursor - pts[:, 1].min()])
        for p in members:
            R, t = placements[p.id]
            placements[p.id] = (R, t + shift)
        y_cursor += float(np.ptp(pts[:, 1])) + gap
    return [{"id": pid, "band": layout.panels[pid].band, "rotation": R, "translation": t}
            for pid, (R, t) in sorted(placements.items())]


def _orient_band_start(uv: np.ndarray, panel) -> tuple[np.ndarray, np.ndarray]:
    """Rotate the first panel of a band so its first row (an arc) runs along +x."""
    a = uv[0]
    b = uv[len(panel.stations) - 1]
    d = (b - a) / np.linalg.norm(b - a)
    R = np.array([[d[0], d[1]], [-d[1], d[0]]])
    return R, -R @ a


def _kabsch_2d(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Best rotation R and translation t with src @ R.T + t ~ dst (no reflection)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    H = (src - cs).T @ (dst - cd)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, cd - R @ cs


def run_report(run: PanelsRun) -> dict:
    """The JSON report of a multi-panel run."""
    layout = run.layout
    n = len(layout.panels)
    cong = run.congruency
    per_panel_cong = cong.per_panel_max(n)
    arc_planarity = _arc_planarity(layout)
    return {
        "format": "fabkit.panels/1",
        "ok": run.ok,
        "panels": n,
        "bands": int(len(layout.arcs) - 1),
        "singularity_points": int(len(layout.singular_keys)),
        "singularity_points_per_panel": layout.singularity_ratio,
        "singularity_note": "paper §3.2 says n/2; aligned band pairs give cols-1 and offset pairs cols "
                            "four-panel corners, so the ratio approaches 1/2 as cols grows",
        "max_arc_plane_distance_m": arc_planarity,
        "options": run.options.__dict__,
        "tolerances": {"congruency": run.options.tol_congruency, "unfold": run.options.tol_unfold},
        "max_incongruency": cong.max_relative,
        "mean_incongruency": cong.mean_relative,
        "max_unfold_deviation": max(r.unfold_max for r in run.results),
        "max_deviation_from_targets": max(r.target_max for r in run.results),
        "relax_converged": sum(r.converged for r in run.results),
        "rounds": list(run.rounds),
        "seconds": run.seconds,
        "failing_panels": [{"id": i, "name": layout.panels[i].name, "why": why} for i, why in run.failing_panels()],
        "per_panel": [{
            "id": r.id, "name": layout.panels[r.id].name, "band": layout.panels[r.id].band,
            "index": layout.panels[r.id].index, "converged": r.converged, "max_defect_rad": r.max_defect,
            "max_planarity": r.max_planarity, "max_displacement_m": r.max_displacement,
            "unfold_mean": r.unfold_mean, "unfold_max": r.unfold_max, "target_max": r.target_max,
            "flipped": r.flipped, "outline_overlaps": r.overlaps, "max_incongruency": float(per_panel_cong[r.id]),
        } for r in run.results],
    }


def _arc_planarity(layout) -> float:
    P = layout.surface.points
    worst = 0.0
    for j in layout.arcs:
        X = P[:, j] - P[:, j].mean(axis=0)
        n = np.linalg.svd(X)[2][-1]
        worst = max(worst, float(np.abs(X @ n).max()))
    return worst


def panel_file_texts(task: dict) -> dict[str, str]:
    """One panel's geometry files as {file name: text}: the relaxed and the flat OBJ, the
    crease-pattern FOLD (validated) and, with `task["cut_files"]`, the DXF and SVG cut files.
    Pure (picklable task in, texts out), so the panels' files are made on any executor."""
    import io

    from fabkit.cutfiles.creases import crease_assignment
    from fabkit.cutfiles.dxf import dxf_document
    from fabkit.cutfiles.pattern import cut_pattern
    from fabkit.cutfiles.svg import svg_text
    from fabkit.fold import FoldFrame, FoldModel, validate_fold_model
    from fabkit.io.fold import fold_text
    from fabkit.io.obj import format_obj

    name, mesh, relaxed, uv = task["name"], task["mesh"], np.asarray(task["relaxed"]), np.asarray(task["uv"])
    mesh3d = mesh.with_vertices(relaxed)
    flat = mesh.with_vertices(np.column_stack([uv, np.zeros(len(uv))]))
    creases = crease_assignment(mesh3d)
    model = FoldModel.from_mesh(flat, creases.edges_assignment, creases.edges_fold_angle,
                                frames=(FoldFrame(mesh3d.vertices, creases.edges_fold_angle),),
                                file_data={"panel": name}, classes=("creasePattern",), title=f"fabkit panel {name}")
    validate_fold_model(model, source=f"{name}.fold")
    out = {f"{name}.obj": format_obj(mesh3d), f"{name}_flat.obj": format_obj(flat), f"{name}.fold": fold_text(model)}
    if task["cut_files"]:
        pattern = cut_pattern(mesh3d, uv, creases, panel_id=name)
        buf = io.StringIO()
        dxf_document(pattern).write(buf)
        out[f"{name}.dxf"] = buf.getvalue()
        out[f"{name}.svg"] = svg_text(pattern)
    return out


def write_run(run: PanelsRun, out: str | os.PathLike, *, plots: bool = True, cut_files: bool = True,
              jobs: int = 1, scheduler: str | None = None, executor=None) -> dict:
    """Write every artifact of `run` into `out` (created if needed); returns the report dict.

    The panels' files are made on `jobs` worker processes (or the dask `scheduler`, or the open
    `executor` of the run) and written here;
    the staging folder is moved into place only when all of them are written."""
    from fabkit.io.atomic import write_error
    from fabkit.panels.executor import map_ordered, panel_executor

    out = Path(out)
    parent = out.parent if str(out.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    try:
        pdir = stage / "panels"
        pdir.mkdir()
        report = run_report(run)
        tasks = [{"name": p.name, "mesh": p.mesh, "relaxed": r.relaxed, "uv": r.uv, "cut_files": cut_files}
                 for p, r in zip(run.layout.panels, run.results)]
        with (contextlib.nullcontext(executor) if executor is not None else
              panel_executor(jobs if len(tasks) > 1 else 1, scheduler)) as ex:
            for files in map_ordered(ex, panel_file_texts, tasks):
                for fname, text in files.items():  # the staging folder is the atomic unit (moved at the end)
                    try:
                        (pdir / fname).write_text(text, encoding="utf-8")
                    except OSError as exc:
                        raise write_error(exc, out / "panels" / fname) from None
        bands = band_layout(run)
        write_json(stage / "band_layout.json", {"format": "fabkit.bands/1", "placements": bands})
        if plots:
            from fabkit.panels import plots as P

            P.plot_panel_errors(run, stage / "unfold_error_per_panel.png")
            P.plot_band_layout(run, bands, stage / "band_layout.png")
            P.plot_surface_errors(run, stage / "surface_error.png")
            P.plot_rounds(run, stage / "feedback_rounds.png")
        write_json(stage / "report.json", report)
        out.mkdir(parents=True, exist_ok=True)
        for src in sorted(stage.rglob("*")):
            dst = out / src.relative_to(stage)
            if src.is_dir():
                dst.mkdir(exist_ok=True)
            else:
                os.replace(src, dst)
        return to_jsonable(report)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
