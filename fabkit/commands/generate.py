"""fabkit generate: procedural input meshes (presets) written as OBJ with their tags."""
from __future__ import annotations

from fabkit.commands._common import add_common, say, write_report
from fabkit import presets
from fabkit.presets import PRESETS

HELP = """Write a procedural input mesh.

Presets (parameters in brackets, defaults after '='; lengths in metres, angles in degrees):
  reflect  exactly developable curved-crease panel by the reflection method
           [radius=0.5 arc=60 width=0.6 creases=1 offset fold=60 skew=0 offset2 fold2 skew2
            columns=24 rows=4]; offset defaults to width/2 (one crease) or width/4 (two creases),
           offset2 to 3*width/5, fold2 to -fold, skew2 to skew
  trifold  the tri-fold panel of the paper's Fig. 3 (bevel a box, delete its faces, extrude the
           hole borders, Catmull-Clark with sharp creases, keep one edge band, retopologise)
           [length=1.6 depth=0.8 height=depth bevel=0.2 extrude=0.12 resolution=16 rows=1]; the box
           is length x depth x height, the panel about bevel*length long, resolution = columns
  canopy   the multi-panel workflow's wave-like canopy low-poly (3 vertices across: planar arcs
           after Catmull-Clark; input of `fabkit panels`) [length=6 width=2.4 height=2.2 arch=0.5
           wave=0.35 waves=2 stations=9 sweep=0.3]
  pleated  a vault pleated by alternating mountain/valley curved creases along planar arcs, exactly
           developable (reflection method), one crease per band (input of `fabkit panels`, which puts
           each crease inside its band's panels) [rows=14 fold=40 radius=1.5 arc=90 length=6
           columns=42 rows_per_band=8]
  cube     a closed cube [size=1 subdivide=0]
  prism    a closed right prism over a regular polygon [sides=6 radius=0.5 height=1 subdivide=0]
  grid     a flat quad grid in z=0 [nx=10 ny=10 size_x=1 size_y=1]

Prints vertices, faces, max |angle defect| and max planarity of the written mesh.

Example:
  fabkit generate reflect -o r.obj --creases 2 --fold 50 --columns 40 --png r.png
"""


def add_arguments(parser) -> None:
    parser.add_argument("preset", metavar="PRESET", help=f"one of: {', '.join(PRESETS)}")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.obj", help="output mesh (.obj keeps the tags)")
    parser.add_argument("--png", metavar="F.png", help="picture: 3D view with strips and creases (M red, V blue), "
                                                      "and the development when the preset has one")
    names: dict[str, list[str]] = {}
    for preset, (_, params) in PRESETS.items():
        for name, spec in params.items():
            default = "" if spec.default is None else f", default {spec.default:g}"
            names.setdefault(name, []).append(f"{preset}: {spec.help}{default}")
    for name, texts in names.items():
        parser.add_argument(f"--{name.replace('_', '-')}", dest=f"p_{name}", metavar="VALUE", default=None,
                            help="; ".join(texts))
    add_common(parser)


def plan_files(args, plan) -> None:
    plan.output(args.output, "-o")
    plan.output(args.png, "--png")
    plan.output(args.report, "--report")


def run(args) -> int:
    import numpy as np

    from fabkit import measures
    from fabkit.io import save_mesh

    preset = args.preset
    mesh, p = presets.build_preset(preset, **{k[2:]: v for k, v in vars(args).items()
                                              if k.startswith("p_") and v is not None})
    save_mesh(mesh, args.output)
    if args.png:
        from fabkit.generate.plot import plot_generated

        plot_generated(mesh, args.png, title=f"fabkit generate {preset}")
    s = measures.summary(mesh)
    kinds = {int(k): int(c) for k, c in enumerate(np.bincount(mesh.face_sizes)) if c}
    report = {"preset": preset, "params": p, "output": str(args.output), "png": args.png, **s,
              "face_sizes": kinds, "tags": sorted(mesh.face_data) + sorted(mesh.vertex_data)}
    if "strip" in mesh.face_data:
        from fabkit.structure import panel_structure

        structure = panel_structure(mesh)
        report["strips"] = structure.n_strips
        report["creases"] = [{k: c[k] for k in ("between_strips", "edges", "min_fold_deg", "max_fold_deg")}
                             for c in structure.summary(mesh)["creases"]]
    write_report(args, report)
    say(args, f"{preset}: {s['vertices']} vertices, {s['faces']} faces "
              f"({', '.join(f'{c}x{k}-gon' for k, c in kinds.items())}) -> {args.output}")
    say(args, f"max |angle defect| {s['max_abs_angle_defect_rad']:.3g} rad, max planarity {s['max_planarity']:.3g}")
    for c in report.get("creases", []):
        say(args, f"crease {c['between_strips'][0]}|{c['between_strips'][1]}: {c['edges']} edges, fold "
                  f"{c['min_fold_deg']:.2f}..{c['max_fold_deg']:.2f} deg")
    return 0
