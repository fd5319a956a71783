"""Panels as users bring them, written by the tests: plain OBJ (no fabkit lines) in any unit, shuffled,
triangulated, unwelded, with faces flipped; FOLD in other tools' conventions; Rhino .3dm (rhino3dm)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from fabkit.generate.reflect import reflect_panel


def plain_obj(path: Path, V, faces) -> Path:
    """An OBJ as another program writes it: `v` and `f` lines, nothing else."""
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in np.asarray(V)]
    lines += ["f " + " ".join(str(int(i) + 1) for i in f) for f in faces]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def reflect(columns: int = 8, rows: int = 3):
    """A fabkit reflect panel (one crease) as (vertices in metres, quad faces)."""
    m = reflect_panel(columns=columns, rows=rows)
    return np.array(m.vertices), m.faces_list()


def shuffled(V, faces, seed: int = 3):
    """Vertices and faces in a random order (each face's corners rotated too) -> (V, faces, perm) with
    V_new[i] = V[perm[i]]."""
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(V))
    new_id = np.argsort(perm)
    out = []
    for f in faces:
        g = [int(new_id[i]) for i in f]
        k = int(rng.integers(len(g)))
        out.append(g[k:] + g[:k])
    order = rng.permutation(len(out))
    return np.asarray(V)[perm], [out[k] for k in order], perm


def triangulated(faces, seed: int = 5):
    """Every quad split by one of its diagonals, chosen at random (as exporters do)."""
    rng = np.random.default_rng(seed)
    out = []
    for f in faces:
        if len(f) == 4 and rng.random() < 0.5:
            out += [[f[0], f[1], f[2]], [f[0], f[2], f[3]]]
        elif len(f) == 4:
            out += [[f[1], f[2], f[3]], [f[1], f[3], f[0]]]
        else:
            out.append(list(f))
    return out


def unwelded(V, faces):
    """One vertex copy per face corner (STL-like export)."""
    W, out = [], []
    for f in faces:
        out.append(list(range(len(W), len(W) + len(f))))
        W.extend(np.asarray(V)[f])
    return np.array(W), out


def fold_other_tool(path: Path, V, faces, assignment: dict, *, unit: str | None = None, lower: bool = False,
                    angles: bool = False, frames: list | None = None) -> Path:
    """A FOLD file the way other tools write it: no frame_unit unless given, no file_spec, assignments
    possibly lower case, no edges_foldAngle unless asked, edges in their own order."""
    edges = sorted({(min(a, b), max(a, b)) for f in faces for a, b in zip(f, list(f[1:]) + [f[0]])},
                   key=lambda e: (-e[1], e[0]))  # an order of its own
    count: dict = {}
    for f in faces:
        for a, b in zip(f, list(f[1:]) + [f[0]]):
            count[(min(a, b), max(a, b))] = count.get((min(a, b), max(a, b)), 0) + 1
    letters = [assignment.get(e, "B" if count[e] == 1 else "F") for e in edges]
    d = {"file_creator": "another tool", "vertices_coords": np.asarray(V).tolist(),
         "edges_vertices": [list(e) for e in edges],
         "edges_assignment": [a.lower() if lower else a for a in letters],
         "faces_vertices": [list(map(int, f)) for f in faces]}
    if unit is not None:
        d["frame_unit"] = unit
    if angles:
        d["edges_foldAngle"] = [0 if a in "FB" else None for a in letters]
    if frames:
        d["file_frames"] = [{"frame_classes": ["foldedForm"], "frame_parent": 0, "frame_inherit": True,
                             "vertices_coords": np.asarray(F).tolist()} for F in frames]
    Path(path).write_text(json.dumps(d))
    return Path(path)


def rhino_3dm(path: Path, V, faces, unit: str = "Millimeters", layer: str = "Default") -> Path:
    """A .3dm file with one mesh written by rhino3dm (as Rhino saves a meshed panel)."""
    import rhino3dm

    model = rhino3dm.File3dm()
    model.Settings.ModelUnitSystem = getattr(rhino3dm.UnitSystem, unit)
    lay = rhino3dm.Layer()
    lay.Name = layer
    idx = model.Layers.Add(lay)
    m = rhino3dm.Mesh()
    for x, y, z in np.asarray(V, dtype=float).tolist():
        m.Vertices.AddPoint3d(x, y, z)
    for f in faces:
        m.Faces.AddFace(*[int(i) for i in f])
    attrs = rhino3dm.ObjectAttributes()
    attrs.LayerIndex = idx
    model.Objects.AddMesh(m, attrs)
    assert model.Write(str(path), 8)
    return Path(path)


def edge_assignment_of(mesh_edges, letters) -> dict:
    return {(int(min(a, b)), int(max(a, b))): c for (a, b), c in zip(np.asarray(mesh_edges).tolist(), letters)}
