"""Wavefront OBJ that keeps the user's polygons, vertex order and per-element data.

Written by hand because the libraries we use either triangulate or reorder (trimesh's OBJ loader
merges and triangulates by default) and none keeps our per-face tags. What we keep:

- vertices and faces in file order; a quad stays a quad; coordinates written with `repr` (the
  shortest string that reads back to the same float), so a round trip is bitwise exact;
- `mesh.face_data` / `mesh.vertex_data` as comment lines other OBJ tools ignore::

      # fabkit face_data strip int64 [0, 0, 1, 1]
      # fabkit vertex_data pinned bool [true, false, ...]

  (`<kind> <name> <numpy dtype> <JSON array>`);
- the unit of the coordinates as `# fabkit unit m` (fabkit always writes metres; `fabkit.io.load`
  reads the line, so a file scaled to metres once is not scaled again).

What we read: `v` (extra values such as w or colours ignored), `f` with `v`, `v/vt`, `v//vn`,
`v/vt/vn` corners and negative (relative) indices, line continuations (`\\`), inline comments; texture,
normal, group, object, smoothing and material statements are ignored. Every error names the file and
the line (and the face or vertex).
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

import numpy as np

from fabkit.errors import InputError, MeshError
from fabkit.io.atomic import atomic_write
from fabkit.io.validate import check_coordinates
from fabkit.mesh import PolyMesh, validate_mesh

__all__ = ["load_obj", "save_obj", "parse_obj", "read_text", "format_obj", "locate_obj_error"]

#: OBJ statements we accept and ignore (geometry we do not use, grouping, materials, free-form).
_IGNORED = frozenset("""vt vn vp l p g o s mg usemtl mtllib maplib usemap lod trace_obj shadow_obj bevel
c_interp d_interp ctech stech cstype deg bmat step curv curv2 surf parm trim hole scrv sp end con call csh
""".split())

_DATA_RE = re.compile(r"#\s*fabkit\s+(face_data|vertex_data)\s+(\S+)\s+(\S+)\s+(.*)$")


def _logical_lines(text: str):
    """Yield `(line_number, line)` with `\\` continuations joined (numbered by their first line)."""
    lines = text.splitlines()
    if not any(line.rstrip().endswith("\\") for line in lines):  # no continuations: the common case
        yield from enumerate(lines, start=1)
        return
    pending, start = "", 0
    for number, raw in enumerate(lines, start=1):
        line = raw.rstrip()
        if not pending:
            start = number
            if line.lstrip().startswith("#"):  # a comment ending in '\\' (a Windows path) continues nothing
                yield number, line
                continue
        if line.endswith("\\"):
            pending += line[:-1] + " "
            continue
        yield start, pending + line
        pending = ""
    if pending:
        yield start, pending


def _parse_data(match: re.Match, number: int, source: str) -> tuple[str, str, np.ndarray]:
    kind, name, dtype, payload = match.groups()
    try:
        dt = np.dtype(dtype)
        if dt.kind not in "biufU":
            raise ValueError(f"dtype {dtype} is not bool, int, float or str")
        values = json.loads(payload)
        arr = np.array(values, dtype=dt)
    except (ValueError, TypeError, OverflowError, RecursionError) as exc:
        raise InputError(f"line {number}: cannot read fabkit {kind} '{name}' ({exc})", source=source) from None
    if arr.ndim == 0:
        raise InputError(f"line {number}: fabkit {kind} '{name}' is not an array", source=source)
    return kind, name, arr


def _parse_index(token: str, n_vertices: int, number: int, source: str) -> int:
    """One face corner (`v`, `v/vt`, `v//vn`, `v/vt/vn`) -> 0-based vertex index."""
    head = token.split("/", 1)[0]
    try:
        if not head.lstrip("-").isdigit():  # int() would also take '1_0' or '+1'
            raise ValueError
        i = int(head)
    except ValueError:
        raise InputError(f"line {number}: face corner {token!r} is not a vertex index", source=source) from None
    if i == 0:
        raise InputError(f"line {number}: face corner {token!r}: OBJ vertex indices start at 1", source=source)
    k = i - 1 if i > 0 else n_vertices + i
    if not 0 <= k < n_vertices:
        rng = f"1..{n_vertices}" if n_vertices else "none defined yet"
        raise InputError(f"line {number}: face refers to vertex {i}, but the vertices so far are {rng}",
                         source=source)
    return k


def parse_obj(text: str, source: str = "<obj>") -> tuple[np.ndarray, list[list[int]], dict, dict, list[int], list[int]]:
    """OBJ text -> `(vertices, faces, face_data, vertex_data, face_lines, vertex_lines)` (no mesh checks)."""
    verts: list[tuple[float, float, float]] = []
    faces: list[list[int]] = []
    face_lines: list[int] = []
    vertex_lines: list[int] = []
    data: dict[str, dict[str, tuple[int, np.ndarray]]] = {"face_data": {}, "vertex_data": {}}
    for number, line in _logical_lines(text):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            m = _DATA_RE.match(stripped)
            if m:
                kind, name, arr = _parse_data(m, number, source)
                data[kind][name] = (number, arr)
            continue
        tokens = stripped.split("#", 1)[0].split()
        if not tokens:
            continue
        key, args = tokens[0], tokens[1:]
        if key == "v":
            if len(args) < 3:
                raise InputError(f"line {number}: vertex needs x y z, got {len(args)} values", source=source)
            try:
                if any("_" in a for a in args[:3]):  # float() would read '1_0' as 10
                    raise ValueError
                verts.append((float(args[0]), float(args[1]), float(args[2])))
            except ValueError:
                raise InputError(f"line {number}: vertex coordinates {' '.join(args[:3])!r} are not numbers",
                                 source=source) from None
            vertex_lines.append(number)
        elif key == "f":
            if len(args) < 3:
                raise InputError(f"line {number}: face {len(faces)} has {len(args)} vertices "
                                 "(a face needs at least 3)", source=source)
            try:  # fast path: plain 1-based indices in range
                if not all(t.isdigit() for t in args):
                    raise ValueError
                face = [int(t) - 1 for t in args]
                if min(face) < 0 or max(face) >= len(verts):
                    raise ValueError
            except ValueError:  # v/vt/vn forms, negative indices, or an error to report
                face = [_parse_index(t, len(verts), number, source) for t in args]
            faces.append(face)
            face_lines.append(number)
        elif key not in _IGNORED:
            shown = key if key.isprintable() and len(key) <= 20 else repr(key[:20])
            raise InputError(f"line {number}: unknown OBJ statement {shown} (is this an OBJ file?)", source=source)
    V = np.array(verts, dtype=np.float64).reshape(-1, 3)
    face_data = _check_counts(data["face_data"], len(faces), "face", source)
    vertex_data = _check_counts(data["vertex_data"], len(verts), "vertex", source)
    return V, faces, face_data, vertex_data, face_lines, vertex_lines


def _check_counts(entries: dict, count: int, kind: str, source: str) -> dict[str, np.ndarray]:
    out = {}
    for name, (number, arr) in entries.items():
        if len(arr) != count:
            raise InputError(f"line {number}: fabkit {kind}_data '{name}' has {len(arr)} entries for "
                             f"{count} {'vertices' if kind == 'vertex' else 'faces'}", source=source)
        out[name] = arr
    return out


def locate_obj_error(message: str, face_lines: list[int], vertex_lines: list[int]) -> str:
    """Add the OBJ line to the first 'face k' / 'vertex k' a mesh error mentions."""
    def face(m: re.Match) -> str:
        k = int(m.group(1))
        return f"{m.group(0)} (line {face_lines[k]})" if 0 <= k < len(face_lines) else m.group(0)

    def vertex(m: re.Match) -> str:
        k = int(m.group(1))
        return f"{m.group(0)} (line {vertex_lines[k]})" if 0 <= k < len(vertex_lines) else m.group(0)

    message = re.sub(r"^face (\d+)", face, message, count=1)
    return re.sub(r"^vertex (\d+)", vertex, message, count=1)


def read_text(path: str | os.PathLike, what: str) -> str:
    """Read a UTF-8 text file; one-line `InputError` for a missing, unreadable or binary file."""
    source = str(path)
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise InputError("no such file", source=source) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a file", source=source) from None
    except OSError as exc:
        raise InputError(f"cannot read file ({exc.strerror})", source=source) from None
    if b"\x00" in raw[:4096]:
        raise InputError(f"binary data, not a text {what} file", source=source)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise InputError(f"not a text {what} file (invalid UTF-8 at byte {exc.start})", source=source) from None


def load_obj(path: str | os.PathLike) -> PolyMesh:
    """Read an OBJ into a validated `PolyMesh` (polygons, vertex order and fabkit data kept).

    Raises `InputError` / `MeshError` naming the file and the line, face or vertex.
    `mesh.warnings` lists non-fatal findings (e.g. unused vertices).
    """
    source = str(path)
    V, faces, face_data, vertex_data, face_lines, vertex_lines = parse_obj(read_text(path, "OBJ"), source)
    if len(faces) == 0:
        raise MeshError(f"no faces ({len(V)} vertices)", source=source)
    try:
        check_coordinates(V, None)
        mesh = PolyMesh(V, faces, face_data=face_data, vertex_data=vertex_data, validate=False)
        mesh.warnings = validate_mesh(mesh, source=source)
    except MeshError as exc:
        raise MeshError(locate_obj_error(exc.message, face_lines, vertex_lines), source=source) from None
    return mesh


def _data_line(kind: str, name: str, arr: np.ndarray) -> str:
    if not name or any(c.isspace() for c in name):
        raise ValueError(f"{kind} name {name!r} must be non-empty without whitespace")
    arr = np.asarray(arr)
    if arr.dtype.kind not in "biufU":
        raise ValueError(f"{kind} '{name}' has dtype {arr.dtype}; OBJ comments keep bool, int, float or str")
    values = json.dumps(arr.tolist(), allow_nan=True, separators=(",", ":"))
    return f"# fabkit {kind} {name} {arr.dtype.str if arr.dtype.kind == 'U' else arr.dtype.name} {values}\n"


def format_obj(mesh: PolyMesh, header: str | None = None) -> str:
    """The OBJ text of a mesh (see module docstring)."""
    out = ["# fabkit OBJ: faces and vertex order as in the model; '# fabkit' lines carry per-element data\n",
           "# fabkit unit m\n"]
    if header:
        out.extend(f"# {line}\n" for line in header.splitlines())
    out.extend(f"v {x!r} {y!r} {z!r}\n" for x, y, z in mesh.vertices.tolist())
    out.extend("f " + " ".join(str(i + 1) for i in face) + "\n" for face in mesh.faces_list())
    out.extend(_data_line("face_data", k, v) for k, v in mesh.face_data.items())
    out.extend(_data_line("vertex_data", k, v) for k, v in mesh.vertex_data.items())
    return "".join(out)


def save_obj(mesh: PolyMesh, path: str | os.PathLike, header: str | None = None) -> None:
    """Write `mesh` as OBJ atomically (full float precision, polygons and data kept)."""
    text = format_obj(mesh, header)
    with atomic_write(path) as fh:
        fh.write(text)
