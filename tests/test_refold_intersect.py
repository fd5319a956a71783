"""Face interpenetration check: triangle pairs with known answers, and folded sheets."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from fabkit.refold.intersect import candidate_pairs, intersecting_pairs, neighbour_keys, triangles_intersect

T0 = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _pair(B):
    return bool(triangles_intersect(T0[None], np.asarray(B, float)[None])[0])


@pytest.mark.parametrize("B, expected", [
    # pierces the interior of T0 through the plane
    ([[0.2, 0.2, -1.0], [0.3, 0.2, 1.0], [0.2, 0.3, 1.0]], True),
    # crosses T0's plane outside T0
    ([[2.0, 2.0, -1.0], [2.1, 2.0, 1.0], [2.0, 2.1, 1.0]], False),
    # entirely above
    ([[0.2, 0.2, 0.5], [0.3, 0.2, 1.0], [0.2, 0.3, 1.0]], False),
    # coplanar and overlapping: lying on each other is contact (zero depth), not a penetration
    ([[0.2, 0.2, 0.0], [1.2, 0.2, 0.0], [0.2, 1.2, 0.0]], False),
    # the same, tilted by a hair: now they cross
    ([[0.2, 0.2, -1e-3], [1.2, 0.2, 1e-3], [0.2, 1.2, 1e-3]], True),
    # coplanar, disjoint (separated only by an in-plane axis)
    ([[1.0, 1.0, 0.0], [2.0, 1.0, 0.0], [1.0, 2.0, 0.0]], False),
    # touches T0 in a single point (its corner on T0's edge): not a penetration
    ([[0.5, 0.5, 0.0], [0.5, 0.5, 1.0], [1.0, 1.0, 1.0]], False),
    # edge-edge crossing, like two folded flaps interleaving
    ([[0.25, -0.5, 0.5], [0.25, 0.5, -0.5], [0.25, 0.5, 0.5]], True),
])
def test_triangle_pairs_known_answers(B, expected):
    assert _pair(B) is expected
    assert bool(triangles_intersect(np.asarray(B, float)[None], T0[None])[0]) is expected  # symmetric


def test_random_pairs_agree_with_rigid_motions(rng):
    """The answer does not depend on where the pair sits: random rigid motions of random pairs."""
    A = rng.normal(size=(300, 3, 3))
    B = rng.normal(size=(300, 3, 3)) + rng.normal(scale=0.5, size=(300, 1, 3))
    ref = triangles_intersect(A, B)
    assert 20 < ref.sum() < 280  # both answers occur
    R = Rotation.random(300, random_state=4)
    t = rng.normal(scale=10, size=(300, 1, 3))
    move = lambda X: np.einsum("kij,kpj->kpi", R.as_matrix(), X) + t  # noqa: E731
    np.testing.assert_array_equal(triangles_intersect(move(A), move(B)), ref)


def test_random_pairs_against_segment_triangle_test(rng):
    """Independent check: two triangles intersect iff an edge of one crosses the other (non-coplanar)."""
    def seg_hits(P, Q, T):
        e1, e2 = T[1] - T[0], T[2] - T[0]
        d = Q - P
        h = np.cross(d, e2)
        a = e1 @ h
        if abs(a) < 1e-14:
            return False
        f = 1.0 / a
        s = P - T[0]
        u = f * (s @ h)
        q = np.cross(s, e1)
        v = f * (d @ q)
        t = f * (e2 @ q)
        return u >= 0 and v >= 0 and u + v <= 1 and 0 <= t <= 1

    A = rng.normal(size=(200, 3, 3))
    B = rng.normal(size=(200, 3, 3))
    got = triangles_intersect(A, B)
    for k in range(200):
        ref = any(seg_hits(A[k][i], A[k][(i + 1) % 3], B[k]) for i in range(3)) or \
            any(seg_hits(B[k][i], B[k][(i + 1) % 3], A[k]) for i in range(3))
        assert got[k] == ref, k


def _strip(n=8):
    """A flat strip of 2n triangles along x, and a copy folded about x = 0.5 by `angle`."""
    xs = np.linspace(-1.0, 1.0, n + 1)
    V = np.array([[x, y, 0.0] for x in xs for y in (0.0, 0.4)])
    tris = []
    for i in range(n):
        a, b, c, d = 2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1
        tris += [[a, b, c], [a, c, d]]
    return V, np.array(tris)


def _fold(V, angle, at=0.0):
    W = V.copy()
    right = W[:, 0] > at + 1e-12
    R = Rotation.from_rotvec([0.0, -angle, 0.0])
    W[right] = R.apply(W[right] - [at, 0, 0]) + [at, 0, 0]
    return W


def test_folded_strip_clean_folds_and_a_flap_through_the_sheet():
    V, tris = _strip()
    for deg in (0, 150, 179, -179, 200):  # one straight crease never makes faces cross
        assert len(intersecting_pairs(_fold(V, np.radians(deg)), tris)) == 0
    # a Z: fold the far quarter up by 120 deg, then fold everything right of x = 0 back over the
    # left half by 170 deg: the far flap now points into the left half and passes through it
    W = _fold(_fold(V, np.radians(120), at=0.5), np.radians(170), at=0.0)
    hits = intersecting_pairs(W, tris)
    assert len(hits) > 0
    for i, j in hits:
        assert not set(tris[i]) & set(tris[j])
        xi, xj = V[tris[i], 0].mean(), V[tris[j], 0].mean()
        assert {xi < 0, xj > 0.5} == {True} or {xj < 0, xi > 0.5} == {True}  # left half vs far flap
    # the same Z folded gently (flap 60 deg, back-fold 100 deg) stays clear
    assert len(intersecting_pairs(_fold(_fold(V, np.radians(60), at=0.5), np.radians(100), at=0.0), tris)) == 0


def test_broad_phase_skips_neighbours_and_far_pairs():
    V, tris = _strip()
    pairs = candidate_pairs(V, tris)
    for i, j in pairs:
        assert not set(tris[i]) & set(tris[j])
        assert np.linalg.norm(V[tris[i]].mean(0) - V[tris[j]].mean(0)) < 1.0


def test_neighbour_keys_are_exactly_the_vertex_sharing_pairs():
    V, tris = _strip()
    T = len(tris)
    brute = sorted(i * T + j for i in range(T) for j in range(i + 1, T) if set(tris[i]) & set(tris[j]))
    np.testing.assert_array_equal(neighbour_keys(tris), brute)
    # passing the precomputed keys changes nothing, folded or flat
    W = _fold(_fold(V, np.radians(120), at=0.5), np.radians(170), at=0.0)
    for X in (V, W):
        np.testing.assert_array_equal(candidate_pairs(X, tris, neighbours=neighbour_keys(tris)),
                                      candidate_pairs(X, tris))
    np.testing.assert_array_equal(intersecting_pairs(W, tris, neighbours=neighbour_keys(tris)),
                                  intersecting_pairs(W, tris))
