"""Cell TOML loader: the shipped cells load; every validation branch names the file and key."""
import copy
import tomllib
from pathlib import Path

import numpy as np
import pytest

from fabkit.errors import InputError
from robot import kinematics as K
from robot.cell import load_cell, matrix_to_pose, parse_cell, pose_to_matrix

CELLS = Path(__file__).resolve().parent.parent / "cells"
BENCH = CELLS / "ur5e_bench.toml"


def bench_data() -> dict:
    return tomllib.loads(BENCH.read_text())


@pytest.mark.parametrize("path", sorted(CELLS.glob("*.toml")), ids=lambda p: p.name)
def test_shipped_cells_load(path):
    cell = load_cell(path)
    assert cell.source == str(path)
    assert cell.robot.model in K.MODELS
    for T in [cell.robot.base_pose, cell.tool.tcp, cell.fixture] + [o.pose for o in cell.obstacles]:
        assert T.shape == (4, 4)
        np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-14)
    assert len(cell.obstacles) >= 3 and len(cell.tool.shapes) >= 1
    # the home configuration holds the tool pointing down, above the fixture's height
    Tw = cell.robot.base_pose @ K.fk_tcp(cell.model, cell.robot.home, cell.tool.tcp)
    assert Tw[2, 2] < -0.99 and Tw[2, 3] > cell.fixture[2, 3]
    # realistic gripper length
    assert 0.1 <= np.linalg.norm(cell.tool.tcp[:3, 3]) <= 0.15


def test_bench_values():
    cell = load_cell(BENCH)
    assert cell.name == "ur5e_bench" and cell.model.name == "ur5e"
    np.testing.assert_allclose(cell.tool.tcp[:3, 3], [0, 0, 0.13])
    assert cell.tool.grip_output == 0 and cell.tool.grip_output_kind == "tool"
    table = cell.obstacles[0]
    assert table.name == "bench" and table.kind == "box" and table.size == (0.75, 0.6, 0.02)
    assert cell.tool.shapes[0].size == (0.035, 0.05)
    assert cell.limits.joint_speed == (3.14159,) * 6 and cell.limits.clearance == 0.01
    # base turned 180 deg about z: base -x is world +x
    np.testing.assert_allclose(cell.robot.base_pose[:3, 0], [-1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(cell.panel_to_base[:3, 3], [-0.75, 0.25, 0.30], atol=1e-12)
    # panel point (0.25, 0.25) (the middle of a 0.5 m flat pattern) is 0.5 m in front of the base
    np.testing.assert_allclose((cell.fixture @ [0.25, 0.25, 0, 1])[:3], [0.5, 0.0, 1.10], atol=1e-12)


def test_pose_conversion_round_trip(rng):
    for _ in range(20):
        p = np.concatenate([rng.normal(size=3), rng.normal(size=3)])
        p[3:] *= min(1.0, 3.0 / np.linalg.norm(p[3:]))  # keep the angle below pi
        np.testing.assert_allclose(matrix_to_pose(pose_to_matrix(p)), p, atol=1e-12)


def _set(data, path, value):
    d = data
    for k in path[:-1]:
        d = d[k]
    if value is KeyError:
        del d[path[-1]]
    else:
        d[path[-1]] = value
    return data


BAD = [
    # (path in the document, bad value, expected key in the message, expected words)
    (("name",), 3, "name", "expected a string"),
    (("name",), "  ", "name", "must not be empty"),
    (("colour",), "red", "colour", "unknown key"),
    (("robot", "model"), "ur3", "robot.model", "not one of"),
    (("robot", "model"), KeyError, "robot.model", "missing"),
    (("robot", "base_pose"), [0, 0, 0], "robot.base_pose", "expected 6 numbers"),
    (("robot", "base_pose"), "0 0 0 0 0 0", "robot.base_pose", "expected a list"),
    (("robot", "base_pose"), [0, 0, "x", 0, 0, 0], "robot.base_pose[2]", "expected a number"),
    (("robot", "base_pose"), [0, 0, float("nan"), 0, 0, 0], "robot.base_pose[2]", "not finite"),
    (("robot", "base_pose"), [450.0, 0, 800.0, 0, 0, 0], "robot.base_pose", "millimetres"),
    (("robot", "home"), [0, 0, 4.0, 0, 0, 0], "robot.home", "joint 3"),
    (("robot", "speed"), 1, "robot.speed", "unknown key"),
    (("robot",), [1], "robot", "expected a table"),
    (("tool", "tcp"), [0, 0, 2.0, 0, 0, 0], "tool.tcp", "more than 1 m"),
    (("tool", "grip_output"), 9, "tool.grip_output", "outside 0..1"),
    (("tool", "grip_output"), 0.5, "tool.grip_output", "expected an integer"),
    (("tool", "grip_output"), True, "tool.grip_output", "expected an integer"),
    (("tool", "grip_output_kind"), "analog", "tool.grip_output_kind", "not one of"),
    (("tool", "shapes", 0, "radius"), -0.01, "tool.shapes[0].radius", "must be > 0"),
    (("tool", "shapes", 0, "radius"), KeyError, "tool.shapes[0].radius", "missing"),
    (("tool", "shapes", 0, "kind"), "cone", "tool.shapes[0].kind", "not one of"),
    (("tool", "shapes", 1, "size"), [1, 2, 3], "tool.shapes[1].size", "unknown key"),
    (("tool", "shapes"), {"kind": "box"}, "tool.shapes", "array of tables"),
    (("fixture", "pose"), KeyError, "fixture.pose", "missing"),
    (("fixture", "height"), 1.0, "fixture.height", "unknown key"),
    (("obstacles", 0, "size"), [0.1, 0.0, 0.1], "obstacles[0].size[1]", "must be > 0"),
    (("obstacles", 0, "size"), [0.1, 0.1], "obstacles[0].size", "expected 3 numbers"),
    (("obstacles", 0, "name"), KeyError, "obstacles[0].name", "missing"),
    (("obstacles", 1, "name"), "bench", "obstacles[1].name", "used twice"),
    (("obstacles", 3, "half_length"), 0, "obstacles[3].half_length", "must be > 0"),
    (("limits", "tcp_speed"), 0.0, "limits.tcp_speed", "must be > 0"),
    (("limits", "tcp_speed"), 5.0, "limits.tcp_speed", "must be <= 3"),
    (("limits", "tcp_accel"), "fast", "limits.tcp_accel", "expected a number"),
    (("limits", "joint_speed"), [3.2] * 6, "limits.joint_speed", "exceeds the ur5e"),
    (("limits", "joint_speed"), [1.0] * 5, "limits.joint_speed", "expected 6 numbers"),
    (("limits", "joint_accel"), 100.0, "limits.joint_accel", "must be <= 40"),
    (("limits", "clearance"), -0.001, "limits.clearance", "must be >= 0"),
    (("limits", "clearance"), KeyError, "limits.clearance", "missing"),
]


@pytest.mark.parametrize("path, value, key, words", BAD, ids=[f"{'.'.join(map(str, b[0]))}={b[1]!r}" for b in BAD])
def test_bad_values_name_file_and_key(path, value, key, words):
    data = _set(copy.deepcopy(bench_data()), path, value)
    with pytest.raises(InputError) as info:
        parse_cell(data, "cells/x.toml")
    msg = str(info.value)
    assert msg.startswith(f"cells/x.toml: {key}: "), msg
    assert words in msg and "\n" not in msg


def test_ur10e_speed_limit_is_checked():
    data = tomllib.loads((CELLS / "ur10e_fold_table.toml").read_text())
    data["limits"]["joint_speed"] = [3.14159] * 6
    with pytest.raises(InputError, match=r"limits.joint_speed: joint 1 = 3.14159 rad/s exceeds the ur10e's 2.0944"):
        parse_cell(data, "u.toml")


def test_file_level_errors(tmp_path):
    with pytest.raises(InputError, match="cell file not found"):
        load_cell(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(InputError, match=r"bad.toml: not valid TOML"):
        load_cell(bad)
    binary = tmp_path / "bin.toml"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(InputError, match="cannot read"):
        load_cell(binary)


def test_optional_keys_have_defaults():
    data = bench_data()
    del data["robot"]["home"]
    del data["description"]
    del data["tool"]["grip_output_kind"]
    del data["obstacles"]
    del data["clamp"]  # it names an obstacle
    data["tool"]["shapes"][0].pop("name")
    cell = parse_cell(data, "x.toml")
    np.testing.assert_allclose(cell.robot.home, [0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0])
    assert cell.description == "" and cell.obstacles == () and cell.tool.grip_output_kind == "tool"
    assert cell.tool.shapes[0].name == "tool_0"
