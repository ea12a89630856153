"""Equilibrium criteria (docs/method/equilibrium.md) on columns with known forces."""

from __future__ import annotations

import numpy as np
import pytest
from packing_builders import H, cubic_cubes, single, sphere_column

from granpack.equilibrium import (
    EquilibriumCriteria,
    check_equilibrium,
    equilibrium_fields,
    particle_balance,
    stress_moments,
    wall_force,
)
from granpack.shapes import Pinacoid


def report(packing, **kw):
    return check_equilibrium(packing.state, packing.contacts, packing.time_step, **kw)


def test_column_with_weight_forces_passes():
    packing = sphere_column(3, 6)
    force, torque, energy = particle_balance(packing.state, packing.contacts, H)
    np.testing.assert_allclose(force, 0.0, atol=1e-14)
    np.testing.assert_allclose(torque, 0.0, atol=1e-14)
    r = report(packing)
    assert r.passed
    assert r.wall_force_over_weight == pytest.approx(1.0, abs=1e-12)
    assert r.max_net_force < 1e-12 and r.max_net_torque < 1e-12 and r.kinetic_energy == 0.0


def test_cubes_on_wall_wall_force_equals_weight():
    packing, _ = cubic_cubes(3, 1)
    assert wall_force(packing.contacts, H) == pytest.approx(packing.state.mass.sum(), rel=1e-12)
    r = report(packing)
    assert r.wall_force_over_weight == pytest.approx(1.0, abs=1e-12)
    assert r.passed


def test_perturbed_column_fails():
    packing = sphere_column(3, 6)
    m = packing.state.mass[0]
    # one vertical contact 1% too strong: two particles out of balance, wall balance unchanged
    k = int(np.flatnonzero((packing.contacts.body_j >= 0) & (packing.contacts.normal[:, 2] == 1))[3])
    packing.contacts.impulse[k, 2] *= 1.01
    r = report(packing)
    assert not r.force_ok and r.torque_ok and r.wall_ok and not r.passed
    assert r.max_net_force > 1e-3
    # a tangential force at a contact makes a torque (and a net force)
    packing = sphere_column(3, 6)
    packing.contacts.impulse[k, 0] += 1e-3 * m * H
    r = report(packing)
    assert not r.torque_ok and not r.passed
    # a slowly moving grain fails the kinetic-energy test only
    packing = sphere_column(3, 6)
    packing.state.velocity[5] = (1e-3, 0, 0)
    r = report(packing)
    assert r.force_ok and r.torque_ok and not r.energy_ok
    # a missing wall reaction fails the global balance
    packing = sphere_column(3, 6)
    wall = np.flatnonzero(packing.contacts.body_j < 0)[0]
    packing.contacts.impulse[wall] *= 0.5
    r = report(packing)
    assert not r.wall_ok and r.wall_force_over_weight < 1.0


def test_love_weber_stress_matches_weight_above():
    """Per layer of the column, -sigma_zz (particle form) equals the mean weight above per area."""
    side, layers = 3, 6
    packing = sphere_column(side, layers)
    s = stress_moments(packing.state, packing.contacts, H)
    np.testing.assert_allclose(s.trace(axis1=1, axis2=2), stress_moments(packing.state, packing.contacts, H, trace_only=True))
    z = packing.state.position[:, 2]
    m = packing.state.mass[0]
    area = packing.box.area
    for k in range(layers):
        in_layer = np.abs(z - (k + 0.5)) < 0.25
        sigma_zz = s[in_layer, 2, 2].sum() / (area * 1.0)
        # (1/d) * integral over the layer of W_above(z)/A: the layer's spheres count half
        expected = side**2 * m * (layers - k - 0.5) / area
        assert -sigma_zz == pytest.approx(expected, rel=1e-12)


def test_pressure_floor_near_surface():
    packing = sphere_column(3, 10)
    fields = equilibrium_fields(packing.state, packing.contacts, H)
    z = packing.state.position[:, 2]
    top = z == z.max()
    # local pressure decreases upwards but never below the floor taken 2 d below the surface
    assert fields.pressure_floor > 0
    assert np.all(fields.pressure >= fields.pressure_floor - 1e-15)
    np.testing.assert_allclose(fields.pressure[top], fields.pressure_floor)
    assert fields.pressure[z == z.min()].min() > fields.pressure_floor
    assert fields.z_surface == pytest.approx(9.5)


def test_bulk_pressure_of_a_pile_thinner_than_the_top_margin_is_the_column_average():
    """Two layers: the top of the bulk (2 d below the surface) is below every centre, so the
    kinetic criterion's pressure is the column's Love-Weber average, not that of the lowest
    centres alone (which, on a 1.6 d pile of flat & elongated grains, was one grain's: 0.0013
    against a column average of 0.35, and the pile could never pass)."""
    packing = sphere_column(3, 2)
    fields = equilibrium_fields(packing.state, packing.contacts, H)
    trace = stress_moments(packing.state, packing.contacts, H, trace_only=True)
    column = -trace.sum() / (3.0 * packing.box.area * (fields.z_surface + 0.5))
    assert fields.z_surface == pytest.approx(1.5)
    assert fields.bulk_pressure == pytest.approx(column, rel=1e-12)


def test_single_grain_without_contact_fails_cleanly():
    packing = single(Pinacoid.family("isometric"), position=(1, 1, 0.5))
    r = report(packing)
    assert not r.passed and not r.force_ok
    assert r.max_net_force == np.inf
    strict = EquilibriumCriteria(force=1e-8)
    assert report(sphere_column(3, 4), criteria=strict).passed
