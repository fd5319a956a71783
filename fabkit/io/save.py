"""Write a panel by file suffix: `.obj` (exact, tags and unit kept), `.fold`, `.3dm`, or a view format.

Every format carries its unit: OBJ a `# fabkit unit m` line, FOLD `frame_unit`, `.3dm` the model
unit system (millimetres), PLY/STL/GLB are metres by glTF convention (viewing only).
"""
from __future__ import annotations

import os
from pathlib import Path

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh

__all__ = ["save_panel", "PANEL_OUTPUT_SUFFIXES", "panel_fold_model"]

PANEL_OUTPUT_SUFFIXES = (".obj", ".fold", ".3dm", ".ply", ".stl", ".glb")


def panel_fold_model(mesh: PolyMesh, title: str = ""):
    """A one-frame FOLD model of a panel: creases from its tags or fold angles (`crease_assignment`);
    a flat panel is a crease pattern, a folded one a folded form."""
    import numpy as np

    from fabkit.cutfiles.creases import crease_assignment
    from fabkit.fold import FoldModel

    creases = crease_assignment(mesh)
    flat = bool(np.all(mesh.vertices[:, 2] == 0.0))
    return FoldModel.from_mesh(mesh, creases.edges_assignment, creases.edges_fold_angle, title=title,
                               classes=("creasePattern",) if flat else ("foldedForm",))


def save_panel(mesh: PolyMesh, path: str | os.PathLike, header: str | None = None) -> None:
    """Write `mesh` (metres) in the format its suffix names (see `PANEL_OUTPUT_SUFFIXES`), atomically."""
    suffix = Path(path).suffix.lower()
    if suffix == ".obj":
        from fabkit.io.obj import save_obj

        save_obj(mesh, path, header)
    elif suffix == ".fold":
        from fabkit.io.fold import save_fold

        save_fold(panel_fold_model(mesh, title=header or ""), path)
    elif suffix == ".3dm":
        from fabkit.io.rhino import save_3dm

        save_3dm(mesh, path, title=header or "")
    elif suffix in (".ply", ".stl", ".glb"):
        from fabkit.io.export import export_mesh

        export_mesh(mesh, path)
    else:
        raise InputError(f"cannot write '{suffix or 'no suffix'}': use one of {', '.join(PANEL_OUTPUT_SUFFIXES)}",
                         source=str(path))
