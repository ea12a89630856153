"""The separating-axis test of two general polyhedra against an exhaustive reference.

The kernel tries, besides the face axes, only the edge pairs that make a face of the Minkowski
difference (``separating_axes._minkowski_edge_axes``); the reference here tries the cross
product of every pair of edge directions. Random convex polyhedra (hulls of 20 to 40 points) in
random relative poses, from overlapping to separated.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from granpack.contact.detect import _Tables
from granpack.contact.narrowphase import _KEEP_BAND, _general_tables, _scratch, poly_poly
from granpack.contact.separating_axes import GENERAL, SatResult, _general_axes, _sat, world_geometry
from granpack.rotations import quat_to_matrix, random_quaternions
from granpack.shapes import ConvexPolyhedron, ShapeTable

ALERT = 0.05
EPS_F = 1e-3


def random_hulls(rng, count) -> list[ConvexPolyhedron]:
    """Hulls of 20 to 40 points on a noisy ellipsoid, every point a vertex, of size about 1."""
    shapes = []
    while len(shapes) < count:
        n = int(rng.integers(20, 41))
        u = rng.normal(size=(n, 3))
        u /= np.linalg.norm(u, axis=1)[:, None]
        pts = u * (1.0 + 0.15 * rng.standard_normal((n, 1))) * np.array([0.5, rng.uniform(0.3, 0.5),
                                                                           rng.uniform(0.2, 0.5)])
        pts = pts[ConvexHull(pts).vertices]
        if len(pts) >= 20:
            shapes.append(ConvexPolyhedron(pts, name=f"hull-{len(shapes)}"))
    return shapes


def world_axes(shape, q):
    """World face axes and edge directions of ``shape`` turned by ``q``."""
    rot = quat_to_matrix(q)
    return shape.face_axes @ rot.T, shape.edge_directions @ rot.T


def exhaustive(va, vb, faces_a, faces_b, dirs_a, dirs_b):
    """Best face axis of A, of B and best edge axis over every pair of edge directions.

    ``va``, ``vb``: world vertices (A centred, B offset); returns ``{name: (separation, unit axis
    oriented from A to B)}`` for ``"a"``, ``"b"``, ``"edge"``.
    """
    out = {}
    i, j = np.meshgrid(np.arange(len(dirs_a)), np.arange(len(dirs_b)), indexing="ij")
    c = np.cross(dirs_a[i.ravel()], dirs_b[j.ravel()])
    keep = np.einsum("ij,ij->i", c, c) >= 1e-12
    c = c[keep] / np.linalg.norm(c[keep], axis=1)[:, None]
    for name, axes in (("a", faces_a), ("b", faces_b), ("edge", c)):
        pa, pb = axes @ va.T, axes @ vb.T
        up, down = pb.min(axis=1) - pa.max(axis=1), pa.min(axis=1) - pb.max(axis=1)
        s = np.maximum(up, down)
        k = int(np.argmax(s))
        out[name] = (float(s[k]), axes[k] * (1.0 if up[k] >= down[k] else -1.0))
    return out


def minkowski_best(va, vb, shape_a, shape_b, tol=1e-9):
    """Best separation over the edge pairs ``(e_A, e_B)`` whose axis ``u`` has ``e_A`` in A's
    support set along ``u`` and ``e_B`` in B's along ``-u`` (for one sign of ``u``): the faces of
    the Minkowski difference, found from the vertices alone (no Gauss map)."""
    best = -np.inf
    for ea in shape_a.edges:
        for eb in shape_b.edges:
            c = np.cross(va[ea[1]] - va[ea[0]], vb[eb[1]] - vb[eb[0]])
            norm = np.linalg.norm(c)
            if norm < 1e-9:
                continue
            for u in (c / norm, -c / norm):
                ha, hb = va @ u, vb @ u
                if (ha[ea] >= ha.max() - tol).all() and (hb[eb] <= hb.min() + tol).all():
                    best = max(best, hb.min() - ha.max())
    return best


def place(shape_a, shape_b, qa, qb, direction, target) -> np.ndarray:
    """Offset of B along ``direction`` at which the reference's best separation is ``target``
    (bisection: every axis's separation is affine in the distance)."""
    fa, da = world_axes(shape_a, qa)
    fb, db = world_axes(shape_b, qb)
    va = shape_a.vertices @ quat_to_matrix(qa).T
    vb0 = shape_b.vertices @ quat_to_matrix(qb).T
    lo, hi = 0.0, 2.0 * (shape_a.circumscribed_radius + shape_b.circumscribed_radius)
    for _ in range(60):
        r = 0.5 * (lo + hi)
        best = max(s for s, _ in exhaustive(va, vb0 + r * direction, fa, fb, da, db).values())
        lo, hi = (r, hi) if best < target else (lo, r)
    return 0.5 * (lo + hi) * direction


@pytest.fixture(scope="module")
def pairs():
    """120 pairs of random hulls: state arrays, kernel inputs and the pairs' offsets."""
    rng = np.random.default_rng(76)
    shapes = random_hulls(rng, 12)
    table = ShapeTable.from_shapes(shapes)
    tables = _Tables(table)
    n = 120
    kind = rng.integers(0, len(shapes), 2 * n).astype(np.int64)
    quat = random_quaternions(2 * n, rng)
    position = np.zeros((2 * n, 3))
    for k in range(n):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        target = rng.uniform(-0.05, 0.05)
        position[2 * k + 1] = place(shapes[kind[2 * k]], shapes[kind[2 * k + 1]], quat[2 * k], quat[2 * k + 1], u,
                                    target)
    geo = world_geometry(position, quat, kind, table.vertex_start, table.vertices, table.face_start,
                         table.face_normals, table.axis_start, table.face_axes, table.direction_start,
                         table.edge_directions)
    return shapes, table, tables, kind, quat, position, geo


def kernel_inputs(table, tables, kind):
    """The bundles and scratch arrays that ``narrow_phase`` hands to ``_sat`` and ``poly_poly``."""
    scr = _scratch(tables.max_points)
    tab = tables.tab(kind)
    gauss = _general_tables(tab, tables.axis_extent, tables.edge_arc, table.n_kinds)
    inradius = gauss.inradius
    assert np.allclose(inradius, [s.face_offsets.min() for s in table.shapes])
    return scr, tab, gauss, tables.symmetric, inradius


def test_edge_faces_are_the_two_faces_of_each_edge():
    shape = random_hulls(np.random.default_rng(3), 1)[0]
    for (a, b), (f, g) in zip(shape.edges, shape.edge_faces):
        assert f != g
        for face in (shape.faces[f], shape.faces[g]):
            assert a in face and b in face
        # the edge runs a -> b counter-clockwise round face f, b -> a round face g
        ring = list(shape.faces[f])
        assert ring[(ring.index(a) + 1) % len(ring)] == b


def test_minkowski_edge_pairs_give_the_exhaustive_separation_and_manifold(pairs):
    shapes, table, tables, kind, quat, position, geo = pairs
    ax = geo.axes
    scr, tab, gauss, symmetric, inradius = kernel_inputs(table, tables, kind)
    X, pts, gp = scr.vertex_block, np.empty((tables.max_points, 3)), np.empty(tables.max_points)
    Y = np.empty_like(X)
    margin = _KEEP_BAND * EPS_F
    n_over = n_sep = n_edge = n_beaten = 0
    for k in range(len(position) // 2):
        a, b = 2 * k, 2 * k + 1
        ka, kb = kind[a], kind[b]
        o = position[b] - position[a]
        sat = _sat(geo, a, b, ka, kb, *o, symmetric, ALERT, inradius[ka] + inradius[kb], margin, X, Y, -1)
        assert sat.axis == GENERAL  # random hulls are not centrally symmetric
        sat = _general_axes(geo, a, b, ka, kb, *o, gauss, symmetric.axis_start, ALERT, inradius[ka] + inradius[kb],
                            margin, X)
        assert not sat.far
        va = shapes[ka].vertices @ quat_to_matrix(quat[a]).T
        vb = shapes[kb].vertices @ quat_to_matrix(quat[b]).T + o
        (fa, da), (fb, db) = world_axes(shapes[ka], quat[a]), world_axes(shapes[kb], quat[b])
        ref = exhaustive(va, vb, fa, fb, da, db)
        assert sat.sfa == pytest.approx(ref["a"][0], abs=1e-12)
        assert sat.sfb == pytest.approx(ref["b"][0], abs=1e-12)
        sigma_ref = max(s for s, _ in ref.values())
        sigma = max(sat.sfa, sat.sfb, sat.se)
        # the edge axis is the best over the Minkowski faces (whenever it can matter: within the
        # margin of the best face axis)
        mink = minkowski_best(va, vb, shapes[ka], shapes[kb])
        if mink >= max(sat.sfa, sat.sfb) - margin:
            assert sat.se == pytest.approx(mink, abs=1e-12)
        if sigma_ref <= 0.0:
            # overlapping: the largest separation over every direction is at a face of A - B
            n_over += 1
            assert sigma == pytest.approx(sigma_ref, abs=1e-12)
            if ref["edge"][0] > max(ref["a"][0], ref["b"][0]) + 1e-9:
                n_edge += 1
                assert sat.se == pytest.approx(ref["edge"][0], abs=1e-12)
                np.testing.assert_allclose([sat.ex, sat.ey, sat.ez], ref["edge"][1], atol=1e-9)
        else:
            # separated: a lower bound of the distance; an edge-direction pair that is no face of
            # A - B may separate more (closest features a vertex and a vertex or an edge)
            n_sep += 1
            assert sigma <= sigma_ref + 1e-12
            n_beaten += sigma < sigma_ref - 1e-9
        # the manifold from the pruned test and from the exhaustive one: same points and gaps
        s_ref, u_ref = ref["edge"]
        full = SatResult(False, sat.sfa, sat.kfa, sat.gfa, sat.sfb, sat.kfb, sat.gfb, s_ref, sat.ie, sat.je,
                         *u_ref, -1)
        # without a previous normal, and with the previous normal along each body's best face
        # axis or the exhaustive edge axis (the axis hysteresis)
        hints = [np.zeros(3), np.asarray(u_ref)] + [ax[r] for r in (sat.kfa, sat.kfb)]
        for h in hints:
            got = []
            for s in (sat, full):
                cnt, nx, ny, nz = poly_poly(a, b, *o, *h, s, geo, tab, ALERT, EPS_F, scr, pts, gp)
                got.append((cnt, np.array([nx, ny, nz]), pts[:cnt].copy(), gp[:cnt].copy()))
            (cnt, normal, points, gaps), (cnt_ref, normal_ref, points_ref, gaps_ref) = got
            assert cnt == cnt_ref and cnt > 0
            np.testing.assert_allclose(normal, normal_ref, atol=1e-9)
            np.testing.assert_allclose(points, points_ref, atol=1e-9)
            np.testing.assert_allclose(gaps, gaps_ref, atol=1e-9)
    assert n_over >= 40 and n_sep >= 40 and n_edge >= 5 and n_beaten >= 2


#: two generated rocks of a 1000-rock pile at rest, d: (vertices in the body frame, centre,
#: quaternion). B's edge lies across A's face within 5e-6 d of parallel, 5e-4 d deep: the pair has
#: no crossing-edge manifold, so its manifold is the deepest-vertex fallback's.
ROCK_PAIR = {
    "a": (np.array([
        [0.071360447686, -0.203038534875, 0.350680451941], [0.108882084081, 0.231756216916, 0.370127317519],
        [0.336565718944, -0.369714686236, -0.005879422821], [0.324555642700, -0.349767021325, 0.049007136651],
        [0.155781919440, 0.267889977564, 0.323144434506], [-0.015698367068, -0.182366930723, 0.361368959780],
        [-0.113365595759, 0.139182160622, 0.389534138561], [0.136807856854, -0.371064304323, -0.133758467858],
        [-0.339756553398, -0.221831037142, 0.037461026356], [-0.467301156573, -0.105121970688, -0.040138008015],
        [0.319779779661, -0.227871837589, -0.097124044339], [-0.203015871629, 0.138111936474, 0.303640261305],
        [-0.461261715972, -0.078121998452, -0.024193428781], [-0.045127529320, -0.107644909007, -0.400301678706],
        [-0.395931973739, -0.092699712798, -0.121681459556], [0.002860856847, 0.405840824294, -0.184530411641],
        [-0.006766162656, 0.397482133574, -0.194410395624], [0.178645361271, 0.432802571193, -0.080354356643],
        [0.238209971203, 0.217566084633, -0.181158347497], [-0.056400943484, 0.136411248915, -0.359937617235],
        [-0.039048116696, 0.185791350678, -0.338949668734], [-0.018314293850, -0.052450720893, -0.414332736956],
        [0.087259268421, -0.006225268737, -0.372556146510], [0.105080062423, 0.050655191069, -0.348917348955],
    ]), np.array([0.488275022820, 3.303715187943, 16.107595894317]), np.array([-0.288761073640, 0.268069489161, -0.855468696396, 0.336049253559])),
    "b": (np.array([
        [0.311346118242, 0.303565062075, 0.229700715978], [-0.100352725474, 0.361641420729, 0.127125291062],
        [-0.440186629364, 0.232163767011, -0.048329252177], [-0.327233735783, 0.368518254515, -0.039171013948],
        [0.367842808971, 0.202333380123, -0.163623584179], [0.262063207734, 0.187918394307, -0.318132037171],
        [0.202590094844, -0.003701582593, 0.407996944216], [0.233590643008, -0.279769384402, -0.062036667964],
        [0.162678090868, -0.411232835334, -0.087441619986], [-0.029904076198, 0.004109737553, 0.365978010113],
        [-0.390400243238, -0.075139641854, 0.149249302415], [0.086467890835, -0.234827719155, 0.343532139620],
        [0.152443963311, -0.063402521240, 0.438016043309], [-0.215280334619, 0.008831560325, -0.272097636677],
        [0.162848442561, 0.195696262315, -0.370013395026], [0.156255011234, 0.197187615762, -0.369204424478],
        [-0.039214475923, -0.259321701090, -0.348145948210], [-0.032478451435, 0.045671561585, -0.347182279733],
        [0.112466534291, -0.439511183820, -0.147025741830], [-0.294310675190, -0.256711045998, 0.136207804627],
        [-0.200346849924, -0.330519706312, 0.159697722110], [0.066145214599, -0.364715697921, -0.266742827204],
        [-0.045928412746, -0.258707348133, -0.345364072402], [-0.040024709392, -0.261939871887, -0.347843310789],
    ]), np.array([3.864053192797, 3.701033395510, 16.022045857057]), np.array([-0.611958897855, 0.466736764408, -0.608415673437, 0.193632302066])),
}


def test_an_edge_lying_in_the_other_grains_support_plane_touches_at_both_ends():
    """The manifold of two rocks whose contact is an edge lying on a face gives a point at each
    end of the edge (each with its own depth), not only at the deeper one: the deeper
    end turns on the last digits, and a single point jumping between the ends from step to step
    rocked the grains of a rock pile at rest for ever (a period-4 cycle, |omega| 5e-4 to 6e-3)."""
    from granpack.box import Box
    from granpack.contact import detect
    from granpack.rotations import quat_from_axis_angle, quat_multiply
    from granpack.state import ParticleState

    shapes = [ConvexPolyhedron(ROCK_PAIR[k][0]) for k in ("a", "b")]
    x = np.array([ROCK_PAIR["a"][1], ROCK_PAIR["b"][1]])
    ends = []
    for angle in (0.0, 3e-5, 1e-4):  # A turned by up to 1e-4 rad: the deeper end changes
        q = np.array([ROCK_PAIR["a"][2], ROCK_PAIR["b"][2]])
        q[0] = quat_multiply(quat_from_axis_angle([0.3, 0.5, 0.8], angle), q[0])
        state = ParticleState(box=Box.square(4.0), shapes=ShapeTable.from_shapes(shapes), kind=np.array([0, 1]),
                              population=np.zeros(2, np.int64), position=x.copy(), quaternion=q)
        c = detect(state, 0.02)
        # the two ends of the edge, and any other point of the incident face open (within the alert)
        assert len(c.body_i) == 1 and c.n_points >= 2
        deepest = np.argsort(c.gap)[:2]
        gaps = c.gap[deepest]
        assert -5.3e-4 < gaps[0] < gaps[1] < -4.9e-4 and gaps[1] - gaps[0] < 1e-3 * state.shapes.radius.min() * 2
        assert np.all(np.delete(c.gap, deepest) > 1e-3)
        ends.append(c.point[deepest] - x[0])
    # the two points stay at the edge's two ends (to the turn's displacement), whichever is deeper
    for other in ends[1:]:
        assert np.abs(np.sort(other, axis=0) - np.sort(ends[0], axis=0)).max() < 1e-4
    assert np.linalg.norm(ends[0][0] - ends[0][1]) > 0.15  # the ends of the edge's part over the face, 0.19 d apart
