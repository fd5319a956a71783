"""FOLD 1.2 writer: a `FoldModel` (metres, radians) as FOLD text in millimetres and degrees, in the
layout `fabkit.io.fold` describes. Written by hand (see there why)."""
from __future__ import annotations

import json
import os
from typing import Any

import numpy as np

from fabkit.fold import FoldFrame, FoldModel, validate_fold_model
from fabkit.io.atomic import atomic_write
from fabkit.io.fold_keys import FABKIT_PREFIX, FLAVOURS, FOLD_SPEC, JOIN_KEY, WRITE_UNIT
from fabkit.io.fold_numbers import Num, metres_to_mm_text, radians_to_degrees_text

__all__ = ["save_fold", "fold_to_json", "fold_text"]


# ---- writing -------------------------------------------------------------------------------------
class _Raw(str):
    """JSON text already encoded (written verbatim)."""


class _Rows(list):
    """Encoded JSON array elements, written one per line."""


def _coords_rows(V: np.ndarray) -> _Rows:
    texts = list(map(metres_to_mm_text, V.ravel().tolist()))
    it = iter(texts)
    return _Rows(f"[{a},{b},{c}]" for a, b, c in zip(it, it, it))


def _angles_raw(a: np.ndarray) -> _Raw:
    memo: dict[float, str] = {}
    out = []
    for x in a.tolist():
        t = memo.get(x)
        if t is None:
            t = radians_to_degrees_text(x) or "null"
            if x == x:  # NaN is not a usable key
                memo[x] = t
        out.append(t)
    return _Raw("[" + ",".join(out) + "]")


def _int_rows(rows) -> _Rows:
    return _Rows("[" + ",".join(map(str, r)) + "]" for r in rows)


def _jsonable_array(arr: np.ndarray) -> list:
    """Array -> nested lists with NaN as None (JSON null)."""
    arr = np.asarray(arr)
    if arr.dtype.kind == "f":
        obj = arr.astype(object)
        obj[np.isnan(arr)] = None
        return obj.tolist()
    return arr.tolist()


def _data_raw(arr: np.ndarray) -> _Raw:
    return _Raw(json.dumps(_jsonable_array(arr), separators=(",", ":"), allow_nan=False))


def _key(kind: str, name: str) -> str:
    """`faces` + `strip` -> `faces_fabkit:strip`; names that already contain ':' are kept verbatim."""
    return name if ":" in name else f"{kind}_{FABKIT_PREFIX}{name}"


def _dimension(V: np.ndarray) -> str:
    return "2D" if len(V) == 0 or bool(np.all(V[:, 2] == 0.0)) else "3D"


def _attributes(declared: tuple, V: np.ndarray, assignment: np.ndarray) -> list[str]:
    """`frame_attributes` that match the content: the dimension measured from the coordinates (2D
    when every z is 0), `cuts` / `joins` when C / J edges are written; other declared attributes kept
    (declared 2D/3D/cuts/joins are replaced by what was measured)."""
    measured = [_dimension(V)]
    if np.any(assignment == "C"):
        measured.append("cuts")
    if np.any(assignment == "J"):
        measured.append("joins")
    replaced = {"2D", "3D", "cuts", "noCuts", "joins", "noJoins"}
    return measured + [a for a in declared if a not in replaced]


def _fold_parts(model: FoldModel, flavour: str = "compatible") -> dict[str, Any]:
    """The FOLD 1.2 top level, big arrays pre-encoded (millimetres, degrees)."""
    if flavour not in FLAVOURS:
        raise ValueError(f"unknown FOLD flavour {flavour!r}: use one of {', '.join(FLAVOURS)}")
    assignment = model.edges_assignment
    join = assignment == "J"
    if flavour == "compatible" and np.any(join):
        assignment = np.where(join, "F", assignment)
    d: dict[str, Any] = {
        "file_spec": FOLD_SPEC,
        "file_creator": "fabkit",
        "file_classes": ["animation"] if model.frames else ["singleModel"],
    }
    if model.title:
        d["file_title"] = model.title
    for name, value in model.file_data.items():
        d[_key("file", name)] = value
    if model.classes:
        d["frame_classes"] = list(model.classes)
    d["frame_attributes"] = _attributes(model.attributes, model.vertices_coords, assignment)
    d["frame_unit"] = WRITE_UNIT
    d["vertices_coords"] = _coords_rows(model.vertices_coords)
    d["edges_vertices"] = _int_rows(model.edges_vertices.tolist())
    d["edges_assignment"] = _Raw(json.dumps(assignment.tolist(), separators=(",", ":")))
    d["edges_foldAngle"] = _angles_raw(model.edges_fold_angle)
    d["faces_vertices"] = _int_rows(model.faces_vertices)
    for kind, data in (("vertices", model.vertices_data), ("edges", model.edges_data), ("faces", model.faces_data)):
        for name, arr in data.items():
            d[_key(kind, name)] = _data_raw(arr)
    if flavour == "compatible" and np.any(join):
        d[JOIN_KEY] = _data_raw(join.astype(np.int64))
    if model.frames:
        d["file_frames"] = [_frame_parts(f, assignment) for f in model.frames]
    return d


def _frame_parts(frame: FoldFrame, assignment: np.ndarray) -> dict[str, Any]:
    d: dict[str, Any] = {
        "frame_parent": 0,
        "frame_inherit": True,
        "frame_classes": list(frame.classes),
        "frame_attributes": _attributes(frame.attributes, frame.vertices_coords, assignment),
        "vertices_coords": _coords_rows(frame.vertices_coords),
    }
    if frame.edges_fold_angle is not None:
        d["edges_foldAngle"] = _angles_raw(frame.edges_fold_angle)
    for name, value in frame.data.items():
        d[_key("frame", name)] = _data_raw(value) if isinstance(value, np.ndarray) else value
    return d


def _dump(d: dict[str, Any], indent: str = "") -> str:
    """JSON with one top-level key per line and one array element per line (readable, diffable)."""
    lines = []
    for k, v in d.items():
        key = json.dumps(k)
        if k == "file_frames":
            body = (",\n" + indent + "  ").join(_dump(f, indent + "  ") for f in v)
            lines.append(f"{indent} {key}: [\n{indent}  {body}\n{indent} ]")
        elif isinstance(v, _Rows):
            rows = (",\n" + indent + "  ").join(v)
            lines.append(f"{indent} {key}: [\n{indent}  {rows}\n{indent} ]" if v else f"{indent} {key}: []")
        elif isinstance(v, _Raw):
            lines.append(f"{indent} {key}: {v}")
        else:
            lines.append(f"{indent} {key}: {json.dumps(v, separators=(',', ':'), allow_nan=False)}")
    return "{\n" + ",\n".join(lines) + "\n" + indent + "}"


def fold_text(model: FoldModel, flavour: str = "compatible") -> str:
    """The FOLD 1.2 text of a model (not validated; `save_fold` validates first). See `FLAVOURS`."""
    return _dump(_fold_parts(model, flavour)) + "\n"


def fold_to_json(model: FoldModel, flavour: str = "compatible") -> dict[str, Any]:
    """The FOLD 1.2 dictionary of a model, exactly as `save_fold` writes it (millimetres, degrees)."""
    return json.loads(fold_text(model, flavour), parse_float=Num)


def save_fold(model: FoldModel, path: str | os.PathLike, flavour: str = "compatible") -> None:
    """Validate `model` and write it as FOLD 1.2 (frame_unit mm, degrees) atomically (see `FLAVOURS`)."""
    validate_fold_model(model, source=str(path))
    text = fold_text(model, flavour)
    with atomic_write(path) as fh:
        fh.write(text)
