"""UR kinematics: FK against published values and the library, Jacobian, IK wrapper completeness."""
import numpy as np
import pytest
import ur_analytic_ik

from robot import kinematics as K

HOME = np.array([0.0, -np.pi / 2, np.pi / 2, -np.pi / 2, -np.pi / 2, 0.0])


@pytest.mark.parametrize("name, expected", [
    ("ur5e", (-0.8172, -0.2329, 0.0628)),
    ("ur10e", (-1.18425, -0.2907, 0.06085)),
])
def test_fk_zero_pose_matches_published_values(name, expected):
    T = K.fk(name, np.zeros(6))
    # q = 0: x = a2 + a3, y = -(d4 + d6), z = d1 - d5 (reference §1.1)
    np.testing.assert_allclose(T[:3, 3], expected, atol=1e-12)


def test_fk_home_tool_points_down():
    T = K.fk("ur5e", HOME)
    np.testing.assert_allclose(T[:3, 3], (-0.4919, -0.1333, 0.4879), atol=1e-12)
    np.testing.assert_allclose(T[:3, 2], (0, 0, -1), atol=1e-12)


@pytest.mark.parametrize("name", ["ur5e", "ur10e"])
def test_fk_matches_ur_analytic_ik(name, rng):
    Q = rng.uniform(-2 * np.pi, 2 * np.pi, (300, 6))
    ours = K.fk(name, Q)
    theirs = np.array([getattr(ur_analytic_ik, name).forward_kinematics(*q) for q in Q])
    assert np.abs(ours - theirs).max() < 1e-14
    # single configuration and frame chain agree with the batch
    np.testing.assert_array_equal(K.fk(name, Q[0]), ours[0])
    np.testing.assert_allclose(K.fk_frames(name, Q[:5])[:, 6], ours[:5], atol=1e-15)


def test_fk_tcp_is_flange_times_tcp(rng):
    q = rng.uniform(-np.pi, np.pi, 6)
    tcp = np.eye(4)
    tcp[:3, 3] = (0.01, -0.02, 0.12)
    np.testing.assert_allclose(K.fk_tcp("ur10e", q, tcp), K.fk("ur10e", q) @ tcp, atol=1e-15)
    lib = ur_analytic_ik.ur10e.forward_kinematics_with_tcp(*q, tcp)
    np.testing.assert_allclose(K.fk_tcp("ur10e", q, tcp), lib, atol=1e-14)


@pytest.mark.parametrize("name", ["ur5e", "ur10e"])
def test_jacobian_matches_finite_differences(name, rng):
    from scipy.spatial.transform import Rotation

    for _ in range(5):
        q = rng.uniform(-np.pi, np.pi, 6)
        J = K.jacobian(name, q)
        T0 = K.fk(name, q)
        h = 1e-6
        for i in range(6):
            dq = np.zeros(6)
            dq[i] = h
            Tp, Tm = K.fk(name, q + dq), K.fk(name, q - dq)
            v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
            w = Rotation.from_matrix(Tp[:3, :3] @ Tm[:3, :3].T).as_rotvec() / (2 * h)
            np.testing.assert_allclose(J[:3, i], v, atol=1e-8)
            np.testing.assert_allclose(J[3:, i], w, atol=1e-8)
        assert np.allclose(T0, K.fk(name, q))


@pytest.mark.parametrize("name", ["ur5e", "ur10e"])
def test_singularity_factors_give_the_jacobian_determinant(name, rng):
    Q = rng.uniform(-np.pi, np.pi, (100, 6))
    f = K.singularity_factors(name, Q)
    dets = np.array([np.linalg.det(K.jacobian(name, q)) for q in Q])
    np.testing.assert_allclose(f.det, dets, rtol=1e-9, atol=1e-15)
    # known singular configurations: stretched elbow, wrist aligned, wrist centre on the base axis
    q = HOME.copy()
    q[2] = 0.0
    assert abs(K.singularity_factors(name, q).elbow) < 1e-15
    q = HOME.copy()
    q[4] = 0.0
    assert abs(K.singularity_factors(name, q).wrist) < 1e-15
    m = K.get_model(name)
    # q2 = -90 deg, q3 = 0, q4 = -90 deg: the arm points straight up, wrist centre above the base axis
    q = np.array([0.3, -np.pi / 2, 0.0, -np.pi / 2, 1.0, 0.0])
    assert abs(K.singularity_factors(m, q).shoulder) < 1e-15 + abs(m.d[4] * np.sin(-np.pi)) + 1e-12


def _sample_poses(name, rng, n):
    """Random configurations with the degenerate families mixed in (about half of them)."""
    Q = rng.uniform(-np.pi, np.pi, (n, 6))
    kind = rng.integers(0, 6, n)
    q5 = rng.choice([-np.pi / 2, np.pi / 2], n)
    q6 = rng.choice([0.0, np.pi, -np.pi], n)
    # 1: wrist 2 at +-90 deg with wrist 3 at 0/180 deg (the library drops the generating q)
    Q[kind == 1, 4] = q5[kind == 1]
    Q[kind == 1, 5] = q6[kind == 1]
    # 2: the same with round "nice" angles on every joint (multiples of 15 deg)
    nice = np.radians(rng.integers(-12, 12, (n, 6)) * 15.0)
    Q[kind == 2] = nice[kind == 2]
    Q[kind == 2, 4] = q5[kind == 2]
    Q[kind == 2, 5] = q6[kind == 2]
    # 3: near (not at) the wrist singularity
    Q[kind == 3, 4] = rng.choice([-1, 1], (kind == 3).sum()) * 1e-3
    # 4: wrist 2 at +-90 deg only
    Q[kind == 4, 4] = q5[kind == 4]
    Q = Q[np.abs(np.sin(Q[:, 2])) > 1e-3]  # skip exact elbow singularities (a continuum there)
    return Q


@pytest.mark.parametrize("name", ["ur5e", "ur10e"])
def test_ik_returns_the_original_configuration_always(name, rng):
    """5,000 poses per model (10,000 in all), degenerate families included: 100 % recovered."""
    m = K.get_model(name)
    Q = _sample_poses(name, rng, 5000)
    T = K.fk(m, Q)
    # every other pose from the library's FK: its last-bit differences change which solutions it drops
    lib = getattr(ur_analytic_ik, name)
    T[1::2] = [lib.forward_kinematics(*q) for q in Q[1::2]]
    missing, sols, owner, counts = [], [], [], []
    for i, (q, Tq) in enumerate(zip(Q, T)):
        S = K.ik(m, Tq)
        counts.append(len(S))
        if len(S) == 0 or K.wrapped_distance(S, q).min() > 1e-8:
            missing.append(q)
        sols.append(S)
        owner.extend([i] * len(S))
    assert not missing, f"{len(missing)} of {len(Q)} originals missing, first {missing[0].tolist()}"
    # every returned solution, checked again in one batch
    dp, dr = K.pose_error(K.fk(m, np.concatenate(sols)), T[np.array(owner)])
    assert dp.max() <= K.IK_TOL_POS and dr.max() <= K.IK_TOL_ROT
    assert len(Q) > 4900 and max(counts) <= 8


def test_library_alone_misses_the_degenerate_home_pose():
    """The defect the wrapper exists for (reference §2.3): home is not among the raw solutions."""
    T = ur_analytic_ik.ur5e.forward_kinematics(*HOME)  # the library's own FK of home
    raw = K.ik_raw("ur5e", T)
    assert len(raw) < 8 and K.wrapped_distance(raw, HOME).min() > 1e-3
    ours = K.ik("ur5e", T)
    assert len(ours) == 8 and K.wrapped_distance(ours, HOME).min() < 1e-12


def test_ik_with_tcp(rng):
    tcp = np.eye(4)
    tcp[:3, 3] = (0.0, 0.0, 0.13)
    for _ in range(20):
        q = rng.uniform(-np.pi, np.pi, 6)
        T = K.fk_tcp("ur10e", q, tcp)
        S = K.ik("ur10e", T, tcp=tcp)
        assert K.wrapped_distance(S, q).min() < 1e-9
        dp, dr = K.pose_error(K.fk_tcp("ur10e", S, tcp), T[None])
        assert dp.max() < 1e-9 and dr.max() < 1e-9


def test_ik_unreachable_pose_is_empty():
    T = np.eye(4)
    T[:3, 3] = (3.0, 0.0, 0.5)
    S = K.ik("ur5e", T)
    assert S.shape == (0, 6)
    with pytest.raises(ValueError):
        K.ik("ur5e", np.full((4, 4), np.nan))


def test_ik_keeps_library_noise_off_stdout(capfd):
    print("before", flush=True)
    K.ik("ur5e", ur_analytic_ik.ur5e.forward_kinematics(*HOME))  # makes the C++ solver print warnings
    print("after", flush=True)
    out, _ = capfd.readouterr()
    assert out == "before\nafter\n"
    # and the raw library does print (so the test above is not vacuous)
    ur_analytic_ik.ur5e.inverse_kinematics(ur_analytic_ik.ur5e.forward_kinematics(*HOME))
    out, _ = capfd.readouterr()
    assert "Warning" in out


def test_quiet_stdout_is_reentrant(capfd):
    import os

    with K.quiet_stdout():
        with K.quiet_stdout():
            os.write(1, b"hidden\n")
        os.write(1, b"hidden too\n")
    os.write(1, b"shown\n")
    assert capfd.readouterr().out == "shown\n"


def test_branch_signatures_of_the_eight_solutions_differ(rng):
    for name in ("ur5e", "ur10e"):
        for _ in range(20):
            q = rng.uniform(-np.pi, np.pi, 6)
            S = K.ik(name, K.fk(name, q))
            if len(S) == 8:
                sig = {tuple(s) for s in K.branch_signs(name, S)}
                assert len(sig) == 8
    assert K.branch_label("ur5e", HOME) in {f"shoulder{a} elbow{b} wrist{c}" for a in "+-" for b in "+-" for c in "+-"}
    assert K.branch_label("ur5e", HOME) == "shoulder- elbow+ wrist-"


def test_select_nearest_is_wrap_aware():
    sols = np.array([[-np.pi + 0.01, 0, 0, 0, 0, 0], [0.5, 0, 0, 0, 0, 0]])
    q_ref = np.array([np.pi - 0.01, 0, 0, 0, 0, 0])
    q = K.select_nearest(sols, q_ref)
    np.testing.assert_allclose(q, [np.pi + 0.01, 0, 0, 0, 0, 0], atol=1e-15)
    assert K.nearest_index(sols, q_ref) == 0
    # the library's own "closest" is not used; our pick is the wrapped-nearest one
    q_ref2 = np.array([0.4, 0, 0, 0, 0, 0])
    assert K.nearest_index(sols, q_ref2) == 1


def test_unwrap_near_respects_joint_ranges():
    q = np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0])
    q_ref = np.array([2 * np.pi - 0.1, 0, -3.0, 0, 0, 0])
    out = K.unwrap_near(q, q_ref)
    # joint 1 would want 2pi (inside +-2pi); the elbow stays inside +-pi instead of -3.28
    np.testing.assert_allclose(out[0], 2 * np.pi, atol=1e-15)
    assert abs(out[2]) <= np.pi


def test_select_nearest_by_branch(rng):
    q = np.array([0.2, -1.0, 1.2, -1.4, -1.3, 0.4])
    S = K.ik("ur5e", K.fk("ur5e", q))
    sig = K.branch_signs("ur5e", q)
    other = -sig
    chosen = K.select_nearest(S, q, model="ur5e", branch=other)
    assert tuple(K.branch_signs("ur5e", chosen)) == tuple(other)
    with pytest.raises(LookupError):
        K.select_nearest(S[:0], q)
    with pytest.raises(ValueError, match="needs the model"):
        K.select_nearest(S, q, branch=other)


def test_get_model_unknown():
    with pytest.raises(ValueError, match="ur3"):
        K.get_model("ur3")
    assert K.get_model("UR10E").joint_speed_max[0] == pytest.approx(np.radians(120))
