"""PLY / STL / GLB export through trimesh, for viewing only (triangulated).

The mesh is fan-triangulated by `PolyMesh.triangulate` and handed to trimesh with
`process=False`, so trimesh neither merges nor reorders vertices: vertex ids in the exported file
are the model's. Use OBJ (`fabkit.io.obj`) for anything that must be read back.
"""
from __future__ import annotations

import os
from pathlib import Path

from fabkit.errors import InputError
from fabkit.io.atomic import atomic_path
from fabkit.mesh import PolyMesh

__all__ = ["export_mesh", "EXPORT_FORMATS"]

#: file suffix -> trimesh file_type
EXPORT_FORMATS = {".ply": "ply", ".stl": "stl", ".glb": "glb"}


def export_mesh(mesh: PolyMesh, path: str | os.PathLike) -> None:
    """Write a triangulated copy of `mesh` as PLY, STL or GLB (chosen by suffix), atomically."""
    suffix = Path(path).suffix.lower()
    if suffix not in EXPORT_FORMATS:
        raise InputError(f"cannot export '{suffix or 'no suffix'}': use one of "
                         f"{', '.join(sorted(EXPORT_FORMATS))} (or .obj with save_obj)", source=str(path))
    tm = mesh.to_trimesh()
    with atomic_path(path) as tmp:
        tm.export(str(tmp), file_type=EXPORT_FORMATS[suffix])
