"""The two-arm cell: schema, one MuJoCo model with both arms, arm-arm contacts."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from fabkit.errors import InputError
from robot import kinematics as K
from robot.cell import load_cell, parse_cell
from sim.arm_contacts import arm_arm_contacts
from sim.model import build_cell_model

ROOT = Path(__file__).resolve().parent.parent
DUAL = ROOT / "cells" / "dual_ur10e.toml"


@pytest.fixture(scope="module")
def cell():
    return load_cell(DUAL)


def test_dual_cell_loads_with_two_arms(cell):
    assert [n for n, _ in cell.arms] == ["a", "b"]
    for _, mount in cell.arms:
        Tw = mount.base_pose @ K.fk_tcp(K.get_model(mount.model), mount.home, cell.tool.tcp)
        assert Tw[2, 2] < -0.99 and Tw[2, 3] > cell.fixture[2, 3]      # tool down, above the panel
    # the two homes are mirror images across the table's middle
    ta = cell.arms[0][1].base_pose @ K.fk_tcp(cell.model, cell.arms[0][1].home, cell.tool.tcp)
    tb = cell.arms[1][1].base_pose @ K.fk_tcp(cell.model, cell.arms[1][1].home, cell.tool.tcp)
    np.testing.assert_allclose(ta[0, 3] + tb[0, 3], 1.9, atol=1e-9)


def test_one_model_with_both_arms(cell):
    m1, n1 = build_cell_model(cell)
    m2, n2 = build_cell_model(cell, all_arms=True)
    assert m1.nq == 6 and m2.nq == 12
    assert n2.extra_arms[0]["joints"][0] == "b_shoulder_pan" and "b_tcp" in n2.extra_arms[0]["tcp_site"]
    # the extra arm's FK in MuJoCo is the DH FK of its mount
    import mujoco

    d = mujoco.MjData(m2)
    qb = np.array([0.3, -1.2, 1.1, -1.4, -1.5, 0.2])
    d.qpos[6:] = qb
    mujoco.mj_kinematics(m2, d)
    sid = mujoco.mj_name2id(m2, mujoco.mjtObj.mjOBJ_SITE, "b_tcp")
    T = cell.arms[1][1].base_pose @ K.fk_tcp(cell.model, qb, cell.tool.tcp)
    np.testing.assert_allclose(d.site_xpos[sid], T[:3, 3], atol=1e-9)


def test_arms_at_home_are_clear_and_reaching_into_each_other_collide(cell):
    homes = {n: mnt.home[None] for n, mnt in cell.arms}
    assert arm_arm_contacts(cell, homes) == []
    # both arms stretched horizontally toward each other over the table (reach 1.3 m each, 1.9 m apart)
    reach = np.array([[np.pi / 2 + 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    hits = arm_arm_contacts(cell, {"a": reach, "b": reach})
    assert hits and all(h.distance_m < 0 for h in hits)
    assert any(not h.pair[0].startswith("b_") and h.pair[1].startswith("b_") for h in hits)
    # with a clearance, parts closer than it are reported before they touch (the homes are < 2 m apart)
    near = arm_arm_contacts(cell, homes, clearance=2.0)
    assert near and all(h.distance_m < 2.0 for h in near)


def test_bad_arms_name_the_key():
    import tomllib

    d = tomllib.loads(DUAL.read_text())
    d["arms"][0]["name"] = "a"
    with pytest.raises(InputError, match="used twice"):
        parse_cell(d, "x.toml")
    d["arms"][0]["name"] = "B-arm"
    with pytest.raises(InputError, match="arms\\[0\\].name"):
        parse_cell(d, "x.toml")
    d = tomllib.loads(DUAL.read_text())
    d["arms"][0]["model"] = "ur3"
    with pytest.raises(InputError, match="arms\\[0\\].model"):
        parse_cell(d, "x.toml")


def test_missing_arm_joints(cell):
    with pytest.raises(ValueError, match="no joints for arm 'b'"):
        arm_arm_contacts(cell, {"a": np.zeros((1, 6))})
