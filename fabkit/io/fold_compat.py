"""What Origami Simulator's FOLD importer needs, checked on a FOLD dictionary.

The rules are read from its source (amandaghassaei/OrigamiSimulator, `js/importer.js`,
`js/pattern.js`, `js/model.js`):

- the file must have all of `vertices_coords`, `edges_vertices`, `edges_assignment` and
  `faces_vertices` (importer.js refuses it otherwise), none of them empty (model.js warns and stops);
- every assignment is one of U, V, M, B, F, C: model.js files edges into a table keyed by exactly
  these letters, so any other letter (J, lower case) throws and the file never loads;
- `edges_foldAngle` (or FOLD 1.0's `edges_foldAngles`), when present, has one entry per edge, each
  a number in [-180, 180] or null; faces that are not triangles are triangulated by pushing onto
  it, so it must be a list whenever a face has more than three corners and the file has angles;
- vertex coordinates are 2 or 3 numbers (2D ones are read as (x, 0, y));
- face corners and edge ends are indices of existing vertices, faces have at least 3 corners;
- at most 65,535 vertices (model.js indexes vertices with 16-bit integers);
- only the key frame is read: `file_frames` are ignored, so the key frame must be a usable model.
"""
from __future__ import annotations

from typing import Any

__all__ = ["origami_simulator_problems", "OSIM_ASSIGNMENTS", "OSIM_REQUIRED"]

OSIM_ASSIGNMENTS = frozenset("UVMBFC")
OSIM_REQUIRED = ("vertices_coords", "edges_vertices", "edges_assignment", "faces_vertices")
OSIM_MAX_VERTICES = 65535


def _number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def origami_simulator_problems(d: Any) -> list[str]:
    """Reasons Origami Simulator would not load the FOLD dictionary `d` (empty list: it loads)."""
    if not isinstance(d, dict):
        return ["not a JSON object"]
    out = [f"missing {k}" for k in OSIM_REQUIRED if k not in d]
    if out:
        return out
    V, E, A, F = (d[k] for k in OSIM_REQUIRED)
    for k in OSIM_REQUIRED:
        if not isinstance(d[k], list) or not d[k]:
            out.append(f"{k} is empty or not a list")
    if out:
        return out
    n = len(V)
    if n > OSIM_MAX_VERTICES:
        out.append(f"{n} vertices: more than the {OSIM_MAX_VERTICES} a 16-bit index can address")
    bad = [i for i, v in enumerate(V) if not (isinstance(v, list) and len(v) in (2, 3) and all(map(_number, v)))]
    if bad:
        out.append(f"vertices_coords[{bad[0]}] is not 2 or 3 numbers")
    if len(A) != len(E):
        out.append(f"edges_assignment has {len(A)} entries for {len(E)} edges")
    unknown = sorted({a for a in A if a not in OSIM_ASSIGNMENTS}, key=str)
    if unknown:
        out.append(f"assignments {unknown} are not among U V M B F C (the importer throws on them)")
    bad = [i for i, e in enumerate(E) if not (isinstance(e, list) and len(e) == 2
                                            and all(isinstance(x, int) and 0 <= x < n for x in e))]
    if bad:
        out.append(f"edges_vertices[{bad[0]}] is not two vertex indices")
    bad = [i for i, f in enumerate(F) if not (isinstance(f, list) and len(f) >= 3
                                            and all(isinstance(x, int) and 0 <= x < n for x in f))]
    if bad:
        out.append(f"faces_vertices[{bad[0]}] is not a face of >= 3 vertex indices")
    key = "edges_foldAngle" if "edges_foldAngle" in d else "edges_foldAngles" if "edges_foldAngles" in d else None
    if key is not None:
        angles = d[key]
        if not isinstance(angles, list) or len(angles) != len(E):
            out.append(f"{key} must have one entry per edge ({len(E)})")
        else:
            bad = [i for i, a in enumerate(angles) if not (a is None or (_number(a) and -180 <= a <= 180))]
            if bad:
                out.append(f"{key}[{bad[0]}] is not a number in [-180, 180] or null")
    return out
