"""One DXF and one SVG per nested sheet: outlines, creases, crease detailing and labels (mm).

Layers:
- `CUT` outlines (closed LWPOLYLINE), `RELIEF` relief holes where a crease meets the outline
  (CIRCLE, diameter `relief_factor * t`, at least t/2, the sheet-metal rule of thumb), both cut through;
- `MOUNTAIN` / `VALLEY` the creases as true curves: a DXF SPLINE through the crease polyline's
  vertices (ezdxf `fit_points_to_cad_cv`), kept only when it stays within `spline_allowance` of
  the polyline (measured: Hausdorff distance of the spline, sampled, to the polyline), else the
  polyline;
- `GROOVE_TOP` / `GROOVE_BOTTOM` V-groove centre lines of the valley / mountain creases (a groove
  goes on the inside of the bend: the front face for a valley, the back face for a mountain; the
  drawing shows both seen from the front). Depth and angle are in the layer description;
- `LABEL` engravable text (DXF TEXT, single-line): the panel id at its centre, under it the cut
  files' face-up mark (`FACE UP: FRONT (valleys fold up); 1 mm 5052-H32`, from the placed
  drawing's turning sense, `fabkit.cutfiles.pattern.face_up`), each neighbour's id next to the side
  they share, and an orientation arrow pointing from the panel's first arc towards its second.
Kerf is not compensated (nominal geometry; the CAM applies it), as the shops expect.
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path
from xml.sax.saxutils import escape

import ezdxf
import numpy as np
from ezdxf import units
from ezdxf.math import fit_points_to_cad_cv
from shapely.geometry import LineString

from fabkit.cutfiles.creases import chain_edges, crease_assignment
from fabkit.cutfiles.pattern import face_up, face_up_text
from fabkit.io.atomic import atomic_path, atomic_write

__all__ = ["write_sheets", "sheet_drawing", "sheet_note", "SPLINE_TOL_MM", "spline_allowance", "spline_deviation", "SHEET_LAYERS"]

#: Tolerance [mm] of a crease SPLINE: it passes through every vertex of the crease polyline and may
#: leave the polyline by at most this plus the polyline's own chord error (the sagitta c^2 k / 8 of
#: its longest chord c at the largest discrete curvature k, where the smooth crease runs off the
#: chords too); `spline_allowance`.
SPLINE_TOL_MM = 0.05
#: layer -> (DXF colour, SVG colour)
SHEET_LAYERS = {"CUT": (7, "#000000"), "RELIEF": (7, "#000000"), "MOUNTAIN": (1, "#d62728"),
                "VALLEY": (5, "#1f4fd6"), "GROOVE_TOP": (4, "#0aa"), "GROOVE_BOTTOM": (6, "#b0b"),
                "LABEL": (3, "#2ca02c")}


def spline_allowance(points: np.ndarray) -> float:
    """Allowed Hausdorff distance [mm] of a crease spline from its polyline (see `SPLINE_TOL_MM`)."""
    P = np.asarray(points, float)
    if len(P) < 3:
        return SPLINE_TOL_MM
    a, b, c = P[:-2], P[1:-1], P[2:]
    ab, bc, ca = (np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1))
    cross = np.abs((b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0])
    kappa = 2 * cross / np.maximum(ab * bc * ca, 1e-300)  # curvature of the circle through 3 vertices
    chord = np.linalg.norm(np.diff(P, axis=0), axis=1).max()
    return SPLINE_TOL_MM + chord ** 2 * float(kappa.max()) / 8


def spline_deviation(points: np.ndarray, bspline, samples_per_segment: int = 8) -> float:
    """Hausdorff distance [mm] between a B-spline (sampled) and the polyline through `points`."""
    curve = np.array([tuple(p)[:2] for p in bspline.approximate(samples_per_segment * max(1, len(points) - 1))])
    return float(LineString(curve).hausdorff_distance(LineString(points)))


def _apply(M: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return np.asarray(pts, float) @ M[:, :2].T + M[:, 2]


def _panel_drawing(panel, result, neighbours: dict, M: np.ndarray, name_of, thickness_mm: float,
                   relief_factor: float, face_note: str = "") -> dict:
    """Sheet-coordinate geometry of one panel (see the module docstring)."""
    mesh3d = panel.mesh.with_vertices(result.relaxed)
    uv = np.asarray(result.uv) * 1000.0
    P = _apply(M, uv)
    loop = max(panel.mesh.boundary_loops, key=len)
    ca = crease_assignment(mesh3d)
    creases = {}
    reliefs = []
    boundary = set(int(v) for v in loop)
    fold = {}
    for kind, layer in (("M", "MOUNTAIN"), ("V", "VALLEY")):
        e = panel.mesh.edges[ca.edges_with(kind)]
        if not len(e):
            continue
        chains = [np.array(c) for c in chain_edges(e)]
        creases[layer] = [P[c] for c in chains]
        fold[layer] = float(np.degrees(np.abs(ca.edges_fold_angle[ca.edges_with(kind)]).max()))
        for c in chains:
            for end in (c[0], c[-1]):
                if int(end) in boundary:
                    reliefs.append(P[end])
    c = P[loop].mean(axis=0)
    labels = [(name_of(panel.id), c[0], c[1], 0.0, 8.0),  # the cut files' face-up mark, under the id
              (face_up_text(face_up(panel.mesh, P), face_note), c[0], c[1] - 9.0, 0.0, 3.0)]
    E = panel.mesh.edges
    for other, edges in sorted(neighbours.items()):
        mids = np.array([0.5 * (P[E[e, 0]] + P[E[e, 1]]) for e in edges])
        d = P[E[edges[-1], 1]] - P[E[edges[0], 0]]
        mid = mids[len(mids) // 2]
        pos = mid + 0.18 * (c - mid)
        ang = math.degrees(math.atan2(d[1], d[0]))
        ang = ang - 180.0 if ang > 90 else ang + 180.0 if ang < -90 else ang  # readable, never upside down
        labels.append((name_of(other), pos[0], pos[1], ang, 4.0))
    # orientation arrow: from the first arc towards the second, across the band
    n_st = len(panel.stations)
    a0 = P[:n_st].mean(axis=0)
    a1 = P[-n_st:].mean(axis=0)
    u = (a1 - a0) / max(np.linalg.norm(a1 - a0), 1e-9)
    v = np.array([-u[1], u[0]])
    base = c - 22.0 * u
    tip = base + 12.0 * u
    arrow = np.array([base, tip, tip - 4.0 * u + 2.5 * v, tip, tip - 4.0 * u - 2.5 * v])
    return {"outline": P[loop], "creases": creases, "reliefs": reliefs, "fold_max_deg": fold,
            "relief_diameter": max(0.5 * thickness_mm, relief_factor * thickness_mm), "labels": labels,
            "arrow": arrow}


def sheet_drawing(geometry, nest, sheet: int, thickness_mm: float, relief_factor: float = 1.5,
                  face_note: str = "") -> list[dict]:
    """Per panel on `sheet`: its drawing in sheet coordinates (mm); `face_note` follows the face-up
    mark (`fabkit.cutfiles.pattern.face_up_text`)."""
    layout = geometry.layout
    neighbours: dict[int, dict[int, list[int]]] = {p.id: {} for p in layout.panels}
    for pa, ea, pb, eb in layout.shared_edges:
        neighbours[pa].setdefault(pb, []).append(int(ea))
        neighbours[pb].setdefault(pa, []).append(int(eb))
    out = []
    for p in nest.placements:
        if p.sheet != sheet:
            continue
        panel = layout.panels[p.part]
        d = _panel_drawing(panel, geometry.results[p.part], neighbours[p.part], nest.sheet_transform(p.part),
                           lambda i: layout.panels[i].name, thickness_mm, relief_factor, face_note)
        out.append({"id": panel.name, "panel": p.part, **d})
    return out


def _dxf(drawings: list[dict], sheet_size, thickness_mm: float) -> tuple["ezdxf.document.Drawing", dict]:
    doc = ezdxf.new("R2010", units=units.MM)
    doc.header["$INSUNITS"] = units.MM
    doc.header["$MEASUREMENT"] = 1
    groove = f"V-groove centre line, depth {0.5 * thickness_mm:g} mm (t/2), included angle 90 deg"
    descriptions = {"CUT": "outline: cut through", "RELIEF": "relief holes where a crease meets the outline: cut",
                    "MOUNTAIN": "mountain crease (reference)", "VALLEY": "valley crease (reference)",
                    "GROOVE_TOP": groove + ", front face (valleys)",
                    "GROOVE_BOTTOM": groove + ", back face (mountains), positions seen from the front",
                    "LABEL": "engrave: panel id, face-up mark, neighbour ids at shared sides, orientation arrow"}
    for name, (aci, _) in SHEET_LAYERS.items():
        doc.layers.add(name, color=aci).description = descriptions[name]
    msp = doc.modelspace()
    W, H = sheet_size
    msp.add_lwpolyline([(0, 0), (W, 0), (W, H), (0, H)], close=True, dxfattribs={"layer": "LABEL", "linetype": "CONTINUOUS"})
    stats = {"splines": 0, "polylines_kept": 0, "max_spline_deviation_mm": 0.0}
    for d in drawings:
        msp.add_lwpolyline(d["outline"].tolist(), format="xy", close=True, dxfattribs={"layer": "CUT"})
        for ctr in d["reliefs"]:
            msp.add_circle((float(ctr[0]), float(ctr[1])), d["relief_diameter"] / 2, dxfattribs={"layer": "RELIEF"})
        for layer, chains in d["creases"].items():
            groove = "GROOVE_TOP" if layer == "VALLEY" else "GROOVE_BOTTOM"
            for pts in chains:
                msp.add_lwpolyline(pts.tolist(), format="xy", dxfattribs={"layer": groove})
                if len(pts) >= 3:
                    bs = fit_points_to_cad_cv([(float(x), float(y), 0.0) for x, y in pts])
                    dev = spline_deviation(pts, bs)
                    if dev <= spline_allowance(pts):
                        msp.add_spline(dxfattribs={"layer": layer}).apply_construction_tool(bs)
                        stats["splines"] += 1
                        stats["max_spline_deviation_mm"] = max(stats["max_spline_deviation_mm"], dev)
                        continue
                msp.add_lwpolyline(pts.tolist(), format="xy", dxfattribs={"layer": layer})
                stats["polylines_kept"] += 1
        for text, x, y, ang, h in d["labels"]:
            msp.add_text(text, height=h, rotation=ang, dxfattribs={"layer": "LABEL"}).set_placement(
                (float(x), float(y)), align=ezdxf.enums.TextEntityAlignment.MIDDLE_CENTER)
        msp.add_lwpolyline(d["arrow"].tolist(), format="xy", dxfattribs={"layer": "LABEL"})
    return doc, stats


def _fmt(v: float) -> str:
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _svg(drawings: list[dict], sheet_size) -> str:
    """SVG of a sheet (hand-written XML like fabkit.cutfiles.svg; y flipped, mm)."""
    W, H = sheet_size

    def pts(a):
        return " ".join(f"{_fmt(x)},{_fmt(H - y)}" for x, y in np.asarray(a).tolist())

    groups: dict[str, list[str]] = {k: [] for k in SHEET_LAYERS}
    groups["LABEL"].append(f'<rect x="0" y="0" width="{_fmt(W)}" height="{_fmt(H)}" fill="none" stroke="#2ca02c"/>')
    for d in drawings:
        groups["CUT"].append(f'<polygon points="{pts(d["outline"])}"/>')
        for ctr in d["reliefs"]:
            groups["RELIEF"].append(f'<circle cx="{_fmt(ctr[0])}" cy="{_fmt(H - ctr[1])}" r="{_fmt(d["relief_diameter"] / 2)}"/>')
        for layer, chains in d["creases"].items():
            groove = "GROOVE_TOP" if layer == "VALLEY" else "GROOVE_BOTTOM"
            for c in chains:
                groups[layer].append(f'<polyline points="{pts(c)}"/>')
                groups[groove].append(f'<polyline points="{pts(c)}"/>')
        for text, x, y, ang, h in d["labels"]:
            groups["LABEL"].append(f'<text x="{_fmt(x)}" y="{_fmt(H - y)}" font-size="{_fmt(h)}" text-anchor="middle" '
                                   f'dominant-baseline="middle" transform="rotate({_fmt(-ang)} {_fmt(x)} {_fmt(H - y)})">'
                                   f'{escape(text)}</text>')
        groups["LABEL"].append(f'<polyline points="{pts(d["arrow"])}" fill="none" stroke="#2ca02c"/>')
    out = ['<?xml version="1.0" encoding="UTF-8"?>\n',
           '<svg xmlns="http://www.w3.org/2000/svg" xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" '
           f'width="{_fmt(W)}mm" height="{_fmt(H)}mm" viewBox="0 0 {_fmt(W)} {_fmt(H)}">\n']
    for name, (_, colour) in SHEET_LAYERS.items():
        style = (f'fill="{colour}" stroke="none" font-family="sans-serif"' if name == "LABEL"
                 else f'fill="none" stroke="{colour}" stroke-width="0.2"')
        out.append(f'<g id="{name}" inkscape:groupmode="layer" inkscape:label="{name}" {style}>\n')
        out.extend(f"{g}\n" for g in groups[name])
        out.append("</g>\n")
    out.append("</svg>\n")
    return "".join(out)


def _png(drawings: list[dict], sheet_size, path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection, PolyCollection

    W, H = sheet_size
    fig = plt.figure(figsize=(8, 8 * (H + 40) / (W + 20)))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0 - 0.3 / (8 * (H + 40) / (W + 20))))  # room for the title, drawn once
    ax.add_patch(plt.Rectangle((0, 0), W, H, fill=False, color="#2ca02c"))
    ax.add_collection(PolyCollection([d["outline"] for d in drawings], facecolor="#dde6ee", edgecolor="k", lw=0.5))
    for layer in ("MOUNTAIN", "VALLEY"):
        chains = [c for d in drawings for c in d["creases"].get(layer, [])]
        if chains:
            ax.add_collection(LineCollection(chains, colors=SHEET_LAYERS[layer][1], lw=0.6))
    for d in drawings:
        ax.text(*d["labels"][0][1:3], d["id"], fontsize=4, ha="center", va="center")
    ax.set_aspect("equal")
    ax.set_xlim(-10, W + 10)
    ax.set_ylim(-10, H + 10)
    ax.set_title(title, fontsize=9)
    ax.axis("off")
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def sheet_note(material, sheet=None) -> str:
    """What follows the face-up mark on a production sheet: thickness and material, and with a
    grooved `sheet` (`fabkit.sheet.SheetSpec`) where the grooves go (as `fabkit unfold --material`)."""
    note = f"{material.thickness * 1000:g} mm {material.name}"
    if sheet is not None and sheet.prep.kind == "grooved":
        note += "; grooves on the inside of each fold: valleys front, mountains back"
    return note


def write_sheets(production_or_geometry, nest, folder: str | os.PathLike, material, relief_factor: float = 1.5,
                 pictures: bool = True, sheet=None) -> list[dict]:
    """Write sheets/sheet_NN.{dxf,svg,json,png}; returns one summary dict per sheet. `material`
    (`fabkit.panels.production.Stock`) and `sheet` (the programs' `SheetSpec` or None) name the
    sheet after every panel's face-up mark."""
    geometry = getattr(production_or_geometry, "geometry", production_or_geometry)
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    t_mm = material.thickness * 1000.0
    size = nest.nesting.options.sheet
    out = []
    for s in range(nest.nesting.n_sheets):
        drawings = sheet_drawing(geometry, nest, s, t_mm, relief_factor, sheet_note(material, sheet))
        stem = f"sheet_{s + 1:02d}"
        doc, stats = _dxf(drawings, size, t_mm)
        with atomic_path(folder / f"{stem}.dxf") as tmp:
            doc.saveas(tmp)
        with atomic_write(folder / f"{stem}.svg") as fh:
            fh.write(_svg(drawings, size))
        if pictures:
            _png(drawings, size, folder / f"{stem}.png", f"{stem}: {len(drawings)} panels")
        area = sum(nest.parts[d["panel"]].area for d in drawings)
        info = {"sheet": s + 1, "dxf": f"sheets/{stem}.dxf", "svg": f"sheets/{stem}.svg",
                "png": f"sheets/{stem}.png" if pictures else None, "panels": [d["id"] for d in drawings],
                "part_area_mm2": area, "utilisation": area / (size[0] * size[1]),
                "relief_diameter_mm": max(0.5 * t_mm, relief_factor * t_mm), "spline_tolerance_mm": SPLINE_TOL_MM,
                **stats, "transforms": {d["id"]: nest.sheet_transform(d["panel"]).tolist() for d in drawings}}
        with atomic_write(folder / f"{stem}.json") as fh:
            json.dump(info, fh, indent=1)
        out.append({k: v for k, v in info.items() if k != "transforms"})
    return out
