"""Picture of a generated mesh: a 3D view with strips coloured and creases drawn by their sign, plus
the planar development when the mesh carries one (`vertex_data["uv"]`, e.g. the reflect preset)."""
from __future__ import annotations

import os

import numpy as np

from fabkit import measures
from fabkit.io.atomic import atomic_path
from fabkit.mesh import PolyMesh
from fabkit.structure import panel_structure

__all__ = ["plot_generated"]

STRIP_COLOURS = ("#9ecae1", "#fdd0a2", "#c7e9c0", "#dadaeb", "#fcbba1")
MOUNTAIN, VALLEY = "#d62728", "#1f77b4"


def plot_generated(mesh: PolyMesh, path: str | os.PathLike, *, title: str = "", dpi: int = 110) -> None:
    """Write a PNG: faces coloured by strip (tagged, else inferred: `fabkit.structure`), mountain
    creases red, valley blue, the middle row outlined; a second panel shows `uv` when present.
    Lengths in millimetres."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    V = mesh.vertices * 1000.0
    faces = mesh.faces_list()
    structure = panel_structure(mesh)  # the strip tags, else the strips between the inferred creases
    colours = [STRIP_COLOURS[int(s) % len(STRIP_COLOURS)] for s in structure.strip]
    crease = structure.crease
    crease_colours = np.where(structure.fold_angle[crease] < 0, MOUNTAIN, VALLEY)
    has_uv = "uv" in mesh.vertex_data
    fig = Figure(figsize=(11.0 if has_uv else 6.5, 5.5))
    ax = fig.add_subplot(1, 2 if has_uv else 1, 1, projection="3d")
    ax.add_collection3d(Poly3DCollection([V[f] for f in faces], facecolors=colours, edgecolors="0.35",
                                         linewidths=0.3), autolim=False)
    if crease.any():
        ax.add_collection3d(Line3DCollection(V[mesh.edges[crease]], colors=list(crease_colours), linewidths=2.0), autolim=False)
    lo, hi = V.min(axis=0), V.max(axis=0)
    centre, half = (lo + hi) / 2, (hi - lo).max() / 2 or 1.0
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_zlabel("z [mm]")
    ax.view_init(elev=28, azim=-20)  # looking along the creases (x), so every strip is in view
    s = measures.summary(mesh)
    ax.set_title(f"{title}\n{mesh.n_vertices} vertices, {mesh.n_faces} faces; max |defect| "
                 f"{s['max_abs_angle_defect_rad']:.2g} rad, planarity {s['max_planarity']:.2g}", fontsize=9)
    if has_uv:
        uv = np.asarray(mesh.vertex_data["uv"]) * 1000.0
        ax2 = fig.add_subplot(1, 2, 2)
        ax2.add_collection(PolyCollection([uv[f] for f in faces], facecolors=colours, edgecolors="0.35",
                                          linewidths=0.3))
        if crease.any():
            ax2.add_collection(LineCollection(uv[mesh.edges[crease]], colors=list(crease_colours), linewidths=2.0))
        if "middle" in mesh.face_data:
            mid = np.flatnonzero(np.asarray(mesh.face_data["middle"]) == 1)
            ax2.add_collection(PolyCollection([uv[faces[f]] for f in mid], facecolors="none", edgecolors="k",
                                              linewidths=1.2))
        ax2.autoscale_view()
        ax2.set_aspect("equal")
        ax2.set_xlabel("u [mm]")
        ax2.set_ylabel("v [mm]")
        ax2.set_title("development (uv): mountain red, valley blue, middle row outlined", fontsize=9)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
