"""`fabkit info FILE`: validate a mesh or FOLD file and print its headline numbers."""
from __future__ import annotations

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

    from fabkit.file_info import summarize

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unused-vertex warnings are in the report instead
        report = summarize(args.file, args.frame, getattr(args, "units", None))
    for line in _lines(report):
        say(args, line)
    write_report(args, report)
    return 0
