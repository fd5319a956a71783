"""A FoldSequence as files: FOLD animation, GLB film strip, OBJ per state, fold-angle plot.

The FOLD key frame is the crease pattern (flat, triangulated: quads split by `J` diagonals,
creases and bent rulings `M`/`V`, flat hinges `F`, outline `B`, `edges_foldAngle` = the target
angles); every state is a child frame overriding `vertices_coords` and `edges_foldAngle`. Maps back
to the quads: `faces_fabkit:polygon` (the quad of each triangle), `faces_fabkit:strip/column/middle`,
`edges_fabkit:kind` (0 boundary, 1 crease, 2 ruling, 3 diagonal), `edges_fabkit:driven`,
`edges_fabkit:polygon_edge` (-1 for diagonals), `edges_fabkit:crease` (crease row, -1 off creases). Per frame: `frame_fabkit:state`, `frame_fabkit:step`,
`frame_fabkit:loop_residual_rad`, `frame_fabkit:edge_length_error`, `frame_fabkit:intersections`.
File: `file_fabkit:fixed_face`, `file_fabkit:fixed_triangle`, `file_fabkit:target_distance_m` (when the
last scheduled state was reached), else `file_fabkit:failed_state` and `file_fabkit:failure`. Only
converged states are written.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from fabkit.errors import InputError
from fabkit.fold import FoldFrame, FoldModel
from fabkit.mesh import PolyMesh
from fabkit.refold.sequence import FoldSequence
from fabkit.refold.triangulate import EDGE_KINDS

__all__ = ["to_fold_model", "save_glb_strip", "save_obj_states", "plot_fold_angles"]


def _tri_mesh(seq: FoldSequence, vertices: np.ndarray | None = None) -> PolyMesh:
    V = seq.flat_vertices if vertices is None else vertices
    return PolyMesh(V, seq.tris, face_data=seq.face_data, validate=False)


def to_fold_model(seq: FoldSequence, *, title: str = "", file_data: dict | None = None) -> FoldModel:
    """The FOLD model of a sequence (see module docstring); validated by `FoldModel.from_mesh`."""
    mesh = _tri_mesh(seq)
    if not np.array_equal(mesh.edges, seq.edges):
        raise ValueError("sequence edges are not the triangle mesh's sorted edges")
    kind = np.array([EDGE_KINDS.index(str(k)) for k in seq.edge_kind], np.int64)
    driven = np.zeros(len(seq.edges), np.int64)
    driven[seq.driven] = 1
    edges_data = {"kind": kind, "driven": driven, "polygon_edge": np.asarray(seq.polygon_edge, np.int64),
                  "crease": np.asarray(seq.edge_crease, np.int64)}
    frames = []
    for s in range(seq.n_states):
        frames.append(FoldFrame(seq.positions[s], seq.angles[s], data={
            "fabkit:state": int(s), "fabkit:step": int(seq.step[s]),
            "fabkit:loop_residual_rad": float(seq.residual[s]),
            "fabkit:edge_length_error": float(seq.edge_length_error[s]),
            "fabkit:intersections": int(seq.intersections[s]),
        }))
    fd = {"fabkit:fixed_face": int(seq.fixed_face), "fabkit:fixed_triangle": int(seq.fixed_triangle)}
    if np.isfinite(seq.target_distance):  # NaN when a state did not converge: the file says so instead
        fd["fabkit:target_distance_m"] = float(seq.target_distance)
    if not seq.complete:
        fd["fabkit:failed_state"] = int(seq.failed_state)
        fd["fabkit:failure"] = seq.failure
    fd.update(file_data or {})
    return FoldModel.from_mesh(mesh, seq.edges_assignment, seq.target_angles, frames=frames, edges_data=edges_data,
                               file_data=fd, title=title, attributes=("2D",))


def save_glb_strip(seq: FoldSequence, path: str | os.PathLike, spacing: float = 1.25) -> None:
    """All states in one GLB scene, side by side along +x (`spacing` x panel size apart), for viewing."""
    import trimesh

    from fabkit.io.atomic import atomic_path

    if Path(path).suffix.lower() != ".glb":
        raise InputError("the film strip is written as .glb", source=str(path))
    scene = trimesh.Scene()
    step = spacing * seq.panel_size
    for s in range(seq.n_states):
        V = seq.positions[s] + np.array([s * step, 0.0, 0.0])
        scene.add_geometry(trimesh.Trimesh(vertices=V, faces=seq.tris, process=False), node_name=f"state_{s:03d}",
                           geom_name=f"state_{s:03d}")
    with atomic_path(path) as tmp:
        scene.export(str(tmp), file_type="glb")


def save_obj_states(seq: FoldSequence, quad_mesh: PolyMesh, directory: str | os.PathLike) -> list[Path]:
    """One OBJ per state with the original polygons (quads) and tags: DIR/state_000.obj, ..."""
    from fabkit.io.obj import save_obj

    d = Path(directory)
    if not d.is_dir():
        raise InputError("output directory does not exist", source=str(d))
    out = []
    for s in range(seq.n_states):
        p = d / f"state_{s:03d}.obj"
        save_obj(quad_mesh.with_vertices(seq.positions[s]), p)
        out.append(p)
    return out


def plot_fold_angles(seq: FoldSequence, path: str | os.PathLike) -> None:
    """Fold angle [deg] of every crease hinge against the state (driven hinges bold), PNG via Agg."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    from fabkit.io.atomic import atomic_path

    fig = Figure(figsize=(7.0, 4.0), dpi=120)
    ax = fig.add_subplot(1, 1, 1)
    states = np.arange(seq.n_states)
    crease = np.flatnonzero(seq.edge_kind == "crease")
    free = np.setdiff1d(crease, seq.driven)
    for e in free:
        ax.plot(states, np.degrees(seq.angles[:, e]), color="0.7", lw=0.6)
    for e in seq.driven:
        ax.plot(states, np.degrees(seq.angles[:, e]), lw=2.0,
                label=f"driven ({seq.edges[e, 0]}, {seq.edges[e, 1]})" if len(seq.driven) <= 8 else None)
    ax.set_xlabel("fold state")
    ax.set_ylabel("fold angle [deg] (valley +)")
    ax.set_title(f"{len(seq.driven)} driven hinges (bold), {len(free)} other crease hinges (grey)")
    ax.grid(True, lw=0.3)
    if len(seq.driven) <= 8:
        ax.legend(loc="best", fontsize=7)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(str(tmp), format="png")
