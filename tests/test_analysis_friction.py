"""The analysis of frictional piles: the frictional rattler rule, constraint count and sliding contacts,
on hand-built configurations where the frictional and frictionless rules part."""

from __future__ import annotations

import math

import numpy as np
import pytest
from packing_builders import H, contact_set, cubic_cubes, fcc_spheres

from granpack.analysis import Coordination
from granpack.analysis.coordination import COMPONENTS, mobilisation
from granpack.analysis.report import AnalysisOptions, analyze_packing, summary_rows
from granpack.box import Box
from granpack.errors import InputError
from granpack.packing import Packing
from granpack.shapes import ShapeTable, Sphere, platonic
from granpack.state import ParticleState

# the rattlers of these configurations are their one or two bulk grains: that warning is expected
pytestmark = pytest.mark.filterwarnings("ignore:every bulk grain is a rattler")

BULK = (2.0, 6.0)
FRICTIONAL_CONFIG = "seed = 1\n\n[solver]\nfriction = 0.5\ntolerance = 1e-4\n"


def _grains(shapes: list[str], z: list[float], metadata: dict | None = None, manifolds=()) -> Packing:
    """Grains ``"sphere"`` or ``"cube"`` (circumscribed diameter 1) in a row along x at heights ``z``,
    with the given manifolds."""
    kinds = {"sphere": 0, "cube": 1}
    n = len(shapes)
    state = ParticleState(
        box=Box.square(2.0 * n + 2.0),
        shapes=ShapeTable.from_shapes([Sphere(1.0), platonic("cube", 1.0)]),
        kind=np.array([kinds[s] for s in shapes], np.int64),
        population=np.zeros(n, np.int64),
        position=np.column_stack([2.0 * np.arange(n) + 1.0, np.full(n, 1.0), z]),
        quaternion=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)),
    )
    return Packing(state, contact_set(list(manifolds)), H, ["grains"], dict(metadata or {}))


def _contact(i: int, j: int, ctype: int, normal=(0.0, 0.0, 1.0), tangential=(0.0, 0.0, 0.0), normal_force: float = 1.0) -> dict:
    """A manifold of 1 point, 2 points (an edge) or 4 points (a face) about the origin of the
    plane normal to ``normal``, each carrying its share of ``normal_force n + tangential``."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    t = np.cross(n, (1.0, 0.0, 0.0)) if abs(n[0]) < 0.9 else np.cross(n, (0.0, 1.0, 0.0))
    t /= np.linalg.norm(t)
    s = np.cross(n, t)
    offsets = {1: [(0, 0)], 2: [(-1, 0), (1, 0)], 3: [(-1, -1), (1, -1), (1, 1), (-1, 1)]}[ctype]
    points = [0.1 * (a * t + b * s) for a, b in offsets]
    force = (normal_force * n + np.asarray(tangential, float)) / len(points)
    return dict(i=i, j=j, normal=n, ctype=ctype, points=points, forces=np.repeat(force[None], len(points), axis=0))


# one bulk grain (0, at z = 4) on boundary grains below the bulk (1, 2, 3 at z = 1)
ON_SUPPORTS = ["sphere", "sphere", "sphere", "sphere"]
SUPPORT_Z = [4.0, 1.0, 1.0, 1.0]
TILTED = [(0.3, 0.0, 1.0), (-0.15, 0.26, 1.0), (-0.15, -0.26, 1.0)]


def _rattler(packing: Packing, friction: float | None) -> bool:
    co = Coordination(BULK, friction=friction).compute(packing)
    assert co.n_analysed == 1
    return bool(co.rattlers[0])


def test_a_sphere_on_three_contacts_is_held_with_friction_and_a_rattler_without():
    packing = _grains(ON_SUPPORTS, SUPPORT_Z, manifolds=[_contact(0, k + 1, 1, TILTED[k]) for k in range(3)])
    assert not _rattler(packing, 0.5)
    assert _rattler(packing, 0.0)  # a frictionless sphere needs 4


def test_a_sphere_on_two_contacts_is_a_rattler_with_and_without_friction():
    packing = _grains(ON_SUPPORTS, SUPPORT_Z, manifolds=[_contact(0, k + 1, 1, TILTED[k]) for k in range(2)])
    assert _rattler(packing, 0.5)  # it rolls about the line through its two contacts
    assert _rattler(packing, 0.0)


def test_a_cube_resting_on_one_face_is_held_with_friction_and_a_rattler_without():
    packing = _grains(["cube", "cube"], [4.0, 1.0], manifolds=[_contact(0, 1, 3)])
    co = Coordination(BULK, friction=0.5).compute(packing)
    assert co.types[0] == 3 and not co.rattlers[0]
    assert co.figures == {"N": 1.0, "Ns": 0.0, "Nd": 0.0, "Nt": 1.0, "Nc": 3.0}
    assert _rattler(packing, 0.0)  # 3 constraints < 7


def test_a_cube_on_a_double_and_a_simple_contact_is_held_with_friction():
    packing = _grains(["cube", "cube", "cube"], [4.0, 1.0, 1.0],
                      manifolds=[_contact(0, 1, 2, (0.2, 0.0, 1.0)), _contact(0, 2, 1, (-0.2, 0.1, 1.0))])
    assert not _rattler(packing, 0.5)
    assert _rattler(packing, 0.0)


@pytest.mark.parametrize("shape", ["sphere", "cube"])
def test_a_grain_on_two_simple_contacts_is_a_rattler_under_both_rules(shape):
    packing = _grains([shape, shape, shape], [4.0, 1.0, 1.0],
                      manifolds=[_contact(0, 1, 1, (0.3, 0.0, 1.0)), _contact(0, 2, 1, (-0.3, 0.0, 1.0))])
    assert _rattler(packing, 0.5)
    assert _rattler(packing, 0.0)


def test_frictional_rattlers_are_removed_until_none_is_left():
    """Grain 0 (bulk) on two boundary spheres and on grain 4 (bulk); grain 4 has one more contact
    with the boundary only: 4 is a rattler (2 contacts), then 0 is left with 2."""
    packing = _grains(["sphere"] * 5, [4.0, 1.0, 1.0, 1.0, 4.5],
                      manifolds=[_contact(0, 1, 1, TILTED[0]), _contact(0, 2, 1, TILTED[1]), _contact(0, 4, 1, (0.0, 1.0, 0.2)),
                                 _contact(4, 3, 1, TILTED[2])])
    co = Coordination(BULK, friction=0.5).compute(packing)
    assert co.n_analysed == 2
    assert co.rattlers.tolist() == [True, False, False, False, True]
    assert co.with_rattlers["N"] == 2.5  # (3 + 2) / 2 before the removal


def test_the_friction_is_the_packings_unless_given():
    manifolds = [_contact(0, k + 1, 1, TILTED[k]) for k in range(3)]
    frictional = _grains(ON_SUPPORTS, SUPPORT_Z, {"config": FRICTIONAL_CONFIG}, manifolds)
    assert frictional.friction == 0.5
    co = Coordination(BULK).compute(frictional)
    assert co.mu == 0.5 and co.rattler_rule == "frictional" and not co.rattlers[0]
    co = Coordination(BULK, friction=0.0).compute(frictional)
    assert co.mu == 0.0 and co.rattler_rule == "frictionless" and co.rattlers[0]
    plain = _grains(ON_SUPPORTS, SUPPORT_Z, manifolds=manifolds)
    assert plain.friction == 0.0
    assert Coordination(BULK).compute(plain).rattler_rule == "frictionless"
    assert Coordination(BULK, friction=0.5).compute(plain).rattler_rule == "frictional"
    assert _grains(ON_SUPPORTS, SUPPORT_Z, {"config": "[solver]\ntolerance = 1e-4\n"}).friction == 0.0


@pytest.mark.parametrize("config", ["[solver\nfriction = 0.5", "[solver]\nfriction = -0.5\n", "[solver]\nfriction = 'x'\n"])
def test_a_packing_whose_config_holds_no_valid_friction_says_so(config):
    with pytest.raises(InputError, match="packing's config"):
        _grains(ON_SUPPORTS, SUPPORT_Z, {"config": config}).friction


def test_a_contact_on_the_coulomb_cone_slides_and_one_inside_it_sticks():
    mu = 0.5
    side = np.array([1.0, 0.0, 0.0])
    manifolds = [_contact(0, 1, 1, tangential=mu * side),  # on the cone: sliding
                 _contact(0, 2, 3, tangential=0.5 * mu * side),  # half way: sticking
                 _contact(0, 3, 1, tangential=(1 - 2e-3) * mu * side)]  # just inside the cone
    packing = _grains(ON_SUPPORTS, SUPPORT_Z, manifolds=manifolds)
    np.testing.assert_allclose(mobilisation(packing, mu), [1.0, 0.5, 1 - 2e-3], rtol=1e-12)
    co = Coordination(BULK, friction=mu).compute(packing)
    assert co.sliding["n_contacts"] == 3
    assert co.sliding["sliding_fraction"] == pytest.approx(1 / 3)
    assert co.sliding["mean_mobilisation"] == pytest.approx((1.0 + 0.5 + 1 - 2e-3) / 3)
    assert Coordination(BULK, friction=mu, slide_tol=1e-2).compute(packing).sliding["sliding_fraction"] == pytest.approx(2 / 3)
    # the same forces under a larger mu: nothing slides
    assert Coordination(BULK, friction=2 * mu).compute(packing).sliding["sliding_fraction"] == 0.0
    assert math.isnan(Coordination(BULK, friction=0.0).compute(packing).sliding["sliding_fraction"])


def test_points_sliding_opposite_ways_do_not_make_a_sliding_contact():
    """Two points of an edge each on its cone but twisting (opposite tangential forces): the
    resultant has no tangential part, the contact as a whole does not slide."""
    contact = _contact(0, 1, 2)
    contact["forces"] = contact["forces"] + np.array([[0.25, 0.0, 0.0], [-0.25, 0.0, 0.0]])
    packing = _grains(ON_SUPPORTS, SUPPORT_Z, manifolds=[contact])
    assert mobilisation(packing, 0.5)[0] == pytest.approx(0.0, abs=1e-12)


def test_mobilisation_needs_friction():
    with pytest.raises(ValueError, match="friction"):
        mobilisation(_grains(ON_SUPPORTS, SUPPORT_Z, manifolds=[_contact(0, 1, 1)]), 0.0)


def test_constraint_counts_and_isostatic_references_under_each_rule():
    cubes, _ = cubic_cubes(3, 12)  # six triple contacts per grain
    assert Coordination(friction=0.5).compute(cubes).constraints == {
        "constraints_per_grain": 36.0, "isostatic_constraints": 12.0, "hyperstaticity": 12.0}
    assert Coordination(friction=0.0).compute(cubes).constraints == {
        "constraints_per_grain": 18.0, "isostatic_constraints": 12.0, "hyperstaticity": 3.0}
    spheres, _ = fcc_spheres(4, 6)  # twelve simple contacts per grain
    assert Coordination(friction=0.5).compute(spheres).constraints == {
        "constraints_per_grain": 36.0, "isostatic_constraints": 12.0, "hyperstaticity": 12.0}
    assert Coordination(friction=0.0).compute(spheres).constraints == {
        "constraints_per_grain": 12.0, "isostatic_constraints": 6.0, "hyperstaticity": 3.0}
    assert COMPONENTS["frictional"].tolist() == [3.0, 5.0, 6.0]


def test_a_frictional_packings_analysis_json_says_its_rule_and_a_frictionless_ones_does_not():
    spheres, _ = fcc_spheres(4, 6)
    frictionless = analyze_packing(spheres)["coordination"]
    assert "frictional" not in frictionless
    frictional = analyze_packing(spheres, AnalysisOptions(friction=0.5))
    part = frictional["coordination"]["frictional"]
    assert part["mu"] == 0.5 and part["rattler_rule"].startswith("fewer than 3 force-bearing points")
    assert part["constraints_per_grain"] == 36.0 and part["isostatic_constraints"] == 12.0
    assert part["sliding_fraction"] == 0.0 and part["slide_tol"] == 1e-3  # fcc forces are normal
    rows = dict(summary_rows(frictional))
    assert rows["N / Nc (backbone, frictional rule, μ = 0.5)"] == "12.000 / 12.000"
    assert rows["constraints per grain (isostatic)"].startswith("36.000 (12)")
    assert "N / Nc (backbone, frictionless rule)" in dict(summary_rows(analyze_packing(spheres)))
