"""Every malformed file in tests/data/bad: `fabkit info` exits 2 with one line naming the file and the
problem, no traceback, and leaves no report behind; the Python readers raise InputError naming the file."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from fabkit.errors import InputError

BAD = Path(__file__).parent / "data" / "bad"
ROOT = Path(__file__).parent.parent

#: file -> words the one-line error must contain (the problem, said specifically)
EXPECTED: dict[str, str] = {
    "ascii-stl-renamed.obj": "line 1: unknown OBJ statement solid",
    "assignment-not-string.fold": "edges_assignment[3] is 1",
    "assignment-unknown-letter.fold": 'edges_assignment[3] is "X"',
    "assignment-wrong-length.fold": "edges_assignment has 6 entries for 7 edges",
    "bad-face-token.obj": "line 5: face corner 'x' is not a vertex index",
    "bad-number.obj": "line 2: vertex coordinates '1 0 zero' are not numbers",
    "binary-junk.fold": "binary data",
    "binary-junk.obj": "binary data",
    "clockwise-crease-pattern.fold": "face 0 is clockwise",
    "coords-four-values.fold": "vertices_coords[1]",
    "coords-not-a-list.fold": "vertices_coords must be a list",
    "coords-string-entry.fold": "vertices_coords[1]",
    "deeply-nested.fold": "JSON nested too deeply",
    "deeply-nested-data.obj": "line 5: cannot read fabkit face_data 's' (maximum recursion depth",
    "deeply-nested-data.fold": "a field is nested too deeply",
    "duplicate-edge.fold": "edges 5 and 6 both join vertices",
    "exponent-overflow.fold": "vertices_coords[4] is [100,1e999999999]: coordinates must be finite",
    "edges-float-index.fold": "edges_vertices[3]",
    "edges-index-out-of-range.fold": "edge 6 refers to vertex [4, 6]",
    "edges-negative-index.fold": "edge 6 refers to vertex [-1, 5]",
    "edges-three-vertices.fold": "edges_vertices[1]",
    "empty-faces.fold": "no faces",
    "empty.fold": "empty file",
    "empty.obj": "no faces",
    "fabkit-data-bad-json.obj": "line 6: cannot read fabkit face_data 'strip'",
    "fabkit-data-wrong-length.obj": "line 6: fabkit face_data 'strip' has 3 entries for 1 faces",
    "face-repeated-vertex.fold": "face 1 repeats vertex 2",
    "face-side-without-edge.fold": "face 1 has side (5, 4) that is not in edges_vertices",
    "face-two-vertices.fold": "face 1 has 2 vertices",
    "face-two-vertices.obj": "line 5: face 0 has 2 vertices",
    "faces-data-wrong-length.fold": "faces_fabkit:strip has 3 entries for 2 faces",
    "faces-index-huge.fold": "faces_vertices[1] is [1,2,99999999999999999999,4]: vertex index out of range",
    "faces-index-out-of-range.fold": "face 1 refers to vertex 7",
    "faces-negative-index.fold": "face 1 refers to vertex -1",
    "foldangle-over-180.fold": "outside [-180, 180]",
    "foldangle-sign-contradicts-valley.fold": "edge 3 is a valley (V) but its fold angle is -90 deg",
    "foldangle-string.fold": 'edges_foldAngle[3] is "90"',
    "foldangle-wrong-length.fold": "edges_foldAngle has 8 entries for 7 edges",
    "frame-changes-topology.fold": "frame 1): overrides faces_vertices",
    "frame-foldangle-sign.fold": "frame 1: edge 3 is a valley (V) but its fold angle is -45 deg",
    "frame-inherit-not-bool.fold": "frame_inherit must be true or false",
    "frame-inherit-without-parent.fold": "frame_parent is missing",
    "frame-not-inheriting-no-coords.fold": "has no vertices_coords and does not inherit them",
    "frame-parent-out-of-range.fold": "frame_parent 5 must be an earlier frame",
    "frame-parent-self.fold": "frame_parent 1 must be an earlier frame",
    "frame-wrong-vertex-count.fold": "frame 1: vertices_coords has shape (3, 3), expected (6, 3)",
    "frames-not-a-list.fold": "file_frames must be a list",
    "inconsistent-orientation.fold": "inconsistent orientation",
    "index-out-of-range.obj": "line 5: face refers to vertex 9",
    "inf-coordinate.obj": "vertex 2 (line 3) has a non-finite coordinate",
    "latin1-text.obj": "invalid UTF-8",
    "nan-coordinate.fold": "NaN is not valid JSON",
    "nan-coordinate.obj": "vertex 2 (line 3) has a non-finite coordinate",
    "negative-index-out-of-range.obj": "line 5: face refers to vertex -9",
    "no-faces.fold": "no faces_vertices",
    "no-faces.obj": "no faces (4 vertices)",
    "no-vertices.fold": "no vertices_coords",
    "non-manifold-crease.fold": "edge 3 (V) borders 3 faces [0, 1, 2]",
    "non-manifold-edge.obj": "shared by 3 faces [0, 1, 2]",
    "only-comments.obj": "no faces",
    "overflow-coordinate.fold": "coordinates must be finite",
    "repeated-vertex.obj": "face 0 (line 5) repeats vertex 1",
    "spec-not-a-number.fold": "file_spec",
    "top-level-array.fold": "a FOLD file is a JSON object, got list",
    "truncated-json.fold": "invalid JSON at line 34",
    "unknown-unit.fold": 'frame_unit "furlong" is not a FOLD unit',
    "unsupported-suffix.ply": "cannot read '.ply'",
    "vertex-two-coordinates.obj": "line 1: vertex needs x y z",
    "whitespace-only.fold": "empty file",
    "zero-area-face.fold": "face 0 has zero area",
    "zero-area-face.obj": "face 0 (line 4) has zero area",
    "zero-index.obj": "OBJ vertex indices start at 1",
}


def test_corpus_is_complete():
    files = sorted(p.name for p in BAD.iterdir())
    assert files == sorted(EXPECTED), "every bad file needs an expected message (and vice versa)"
    assert len(files) >= 30
    assert sum(f.endswith(".obj") for f in files) >= 15 and sum(f.endswith(".fold") for f in files) >= 15


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_info_refuses_bad_file(name, tmp_path):
    report = tmp_path / "report.json"
    proc = subprocess.run([sys.executable, "-m", "fabkit", "info", str(BAD / name), "--report", str(report)],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 2, (proc.stdout, proc.stderr)
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    line = lines[0]
    assert "Traceback" not in proc.stderr and "internal error" not in line
    assert line.startswith(f"fabkit info: error: {BAD / name}: "), line
    assert EXPECTED[name] in line, line
    assert proc.stdout == ""
    assert list(tmp_path.iterdir()) == []  # neither the report nor a temporary file


@pytest.mark.parametrize("name", sorted(n for n in EXPECTED if n.endswith((".obj", ".fold"))))
def test_python_readers_raise_input_error_naming_the_file(name):
    from fabkit.io import load_mesh

    path = BAD / name
    with pytest.raises(InputError) as err:
        load_mesh(path)
    assert err.value.source == str(path)
    assert str(err.value).startswith(f"{path}: ")
    assert EXPECTED[name] in str(err.value)
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("kind", ["obj", "fold"])
def test_mutated_files_fail_only_with_input_errors(tmp_path, kind):
    """Seeded fuzzing: byte edits, deletions, duplications and truncations of a good file either
    still read or raise InputError (never another exception, which the CLI would call a bug)."""
    import random
    import warnings

    import numpy as np

    from fabkit.fold import FoldFrame, FoldModel
    from fabkit.io import load_mesh, save_fold, save_obj
    from io_meshes import folded_coords, mixed_mesh

    mesh = mixed_mesh()
    good = tmp_path / f"good.{kind}"
    if kind == "obj":
        save_obj(mesh, good)
    else:
        save_fold(FoldModel.from_mesh(mesh, frames=[FoldFrame(folded_coords(mesh, 0.3))]), good)
    src = good.read_bytes()
    rng = random.Random(2024)
    bad = tmp_path / f"bad.{kind}"
    outcomes = {"read": 0, "refused": 0}
    for _ in range(300):
        b = bytearray(src)
        op = rng.randrange(4)
        for _ in range(rng.randrange(1, 4)):
            if op == 0 and b:
                b[rng.randrange(len(b))] = rng.choice(b'0123456789-.,[]{}":eE nulltrueVMBFJ/#\n')
            elif op == 1 and b:
                k = rng.randrange(len(b))
                del b[k:k + rng.randrange(1, 20)]
            elif op == 2:
                k = rng.randrange(len(b))
                b[k:k] = b[k:k + rng.randrange(1, 40)]
            else:
                b = b[:rng.randrange(len(b) + 1)]
        bad.write_bytes(bytes(b))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                m = load_mesh(bad)
                assert np.all(np.isfinite(m.vertices))
                outcomes["read"] += 1
            except InputError as exc:
                assert str(exc).startswith(f"{bad}: ") and "\n" not in str(exc)
                outcomes["refused"] += 1
    assert outcomes["refused"] > 100  # the mutations really break files


@pytest.mark.parametrize("value", ["1e300", "-2e6", "1e308"])
def test_readers_refuse_absurd_coordinates(tmp_path, value):
    """Finite but absurd coordinates (beyond ±1e6 m) are refused by the OBJ and FOLD readers alike."""
    import json

    from fabkit.io import load_fold, load_obj

    obj = tmp_path / "a.obj"
    obj.write_text(f"v 0 0 0\nv 1 0 0\nv 1 1 {value}\nv 0 1 0\nf 1 2 3 4\n")
    with pytest.raises(InputError, match=r"a.obj: vertex 2 \(line 3\) has coordinate .*beyond"):
        load_obj(obj)
    fold = tmp_path / "a.fold"
    fold.write_text(json.dumps({"frame_unit": "m", "vertices_coords": [[0, 0], [1, 0], [1, float(value)], [0, 1]],
                                "faces_vertices": [[0, 1, 2, 3]]}))
    with pytest.raises(InputError, match=r"a.fold: vertices_coords: vertex 2 has coordinate .*beyond"):
        load_fold(fold)
