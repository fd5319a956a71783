"""`fabkit tag IN.obj -o OUT.obj`: write the panel structure as explicit `# fabkit` tags."""
from __future__ import annotations

from pathlib import Path

from fabkit.commands._common import add_common, say, write_report

HELP = """Write IN with its panel structure as explicit '# fabkit' tags the user can read and edit.

The structure (fabkit.structure) is what every stage uses: face_data strip (the developable strips
between creases: a crease is an edge between faces of different strips), middle (one face per
strip in the middle column: refold drives its creases, the toolpath grips one of them, the middle
strip's is clamped) and, on quad meshes, column. Tags IN already has are kept as they are and win;
what is missing is inferred from the folded geometry (see 'fabkit info'). --infer ignores IN's tags
and infers everything. Vertices, faces and their order are unchanged.

Exit codes: 0 ok; 2 bad input (nothing written).

Example:
  fabkit tag designer_panel.obj -o tagged.obj && fabkit info tagged.obj
"""


def add_arguments(parser) -> None:
    parser.add_argument("input", metavar="IN.obj", help="folded panel (OBJ)")
    parser.add_argument("-o", "--output", metavar="OUT.obj", required=True, help="the same mesh with structure tags")
    parser.add_argument("--infer", action="store_true", help="ignore IN's strip/column/middle tags and infer them")
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.input(args.input, "IN")
    plan.output(args.output, "-o")
    plan.output(args.report, "--report")


def run(args) -> int:
    from fabkit.commands.info import structure_lines
    from fabkit.errors import InputError
    from fabkit.io.obj import load_obj, save_obj
    from fabkit.mesh import PolyMesh
    from fabkit.structure import TAG_NAMES, panel_structure

    out = Path(args.output)
    if out.resolve() == Path(args.input).resolve():
        raise InputError("the output would overwrite the input", source=args.output)
    if not out.parent.is_dir():
        raise InputError("output directory does not exist", source=args.output)
    if out.suffix.lower() != ".obj":
        raise InputError("tags are written to an .obj file", source=args.output)
    mesh = load_obj(args.input)
    if args.infer:
        mesh = PolyMesh(mesh.vertices, topology=mesh.topology, vertex_data=mesh.vertex_data, validate=False,
                        face_data={k: v for k, v in mesh.face_data.items() if k not in TAG_NAMES})
    structure = panel_structure(mesh)
    tagged = structure.with_tags(mesh)
    save_obj(tagged, out)
    summary = structure.summary(mesh)
    write_report(args, {"format": "fabkit.tag/1", "input": str(args.input), "output": str(out), "ok": True,
                        "problems": [], "structure": summary})
    say(args, f"{args.input} -> {out}: tags {', '.join(sorted(structure.face_data()))}")
    for line in structure_lines(summary):
        say(args, line)
    return 0
