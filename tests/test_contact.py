"""Contact detection (granpack.contact) on hand-built configurations with exact answers.

Every expected value here is computed independently of the detection kernels: feature
placements give gaps, points and normals by construction; random pairs are checked against the
exact distance / penetration depth of two convex polytopes, computed in plain numpy as the
distance from the origin to the boundary of their Minkowski difference (scipy ConvexHull), which
owes nothing to the separating-axis test or to GJK.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from granpack.box import Box
from granpack.contact import DOUBLE, SIMPLE, TRIPLE, ContactSet, Detector, contact_types, detect
from granpack.rotations import quat_from_axis_angle, quat_multiply, quat_to_matrix, random_quaternions
from granpack.shapes import Pinacoid, ShapeTable, Sphere, platonic
from granpack.state import ParticleState

ALERT = 0.02
EZ = np.array([0.0, 0.0, 1.0])
FAMILIES = [(1.0, 1.0), (2.0, 1.0), (1.0, 3.0), (2.0, 3.0)]
SIZES = [1.0, 1.0 / 3.0]


# ---------------------------------------------------------------------------------------------
# helpers: rotations, world geometry, states


def rot_to(a, b) -> np.ndarray:
    """Quaternion of the smallest rotation taking unit vector ``a`` onto unit vector ``b``."""
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    c = np.cross(a, b)
    s, cos = np.linalg.norm(c), float(a @ b)
    if s < 1e-12:
        if cos > 0:
            return np.array([1.0, 0.0, 0.0, 0.0])
        perp = np.cross(a, [1.0, 0.0, 0.0])
        if np.linalg.norm(perp) < 1e-6:
            perp = np.cross(a, [0.0, 1.0, 0.0])
        return quat_from_axis_angle(perp, math.pi)
    return quat_from_axis_angle(c, math.atan2(s, cos))


def spin_z(angle: float) -> np.ndarray:
    return quat_from_axis_angle(EZ, angle)


def then(q_first, q_second) -> np.ndarray:
    """Quaternion of ``q_first`` followed by ``q_second``."""
    return quat_multiply(q_second, q_first)


def make_state(shapes, kinds, positions, quaternions, box=12.0) -> ParticleState:
    n = len(kinds)
    return ParticleState(
        box=Box.square(box),
        shapes=ShapeTable.from_shapes(shapes),
        kind=np.asarray(kinds, np.int64),
        population=np.zeros(n, np.int64),
        position=np.asarray(positions, float).reshape(n, 3),
        quaternion=np.asarray(quaternions, float).reshape(n, 4),
    )


def world_vertices(shape, q, x) -> np.ndarray:
    return np.asarray(x) + shape.vertices @ quat_to_matrix(np.asarray(q)).T


def face_polygon(shape, f, q, x) -> tuple[np.ndarray, np.ndarray]:
    """World vertices ``(k, 3)`` and outward unit normal of face ``f``."""
    R = quat_to_matrix(np.asarray(q))
    return np.asarray(x) + shape.vertices[shape.faces[f]] @ R.T, R @ shape.face_normals[f]


def face_area(shape, f) -> float:
    p = shape.vertices[shape.faces[f]]
    return 0.5 * float(np.linalg.norm(sum(np.cross(p[k], p[(k + 1) % len(p)]) for k in range(len(p)))))


def in_polygon(point, poly, normal, tol=1e-9) -> bool:
    """True if ``point`` projects inside the convex polygon ``poly`` (ccw about ``normal``)."""
    k = len(poly)
    return all(np.cross(poly[(e + 1) % k] - poly[e], point - poly[e]) @ normal >= -tol for e in range(k))


def vertex_faces(shape, v) -> list[int]:
    return [f for f, face in enumerate(shape.faces) if v in face]


def edge_faces(shape, e) -> list[int]:
    a, b = shape.edges[e]
    return [f for f, face in enumerate(shape.faces) if a in face and b in face]


def feature_down(shape, normals_idx) -> np.ndarray:
    """Unit direction (body frame) inside the normal cone of the feature with those faces."""
    m = shape.face_normals[normals_idx].sum(axis=0)
    return m / np.linalg.norm(m)


def manifolds(cs: ContactSet) -> list[dict]:
    out = []
    for m in range(cs.n_manifolds):
        s = slice(cs.point_start[m], cs.point_start[m + 1])
        out.append(dict(i=int(cs.body_i[m]), j=int(cs.body_j[m]), shift=cs.shift[m], normal=cs.normal[m],
                        ctype=int(cs.ctype[m]), points=cs.point[s], gaps=cs.gap[s]))
    return out


def pair_manifold(cs: ContactSet, i=0, j=1) -> dict:
    found = [m for m in manifolds(cs) if m["i"] == i and m["j"] == j]
    assert len(found) == 1, f"expected one manifold ({i}, {j}), got {len(found)}"
    return found[0]


# ---------------------------------------------------------------------------------------------
# independent exact distance / penetration depth of two convex polytopes


def closest_on_triangles(p, a, b, c) -> np.ndarray:
    """Closest point of each triangle ``(a[k], b[k], c[k])`` to ``p``: ``(T, 3)``.

    The projection on the triangle's plane if it falls inside, else the nearest of the three
    edges' closest points (a triangle's closest point is interior or on its boundary).
    """
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    q = p - np.einsum("ij,ij->i", p - a, n)[:, None] * n
    inside = np.ones(len(a), bool)
    cands = []
    for v0, v1 in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(v1 - v0, q - v0), n) >= 0.0
        e = v1 - v0
        t = np.clip(np.einsum("ij,ij->i", p - v0, e) / np.einsum("ij,ij->i", e, e), 0.0, 1.0)
        cands.append(v0 + t[:, None] * e)
    cands = np.stack(cands)  # (3, T, 3)
    edge_best = cands[np.argmin(np.linalg.norm(cands - p, axis=2), axis=0), np.arange(len(a))]
    return np.where(inside[:, None], q, edge_best)


def exact_gap(va: np.ndarray, vb: np.ndarray) -> tuple[float, np.ndarray]:
    """Signed distance between hull(va) and hull(vb) and the unit direction from A to B.

    The Minkowski difference ``D = hull(vb - va)`` contains the origin iff the bodies overlap.
    Separated: the distance is that of the origin to ``D`` (nearest point of its boundary
    triangles), the direction that of this nearest point. Overlapping: the penetration depth is
    the distance from the origin to the nearest facet plane of ``D`` (the minimum translational
    distance); B leaves along minus that facet's outward normal.
    """
    diff = (vb[None, :, :] - va[:, None, :]).reshape(-1, 3)
    hull = ConvexHull(diff)
    normals, offsets = hull.equations[:, :3], hull.equations[:, 3]
    if np.all(offsets < 0.0):  # origin inside D
        k = int(np.argmax(offsets))
        return float(offsets[k]), -normals[k]
    s = hull.simplices
    q = closest_on_triangles(np.zeros(3), diff[s[:, 0]], diff[s[:, 1]], diff[s[:, 2]])
    d = np.linalg.norm(q, axis=1)
    k = int(np.argmin(d))
    return float(d[k]), q[k] / d[k]


def point_hull_distance(p, verts) -> float:
    """Distance from ``p`` to hull(verts) (0 inside)."""
    hull = ConvexHull(verts)
    if np.all(hull.equations[:, :3] @ p + hull.equations[:, 3] <= 0.0):
        return 0.0
    s = hull.simplices
    q = closest_on_triangles(np.asarray(p, float), verts[s[:, 0]], verts[s[:, 1]], verts[s[:, 2]])
    return float(np.linalg.norm(q - p, axis=1).min())


# ---------------------------------------------------------------------------------------------
# hand-built pinacoid configurations

X0 = np.array([6.0, 6.0, 5.0])  # far from the wall and from the periodic boundaries


def largest_face(shape) -> int:
    return int(np.argmax([face_area(shape, f) for f in range(len(shape.faces))]))


def face_up(shape, spin=0.0):
    """Body A with its largest face on top (normal +z) at ``X0``: ``(q, polygon, centroid)``."""
    f = largest_face(shape)
    q = then(rot_to(shape.face_normals[f], EZ), spin_z(spin))
    poly, n = face_polygon(shape, f, q, X0)
    assert np.allclose(n, EZ)
    return q, poly, poly.mean(axis=0)


def pinacoid_pairs():
    """(family A, size A, family B, size B): every family at sizes 1 and 1/3, plus mixed pairs."""
    out = [(fam, s, fam, s) for fam in FAMILIES for s in SIZES]
    out += [((1.0, 1.0), 1.0, (1.0, 1.0), 1.0 / 3.0), ((2.0, 3.0), 1.0, (1.0, 3.0), 1.0 / 3.0),
            ((1.0, 3.0), 1.0 / 3.0, (2.0, 1.0), 1.0)]
    return out


def _ids(p):
    return "A{}x{:.2f}-B{}x{:.2f}".format(p[0], p[1], p[2], p[3])


@pytest.mark.parametrize("spec", pinacoid_pairs(), ids=_ids)
@pytest.mark.parametrize("gap", [0.004, 0.0, -0.003])
def test_face_on_face_is_triple(spec, gap):
    fam_a, size_a, fam_b, size_b = spec
    sa, sb = Pinacoid.from_size(size_a, *fam_a), Pinacoid.from_size(size_b, *fam_b)
    qa, pa, ca = face_up(sa)
    fb = largest_face(sb)
    qb = then(rot_to(sb.face_normals[fb], -EZ), spin_z(0.3))
    pb0, _ = face_polygon(sb, fb, qb, np.zeros(3))
    xb = ca + gap * EZ - pb0.mean(axis=0)
    pb, nb = face_polygon(sb, fb, qb, xb)
    cs = detect(make_state([sa, sb], [0, 1], [X0, xb], [qa, qb]), ALERT)
    assert cs.n_manifolds == 1
    m = pair_manifold(cs)
    assert m["ctype"] == TRIPLE
    assert 3 <= len(m["gaps"]) <= 4
    np.testing.assert_allclose(m["normal"], -EZ, atol=1e-12)  # from j = 1 (upper) to i = 0
    np.testing.assert_allclose(m["gaps"], gap, atol=1e-12)
    np.testing.assert_allclose(m["points"][:, 2], ca[2] + 0.5 * gap, atol=1e-12)
    for p in m["points"]:
        assert in_polygon(p, pa, EZ) and in_polygon(p, pb, nb)
    # the points span a real area, not a segment
    assert contact_types(cs, eps=1e-3)[0] == TRIPLE


def shortest_edge(shape) -> int:
    v = shape.vertices
    return int(np.argmin(np.linalg.norm(v[shape.edges[:, 1]] - v[shape.edges[:, 0]], axis=1)))


def edge_down(shape, e, direction_world):
    """Quaternion putting edge ``e`` lowest (outward bisector along -z), along ``direction_world``."""
    q = rot_to(feature_down(shape, edge_faces(shape, e)), -EZ)
    a, b = shape.edges[e]
    d = quat_to_matrix(q) @ (shape.vertices[b] - shape.vertices[a])
    assert abs(d[2]) < 1e-12
    ang = math.atan2(direction_world[1], direction_world[0]) - math.atan2(d[1], d[0])
    return then(q, spin_z(ang))


@pytest.mark.parametrize("spec", [p for p in pinacoid_pairs() if p[3] <= p[1]], ids=_ids)
@pytest.mark.parametrize("gap", [0.004, -0.002])
def test_edge_on_face_is_double_with_edge_ends(spec, gap):
    fam_a, size_a, fam_b, size_b = spec
    sa, sb = Pinacoid.from_size(size_a, *fam_a), Pinacoid.from_size(size_b, *fam_b)
    qa, pa, ca = face_up(sa)
    longest = max(range(len(pa)), key=lambda k: np.linalg.norm(pa[(k + 1) % len(pa)] - pa[k]))
    e = shortest_edge(sb)
    qb = edge_down(sb, e, pa[(longest + 1) % len(pa)] - pa[longest])
    ends0 = world_vertices(sb, qb, np.zeros(3))[sb.edges[e]]
    xb = ca + gap * EZ - ends0.mean(axis=0)
    ends = ends0 + xb
    assert all(in_polygon(p, pa, EZ, tol=-1e-3) for p in ends)  # the edge lies inside the face
    cs = detect(make_state([sa, sb], [0, 1], [X0, xb], [qa, qb]), ALERT)
    m = pair_manifold(cs)
    assert m["ctype"] == DOUBLE
    assert len(m["gaps"]) == 2
    np.testing.assert_allclose(m["normal"], -EZ, atol=1e-12)
    np.testing.assert_allclose(m["gaps"], gap, atol=1e-12)
    expected = ends - 0.5 * gap * EZ
    got = m["points"][np.argsort(m["points"] @ (ends[1] - ends[0]))]
    want = expected[np.argsort(expected @ (ends[1] - ends[0]))]
    np.testing.assert_allclose(got, want, atol=1e-12)


@pytest.mark.parametrize("spec", pinacoid_pairs(), ids=_ids)
@pytest.mark.parametrize("vertex", [0, 4])
def test_vertex_on_face_is_simple_at_the_vertex(spec, vertex):
    fam_a, size_a, fam_b, size_b = spec
    sa, sb = Pinacoid.from_size(size_a, *fam_a), Pinacoid.from_size(size_b, *fam_b)
    qa, pa, ca = face_up(sa)
    gap = 0.006
    # body-frame vertex of the pinacoid definition (0: rectangle corner, 4: ridge end)
    v = int(np.argmin(np.linalg.norm(sb.vertices - Pinacoid.from_size(size_b, *fam_b).vertices[vertex], axis=1)))
    qb = then(rot_to(feature_down(sb, vertex_faces(sb, v)), -EZ), spin_z(0.7))
    tip0 = world_vertices(sb, qb, np.zeros(3))[v]
    xb = ca + gap * EZ - tip0
    heights = world_vertices(sb, qb, xb)[:, 2] - ca[2]
    assert np.sort(heights)[1] > ALERT  # the vertex is the only low feature
    cs = detect(make_state([sa, sb], [0, 1], [X0, xb], [qa, qb]), ALERT)
    m = pair_manifold(cs)
    assert m["ctype"] == SIMPLE and len(m["gaps"]) == 1
    np.testing.assert_allclose(m["normal"], -EZ, atol=1e-12)
    np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
    np.testing.assert_allclose(m["points"][0], ca + 0.5 * gap * EZ, atol=1e-12)


@pytest.mark.parametrize("spec", pinacoid_pairs(), ids=_ids)
@pytest.mark.parametrize("gap", [0.005, -0.001])
def test_crossed_edges_is_simple_at_the_crossing(spec, gap):
    fam_a, size_a, fam_b, size_b = spec
    sa, sb = Pinacoid.from_size(size_a, *fam_a), Pinacoid.from_size(size_b, *fam_b)
    ea, eb = shortest_edge(sa), shortest_edge(sb)
    qa = edge_down(sa, ea, [1.0, 0.0, 0.0])
    qa = then(qa, quat_from_axis_angle([1.0, 0.0, 0.0], math.pi))  # edge A on top, along x
    qb = edge_down(sb, eb, [0.3, 1.0, 0.0])  # edge B at the bottom, crossing A's edge
    top = world_vertices(sa, qa, X0)[sa.edges[ea]]
    assert abs(top[0, 2] - top[1, 2]) < 1e-12
    mid_a = top.mean(axis=0)
    bottom0 = world_vertices(sb, qb, np.zeros(3))[sb.edges[eb]]
    xb = mid_a + gap * EZ - bottom0.mean(axis=0)
    cs = detect(make_state([sa, sb], [0, 1], [X0, xb], [qa, qb]), ALERT)
    m = pair_manifold(cs)
    assert m["ctype"] == SIMPLE and len(m["gaps"]) == 1
    np.testing.assert_allclose(m["normal"], -EZ, atol=1e-12)
    np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
    np.testing.assert_allclose(m["points"][0], mid_a + 0.5 * gap * EZ, atol=1e-12)


@pytest.mark.parametrize("spec", pinacoid_pairs()[:8], ids=_ids)
def test_separated_beyond_alert_is_no_contact(spec):
    fam_a, size_a, fam_b, size_b = spec
    sa, sb = Pinacoid.from_size(size_a, *fam_a), Pinacoid.from_size(size_b, *fam_b)
    qa, pa, ca = face_up(sa)
    fb = largest_face(sb)
    qb = then(rot_to(sb.face_normals[fb], -EZ), spin_z(0.3))
    pb0, _ = face_polygon(sb, fb, qb, np.zeros(3))
    for gap, found in ((ALERT * 1.001, 0), (ALERT * 0.999, 1), (3 * ALERT, 0)):
        xb = ca + gap * EZ - pb0.mean(axis=0)
        cs = detect(make_state([sa, sb], [0, 1], [X0, xb], [qa, qb]), ALERT)
        assert cs.n_manifolds == found


# ---------------------------------------------------------------------------------------------
# random pairs against the exact distance / penetration depth


def random_pairs(rng, n_pairs, gap_range=(-0.04, 0.03), spheres=False):
    """``n_pairs`` pinacoid pairs (random families, sizes 1 or 1/3, orientations) on a grid.

    Each pair is placed along a random direction at a distance tuned (Newton steps on the exact
    gap) to a random target gap in ``gap_range``. Returns ``(state, shapes, exact)`` where the
    bodies of pair k are ``2k`` and ``2k+1`` and ``exact[k] = (gap, direction 2k -> 2k+1)``.
    """
    shapes = [Pinacoid.from_size(s, *fam) for fam in FAMILIES for s in SIZES]
    side = int(math.ceil(math.sqrt(n_pairs)))
    box = 3.0 * side
    kinds, pos, quats, exact = [], [], [], []
    for k in range(n_pairs):
        ka, kb = rng.integers(len(shapes), size=2)
        qa, qb = random_quaternions(2, rng)
        xa = np.array([3.0 * (k % side) + 1.5, 3.0 * (k // side) + 1.5, 5.0])
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        target = rng.uniform(*gap_range)
        va = world_vertices(shapes[ka], qa, xa)
        r = shapes[ka].circumscribed_radius + shapes[kb].circumscribed_radius
        for _ in range(6):
            g, direction = exact_gap(va, world_vertices(shapes[kb], qb, xa + r * u))
            if abs(g - target) < 1e-4:
                break
            r -= (g - target) / max(u @ direction, 0.2)
        xb = xa + r * u
        exact.append(exact_gap(va, world_vertices(shapes[kb], qb, xb)))
        kinds += [ka, kb]
        pos += [xa, xb]
        quats += [qa, qb]
    state = make_state(shapes, kinds, pos, quats, box=box)
    return state, shapes, exact


def _pair_table(cs: ContactSet) -> dict:
    return {(m["i"], m["j"]): m for m in manifolds(cs)}


def test_gaps_equal_the_exact_distance_and_penetration_depth(rng):
    state, shapes, exact = random_pairs(rng, 400, gap_range=(-0.03, 0.03))
    eps_f = 1e-3 * 2.0 * min(s.circumscribed_radius for s in shapes)
    default = _pair_table(detect(state, ALERT))
    sharp = _pair_table(Detector(eps_f=1e-9).detect(state, ALERT))
    n_sep = n_over = 0
    for k, (g, direction) in enumerate(exact):
        i, j = 2 * k, 2 * k + 1
        if g > ALERT + 1e-9:
            assert (i, j) not in default and (i, j) not in sharp
            continue
        assert (i, j) in default, f"pair {k} with exact gap {g} not found"
        m = default[(i, j)]
        gmin = m["gaps"].min()
        if g > 0.0:
            n_sep += 1
            # the separated gap is the exact distance, along the closest-point direction (j -> i)
            assert gmin == pytest.approx(g, abs=1e-9)
            np.testing.assert_allclose(m["normal"], -direction, atol=1e-6)
            # the point of smallest gap is the midpoint of the closest points
            p = m["points"][np.argmin(m["gaps"])]
            va = world_vertices(shapes[state.kind[i]], state.quaternion[i], state.position[i])
            vb = world_vertices(shapes[state.kind[j]], state.quaternion[j], state.position[j])
            assert point_hull_distance(p, va) == pytest.approx(0.5 * g, abs=1e-7)
            assert point_hull_distance(p, vb) == pytest.approx(0.5 * g, abs=1e-7)
        else:
            n_over += 1
            # interpenetration: the minimum translational distance, up to the axis hysteresis
            assert -g - 1e-9 <= -gmin <= -g + eps_f + 1e-9
            assert sharp[(i, j)]["gaps"].min() == pytest.approx(g, abs=1e-9)
        assert np.all(m["gaps"] <= ALERT + 1e-12)
        assert np.linalg.norm(m["normal"]) == pytest.approx(1.0, abs=1e-12)
    assert n_sep >= 100 and n_over >= 100


def test_swapping_bodies_flips_the_normal_and_keeps_the_gaps(rng):
    state, _, exact = random_pairs(rng, 150)
    swapped = state.copy()
    order = np.arange(state.n).reshape(-1, 2)[:, ::-1].ravel()
    swapped.kind, swapped.position, swapped.quaternion = state.kind[order], state.position[order], state.quaternion[order]
    a, b = _pair_table(detect(state, ALERT)), _pair_table(detect(swapped, ALERT))
    assert a.keys() == b.keys() and len(a) > 100
    for key, m in a.items():
        w = b[key]
        np.testing.assert_allclose(w["normal"], -m["normal"], atol=1e-9)
        np.testing.assert_allclose(np.sort(w["gaps"]), np.sort(m["gaps"]), atol=1e-9)
        # the same points (up to order)
        assert len(w["points"]) == len(m["points"])
        dist = np.linalg.norm(w["points"][:, None, :] - m["points"][None, :, :], axis=2)
        assert dist.min(axis=1).max() < 1e-9 and dist.min(axis=0).max() < 1e-9
