"""Coordination numbers by contact type, rattlers (PHYSICS.md §5f)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from packing_builders import H, contact_set, cubic_cubes, fcc_spheres, sphere_column

from granpack.analysis import AnalysisWarning, Coordination, NotComputedError
from granpack.box import Box
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
        k = ctype + (ctype == 3)  # 1, 2 or 4 points
        return dict(i=i, j=j, normal=normal, ctype=ctype, points=np.repeat(0.5 * (pos[i] + pos[j])[None], k, axis=0),
                    forces=np.repeat((force / k * normal)[None], k, axis=0))

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
