"""Procedural input meshes (paper §2.1 Fig. 3, §3.1): presets and the mesh operations behind them."""
from fabkit.generate.polyhedra import box, cube, grid, octahedron, prism, signed_volume, tetrahedron
from fabkit.generate.reflect import MirrorPlane, grid_faces, reflect_panel
from fabkit.generate.subdivide import catmull_clark, catmull_clark_operator

__all__ = ["MirrorPlane", "grid_faces", "reflect_panel", "box", "cube", "grid", "octahedron", "prism",
           "signed_volume", "tetrahedron", "catmull_clark", "catmull_clark_operator"]
