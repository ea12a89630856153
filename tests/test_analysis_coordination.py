"""Coordination numbers by contact type (types from the force-bearing points), rattlers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from packing_builders import H, contact_set, cube_on_cube, cubic_cubes, fcc_spheres, sphere_column

from granpack.analysis import AnalysisWarning, Coordination, NotComputedError
from granpack.analysis.coordination import force_bearing_points, near_points, type_rules
from granpack.box import Box
from granpack.contact import DOUBLE, SIMPLE, TRIPLE
from granpack.packing import Packing
from granpack.shapes import Pinacoid, ShapeTable
from granpack.state import ParticleState


def test_results_raise_before_compute():
    with pytest.raises(NotComputedError):
        Coordination().N


def test_fcc_spheres_have_twelve_simple_contacts():
    packing, _ = fcc_spheres(4, 6)
    co = Coordination().compute(packing)
    assert co.n_analysed > 0 and co.warnings == []
    assert co.figures == {"N": 12.0, "Ns": 12.0, "Nd": 0.0, "Nt": 0.0, "Nc": 12.0}
    assert co.rattler_fraction == 0.0


def test_cubes_face_to_face_are_triple_contacts():
    packing, _ = cubic_cubes(3, 12)
    co = Coordination().compute(packing)
    assert co.n_analysed == 9 * 6  # the layers with centre in the bulk [2, 4.92]: k = 3 .. 8
    assert co.figures == {"N": 6.0, "Ns": 0.0, "Nd": 0.0, "Nt": 6.0, "Nc": 18.0}
    assert co.with_rattlers == co.figures
    assert co.rattler_fraction == 0.0


def _hand_built():
    """Three bulk pinacoids (0, 4, 5) among boundary grains (1, 2, 3) outside the bulk [2, 6].

    Force-bearing contacts: 0-1 triple, 0-2 triple, 0-3 simple; 4-1 triple, 4-5 double, 4-2 simple,
    4-3 simple; 5-3 simple. Carrying no force: 0-5 triple (not counted).
    Constraints: grain 0: 3+3+1 = 7 (stays), grain 4: 3+2+1+1 = 7, grain 5: 2+1 = 3 < 7 (rattler);
    once 5 is removed grain 4 has 3+1+1 = 5 < 7 (rattler at the second pass).
    """
    z = np.array([4.0, 1.0, 1.0, 7.0, 4.0, 4.5])
    pos = np.column_stack([np.arange(6) * 1.2 + 0.5, np.full(6, 1.0), z])
    state = ParticleState(
        box=Box.square(8.0),
        shapes=ShapeTable.from_shapes([Pinacoid.family("isometric", 1.0)]),
        kind=np.zeros(6, np.int64),
        population=np.zeros(6, np.int64),
        position=pos,
        quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (6, 1)),
    )

    def contact(i, j, ctype, force=1.0):
        normal = (pos[i] - pos[j]) / np.linalg.norm(pos[i] - pos[j])
        t = np.cross(normal, (0.0, 0.0, 1.0)) if abs(normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
        t /= np.linalg.norm(t)
        s = np.cross(normal, t)
        # 1 point, a segment of 2 or a square of 4, with loaded points spanning that rank
        offsets = {1: [(0, 0)], 2: [(-1, 0), (1, 0)], 3: [(-1, -1), (1, -1), (1, 1), (-1, 1)]}[ctype]
        points = [0.5 * (pos[i] + pos[j]) + 0.1 * (a * t + b * s) for a, b in offsets]
        k = len(points)
        return dict(i=i, j=j, normal=normal, ctype=ctype, points=points, forces=np.repeat((force / k * normal)[None], k, axis=0))

    manifolds = [contact(0, 1, 3), contact(0, 2, 3), contact(3, 0, 1), contact(4, 1, 3), contact(5, 4, 2),
                 contact(4, 2, 1), contact(4, 3, 1), contact(5, 3, 1), contact(0, 5, 3, force=0.0)]
    return Packing(state, contact_set(manifolds), H, ["grains"], {})


def test_hand_built_rattlers_and_contact_types():
    co = Coordination(z_range=(2.0, 6.0)).compute(_hand_built())
    assert co.n_analysed == 3
    # all bulk grains, every force-bearing contact: (0: s1 t2) (4: s2 d1 t1) (5: s1 d1)
    w = co.with_rattlers
    assert w["N"] == pytest.approx(3.0)
    assert w["Ns"] == pytest.approx(4 / 3) and w["Nd"] == pytest.approx(2 / 3) and w["Nt"] == pytest.approx(1.0)
    assert w["Nc"] == pytest.approx(17 / 3)
    # backbone: 5 then 4 removed (two passes), grain 0 keeps its 7 constraints; boundary grains are never removed
    assert list(np.flatnonzero(co.rattlers)) == [4, 5]
    assert co.rattler_fraction == pytest.approx(2 / 3)
    assert co.figures == {"N": 3.0, "Ns": 1.0, "Nd": 0.0, "Nt": 2.0, "Nc": 7.0}
    np.testing.assert_array_equal(co.per_particle[0], [1, 0, 2])
    # without the rattler rule the backbone is all bulk grains
    plain = Coordination(z_range=(2.0, 6.0), remove_rattlers=False).compute(_hand_built())
    assert plain.figures == pytest.approx(w) and plain.rattler_fraction == 0.0


def test_sphere_rattler_rule_needs_four_contacts():
    """In the simple-cubic column only the two vertical contacts carry force: every bulk sphere is a rattler."""
    with pytest.warns(AnalysisWarning, match="every bulk grain is a rattler"):
        co = Coordination(z_range=(2.0, 6.0)).compute(sphere_column(3, 8))
    assert co.with_rattlers["N"] == 2.0 and co.with_rattlers["Ns"] == 2.0
    assert co.rattler_fraction == 1.0
    assert math.isnan(co.N) and math.isnan(co.Nc)


def test_no_bulk_and_no_force_give_nan_with_warning():
    packing, _ = cubic_cubes(3, 3)
    with pytest.warns(AnalysisWarning, match="no grain in the bulk"):
        co = Coordination().compute(packing)
    assert math.isnan(co.N) and math.isnan(co.rattler_fraction)
    packing, _ = fcc_spheres(2, 6, forces=False)
    packing.contacts.impulse[:] = 0.0  # the wall contacts too
    with pytest.warns(AnalysisWarning, match="no force-bearing contact"):
        co = Coordination(z_range=(2.0, 5.0)).compute(packing)
    assert math.isnan(co.N) and co.with_rattlers["N"] == 0.0 and co.rattler_fraction == 1.0


# ---------------------------------------------------------------------------------------------
# contact types from the force-bearing points (two cubes, manifold from detection)

ALERT = 0.02
BOTH = (0.0, 10.0)  # a bulk region holding the two cubes


def _figures(ns, nd, nt):
    """Figures of each of the two cubes of :func:`cube_on_cube` (one manifold, counted by both)."""
    return {"N": float(ns + nd + nt), "Ns": float(ns), "Nd": float(nd), "Nt": float(nt), "Nc": float(ns + 2 * nd + 3 * nt)}


def _assert_every_point_in_alert(packing):
    """Premise of the tests: detection sees the whole face, so its (geometric) type is triple."""
    c = packing.contacts
    assert c.n_manifolds == 1 and c.n_points >= 3
    assert np.all(c.gap <= ALERT) and c.ctype[0] == TRIPLE


@pytest.mark.parametrize("tilt", [0.01, 0.03])
def test_tilted_face_resting_on_one_edge_is_double(tilt):
    """Face tilted about an edge direction: every corner within the alert distance, force on the
    two corners of the edge only. The detection type (triple) would give Nt = 1, Nc = 3."""
    packing = cube_on_cube(axis=(1.0, 0.0, 0.0), tilt=tilt)
    _assert_every_point_in_alert(packing)
    loaded = force_bearing_points(packing)
    assert loaded.sum() == 2 and np.all(packing.contacts.gap[~loaded] > 1e-3)
    co = Coordination(z_range=BOTH, remove_rattlers=False).compute(packing)
    assert list(co.types) == [DOUBLE]
    assert co.figures == _figures(0, 1, 0) and co.with_rattlers == co.figures
    assert {k: co.by_rule["geometric"][k] for k in co.figures} == _figures(0, 0, 1)
    # the open corners are 5.7e-3 d (tilt 0.01) or more away: the gap rule agrees
    assert {k: co.by_rule["gap_rule"][k] for k in co.figures} == _figures(0, 1, 0)
    assert co.by_rule["gap_rule"]["same_type_as_force"] == 1.0 and co.by_rule["geometric"]["same_type_as_force"] == 0.0


def test_vertex_on_a_face_is_simple():
    """Face tilted about a face-diagonal normal: it rests on one corner, the other three within the
    alert distance carry no force. The detection type (triple) would give Nt = 1."""
    packing = cube_on_cube(axis=(1.0, -1.0, 0.0), tilt=0.01)
    _assert_every_point_in_alert(packing)
    assert force_bearing_points(packing).sum() == 1
    co = Coordination(z_range=BOTH, remove_rattlers=False).compute(packing)
    assert list(co.types) == [SIMPLE]
    assert co.figures == _figures(1, 0, 0)
    assert {k: co.by_rule["gap_rule"][k] for k in co.figures} == _figures(1, 0, 0)


def _load_corners(packing, forces_by_corner):
    """Set the normal force of the flat contact's corners, keyed by (sign x, sign y) about the centre."""
    c = packing.contacts
    normal = c.normal[c.point_manifold]
    for k, p in enumerate(c.point):
        key = (int(np.sign(p[0] - 1.5)), int(np.sign(p[1] - 1.5)))
        c.impulse[k] = H * forces_by_corner.get(key, 0.0) * normal[k]
    return packing


def test_flat_face_on_face_is_triple_with_three_or_more_loaded_corners():
    packing = cube_on_cube()
    c = packing.contacts
    assert c.n_points == 4 and np.all(np.abs(c.gap) < 1e-12)
    co = Coordination(z_range=BOTH, remove_rattlers=False).compute(packing)
    assert list(co.types) == [TRIPLE] and co.figures == _figures(0, 0, 1)
    # three non-collinear corners with unequal forces still span an area
    _load_corners(packing, {(-1, -1): 1.0, (1, -1): 0.3, (1, 1): 0.01})
    co = Coordination(z_range=BOTH, remove_rattlers=False).compute(packing)
    assert force_bearing_points(packing).sum() == 3
    assert list(co.types) == [TRIPLE] and co.figures == _figures(0, 0, 1)


def test_flat_face_loaded_along_one_side_is_double_and_the_gap_rule_says_triple():
    """The force, not the geometry, decides: two loaded corners of a flat face are a segment.
    The gap rule (all four corners touch) reports the disagreement."""
    packing = _load_corners(cube_on_cube(), {(1, -1): 1.0, (1, 1): 0.5})
    co = Coordination(z_range=BOTH, remove_rattlers=False).compute(packing)
    assert list(co.types) == [DOUBLE] and co.figures == _figures(0, 1, 0)
    assert list(near_points(packing)) == [True] * 4
    assert {k: co.by_rule["gap_rule"][k] for k in co.figures} == _figures(0, 0, 1)
    assert co.by_rule["gap_rule"]["same_type_as_force"] == 0.0


def test_point_threshold_is_relative_to_the_manifold():
    """Corners loaded below ``point_tol x`` the largest point force of the contact do not count,
    whatever the scale of the forces."""
    for scale in (1.0, 1e-6):
        packing = _load_corners(cube_on_cube(), {(1, -1): scale, (1, 1): scale, (-1, 1): 1e-5 * scale, (-1, -1): 1e-5 * scale})
        assert list(type_rules(packing)["force"]) == [DOUBLE]
        assert list(type_rules(packing, point_tol=1e-6)["force"]) == [TRIPLE]
        assert list(type_rules(packing, point_tol=0.0)["force"]) == [TRIPLE]
    with pytest.raises(ValueError, match="point_tol"):
        force_bearing_points(packing, point_tol=1.0)


def test_rattler_rule_uses_the_force_types():
    """In the hand-built packing, grain 0 has 3 + 3 + 1 = 7 constraints; with force on one side
    only of its square contact with grain 1 that contact is double and grain 0 (6 < 7) a rattler.
    The detection types keep the old backbone."""
    packing = _hand_built()
    c = packing.contacts
    assert (c.body_i[0], c.body_j[0]) == (0, 1) and c.point_start[1] == 4
    c.impulse[2:4] = 0.0  # the corners (1, 1) and (-1, 1) of manifold 0-1 unloaded
    with pytest.warns(AnalysisWarning, match="every bulk grain is a rattler"):
        co = Coordination(z_range=(2.0, 6.0)).compute(packing)
    assert co.types[0] == DOUBLE and co.by_rule["geometric"]["rattler_fraction"] == pytest.approx(2 / 3)
    assert co.rattler_fraction == 1.0 and list(np.flatnonzero(co.rattlers)) == [0, 4, 5]
    assert co.with_rattlers["Nd"] == pytest.approx(1.0) and co.with_rattlers["Nt"] == pytest.approx(2 / 3)
    assert co.by_rule["geometric"]["N"] == 3.0 and co.by_rule["geometric"]["Nc"] == 7.0
