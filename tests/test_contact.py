"""Contact detection (granpack.contact) on hand-built configurations with exact answers.

Every expected value here is computed independently of the detection kernels: feature
placements give gaps, points and normals by construction; random pairs are checked against the
exact distance / penetration depth of two convex polytopes, computed in plain numpy as the
distance from the origin to the boundary of their Minkowski difference (scipy ConvexHull), which
owes nothing to the separating-axis test or to GJK.
"""

from __future__ import annotations

import importlib
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from granpack.box import Box
from granpack.contact import DOUBLE, SIMPLE, TRIPLE, ContactSet, Detector, contact_types, detect
from granpack.contact.broadphase import candidate_pairs
from granpack.rotations import quat_from_axis_angle, quat_multiply, quat_to_matrix, random_quaternions
from granpack.shapes import ConvexPolyhedron, Pinacoid, ShapeTable, Sphere, platonic
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


def overlap_polygon_vertices(pa, pb) -> np.ndarray:
    """Vertices ``(k, 2)`` of the overlap of two convex polygons in the plane: the vertices of each
    inside the other and the crossings of their edges (not ordered)."""

    def cross(u, v):
        return u[0] * v[1] - u[1] * v[0]

    def inside(p, poly):
        k = len(poly)
        sign = np.sign(cross(poly[1] - poly[0], poly[2] - poly[1]))
        return all(sign * cross(poly[(e + 1) % k] - poly[e], p - poly[e]) >= -1e-12 for e in range(k))

    out = [p for p in pa if inside(p, pb)] + [p for p in pb if inside(p, pa)]
    for e in range(len(pa)):
        a0, a1 = pa[e], pa[(e + 1) % len(pa)]
        for f in range(len(pb)):
            b0, b1 = pb[f], pb[(f + 1) % len(pb)]
            den = cross(a1 - a0, b1 - b0)
            if abs(den) < 1e-15:
                continue
            t = cross(b0 - a0, b1 - b0) / den
            u = cross(b0 - a0, a1 - a0) / den
            if 0.0 < t < 1.0 and 0.0 < u < 1.0:
                out.append(a0 + t * (a1 - a0))
    unique = []
    for p in out:
        if all(np.linalg.norm(p - q) > 1e-9 for q in unique):
            unique.append(p)
    return np.array(unique)


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
    np.testing.assert_allclose(m["normal"], -EZ, atol=1e-12)  # from j = 1 (upper) to i = 0
    np.testing.assert_allclose(m["gaps"], gap, atol=1e-12)
    np.testing.assert_allclose(m["points"][:, 2], ca[2] + 0.5 * gap, atol=1e-12)
    for p in m["points"]:
        assert in_polygon(p, pa, EZ) and in_polygon(p, pb, nb)
    # the points are the vertices of the overlap of the two faces, every one of them (a vertex
    # left out would be free to sink when the grain rocks)
    expected = overlap_polygon_vertices(pa[:, :2], pb[:, :2])
    assert len(m["points"]) == len(expected) >= 3
    for p in expected:
        assert np.min(np.linalg.norm(m["points"][:, :2] - p, axis=1)) < 1e-9
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


def _edge_beside_a_flatter_face():
    """A grain (input-frame vertices) whose lowest feature is the edge v0 v1 (along x, at z = 0),
    with both faces of the edge tilted 17 degrees off -z, and beside it a face holding v1 alone,
    tilted 6 degrees: the face most opposed to a floor's normal does not hold the edge (as an edge
    of a scanned grain lying across a neighbour's face)."""
    return np.array([[-0.3, 0.0, 0.0], [0.3, 0.0, 0.0], [0.6, 0.1, 0.03], [0.6, -0.1, 0.03],
                     [-0.3, 0.25, 0.35], [0.3, 0.25, 0.35], [-0.3, -0.25, 0.35], [0.3, -0.25, 0.35]])


@pytest.mark.parametrize("gap", [0.004, -3e-4])
def test_edge_on_face_beside_a_more_opposed_face_keeps_both_edge_ends(gap):
    v = _edge_beside_a_flatter_face()
    sb = ConvexPolyhedron(v, name="edge-beside-a-flatter-face")
    sa = platonic("cube", 2.5)
    qa, pa, ca = face_up(sa)
    # B turned back to its input frame: a vertex v is at x_B + (v - input centroid)
    x, y, z, w = Rotation.from_matrix(sb.rotation.T).as_quat()
    qb = np.array([w, x, y, z])
    ends = v[:2] - sb.input_centroid
    xb = ca + gap * EZ - ends.mean(axis=0)
    np.testing.assert_allclose(world_vertices(sb, qb, xb).min(axis=0)[2], ca[2] + gap, atol=1e-12)
    cs = detect(make_state([sa, sb], [0, 1], [X0, xb], [qa, qb]), ALERT)
    m = pair_manifold(cs)
    # both ends of the edge are points, each at its gap; the far vertices (0.03 d up) are beyond
    # the alert distance
    assert m["ctype"] == DOUBLE
    np.testing.assert_allclose(m["normal"], -EZ, atol=1e-12)
    np.testing.assert_allclose(m["gaps"], gap, atol=1e-12)
    want = ends + xb - 0.5 * gap * EZ
    got = m["points"][np.argsort(m["points"][:, 0])]
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
    default = _pair_table(detect(state, ALERT))
    sharp = _pair_table(Detector(eps_f=1e-9).detect(state, ALERT))
    n_sep = n_over = n_hysteresis = 0
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
            # the separated gap is the exact distance; a single point lies along the closest-point
            # direction (j -> i); a face manifold has the face's normal, close to that direction
            assert gmin == pytest.approx(g, abs=1e-9)
            if len(m["gaps"]) == 1:
                np.testing.assert_allclose(m["normal"], -direction, atol=1e-6)
            else:
                faces = np.vstack([quat_to_matrix(state.quaternion[b]) @ shapes[state.kind[b]].face_normals.T
                                   for b in (i, j)]).reshape(2, 3, -1).transpose(0, 2, 1).reshape(-1, 3)
                assert np.max(np.abs(faces @ m["normal"])) == pytest.approx(1.0, abs=1e-12)
                assert m["normal"] @ -direction > 0.99
            # the point of smallest gap is the midpoint of the closest points
            p = m["points"][np.argmin(m["gaps"])]
            va = world_vertices(shapes[state.kind[i]], state.quaternion[i], state.position[i])
            vb = world_vertices(shapes[state.kind[j]], state.quaternion[j], state.position[j])
            assert point_hull_distance(p, va) == pytest.approx(0.5 * g, abs=1e-7)
            assert point_hull_distance(p, vb) == pytest.approx(0.5 * g, abs=1e-7)
        else:
            n_over += 1
            # interpenetration: the minimum translational distance, also when the axis hysteresis
            # prefers a face axis along which the bodies overlap more
            assert gmin == pytest.approx(g, abs=1e-9)
            assert sharp[(i, j)]["gaps"].min() == pytest.approx(g, abs=1e-9)
            n_hysteresis += abs(m["normal"] @ sharp[(i, j)]["normal"]) < 1.0 - 1e-9
        assert np.all(m["gaps"] <= ALERT + 1e-12)
        assert np.linalg.norm(m["normal"]) == pytest.approx(1.0, abs=1e-12)
    assert n_sep >= 100 and n_over >= 100 and n_hysteresis >= 2


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


def test_antipodal_halves_pick_one_vertex_of_each_pair():
    from granpack.contact.detect import _antipodal_halves

    shapes = ShapeTable.from_shapes([Pinacoid.from_size(1.0, 2.0, 3.0), platonic("tetrahedron", 1.0), Sphere(1.0),
                                     platonic("cube", 1.0)])
    start, half = _antipodal_halves(shapes)
    assert np.diff(start).tolist() == [4, 0, 0, 4]  # the tetrahedron is not centrally symmetric
    for k in (0, 3):
        v = shapes.vertices[shapes.vertex_start[k]:shapes.vertex_start[k + 1]]
        chosen = v[half[start[k]:start[k + 1]]]
        # the chosen vertices and their opposites are all the vertices, each once
        both = np.vstack([chosen, -chosen])
        assert np.abs(np.sort(both, axis=0) - np.sort(v, axis=0)).max() < 1e-12
        assert len(np.unique(np.round(both, 9), axis=0)) == len(v)


def test_symmetric_separating_axis_test_equals_the_general_one(rng):
    """The half-vertex test of centrally symmetric bodies gives the manifolds of the general one."""
    state, _, _ = random_pairs(rng, 300)
    fast = Detector()
    general = Detector()
    general.detect(state, ALERT)
    general._tables.half_start[:] = 0  # every kind treated as not symmetric
    a, b = _pair_table(fast.detect(state, ALERT)), _pair_table(general.detect(state, ALERT))
    assert fast._tables.half.size > 0 and a.keys() == b.keys() and len(a) > 150
    for key, m in a.items():
        np.testing.assert_allclose(b[key]["normal"], m["normal"], atol=1e-12)
        np.testing.assert_allclose(b[key]["gaps"], m["gaps"], atol=1e-12)
        np.testing.assert_allclose(b[key]["points"], m["points"], atol=1e-12)


def _axis_of_code(state, code, a, b) -> np.ndarray:
    """World unit axis of a separating-axis code of the pair (A = ``a``, B = ``b``): face axes of
    A, then of B, then the edge-direction pairs of A and B, row-major (``separating_axes._sat``)."""
    s = state.shapes

    def axes(body):
        k, rot = state.kind[body], quat_to_matrix(state.quaternion[body])
        face = s.face_axes[s.axis_start[k]:s.axis_start[k + 1]] @ rot.T
        return face, s.edge_directions[s.direction_start[k]:s.direction_start[k + 1]] @ rot.T

    (fa, da), (fb, db) = axes(a), axes(b)
    if code < len(fa):
        return fa[code]
    if code < len(fa) + len(fb):
        return fb[code - len(fa)]
    i, j = divmod(code - len(fa) - len(fb), len(db))
    c = np.cross(da[i], db[j])
    return c / np.linalg.norm(c)


def test_cached_separating_axis_separates_the_pair(rng):
    """The axis kept per candidate pair is one along which the pair is separated beyond the alert."""
    state, shapes, _ = random_pairs(rng, 300, gap_range=(0.021, 0.1))
    det = Detector(skin=0.5)
    assert det.detect(state, ALERT).n_manifolds == 0
    codes, pair_start, pair_j = det._pair_axis.copy(), det.verlet.pair_start, det.verlet.pair_j
    kinds = []
    for i in range(state.n):
        for q in range(pair_start[i], pair_start[i + 1]):
            j, code = pair_j[q], codes[q]
            if code < 0:  # separated along the centre line
                continue
            u = _axis_of_code(state, code, a=j, b=i)
            pa = world_vertices(shapes[state.kind[j]], state.quaternion[j], state.position[j]) @ u
            pb = world_vertices(shapes[state.kind[i]], state.quaternion[i], state.position[i]) @ u
            assert max(pb.min() - pa.max(), pa.min() - pb.max()) > ALERT
            n_faces = sum(np.diff(state.shapes.axis_start)[state.kind[[j, i]]])
            kinds.append("edge" if code >= n_faces else "face")
    # face and edge axes both occur, and the next call, unmoved, keeps them (found first)
    assert kinds.count("face") > 50 and kinds.count("edge") > 20
    assert det.detect(state, ALERT).n_manifolds == 0 and det.n_builds == 1
    np.testing.assert_array_equal(det._pair_axis, codes)


# ---------------------------------------------------------------------------------------------
# periodic images


def face_face_pair(size_a=1.0, size_b=1.0, gap=0.004, fam=(1.0, 1.0)):
    """Positions and orientations of a face-on-face pair (B on top of A at ``X0``)."""
    sa, sb = Pinacoid.from_size(size_a, *fam), Pinacoid.from_size(size_b, *fam)
    qa, pa, ca = face_up(sa, spin=0.2)
    fb = largest_face(sb)
    qb = then(rot_to(sb.face_normals[fb], -EZ), spin_z(0.9))
    pb0, _ = face_polygon(sb, fb, qb, np.zeros(3))
    xb = ca + gap * EZ - pb0.mean(axis=0)
    return [sa, sb], np.array([X0, xb]), np.array([qa, qb])


@pytest.mark.parametrize("corner", [(1, 0), (0, 1), (1, 1)])
def test_pair_across_the_periodic_boundary_is_found_once_with_its_shift(corner):
    box = 5.0
    shapes, pos, quat = face_face_pair()
    # tilt the pair so that it is not aligned with z, then lay it across the boundary
    tilt = quat_from_axis_angle([1.0, 1.0, 0.0], 1.1)
    centre = pos.mean(axis=0)
    pos = centre + (pos - centre) @ quat_to_matrix(tilt).T
    quat = np.array([then(q, tilt) for q in quat])
    ref = detect(make_state(shapes, [0, 1], pos, quat, box=box), ALERT)
    m_ref = pair_manifold(ref)
    # move the pair's midpoint onto the boundary (x = 0 and/or y = 0), then wrap
    target = np.array([box / 2, box / 2, pos[0, 2]])
    target[0] = 0.0 if corner[0] else target[0]
    target[1] = 0.0 if corner[1] else target[1]
    moved = pos + (target - centre)
    wrapped = Box.square(box).wrap(moved)
    image = wrapped - moved  # multiples of the period
    cross = np.abs(image[0] - image[1]) > 0
    assert np.array_equal(cross[:2], np.array(corner, bool))  # the two grains sit on both sides
    cs = detect(make_state(shapes, [0, 1], wrapped, quat, box=box), ALERT)
    assert cs.n_manifolds == 1
    m = pair_manifold(cs)
    # x_j + shift is the image of j next to i
    np.testing.assert_allclose(m["shift"], image[0] - image[1], atol=1e-12)
    np.testing.assert_allclose(wrapped[1] + m["shift"] - wrapped[0], pos[1] - pos[0], atol=1e-12)
    np.testing.assert_allclose(m["normal"], m_ref["normal"], atol=1e-12)
    np.testing.assert_allclose(m["gaps"], m_ref["gaps"], atol=1e-12)
    np.testing.assert_allclose(m["points"], m_ref["points"] + (wrapped[0] - pos[0]), atol=1e-12)
    assert m["ctype"] == m_ref["ctype"] == TRIPLE


def test_box_too_small_for_one_image_is_refused():
    shapes, pos, quat = face_face_pair()
    with pytest.raises(ValueError, match="too small"):
        detect(make_state(shapes, [0, 1], pos - X0 + 1.0, quat, box=2.0), ALERT)
    with pytest.raises(ValueError, match="alert"):
        detect(make_state(shapes, [0, 1], pos, quat), -0.1)


@pytest.mark.parametrize("sizes", [(1.0,), (1.0, 1.0 / 3.0)])
@pytest.mark.parametrize("periods", [(2.3, 2.3), (4.1, 2.3), (7.9, 6.2)])
def test_candidate_pairs_are_all_close_pairs_once(rng, sizes, periods):
    """Grid search (half shell for equal grains) against all pairs, boxes narrow and wide."""
    lx, ly = periods
    n = 300
    radius = 0.5 * rng.choice(sizes, size=n)
    pos = np.c_[rng.uniform(-lx, 2 * lx, n), rng.uniform(-ly, 2 * ly, n), rng.uniform(0.0, 3.0, n)]
    cutoff = 0.07
    pair_start, pair_j = candidate_pairs(pos, radius, lx, ly, cutoff)
    i, j = np.triu_indices(n, k=1)
    d = pos[i] - pos[j]
    d[:, 0] -= lx * np.floor(d[:, 0] / lx + 0.5)
    d[:, 1] -= ly * np.floor(d[:, 1] / ly + 0.5)
    close = np.einsum("ij,ij->i", d, d) < (radius[i] + radius[j] + cutoff) ** 2
    expected = np.zeros(n + 1, np.int64)
    np.add.at(expected, i[close] + 1, 1)
    np.testing.assert_array_equal(pair_start, np.cumsum(expected))
    np.testing.assert_array_equal(pair_j, j[close])  # rows sorted, each pair once


# ---------------------------------------------------------------------------------------------
# the bottom wall


@pytest.mark.parametrize("fam", FAMILIES)
@pytest.mark.parametrize("size", SIZES)
@pytest.mark.parametrize("gap", [0.003, -0.002])
def test_grain_on_the_wall_by_a_face_is_triple(fam, size, gap):
    sh = Pinacoid.from_size(size, *fam)
    f = largest_face(sh)
    q = then(rot_to(sh.face_normals[f], -EZ), spin_z(0.4))
    x = np.array([2.0, 3.0, sh.face_offsets[f] + gap])
    cs = detect(make_state([sh], [0], [x], [q]), ALERT)
    assert cs.n_manifolds == 1
    m = manifolds(cs)[0]
    assert (m["i"], m["j"], m["ctype"]) == (0, -1, TRIPLE)
    np.testing.assert_allclose(m["normal"], EZ)
    np.testing.assert_allclose(m["shift"], 0.0)
    poly, _ = face_polygon(sh, f, q, x)
    assert len(m["gaps"]) == len(poly)
    np.testing.assert_allclose(m["gaps"], gap, atol=1e-12)
    expected = poly.copy()
    expected[:, 2] = 0.5 * gap
    got = m["points"]
    assert np.linalg.norm(got[:, None, :] - expected[None], axis=2).min(axis=1).max() < 1e-12


def test_grain_on_the_wall_by_an_edge_or_a_vertex():
    sh = Pinacoid.from_size(1.0, 2.0, 3.0)
    gap = 0.005
    e = shortest_edge(sh)
    q = edge_down(sh, e, [1.0, 0.0, 0.0])
    v = world_vertices(sh, q, np.zeros(3))
    x = np.array([3.0, 3.0, gap - v[:, 2].min()])
    m = manifolds(detect(make_state([sh], [0], [x], [q]), ALERT))[0]
    assert m["ctype"] == DOUBLE and len(m["gaps"]) == 2
    ends = v[sh.edges[e]] + x
    ends[:, 2] = 0.5 * gap
    np.testing.assert_allclose(m["points"][np.argsort(m["points"][:, 0])], ends[np.argsort(ends[:, 0])], atol=1e-12)
    np.testing.assert_allclose(m["gaps"], gap, atol=1e-12)
    q = rot_to(feature_down(sh, vertex_faces(sh, 0)), -EZ)
    v = world_vertices(sh, q, np.zeros(3))
    x = np.array([3.0, 3.0, gap - v[:, 2].min()])
    m = manifolds(detect(make_state([sh], [0], [x], [q]), ALERT))[0]
    assert m["ctype"] == SIMPLE and len(m["gaps"]) == 1
    np.testing.assert_allclose(m["points"][0], [*(x + v[0])[:2], 0.5 * gap], atol=1e-12)
    # lifted beyond the alert distance: no wall contact
    x[2] += ALERT
    assert detect(make_state([sh], [0], [x], [q]), ALERT).n_manifolds == 0


# ---------------------------------------------------------------------------------------------
# spheres


@pytest.mark.parametrize("gap", [0.01, 0.0, -0.004])
def test_sphere_sphere_and_sphere_wall(rng, gap):
    d_i, d_j = 1.0 / 3.0, 1.0
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    xj = X0
    xi = xj + (0.5 * (d_i + d_j) + gap) * u
    cs = detect(make_state([Sphere(d_i), Sphere(d_j)], [0, 1], [xi, xj], np.tile([1.0, 0, 0, 0], (2, 1))), ALERT)
    m = pair_manifold(cs)
    assert m["ctype"] == SIMPLE
    np.testing.assert_allclose(m["normal"], u, atol=1e-12)  # from j to i
    np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
    np.testing.assert_allclose(m["points"][0], xj + (0.5 * d_j + 0.5 * gap) * u, atol=1e-12)
    # on the wall
    x = np.array([1.0, 2.0, 0.5 * d_i + gap])
    m = manifolds(detect(make_state([Sphere(d_i)], [0], [x], [[1.0, 0, 0, 0]]), ALERT))[0]
    assert (m["j"], m["ctype"]) == (-1, SIMPLE)
    np.testing.assert_allclose(m["normal"], EZ)
    np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
    np.testing.assert_allclose(m["points"][0], [1.0, 2.0, 0.5 * gap], atol=1e-12)


def _sphere_poly_case(where, gap, radius):
    """Polyhedron at X0 (identity), sphere centre and the expected closest point and normal."""
    sh = Pinacoid.from_size(1.0, 2.0, 1.0)
    v = sh.vertices
    if where == "face":
        f = largest_face(sh)
        anchor = v[sh.faces[f]].mean(axis=0)
        n = sh.face_normals[f]
    elif where == "edge":
        e = shortest_edge(sh)
        anchor = v[sh.edges[e]].mean(axis=0)
        n = feature_down(sh, edge_faces(sh, e))
    else:
        anchor = v[4]
        n = feature_down(sh, vertex_faces(sh, 4))
    return sh, X0 + anchor + (radius + gap) * n, X0 + anchor, n


@pytest.mark.parametrize("where", ["face", "edge", "vertex"])
@pytest.mark.parametrize("gap", [0.008, -0.003])
@pytest.mark.parametrize("sphere_first", [True, False])
def test_sphere_polyhedron_exact_gap_and_normal(where, gap, sphere_first):
    radius = 1.0 / 6.0
    sh, centre, closest, n = _sphere_poly_case(where, gap, radius)
    # overlapping (gap < 0) with the centre still outside: the gap is the centre's distance minus R
    shapes = [Sphere(2 * radius), sh]
    if sphere_first:
        state = make_state(shapes, [0, 1], [centre, X0], [[1.0, 0, 0, 0]] * 2)
        sign = 1.0  # normal from j (polyhedron) to i (sphere)
    else:
        state = make_state(shapes, [1, 0], [X0, centre], [[1.0, 0, 0, 0]] * 2)
        sign = -1.0
    m = pair_manifold(detect(state, ALERT))
    assert m["ctype"] == SIMPLE and len(m["gaps"]) == 1
    np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
    np.testing.assert_allclose(m["normal"], sign * n, atol=1e-12)
    np.testing.assert_allclose(m["points"][0], closest + 0.5 * gap * n, atol=1e-12)


@pytest.mark.parametrize("sphere_first", [True, False])
def test_sphere_centre_inside_a_polyhedron(sphere_first):
    radius = 0.1
    sh = Pinacoid.from_size(1.0, 1.0, 1.0)
    f = largest_face(sh)
    n = sh.face_normals[f]
    depth = 0.03  # centre this far inside face f, much deeper inside every other face
    centre = X0 + sh.vertices[sh.faces[f]].mean(axis=0) - depth * n
    inside = sh.face_offsets - sh.face_normals @ (centre - X0)
    assert np.argmin(inside) == f and inside.min() == pytest.approx(depth)
    shapes = [Sphere(2 * radius), sh]
    if sphere_first:
        state, sign = make_state(shapes, [0, 1], [centre, X0], [[1.0, 0, 0, 0]] * 2), 1.0
    else:
        state, sign = make_state(shapes, [1, 0], [X0, centre], [[1.0, 0, 0, 0]] * 2), -1.0
    m = pair_manifold(detect(state, ALERT))
    np.testing.assert_allclose(m["gaps"], [-(depth + radius)], atol=1e-12)
    np.testing.assert_allclose(m["normal"], sign * n, atol=1e-12)
    # the point is the midpoint between the face and the sphere's far side along n
    face_point = centre + depth * n
    np.testing.assert_allclose(m["points"][0], face_point - 0.5 * (depth + radius) * n, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# Verlet skin


def dense_lattice(rng, n_side=4, layers=3, spacing=0.62, mixed=True) -> ParticleState:
    """Jittered cubic lattice of randomly oriented pinacoids (and a few small spheres) near contact."""
    shapes = [Pinacoid.from_size(1.0), Pinacoid.from_size(1.0 / 3.0, 2.0, 3.0), Sphere(1.0 / 3.0)]
    cells = np.array(list(itertools.product(range(n_side), range(n_side), range(layers))), float)
    pos = (cells + 0.5) * spacing + rng.uniform(-0.05, 0.05, size=cells.shape)
    pos[:, 2] += 0.05
    n = len(pos)
    kinds = rng.choice(3, size=n, p=[0.7, 0.2, 0.1]) if mixed else np.zeros(n, np.int64)
    box = max(n_side * spacing, 4.3)
    return make_state(shapes, kinds, Box.square(box).wrap(pos), random_quaternions(n, rng), box=box)


def test_verlet_skin_gives_the_same_contacts_as_skin_zero(rng):
    state = dense_lattice(rng, n_side=7, layers=3)
    verlet = Detector(skin=0.06)
    previous = None
    steps = 40
    n_contacts = []
    for _ in range(steps):
        state.position = state.box.wrap(state.position + rng.normal(scale=0.004, size=state.position.shape))
        turn = [quat_from_axis_angle(rng.normal(size=3), rng.normal(scale=0.01)) for _ in range(state.n)]
        state.quaternion = np.array([then(q, t) for q, t in zip(state.quaternion, turn)])
        ref = detect(state, ALERT, previous)
        got = verlet.detect(state, ALERT, previous)
        for name in ("body_i", "body_j", "shift", "normal", "ctype", "point_start", "point", "gap"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
        assert verlet.n_tested <= verlet.n_candidates
        n_contacts.append(ref.n_manifolds)
        previous = ref
    assert min(n_contacts) > state.n  # a dense configuration
    assert 2 <= verlet.n_builds < steps // 2  # the list was reused, and rebuilt when grains moved


@pytest.mark.parametrize("mixed", [False, True])
def test_threaded_narrow_phase_gives_the_contacts_of_one_thread(rng, monkeypatch, mixed):
    """Row ranges tested by three threads, concatenated: the manifolds, points and axis caches of one
    thread, step after step (with the previous step's normals), for pinacoids and a mix with spheres."""
    detect_module = importlib.import_module("granpack.contact.detect")
    monkeypatch.setattr(detect_module, "_PAIRS_PER_THREAD", 1)
    state = dense_lattice(rng, n_side=7, layers=3, mixed=mixed)
    one, three = Detector(skin=0.06, threads=1), Detector(skin=0.06, threads=3)
    previous = None
    for _ in range(5):
        state.position = state.box.wrap(state.position + rng.normal(scale=0.004, size=state.position.shape))
        ref = one.detect(state, ALERT, previous)
        got = three.detect(state, ALERT, previous)
        for name in ("body_i", "body_j", "shift", "normal", "ctype", "point_start", "point", "gap"):
            np.testing.assert_array_equal(getattr(got, name), getattr(ref, name), err_msg=name)
        np.testing.assert_array_equal(three._pair_axis, one._pair_axis)
        assert three.n_tested == one.n_tested
        previous = ref
    assert len(detect_module._row_ranges(three.verlet.pair_start, 3)) == 4  # three ranges were used
    assert ref.n_manifolds > state.n


# ---------------------------------------------------------------------------------------------
# contact types from the rank of the manifold


def _one_manifold(points, normal) -> ContactSet:
    points = np.asarray(points, float).reshape(-1, 3)
    k = len(points)
    return ContactSet(body_i=np.zeros(1, np.int64), body_j=np.ones(1, np.int64), shift=np.zeros((1, 3)),
                      normal=np.asarray(normal, float).reshape(1, 3), ctype=np.zeros(1, np.int64),
                      point_start=np.array([0, k], np.int64), point=points, gap=np.zeros(k))


def _tangent_frame(normal):
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    t = np.cross(n, [0.3, 0.5, 0.7])
    t /= np.linalg.norm(t)
    return n, t, np.cross(n, t)


@pytest.mark.parametrize("normal", [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.3, -0.8, 0.5)])
def test_contact_types_of_hand_built_manifolds(normal):
    n, t, s = _tangent_frame(normal)
    c = np.array([1.0, 2.0, 3.0])
    eps = 1e-3
    cases = [
        ([c], SIMPLE),  # one point
        ([c, c + 0.2 * t], DOUBLE),  # segment
        ([c, c + 0.1 * t, c + 0.2 * t], DOUBLE),  # collinear points
        ([c + 0.1 * a * t + 0.1 * b * s for a in (-1, 1) for b in (-1, 1)], TRIPLE),  # square
        ([c, c + 0.2 * t, c + 0.1 * t + 0.05 * s], TRIPLE),  # triangle
        ([c, c + 0.3 * n], SIMPLE),  # spread only along the normal: one point in the tangent plane
        ([c, c + 2e-4 * t, c + 2e-4 * s], SIMPLE),  # within the tolerance
        ([c, c + 0.2 * t, c + 0.2 * t + 2e-4 * s, c + 2e-4 * s], DOUBLE),  # a thin sliver
        ([c + 0.1 * a * t + 0.1 * b * s + 0.01 * a * n for a in (-1, 1) for b in (-1, 1)], TRIPLE),  # tilted
    ]
    for pts, expected in cases:
        assert contact_types(_one_manifold(pts, n), eps)[0] == expected, (pts, expected)


def test_contact_types_with_a_mask_and_consistency_with_detection(rng):
    n, t, s = _tangent_frame((0.0, 0.0, 1.0))
    pts = [np.zeros(3), 0.2 * t, 0.2 * s, 0.2 * (t + s)]
    cs = _one_manifold(pts, n)
    cs.gap = np.array([0.0, 0.0, 0.01, 0.01])
    assert contact_types(cs, 1e-3, mask=cs.gap <= 1e-3)[0] == DOUBLE
    assert contact_types(cs, 1e-3, mask=np.array([True, False, False, False]))[0] == SIMPLE
    assert contact_types(cs, 1e-3, mask=np.zeros(4, bool))[0] == 0
    assert contact_types(cs, 1e-3)[0] == TRIPLE
    with pytest.raises(ValueError, match="one entry per point"):
        contact_types(cs, 1e-3, mask=np.ones(3, bool))
    # detection's ctype is the rank of all its points
    state = dense_lattice(rng, n_side=5, layers=2)
    det = detect(state, ALERT)
    np.testing.assert_array_equal(contact_types(det, 1e-3 / 3.0), det.ctype)


def tilted_face_face_pair(gap, tilt):
    """:func:`face_face_pair` with the upper grain turned by ``tilt`` (rad) about a horizontal
    axis through its contact face's centre."""
    shapes, pos, quat = face_face_pair(gap=gap)
    r = quat_from_axis_angle([1.0, 0.3, 0.0], tilt)
    contact = pos[1] + quat_to_matrix(quat[1]) @ shapes[1].vertices[shapes[1].faces[largest_face(shapes[1])]].mean(0)
    pos[1] = contact + quat_to_matrix(r) @ (pos[1] - contact)
    quat[1] = then(quat[1], r)
    return shapes, pos, quat


@pytest.mark.parametrize("tilt", [0.002, 0.01])
def test_slightly_tilted_face_on_face_is_still_triple(tilt):
    shapes, pos, quat = tilted_face_face_pair(0.002, tilt)
    m = pair_manifold(detect(make_state(shapes, [0, 1], pos, quat), ALERT))
    assert m["ctype"] == TRIPLE and len(m["gaps"]) >= 3
    assert np.ptp(m["gaps"]) > 0.0  # the gaps differ along the tilt
    assert np.all(m["gaps"] <= ALERT)


@pytest.mark.parametrize("tilt", [0.002, 0.01])
def test_tilted_face_on_face_stays_triple_whatever_the_previous_edge_normal(tilt):
    """A face-face contact reached through an edge-edge contact keeps its face manifold.

    Any edge-edge axis of two faces in contact is nearly the face normal. With such an axis as
    the previous step's normal, the temporal hysteresis must still give the face manifold (all
    its corners, as without a previous normal), not a one-point edge-edge contact that leaves
    the corners free to sink. (Its reference face may be the other body's.)
    """
    shapes, pos, quat = tilted_face_face_pair(-0.001, tilt)
    state = make_state(shapes, [0, 1], pos, quat)
    fresh = pair_manifold(detect(state, ALERT))
    assert fresh["ctype"] == TRIPLE and len(fresh["gaps"]) >= 3
    faces = [EZ, quat_to_matrix(quat[1]) @ shapes[1].face_normals[largest_face(shapes[1])]]
    directions = []
    for body in (0, 1):
        v, rot = shapes[body].vertices, quat_to_matrix(quat[body])
        directions.append([rot @ (v[b] - v[a]) for a, b in shapes[body].edges])
    tried = 0
    for da, db in itertools.product(*directions):
        axis = np.cross(da, db)
        if np.linalg.norm(axis) < 1e-9:
            continue
        axis /= np.linalg.norm(axis)
        cos = float(axis @ fresh["normal"])
        if not 0.999 < abs(cos) < 1.0 - 1e-12:  # a distinct edge axis within the hysteresis cone
            continue
        tried += 1
        m = pair_manifold(detect(state, ALERT, _one_manifold([pos[0]], np.sign(cos) * axis)))
        assert m["ctype"] == TRIPLE and len(m["gaps"]) >= 3
        assert max(abs(m["normal"] @ f) for f in faces) > 1.0 - 1e-12  # a face axis, not the edge axis
    assert tried >= 10


# ---------------------------------------------------------------------------------------------
# property-based: other convex polyhedra


@settings(max_examples=60, deadline=None)
@given(
    names=st.tuples(st.sampled_from(["cube", "tetrahedron", "octahedron", "pinacoid"]),
                    st.sampled_from(["cube", "tetrahedron", "dodecahedron", "pinacoid"])),
    seed=st.integers(0, 2**32 - 1),
    target=st.floats(-0.03, 0.015).filter(lambda t: abs(t) > 1e-3),  # exactly touching: no direction
)
def test_polyhedra_gap_property(names, seed, target):
    rng = np.random.default_rng(seed)
    shapes = [Pinacoid.from_size(1.0, 2.0, 3.0) if n == "pinacoid" else platonic(n, 1.0) for n in names]
    qa, qb = random_quaternions(2, rng)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    va = world_vertices(shapes[0], qa, X0)
    r = shapes[0].circumscribed_radius + shapes[1].circumscribed_radius
    for _ in range(8):
        g, direction = exact_gap(va, world_vertices(shapes[1], qb, X0 + r * u))
        r -= (g - target) / max(u @ direction, 0.2)
    xb = X0 + r * u
    g, direction = exact_gap(va, world_vertices(shapes[1], qb, xb))
    cs = Detector(eps_f=1e-9).detect(make_state(shapes, [0, 1], [X0, xb], [qa, qb]), ALERT)
    if g > ALERT:
        assert cs.n_manifolds == 0
        return
    m = pair_manifold(cs)
    assert m["gaps"].min() == pytest.approx(g, abs=1e-9)
    if len(m["gaps"]) == 1 and g > 0:
        np.testing.assert_allclose(m["normal"], -direction, atol=1e-6)


def test_merge_points_drops_only_duplicates_and_keeps_the_deeper_gap():
    from granpack.contact.manifold import _merge_points

    angles = np.arange(8) * math.pi / 4 + 0.1
    ring = np.c_[np.cos(angles), np.sin(angles), np.full(8, 0.3)]
    pts = np.vstack([ring, ring[5] + 1e-9, ring[2] - 1e-9])  # duplicates of points 5 and 2
    gp = np.array([0.01, 0.02, 0.0, -0.01, 0.015, 0.012, 0.01, 0.005, -0.02, 0.03])
    kept, kept_gaps = pts.copy(), gp.copy()
    cnt = _merge_points(kept, kept_gaps, len(pts), 1e-6)
    assert cnt == 8  # every distinct vertex of the octagon stays
    np.testing.assert_array_equal(kept[:8], ring)
    expected = gp[:8].copy()
    expected[5] = -0.02  # the deeper gap of the merged pair
    np.testing.assert_array_equal(kept_gaps[:8], expected)


# ---------------------------------------------------------------------------------------------
# temporal axis hysteresis: two bands


def _flicker_pair() -> ParticleState:
    """Two isometric pinacoids of a settled pile (interpenetrating by 2.35e-5 d) whose best axis is
    an edge-edge one and whose next face axis (0.67 degrees from it) separates them 1.0e-3 d less."""
    return make_state(
        [Pinacoid.from_size(1.0)], [0, 0],
        [[0.24198513454644313, 1.2159749204581183, 4.536182570625141],
         [0.4826593550127663, 1.2593438018564944, 5.125825527351792]],
        [[0.03904431644091875, -0.41220659985244157, -0.6785846949032701, 0.6066993260543366],
         [-0.7348805650007875, 0.032860228270470075, 0.04133338216626628, 0.6761377907651912]],
        box=3.0,
    )


def test_previous_axis_stays_the_normal_within_twice_the_band():
    """An axis that was the previous normal stays a candidate within 2 eps_f of the best separation
    (others within eps_f): with one band, an axis at its edge flickered in and out from step to
    step in a pile at rest, the manifold's normal and force turning with it."""
    state = _flicker_pair()
    detector = Detector(eps_f=7e-4)  # the face axis is 1.0e-3 d worse: outside eps_f, inside 2 eps_f
    fresh = detector.detect(state, 0.02)
    edge = pair_manifold(fresh)
    assert edge["ctype"] == SIMPLE and len(edge["gaps"]) == 1  # the edge-edge axis, one point
    face_normal = np.array([-0.6930802, -0.1327286, -0.7085358])
    assert 0.999 < abs(edge["normal"] @ face_normal) < 0.99995
    previous = ContactSet(**{**fresh.__dict__, "normal": np.array(fresh.normal, float)})
    previous.normal[0] = face_normal / np.linalg.norm(face_normal)
    kept = pair_manifold(Detector(eps_f=7e-4).detect(state, 0.02, previous=previous))
    assert abs(kept["normal"] @ face_normal) > 1 - 1e-9
    assert kept["gaps"].min() == pytest.approx(edge["gaps"].min(), abs=1e-12)  # the exact depth either way
    kept_set = Detector(eps_f=7e-4).detect(state, 0.02, previous=previous)
    again = pair_manifold(Detector(eps_f=7e-4).detect(state, 0.02, previous=kept_set))
    assert np.allclose(again["normal"], kept["normal"], atol=1e-12)  # a fixed point: no flicker


@pytest.mark.parametrize("eps_f, kept", [(2.2e-4, True), (1.8e-4, False)])
def test_previous_axis_is_kept_within_five_bands_and_left_beyond(eps_f, kept):
    """The kept band is 5 eps_f: the face axis 1.0e-3 d worse than the best (edge) axis stays the
    normal at eps_f = 2.2e-4 d (4.5 bands; a band of 2 eps_f lost it) and is left for the edge
    axis at 1.8e-4 d (5.6 bands). A narrow loop between the bands fed a grain sliding between
    parallel faces energy at each swing, and the pile never came to rest."""
    state = _flicker_pair()
    face_normal = np.array([-0.6930802, -0.1327286, -0.7085358])
    face_normal /= np.linalg.norm(face_normal)
    fresh = Detector(eps_f=eps_f).detect(state, 0.02)
    previous = ContactSet(**{**fresh.__dict__, "normal": np.array(fresh.normal, float)})
    previous.normal[0] = face_normal
    m = pair_manifold(Detector(eps_f=eps_f).detect(state, 0.02, previous=previous))
    if kept:
        assert abs(m["normal"] @ face_normal) > 1 - 1e-9 and len(m["gaps"]) > 1
    else:
        assert abs(m["normal"] @ face_normal) < 0.99995 and m["ctype"] == SIMPLE and len(m["gaps"]) == 1


def _grains_placed(*world: np.ndarray) -> ParticleState:
    """Grains given by their world vertices (d), each at its centroid with the orientation that
    puts its body frame there: a pair of a settled pile rebuilt from its vertices."""
    shapes, positions, quaternions = [], [], []
    for vertices in world:
        shape = ConvexPolyhedron(vertices)
        x, y, z, w = Rotation.from_matrix(shape.rotation.T).as_quat()
        shapes.append(shape)
        positions.append(shape.input_centroid)
        quaternions.append([w, x, y, z])
    return make_state(shapes, list(range(len(world))), positions, quaternions)


# the scan pile's pair whose kept face axis put a point beside the face, outside the other grain
_KEPT_AXIS_LOWER = np.array([
    [0.152668942, 0.280082552, -0.374653412],
    [0.280649103, 0.115351004, -0.348397572],
    [0.147498705, 0.161980701, -0.263129443],
    [0.405999652, -0.173486030, -0.414787766],
    [0.322160106, 0.077053550, -0.517793844],
    [0.378670004, -0.246555682, -0.551483874],
    [0.195297617, -0.024005882, -0.678924092],
    [0.020399332, 0.238010182, -0.597529407],
    [-0.043382051, 0.328683664, -0.393615778],
    [0.284938926, -0.189147197, -0.215655949],
    [0.259683525, -0.567310998, -0.333266215],
    [-0.202360202, 0.186461536, -0.486424643],
    [-0.198769963, 0.212473460, -0.360875060],
    [-0.153714546, -0.075000736, -0.646680110],
    [0.135068177, -0.605134569, -0.581684103],
    [-0.002920950, -0.597428845, -0.325661130],
    [-0.220954203, -0.146940913, -0.243016506],
    [-0.179547415, -0.471622219, -0.422717730],
    [-0.279781673, -0.159167241, -0.451742618],
    [-0.025387317, -0.493766323, -0.603229966],
    [0.075827087, -0.301269050, -0.167625934],
    [-0.099765282, 0.109447934, -0.221034164],
    [0.133401913, -0.412503141, -0.664093382],
    [0.349462981, -0.505415477, -0.490641208],
])
_KEPT_AXIS_UPPER = np.array([
    [-0.077071689, -0.233987710, -0.134157298],
    [-0.156040548, -0.353279219, -0.037802824],
    [0.054895044, -0.333222759, -0.036661772],
    [0.144385217, -0.143400839, -0.204558431],
    [0.332240345, -0.088455945, -0.122208595],
    [0.021781146, -0.317289876, 0.157858144],
    [-0.263220763, -0.379613311, 0.208935491],
    [-0.373013715, -0.333247888, 0.154185996],
    [0.272935598, 0.040160522, -0.255615531],
    [-0.358318502, -0.087468583, -0.012761199],
    [-0.437526734, -0.126317123, 0.225815445],
    [-0.170913458, -0.114950261, 0.290850072],
    [0.187007446, -0.085472789, 0.119243650],
    [0.364081938, 0.147019847, -0.062380854],
    [0.118650802, 0.345088043, -0.176338602],
    [-0.127822014, 0.202012273, -0.125280896],
    [-0.289564188, 0.197802400, 0.074712204],
    [-0.004488145, 0.363913482, 0.049429298],
    [-0.154281866, 0.141629623, 0.242139003],
    [0.148219251, 0.321702092, 0.071316214],
    [0.273405015, 0.361153414, -0.148130812],
    [0.047896555, 0.087988959, -0.238178293],
    [0.097917462, 0.167164065, 0.164431630],
    [0.345632633, 0.212425393, -0.213387018],
])
_KEPT_AXIS_PREVIOUS_NORMAL = np.array([np.float64(-0.1159212075552653), np.float64(-0.18998639931353056), np.float64(-0.9749191975311644)])


def test_a_face_axis_kept_by_the_hysteresis_puts_every_point_where_the_grains_meet():
    """Two scan-like grains of a pile near rest (24 vertices each), overlapping by 1.804e-3 d along
    the lower grain's face; the previous normal is the upper grain's face 0.8 degrees away, along
    which the lower grain seems to overlap 3.7e-3 d: its deepest vertex lies below that face's
    plane but beside the face, 0.06 d outside the upper grain. The kept manifold's deepest point was
    that vertex (a force where the grains do not touch, while the vertex that is truly deepest had
    no point and sank step after step); it must be the point where the grains are 1.804e-3 d deep,
    and every point must lie within half its gap of both grains."""
    state = _grains_placed(_KEPT_AXIS_LOWER + X0, _KEPT_AXIS_UPPER + X0)
    fresh = Detector().detect(state, 0.02)
    depth = -pair_manifold(fresh)["gaps"].min()
    assert depth == pytest.approx(1.804e-3, abs=1e-6)
    assert abs(pair_manifold(fresh)["normal"] @ _KEPT_AXIS_PREVIOUS_NORMAL) < 0.99995  # another axis
    previous = ContactSet(**{**fresh.__dict__, "normal": np.array(fresh.normal, float)})
    previous.normal[0] = _KEPT_AXIS_PREVIOUS_NORMAL
    kept = pair_manifold(Detector().detect(state, 0.02, previous=previous))
    assert abs(kept["normal"] @ _KEPT_AXIS_PREVIOUS_NORMAL) > 1 - 1e-9  # the hysteresis keeps the axis
    assert kept["gaps"].min() == pytest.approx(-depth, abs=1e-12)
    for point, gap in zip(kept["points"], kept["gaps"]):
        for vertices in (_KEPT_AXIS_LOWER, _KEPT_AXIS_UPPER):
            assert point_hull_distance(point, vertices + X0) <= 0.5 * abs(gap) + 1e-9


# the scan pile's separated pair whose kept face axis gave overlapping points
_SEPARATED_LOWER = np.array([
    [0.366597818, -0.084567340, -0.188252713],
    [0.132655501, 0.133253976, -0.370478048],
    [0.083761801, -0.085181291, -0.214993488],
    [-0.195454396, -0.089364516, -0.453626818],
    [0.064175383, -0.311080205, -0.295461853],
    [0.303774787, -0.379911746, -0.241958755],
    [0.494242369, -0.159196140, -0.226990573],
    [-0.197887723, 0.138194560, -0.727683508],
    [0.009737526, 0.220381695, -0.654671168],
    [0.490541873, 0.002313175, -0.371632138],
    [0.556419089, -0.362263384, -0.392658946],
    [-0.204976040, -0.137259511, -0.824011171],
    [0.171849710, 0.136040208, -0.905580351],
    [0.291647956, -0.070566168, -0.972620791],
    [0.492440201, -0.169480083, -0.770667545],
    [0.151265041, -0.219852370, -0.969935239],
    [-0.016419541, -0.240757300, -0.921107007],
    [-0.112550240, -0.065925911, -0.994340657],
    [-0.102393687, 0.098959320, -0.952612710],
    [0.221964993, 0.192253337, -0.694654162],
    [0.594464976, -0.160640017, -0.499761758],
    [0.506313233, 0.000300812, -0.641466566],
    [0.303099046, -0.420227950, -0.702997322],
    [0.002829236, -0.373748814, -0.650110156],
])
_SEPARATED_UPPER = np.array([
    [0.116631209, -0.357669990, -0.006356311],
    [0.230652835, -0.255746097, 0.064050391],
    [-0.111942783, -0.306671709, 0.000285358],
    [-0.080473280, -0.221179492, 0.126911691],
    [-0.281522557, -0.153655970, -0.073063037],
    [0.066242425, -0.235753682, -0.194163007],
    [0.327816763, -0.300466897, -0.128818191],
    [-0.391458439, 0.014855593, 0.180560163],
    [0.167259131, 0.102513998, 0.172119533],
    [0.468892368, -0.115045118, -0.106730397],
    [0.103644130, 0.037930245, -0.208462261],
    [-0.413531786, -0.048837117, 0.043132017],
    [-0.370944148, 0.173650448, -0.020553499],
    [-0.114927461, 0.371663903, 0.136992678],
    [-0.180686547, 0.237441207, 0.234987196],
    [0.267167480, 0.244888790, -0.004585039],
    [0.013111060, 0.278349562, -0.094444710],
    [-0.251290175, 0.306915784, -0.015316681],
    [-0.420927190, 0.217495945, 0.153372476],
    [-0.076175921, 0.035045601, 0.223364013],
    [0.398248209, -0.111676877, 0.027176887],
    [0.344047116, -0.070037512, -0.190542776],
    [0.351000547, 0.064022086, -0.160611640],
    [-0.153381790, 0.102769628, -0.152152525],
])
_SEPARATED_PREVIOUS_NORMAL = np.array([np.float64(0.052761017093588214), np.float64(-0.06753689558071047), np.float64(-0.9963207529759535)])


def test_a_face_axis_kept_by_the_hysteresis_gives_no_overlap_between_separated_grains():
    """Two scan-like grains 1.816e-3 d apart across crossed edges; the previous normal is a face of
    the lower grain 4.6 degrees away, along which their shadows overlap by 2.5e-4 d, within the
    hysteresis's band. That axis's sign points away from the lower grain's face: clipped on the
    nearest face, the manifold gave points 1.2e-4 and 2.1e-4 d deep, up to 0.03 d outside the
    lower grain, forces between grains that do not touch. The axis gives no face manifold on that
    side, and the manifold is the crossing of the edges, at the exact distance."""
    state = _grains_placed(_SEPARATED_LOWER + X0, _SEPARATED_UPPER + X0)
    distance, _ = exact_gap(_SEPARATED_LOWER, _SEPARATED_UPPER)
    assert distance == pytest.approx(1.816e-3, abs=1e-6)
    fresh = Detector().detect(state, 0.02)
    previous = ContactSet(**{**fresh.__dict__, "normal": np.array(fresh.normal, float)})
    previous.normal[0] = _SEPARATED_PREVIOUS_NORMAL
    m = pair_manifold(Detector().detect(state, 0.02, previous=previous))
    assert m["gaps"].min() == pytest.approx(distance, abs=1e-9)
    for point, gap in zip(m["points"], m["gaps"]):
        for vertices in (_SEPARATED_LOWER, _SEPARATED_UPPER):
            assert point_hull_distance(point, vertices + X0) <= 0.5 * abs(gap) + 1e-9


# the scan pile's pair whose face axis of the wrong sign was clipped on a face 5.7 degrees off
_OTHER_SIDE_LOWER = np.array([
    [0.241490706, 0.275143242, -0.624101941],
    [0.278881860, 0.062776184, -0.767182588],
    [-0.037336348, 0.141070342, -0.654929317],
    [-0.033135708, 0.141541755, -0.414380338],
    [0.223773963, 0.294520108, -0.501815921],
    [0.524382493, 0.200248293, -0.384760161],
    [0.540419246, 0.216049411, -0.571450576],
    [-0.194159824, -0.090509989, -0.649280528],
    [0.629349883, 0.077652846, -0.440848262],
    [0.175243936, 0.102716019, -0.259328878],
    [-0.239783489, -0.142602364, -0.387665347],
    [0.136804117, -0.518623310, -0.519732912],
    [-0.088671376, -0.460618169, -0.628530968],
    [0.279244095, -0.441563107, -0.370150012],
    [0.343380172, -0.265079371, -0.250362867],
    [-0.015741951, -0.495721094, -0.371805675],
    [0.105535345, -0.320826327, -0.224797950],
    [-0.217975519, -0.383978965, -0.371400919],
    [0.224734084, -0.301437836, -0.714385221],
    [0.031759280, -0.171436149, -0.772341969],
    [0.573420710, -0.157153377, -0.489439631],
    [0.449090563, -0.187784919, -0.671403957],
    [0.417885339, -0.046548047, -0.250549613],
    [-0.068680483, -0.124650070, -0.263687440],
])
_OTHER_SIDE_UPPER = np.array([
    [-0.363625433, 0.270591244, 0.119945134],
    [0.102828267, 0.401785597, 0.070782674],
    [-0.167079658, 0.384863022, -0.121217569],
    [0.168941975, 0.402612982, -0.078579719],
    [-0.253852828, 0.168298336, -0.243988324],
    [-0.407492505, 0.263281743, -0.012464117],
    [-0.510270071, -0.015126359, -0.042745946],
    [-0.214520761, 0.125998999, 0.239399704],
    [-0.154616457, -0.109067128, 0.280165517],
    [-0.441406665, -0.164581148, 0.123812517],
    [-0.077119721, -0.080049296, -0.273582978],
    [0.173528903, 0.279802437, -0.195936017],
    [0.421580746, -0.105631502, 0.154300147],
    [0.299327911, -0.151836070, 0.244893058],
    [-0.142473858, -0.402351121, 0.168301970],
    [0.171663813, -0.427232256, 0.024013220],
    [-0.088468224, -0.387010720, -0.093956656],
    [0.393013473, -0.234974150, -0.044339970],
    [0.137990923, -0.313692769, -0.152206947],
    [0.171743357, 0.127698739, 0.247503390],
    [-0.417774183, -0.184583461, -0.132686171],
    [0.304526029, -0.069779589, -0.203914393],
    [0.460498348, 0.040284210, -0.093140402],
    [0.444417318, 0.172620940, 0.018266308],
])


def test_a_face_axis_meets_a_body_not_centrally_symmetric_on_its_face_side_only():
    """A face axis is a face's normal up to sign. Two scan-like grains overlapping by 1.932e-4 d
    across crossed edges, along which the lower grain's face axis is within eps_f of the best
    separation, but with the sign that points away from that face: the lower grain has no face
    there, and the face nearest that direction is 5.7 degrees off. Clipped on it, the manifold
    had a point 0.012 d outside the lower grain at a gap of -7e-8 d. The face axis now gives no
    manifold on the side without the face: the crossing of the edges, at the exact depth, and
    every point within half its gap of both grains."""
    state = _grains_placed(_OTHER_SIDE_LOWER + X0, _OTHER_SIDE_UPPER + X0)
    depth, _ = exact_gap(_OTHER_SIDE_LOWER, _OTHER_SIDE_UPPER)
    assert depth == pytest.approx(-1.932e-4, abs=1e-7)
    m = pair_manifold(Detector().detect(state, 0.02))
    assert m["gaps"].min() == pytest.approx(depth, abs=1e-9)
    for point, gap in zip(m["points"], m["gaps"]):
        for vertices in (_OTHER_SIDE_LOWER, _OTHER_SIDE_UPPER):
            assert point_hull_distance(point, vertices + X0) <= 0.5 * abs(gap) + 1e-9


@pytest.mark.parametrize("shape", [Sphere(1.0), Pinacoid.from_size(1.0, 1, 1)], ids=["spheres", "pinacoids"])
def test_per_body_reach_keeps_slow_pairs_at_the_base_alert_distance(shape):
    """A fast grain raises the alert distance of its own pairs only: with ``reach`` the slow pair
    0-1 (gap 0.05 d) is left out at alert 0.16 d, the pair 2-3 of the fast grain 2 (gap 0.1 d) is
    kept, and so are the wall contacts of 0 and 1; without ``reach`` every pair within 0.16 d is."""
    lift = 0.5 if isinstance(shape, Sphere) else float(-shape.vertices[:, 2].min())
    width = 1.0 if isinstance(shape, Sphere) else float(np.ptp(shape.vertices[:, 0]))
    centres = [[2.0, 2.0, lift], [2.0 + width + 0.05, 2.0, lift], [6.0, 6.0, 4.0], [6.0 + width + 0.1, 6.0, 4.0]]
    state = make_state([shape], [0, 0, 0, 0], centres, np.tile([1.0, 0, 0, 0], (4, 1)))
    pairs = lambda c: {(int(i), int(j)) for i, j in zip(c.body_i, c.body_j)}
    everything = Detector().detect(state, 0.16)
    assert pairs(everything) == {(0, -1), (1, -1), (0, 1), (2, 3)}
    c = everything
    gaps = {(int(c.body_i[k]), int(c.body_j[k])): c.gap[c.point_start[k]:c.point_start[k + 1]].min()
            for k in range(c.n_manifolds)}
    assert gaps[(0, 1)] == pytest.approx(0.05, abs=1e-9) and gaps[(2, 3)] == pytest.approx(0.1, abs=1e-9)
    reached = Detector().detect(state, 0.16, reach=np.array([0.01, 0.01, 0.15, 0.01]))
    assert pairs(reached) == {(0, -1), (1, -1), (2, 3)}
    with pytest.raises(ValueError, match="reach must be 4 non-negative"):
        Detector().detect(state, 0.16, reach=np.array([0.01, -0.01, 0.15, 0.01]))
