"""Picture of a flat pattern coloured by per-spring length deviation (like the paper's Fig. 16)."""
from __future__ import annotations

import os

import numpy as np

from fabkit.io.atomic import atomic_path
from fabkit.mesh import PolyMesh
from fabkit.unfold.development import Development

__all__ = ["plot_unfold_error"]


def plot_unfold_error(mesh: PolyMesh, dev: Development, path: str | os.PathLike, *, title: str | None = None,
                      dpi: int = 110, log_scale: bool | None = None) -> None:
    """Write a PNG: faces in grey, every edge and diagonal coloured by |relative length deviation|,
    with a colour bar and the mean/max in the title. Diagonals are drawn thinner than edges. The
    colour scale is linear from 0, or logarithmic when every deviation is below 1e-6 (an exactly
    developable panel, where only round-off is left to show)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import colors
    from matplotlib.collections import LineCollection, PolyCollection
    from matplotlib.figure import Figure

    uv = dev.uv * 1000.0  # mm
    t = mesh.topology
    polys = [uv[f] for f in t.faces_list()]
    segs = np.concatenate([dev.edges, dev.diagonals])
    err = np.abs(dev.spring_relative_deviation)
    lo = max(float(err.min()), 1e-17)
    hi = max(float(err.max()), lo * 10)
    if log_scale is None:
        log_scale = hi < 1e-6
    norm = colors.LogNorm(vmin=lo, vmax=hi) if log_scale else colors.Normalize(vmin=0.0, vmax=hi)
    order = np.argsort(err)  # worst springs drawn last, on top
    fig = Figure(figsize=(7.0, 5.5))
    ax = fig.add_subplot()
    ax.add_collection(PolyCollection(polys, facecolors="0.92", edgecolors="none"))
    widths = np.where(np.arange(len(segs)) < len(dev.edges), 1.1, 0.5)
    lines = LineCollection(uv[segs[order]], cmap="viridis", norm=norm, linewidths=widths[order])
    lines.set_array(np.maximum(err[order], lo))
    ax.add_collection(lines)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    cb = fig.colorbar(lines, ax=ax, shrink=0.85)
    cb.set_label("|l2D - l3D| / l3D (edges and diagonals)")
    head = title or f"{dev.method} development"
    ax.set_title(f"{head}\nmean {dev.mean_relative_deviation:.3g}, max {dev.max_relative_deviation:.3g} "
                 f"relative; flipped faces {dev.n_flipped}", fontsize=10)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format="png")
