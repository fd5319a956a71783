"""The rigid-panel hold model (`fabkit.holds.HoldModel`) of a FOLD file: refold's hinge kinds and
crease rows when the file carries them, else taken from its geometry (triangles of its faces,
dihedral angles, diagonals of planar quads locked). Kept apart from the hold analysis itself
(`fabkit.holds`), which works on the model whatever file it came from."""
from __future__ import annotations

import numpy as np

from fabkit.holds import HoldModel
from fabkit.mesh import MeshTopology

__all__ = ["hold_model_from_fold", "fold_triangles"]


def hold_model_from_fold(model, source: str | None = None) -> tuple[HoldModel, np.ndarray]:
    """`(HoldModel, angles (S, E))` from a triangulated `fabkit.fold.FoldModel` as `fabkit refold`
    writes it (edges_fabkit:kind/crease, faces_fabkit:polygon, file_data fabkit:fixed_triangle);
    `angles` are the frames' fold angles in the model's edge order (radians, valley +)."""
    from types import SimpleNamespace

    from fabkit.errors import InputError
    from fabkit.refold.triangulate import EDGE_KINDS

    tris, tri_face = fold_triangles(model)
    V = np.asarray(model.vertices_coords, np.float64)
    topo = MeshTopology(tris.ravel(), np.arange(0, 3 * len(tris) + 1, 3), len(V))
    if len(tris) != len(model.faces_vertices):          # polygons split here: kinds from the geometry
        return _hold_model_from_geometry(model, topo, tris, V, source, tri_face)
    ids = topo.edge_ids(np.sort(np.asarray(model.edges_vertices), axis=1))
    if np.any(ids < 0) or len(np.unique(ids)) != topo.n_edges:
        raise InputError("edges_vertices do not match the faces' edges", source=source)

    def per_edge(values, fill):
        out = np.full(topo.n_edges, fill, dtype=np.asarray(values).dtype)
        out[ids] = values
        return out

    if "kind" not in model.edges_data:
        return _hold_model_from_geometry(model, topo, tris, V, source)
    kind = np.array(EDGE_KINDS)[per_edge(np.asarray(model.edges_data["kind"], np.int64), 0)]
    crease = per_edge(np.asarray(model.edges_data.get("crease", np.full(model.n_edges, -1)), np.int64), -1)
    frames = model.frames or ()
    angles = np.stack([per_edge(np.asarray(f.edges_fold_angle if f.edges_fold_angle is not None
                                           else model.edges_fold_angle, np.float64), 0.0) for f in frames])         if frames else per_edge(np.asarray(model.edges_fold_angle, np.float64), 0.0)[None]
    used = np.unique(tris)
    seq = SimpleNamespace(
        tris=tris, flat_vertices=V, edges=topo.edges, edge_kind=kind, edge_crease=crease,
        target_angles=per_edge(np.asarray(model.edges_fold_angle, np.float64), 0.0),
        tri_face=np.asarray(model.faces_data.get("polygon", np.arange(len(tris))), np.int64),
        fixed_triangle=int(model.file_data.get("fabkit:fixed_triangle", 0)),
        panel_size=float(np.linalg.norm(np.ptp(V[used], axis=0))))
    return HoldModel.from_sequence(seq), angles


def fold_triangles(model) -> tuple[np.ndarray, np.ndarray]:
    """`(tris (T, 3), tri_face (T,))` of a FOLD model: its triangles with their polygon ids
    (`faces_fabkit:polygon`, else the face index); polygons split into fans from their first vertex
    (planar convex faces, as a panel's quads are)."""
    poly = np.asarray(model.faces_data.get("polygon", np.arange(len(model.faces_vertices))), np.int64)
    tris, owner = [], []
    for f, face in enumerate(model.faces_vertices):
        face = [int(v) for v in face]
        for k in range(1, len(face) - 1):
            tris.append((face[0], face[k], face[k + 1]))
            owner.append(int(poly[f]))
    return np.array(tris, np.int64).reshape(-1, 3), np.array(owner, np.int64)


def _hold_model_from_geometry(model, topo, tris, V, source, tri_face=None) -> tuple[HoldModel, np.ndarray]:
    """The hold model of a triangulated FOLD file without refold's hinge kinds, from its geometry:
    the fold angle of every edge in every frame (signed dihedral, valley +), edges inside one
    polygon (`faces_fabkit:polygon`) are diagonals, edges between faces of different strips
    (`faces_fabkit:strip`) that fold in some frame are creases of the row min(strip) (with no strip
    tags: edges assigned M or V), every other interior edge is a ruling (a flat one is locked)."""
    from types import SimpleNamespace

    from fabkit.measures import dihedral_angles
    from fabkit.mesh import PolyMesh

    frames = [np.asarray(f.vertices_coords, np.float64) for f in model.frames] or [V]
    angles = []
    for X in frames:
        mesh = PolyMesh(X, tris)
        a = np.zeros(topo.n_edges)
        a[topo.edge_ids(mesh.edges)] = dihedral_angles(mesh)
        angles.append(a)
    angles = np.stack(angles)
    folds = np.abs(angles).max(axis=0) > 1e-6
    ef = topo.edge_faces
    inner = np.zeros(topo.n_edges, bool)
    inner[topo.interior_edges] = True
    a, b = np.maximum(ef[:, 0], 0), np.maximum(ef[:, 1], 0)
    poly = np.asarray(model.faces_data.get("polygon", np.arange(len(tris))), np.int64) if tri_face is None \
        else np.asarray(tri_face, np.int64)
    kind = np.where(inner, "ruling", "boundary").astype("<U8")
    kind[inner & (poly[a] == poly[b])] = "diagonal"
    crease = np.full(topo.n_edges, -1, np.int64)
    between = inner & (poly[a] != poly[b])
    if "strip" in model.faces_data:
        strip = np.asarray(model.faces_data["strip"], np.int64)
        if tri_face is not None:    # per FOLD face -> per triangle of its fan
            strip = np.repeat(strip, [len(f) - 2 for f in model.faces_vertices])
        is_crease = between & (strip[a] != strip[b]) & folds
        crease[is_crease] = np.minimum(strip[a], strip[b])[is_crease]
    else:
        mv = np.isin(np.asarray(model.edges_assignment), ["M", "V"])
        ids = topo.edge_ids(np.sort(np.asarray(model.edges_vertices), axis=1))
        is_crease = np.zeros(topo.n_edges, bool)
        is_crease[ids[ids >= 0]] = mv[ids >= 0]
        is_crease &= between
    kind[is_crease] = "crease"
    used = np.unique(tris)
    seq = SimpleNamespace(
        tris=tris, flat_vertices=V, edges=topo.edges, edge_kind=kind, edge_crease=crease, target_angles=angles[-1],
        tri_face=poly, fixed_triangle=int(model.file_data.get("fabkit:fixed_triangle", 0)),
        panel_size=float(np.linalg.norm(np.ptp(V[used], axis=0))))
    return HoldModel.from_sequence(seq), angles
