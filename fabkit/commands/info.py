"""`fabkit info FILE`: validate a mesh or FOLD file and print its headline numbers."""
from __future__ import annotations

from pathlib import Path

from fabkit.commands._common import add_common, say, write_report

HELP = """Read an OBJ or FOLD file, validate it, and print a short summary.

The summary: vertices, faces by size (a quad stays a quad), edges, boundary loops, the angle
defect 2*pi - sum of corner angles over interior vertices (max and mean of its absolute value,
radians; 0 for a developable panel), face planarity (max distance of a face's vertices to its
best-fit plane / mean edge length of the face), the face/vertex tags present, and for FOLD files
the frames, edge assignments and the file's unit. FOLD files are measured in their key frame
(the crease pattern) unless --frame picks a fold state. With fold states, info also gives the
largest relative edge-length change against the key frame over all states (0 for an isometric
fold), their largest face planarity, how
far the fold angles stored for M/V creases are from the angles measured from the coordinates, how
many creases bend against their M/V assignment, and the largest fold angle of the last state.
Units inside are metres.

The panel structure (fabkit.structure) is printed too, measured on the folded geometry (a FOLD
file's last state, or --frame): creases per crease row with their M/V counts and fold-angle range,
strips, the middle row, the clamp face and the grip candidates, and whether each part came from
the '# fabkit' tags or was inferred from the geometry (a crease is a chain of edges from boundary to
boundary along which the fold angle jumps against the bending beside it). 'fabkit tag' writes the
inferred structure as tags you can edit.

Exit codes: 0 ok; 2 bad file (one line naming the file and the problem; --report not written).

Example:
  fabkit info tests/data/fold/pleat-xz.fold --report info.json
"""


def add_arguments(parser) -> None:
    parser.add_argument("file", metavar="FILE", help="a mesh (.obj, .3dm, .svg crease pattern) or FOLD file (.fold)")
    from fabkit.commands._loading import add_units

    add_units(parser)
    parser.add_argument("--frame", type=int, metavar="K",
                        help="FOLD files: measure frame K instead of the key frame (0 = crease pattern, "
                             "1..N = fold states, -1 = the last state)")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.file, "FILE")
    plan.output(args.report, "--report")


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
    from fabkit.structure import panel_structure

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
        "structure": panel_structure(folded, crease_edges=_assigned_creases(model, folded),
                                     crease_letters=_assigned_letters(model, folded)).summary(folded),
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
            report.update(_frame_measures(model, model.mesh(validate=False)))
    return report


def _assigned_creases(model, mesh):
    """Mesh edge ids a FOLD file assigns M, V or U (explicit creases), or None for OBJ files or FOLD
    files that assign none."""
    import numpy as np

    if model is None:
        return None
    ids = model.mesh_edge_index[np.isin(model.edges_assignment, ["M", "V", "U"])]
    ids = ids[ids >= 0]
    return ids if len(ids) else None


def _assigned_letters(model, mesh):
    """(E,) the FOLD file's assignment letter of every mesh edge ("" where it has none), or None for
    OBJ files."""
    import numpy as np

    if model is None:
        return None
    letters = np.full(mesh.n_edges, "", dtype="<U1")
    idx = np.asarray(model.mesh_edge_index)
    ok = idx >= 0
    letters[idx[ok]] = np.asarray(model.edges_assignment)[ok]
    return letters


#: a crease bent the wrong way by less than this (radians) counts as flat, not as a contradiction
SIGN_NOISE_RAD = 1e-6


def _frame_measures(model, key) -> dict:
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


def _lines(r: dict) -> list[str]:
    faces = ", ".join(f"{c} {k}" for k, c in r["faces_by_size"].items())
    out = [
        f"{r['file']}: {r['kind'].upper()}, {r['vertices']} vertices, {r['faces']} faces ({faces}), "
        f"{r['edges']} edges, {r['boundary_loops']} boundary loop(s)",
        f"  angle defect |2pi - sum|: max {r['max_abs_angle_defect_rad']:.3g} rad, "
        f"mean {r['mean_abs_angle_defect_rad']:.3g} rad over {r['interior_vertices']} interior vertices",
        f"  planarity (plane distance / edge): max {r['max_planarity']:.3g}, mean {r['mean_planarity']:.3g}",
        f"  size {r['size_m']:.4g} m (bounding-box diagonal), edges {r['min_edge_m']:.4g}..{r['max_edge_m']:.4g} m",
        f"  tags: faces [{', '.join(r['face_tags'])}], vertices [{', '.join(r['vertex_tags'])}]"
        + (f", edges [{', '.join(r['edge_tags'])}]" if r.get("edge_tags") else ""),
    ]
    if r["kind"] == "fold":
        asg = " ".join(f"{k}:{v}" for k, v in r["edges_assignment"].items())
        if r["measured_frame"]:
            out.insert(1, f"  (measured in frame {r['measured_frame']} of {r['frames']}, a fold state)")
        out.append(f"  FOLD: {r['frames']} fold state frame(s), file unit {r['unit']!r} (shown in metres), "
                   f"classes {r['frame_classes']}, assignments {asg}")
        if r["frames"]:
            out.append(f"  fold states: max edge-length change {r['frames_max_edge_strain']:.3g} (relative), "
                       f"max planarity {r['frames_max_planarity']:.3g}, "
                       f"last state's largest fold {r['last_frame_max_fold_deg']:.4g} deg")
            out.append(f"  M/V creases: stored vs measured fold angle differ by up to "
                       f"{r['frames_max_fold_angle_mismatch_deg']:.3g} deg; "
                       f"{r['frames_creases_bent_wrong_way']} crease-frame(s) bent against their assignment")
        out.extend(f"  note: {n}" for n in r["notes"])
    out.extend(structure_lines(r["structure"]))
    if r["kind"] != "fold":
        out.extend(f"  note: {n}" for n in r["loaded"]["notes"])
    out.extend(f"  warning: {w}" for w in r["warnings"])
    return out


def structure_lines(st: dict) -> list[str]:
    """The panel structure summary (`PanelStructure.summary`) as indented lines."""
    src = st["source"]
    where = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in src.items())
    n = len(st["creases"])
    out = [f"  structure ({where}): {st['strips']} strip(s), {n} crease row(s), {st['crease_edges']} crease edges "
           f"in {st['chains']} chain(s)" + (f", {st['columns']} columns" if st["columns"] else "")]
    for c in st["creases"]:
        mv = ", ".join(f"{k} {c[k]}" for k in "MVU" if c[k])
        out.append(f"    crease {c['row']} (strips {c['between_strips'][0]}|{c['between_strips'][1]}): {c['edges']} "
                   f"edges, {mv}, fold {c['min_fold_deg']:.2f}..{c['max_fold_deg']:.2f} deg")
    out.append(f"    middle row: faces {st['middle_row']}; clamp face {st['clamp_face']}; "
               f"grip candidates {st['grip_faces']}; driven creases {len(st['middle_creases'])}")
    if st["noise_deg"] is not None:
        out.append(f"    inferred: fold-angle noise {st['noise_deg']:.3g} deg, a crease jumps by more than "
                   f"{st['strong_jump_deg']:.3g} deg")
    return out


def run(args) -> int:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unused-vertex warnings are in the report instead
        report = summarize(args.file, args.frame, getattr(args, "units", None))
    for line in _lines(report):
        say(args, line)
    write_report(args, report)
    return 0
