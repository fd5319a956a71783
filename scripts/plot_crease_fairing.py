"""Regenerate docs/img/relax_fairing.png: crease fold angles of a noisy reflect panel, relaxed with and
without crease fairing, against the noise-free panel (48 x 25 columns x rows, σ = 1 %, seed 0).

Run: `.venv/bin/python scripts/plot_crease_fairing.py [OUT.png]`.
"""
from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from fabkit import measures  # noqa: E402
from fabkit.generate import reflect_panel  # noqa: E402
from fabkit.relax import relax  # noqa: E402
from fabkit.relax.fairing import crease_chains  # noqa: E402


def main(out: str = "docs/img/relax_fairing.png") -> None:
    truth = reflect_panel(columns=48, rows=25)
    sigma = 0.01 * float(truth.edge_lengths.mean())
    noisy = truth.with_vertices(truth.vertices + np.random.default_rng(0).normal(scale=sigma, size=truth.vertices.shape))
    plain = relax(noisy, crease_fairness=0.0)
    faired = relax(noisy)                      # crease fairing is on by default (weight 10)
    (chain,) = crease_chains(truth)
    lookup = {tuple(sorted(e)): i for i, e in enumerate(truth.edges.tolist())}
    edges = np.array([lookup[tuple(sorted(p))] for p in zip(chain[:-1].tolist(), chain[1:].tolist())])
    angle = {name: np.degrees(measures.dihedral_angles(m)[edges])
             for name, m in (("noise-free", truth), ("noisy input", noisy), ("--crease-fairness 0", plain.mesh),
                             ("default (crease fairing 10)", faired.mesh))}
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 5.5), sharex=True)
    x = np.arange(len(edges))
    for name, style in (("noise-free", "k-"), ("noisy input", "C7."), ("--crease-fairness 0", "C1.-"),
                        ("default (crease fairing 10)", "C0.-")):
        top.plot(x, angle[name], style, label=name, lw=1, ms=3)
    top.set_ylabel("crease fold angle [deg]")
    top.legend(fontsize=8)
    for name, color in (("--crease-fairness 0", "C1"), ("default (crease fairing 10)", "C0")):
        d = angle[name] - angle["noise-free"]
        bottom.plot(x, d, ".-", color=color, lw=1, ms=3, label=f"{name}: max |Δ| {np.abs(d).max():.2f}°")
    bottom.axhspan(-1, 1, color="C2", alpha=0.1, label="±1° goal")
    bottom.set_xlabel("crease edge along the crease")
    bottom.set_ylabel("change vs noise-free [deg]")
    bottom.legend(fontsize=8)
    fig.suptitle(f"reflect panel {truth.n_vertices} vertices, σ = 1 % of the mean edge: both relaxed to ≤ 1e-8",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*sys.argv[1:])
