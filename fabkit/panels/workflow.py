"""The multi-panel workflow with automatic feedback (paper §3, §4.1) and symmetry (§4.2).

relax every panel (singularity points fixed) -> unfold -> measure shared-edge congruency ->
merge incongruent edges into target lengths -> unfold again with the targets -> ... until the
shared edges agree to `tol_congruency` and every panel's development stays within
`tol_unfold` of its 3D edge lengths, or `max_rounds` is reached.

Feedback rule (the paper left it manual): each panel's target for a shared edge moves by
(mean developed length of both sides − its own developed length). A development only partly
follows changed targets (the interior springs resist), so simply re-targeting both sides to the
mean stalls after one round; accumulating the error like this drives the mismatch to zero
geometrically.

Per-panel work is a pure function of its inputs (`panel_task`), run through any executor
(`fabkit.panels.executor`), so serial, process-pool and dask runs give the same numbers.
"""
from __future__ import annotations

import contextlib

import time
from dataclasses import dataclass, field

import numpy as np

from fabkit.errors import InputError
from fabkit.mesh import PolyMesh
from fabkit.panels.congruency import Congruency, measure_congruency
from fabkit.panels.executor import map_ordered, panel_executor
from fabkit.panels.layout import Panel, PanelLayout

__all__ = ["PanelsOptions", "PanelResult", "PanelsRun", "panel_task", "run_panels", "mirror_partner"]

MIRROR = np.diag([-1.0, 1.0, 1.0])  # the canopy's mirror plane is x = 0


@dataclass(frozen=True)
class PanelsOptions:
    tol_congruency: float = 1e-4      # max |l_a - l_b| / mean over shared edges
    tol_unfold: float = 1e-3          # max relative 2D-vs-3D edge/diagonal deviation per panel
    max_rounds: int = 12              # merge rounds after the first unfold
    symmetric: bool = False           # solve half (bands below the mirror plane) and mirror
    tol_defect: float = 1e-8          # relax tolerances per panel
    tol_planarity: float = 1e-8
    relax_max_iter: int = 5000
    keep_shared_edges: bool = True    # relax each panel with its shared boundary edges kept at their
                                      # lengths on the common input surface (neighbours then agree in 3D)
    edge_length_weight: float = 1.0   # weight of those kept-length residuals in the relaxation


@dataclass(frozen=True)
class PanelResult:
    id: int
    relaxed: np.ndarray           # (n, 3) relaxed 3D vertices
    uv: np.ndarray                # (n, 2) development
    converged: bool
    message: str
    max_defect: float
    max_planarity: float
    max_displacement: float
    unfold_mean: float            # mean relative 2D-vs-3D deviation (edges + diagonals)
    unfold_max: float
    target_mean: float            # the same against the (merged) target lengths the unfold aimed at
    target_max: float
    overlaps: bool
    flipped: int
    seconds: float


@dataclass(frozen=True)
class PanelsRun:
    layout: PanelLayout
    options: PanelsOptions
    results: tuple[PanelResult, ...]
    congruency: Congruency
    rounds: tuple[dict, ...]       # metrics per feedback round
    targets: tuple                 # final per-panel target arrays (E,)
    seconds: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return (self.congruency.max_relative <= self.options.tol_congruency
                and all(r.converged and r.unfold_max <= self.options.tol_unfold and r.flipped == 0
                        for r in self.results))

    def failing_panels(self) -> list[tuple[int, str]]:
        out = []
        cong = self.congruency.per_panel_max(len(self.results))
        for r in self.results:
            why = []
            if not r.converged:
                why.append(f"relax: {r.message}")
            if r.unfold_max > self.options.tol_unfold:
                why.append(f"unfold max deviation {r.unfold_max:.3g} > {self.options.tol_unfold:g}")
            if r.flipped:
                why.append(f"{r.flipped} flipped faces")
            if cong[r.id] > self.options.tol_congruency:
                why.append(f"shared-edge incongruency {cong[r.id]:.3g} > {self.options.tol_congruency:g}")
            if why:
                out.append((r.id, "; ".join(why)))
        return out


def _deviation(mesh: PolyMesh, uv: np.ndarray) -> tuple[float, float]:
    """Mean and max relative deviation of 2D vs 3D lengths over edges and face diagonals."""
    from fabkit.unfold import reference_lengths

    pairs, rest = reference_lengths(mesh)
    l2 = np.linalg.norm(uv[pairs[:, 1]] - uv[pairs[:, 0]], axis=1)
    rel = np.abs(l2 - rest) / rest
    return float(rel.mean()), float(rel.max())


def panel_task(task: dict) -> dict:
    """Relax (when `task["relax"]`) and unfold one panel. Pure: arrays in, arrays out (picklable)."""
    from fabkit.relax.solver import relax
    from fabkit.unfold import develop

    t0 = time.perf_counter()
    # fresh, contiguous copies: arrays that arrive deserialised (dask) may sit at another memory
    # alignment, and numpy's SIMD reductions can round differently on differently aligned data
    task = {k: (np.array(v, copy=True, order="C") if isinstance(v, np.ndarray) else v) for k, v in task.items()}
    mesh = PolyMesh(task["vertices"], task["faces"], validate=False)
    out = {"id": task["id"]}
    if task.get("relax", True):
        keep = task.get("keep_edges")
        extra = {}
        if keep is not None and len(keep):
            extra = {"edge_lengths": (keep, mesh.edge_lengths[keep]),
                     "edge_length_weight": task.get("edge_length_weight", 1.0)}
        res = relax(mesh, fixed=task["fixed"], tol_defect=task["tol_defect"], tol_planarity=task["tol_planarity"],
                    max_iter=task["max_iter"], **extra)
        mesh = res.mesh
        out.update(converged=bool(res.converged), message=res.message, max_defect=float(res.max_defect),
                   max_planarity=float(res.max_planarity), max_displacement=float(res.max_displacement))
    dev = develop(mesh, target_lengths=task.get("targets"))
    uv = np.asarray(dev.uv)[:, :2]
    mean, mx = _deviation(mesh, uv)
    out.update(relaxed=np.array(mesh.vertices), uv=uv, unfold_mean=mean, unfold_max=mx,
               target_mean=float(dev.mean_relative_deviation), target_max=float(dev.max_relative_deviation),
               flipped=int(dev.n_flipped), overlaps=bool(dev.outline_self_overlaps),
               seconds=time.perf_counter() - t0)
    return out


def mirror_partner(layout: PanelLayout) -> np.ndarray:
    """Partner panel of every panel under the x = 0 mirror (band b <-> rows-1-b, same index)."""
    rows = len(layout.arcs) - 1
    by_key = {(p.band, p.index): p.id for p in layout.panels}
    partner = np.empty(len(layout.panels), dtype=np.int64)
    for p in layout.panels:
        q = by_key.get((rows - 1 - p.band, p.index))
        if q is None or len(layout.panels[q].stations) != len(p.stations) or len(layout.panels[q].rows) != len(p.rows):
            raise InputError("the panel layout is not mirror-symmetric (use an even number of bands on a "
                             "symmetric surface)", source="--symmetric")
        partner[p.id] = q
    return partner


def _mirror_arrays(src: Panel, dst: Panel, relaxed: np.ndarray, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Map a solved panel's arrays onto its mirror partner (rows reversed, x and u negated)."""
    nr, nc = len(src.rows), len(src.stations)
    perm = np.arange(nr * nc).reshape(nr, nc)[::-1].ravel()  # dst vertex (r', c) <- src (nr-1-r', c)
    return relaxed[perm] @ MIRROR, uv[perm] * np.array([-1.0, 1.0])


def _map_cached(ex, tasks: list[dict], cache, progress) -> list[dict]:
    """`panel_task` over `tasks`, taking results `cache` (a `ResultCache`) already holds."""
    if cache is None:
        return map_ordered(ex, panel_task, tasks, progress=progress)
    keys = [cache.key(t) for t in tasks]
    out: list = [cache.get(k) for k in keys]
    todo = [i for i, r in enumerate(out) if r is None]
    for i in range(len(tasks)):
        if out[i] is not None:
            cache.reused.append(tasks[i]["id"])
            if progress:
                progress()
    for i, r in zip(todo, map_ordered(ex, panel_task, [tasks[i] for i in todo], progress=progress)):
        cache.put(keys[i], r)
        cache.computed.append(tasks[i]["id"])
        out[i] = r
    return out


def run_panels(layout: PanelLayout, options: PanelsOptions = PanelsOptions(), *, jobs: int = 1,
               scheduler: str | None = None, progress=None, cache=None, executor=None) -> PanelsRun:
    """Relax, unfold and make congruent every panel of `layout` (see the module docstring).

    `cache`: a `fabkit.panels.cache.ResultCache`; tasks whose inputs it already holds are not run.
    `executor`: an open `panel_executor` to run on (one pool for every stage of a run) instead of
    one opened for `jobs` / `scheduler`.
    """
    panels = layout.panels
    n = len(panels)
    if options.symmetric:
        partner = mirror_partner(layout)
        rows = len(layout.arcs) - 1
        solve = [p.id for p in panels if p.band < rows // 2]
    else:
        partner = np.arange(n)
        solve = list(range(n))
    timings: dict[str, float] = {}
    shared_ids = [set() for _ in range(n)]
    for pa, ea, pb, eb in layout.shared_edges:
        shared_ids[pa].add(int(ea))
        shared_ids[pb].add(int(eb))
    base_tasks = {p.id: {"id": p.id, "vertices": np.array(p.mesh.vertices), "faces": p.mesh.topology.face_array,
                         "fixed": np.flatnonzero(p.fixed), "tol_defect": options.tol_defect,
                         "tol_planarity": options.tol_planarity, "max_iter": options.relax_max_iter,
                         "keep_edges": (np.array(sorted(shared_ids[p.id]), dtype=np.int64)
                                        if options.keep_shared_edges else None),
                         "edge_length_weight": options.edge_length_weight}
                  for p in panels}
    edges = [p.mesh.edges for p in panels]
    results: dict[int, dict] = {}

    def fill_mirrors(res: dict[int, dict]) -> None:
        if not options.symmetric:
            return
        for pid in range(n):
            if pid in solve:
                continue
            src = partner[pid]
            r = res[src]
            relaxed, uv = _mirror_arrays(panels[src], panels[pid], r["relaxed"], r["uv"])
            res[pid] = {**r, "id": pid, "relaxed": relaxed, "uv": uv}

    with (contextlib.nullcontext(executor) if executor is not None else panel_executor(jobs, scheduler)) as ex:
        t0 = time.perf_counter()
        for r in _map_cached(ex, [base_tasks[i] for i in solve], cache, progress):
            results[r["id"]] = r
        fill_mirrors(results)
        timings["relax_unfold"] = time.perf_counter() - t0

        relaxed_meshes = [panels[i].mesh.with_vertices(results[i]["relaxed"]) for i in range(n)]
        lengths3d = [m.edge_lengths.copy() for m in relaxed_meshes]
        targets = [l.copy() for l in lengths3d]
        rounds = []
        t0 = time.perf_counter()
        cong = measure_congruency(layout.shared_edges, edges, [results[i]["uv"] for i in range(n)])
        rounds.append(_round_metrics(0, cong, results, n))
        for rnd in range(1, options.max_rounds + 1):
            if _done(cong, results, options, n):
                break
            # integrate the mismatch into each panel's shared-edge targets
            mean = 0.5 * (cong.length_a + cong.length_b)
            for (pa, ea, pb, eb), m, la, lb in zip(cong.pairs.tolist(), mean, cong.length_a, cong.length_b):
                targets[pa][ea] += m - la
                targets[pb][eb] += m - lb
            tasks = [{**base_tasks[i], "vertices": results[i]["relaxed"], "relax": False, "targets": targets[i]}
                     for i in solve]
            for r in _map_cached(ex, tasks, cache, progress):
                keep = {k: results[r["id"]][k] for k in ("converged", "message", "max_defect", "max_planarity",
                                                           "max_displacement")}
                results[r["id"]] = {**r, **keep}
            fill_mirrors(results)
            if options.symmetric:
                for pid in range(n):
                    if pid not in solve:
                        targets[pid] = targets[partner[pid]][_edge_perm(panels[partner[pid]], panels[pid])]
            cong = measure_congruency(layout.shared_edges, edges, [results[i]["uv"] for i in range(n)])
            rounds.append(_round_metrics(rnd, cong, results, n))
        timings["congruency_merge"] = time.perf_counter() - t0

    final = tuple(PanelResult(id=i, relaxed=results[i]["relaxed"], uv=results[i]["uv"],
                              converged=results[i]["converged"], message=results[i]["message"],
                              max_defect=results[i]["max_defect"], max_planarity=results[i]["max_planarity"],
                              max_displacement=results[i]["max_displacement"],
                              unfold_mean=results[i]["unfold_mean"], unfold_max=results[i]["unfold_max"],
                              target_mean=results[i]["target_mean"], target_max=results[i]["target_max"],
                              overlaps=results[i]["overlaps"], flipped=results[i]["flipped"], seconds=results[i]["seconds"]) for i in range(n))
    return PanelsRun(layout=layout, options=options, results=final, congruency=cong, rounds=tuple(rounds),
                     targets=tuple(targets), seconds=timings)


def _edge_perm(src: Panel, dst: Panel) -> np.ndarray:
    """For each edge of `dst`, the matching edge id of its mirror partner `src`."""
    nr, nc = len(src.rows), len(src.stations)
    vmap = np.arange(nr * nc).reshape(nr, nc)[::-1].ravel()  # dst vertex -> src vertex
    E_src = src.mesh.edges
    lookup = {(int(a), int(b)): e for e, (a, b) in enumerate(E_src)}
    out = np.empty(dst.mesh.n_edges, dtype=np.int64)
    for e, (a, b) in enumerate(dst.mesh.edges):
        u, v = int(vmap[a]), int(vmap[b])
        out[e] = lookup[(min(u, v), max(u, v))]
    return out


def _done(cong: Congruency, results: dict, options: PanelsOptions, n: int) -> bool:
    return cong.max_relative <= options.tol_congruency and all(results[i]["unfold_max"] <= options.tol_unfold
                                                               for i in range(n))


def _round_metrics(rnd: int, cong: Congruency, results: dict, n: int) -> dict:
    umax = np.array([results[i]["unfold_max"] for i in range(n)])
    umean = np.array([results[i]["unfold_mean"] for i in range(n)])
    tmax = np.array([results[i]["target_max"] for i in range(n)])
    return {"round": rnd, "max_incongruency": cong.max_relative, "mean_incongruency": cong.mean_relative,
            "max_unfold_deviation": float(umax.max()), "mean_unfold_deviation": float(umean.mean()),
            "max_deviation_from_targets": float(tmax.max())}
