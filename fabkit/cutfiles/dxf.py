"""DXF cut file (ezdxf) in millimetres: CUT, MOUNTAIN, VALLEY, SCORE and LABEL layers.

The header declares the units ($INSUNITS = 4, millimetres; $MEASUREMENT = 1, metric) and the
drawing's extents ($EXTMIN/$EXTMAX, $LIMMIN/$LIMMAX: the outline's bounding box). Outlines are
closed LWPOLYLINEs, score lines open (or closed) LWPOLYLINEs, labels TEXT. Written atomically.
"""
from __future__ import annotations

import os

import ezdxf
from ezdxf import units

from fabkit.cutfiles.pattern import LAYERS, CutPattern
from fabkit.io.atomic import atomic_path

__all__ = ["dxf_document", "write_dxf"]


def dxf_document(pattern: CutPattern) -> "ezdxf.document.Drawing":
    """An ezdxf drawing of `pattern` (R2010, millimetres)."""
    doc = ezdxf.new("R2010", units=units.MM)
    doc.header["$INSUNITS"] = units.MM
    doc.header["$MEASUREMENT"] = 1
    (x0, y0), (x1, y1) = pattern.extent.tolist()
    doc.header["$EXTMIN"] = (x0, y0, 0.0)  # the drawing's extents, so viewers "zoom extents" right away
    doc.header["$EXTMAX"] = (x1, y1, 0.0)
    doc.header["$LIMMIN"] = (x0, y0)
    doc.header["$LIMMAX"] = (x1, y1)
    for name, (aci, _, description) in LAYERS.items():
        layer = doc.layers.add(name, color=aci)
        layer.description = description
    msp = doc.modelspace()
    msp.dxf.extmin, msp.dxf.extmax = (x0, y0, 0.0), (x1, y1, 0.0)  # ezdxf writes the header's from these
    msp.dxf.limmin, msp.dxf.limmax = (x0, y0), (x1, y1)
    for loop in pattern.outlines:
        msp.add_lwpolyline(loop.tolist(), format="xy", close=True, dxfattribs={"layer": "CUT"})
    for layer, chains in pattern.polylines.items():
        for chain in chains:
            closed = len(chain) > 2 and bool((chain[0] == chain[-1]).all())
            pts = chain[:-1] if closed else chain
            msp.add_lwpolyline(pts.tolist(), format="xy", close=closed, dxfattribs={"layer": layer})
    for lab in pattern.labels:
        msp.add_text(lab.text, height=lab.height, dxfattribs={"layer": lab.layer}).set_placement(
            (lab.x, lab.y), align=ezdxf.enums.TextEntityAlignment.MIDDLE_CENTER)
    return doc


def write_dxf(pattern: CutPattern, path: str | os.PathLike) -> None:
    """Write `pattern` as a DXF file (temporary file, renamed when complete)."""
    doc = dxf_document(pattern)
    with atomic_path(path) as tmp:
        doc.saveas(tmp)
