"""The FOLD keys and versions fabkit writes and reads (`fabkit.io.fold` describes the layout)."""
from __future__ import annotations

__all__ = ["FOLD_SPEC", "WRITE_UNIT", "FABKIT_PREFIX", "JOIN_KEY", "FLAVOURS", "TOPOLOGY_KEYS"]

FOLD_SPEC = 1.2
WRITE_UNIT = "mm"

#: project data keys are `<kind>_fabkit:<name>` (faces, vertices, edges, file, frame)
FABKIT_PREFIX = "fabkit:"
#: edges fabkit holds as J (quad diagonals) are written as F with this 0/1 marker (flavour "compatible")
JOIN_KEY = "edges_fabkit:join"
#: `save_fold` flavours: "compatible" (default) writes only the assignments Origami Simulator's importer
#: knows (B M V F U C: J diagonals as F, marked in `edges_fabkit:join` so fabkit reads them back as J);
#: "spec" writes J as the FOLD specification has it.
FLAVOURS = ("compatible", "spec")
#: the keys that give a FOLD file its topology
TOPOLOGY_KEYS = ("edges_vertices", "faces_vertices")
