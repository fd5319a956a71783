"""Rhino `.3dm` in and out through `rhino3dm` (McNeel's OpenNURBS bindings).

Reading: the one mesh object of the file (or the one on layer `PANEL` when there are several);
quads stay quads (a face whose last two corners repeat is a triangle); the model unit system gives
the unit (metres, millimetres, centimetres, inches; a file with no unit system is metres unless
`--units` says otherwise). Tags are the mesh object's user text, one key per array, the same
encoding as the OBJ comments (`fabkit.io.obj`):

    key   "fabkit face_data strip"     value  "int64 [0,0,1,1]"
    key   "fabkit vertex_data pinned"  value  "bool [true,false,...]"

Writing: metres (`ModelUnitSystem = Meters`, double-precision vertices, so a round trip is exact);
layer `PANEL` holds the mesh with its tags as user text; layers `CUT` (outline), `MOUNTAIN`,
`VALLEY` and `SCORE` hold the boundary and the creases (from tags or fold angles, as the cut files)
as polylines, coloured as the cut files.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass

import numpy as np

from fabkit.errors import InputError
from fabkit.io.atomic import atomic_path
from fabkit.mesh import PolyMesh

__all__ = ["read_3dm", "save_3dm", "Raw3dm", "PANEL_LAYER"]

PANEL_LAYER = "PANEL"
_TAG_PREFIX = "fabkit "
_UNITS = {"Meters": "m", "Millimeters": "mm", "Centimeters": "cm", "Inches": "in"}


@dataclass(frozen=True)
class Raw3dm:
    """The mesh of a `.3dm` file in file units (`unit` None when the file has no unit system)."""

    vertices: np.ndarray
    faces: list
    face_data: dict
    vertex_data: dict
    unit: str | None
    notes: tuple
    layer: str


def _decode_tag(key: str, value: str, source: str) -> tuple[str, str, np.ndarray] | None:
    parts = key.split()
    if len(parts) != 3 or parts[0] != _TAG_PREFIX.strip() or parts[1] not in ("face_data", "vertex_data"):
        return None
    try:
        dtype, payload = value.split(" ", 1)
        dt = np.dtype(dtype)
        if dt.kind not in "biufU":
            raise ValueError(f"dtype {dtype} is not bool, int, float or str")
        arr = np.array(json.loads(payload), dtype=dt)
    except (ValueError, TypeError) as exc:
        raise InputError(f"user text '{key}': cannot read it ({exc})", source=source) from None
    return parts[1], parts[2], arr


def read_3dm(path: str | os.PathLike) -> Raw3dm:
    """The panel mesh of a `.3dm` file (see module docstring); `InputError` naming the file."""
    import rhino3dm

    source = str(path)
    if not os.path.isfile(source):
        raise InputError("no such file", source=source)
    model = rhino3dm.File3dm.Read(source)
    if model is None:
        raise InputError("not a readable Rhino .3dm file", source=source)
    layers = {i: model.Layers[i].Name for i in range(len(model.Layers))}
    meshes = [(o, layers.get(o.Attributes.LayerIndex, "")) for o in model.Objects
              if isinstance(o.Geometry, rhino3dm.Mesh)]
    if len(meshes) > 1:
        on_panel = [m for m in meshes if m[1] == PANEL_LAYER]
        if len(on_panel) == 1:
            meshes = on_panel
        else:
            names = ", ".join(f"'{o.Attributes.Name or '?'}' on {layer or '?'}" for o, layer in meshes[:5])
            raise InputError(f"{len(meshes)} meshes ({names}): keep one panel per file or put it on layer "
                             f"{PANEL_LAYER}", source=source)
    if not meshes:
        raise InputError("no mesh object (fabkit reads a panel as a Rhino mesh: Mesh from the surface first)",
                         source=source)
    obj, layer = meshes[0]
    mesh = obj.Geometry
    n = len(mesh.Vertices)
    V = np.array([[p.X, p.Y, p.Z] for p in (mesh.Vertices.Point3dAt(i) for i in range(n))], dtype=np.float64)
    faces = []
    for k in range(mesh.Faces.Count):
        a, b, c, d = mesh.Faces[k]
        faces.append([a, b, c] if c == d else [a, b, c, d])
    face_data, vertex_data = {}, {}
    strings = obj.Attributes.GetUserStrings()
    for key, value in (strings.items() if isinstance(strings, dict) else strings):
        tag = _decode_tag(key, value, source)
        if tag is None:
            continue
        kind, name, arr = tag
        count = len(faces) if kind == "face_data" else n
        if arr.ndim == 0 or len(arr) != count:
            raise InputError(f"user text '{key}' has {arr.size} entries for {count} "
                             f"{'faces' if kind == 'face_data' else 'vertices'}", source=source)
        (face_data if kind == "face_data" else vertex_data)[name] = arr
    us = model.Settings.ModelUnitSystem
    name = getattr(us, "name", str(us).split(".")[-1])
    notes = []
    if name in ("None", "Unset"):
        unit = None
    elif name in _UNITS:
        unit = _UNITS[name]
    else:
        raise InputError(f"model unit system {name}: fabkit reads metres, millimetres, centimetres or inches "
                         "(change the model's units in Rhino)", source=source)
    return Raw3dm(V, faces, face_data, vertex_data, unit, tuple(notes), layer)


def _tag_value(arr: np.ndarray) -> str:
    arr = np.asarray(arr)
    dtype = arr.dtype.str if arr.dtype.kind == "U" else arr.dtype.name
    return f"{dtype} {json.dumps(arr.tolist(), separators=(',', ':'))}"


def save_3dm(mesh: PolyMesh, path: str | os.PathLike, title: str = "") -> None:
    """Write `mesh` as a Rhino 8 `.3dm` file in metres with layers and tags (see module docstring)."""
    import rhino3dm

    from fabkit.cutfiles.creases import chain_edges, crease_assignment
    from fabkit.cutfiles.pattern import LAYERS

    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = rhino3dm.UnitSystem.Meters
    index = {}
    for name, colour in [(PANEL_LAYER, "#808080")] + [(k, LAYERS[k][1]) for k in ("CUT", "MOUNTAIN", "VALLEY", "SCORE")]:
        layer = rhino3dm.Layer()
        layer.Name = name
        r, g, b = (int(colour[i:i + 2], 16) for i in (1, 3, 5))
        layer.Color = (r, g, b, 255)
        index[name] = model.Layers.Add(layer)
    rm = rhino3dm.Mesh()
    for x, y, z in mesh.vertices.tolist():
        rm.Vertices.AddPoint3d(x, y, z)
    for f in mesh.faces_list():
        if len(f) in (3, 4):
            rm.Faces.AddFace(*f)
        else:
            raise InputError(f"a Rhino mesh has triangles and quads only; this panel has a {len(f)}-gon "
                             "(write .obj for polygons)", source=str(path))
    attrs = rhino3dm.ObjectAttributes()
    attrs.LayerIndex = index[PANEL_LAYER]
    attrs.Name = title or "fabkit panel"
    for kind, data in (("face_data", mesh.face_data), ("vertex_data", mesh.vertex_data)):
        for name, arr in data.items():
            attrs.SetUserString(f"{_TAG_PREFIX}{kind} {name}", _tag_value(arr))
    model.Objects.AddMesh(rm, attrs)
    V = mesh.vertices

    def polyline(ids, layer: str) -> None:
        pl = rhino3dm.Polyline(len(ids))
        for i in ids:
            pl.Add(*V[i].tolist())
        a = rhino3dm.ObjectAttributes()
        a.LayerIndex = index[layer]
        model.Objects.AddCurve(rhino3dm.PolylineCurve(pl), a)

    for loop in mesh.boundary_loops:
        polyline(list(loop) + [loop[0]], "CUT")
    creases = crease_assignment(mesh)
    for letter, layer in (("M", "MOUNTAIN"), ("V", "VALLEY"), ("U", "SCORE")):
        e = mesh.edges[creases.edges_with(letter)]
        for chain in (chain_edges(e) if len(e) else []):
            polyline(chain, layer)
    with atomic_path(path) as tmp:
        if not model.Write(str(tmp), 8):
            raise OSError(f"rhino3dm could not write {path}")
