"""The report of a production run: totals, per-panel status and files, nesting, assembly order."""
from __future__ import annotations

__all__ = ["assembly", "summary"]


def _sides(panel) -> dict[int, str]:
    """Global point key -> side name for the boundary rows/columns of a panel."""
    k = panel.keys
    out = {}
    for name, keys in (("start", k[:, 0]), ("end", k[:, -1]), ("first arc", k[0]), ("second arc", k[-1])):
        for key in keys.tolist():
            out.setdefault(int(key), name)
    return out


def assembly(layout) -> dict:
    """Assembly order and per-panel placement (neighbours by side, face up).

    Order: band by band from the first arc, along each band: every panel after the first meets at
    least one panel already in place (its predecessor in the band, or the band before).
    """
    neighbours: dict[int, dict[int, set]] = {p.id: {} for p in layout.panels}
    for pa, ea, pb, eb in layout.shared_edges:
        for me, e, other in ((pa, ea, pb), (pb, eb, pa)):
            p = layout.panels[me]
            keys = p.keys.ravel()
            a, b = (int(keys[v]) for v in p.mesh.edges[e])
            sides = _sides(p)
            side = sides[a] if sides[a] == sides[b] else sides[b]
            neighbours[me].setdefault(other, set()).add(side)
    order = [p.id for p in sorted(layout.panels, key=lambda p: (p.band, p.index))]
    placed = []
    for step, pid in enumerate(order):
        p = layout.panels[pid]
        before = [layout.panels[o].name for o in neighbours[pid] if o in set(order[:step])]
        placed.append({"step": step + 1, "id": p.name, "band": p.band, "index": p.index,
                       "face_up": "front (the surface's outer side; the side up on the cutting sheet)",
                       "neighbours": [{"id": layout.panels[o].name, "sides": sorted(s)}
                                      for o, s in sorted(neighbours[pid].items())],
                       "joins": before})
    return {"format": "fabkit.assembly/1", "order": [layout.panels[i].name for i in order], "panels": placed}


def summary(run, nest, mat, layout) -> dict:
    """The production report: totals, per-panel status and files, nesting, assembly."""
    from collections import Counter

    W, H = nest.nesting.options.sheet
    sheet_of = {p.part: p.sheet + 1 for p in nest.placements}
    n_sheets = nest.nesting.n_sheets
    ok = sum(p.ok for p in run.panels)
    material_area = n_sheets * W * H * 1e-6
    geo = {"obj": "panels/{}.obj", "flat": "panels/{}_flat.obj", "crease_pattern": "panels/{}.fold",
           "dxf": "panels/{}.dxf", "svg": "panels/{}.svg"}
    per = []
    for p in run.panels:
        lp = layout.panels[p.id]
        per.append({"id": p.id, "name": p.name, "band": lp.band, "index": lp.index, "ok": p.ok,
                    "status": "ok" if p.ok else p.stage, "reason": p.reason, "cycle_time_s": p.cycle_time_s,
                    "unfold_max": p.unfold_max, "grip_face": p.grip_face, "sheet": sheet_of.get(p.id),
                    "recomputed": p.recomputed, "same_as": p.same_as,
                    "files": {**{k: v.format(p.name) for k, v in geo.items()}, **p.files}})
    return {
        "format": "fabkit.production/1", "ok": run.ok, "material": {"name": mat.name, "thickness_m": mat.thickness,
                                                                       "density_kg_m3": mat.density},
        "totals": {"panels": len(run.panels), "ok": ok, "failed": len(run.panels) - ok,
                   "failed_by_stage": dict(Counter(p.stage for p in run.panels if not p.ok)),
                   "robot_time_s": run.robot_time_s, "sheets": n_sheets, "sheet_mm": [W, H],
                   "parts": len({p.same_as or p.name for p in run.panels}),
                   "utilisation": nest.nesting.utilisation,
                   "utilisation_last_sheet_by_length": nest.nesting.used_length_utilisation(nest.parts),
                   "panel_area_m2": nest.nesting.part_area * 1e-6, "material_area_m2": material_area,
                   "material_kg": material_area * mat.thickness * mat.density,
                   "panel_mass_kg": nest.nesting.part_area * 1e-6 * mat.thickness * mat.density},
        "recomputed": run.recomputed, "seconds_by_stage": run.seconds,
        "nesting": {"engine": nest.nesting.engine, "seconds": nest.nesting.seconds, "notes": list(nest.nesting.notes),
                    "spacing_mm": nest.nesting.options.spacing, "kerf_mm": nest.nesting.options.kerf,
                    "edge_mm": nest.nesting.options.edge, "grain": nest.nesting.options.grain},
        "panels": per,
        "assembly": assembly(layout),
    }
