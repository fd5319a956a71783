"""The clamp jaw on the sheet the fold states keep still: a 24 x 16 mm jaw over 10 mm slivers."""
from __future__ import annotations

import numpy as np
import pytest
from shapely.geometry import Polygon

from fabkit.clamp_region import JAW_TOL, best_jaw_pose, clamp_region, region_joins
from fabkit.placement import clamped_face_frame

JAW = np.array([[-0.012, -0.008], [0.012, -0.008], [0.012, 0.008], [-0.012, 0.008]])
W, L, N = 0.010, 0.060, 5          # five 10 x 60 mm faces side by side, rulings between them


def strip(bend_deg: float = 0.0, at: int = 2):
    """(flat (n, 3), tris, tri_face, edges, edge_kind, positions (2, n, 3)): the flat state and a state
    with the faces from column `at` on turned by `bend_deg` about the ruling x = at * W."""
    xs = np.arange(N + 1) * W
    V = np.array([[x, y, 0.0] for x in xs for y in (0.0, L)])      # vertex 2i bottom, 2i + 1 top
    tris, owner = [], []
    for i in range(N):
        a, b, c, d = 2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1
        tris += [(a, b, c), (a, c, d)]
        owner += [i, i]
    edges, kind = [], []
    for i in range(N + 1):
        edges.append((2 * i, 2 * i + 1))
        kind.append("boundary" if i in (0, N) else "ruling")
    for i in range(N):
        edges += [(2 * i, 2 * i + 2), (2 * i + 1, 2 * i + 3), (2 * i, 2 * i + 3)]
        kind += ["boundary", "boundary", "diagonal"]
    t = np.radians(bend_deg)
    X = V.copy()
    x0 = at * W
    m = V[:, 0] > x0 + 1e-12
    X[m, 0] = x0 + (V[m, 0] - x0) * np.cos(t)
    X[m, 2] = (V[m, 0] - x0) * np.sin(t)
    return V, np.array(tris), np.array(owner), np.array(edges), np.array(kind), np.stack([V, X])


def _fit(bend_deg=0.0, at=2, face=1):
    V, T, owner, E, K, X = strip(bend_deg, at)
    reach = float(np.linalg.norm(JAW, axis=1).max())
    region = clamp_region(V, T, owner, region_joins(T, owner, E, K), X, face, reach)
    ring = V[[2 * face, 2 * face + 2, 2 * face + 3, 2 * face + 1]]
    frame = clamped_face_frame(ring, [0, 1, 2, 3], V.mean(0))
    return region, best_jaw_pose(region.polygon, Polygon(ring[:, :2]), JAW, frame), ring


def _jaw_polygon(pose):
    return Polygon(JAW @ pose.frame[:2, :2].T + pose.frame[:2, 2])


def test_a_jaw_wider_than_the_face_sits_on_it_and_its_neighbours_when_the_sheet_stays_still():
    region, pose, ring = _fit()
    # the jaw's centre stays on face 1, so it reaches 14.4 mm (its circumradius) past the face: faces 0, 2, 3
    assert region.faces == (1, 0, 2, 3) and region.worst_m == 0.0 and region.refused == {}
    # 16 mm across a 10 mm face: centred on it, along its long axis, 3 mm onto each neighbour
    assert pose.fits and pose.yaw_deg == 0.0
    np.testing.assert_allclose(pose.frame[:2, 2], ring[:, :2].mean(0), atol=1e-12)
    assert abs(abs(pose.frame[1, 0]) - 1.0) < 1e-12                 # x of the jaw along the face (y)
    assert pose.slack_m == pytest.approx(W / 2, abs=1e-9)           # the centre may move 5 mm: the face's half width
    assert region.polygon.buffer(1e-9).contains(_jaw_polygon(pose))
    assert not Polygon(ring[:, :2]).buffer(1e-9).contains(_jaw_polygon(pose))


def test_a_neighbour_the_fold_states_turn_is_left_out_and_the_jaw_moves_off_it():
    # faces 2.. turn 0.3 deg about x = 20 mm: within the jaw's 14.4 mm reach past face 1 the sheet moves
    # the chord 2 * 14.4 mm * sin 0.15 deg = 0.076 mm, under the 0.1 mm tolerance: kept
    reach = float(np.linalg.norm(JAW, axis=1).max())
    small, _, _ = _fit(0.3)
    assert small.faces == (1, 0, 2, 3)
    assert small.worst_m == pytest.approx(2 * reach * np.sin(np.radians(0.15)), rel=1e-6)
    assert small.worst_m <= JAW_TOL
    # 2 deg: 0.35 mm at face 2's far side, left out (and face 3 behind it); the jaw shifts toward face 0,
    # its centre still on face 1
    region, pose, ring = _fit(2.0)
    assert region.faces == (1, 0) and set(region.refused) == {2}
    assert region.refused[2] == pytest.approx(2 * W * np.sin(np.radians(1.0)), rel=1e-6) and region.refused[2] > JAW_TOL
    jaw = _jaw_polygon(pose)
    assert pose.fits and region.polygon.buffer(1e-9).contains(jaw)
    assert Polygon(ring[:, :2]).buffer(1e-9).contains(jaw.centroid)
    assert jaw.bounds[2] <= 2 * W + 1e-9                          # nothing of the jaw on face 2


def test_no_pose_fits_when_both_neighbours_turn():
    # the clamped face alone (10 mm) under a 16 mm jaw: no yaw fits; the face frame, slack -1
    V, T, owner, E, K, X = strip(5.0, at=2)
    X2 = X.copy()
    m = V[:, 0] < W - 1e-12                                        # and face 0 turns about x = 10 mm
    X2[1, m, 2] = (W - V[m, 0]) * np.sin(np.radians(5.0))
    region = clamp_region(V, T, owner, region_joins(T, owner, E, K), X2, 1, 0.0145)
    assert region.faces == (1,) and set(region.refused) == {0, 2}
    ring = V[[2, 4, 5, 3]]
    pose = best_jaw_pose(region.polygon, Polygon(ring[:, :2]), JAW, clamped_face_frame(ring, [0, 1, 2, 3]))
    assert not pose.fits and pose.slack_m == -1.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_permuted_vertices_and_triangles_give_the_same_jaw(seed):
    region, pose, _ = _fit(0.3)
    V, T, owner, E, K, X = strip(0.3)
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(V))                                  # new vertex i = old perm[i]
    inv = np.argsort(perm)
    torder = rng.permutation(len(T))
    T2 = np.array([np.roll(inv[t], int(rng.integers(3))) for t in T[torder]])
    E2 = inv[E]
    eorder = rng.permutation(len(E2))
    reach = float(np.linalg.norm(JAW, axis=1).max())
    r2 = clamp_region(V[perm], T2, owner[torder], region_joins(T2, owner[torder], E2[eorder], K[eorder]),
                      X[:, perm], 1, reach)
    assert r2.faces == region.faces and abs(r2.polygon.area - region.polygon.area) < 1e-15
    assert r2.polygon.symmetric_difference(region.polygon).area < 1e-15
    ring = V[[2, 4, 5, 3]]
    p2 = best_jaw_pose(r2.polygon, Polygon(ring[::-1, :2]), JAW, clamped_face_frame(ring[[2, 3, 0, 1]], [0, 1, 2, 3],
                                                                                    V.mean(0)))
    np.testing.assert_allclose(p2.frame, pose.frame, atol=1e-9)


def test_without_fold_states_the_region_is_the_flat_sheet_around_the_face():
    V, T, owner, E, K, _ = strip()
    region = clamp_region(V, T, owner, region_joins(T, owner, E, K), np.zeros((0, *V.shape)), 1, 0.0145)
    assert region.faces == (1, 0, 2, 3) and region.worst_m == 0.0
    with pytest.raises(ValueError, match="face 9 is not a face"):
        clamp_region(V, T, owner, region_joins(T, owner, E, K), V[None], 9, 0.0145)


def test_a_footprint_beside_its_pose_is_refused():
    region, _, ring = _fit()
    with pytest.raises(ValueError, match="contain its pose's origin"):
        best_jaw_pose(region.polygon, Polygon(ring[:, :2]), JAW + [0.02, 0.0], np.eye(4))
