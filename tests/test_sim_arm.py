"""The DH-exact MuJoCo arm: flange site FK equals robot.kinematics FK; capsules and filtering."""
import mujoco
import numpy as np
import pytest

from robot.kinematics import fk, get_model
from sim.arm import JOINT_NAMES, LINK_NAMES, add_arm


def _arm(name):
    spec = mujoco.MjSpec()
    names = add_arm(spec, spec.worldbody, get_model(name))
    m = spec.compile()
    return m, mujoco.MjData(m), names


@pytest.mark.parametrize("name", ["ur5e", "ur10e"])
def test_flange_site_equals_dh_fk_on_1000_random_configurations(name):
    m, d, names = _arm(name)
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, names["flange_site"])
    Q = np.random.default_rng(7).uniform(-2 * np.pi, 2 * np.pi, (1000, 6))
    T = fk(name, Q)
    pos_err = rot_err = 0.0
    for q, t in zip(Q, T):
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        pos_err = max(pos_err, np.abs(d.site_xpos[site] - t[:3, 3]).max())
        rot_err = max(rot_err, np.abs(d.site_xmat[site].reshape(3, 3) - t[:3, :3]).max())
    assert pos_err <= 1e-9
    assert rot_err <= 1e-9


@pytest.mark.parametrize("name", ["ur5e", "ur10e"])
def test_known_flange_position_at_zero(name):
    # reference/ur-robots.md section 1.1 sanity values (independent of our FK)
    expected = {"ur5e": (-0.8172, -0.2329, 0.0628), "ur10e": (-1.18425, -0.2907, 0.06085)}[name]
    m, d, names = _arm(name)
    mujoco.mj_kinematics(m, d)
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, names["flange_site"])
    np.testing.assert_allclose(d.site_xpos[site], expected, atol=1e-12)


def test_joint_ranges_actuators_and_torques():
    m, _, names = _arm("ur10e")
    assert names["joints"] == list(JOINT_NAMES)
    np.testing.assert_allclose(m.jnt_range[2], [-np.pi, np.pi])
    np.testing.assert_allclose(m.jnt_range[0], [-2 * np.pi, 2 * np.pi])
    np.testing.assert_allclose(m.actuator_forcerange[:, 1], [330, 330, 150, 54, 54, 54])
    assert m.nu == 6 and all(m.body_mass[1:] > 0)


def test_home_pose_has_no_self_contact_but_a_folded_elbow_does():
    m, d, _ = _arm("ur5e")
    d.qpos[:] = [0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0]
    mujoco.mj_kinematics(m, d)
    mujoco.mj_collision(m, d)
    assert d.ncon == 0  # base-shoulder overlap is excluded, parent-child pairs are filtered
    d.qpos[:] = [0, -np.pi / 2, 3.0, 0.0, -np.pi / 2, 0]  # forearm folded back onto the upper arm
    mujoco.mj_kinematics(m, d)
    mujoco.mj_collision(m, d)
    bodies = {(LINK_NAMES.index(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[c.geom1])),
               LINK_NAMES.index(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, m.geom_bodyid[c.geom2])))
              for c in d.contact[:d.ncon]}
    assert d.ncon > 0 and all(abs(a - b) >= 2 for a, b in bodies)
