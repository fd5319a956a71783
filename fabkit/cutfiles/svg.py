"""SVG cut file in millimetres: width/height in mm, a viewBox in mm, one group per layer.

Written with the standard library (the format is a few lines of XML; no SVG package is a
dependency). The drawing's y axis points up, SVG's down: y is flipped about the sheet's extent.
Lines are 0.1 mm hairlines; groups carry Inkscape layer attributes so they open as layers.
"""
from __future__ import annotations

import os
from xml.sax.saxutils import escape

import numpy as np

from fabkit.cutfiles.pattern import LAYERS, CutPattern
from fabkit.io.atomic import atomic_write

__all__ = ["svg_text", "write_svg"]

MARGIN_MM = 5.0
STROKE_MM = 0.1


def _fmt(v: float) -> str:
    s = f"{v:.6f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def svg_text(pattern: CutPattern) -> str:
    """The SVG document of `pattern` as a string."""
    lo, hi = pattern.extent
    x0, y_top = lo[0] - MARGIN_MM, hi[1] + MARGIN_MM
    w = hi[0] - lo[0] + 2 * MARGIN_MM
    h = hi[1] - lo[1] + 2 * MARGIN_MM

    def pts(a: np.ndarray) -> str:
        return " ".join(f"{_fmt(x - x0)},{_fmt(y_top - y)}" for x, y in a.tolist())

    out = ['<?xml version="1.0" encoding="UTF-8"?>\n',
           f'<svg xmlns="http://www.w3.org/2000/svg" '
           f'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" '
           f'width="{_fmt(w)}mm" height="{_fmt(h)}mm" viewBox="0 0 {_fmt(w)} {_fmt(h)}">\n',
           f'<title>{escape("fabkit cut pattern " + pattern.panel_id)} (units: mm)</title>\n']
    groups = {"CUT": [f'<polygon points="{pts(loop)}"/>' for loop in pattern.outlines]}
    for layer, chains in pattern.polylines.items():
        groups[layer] = [f'<polyline points="{pts(c)}"/>' for c in chains]
    for name, (_, colour, description) in LAYERS.items():
        items = groups.get(name, [])
        if name == "LABEL":
            items = [f'<text x="{_fmt(lab.x - x0)}" y="{_fmt(y_top - lab.y)}" font-size="{_fmt(lab.height)}" '
                     f'text-anchor="middle" dominant-baseline="middle">{escape(lab.text)}</text>'
                     for lab in pattern.labels]
            style = f'fill="{colour}" stroke="none" font-family="sans-serif"'
        else:
            style = f'fill="none" stroke="{colour}" stroke-width="{STROKE_MM}"'
        if not items:
            continue
        out.append(f'<g id="{name}" inkscape:groupmode="layer" inkscape:label="{name}" {style}>\n'
                   f'<desc>{escape(description)}</desc>\n')
        out.extend(f"{item}\n" for item in items)
        out.append("</g>\n")
    out.append("</svg>\n")
    return "".join(out)


def write_svg(pattern: CutPattern, path: str | os.PathLike) -> None:
    """Write `pattern` as an SVG file (temporary file, renamed when complete)."""
    text = svg_text(pattern)
    with atomic_write(path) as fh:
        fh.write(text)
