"""What `fabkit info` reports of a panel file: its measures, panel structure and, for a FOLD file,
its frames checked as an animation of sheet metal (`summarize`, `fold_frame_measures`).

A fold state of a sheet should be an isometry of the key frame with planar faces, and the fold
angles a file stores for its M/V creases should be the ones its coordinates show, with the sign of
their assignment; `fold_frame_measures` measures how far each of these is off.
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["summarize", "fold_frame_measures", "SIGN_NOISE_RAD"]


def _faces_by_size(sizes) -> dict[str, int]:
    import numpy as np

    counts = np.bincount(sizes)
    names = {3: "triangles", 4: "quads", 5: "pentagons", 6: "hexagons"}
    return {names.get(k, f"{k}-gons"): int(c) for k, c in enumerate(counts) if c}


def _measured_mesh(model, frame: int | None, path: str):
    """The key-frame mesh, or the mesh of FOLD frame `frame` (0 = key, 1..N states, negative from the end)."""
    from fabkit.errors import InputError

    if frame is None or frame == 0:
        return model.mesh(), 0
    n = model.n_frames
    k = frame if frame > 0 else n + 1 + frame
    if not 1 <= k <= n:
        raise InputError(f"frame {frame} does not exist: the file has the key frame 0 and fold states 1..{n}"
                         if n else f"frame {frame} does not exist: the file has only the key frame 0",
                         source="--frame")
    return model.frame_mesh(k - 1), k


def summarize(path: str, frame: int | None = None, units: str | None = None) -> dict:
    """Read and validate `path`; return the summary dictionary (raises `InputError` for a bad file).

    `frame` picks the FOLD frame that is measured (default: the key frame)."""
    from fabkit import measures
    from fabkit.errors import InputError
    from fabkit.io.load import load_fold_model, load_panel

    suffix = Path(path).suffix.lower()
    if suffix in (".obj", ".3dm", ".svg"):
        if frame is not None:
            raise InputError("only FOLD files have frames", source="--frame")
        mesh, loaded = load_panel(path, units)
        model, measured = None, None
    elif suffix == ".fold":
        model, loaded = load_fold_model(path, units)
        mesh, measured = _measured_mesh(model, frame, path)
    else:
        raise InputError(f"cannot read '{suffix or 'no suffix'}': fabkit info reads .obj, .fold, .3dm and .svg",
                         source=path)
    from fabkit.structure import assigned_creases, assigned_letters, panel_structure

    s = measures.summary(mesh)
    folded = mesh if model is None or frame is not None or not model.n_frames else model.frame_mesh(-1)
    report = {
        "format": "fabkit.info/1",
        "file": str(path),
        "kind": loaded.format,
        "vertices": s["vertices"],
        "faces": s["faces"],
        "faces_by_size": _faces_by_size(mesh.face_sizes),
        "edges": s["edges"],
        "boundary_loops": s["boundary_loops"],
        "interior_vertices": s["interior_vertices"],
        "max_abs_angle_defect_rad": s["max_abs_angle_defect_rad"],
        "mean_abs_angle_defect_rad": s["mean_abs_angle_defect_rad"],
        "max_planarity": s["max_planarity"],
        "mean_planarity": s["mean_planarity"],
        "min_edge_m": s["min_edge_m"],
        "max_edge_m": s["max_edge_m"],
        "size_m": s["size_m"],
        "face_tags": sorted(mesh.face_data),
        "vertex_tags": sorted(mesh.vertex_data),
        "unit": "m",
        "loaded": loaded.to_report(),
        "warnings": list(mesh.warnings),
        "structure": panel_structure(folded, crease_edges=None if model is None else assigned_creases(model),
                                     crease_letters=None if model is None else assigned_letters(model, folded)
                                     ).summary(folded),
    }
    if model is not None:
        report.update({
            "unit": model.unit,
            "frames": model.n_frames,
            "frame_classes": list(model.classes),
            "edge_tags": sorted(model.edges_data),
            "edges_assignment": {a: int((model.edges_assignment == a).sum()) for a in "BMVFJUC"
                                 if (model.edges_assignment == a).any()},
            "creator": model.creator,
            "notes": list(loaded.notes),
            "measured_frame": measured,
        })
        if model.n_frames:
            report.update(fold_frame_measures(model, model.mesh(validate=False)))
    return report


#: a crease bent the wrong way by less than this (radians) counts as flat, not as a contradiction
SIGN_NOISE_RAD = 1e-6


def fold_frame_measures(model, key) -> dict:
    """Over all fold states: the largest edge-length change against the key frame (a fold state of
    sheet metal should be an isometry), the largest face planarity, how far the fold angles stored
    for M/V creases are from the angles measured from the coordinates (degrees), how many M/V creases
    bend against their assignment, and the last state's largest measured fold angle (degrees, valley +)."""
    import numpy as np

    from fabkit import measures

    L0 = key.edge_lengths
    to_mesh = model.mesh_edge_index  # model edge -> mesh edge
    crease = np.isin(model.edges_assignment, ["M", "V"])
    strain, planarity, mismatch, wrong_way = 0.0, 0.0, 0.0, 0
    for i in range(model.n_frames):
        m = model.frame_mesh(i)
        strain = max(strain, float(np.max(np.abs(m.edge_lengths / L0 - 1.0))) if len(L0) else 0.0)
        planarity = max(planarity, float(measures.face_planarity(m).max()))
        measured = measures.dihedral_angles(m)[to_mesh]
        stored = model.frame_fold_angle(i)
        known = crease & np.isfinite(stored)
        if np.any(known):
            mismatch = max(mismatch, float(np.degrees(np.max(np.abs(measured[known] - stored[known])))))
        wrong_way += int(np.sum(((model.edges_assignment == "V") & (measured < -SIGN_NOISE_RAD))
                                | ((model.edges_assignment == "M") & (measured > SIGN_NOISE_RAD))))
    d = np.degrees(measures.dihedral_angles(model.frame_mesh(-1)))
    k = int(np.argmax(np.abs(d))) if len(d) else 0
    return {"frames_max_edge_strain": strain, "frames_max_planarity": planarity,
            "frames_max_fold_angle_mismatch_deg": mismatch, "frames_creases_bent_wrong_way": wrong_way,
            "last_frame_max_fold_deg": float(d[k]) if len(d) else 0.0}
