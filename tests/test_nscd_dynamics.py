"""NSCD dynamics with real contact detection: ``granpack.nscd.step`` on spheres and pinacoids.

Units d = 1, density 1, g = 1 (gravity ``(0, 0, -1)``), h = 5e-3 unless said. Wall force: the
sum of the z-components of ``contacts.impulse`` over the wall points (``body_j == -1``),
divided by h.

Energy (decision, documented here and in :mod:`granpack.nscd.integrator`): the energy budget of
a step is ``ΔE - correction_energy``, where ``correction_energy`` (:class:`StepInfo`) is the
potential energy ``Σ m g δz`` the post-step position correction adds (it moves positions, and
only removes kinetic energy).
For θ = 1 the Moreau–Jean step with e_N = 0 is strictly dissipative,
``ΔE - ΔE_corr = Σ r u^{n+1} - ½|ΔV|²_M <= 0``; for θ = ½ (the default) the impulses work at
the mean velocity, ``ΔE - ΔE_corr = Σ_α r_α (u^n_α + u^{n+1}_α) / 2`` with ``u^{n+1} <= 0``
wherever ``r > 0``, so a step may gain at most ``Σ_α r_α max(0, u^n_α) / 2``: a contact that
pushes although it was opening at the start of the step (a known property of the θ = ½ scheme
with a velocity-level impact law). Both are checked, step by step, on a pour.
"""

from dataclasses import replace
import subprocess
import sys

import numpy as np
import pytest

from granpack import Box, ShapeTable, Sphere
from granpack.contact import Detector, detect
from granpack.deposit import deposit
from granpack.nscd import (
    CORRECTED_OVERLAP,
    StepParameters,
    advance,
    assemble,
    predict,
    required_alert,
    step,
    total_energy,
)
from granpack.rotations import quat_from_axis_angle, quat_multiply, random_quaternions, rotate
from granpack.shapes import Pinacoid
from granpack.state import ParticleState

H = 5e-3
PIN = Pinacoid.from_size(1.0, 1, 1)
#: the pinacoid lying on one of its trapezoidal faces (body normal (0, 1, -1)/√2 turned to -z)
ON_FACE = quat_from_axis_angle([1.0, 0.0, 0.0], -np.pi / 4)
FACE_NORMAL = np.array([0.0, 1.0, -1.0]) / np.sqrt(2.0)


def make_state(shape, positions, quaternions=None, box=6.0, velocity=None, omega=None):
    positions = np.atleast_2d(np.asarray(positions, dtype=float))
    n = len(positions)
    q = np.tile([1.0, 0, 0, 0], (n, 1)) if quaternions is None else np.array(np.atleast_2d(quaternions), dtype=float)
    return ParticleState(
        box=Box.square(box), shapes=ShapeTable.from_shapes([shape]), kind=np.zeros(n, int),
        population=np.zeros(n, int), position=positions, quaternion=q, velocity=velocity, omega=omega,
    )


def half_height(shape, q):
    """Distance from the centre to the lowest point of ``shape`` turned by ``q``."""
    if isinstance(shape, Sphere):
        return 0.5 * shape.diameter
    return float(-rotate(q, shape.vertices)[:, 2].min())


def wall_force(contacts, h=H):
    on_wall = np.repeat(contacts.body_j == -1, np.diff(contacts.point_start))
    return float(contacts.impulse[on_wall, 2].sum() / h)


def pair_forces(contacts, h=H):
    """``{(i, j): resultant world force on i}`` per manifold."""
    m = contacts.point_manifold
    return {(int(contacts.body_i[k]), int(contacts.body_j[k])): contacts.impulse[m == k].sum(axis=0) / h for k in range(contacts.n_manifolds)}


def run(state, params, steps, warm=None, each=None):
    for n in range(steps):
        warm, info = step(state, params, warm)
        if each is not None:
            each(n, state, warm, info)
    return warm, info


# --- single bodies on the wall -------------------------------------------------------------


@pytest.mark.parametrize("shape, q", [(Sphere(1.0), None), (PIN, ON_FACE)], ids=["sphere", "pinacoid"])
def test_dropped_body_stops_without_bounce_and_carries_its_weight(shape, q):
    z_rest = half_height(shape, q)
    state = make_state(shape, [[3.0, 3.0, z_rest + 0.3]], q)
    params = StepParameters(time_step=H)
    z, vz = [], []
    contacts, _ = run(state, params, 400, each=lambda n, s, c, i: (z.append(s.position[0, 2]), vz.append(s.velocity[0, 2])))
    z, vz = np.array(z), np.array(vz)
    # free fall of 0.3 d lasts sqrt(0.6) = 0.77 (155 steps); after the impact the body never moves up
    first = int(np.argmax(z < z_rest + 1e-9))
    assert 140 < first < 170
    v_impact = -vz[first - 1]
    # no rebound beyond the NLGS tolerance (1e-4 on impulses: the 4-point face contact of the
    # pinacoid leaves +1.8e-6 after the impact step, then 7e-9, 4e-11, ...), no rise
    assert vz[first:].max() < 1e-5 * v_impact and np.abs(vz[first + 5:]).max() < 1e-12
    assert z[first:].max() < z_rest + 1e-8
    assert abs(z[-1] - z_rest) < 1e-7  # overlap left by the solver tolerance (2.5e-8 for the pinacoid)
    weight = state.mass[0] * 1.0
    assert wall_force(contacts) == pytest.approx(weight, rel=1e-6)
    assert np.abs(state.velocity).max() < 1e-12 and np.abs(state.omega).max() < 1e-9


@pytest.mark.parametrize("tilt", [0.0, 0.05, 0.2])
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_pinacoid_on_a_face_settles_flat_and_stops_rotating(tilt, friction):
    q = quat_multiply(quat_from_axis_angle(np.array([1.0, 1.0, 0.0]) / np.sqrt(2), tilt), ON_FACE)
    state = make_state(PIN, [[3.0, 3.0, half_height(PIN, q) + 0.01]], q)
    contacts, info = run(state, StepParameters(time_step=H, friction=friction), 600)
    down = rotate(state.quaternion[0], FACE_NORMAL)
    assert down[2] < -1 + 1e-12  # flat on the face
    assert info.n_points == 4 and wall_force(contacts) == pytest.approx(state.mass[0], rel=1e-6)
    w_world = rotate(state.quaternion[0], state.omega[0])
    assert np.abs(w_world[:2]).max() < 1e-9  # no rocking
    # frictionless: the spin about the vertical (zero, by conservation of L_z) is left to the
    # O(h²) error of the explicit gyroscopic term (measured 1.7e-5 for tilt 0.2); friction stops it
    assert abs(w_world[2]) < (1e-4 if friction == 0 else 1e-9)
    assert np.abs(state.velocity).max() < 1e-9


def test_column_of_spheres_stands_still_with_each_contact_carrying_the_weight_above():
    state = make_state(Sphere(1.0), [[3.0, 3.0, 0.5 + 1.005 * k] for k in range(5)])
    contacts, _ = run(state, StepParameters(time_step=H), 300)
    w = state.mass[0]
    forces = pair_forces(contacts)
    assert sorted(forces) == [(0, -1), (0, 1), (1, 2), (2, 3), (3, 4)]
    assert forces[(0, -1)][2] == pytest.approx(5 * w, rel=1e-6)
    for k in range(4):  # on the lower body i = k from the upper j = k + 1: the weight above, downwards
        assert forces[(k, k + 1)][2] == pytest.approx(-(4 - k) * w, rel=1e-6)
    np.testing.assert_allclose(state.position[:, 2], 0.5 + np.arange(5), atol=1e-6)  # closing overshoot 1.6e-7 per contact
    np.testing.assert_allclose(state.position[:, :2], 3.0, atol=1e-12)
    assert np.abs(state.velocity).max() < 1e-12


@pytest.mark.parametrize("scaled", [True, False], ids=["scaled", "unscaled"])
def test_warm_start_across_a_change_of_time_step_keeps_a_column_at_rest(scaled):
    """A column of 5 balls at rest, then one step twice as long from its impulses with a single
    symmetric pair of sweeps: scaled by h_new / h_old (``warm_time_step``), the warm start is the
    solution and nothing moves; unscaled, it carries half the weights and the column falls."""
    state = make_state(Sphere(1.0), [[3.0, 3.0, 0.5 + 1.005 * k] for k in range(5)])
    contacts, _ = run(state, StepParameters(time_step=H), 300)
    assert np.abs(state.velocity).max() < 1e-12
    params = StepParameters(time_step=2 * H, max_iterations=2, check_every=2)
    prediction = predict(state, params)
    detected = detect(prediction.state, params.alert, previous=contacts)
    advance(state, prediction, detected, params, contacts, warm_time_step=H if scaled else None)
    fall = float(np.abs(state.velocity).max())
    if scaled:
        assert fall < 1e-12
    else:
        assert fall > 1e-3  # half the impulses: the lowest ball loses g h / 2 = 5e-3 sqrt(g d)


def test_stack_of_pinacoids_stands_still_with_each_contact_carrying_the_weight_above():
    z0, height = half_height(PIN, ON_FACE), 2 * half_height(PIN, ON_FACE)
    state = make_state(PIN, [[3.0, 3.0, z0 + k * (height + 0.005)] for k in range(3)], np.tile(ON_FACE, (3, 1)))
    contacts, _ = run(state, StepParameters(time_step=H), 300)
    w = state.mass[0]
    forces = pair_forces(contacts)
    assert sorted(forces) == [(0, -1), (0, 1), (1, 2)]
    # face-face manifolds: on the wall the four corners of the face, between grains the hexagon
    # where a trapezoid meets the opposite face of the grain below (the same trapezoid turned by
    # 180 degrees), every vertex a point
    assert np.diff(contacts.point_start)[0] == 4 and all(n >= 6 for n in np.diff(contacts.point_start)[1:])
    assert forces[(0, -1)][2] == pytest.approx(3 * w, rel=1e-6)
    assert forces[(0, 1)][2] == pytest.approx(-2 * w, rel=1e-6)
    assert forces[(1, 2)][2] == pytest.approx(-w, rel=1e-6)
    for f in forces.values():
        assert np.abs(f[:2]).max() < 1e-6 * w
    np.testing.assert_allclose(state.position[:, 2], z0 + height * np.arange(3), atol=1e-6)
    # frictionless: nothing damps the horizontal drift the closing impacts leave (6.5e-7, NLGS tolerance)
    assert np.abs(state.velocity).max() < 1e-5 and np.abs(state.omega).max() < 1e-5


@pytest.mark.parametrize(("turn", "spin"), [(0.785, (1.5, 0.4, 0.0)), (0.6, (1.5, 0.4, 0.0)), (0.785, (0.2, 1.0, 0.0))])
def test_pinacoid_rocking_on_another_does_not_sink_into_it(turn, spin):
    """A pinacoid on a face of another, turned about the vertical (an octagonal contact polygon,
    eight points plus the deepest vertex), set rocking: after 800 steps it has not sunk into the
    lower one (penetration depth < 1e-6 d; measured 9e-8, 8e-9, 1.1e-7). Four points kept out of
    the polygon's eight (the reduction this package no longer does) let the others sink: 1.2e-4,
    1.1e-4 and 4e-5 d here. In the third case the rocking grain comes down with a corner beside
    the lower face, 4e-7 d above it: the face manifold is exact (its smallest gap is the best
    separation of every axis, an edge axis's), and when it was checked against its own axis and
    then against GJK, which took the pair for touching, it was replaced by a one-point edge
    manifold and the grain landed 4.8e-5 d deep."""
    z0, height = half_height(PIN, ON_FACE), 2 * half_height(PIN, ON_FACE)
    upper = quat_multiply(quat_from_axis_angle([0.0, 0.0, 1.0], turn), ON_FACE)
    state = make_state(PIN, [[3.0, 3.0, z0], [3.0, 3.0, z0 + height + 0.002]], [ON_FACE, upper])
    state.omega[1] = rotate(upper * [1.0, -1.0, -1.0, -1.0], np.array(spin))  # body frame of a world spin
    points = []
    run(state, StepParameters(time_step=H), 800,
        each=lambda n, s, c, i: points.append(np.diff(c.point_start)[(c.body_i == 0) & (c.body_j == 1)].max(initial=0)))
    assert max(points) > 4
    exact = Detector(eps_f=1e-9).detect(state, 1e-6)  # a pair touching within 1e-6 d, deepest point below
    pair = np.repeat((exact.body_i == 0) & (exact.body_j == 1), np.diff(exact.point_start))
    assert pair.any() and -exact.gap[pair].min() < 1e-6


def test_rotation_from_start_leaves_the_overlaps_the_theta_update_does_not():
    """A pinacoid spinning at (8, 3, 0) rad/sqrt(d/g) lands on the wall at 3 sqrt(g d), with the
    velocity-level law alone (no recovery, no projection). The θ update turns the grain in the
    scheme the gaps are linearised in, and the deepest overlap of its 400 steps is 8e-7 d; turned
    from the start orientation by h ω^{n+1} (``rotation_from_start``, LMGC90's 'new rotation
    scheme'), the grain is off that scheme by (1 - θ) h Δω at each impact: 7.5e-4 d, which the law
    then keeps."""
    deepest = {}
    for from_start in (False, True):
        q = quat_multiply(quat_from_axis_angle([1.0, 1.0, 0.0], 0.3), ON_FACE)
        state = make_state(PIN, [[3.0, 3.0, half_height(PIN, q) + 0.05]], [q])
        state.velocity[0] = [0.0, 0.0, -3.0]
        state.omega[0] = rotate(q * [1.0, -1.0, -1.0, -1.0], np.array([8.0, 3.0, 0.0]))
        params = StepParameters(time_step=H, recovery_rate=0.0, overlap_slop=0.0, rotation_from_start=from_start)
        depth = []
        run(state, params, 400,
            each=lambda n, s, c, i: depth.append(-Detector(eps_f=1e-9).detect(s, 1e-3).gap.min(initial=1.0)))
        deepest[from_start] = max(depth)
    assert deepest[False] < 1e-5
    assert deepest[True] > 2e-4


# --- two free bodies -----------------------------------------------------------------------


@pytest.mark.parametrize("shape", ["sphere", "pinacoid"])
def test_head_on_inelastic_collision_conserves_momentum(shape):
    if shape == "sphere":
        shp, q = Sphere(1.0), None
    else:  # lying on a face turned to +x: two parallel faces meet head-on
        shp, q = PIN, np.tile(quat_multiply(quat_from_axis_angle([0.0, 1.0, 0.0], -np.pi / 2), ON_FACE), (2, 1))
    state = make_state(shp, [[2.0, 3.0, 4.0], [3.5, 3.0, 4.0]], q, velocity=[[1.0, 0.0, 0.0], [-0.6, 0.0, 0.0]])
    m = state.mass[:, None]
    p0 = (m * state.velocity).sum(axis=0)
    touched = []
    run(state, StepParameters(time_step=H), 150, each=lambda n, s, c, i: touched.append(i.n_points > 0))
    p1 = (m * state.velocity).sum(axis=0)
    assert any(touched)
    # horizontal momentum exactly; vertical: both fell freely for 150 h
    assert p1[0] == pytest.approx(p0[0], rel=1e-14)
    assert abs(p1[1]) < 1e-15
    assert p1[2] == pytest.approx(-m.sum() * 150 * H, rel=1e-13)
    # e_N = 0: they move on together
    # e_N = 0: they move on together (to the NLGS tolerance: 8e-7 apart for the 4-point face contact)
    assert state.velocity[0, 0] == pytest.approx(state.velocity[1, 0], abs=1e-5)
    assert state.velocity[:, 0] == pytest.approx([0.2, 0.2], abs=1e-5)


# --- friction ------------------------------------------------------------------------------


@pytest.mark.parametrize("mu", [0.0, 0.25, 0.5])
def test_block_sliding_on_the_wall_decelerates_at_mu_g(mu):
    v0 = 1.0
    z0 = half_height(PIN, ON_FACE)
    state = make_state(PIN, [[1.0, 3.0, z0]], ON_FACE, box=12.0, velocity=[[v0, 0.0, 0.0]])
    vx = []
    run(state, StepParameters(time_step=H, friction=mu), 900, each=lambda n, s, c, i: vx.append(s.velocity[0, 0]))
    vx = np.array(vx)
    travelled = np.mod(state.position[0, 0] - 1.0, 12.0)
    if mu == 0:
        assert np.all(vx == v0)
        assert travelled == pytest.approx(900 * H * v0, rel=1e-12)
        return
    n_stop = v0 / (mu * H)  # steps to stop at constant deceleration mu g
    moving = vx[: int(n_stop) - 1]
    assert v0 - vx[0] == pytest.approx(mu * H, rel=1e-4)
    # -mu g h per step, to the NLGS tolerance while warm starts build up (1.6e-5 at the 2nd step)
    np.testing.assert_allclose(np.diff(moving), -mu * H, rtol=1e-4)
    np.testing.assert_allclose(np.diff(moving[5:]), -mu * H, rtol=1e-9)
    assert np.abs(vx[int(np.ceil(n_stop)):]).max() < 1e-7  # stopped (a 3e-8 wobble, then 1e-19)
    assert travelled == pytest.approx(v0**2 / (2 * mu), abs=0.5 * H * H)
    assert abs(state.position[0, 2] - z0) < 1e-9


def test_damping_decays_a_sliding_block_exponentially_and_reports_the_energy_it_removes():
    """End-game damping: on the frictionless floor nothing else acts along x, so after n steps the
    velocity is exactly v0 exp(-γ n h), and the kinetic energy removed is reported step by step."""
    gamma, v0, n = 2.0, 0.5, 200
    z0 = half_height(PIN, ON_FACE)
    state = make_state(PIN, [[1.0, 3.0, z0]], ON_FACE, box=12.0, velocity=[[v0, 0.0, 0.0]])
    removed = []
    run(state, StepParameters(time_step=H, damping=gamma), n, each=lambda k, s, c, i: removed.append(i.damped_energy))
    assert state.velocity[0, 0] == pytest.approx(v0 * np.exp(-gamma * n * H), rel=1e-12)
    mass = state.mass[0]
    assert sum(removed) == pytest.approx(0.5 * mass * v0**2 * (1 - np.exp(-2 * gamma * n * H)), rel=1e-9)
    assert abs(state.position[0, 2] - z0) < 1e-9  # still resting on its face


# --- many grains ---------------------------------------------------------------------------


def pour(n=150, lateral=5.0, stretch=1.3, shape="pinacoid", seed=7):
    """``n`` grains on the centres of a periodic sphere deposit, heights stretched so they fall."""
    rng = np.random.default_rng(seed)
    x = deposit(np.full(n, 0.5), lateral, rng, lateral="periodic")
    x[:, 2] = 0.5 + stretch * (x[:, 2] - 0.5)
    if shape == "sphere":
        return make_state(Sphere(1.0), x, box=lateral)
    return make_state(PIN, x, random_quaternions(n, rng), box=lateral)


def pour_energy_steps(state, params, n_steps=400):
    """Step ``state`` ``n_steps`` times; per step yield ``(gain, correction, r_n, u_start, u_end)``:
    the energy change without the correction's, the correction's energy, and the normal impulses
    and the normal velocities at the start and end of the step of each contact point."""
    warm = None
    for _ in range(n_steps):
        before = total_energy(state)
        pr = predict(state, params)
        contacts = detect(pr.state, params.alert, previous=warm)
        warm, info = advance(state, pr, contacts, params, warm)
        gain = total_energy(state) - before - info.correction_energy
        r = np.zeros((contacts.n_points, 3))
        u_start = u_end = np.zeros(0)
        if contacts.n_points:
            problem = assemble(contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, H)
            r[:, 0] = np.einsum("ij,ij->i", contacts.impulse, problem.normal)
            u_start = problem.local_velocity(pr.start_velocity)[:, 0]
            u_end = problem.local_velocity(problem.velocity(r))[:, 0]
        yield gain, info.correction_energy, r[:, 0], u_start, u_end


@pytest.mark.parametrize("theta", [0.5, 1.0])
def test_pour_energy_never_increases_beyond_the_scheme_bound(theta):
    state = pour()
    e0 = total_energy(state)
    excess, gains, corrections = [], [], 0.0
    for gain, correction, r_n, u_start, _ in pour_energy_steps(state, StepParameters(time_step=H, theta=theta)):
        corrections += correction
        bound = 0.5 * float(np.sum(r_n * np.maximum(0.0, u_start))) if theta == 0.5 else 0.0
        gains.append(gain)
        excess.append(gain - bound)
    assert max(excess) < 1e-12 * e0
    assert total_energy(state) - corrections < e0 - 1.0  # the pour dissipated
    if theta == 1.0:
        assert max(gains) < 1e-12 * e0


def test_sphere_pour_energy_change_is_the_impulses_work_at_the_mean_velocity():
    """theta = 1/2: each step's energy change (correction excluded) is 1/2 sum r (u_start + u_end),
    exactly for spheres (their rotation stores no energy the impulses do not account for); the
    contacts dissipate, and put energy back only at loaded points that were opening."""
    state = pour(shape="sphere")
    e0 = total_energy(state)
    mismatch, given_back, taken = [], 0.0, 0.0
    for gain, _, r_n, u_start, u_end in pour_energy_steps(state, StepParameters(time_step=H, theta=0.5)):
        mismatch.append(abs(gain - 0.5 * float(np.sum(r_n * (u_start + u_end)))))
        given_back += 0.5 * float(np.sum(r_n * np.maximum(u_start, 0.0)))
        taken -= 0.5 * float(np.sum(r_n * np.minimum(u_start, 0.0)))
    assert max(mismatch) < 1e-12 * e0
    assert taken > 1.0 and 0.0 < given_back < 0.01 * taken


def test_settling_pile_overlaps_stay_small():
    """A bidisperse sphere deposit lifted by 2 % falls back and settles: interpenetration < 1e-4 d.

    Formulation: velocity-level IQS Signorini (existing overlaps are not pushed back by the
    velocity solve) plus the post-step position projection with ``overlap_slop`` 5e-5 d
    (:mod:`granpack.nscd.integrator`). Measured: largest overlap 6e-7 d (frictionless).
    """
    rng = np.random.default_rng(3)
    radii = np.r_[np.full(90, 0.5), np.full(90, 0.35)]
    rng.shuffle(radii)
    x = deposit(radii, 5.0, rng, lateral="periodic")
    x[:, 2] *= 1.02  # pure scaling: no overlap created
    table = ShapeTable.from_shapes([Sphere(0.7), Sphere(1.0)])
    state = ParticleState(box=Box.square(5.0), shapes=table, kind=(radii == 0.5).astype(int), population=np.zeros(180, int),
                          position=x, quaternion=np.tile([1.0, 0, 0, 0], (180, 1)))
    overlaps, points = [], []
    run(state, StepParameters(time_step=H, overlap_slop=5e-5), 400, each=lambda n, s, c, i: (overlaps.append(i.max_overlap), points.append(i.n_points)))
    assert min(points[200:]) > 300  # a connected pile (about 2 points per grain)
    assert max(overlaps) < 1e-4
    final = detect(state, 1e-3)
    assert final.n_points > 300 and max(0.0, -final.gap.min()) < 1e-4
    print(f"largest overlap {max(overlaps):.2e} d, at the end {max(0.0, -final.gap.min()):.2e} d")


def test_position_correction_translates_and_never_turns_a_grain():
    """A pinacoid on one vertex, 0.01 d into the wall, at rest: one step with ``overlap_slop`` 1e-4 d.

    The correction lifts it (lowest point back to about -0.1 slop) by a translation only: the
    grain turns by exactly ``θ h |ω^{n+1}|`` (the velocity update), not by the ~0.02 rad a
    rotation about the contact would take (the pumping that rotational projection caused on
    small grains wedged between large ones, :mod:`granpack.nscd.integrator`).
    """
    q = quat_multiply(quat_from_axis_angle([1.0, 0.3, 0.0], 0.4), quat_from_axis_angle([0.0, 0.0, 1.0], 0.2))
    lowest = half_height(PIN, q)
    state = make_state(PIN, [[0.0, 0.0, lowest - 0.01]], [q])
    params = StepParameters(time_step=H, overlap_slop=1e-4, correction_step=0.1)  # the whole correction at once
    contacts, info = step(state, params)
    assert info.correction_iterations > 0 and (contacts.gap < 0).sum() == 1  # one vertex in the wall
    bottom = state.position[0, 2] - half_height(PIN, state.quaternion[0])
    assert -1e-4 <= bottom <= 0.0
    cos_half = abs(float(np.dot(state.quaternion[0], q)))
    turned = 2.0 * np.arccos(min(1.0, cos_half))
    assert turned == pytest.approx(0.5 * H * np.linalg.norm(state.omega[0]), abs=1e-9)
    assert turned < 1e-3


def test_body_crossing_the_periodic_boundary_keeps_contacts_and_velocity():
    """A pinacoid on a face carrying a sphere 0.2 d off-centre, both sliding (μ = 0) across x = L."""
    lateral = 4.0
    z0, height = half_height(PIN, ON_FACE), 2 * half_height(PIN, ON_FACE)
    state = ParticleState(
        box=Box.square(lateral), shapes=ShapeTable.from_shapes([PIN, Sphere(1.0)]), kind=[0, 1], population=[0, 0],
        position=[[3.3, 2.0, z0], [3.5, 2.0, height + 0.5]], quaternion=[ON_FACE, [1.0, 0, 0, 0]],
    )
    params = StepParameters(time_step=H)
    weight = state.mass
    shifts = []
    warm, _ = run(state, params, 60)  # settle (the closing transient decays to 1e-11 in 40 steps)
    state.velocity[:] = [2.0, 0.0, 0.0]

    def check(n, s, c, info):
        forces = pair_forces(c)
        assert sorted(forces) == [(0, -1), (0, 1)]
        assert info.n_warm == info.n_points == 5  # every point warm-started, across the boundary too
        assert forces[(0, -1)][2] == pytest.approx(weight.sum(), rel=1e-9)
        assert forces[(0, 1)][2] == pytest.approx(-weight[1], rel=1e-9)
        np.testing.assert_allclose(s.velocity, [[2.0, 0, 0], [2.0, 0, 0]], rtol=0, atol=1e-8)  # a 1e-11 face tilt: vy ~ 1e-10
        shifts.append(float(c.shift[c.body_j == 1][0, 0]))

    run(state, params, 200, warm, each=check)  # 2 d: both cross x = L
    assert set(shifts) == {0.0, lateral}  # the pair was seen through its periodic image (20 steps)
    assert shifts.count(lateral) == pytest.approx(20, abs=1)
    dx = np.mod(state.position[1, 0] - state.position[0, 0] + 0.5 * lateral, lateral) - 0.5 * lateral
    assert dx == pytest.approx(0.2, abs=1e-9)


_POUR_DIGEST = """
import hashlib, numpy as np, sys
sys.path.insert(0, {tests!r})
from test_nscd_dynamics import pour, run, H
from granpack.nscd import StepParameters
state = pour(n={n}, seed={seed})
run(state, StepParameters(time_step=H, {params}), {steps})
h = hashlib.sha256()
for a in (state.position, state.quaternion, state.velocity, state.omega):
    h.update(np.ascontiguousarray(a).tobytes())
print(h.hexdigest())
"""


def _pour_digest(n, seed, params, steps, threads=None):
    """SHA-256 of the state after a pour of ``n`` pinacoids, run in a fresh process (``threads``:
    its NUMBA_NUM_THREADS)."""
    import os
    import pathlib

    code = _POUR_DIGEST.format(tests=str(pathlib.Path(__file__).parent), n=n, seed=seed, params=params, steps=steps)
    env = os.environ if threads is None else {**os.environ, "NUMBA_NUM_THREADS": threads}
    digest = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout
    assert len(digest) > 60
    return digest


def test_results_are_bitwise_identical_run_to_run():
    assert len({_pour_digest(100, 11, "friction=0.2", 200) for _ in range(2)}) == 1


def test_results_do_not_depend_on_the_thread_count():
    """Kernels that split their bodies, manifolds or points among threads (prediction, update,
    assembly, warm start, the two-part solve) give the same pour on one thread and on three, bit for bit."""
    assert len({_pour_digest(60, 5, "parallel_points=1", 150, threads) for threads in ("1", "3")}) == 1


def test_granpack_lets_waiting_openmp_threads_spin_only_briefly():
    """granpack sets GNU OpenMP's spin count before the runtime loads, unless the user did."""
    import os

    code = "import os, granpack._numba; print(os.environ['GOMP_SPINCOUNT'])"
    env = {k: v for k, v in os.environ.items() if k != "GOMP_SPINCOUNT"}
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout.strip() == "10000"
    env["GOMP_SPINCOUNT"] = "5"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env).stdout.strip() == "5"


def test_required_alert_catches_fast_approaches_that_a_fixed_alert_misses():
    """Two spheres approaching at 2 x 8 sqrt(g d): 0.08 d per step, more than the default alert.

    Gap 0.11: 0.07 at the first predicted configuration (not detected with alert 0.05), -0.01 at
    the next one; IQS does not push existing overlaps back (and the correction is off here).
    """

    def collide(alert):
        state = make_state(Sphere(1.0), [[2.0, 3.0, 4.0], [3.11, 3.0, 4.0]], velocity=[[8.0, 0, 0], [-8.0, 0, 0]])
        worst = 0.0
        warm = None
        for _ in range(10):
            a = required_alert(state, H) if alert is None else alert
            warm, info = step(state, StepParameters(time_step=H, alert=a, overlap_slop=0.0), warm)
            d = np.linalg.norm(state.position[1] - state.position[0])
            worst = max(worst, 1.0 - d)
        return worst, state

    missed, _ = collide(0.05)
    assert missed > 1e-3  # the contact is first seen already interpenetrating
    caught, state = collide(None)
    assert caught < 1e-9
    assert state.velocity[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert required_alert(state, H) == pytest.approx(2 * H * np.linalg.norm(state.velocity[0]) + H * H)
    assert required_alert(state, H, minimum=0.02) == 0.02


def test_step_parameters_reject_bad_values_and_bound_the_correction_budget():
    for bad in ({"time_step": 0.0}, {"theta": 0.4}, {"friction": -0.1}, {"restitution": 1.5}, {"alert": -1.0},
                {"correction_sweeps": 0}, {"correction_step": 0.0}, {"slow_recovery_speed": -1e-4},
                {"slow_recovery_slop": -1e-5}):
        with pytest.raises(ValueError):
            StepParameters(**bad)
    assert StepParameters().correction_options.max_iterations == 200
    assert StepParameters(max_iterations=50).correction_options.max_iterations == 50
    assert StepParameters(tolerance=3e-4).correction_options.tolerance == 3e-4


@pytest.mark.parametrize(("overlap", "lift"), [(5e-4, 5e-4 - CORRECTED_OVERLAP * 1e-4), (0.01, 1e-3)])
def test_position_correction_lifts_to_the_corrected_overlap_at_most_one_correction_step_per_step(overlap, lift):
    """A sphere at rest ``overlap`` into the wall, ``overlap_slop`` 1e-4 d: one step lifts it to
    an overlap of ``CORRECTED_OVERLAP`` slop, or by ``correction_step`` (1e-3 d) when more is needed (the bound that
    stops the correction/IQS treadmill, :mod:`granpack.nscd.integrator`); its velocity stays 0."""
    ball = Sphere(1.0)
    state = make_state(ball, [[0.0, 0.0, 0.5 - overlap]])
    _, info = step(state, StepParameters(time_step=H, overlap_slop=1e-4, recovery_rate=0.0))
    assert info.correction_iterations > 0
    assert state.position[0, 2] - (0.5 - overlap) == pytest.approx(lift, abs=1e-12)
    np.testing.assert_allclose(state.velocity[0], 0.0, atol=1e-15)


def test_overlap_recovery_pushes_a_ball_out_of_the_wall_at_a_bounded_speed_and_stops_at_the_slop():
    """A ball at rest 0.01 d into the wall, position correction off: the velocity law pushes it
    out at ``recovery_speed`` (0.05 sqrt(g d)) while the excess over ``recovery_slop`` is large,
    then at 0.2 of the excess per step, and it comes to rest (from step 45) with the overlap just
    under the slop (3.75e-4 d: the last push goes on over the first half of the next step, θ = ½),
    never launched off the wall. Without the recovery it stays 0.01 d in."""
    ball = Sphere(1.0)
    params = StepParameters(time_step=H, overlap_slop=0.0, tolerance=1e-10, max_iterations=20000)
    state = make_state(ball, [[0.0, 0.0, 0.5 - 0.01]])
    warm, info = step(state, params)
    assert state.velocity[0, 2] == pytest.approx(params.recovery_speed, rel=1e-6)
    overlaps = []
    run(state, params, 600, warm, each=lambda n, s, c, i: overlaps.append(0.5 - s.position[0, 2]))
    assert np.all(np.diff(overlaps) <= 1e-12) and overlaps[-1] > 0.0
    assert params.recovery_slop - 2e-4 < overlaps[-1] <= params.recovery_slop
    assert overlaps[100] == overlaps[-1] and state.velocity[0, 2] == 0.0
    plain = make_state(ball, [[0.0, 0.0, 0.5 - 0.01]])
    run(plain, replace(params, recovery_rate=0.0), 100)
    assert 0.5 - plain.position[0, 2] == pytest.approx(0.01, abs=1e-9)


def test_slow_overlap_recovery_pushes_an_overlap_between_the_two_slops_back_at_its_own_speed():
    """A ball at rest 3e-4 d into the wall, below the recovery slop (5e-4 d): the velocity law
    alone leaves it there; with the slow tier (slop 5e-5 d, speed 2e-4 sqrt(g d)) it moves out at
    that speed, never faster, and stops at the slow slop (0.2 of the excess per step at the end).
    A ball 0.01 d in is still pushed out at the fast tier's speed (the slow tier never slows a
    deep overlap down)."""
    ball = Sphere(1.0)
    params = StepParameters(time_step=H, overlap_slop=0.0, tolerance=1e-10, max_iterations=20000)
    slow = replace(params, slow_recovery_slop=5e-5, slow_recovery_speed=2e-4)
    kept = make_state(ball, [[0.0, 0.0, 0.5 - 3e-4]])
    run(kept, params, 50)
    assert 0.5 - kept.position[0, 2] == pytest.approx(3e-4, abs=1e-12)
    state = make_state(ball, [[0.0, 0.0, 0.5 - 3e-4]])
    overlaps, speeds = [], []

    def record(n, s, c, i):
        overlaps.append(0.5 - s.position[0, 2])
        speeds.append(s.velocity[0, 2])

    run(state, slow, 600, each=record)
    assert max(speeds) == pytest.approx(2e-4, rel=1e-6) and min(speeds) >= 0.0
    assert np.all(np.diff(overlaps) <= 1e-15)
    assert overlaps[-1] == pytest.approx(5e-5, abs=1e-12) and abs(speeds[-1]) < 1e-12
    deep = make_state(ball, [[0.0, 0.0, 0.5 - 0.01]])
    step(deep, slow)
    assert deep.velocity[0, 2] == pytest.approx(params.recovery_speed, rel=1e-6)


def _manifold_gaps(state):
    """``{(i, j): deepest gap}`` of every pair within 1e-3 d."""
    found = detect(state, 1e-3)
    m = np.repeat(np.arange(found.n_manifolds), np.diff(found.point_start))
    return {(int(found.body_i[k]), int(found.body_j[k])): float(found.gap[m == k].min()) for k in range(found.n_manifolds)}


def test_capped_position_correction_never_digs_a_new_overlap():
    """Four balls: B sits 0.02 d into A (A on the wall), C touches B from the side and D is
    0.002 d into C. The correction lifts B by 0.02 d and pushes C towards B; with the bound of
    1e-3 d per step, scaling each body alone (B by 1/20, C not at all) drove C 6e-4 d into B. One
    common factor for every translation (:mod:`granpack.nscd.integrator`) keeps every contact that
    was not overlapping at >= -0.1 slop while every overlap shrinks."""
    slop = 1e-4
    start = np.array([[0.0, 0.0, 0.5], [0.0, 0.0, 1.48], [1.0, 0.0, 1.48], [1.998, 0.0, 1.48]])
    state = make_state(Sphere(1.0), start.copy(), box=12.0)
    before = _manifold_gaps(state)
    assert before[(1, 2)] == pytest.approx(0.0, abs=1e-12) and before[(0, 1)] == pytest.approx(-0.02)
    params = StepParameters(time_step=H, overlap_slop=slop, tolerance=1e-8, max_iterations=20000,
                            correction_sweeps=20000, recovery_rate=0.0)
    _, info = step(state, params)
    after = _manifold_gaps(state)
    assert info.correction_iterations > 0
    assert state.position[1, 2] - start[1, 2] == pytest.approx(1e-3, abs=1e-6)  # the longest translation
    for pair, gap in before.items():
        if gap >= -CORRECTED_OVERLAP * slop:
            assert after[pair] >= -CORRECTED_OVERLAP * slop - 1e-9, pair
        else:
            assert after[pair] > gap + 5e-5, pair


def test_bounded_position_correction_shrinks_every_overlap_of_a_column():
    """Eight balls stacked on the wall, each 0.01 d into the one below (the first 0.01 d into the
    wall): the projection lifts ball k by (k + 1) 0.01 d. Bounding each ball's translation to
    1e-3 d alone lifts the whole column rigidly, so only the wall contact shrinks; in a pile of
    flat pinacoids that rigid lift fell back at the next step, every step, and the pile never came
    to rest (docs/design-notes.md). The common factor shrinks every overlap by the same fraction
    (1e-3 d over the 8 contacts of the column: 1/80 of each overlap)."""
    n, overlap = 8, 0.01
    start = np.zeros((n, 3))
    start[:, 2] = 0.5 - overlap + np.arange(n) * (1.0 - overlap)
    state = make_state(Sphere(1.0), start.copy(), box=3.0)
    before = _manifold_gaps(state)
    params = StepParameters(time_step=H, overlap_slop=1e-4, tolerance=1e-10, max_iterations=20000,
                            correction_sweeps=20000, recovery_rate=0.0)
    _, info = step(state, params)
    after = _manifold_gaps(state)
    assert info.correction_iterations > 0
    assert len(before) == n and all(gap == pytest.approx(-overlap) for gap in before.values())
    for pair, gap in before.items():
        assert after[pair] - gap == pytest.approx(1e-3 / n, rel=0.05), pair
