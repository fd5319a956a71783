"""Procedural input meshes (paper §2.1 Fig. 3, §3.1): presets and the mesh operations behind them."""
from fabkit.generate.reflect import MirrorPlane, grid_faces, reflect_panel

__all__ = ["MirrorPlane", "grid_faces", "reflect_panel"]
