"""Readers and writers, with typed entry points (`load_obj`, `load_fold`, ...).

Commands read panels through `load_panel` (any of .obj, .fold, .3dm, .svg; units, welding,
winding and split quads handled and reported in a `LoadInfo`, see `fabkit.io.load`) and write them
with `save_panel` (by suffix, see `fabkit.io.save`).

Each entry point returns one type: `load_mesh` always a `PolyMesh` (from OBJ, or the key frame of a
FOLD file), `load_fold` always a `FoldModel`. Writers are atomic (temporary file + rename).
"""
from __future__ import annotations

import os
from pathlib import Path

from typing import TYPE_CHECKING

from fabkit.errors import InputError

if TYPE_CHECKING:  # the readers import numpy on use: `fabkit SUB --help` stays light
    from fabkit.mesh import PolyMesh

__all__ = ["load_mesh", "save_mesh", "load_obj", "save_obj", "load_fold", "save_fold", "export_mesh",
           "MESH_SUFFIXES", "load_panel", "save_panel"]

#: suffixes `load_mesh` reads
MESH_SUFFIXES = (".obj", ".fold")


def load_panel(path: str | os.PathLike, units: str | None = None, state: str = "folded"):
    """Any panel file -> `(PolyMesh in metres, LoadInfo)` (see `fabkit.io.load`)."""
    from fabkit.io.load import load_panel as _load

    return _load(path, units, state=state)


def save_panel(mesh: PolyMesh, path: str | os.PathLike, header: str | None = None) -> None:
    """`PolyMesh` -> .obj / .fold / .3dm / .ply / .stl / .glb by suffix (see `fabkit.io.save`)."""
    from fabkit.io.save import save_panel as _save

    _save(mesh, path, header)


def load_obj(path: str | os.PathLike) -> PolyMesh:
    """OBJ -> `PolyMesh` (see `fabkit.io.obj`)."""
    from fabkit.io.obj import load_obj as _load

    return _load(path)


def save_obj(mesh: PolyMesh, path: str | os.PathLike, header: str | None = None) -> None:
    """`PolyMesh` -> OBJ (see `fabkit.io.obj`)."""
    from fabkit.io.obj import save_obj as _save

    _save(mesh, path, header)


def load_fold(path: str | os.PathLike):
    """FOLD -> `FoldModel` (see `fabkit.io.fold`)."""
    from fabkit.io.fold import load_fold as _load

    return _load(path)


def save_fold(model, path: str | os.PathLike) -> None:
    """`FoldModel` -> FOLD 1.2 (see `fabkit.io.fold`)."""
    from fabkit.io.fold import save_fold as _save

    _save(model, path)


def export_mesh(mesh: PolyMesh, path: str | os.PathLike) -> None:
    """`PolyMesh` -> PLY/STL/GLB for viewing (see `fabkit.io.export`)."""
    from fabkit.io.export import export_mesh as _export

    _export(mesh, path)


def load_mesh(path: str | os.PathLike) -> PolyMesh:
    """A `PolyMesh` from `.obj`, or the key frame (crease pattern) of a `.fold` file."""
    suffix = Path(path).suffix.lower()
    if suffix == ".obj":
        return load_obj(path)
    if suffix == ".fold":
        return load_fold(path).mesh()
    raise InputError(f"cannot read '{suffix or 'no suffix'}' as a mesh: use .obj or .fold", source=str(path))


def save_mesh(mesh: PolyMesh, path: str | os.PathLike) -> None:
    """Write `.obj` (exact, tags kept) or `.ply`/`.stl`/`.glb` (viewing only), by suffix."""
    if Path(path).suffix.lower() == ".obj":
        save_obj(mesh, path)
    else:
        export_mesh(mesh, path)
