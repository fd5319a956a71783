"""A pleated vault: alternating mountain and valley curved creases along planar arcs, exactly developable.

The installation the paper describes was pleated aluminium ("the corrugation makes the whole thing
stand"). The vault is built by the reflection method (`fabkit.generate.reflect`): a circular
cylinder strip of `radius`, spanning `arc` around its axis and `length` along it, is mirrored
across one plane per band; plane b meets the middle generator at ``(b + 1/2) * length / rows`` and
folds the sheet by ``(-1)**b * fold`` (valley +), so the creases alternate valley, mountain, ... Every
crease is a planar curve (it lies in its mirror plane), every iso-line across the vault is a planar
arc (a reflected circle arc), and the discrete mesh is developable to round-off, so the relaxation
has nothing to undo.

Rows: each band has `rows_per_band` quads along the generators, the crease in its middle row;
the band boundaries (halfway between creases) are grid rows where the surface does not kink, so
`fabkit panels` finds the creases (`fabkit.panels.layout.crease_rows`) and puts one inside every
band's panels. Use `columns` = panels per band x columns per panel so the layout's stations fall on
the generators.

Measured (docs/panels.md): offsetting a free-form canopy's arcs into pleats instead is not near a
creased developable surface — the relaxation flattened most of its creases.
"""
from __future__ import annotations

import numpy as np

from fabkit.errors import InputError
from fabkit.generate.reflect import MirrorPlane, reflect_panel
from fabkit.mesh import PolyMesh

__all__ = ["pleated_vault"]


def pleated_vault(rows: int = 14, fold: float = np.radians(40.0), radius: float = 1.5,
                  arc: float = np.radians(90.0), length: float = 6.0, columns: int = 42,
                  rows_per_band: int = 8) -> PolyMesh:
    """The pleated vault as a quad grid with strip/column/middle tags (see the module docstring)."""
    if rows < 2 or rows % 2:
        raise InputError(f"rows must be an even number >= 2 (bands come in aligned pairs), got {rows}")
    if not 0 < fold < np.radians(150.0):
        raise InputError(f"fold must be between 0 and 150 degrees, got {np.degrees(fold):g}")
    if rows_per_band < 2 or rows_per_band % 2:
        raise InputError(f"rows per band must be even and >= 2 (the crease in the middle), got {rows_per_band}")
    s = length / rows
    # the builder's planes all lean the same way (reflect.py builds plane j with (-1)^j times the
    # finished fold), so every crease is the same curve in the development, shifted by s: the sheet
    # is made longer by that curve's rise so the last crease stays inside it
    rise = radius * (1.0 - np.cos(arc / 2)) / np.tan(fold / 2)
    planes = [MirrorPlane(offset=(b + 0.5) * s, fold=(1.0 if b % 2 == 0 else -1.0) * fold) for b in range(rows)]
    half = rows_per_band // 2
    strip_rows = [half] + [rows_per_band] * (rows - 1) + [half]
    mesh = reflect_panel(radius=radius, arc=arc, width=length + rise, planes=planes, columns=columns,
                         rows=strip_rows)
    if mesh.face_normals[:, 2].mean() > 0:  # the vault's outer side up, like the canopy presets
        mesh = PolyMesh(mesh.vertices * np.array([1.0, 1.0, -1.0]) + [0.0, 0.0, 2 * radius], topology=mesh.topology,
                        face_data=mesh.face_data, vertex_data=mesh.vertex_data)
    return mesh
