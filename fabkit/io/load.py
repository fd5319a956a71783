"""One loader for every command that reads a panel: any format in, a clean `PolyMesh` in metres out.

`load_panel(path, units=None, state=...)` reads OBJ, FOLD, Rhino `.3dm` or an SVG crease pattern,
converts the coordinates to metres (the file's unit, `--units`, or metres assumed with a note when
the size suggests another unit), and runs the hygiene steps of `fabkit.io.hygiene` (weld, winding,
triangle pairs back to quads). Everything it did is in the returned `LoadInfo`: unit and where it
came from, notes, how many vertices were welded with the old -> new index map, how many quads were
re-merged with the face map, which faces were turned.

FOLD crease assignments are kept as face tags: `face_data["strip"]` numbers the pieces between the
creases (M, V, U edges) when the file has no strip tags (`fabkit.structure.strips_of_creases`), and `face_data["assignment"]` holds, per face,
one FOLD letter per side (side k runs from corner k to corner k+1), so M/V survive OBJ and `.3dm`.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from fabkit.errors import InputError, MeshError
from fabkit.io import hygiene
from fabkit.io.units import UNITS, scale_to_metres, unit_note
from fabkit.io.validate import check_coordinates
from fabkit.mesh import PolyMesh, validate_mesh

__all__ = ["load_panel", "load_fold_model", "LoadInfo", "PANEL_SUFFIXES", "STATES", "side_assignments"]

#: suffixes `load_panel` reads
PANEL_SUFFIXES = (".obj", ".fold", ".3dm", ".svg")
#: which geometry of a FOLD file: its last fold state (the key frame if it has none), the key frame
#: (crease pattern), or the first fold state
STATES = ("folded", "key", "first")

_OBJ_UNIT = re.compile(r"^#\s*fabkit\s+unit\s+(\S+)\s*$", re.MULTILINE)


@dataclass(frozen=True, eq=False)
class LoadInfo:
    """What `load_panel` read and did (see module docstring); `to_report()` for JSON reports."""

    path: str
    format: str
    unit: str
    unit_source: str
    size_m: float
    notes: tuple = ()
    welded: int = 0
    vertex_map: np.ndarray | None = None
    merged_quads: int = 0
    face_map: tuple | None = None
    flipped_faces: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    state: str = "mesh"
    model: object = None

    def to_report(self) -> dict:
        return {"file": self.path, "format": self.format, "unit": self.unit, "unit_source": self.unit_source,
                "size_m": self.size_m, "welded_vertices": self.welded, "merged_quads": self.merged_quads,
                "flipped_faces": int(len(self.flipped_faces)), "state": self.state, "notes": list(self.notes)}


def _check_units(units: str | None) -> None:
    if units is not None and units not in UNITS:
        raise InputError(f"unknown unit {units!r}: use one of {', '.join(UNITS)}", source="--units")


def _resolve_unit(file_unit: str | None, units: str | None, source: str) -> tuple[str, str]:
    """(unit, how) from the file's declared unit and `--units`; a contradiction is refused."""
    if units is not None:
        if file_unit is not None and file_unit != units:
            raise InputError(f"the file declares its unit as {file_unit} but --units {units} was given "
                             "(drop --units, or fix the file)", source=source)
        return units, "from --units"
    if file_unit is not None:
        return file_unit, "from the file"
    return "m", "assumed"


def _obj_raw(path: str):
    from fabkit.io.obj import parse_obj, read_text

    text = read_text(path, "OBJ")
    V, faces, face_data, vertex_data, face_lines, vertex_lines = parse_obj(text, path)
    m = _OBJ_UNIT.search(text)
    unit = m.group(1) if m else None
    if unit is not None and unit not in UNITS:
        raise InputError(f"'# fabkit unit {unit}' is not one of {', '.join(UNITS)}", source=path)
    ours = text.startswith("# fabkit OBJ")  # written by fabkit: clean by construction, ids kept exactly
    return V, faces, face_data, vertex_data, unit, (face_lines, vertex_lines), ours


def _finish(path: str, fmt: str, V, faces, face_data, vertex_data, unit: str, how: str, notes: list,
            other_states: list | None = None, weld: bool = True, state: str = "mesh", model=None,
            sides: dict | None = None, lines: tuple | None = None) -> tuple[PolyMesh, LoadInfo]:
    """Units already applied: weld, orient, merge, build and validate the mesh. `lines`: OBJ
    (face_lines, vertex_lines), so errors found before renumbering name the file's line."""
    if len(faces) == 0:
        raise MeshError(f"no faces ({len(V)} vertices)", source=path)
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)

    def located(exc: MeshError) -> MeshError:
        if lines is None or exc.source:
            return exc.with_source(path)
        from fabkit.io.obj import locate_obj_error

        return MeshError(locate_obj_error(exc.message, *lines), source=path)

    try:  # finite and fabrication-sized, before any geometry is measured
        check_coordinates(V, None)
    except MeshError as exc:
        raise located(exc) from None

    try:  # the file as written: structure and coordinates, errors named by its lines
        validate_mesh(PolyMesh(V, faces, validate=False), source=None)
    except MeshError as exc:
        msg = exc.message
        if not ("inconsistent orientation" in msg or "non-manifold" in msg):
            raise located(exc) from None
    n0 = len(V)
    vertex_map = None
    welded = 0
    try:
        if weld:
            w = hygiene.weld(V, faces)
            if w.merged:
                welded, vertex_map = w.merged, w.index_map
                notes.append(f"welded {w.merged} coincident vertices (within {w.tolerance:.3g} m): "
                             f"{n0} -> {len(w.kept)} vertices, ids renumbered in their original order")
                V, faces = w.vertices, w.faces
                vertex_data = {k: np.asarray(a)[w.kept] for k, a in vertex_data.items()}
                other_states = [np.asarray(g)[w.kept] for g in (other_states or [])]
                if sides is not None:
                    sides = {(int(w.index_map[a]), int(w.index_map[b])): c for (a, b), c in sides.items()}
        o = hygiene.orient(V, faces)
        if len(o.flipped):
            notes.append(f"{len(o.flipped)} faces turned so every face is counter-clockwise seen from the front "
                         f"(first: face {int(o.flipped[0])})")
        faces = o.faces
        m = hygiene.merge_triangle_pairs(V, faces, geometry=other_states)
    except MeshError as exc:
        raise located(exc) if not welded else exc.with_source(path) from None
    face_map = None
    if m.merged:
        face_map = m.face_map
        notes.append(f"merged {m.merged} coplanar triangle pairs back into quads: {len(faces)} -> {len(m.faces)} "
                     "faces")
        first = np.array([g[0] for g in m.face_map])
        face_data = {k: np.asarray(a)[first] for k, a in face_data.items() if k != "assignment"}
        faces = m.faces
    if sides is not None:
        face_data = {**face_data, **side_assignments(faces, sides)}
    try:
        mesh = PolyMesh(V, faces, face_data=face_data, vertex_data=vertex_data, validate=False)
        if sides is not None and "strip" not in face_data:  # the file's strip tags win
            strip = _strips_of_sides(mesh, sides)
            if strip is not None:
                mesh = PolyMesh(V, faces, face_data={**face_data, "strip": strip}, vertex_data=vertex_data,
                                validate=False)
        mesh.warnings = validate_mesh(mesh, source=path)
    except MeshError as exc:
        raise located(exc) if not (welded or m.merged) else exc.with_source(path) from None
    size = mesh.size
    note = unit_note(size, unit, how)
    if note:
        notes.append(note)
    info = LoadInfo(path=path, format=fmt, unit=unit, unit_source=how, size_m=size, notes=tuple(notes),
                    welded=welded, vertex_map=vertex_map, merged_quads=m.merged, face_map=face_map,
                    flipped_faces=o.flipped, state=state, model=model)
    return mesh, info


def side_assignments(faces: list, sides: dict) -> dict[str, np.ndarray]:
    """`{(u, v): letter}` edge assignments -> `face_data["assignment"]`: one FOLD letter per face
    side (side k from corner k to corner k+1; U where the file says nothing)."""
    letters = ["".join(sides.get((min(a, b), max(a, b)), "U") for a, b in zip(f, f[1:] + f[:1])) for f in faces]
    return {"assignment": np.array(letters)}


def _strips_of_sides(mesh: PolyMesh, sides: dict) -> np.ndarray | None:
    """`face_data["strip"]` from a file's crease assignments (interior M, V or U edges), numbered
    by `fabkit.structure.strips_of_creases` (the same strips as for creases inferred from the
    geometry); None when no interior edge is a crease."""
    from fabkit.structure import strips_of_creases

    crease = np.array([sides.get((int(min(u, v)), int(max(u, v))), "") in ("M", "V", "U") for u, v in mesh.edges],
                      dtype=bool) & ~mesh.topology.boundary_edge_mask
    return strips_of_creases(mesh, crease) if crease.any() else None


def _fold_sides(model) -> dict:
    return {(int(min(u, v)), int(max(u, v))): str(c) for (u, v), c in
            zip(model.edges_vertices.tolist(), model.edges_assignment.tolist())}


def _scale_model(model, factor: float):
    """A FoldModel with every coordinate multiplied by `factor` (for a unitless file and --units)."""
    import dataclasses

    from fabkit.fold import FoldFrame

    frames = tuple(FoldFrame(f.vertices_coords * factor, f.edges_fold_angle, f.classes, f.data, f.attributes)
                   for f in model.frames)
    return dataclasses.replace(model, vertices_coords=model.vertices_coords * factor, frames=frames)


def load_fold_model(path: str | os.PathLike, units: str | None = None):
    """A FOLD file as a `FoldModel` in metres, with the unit rules of `load_panel` -> `(model, LoadInfo)`.

    Lower-case assignments are read, faces wound the wrong way are turned (both noted)."""
    from fabkit.io.fold import load_fold

    source = str(path)
    _check_units(units)
    model = load_fold(path, repair=True)
    notes = list(model.notes)
    declared = None if model.unit == "unit" else model.unit
    if declared is not None and declared not in UNITS:
        declared_ok = declared  # a FOLD unit outside --units (um, pt): read exactly, not overridable
        if units is not None:
            raise InputError(f"the file declares its unit as {declared_ok} but --units {units} was given",
                             source=source)
        unit, how = declared_ok, "from the file"
    else:
        unit, how = _resolve_unit(declared, units, source)
        if declared is None and unit != "m":
            model = _scale_model(model, UNITS[unit])
            notes = [n for n in notes if not n.startswith("frame_unit 'unit'")]
    V = model.frames[-1].vertices_coords if model.n_frames else model.vertices_coords
    size = float(np.linalg.norm(np.ptp(V, axis=0))) if len(V) else 0.0
    note = unit_note(size, unit, how) if unit in UNITS else None
    if note:
        notes.append(note)
    info = LoadInfo(path=source, format="fold", unit=unit, unit_source=how, size_m=size, notes=tuple(notes),
                    state="model", model=model)
    return model, info


def load_panel(path: str | os.PathLike, units: str | None = None, state: str = "folded",
               weld: bool = True) -> tuple[PolyMesh, LoadInfo]:
    """Read a panel from `.obj`, `.fold`, `.3dm` or `.svg` -> `(mesh in metres, LoadInfo)`.

    `units` (m, mm, cm, in) is the unit of a file that does not declare one; a file that declares a
    different unit is refused. `state` picks a FOLD file's geometry (see `STATES`). Raises
    `InputError` / `MeshError` naming the file.
    """
    source = str(path)
    _check_units(units)
    if state not in STATES:
        raise ValueError(f"state must be one of {STATES}, got {state!r}")
    suffix = Path(path).suffix.lower()
    if suffix == ".obj":
        V, faces, face_data, vertex_data, declared, lines, ours = _obj_raw(source)
        unit, how = _resolve_unit(declared, units, source)
        return _finish(source, "obj", scale_to_metres(V, unit), faces, face_data, vertex_data, unit, how, [],
                       weld=weld and not ours, lines=lines)
    if suffix == ".fold":
        model, info = load_fold_model(path, units)
        if state == "key" or model.n_frames == 0:
            V, chosen = model.vertices_coords, "key frame"
        else:
            i = -1 if state == "folded" else 0
            V = model.frames[i].vertices_coords
            chosen = f"frame {model.n_frames if i == -1 else 1} of {model.n_frames}"
        # triangle pairs merge only when planar in every state, so each state gets the same faces
        others = [model.vertices_coords] + [f.vertices_coords for f in model.frames]
        notes = list(info.notes)
        face_data = dict(model.faces_data)
        face_data.pop("polygon", None)  # the triangle -> polygon map no longer applies once re-merged
        faces = [list(f) for f in model.faces_vertices]
        mesh, out = _finish(source, "fold", V, faces, face_data, dict(model.vertices_data), info.unit,
                            info.unit_source, notes, other_states=others, weld=False, state=chosen, model=model,
                            sides=_fold_sides(model))
        return mesh, out
    if suffix == ".3dm":
        from fabkit.io.rhino import read_3dm

        raw = read_3dm(source)
        unit, how = _resolve_unit(raw.unit, units, source)
        return _finish(source, "3dm", scale_to_metres(raw.vertices, unit), raw.faces, raw.face_data,
                       raw.vertex_data, unit, how, list(raw.notes), weld=weld)
    if suffix == ".svg":
        from fabkit.io.svg_cp import read_svg_crease_pattern

        raw = read_svg_crease_pattern(source)
        unit, how = _resolve_unit(raw.unit, units, source)
        return _finish(source, "svg", scale_to_metres(raw.vertices, unit), raw.faces, {}, {}, unit, how,
                       list(raw.notes), weld=False, sides=raw.sides)
    raise InputError(f"cannot read '{suffix or 'no suffix'}' as a panel: use {', '.join(PANEL_SUFFIXES)}",
                     source=source)
