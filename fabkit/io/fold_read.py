"""FOLD 1.2 reader: lenient where the spec allows, strict where a mistake would bend metal (see
`fabkit.io.fold`); every error is one line naming the file and the element."""
from __future__ import annotations

import json
import math
import os
from typing import Any

import numpy as np

from fabkit.errors import InputError, MeshError
from fabkit.fold import ASSIGNMENTS, FoldFrame, FoldModel, validate_fold_model
from fabkit.io.fold_keys import FABKIT_PREFIX, FOLD_SPEC, JOIN_KEY, TOPOLOGY_KEYS
from fabkit.io.fold_numbers import UNIT_TO_METRES, Num, degrees_to_radians, number_text, to_si
from fabkit.io.obj import read_text
from fabkit.io.validate import check_coordinates
from fabkit.mesh import validate_mesh

__all__ = ["load_fold", "parse_fold"]


# ---- reading: typed field parsers ----------------------------------------------------------------
def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _is_index(x: Any) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def _list(value: Any, key: str, source: str) -> list:
    if not isinstance(value, list):
        raise InputError(f"{key} must be a list, got {type(value).__name__}", source=source)
    return value


def _coords(value: Any, key: str, unit: str, source: str) -> np.ndarray:
    """`vertices_coords` (2D or 3D rows of finite numbers, in `unit`) -> (n, 3) metres."""
    rows = _list(value, key, source)
    if rows and all(type(r) is list for r in rows):
        lengths = {len(r) for r in rows}
        types = {type(c) for r in rows for c in r}
        if lengths <= {2, 3} and types <= {int, Num}:  # fast path: well-formed (checked, not assumed)
            out = np.zeros((len(rows), 3))
            if lengths == {3} or lengths == {2}:
                flat = [to_si(c, unit) for r in rows for c in r]
                out[:, :lengths.pop()] = np.array(flat).reshape(len(rows), -1)
            else:
                for i, r in enumerate(rows):
                    out[i, :len(r)] = [to_si(c, unit) for c in r]
            bad = ~np.all(np.isfinite(out), axis=1)
            if not np.any(bad):
                return check_coordinates(out, source, f"{key}: vertex")
    # slow path: find the first bad entry and say what is wrong with it
    for i, r in enumerate(rows):
        if not isinstance(r, list) or len(r) not in (2, 3) or not all(_is_number(c) for c in r):
            raise InputError(f"{key}[{i}] is {_short(r)}: a vertex needs 2 or 3 numbers", source=source)
        if not all(math.isfinite(to_si(c, unit)) for c in r):
            raise InputError(f"{key}[{i}] is {_short(r)}: coordinates must be finite", source=source)
    return np.zeros((0, 3))


def _index_rows(value: Any, key: str, width: int | None, source: str) -> list[list[int]]:
    rows = _list(value, key, source)
    for i, r in enumerate(rows):
        if not isinstance(r, list) or (width is not None and len(r) != width) or not all(_is_index(c) for c in r):
            need = f"{width} vertex indices" if width else "a list of vertex indices"
            raise InputError(f"{key}[{i}] is {_short(r)}: expected {need} (integers)", source=source)
        if any(not -2**62 < c < 2**62 for c in r):  # would not even fit the int64 index arrays
            raise InputError(f"{key}[{i}] is {_short(r)}: vertex index out of range", source=source)
    return rows


def _assignments(value: Any, key: str, source: str, notes: list[str] | None = None) -> np.ndarray:
    """`edges_assignment` -> letters; lower-case letters (written by some tools) are read as upper case
    with a note."""
    rows = _list(value, key, source)
    lower = 0
    for i, a in enumerate(rows):
        if isinstance(a, str) and len(a) == 1 and a.islower() and a.upper() in ASSIGNMENTS:
            lower += 1
            continue
        if not isinstance(a, str) or a not in ASSIGNMENTS or len(a) != 1:
            raise InputError(f"{key}[{i}] is {_short(a)}: assignment must be one of B, M, V, F, J, U, C",
                             source=source)
    if lower:
        if notes is not None:
            notes.append(f"{lower} lower-case edge assignments read as upper case")
        rows = [a.upper() for a in rows]
    return np.array(rows, dtype="<U1").reshape(-1)


def _angles(value: Any, key: str, source: str) -> np.ndarray:
    """`edges_foldAngle` (degrees or null) -> radians (NaN for null)."""
    rows = _list(value, key, source)
    out = np.full(len(rows), np.nan)
    for i, a in enumerate(rows):
        if a is None:
            continue
        if not _is_number(a) or not math.isfinite(a):
            raise InputError(f"{key}[{i}] is {_short(a)}: a fold angle is a finite number of degrees or null",
                             source=source)
        if abs(a) > 180:
            raise InputError(f"{key}[{i}] is {number_text(a)} deg, outside [-180, 180]", source=source)
        out[i] = degrees_to_radians(a)
    return out


def _none_to_nan(x: Any) -> Any:
    """Nested lists of numbers with JSON nulls -> the same with NaN (None stays elsewhere)."""
    if isinstance(x, list):
        return [_none_to_nan(v) for v in x]
    return np.nan if x is None else x


def _leaves(x: Any):
    if isinstance(x, list):
        for v in x:
            yield from _leaves(v)
    else:
        yield x


def _data_array(value: Any, key: str, source: str) -> np.ndarray:
    """Project data (`faces_fabkit:<name>` etc.) -> a regular numpy array of one kind (numbers, with
    nulls as NaN; booleans; or strings)."""
    rows = _list(value, key, source)
    kinds = {"number" if _is_number(v) else "null" if v is None else type(v).__name__ for v in _leaves(rows)}
    if not (kinds <= {"number", "null"} or kinds == {"bool"} or kinds == {"str"}):
        raise InputError(f"{key} mixes {', '.join(sorted(kinds))}; project data must be numbers, booleans "
                         "or strings", source=source)
    try:
        arr = np.array(_none_to_nan(rows), dtype=np.float64 if "null" in kinds else None)
    except ValueError:
        arr = None
    if arr is None or arr.dtype == object:
        raise InputError(f"{key} is not a regular array (rows of different lengths, or integers beyond 64 bits)",
                         source=source)
    return arr


def _show(x: Any, depth: int = 0) -> str:
    """JSON-like text of a value as the file wrote it (numbers keep their text)."""
    if isinstance(x, Num):
        return x.text
    if isinstance(x, list) and depth < 3:
        return "[" + ",".join(_show(v, depth + 1) for v in x[:8]) + (",...]" if len(x) > 8 else "]")
    try:
        return json.dumps(x, separators=(",", ":"))
    except (TypeError, ValueError, RecursionError):
        return repr(x)


def _short(x: Any) -> str:
    s = _show(x)
    return s if len(s) <= 40 else s[:37] + "..."


def _strings(value: Any, key: str, source: str) -> tuple[str, ...]:
    if isinstance(value, str):
        return (value,)
    rows = _list(value, key, source)
    if not all(isinstance(s, str) for s in rows):
        raise InputError(f"{key} must be a list of strings", source=source)
    return tuple(rows)


def _unit(d: dict, where: str, default: str, source: str) -> str:
    unit = d.get("frame_unit", default)
    if not isinstance(unit, str) or unit not in UNIT_TO_METRES:
        raise InputError(f"{where}frame_unit {_short(unit)} is not a FOLD unit "
                         f"({', '.join(UNIT_TO_METRES)})", source=source)
    return unit


# ---- reading: the model -------------------------------------------------------------------------
def _edges_from_faces(faces: list[list[int]]) -> np.ndarray:
    """Unique face sides, sorted lo < hi (FOLD convert.faces_vertices_to_edges, mesh edge order)."""
    pairs = {(min(a, b), max(a, b)) for f in faces for a, b in zip(f, f[1:] + f[:1])}
    return np.array(sorted(pairs), dtype=np.int64).reshape(-1, 2)


def _default_assignment(edges: np.ndarray, faces: list[list[int]]) -> np.ndarray:
    """Edges on one face -> B, else U (used when a file has no edges_assignment)."""
    count: dict[tuple[int, int], int] = {}
    for f in faces:
        for a, b in zip(f, f[1:] + f[:1]):
            k = (min(a, b), max(a, b))
            count[k] = count.get(k, 0) + 1
    return np.array(["B" if count.get((min(a, b), max(a, b)), 0) == 1 else "U" for a, b in edges.tolist()],
                    dtype="<U1").reshape(-1)


def _namespaced(d: dict, kind: str, source: str) -> dict[str, np.ndarray]:
    prefix = f"{kind}_{FABKIT_PREFIX}"
    return {k[len(prefix):]: _data_array(v, k, source) for k, v in d.items()
            if k.startswith(prefix) and k != JOIN_KEY}


def _plane_rotation(V: np.ndarray, faces: list[list[int]]) -> tuple[np.ndarray | None, str]:
    """Rotation taking a pattern that lies in the x = 0 or y = 0 plane into z = 0 (faces turned to +z).

    Some exporters (Origami Simulator's pleat patterns) store a flat crease pattern in the XZ plane.
    Returns an exact signed permutation matrix, or None when the pattern is not such a case.
    """
    if len(V) == 0 or np.all(V[:, 2] == 0.0):
        return None, ""
    size = float(np.ptp(V, axis=0).max()) or 1.0
    for axis, name in ((1, "XZ plane (y = 0)"), (0, "YZ plane (x = 0)")):
        if np.max(np.abs(V[:, axis])) <= 1e-12 * size:
            normal = np.zeros(3)
            for f in faces:
                P = V[f]
                normal += np.cross(P, np.roll(P, -1, axis=0)).sum(axis=0)
            s = 1.0 if normal[axis] >= 0 else -1.0
            if axis == 1:  # about x: s*y -> +z, i.e. (x, y, z) -> (x, -s z, s y)
                R = np.array([[1.0, 0, 0], [0, 0, -s], [0, s, 0]])
            else:          # about y: s*x -> +z, i.e. (x, y, z) -> (-s z, y, s x)
                R = np.array([[0, 0, -s], [0, 1.0, 0], [s, 0, 0]])
            return R, name
    return None, ""


def _rotate(V: np.ndarray, R: np.ndarray) -> np.ndarray:
    W = V @ R.T
    W[:, 2] = 0.0 if np.all(np.abs(W[:, 2]) <= 1e-12 * (np.ptp(W, axis=0).max() or 1.0)) else W[:, 2]
    return W


def parse_fold(d: Any, source: str = "<fold>", *, repair: bool = False) -> FoldModel:
    """A FOLD dictionary (as loaded from JSON) -> validated `FoldModel` in metres/radians.

    `repair`: a minority of faces wound against the rest is turned (`fabkit.io.hygiene.orient`, said
    in `notes`) instead of refused; a crease pattern wound clockwise throughout is still refused (its
    M/V could be meant from either side)."""
    if not isinstance(d, dict):
        raise InputError(f"a FOLD file is a JSON object, got {type(d).__name__}", source=source)
    notes: list[str] = []
    spec = d.get("file_spec")
    if spec is None:
        notes.append("no file_spec; read as FOLD 1.2")
    elif not _is_number(spec):
        raise InputError(f"file_spec {_short(spec)} must be a number", source=source)
    elif spec > FOLD_SPEC:
        notes.append(f"file_spec {spec} is newer than {FOLD_SPEC}; unknown fields ignored")
    unit = _unit(d, "", "unit", source)
    if "frame_unit" not in d or unit == "unit":
        notes.append("frame_unit 'unit' has no physical size; coordinates taken as metres")
    if "vertices_coords" not in d:
        raise InputError("no vertices_coords (a FOLD file needs vertex coordinates)", source=source)
    if "faces_vertices" not in d:
        raise InputError("no faces_vertices (fabkit and Origami Simulator need faces)", source=source)
    V = _coords(d["vertices_coords"], "vertices_coords", unit, source)
    faces = _index_rows(d["faces_vertices"], "faces_vertices", None, source)
    if repair and faces:
        from fabkit.io.hygiene import orient

        bad = [i for f in faces for i in f if not 0 <= i < len(V)]
        if not bad:
            try:
                turned = orient(V, faces)
            except MeshError:  # non-manifold or non-orientable: the validation below names the element
                turned = None
            if turned is not None and 0 < len(turned.flipped) < len(faces) / 2:  # a few faces against the rest: turn those
                faces = turned.faces
                notes.append(f"{len(turned.flipped)} faces turned so every face is counter-clockwise seen from "
                             f"the front (first: face {int(turned.flipped[0])})")
    if "edges_vertices" in d:
        edges = np.array(_index_rows(d["edges_vertices"], "edges_vertices", 2, source), dtype=np.int64).reshape(-1, 2)
    else:
        edges = _edges_from_faces(faces)
        notes.append("no edges_vertices; edges derived from faces_vertices")
    if "edges_assignment" in d:
        assignment = _assignments(d["edges_assignment"], "edges_assignment", source, notes)
    else:
        assignment = _default_assignment(edges, faces)
        notes.append("no edges_assignment; one-face edges set to B, others to U")
    if JOIN_KEY in d:  # fabkit's own quad diagonals, written as F for other tools: J again
        join = _data_array(d[JOIN_KEY], JOIN_KEY, source)
        if join.shape != assignment.shape:
            raise InputError(f"{JOIN_KEY} has {len(join)} entries for {len(assignment)} edges", source=source)
        assignment = np.where((join == 1) & (assignment == "F"), "J", assignment)
    angle_key = "edges_foldAngle" if "edges_foldAngle" in d else "edges_foldAngles" if "edges_foldAngles" in d else None
    if angle_key == "edges_foldAngles":
        notes.append("edges_foldAngles (FOLD 1.0 name) read as edges_foldAngle")
    if angle_key:
        angle = _angles(d[angle_key], angle_key, source)
    else:
        angle = np.where(np.isin(assignment, ["B", "F", "J", "C"]), 0.0, np.nan)
    frames = _parse_frames(d, V, unit, faces, edges, source)
    R, plane = _plane_rotation(V, faces)
    if R is not None:
        V = _rotate(V, R)
        frames = [FoldFrame(_rotate(f.vertices_coords, R), f.edges_fold_angle, f.classes, f.data, f.attributes)
                  for f in frames]
        notes.append(f"flat pattern in the {plane} rotated into z = 0 (every frame rotated alike)")
    file_data = {k[len("file_" + FABKIT_PREFIX):] if k.startswith("file_" + FABKIT_PREFIX) else k: v
                 for k, v in d.items() if k.startswith("file_" + FABKIT_PREFIX) or (":" in k and "_" + FABKIT_PREFIX not in k)}
    title = d.get("file_title", d.get("frame_title", ""))
    model = FoldModel(
        vertices_coords=V, faces_vertices=faces, edges_vertices=edges, edges_assignment=assignment,
        edges_fold_angle=angle,
        faces_data=_namespaced(d, "faces", source), vertices_data=_namespaced(d, "vertices", source),
        edges_data=_namespaced(d, "edges", source), file_data=file_data, frames=tuple(frames), unit=unit,
        classes=_strings(d.get("frame_classes", []), "frame_classes", source),
        creator=str(d.get("file_creator", "")), title=title if isinstance(title, str) else str(title),
        attributes=_strings(d.get("frame_attributes", []), "frame_attributes", source), notes=tuple(notes),
    )
    warnings = validate_fold_model(model, source=source)
    try:
        mesh_warnings = validate_mesh(model.mesh(validate=False), source=source)
    except MeshError as exc:
        raise exc.with_source(source) from None
    extra = tuple(warnings) + tuple(mesh_warnings)
    if extra:
        object.__setattr__(model, "notes", model.notes + extra)
    return model


def _parse_frames(d: dict, V: np.ndarray, unit: str, faces: list, edges: np.ndarray,
                  source: str) -> list[FoldFrame]:
    """`file_frames` -> FoldFrames (inheritance resolved: each frame gets full coordinates)."""
    if "file_frames" not in d:
        return []
    raw = _list(d["file_frames"], "file_frames", source)
    resolved: list[tuple[np.ndarray, np.ndarray | None, str]] = [(V, None, unit)]  # frame 0 = key frame
    frames: list[FoldFrame] = []
    for i, f in enumerate(raw, start=1):
        where = f"file_frames[{i - 1}] (frame {i}): "
        if not isinstance(f, dict):
            raise InputError(f"{where}must be a JSON object, got {type(f).__name__}", source=source)
        inherit = f.get("frame_inherit", False)
        if not isinstance(inherit, bool):
            raise InputError(f"{where}frame_inherit must be true or false, got {_short(inherit)}", source=source)
        parent = f.get("frame_parent", None)
        if inherit and parent is None:
            raise InputError(f"{where}frame_inherit is true but frame_parent is missing", source=source)
        if parent is not None and (not _is_index(parent) or not 0 <= parent < i):
            raise InputError(f"{where}frame_parent {_short(parent)} must be an earlier frame (0..{i - 1})",
                             source=source)
        for key in TOPOLOGY_KEYS:
            if key in f and f[key] != (d.get(key) if key in d else edges.tolist()):
                raise InputError(f"{where}overrides {key}; fabkit needs every frame to share the key frame's "
                                 "topology", source=source)
        base_V, base_angle, base_unit = resolved[parent] if inherit else (None, None, unit)
        funit = _unit(f, where, base_unit, source)
        if "vertices_coords" in f:
            Vf = _coords(f["vertices_coords"], where + "vertices_coords", funit, source)
        elif base_V is not None:
            Vf = base_V
        else:
            raise InputError(f"{where}has no vertices_coords and does not inherit them", source=source)
        key = "edges_foldAngle" if "edges_foldAngle" in f else "edges_foldAngles" if "edges_foldAngles" in f else None
        angle = _angles(f[key], where + key, source) if key else base_angle
        resolved.append((Vf, angle, funit))
        data = {k[len("frame_" + FABKIT_PREFIX):] if k.startswith("frame_" + FABKIT_PREFIX) else k: v
                for k, v in f.items() if ":" in k}
        frames.append(FoldFrame(Vf, angle, _strings(f.get("frame_classes", []), where + "frame_classes", source),
                                data, _strings(f.get("frame_attributes", []), where + "frame_attributes", source)))
    return frames


def load_fold(path: str | os.PathLike, *, repair: bool = False) -> FoldModel:
    """Read a FOLD file into a validated `FoldModel` (metres, radians; see module docstring);
    `repair` as in `parse_fold`."""
    source = str(path)
    text = read_text(path, "FOLD")
    if not text.strip():
        raise InputError("empty file (a FOLD file is a JSON object)", source=source)
    try:
        d = json.loads(text, parse_float=Num, parse_constant=_reject_constant)
    except json.JSONDecodeError as exc:
        raise InputError(f"invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}", source=source) from None
    except ValueError as exc:
        raise InputError(str(exc), source=source) from None
    except RecursionError:
        raise InputError("JSON nested too deeply to be a FOLD file", source=source) from None
    try:
        return parse_fold(d, source, repair=repair)
    except RecursionError:
        raise InputError("a field is nested too deeply (FOLD arrays are at most two levels)", source=source) from None


def _reject_constant(name: str) -> float:
    raise ValueError(f"{name} is not valid JSON (FOLD numbers must be finite; use null for unknown angles)")
