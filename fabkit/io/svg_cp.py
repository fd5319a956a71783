"""SVG crease patterns in Origami Simulator's colour convention, read as a flat panel.

Stroke colours (as Origami Simulator's importer reads them, `js/pattern.js`): black boundary (B),
red mountain (M), blue valley (V), green cut (C), yellow facet / triangulation (F), magenta
unassigned hinge (U); a stroke opacity below 1 is Origami Simulator's partial fold angle and is only
reported here (fabkit takes fold angles from the folded geometry). Other colours are refused,
naming them, as Origami Simulator warns about them.

Elements read: `line`, `polyline`, `polygon`, `rect`, and `path` with straight segments
(M/L/H/V/Z, absolute or relative); stroke and opacity from attributes, `style` or an enclosing
`g`. `transform` attributes are refused (flatten them in the drawing program first). The lines are
noded and the faces found with shapely (`unary_union` + `polygonize`). SVG's y axis points down:
y is flipped so the pattern is seen from the front as drawn. Units: width/height in mm, cm, in or
pt with a viewBox give the unit of the coordinates (read as millimetres); plain user units (px)
have no physical size and take `--units` (metres when not given, with a note).
"""
from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from fabkit.errors import InputError

__all__ = ["read_svg_crease_pattern", "RawCreasePattern", "STROKE_ASSIGNMENT"]

_COLOURS = ((("#000000", "#000", "black", "rgb(0,0,0)"), "B"),
            (("#ff0000", "#f00", "red", "rgb(255,0,0)"), "M"),
            (("#0000ff", "#00f", "blue", "rgb(0,0,255)"), "V"),
            (("#00ff00", "#0f0", "green", "rgb(0,255,0)"), "C"),
            (("#ffff00", "#ff0", "yellow", "rgb(255,255,0)"), "F"),
            (("#ff00ff", "#f0f", "magenta", "rgb(255,0,255)"), "U"))
#: stroke colour -> FOLD assignment, as Origami Simulator's `typeForStroke`
STROKE_ASSIGNMENT = {name: letter for names, letter in _COLOURS for name in names}

_MM_PER = {"mm": 1.0, "cm": 10.0, "in": 25.4, "pt": 25.4 / 72}
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


@dataclass(frozen=True)
class RawCreasePattern:
    """Flat vertices (n, 3) in file units, faces, `{(u, v): letter}` with u < v, unit (or None)."""

    vertices: np.ndarray
    faces: list
    sides: dict
    unit: str | None
    notes: tuple


def _style(el: ET.Element, inherited: dict) -> dict:
    out = dict(inherited)
    for key in ("stroke", "opacity", "stroke-opacity"):
        if el.get(key) is not None:
            out[key] = el.get(key)
    for part in (el.get("style") or "").split(";"):
        if ":" in part:
            k, v = part.split(":", 1)
            if k.strip() in ("stroke", "opacity", "stroke-opacity"):
                out[k.strip()] = v.strip()
    return out


def _floats(text: str | None) -> list[float]:
    return [float(t) for t in re.findall(_NUM, text or "")]


def _path_points(d: str, source: str) -> list[list[tuple[float, float]]]:
    """Straight-segment path data -> polylines (absolute coordinates)."""
    tokens = re.findall(r"[A-Za-z]|" + _NUM, d)
    runs, cur, pos, start, cmd, i = [], [], (0.0, 0.0), (0.0, 0.0), None, 0
    while i < len(tokens):
        t = tokens[i]
        if t.isalpha():
            cmd = t
            i += 1
            if cmd in "Zz":
                if cur:
                    cur.append(start)
                    runs.append(cur)
                cur, pos = [], start
            elif cmd not in "MmLlHhVv":
                raise InputError(f"path command '{cmd}' draws a curve: a crease pattern is straight lines "
                                 "(flatten curves to polylines)", source=source)
            continue
        if cmd is None:
            raise InputError("path data does not start with a command", source=source)
        rel = cmd.islower()
        c = cmd.upper()
        if c in "ML":
            x, y = float(tokens[i]), float(tokens[i + 1])
            i += 2
            pos = (pos[0] + x, pos[1] + y) if rel else (x, y)
            if c == "M":
                if len(cur) > 1:
                    runs.append(cur)
                cur, start = [pos], pos
                cmd = "l" if rel else "L"  # further pairs after M are line-tos
            else:
                cur.append(pos)
        elif c == "H":
            x = float(tokens[i])
            i += 1
            pos = (pos[0] + x if rel else x, pos[1])
            cur.append(pos)
        elif c == "V":
            y = float(tokens[i])
            i += 1
            pos = (pos[0], pos[1] + y if rel else y)
            cur.append(pos)
    if len(cur) > 1:
        runs.append(cur)
    return runs


def _unit_scale(root: ET.Element) -> tuple[str | None, float]:
    """(unit, file units per user unit) from width + viewBox."""
    width, box = root.get("width"), root.get("viewBox")
    m = re.fullmatch(r"\s*(" + _NUM + r")\s*(mm|cm|in|pt)\s*", width or "")
    if not m or not box:
        return None, 1.0
    vb = _floats(box)
    if len(vb) != 4 or vb[2] <= 0:
        return None, 1.0
    return "mm", float(m.group(1)) * _MM_PER[m.group(2)] / vb[2]


def read_svg_crease_pattern(path: str | os.PathLike) -> RawCreasePattern:
    """An SVG crease pattern (see module docstring) -> flat vertices, faces and edge assignments."""
    import shapely
    from shapely.geometry import LineString
    from shapely.ops import polygonize, unary_union

    from fabkit.io.obj import read_text

    source = str(path)
    text = read_text(path, "SVG")
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise InputError(f"not an SVG file ({exc})", source=source) from None
    unit, per_user = _unit_scale(root)
    segments: list[tuple[tuple, tuple, str]] = []
    bad_colours: set[str] = set()
    partial = 0

    def walk(el: ET.Element, inherited: dict) -> None:
        nonlocal partial
        style = _style(el, inherited)
        if el.get("transform"):
            raise InputError(f"<{el.tag.split('}')[-1]}> has a transform: fabkit reads untransformed "
                             "coordinates (flatten transforms in the drawing program)", source=source)
        tag = el.tag.split("}")[-1]
        runs = []
        if tag == "line":
            runs = [[(float(el.get("x1", 0)), float(el.get("y1", 0))), (float(el.get("x2", 0)), float(el.get("y2", 0)))]]
        elif tag in ("polyline", "polygon"):
            p = _floats(el.get("points"))
            pts = list(zip(p[0::2], p[1::2]))
            runs = [pts + ([pts[0]] if tag == "polygon" and pts else [])]
        elif tag == "rect":
            x, y = float(el.get("x", 0)), float(el.get("y", 0))
            w, h = float(el.get("width", 0)), float(el.get("height", 0))
            runs = [[(x, y), (x + w, y), (x + w, y + h), (x, y + h), (x, y)]]
        elif tag == "path":
            runs = _path_points(el.get("d", ""), source)
        if runs:
            stroke = (style.get("stroke") or "none").replace(" ", "").lower()
            letter = STROKE_ASSIGNMENT.get(stroke)
            if letter is None:
                bad_colours.add(stroke)
            else:
                op = 1.0
                for k in ("opacity", "stroke-opacity"):
                    try:
                        op *= float(style.get(k, 1))
                    except ValueError:
                        pass
                partial += int(letter in "MV" and op < 1)
                for run in runs:
                    for a, b in zip(run, run[1:]):
                        if a != b:
                            segments.append((a, b, letter))
        for child in el:
            walk(child, style)

    walk(root, {})
    if bad_colours:
        raise InputError(f"strokes of unknown colour {', '.join(sorted(bad_colours))}: Origami Simulator's "
                         "convention is black boundary, red mountain, blue valley, green cut, yellow facet, "
                         "magenta hinge", source=source)
    if not segments:
        raise InputError("no lines in the crease pattern", source=source)
    pts = np.array([p for a, b, _ in segments for p in (a, b)], dtype=np.float64) * per_user
    size = float(np.linalg.norm(np.ptp(pts, axis=0))) or 1.0
    tol = 1e-6 * size
    lines = [LineString([np.array(a) * per_user, np.array(b) * per_user]) for a, b, _ in segments]
    noded = unary_union(lines)
    faces_poly = [p for p in polygonize(noded)]
    if not faces_poly:
        raise InputError("the lines enclose no face (is the boundary closed?)", source=source)
    if any(len(p.interiors) for p in faces_poly):
        raise InputError("a face has a hole in it: cut it with a line so every face is a simple polygon",
                         source=source)
    key_of: dict[tuple[int, int], int] = {}
    V: list[tuple[float, float]] = []

    def vid(x: float, y: float) -> int:
        k = (round(x / tol), round(y / tol))
        if k not in key_of:
            key_of[k] = len(V)
            V.append((x, y))
        return key_of[k]

    faces = []
    for poly in faces_poly:
        ring = [vid(x, y) for x, y in list(poly.exterior.coords)[:-1]]
        ring = [v for i, v in enumerate(ring) if v != ring[i - 1]]
        if len(ring) >= 3:
            faces.append(ring)
    tree = shapely.STRtree(lines)
    sides: dict[tuple[int, int], str] = {}
    rank = {"C": 0, "B": 1, "M": 2, "V": 2, "U": 3, "F": 4}
    for f in faces:
        for a, b in zip(f, f[1:] + f[:1]):
            key = (min(a, b), max(a, b))
            if key in sides:
                continue
            mid = shapely.Point((V[a][0] + V[b][0]) / 2, (V[a][1] + V[b][1]) / 2)
            hits = [int(i) for i in tree.query(mid, predicate="dwithin", distance=tol)]
            letters = sorted({segments[i][2] for i in hits}, key=rank.get)
            sides[key] = letters[0] if letters else "U"
    W = np.zeros((len(V), 3))
    W[:, :2] = np.array(V)
    W[:, 1] = 0.0 - W[:, 1]  # SVG y points down (0.0 - y: no negative zeros)
    notes = []
    if partial:
        notes.append(f"{partial} mountain/valley strokes are partly transparent (Origami Simulator's partial "
                     "fold angle): fabkit reads the assignment, not the angle")
    if unit is None:
        notes.append("the SVG has no physical size (width in mm, cm, in or pt with a viewBox): coordinates are "
                     "user units")
    return RawCreasePattern(W, faces, sides, unit, tuple(notes))
