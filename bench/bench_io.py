"""File I/O speed: our OBJ and FOLD readers/writers against baselines measured in the same run.

Baselines: trimesh's OBJ loader (process=False; it triangulates and drops our tags) for OBJ, and
plain `json.loads` of the same FOLD text (the parse cost alone, without validation or the exact
decimal unit conversion) for FOLD. Ratios > 1 mean ours is slower.
"""
from __future__ import annotations

import json
import tempfile
from pathlib import Path

import numpy as np

from bench.common import best_time, report


def _grid(n: int):
    from fabkit.mesh import PolyMesh

    xs, ys = np.meshgrid(np.arange(n + 1) * 0.01, np.arange(n + 1) * 0.01)
    rng = np.random.default_rng(0)
    V = np.column_stack([xs.ravel(), ys.ravel(), rng.normal(scale=1e-4, size=xs.size)])
    F = [[j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i]
         for j in range(n) for i in range(n)]
    return PolyMesh(V, F, face_data={"strip": np.repeat(np.arange(n), n)})


def main() -> dict:
    import trimesh

    from fabkit.fold import FoldFrame, FoldModel
    from fabkit.io.fold import load_fold, save_fold
    from fabkit.io.obj import load_obj, save_obj

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in (50, 150):
            mesh = _grid(n)
            obj = Path(tmp) / f"g{n}.obj"
            fold = Path(tmp) / f"g{n}.fold"
            t_save_obj = best_time(lambda: save_obj(mesh, obj))
            t_load_obj = best_time(lambda: load_obj(obj))
            t_trimesh = best_time(lambda: trimesh.load(obj, process=False, force="mesh"))
            frames = [FoldFrame(mesh.vertices + [0, 0, 0.01 * k]) for k in range(3)]
            model = FoldModel.from_mesh(mesh, frames=frames, attributes=("3D",), classes=("foldedForm",))
            t_save_fold = best_time(lambda: save_fold(model, fold))
            t_load_fold = best_time(lambda: load_fold(fold))
            text = fold.read_text()
            t_json = best_time(lambda: json.loads(text))
            rows.append({"quads": n * n, "vertices": mesh.n_vertices, "save_obj_s": t_save_obj,
                         "load_obj_s": t_load_obj, "trimesh_load_s": t_trimesh,
                         "obj_ratio": t_load_obj / t_trimesh, "save_fold_s": t_save_fold,
                         "load_fold_s": t_load_fold, "json_loads_s": t_json, "fold_ratio": t_load_fold / t_json})
    return report("io", rows, {"frames": 3, "baselines": "trimesh OBJ load (process=False); json.loads"})


if __name__ == "__main__":
    main()
