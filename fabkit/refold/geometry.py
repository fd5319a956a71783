"""Vertex positions from fold angles: rotate faces outward from one clamped face.

A BFS spanning tree over the triangle adjacency (scipy.sparse.csgraph) starts at the clamped face,
which keeps its flat position (the panel frame: the clamped face sits at the fixture). A child face's
rigid transform is its parent's composed with the rotation by the hinge angle about the shared edge
(in the flat pattern), so T_child = T_parent * Rot(edge line, sigma * rho). Faces are processed one
tree level at a time (all hinge rotations in one vectorised scipy Rotation call).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order
from scipy.spatial.transform import Rotation

from fabkit.mesh import MeshTopology

__all__ = ["FaceTree", "build_face_tree", "face_transforms", "vertex_positions"]


@dataclass(frozen=True)
class FaceTree:
    """Spanning tree of the faces rooted at the clamped face.

    `root`; `levels` tuple of face-id arrays by depth (levels[0] = [root]); per face: `parent`,
    `parent_edge`, `sign` (+1 when the face is the hinge's left face), `depth`;
    `vertex_face` (n,) the shallowest face holding each vertex (positions are read from it).
    """

    root: int
    levels: tuple
    parent: np.ndarray
    parent_edge: np.ndarray
    sign: np.ndarray
    depth: np.ndarray
    vertex_face: np.ndarray
    axis: np.ndarray    # (E, 3) unit flat direction lo->hi of every edge
    point: np.ndarray   # (E, 3) flat position of every edge's lo vertex


def build_face_tree(topology: MeshTopology, flat_vertices: np.ndarray, root: int) -> FaceTree:
    """BFS tree over faces sharing an interior edge, from `root`; raises if the panel falls apart."""
    t = topology
    F = t.n_faces
    inner = t.interior_edges
    a, b = t.edge_faces[inner, 0], t.edge_faces[inner, 1]
    # edge id + 1 as the weight so the shared edge can be looked up from the (face, parent) pair
    adj = sp.coo_matrix((np.concatenate([inner, inner]) + 1, (np.concatenate([a, b]), np.concatenate([b, a]))),
                        shape=(F, F)).tocsr()
    order, pred = breadth_first_order(adj, root, directed=False, return_predecessors=True)
    if len(order) != F:
        missing = np.setdiff1d(np.arange(F), order)
        raise ValueError(f"faces {missing[:5].tolist()} are not connected to face {root} across hinges")
    parent = pred.astype(np.int64)
    parent[root] = -1
    depth = np.zeros(F, np.int64)
    for f in order[1:]:  # BFS order: a parent always comes before its children
        depth[f] = depth[parent[f]] + 1
    child = order[1:]
    pedge = np.full(F, -1, np.int64)
    pedge[child] = np.asarray(adj[child, parent[child]]).ravel().astype(np.int64) - 1
    sign = np.zeros(F)
    sign[child] = np.where(t.edge_faces[pedge[child], 0] == child, 1.0, -1.0)
    levels = tuple(np.flatnonzero(depth == k) for k in range(int(depth.max()) + 1))
    # shallowest face at each vertex
    cf = t.corner_face
    order_c = np.lexsort((depth[cf], t.face_indices))
    vi = t.face_indices[order_c]
    first = np.ones(len(vi), bool)
    first[1:] = vi[1:] != vi[:-1]
    vertex_face = np.full(t.n_vertices, -1, np.int64)
    vertex_face[vi[first]] = cf[order_c][first]
    V = np.asarray(flat_vertices, np.float64)
    E = t.edges
    d = V[E[:, 1]] - V[E[:, 0]]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return FaceTree(root=int(root), levels=levels, parent=parent, parent_edge=pedge, sign=sign, depth=depth,
                    vertex_face=vertex_face, axis=d, point=V[E[:, 0]].copy())


def face_transforms(tree: FaceTree, rho: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rigid transforms (R (F,3,3), t (F,3)) mapping flat coordinates of each face to the fold state."""
    F = len(tree.parent)
    R = np.empty((F, 3, 3))
    T = np.empty((F, 3))
    R[tree.root] = np.eye(3)
    T[tree.root] = 0.0
    rho = np.asarray(rho)
    child = np.flatnonzero(tree.parent >= 0)
    e_all = tree.parent_edge[child]
    Q_all = np.empty((F, 3, 3))
    Q_all[child] = Rotation.from_rotvec(tree.axis[e_all] * (tree.sign[child] * rho[e_all])[:, None]).as_matrix()
    # translation part of each hinge rotation about its edge line: x0 - Q x0
    x0 = np.zeros((F, 3))
    x0[child] = tree.point[e_all]
    s_all = x0 - np.einsum("fij,fj->fi", Q_all, x0)
    for faces in tree.levels[1:]:
        p = tree.parent[faces]
        Rp = R[p]
        R[faces] = Rp @ Q_all[faces]
        # x -> Rp (Q (x - x0) + x0) + Tp
        T[faces] = np.einsum("fij,fj->fi", Rp, s_all[faces]) + T[p]
    return R, T


def vertex_positions(tree: FaceTree, flat_vertices: np.ndarray, rho: np.ndarray,
                     transforms: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Fold-state vertex positions (n, 3); unused vertices keep their flat position."""
    R, T = face_transforms(tree, rho) if transforms is None else transforms
    V = np.array(flat_vertices, dtype=np.float64, copy=True)
    used = tree.vertex_face >= 0
    f = tree.vertex_face[used]
    V[used] = np.einsum("fij,fj->fi", R[f], V[used]) + T[f]
    return V


def corner_mismatch(topology: MeshTopology, flat_vertices: np.ndarray, positions: np.ndarray,
                    transforms: tuple[np.ndarray, np.ndarray]) -> float:
    """Largest distance between a vertex and where each of its faces' transforms puts it.

    Zero up to round-off when every loop closes; a direct check that the faces fit together.
    """
    R, T = transforms
    cf = topology.corner_face
    vi = topology.face_indices
    X = np.einsum("cij,cj->ci", R[cf], np.asarray(flat_vertices)[vi]) + T[cf]
    return float(np.linalg.norm(X - positions[vi], axis=1).max(initial=0.0))
