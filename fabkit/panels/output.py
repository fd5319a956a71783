"""Write a multi-panel run to a folder: per-panel OBJ/FOLD/DXF/SVG, band layout, plots, JSON report.

Everything is written into a hidden staging folder next to the target and moved into place only
when every file succeeded, so a failed run leaves no partial output behind.
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from fabkit.io.jsonfile import to_jsonable, write_json
from fabkit.panels.workflow import PanelsRun

__all__ = ["write_run", "run_report", "band_layout"]


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


def write_run(run: PanelsRun, out: str | os.PathLike, *, plots: bool = True, cut_files: bool = True) -> dict:
    """Write every artifact of `run` into `out` (created if needed); returns the report dict."""
    from fabkit.cutfiles.creases import crease_assignment
    from fabkit.cutfiles.dxf import write_dxf
    from fabkit.cutfiles.pattern import cut_pattern
    from fabkit.cutfiles.svg import write_svg
    from fabkit.fold import FoldFrame, FoldModel
    from fabkit.io.fold import save_fold
    from fabkit.io.obj import save_obj

    out = Path(out)
    parent = out.parent if str(out.parent) else Path(".")
    parent.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=parent))
    try:
        pdir = stage / "panels"
        pdir.mkdir()
        report = run_report(run)
        for p, r in zip(run.layout.panels, run.results):
            mesh3d = p.mesh.with_vertices(r.relaxed)
            flat = p.mesh.with_vertices(np.column_stack([r.uv, np.zeros(len(r.uv))]))
            save_obj(mesh3d, pdir / f"{p.name}.obj")
            save_obj(flat, pdir / f"{p.name}_flat.obj")
            creases = crease_assignment(mesh3d)
            model = FoldModel.from_mesh(flat, creases.edges_assignment, creases.edges_fold_angle,
                                        frames=(FoldFrame(mesh3d.vertices, creases.edges_fold_angle),),
                                        file_data={"panel": p.name}, classes=("creasePattern",),
                                        title=f"fabkit panel {p.name}")
            save_fold(model, pdir / f"{p.name}.fold")
            if cut_files:
                pattern = cut_pattern(mesh3d, r.uv, creases, panel_id=p.name)
                write_dxf(pattern, pdir / f"{p.name}.dxf")
                write_svg(pattern, pdir / f"{p.name}.svg")
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
