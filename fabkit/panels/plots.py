"""Plots of a multi-panel run, like the paper's Figs. 16, 17 and 19 (matplotlib, Agg).

- `plot_panel_errors`: unfold error per panel and per band (Fig. 19, left);
- `plot_band_layout`: the developments arranged in adjacency bands, each edge coloured by its
  shared-edge incongruency (Fig. 17 / Fig. 19, right);
- `plot_surface_errors`: the panels on the 3D surface coloured by their max unfold error (Fig. 16);
- `plot_rounds`: incongruency and unfold deviation per feedback round (§4.1).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from fabkit.io.atomic import atomic_path


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> None:
    plt = _plt()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")
    plt.close(fig)


def plot_panel_errors(run, path: Path) -> None:
    plt = _plt()
    n = len(run.results)
    umax = np.array([r.unfold_max for r in run.results])
    cong = run.congruency.per_panel_max(n)
    bands = np.array([p.band for p in run.layout.panels])
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 3.6), gridspec_kw={"width_ratios": [3, 1]})
    x = np.arange(n)
    a1.semilogy(x, np.maximum(umax, 1e-16), ".", label="max unfold deviation (2D vs 3D)")
    a1.semilogy(x, np.maximum(cong, 1e-16), "x", ms=4, label="max shared-edge incongruency")
    a1.axhline(run.options.tol_unfold, color="C0", ls="--", lw=.8)
    a1.axhline(run.options.tol_congruency, color="C1", ls="--", lw=.8)
    a1.set_xlabel("panel")
    a1.set_ylabel("relative deviation")
    a1.grid(alpha=.3, which="both")
    a1.legend(fontsize=8)
    a1.set_title("unfold error per panel")
    per_band = [umax[bands == b].max() for b in np.unique(bands)]
    a2.bar(np.unique(bands), per_band, color="C0")
    a2.set_yscale("log")
    a2.set_xlabel("band")
    a2.set_title("worst per band")
    _save(fig, path)


def plot_band_layout(run, placements: list[dict], path: Path) -> None:
    from matplotlib.collections import LineCollection

    plt = _plt()
    layout = run.layout
    n = len(layout.panels)
    edge_err = [np.zeros(p.mesh.n_edges) for p in layout.panels]
    c = run.congruency
    for (pa, ea, pb, eb), rel in zip(c.pairs.tolist(), c.relative):
        edge_err[pa][ea] = rel
        edge_err[pb][eb] = rel
    segs, vals = [], []
    fig, ax = plt.subplots(figsize=(11, 6))
    for pl in placements:
        p = layout.panels[pl["id"]]
        uv = run.results[p.id].uv @ np.asarray(pl["rotation"]).T + np.asarray(pl["translation"])
        E = p.mesh.edges
        b = p.mesh.topology.boundary_edge_mask
        segs.extend(uv[E[b]])
        vals.extend(edge_err[p.id][b])
        inner = uv[E[~b]]
        ax.add_collection(LineCollection(inner, colors="#cccccc", linewidths=0.3))
        cx, cy = uv.mean(axis=0)
        ax.text(cx, cy, str(p.id), fontsize=5, ha="center", va="center", color="#555555")
    vals = np.maximum(np.array(vals), 1e-12)
    lc = LineCollection(segs, array=np.log10(vals), cmap="inferno_r", linewidths=1.2)
    ax.add_collection(lc)
    fig.colorbar(lc, ax=ax, label="log10 shared-edge incongruency")
    ax.set_aspect("equal")
    ax.autoscale()
    ax.set_title(f"developments in adjacency bands ({n} panels)")
    ax.set_xlabel("m")
    _save(fig, path)


def plot_surface_errors(run, path: Path) -> None:
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    plt = _plt()
    fig = plt.figure(figsize=(9, 6))
    ax = fig.add_subplot(111, projection="3d")
    umax = np.array([max(r.unfold_max, 1e-16) for r in run.results])
    norm = plt.Normalize(np.log10(umax.min()), np.log10(umax.max()) + 1e-9)
    cmap = plt.get_cmap("viridis")
    for p, r in zip(run.layout.panels, run.results):
        quads = r.relaxed[p.mesh.topology.face_array]
        ax.add_collection3d(Poly3DCollection(quads, facecolor=cmap(norm(np.log10(umax[p.id]))), edgecolor="none"),
                          autolim=False)  # the limits are set below
    allv = np.vstack([r.relaxed for r in run.results])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    mid, span = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set_xlim(mid[0] - span, mid[0] + span)
    ax.set_ylim(mid[1] - span, mid[1] + span)
    ax.set_zlim(max(lo[2], mid[2] - span), mid[2] + span)
    sm = plt.cm.ScalarMappable(norm=norm, cmap=cmap)
    fig.colorbar(sm, ax=ax, shrink=0.6, label="log10 max unfold deviation per panel")
    ax.set_title("relaxed panels on the surface")
    _save(fig, path)


def plot_rounds(run, path: Path) -> None:
    plt = _plt()
    r = run.rounds
    fig, ax = plt.subplots(figsize=(6, 3.4))
    x = [d["round"] for d in r]
    ax.semilogy(x, [max(d["max_incongruency"], 1e-16) for d in r], "o-", label="max incongruency")
    ax.semilogy(x, [max(d["max_unfold_deviation"], 1e-16) for d in r], "s-", label="max unfold deviation")
    ax.axhline(run.options.tol_congruency, color="C0", ls="--", lw=.8)
    ax.axhline(run.options.tol_unfold, color="C1", ls="--", lw=.8)
    ax.set_xlabel("feedback round")
    ax.grid(alpha=.3, which="both")
    ax.legend(fontsize=8)
    ax.set_title("automatic feedback (§4.1)")
    _save(fig, path)
