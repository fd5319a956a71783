"""FOLD 1.2 reader and writer (the one boundary where millimetres/degrees become metres/radians).

Written by hand: FOLD is plain JSON and the only Python FOLD package on PyPI is a box-pleating
tool; the reference implementation is JavaScript (npm `fold`), which the tests use to read our files.

Layout we write (docs/file-formats.md "FOLD 1.2"):

- key frame = crease pattern: `frame_classes ["creasePattern"]`, `frame_unit "mm"`,
  `vertices_coords`, `edges_vertices`, `edges_assignment`, `edges_foldAngle` (degrees, valley +,
  `null` for unknown), `faces_vertices` (counter-clockwise polygons as in the mesh);
- every fold state is a `file_frames` child with `frame_parent: 0`, `frame_inherit: true`,
  `frame_classes ["foldedForm"]`, `frame_attributes ["3D"]`, overriding `vertices_coords` (and
  `edges_foldAngle` when the state has its own angles);
- `frame_attributes` measured from the content (`2D` when every z is 0, else `3D`; `cuts`/`joins`);
- quad diagonals (`J` inside) written as `F` with `edges_fabkit:join` = 1, so Origami Simulator's
  importer (which knows only U V M B F C) loads the file; read back as `J` (`flavour="spec"` writes J);
- `file_spec 1.2`, `file_creator "fabkit"`, `file_classes ["animation"]` when there are frames;
- project data as `faces_fabkit:<name>`, `vertices_fabkit:<name>`, `edges_fabkit:<name>`,
  `file_fabkit:<name>`, `frame_fabkit:<name>`.

Reading is lenient where the spec allows (2D coordinates, any `frame_unit`, `edges_foldAngles` of
spec 1.0, `null` angles, missing edges derived from faces, lower-case assignments) and strict where a mistake would bend
metal (types, lengths, indices, assignments, angle signs); every error is one line naming the file
and the element. Remarks made while reading (unit assumptions, a pattern rotated into z = 0) are in
`model.notes`.

The writer is `fabkit.io.fold_write`, the reader `fabkit.io.fold_read`, the keys `fabkit.io.fold_keys`;
this module is their one import place.
"""
from __future__ import annotations

from fabkit.io.fold_keys import FLAVOURS, FOLD_SPEC, WRITE_UNIT
from fabkit.io.fold_numbers import UNIT_TO_METRES
from fabkit.io.fold_read import load_fold, parse_fold
from fabkit.io.fold_write import fold_text, fold_to_json, save_fold

__all__ = ["load_fold", "save_fold", "parse_fold", "fold_to_json", "fold_text", "UNIT_TO_METRES", "FOLD_SPEC",
           "FLAVOURS", "WRITE_UNIT"]
