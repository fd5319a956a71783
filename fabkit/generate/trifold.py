"""The tri-fold panel of the paper's Fig. 3, built by its steps a–f.

The figure itself is not available, only its caption; this is our reading of it, step by step:

a. A closed polyhedron with planar faces: a box ``length x depth x height`` (along x, y, z).
b. + c. "Chamfer the vertices, bevel the original edges": cutting every corner off (b) and
   widening every original edge into a quad (c) is exactly Conway's *bevel* (truncate of ambo):
   the box becomes a truncated cuboctahedron with one octagon per original face, one hexagon per
   corner and one rectangle per original edge (`conway.bevel`, fraction `bevel`). Each edge
   rectangle is ``bevel * length`` long along its edge.
d. Delete the original faces (the octagons) and extrude the border edges of the six holes by
   `extrude` metres towards each hole's centre, in the plane of the deleted face. Every original
   edge now carries a band of three quads across: extrusion | edge rectangle | extrusion.
e. Catmull–Clark subdivision of the whole network, with the hole borders kept as sharp creases
   (DeRose et al. 1998; `subdivide.catmull_clark(..., crease_key="extruded")`). Each hole border
   is a planar octagon, so it refines to a planar cubic B-spline loop: the creases are planar
   curved arcs, as §3.1 asks of the low-poly, and the extruded strips stay exactly flat.
f. Retopologise "so rulings don't intersect except at conical parts":
   f1. delete every face except the band of one original edge (the one between the top and the
       front face). The deleted corner hexagons are the conical parts where three bands' rulings
       would meet.
   f2. in each of the three strips, dissolve the edges that run along the creases, so every strip
       is one row of faces and every face spans its strip between two consecutive rulings (the
       planar-quad representation of a curved-crease panel, §2.1). With `rows` > 1 every
       (C/rows)-th of these lines is kept instead.
   f3. dissolve the vertices left in the middle of the rulings (two edges each), so every face is
       a quad: two crease/boundary vertices on each side.

The result is moved into the panel frame: origin at the centroid, z along the area-weighted mean
normal (the front, the box's outside, faces +z), x along the creases (increasing column), y across
(increasing strip). Outer strips are planar (they lie in the box's face planes before the move);
the middle strip is the smooth Catmull–Clark surface between the two creases and is only nearly
developable — making it exactly developable is the relax stage's job.

Tags (docs/CONTRACTS.md "Panel tags"): face_data "strip" (0, 1, 2 across), "column" (0..C-1 along
the creases), "middle" (the faces of column C // 2, one per strip: with `rows` > 1 the one in the
strip's middle row).
"""
from __future__ import annotations

import numpy as np

from fabkit.errors import InputError, MeshError
from fabkit.generate.conway import ORIGIN_EDGE, ORIGIN_FACE, bevel as conway_bevel
from fabkit.generate.polyhedra import box
from fabkit.generate.subdivide import catmull_clark
from fabkit.generate.topology import delete_faces, dissolve_edges, dissolve_vertices, extrude_border_edges
from fabkit.mesh import PolyMesh

__all__ = ["trifold_panel", "trifold_network", "strip_columns", "MAX_RESOLUTION"]

MAX_RESOLUTION = 64  # columns; the whole network is subdivided (4 s at 64), so keep this bounded


def _check(cond: bool, message: str) -> None:
    if not cond:
        raise InputError(message, source="trifold_panel")


def trifold_network(length: float, depth: float, height: float, bevel: float, extrude: float,
                    levels: int) -> PolyMesh:
    """Steps a–e: the subdivided band network of the bevelled box (see module docstring).

    Raises `InputError` when the extrusion would reach a hole's centre (the strips would overlap).
    """
    b0 = box(length, depth, height)
    bv = conway_bevel(b0, bevel)
    d, _ = delete_faces(bv, bv.face_data["origin"] == ORIGIN_FACE)
    reach = min(float(np.linalg.norm(d.vertices[loop] - d.vertices[loop].mean(axis=0), axis=1).min())
                for loop in d.boundary_loops)
    _check(extrude < 0.75 * reach, f"extrude must be smaller than {0.75 * reach:.4g} m for this box and bevel "
                                   f"(the holes are {reach:.4g} m from border to centre), got {extrude}")
    e = extrude_border_edges(d, extrude, direction="loop")
    return catmull_clark(e, levels, crease_key="extruded")


def strip_columns(mesh: PolyMesh, strip: np.ndarray, crease_strip: int = 1
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Walk the quad grid across each strip: `(column_of_face, row_of_face, along_index)`.

    Starting from every edge of the crease between strips `crease_strip - 1` and `crease_strip`,
    walk through opposite quad edges to the boundary on both sides, across every strip; the faces
    met form one column and the edges crossed inside a strip are the edges that run along the
    creases. Columns are numbered in order along the crease (from its lower-numbered end vertex);
    rows inside each strip from the side the walk entered it (0 next to the starting crease or, for
    a strip beyond another crease, next to that crease). `along_index` (per edge) is k >= 1 for the
    k-th such edge line crossed inside a strip and 0 for every other edge.
    Raises `MeshError` when the grid is not a clean quad grid.
    """
    t = mesh.topology
    if not t.is_uniform or t.face_sizes[0] != 4:
        raise MeshError("strip_columns needs an all-quad mesh")
    ef = mesh.edge_faces
    inner = np.all(ef >= 0, axis=1)
    sa, sb = strip[np.maximum(ef[:, 0], 0)], strip[np.maximum(ef[:, 1], 0)]
    crease = np.flatnonzero(inner & (sa != sb) & (np.minimum(sa, sb) == crease_strip - 1))
    if len(crease) == 0:
        raise MeshError(f"no crease between strips {crease_strip - 1} and {crease_strip}")
    # order the crease edges along the crease polyline
    ce = mesh.edges[crease]
    deg = np.bincount(ce.ravel(), minlength=mesh.n_vertices)
    ends = np.flatnonzero(deg == 1)
    if len(ends) != 2 or np.any(deg > 2):
        raise MeshError("the crease is not a simple open polyline")
    by_vertex: dict[int, list[int]] = {}
    for k, (a, b) in enumerate(ce.tolist()):
        by_vertex.setdefault(a, []).append(k)
        by_vertex.setdefault(b, []).append(k)
    order, v, prev = [], int(min(ends)), -1
    for _ in range(len(ce)):
        k = next(k for k in by_vertex[v] if k != prev)
        order.append(k)
        a, b = ce[k]
        v = int(b if a == v else a)
        prev = k
    he = t.halfedge_edge
    col = np.full(mesh.n_faces, -1, np.int64)
    row = np.zeros(mesh.n_faces, np.int64)
    along = np.zeros(mesh.n_edges, dtype=np.int64)
    for c_idx, k in enumerate(order):
        e0 = crease[k]
        for f0 in ef[e0]:
            f, e = int(f0), int(e0)
            s = strip[f]
            k = 0
            for _ in range(mesh.n_faces):
                if col[f] not in (-1, c_idx):
                    raise MeshError(f"face {f} lies in two columns: the grid is not clean")
                col[f] = c_idx
                row[f] = k
                # the edge opposite to e in quad f
                es = he[4 * f:4 * f + 4]
                pos = int(np.flatnonzero(es == e)[0])
                e = int(es[(pos + 2) % 4])
                nb = ef[e, 0] if ef[e, 0] != f else ef[e, 1]
                if nb < 0:
                    break
                if strip[nb] == s:
                    k += 1
                    along[e] = k  # crossed inside a strip; otherwise crossed the next crease
                else:
                    k = 0
                s = strip[nb]
                f = int(nb)
    if np.any(col < 0):
        raise MeshError(f"{int(np.sum(col < 0))} faces are not reached from the crease: the grid is not clean")
    return col, row, along


def trifold_panel(length: float = 1.6, depth: float = 0.8, height: float | None = None, bevel: float = 0.2,
                  extrude: float = 0.12, resolution: int = 16, rows: int = 1) -> PolyMesh:
    """The Fig. 3 tri-fold panel (module docstring): three strips, two curved creases, C columns.

    length, depth, height [m] > 0: the box of step a (x, y, z extents; height defaults to depth;
    the creases run along `length`); bevel in (0, 1/2): Conway bevel fraction (the panel is about
    ``bevel * length`` long); extrude [m] > 0: width of the outer strips, smaller than the holes
    allow; resolution: at least this many columns (rounded up to a power of 2; 2..64); rows: rows
    of faces per strip, a power of 2 up to the number of columns (1: every face spans its strip;
    more keep every (C/rows)-th Catmull–Clark line along the creases, giving the solver vertices
    inside the strips). Raises `InputError` for impossible values.
    """
    height = depth if height is None else height
    length, depth, height, bevel, extrude = (float(v) for v in (length, depth, height, bevel, extrude))
    for name, v in (("length", length), ("depth", depth), ("height", height), ("extrude", extrude)):
        _check(np.isfinite(v) and v > 0, f"{name} must be a positive length, got {v}")
    _check(np.isfinite(bevel) and 0 < bevel < 0.5, f"bevel must be in (0, 1/2), got {bevel}")
    _check(int(resolution) == resolution and 2 <= resolution <= MAX_RESOLUTION,
           f"resolution must be an integer from 2 to {MAX_RESOLUTION}, got {resolution}")
    levels = int(np.ceil(np.log2(resolution)))
    n_lines = 2 ** levels  # Catmull–Clark rows per strip before f2
    _check(int(rows) == rows and rows >= 1 and n_lines % int(rows) == 0,
           f"rows must be a power of 2 from 1 to the number of columns ({n_lines}), got {rows}")
    step = n_lines // int(rows)

    net = trifold_network(length, depth, height, bevel, extrude, levels)
    # f1: keep the band of the edge between the top (+z) and front (-y) faces, running along x
    b0 = box(length, depth, height)
    band = int(np.flatnonzero((b0.edges[:, 0] == 4) & (b0.edges[:, 1] == 5))[0])
    keep = (net.face_data["origin"] == ORIGIN_EDGE) & (net.face_data["source"] == band)
    panel, _ = delete_faces(net, ~keep)

    # strips: the middle (the edge rectangle's children) and the two extruded sides (top = 0, front = 2)
    cen = panel.face_centroids
    ext = panel.face_data["extruded"] == 1
    on_top = height / 2 - cen[:, 2] < cen[:, 1] + depth / 2  # nearer the top plane than the front plane
    strip = np.where(~ext, 1, np.where(on_top, 0, 2)).astype(np.int64)

    # f2: `rows` rows of faces per strip (one by default); f3: drop the vertices left inside the rulings
    col, row, along = strip_columns(panel, strip)
    panel = PolyMesh(panel.vertices, (panel.face_indices, panel.face_offsets),
                     face_data={"strip": strip, "column": col, "row": row // step}, validate=False)
    corners = _corner_mask(panel)
    merged = dissolve_edges(panel, (along > 0) & (along % step != 0))
    mid = np.flatnonzero((merged.topology.vertex_valence == 2) & ~corners)
    panel, _ = dissolve_vertices(merged, mid)
    if not np.all(panel.face_sizes == 4):
        raise MeshError("retopologised tri-fold is not all quads (internal error)")

    # panel frame: origin at the centroid, z = mean normal, x along increasing column
    V = panel.vertices - panel.vertices.mean(axis=0)
    z = panel.face_normal_sums.sum(axis=0)
    z /= np.linalg.norm(z)
    colc = panel.face_data["column"]
    cen = panel.face_centroids
    x = cen[colc == colc.max()].mean(axis=0) - cen[colc == 0].mean(axis=0)
    x -= (x @ z) * z
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    V = V @ R.T
    st = panel.face_data["strip"]
    if V[np.unique(panel.topology.face_array[st == 2])][:, 1].mean() < V[np.unique(panel.topology.face_array[st == 0])][:, 1].mean():
        st = 2 - st  # strips increase along +y
    n_col = int(colc.max()) + 1
    middle = ((colc == n_col // 2) & (panel.face_data["row"] == int(rows) // 2)).astype(np.int64)
    return PolyMesh(V, (panel.face_indices, panel.face_offsets),
                    face_data={"strip": st.astype(np.int64), "column": colc.astype(np.int64), "middle": middle})


def _corner_mask(mesh: PolyMesh) -> np.ndarray:
    """Corners of the grid's outline (boundary vertices of a single face), found before step f2.

    They keep their place in f3; every other vertex left with two edges after f2 lies inside a
    ruling (or inside an end ruling on the boundary) and is dissolved.
    """
    return mesh.topology.boundary_vertex_mask & (np.bincount(mesh.face_indices, minlength=mesh.n_vertices) == 1)
