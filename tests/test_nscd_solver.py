"""NSCD building blocks on hand-built contact sets: rigid kinematics, NLGS, warm start.

Contacts here are written by hand (spheres: exact gaps and midpoints) so that the solver is
checked independently of contact detection; full dynamics with detection are in
``test_nscd_dynamics.py``.
"""

import numpy as np
import pytest

from granpack import Box, ShapeTable, Sphere
from granpack.contact.contacts import ContactSet
from granpack.nscd import (
    NLGSOptions,
    StepParameters,
    advance,
    assemble,
    kinetic_energy,
    predict,
    solve,
    world_inverse_inertia,
)
from granpack.rotations import quat_to_matrix, random_quaternions
from granpack.shapes import Pinacoid
from granpack.state import ParticleState

H = 5e-3


def sphere_state(positions, diameters=None, box=8.0, velocity=None):
    positions = np.asarray(positions, dtype=float)
    n = len(positions)
    diameters = np.ones(n) if diameters is None else np.asarray(diameters, dtype=float)
    sizes = sorted(set(diameters.tolist()))
    table = ShapeTable.from_shapes([Sphere(d) for d in sizes])
    kind = np.array([sizes.index(d) for d in diameters])
    q = np.tile([1.0, 0, 0, 0], (n, 1))
    return ParticleState(box=Box.square(box), shapes=table, kind=kind, population=np.zeros(n, int), position=positions, quaternion=q, velocity=velocity)


def sphere_contacts(state, pairs, walls):
    """Exact sphere contacts of ``state`` (the predicted configuration): pairs ``(i, j, shift)`` and wall bodies."""
    bi, bj, shift, normal, point, gap = [], [], [], [], [], []
    r = state.radius
    for i, j, s in pairs:
        xj = state.position[j] + np.asarray(s, float)
        d = state.position[i] - xj
        dist = np.linalg.norm(d)
        n = d / dist
        g = dist - r[i] - r[j]
        bi.append(i), bj.append(j), shift.append(s), normal.append(n), gap.append(g)
        point.append(xj + (r[j] + 0.5 * g) * n)
    for i in walls:
        g = state.position[i, 2] - r[i]
        bi.append(i), bj.append(-1), shift.append((0, 0, 0)), normal.append((0, 0, 1.0)), gap.append(g)
        point.append(state.position[i] * [1, 1, 0] + [0, 0, 0.5 * g])
    m = len(bi)
    return ContactSet(
        body_i=np.array(bi, np.int64), body_j=np.array(bj, np.int64), shift=np.array(shift, float).reshape(m, 3),
        normal=np.array(normal, float).reshape(m, 3), ctype=np.ones(m, np.int64), point_start=np.arange(m + 1),
        point=np.array(point, float).reshape(m, 3), gap=np.array(gap, float),
    )


def run(state, params, pairs, walls, steps, warm=None):
    infos = []
    for _ in range(steps):
        pr = predict(state, params)
        contacts = sphere_contacts(pr.state, pairs, walls)
        warm, info = advance(state, pr, contacts, params, warm)
        infos.append(info)
    return warm, infos


def test_world_inverse_inertia_matches_dense_inverse(rng):
    q = random_quaternions(20, rng)
    inertia = rng.uniform(0.5, 2.0, (20, 3))
    sym = world_inverse_inertia(q, inertia)
    rot = quat_to_matrix(q)
    for p in range(20):
        dense = np.linalg.inv(rot[p] @ np.diag(inertia[p]) @ rot[p].T)
        packed = sym[p][[0, 3, 4, 3, 1, 5, 4, 5, 2]].reshape(3, 3)
        np.testing.assert_allclose(packed, dense, rtol=1e-12, atol=1e-12)


def test_free_flight_is_the_exact_parabola_for_theta_half():
    state = sphere_state([[1.0, 1.0, 5.0]], velocity=[[0.3, -0.2, 1.5]])
    params = StepParameters(time_step=H)
    run(state, params, [], [], 200)
    t = 200 * H
    expected = np.array([1.0 + 0.3 * t, 1.0 - 0.2 * t, 5.0 + 1.5 * t - 0.5 * t * t])
    np.testing.assert_allclose(state.position[0], expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state.velocity[0], [0.3, -0.2, 1.5 - t], atol=1e-12)


def test_free_rotation_keeps_unit_quaternion_energy_and_momentum_direction(rng):
    shape = Pinacoid.family("elongated")
    table = ShapeTable.from_shapes([shape])
    state = ParticleState(
        box=Box.square(8), shapes=table, kind=[0], population=[0], position=[[4, 4, 4.0]],
        quaternion=random_quaternions(1, rng), velocity=[[0, 0, 0]], omega=[[3.0, 0.4, -2.0]],
    )
    e0 = 0.5 * np.sum(state.inertia * state.omega**2)
    rot = quat_to_matrix(state.quaternion[0])
    l0 = rot @ (state.inertia[0] * state.omega[0])
    run(state, StepParameters(time_step=H), [], [], 2000)
    assert abs(np.linalg.norm(state.quaternion[0]) - 1.0) < 1e-14
    assert 0.5 * np.sum(state.inertia * state.omega**2) == pytest.approx(e0, rel=1e-12)
    rot = quat_to_matrix(state.quaternion[0])
    l1 = rot @ (state.inertia[0] * state.omega[0])
    # the world angular momentum of a torque-free body stays put (to the scheme's accuracy)
    assert np.linalg.norm(l1 - l0) < 2e-2 * np.linalg.norm(l0)


def test_sphere_resting_on_wall_carries_its_weight_exactly():
    state = sphere_state([[1.0, 1.0, 0.5]])
    params = StepParameters(time_step=H, tolerance=1e-10)
    contacts, infos = run(state, params, [], [0], 20)
    force = contacts.impulse / H
    np.testing.assert_allclose(force[0], [0, 0, state.mass[0]], rtol=1e-12)
    assert state.position[0, 2] == pytest.approx(0.5, abs=1e-14)
    assert np.all(state.velocity == 0.0)


def test_column_of_five_spheres_each_contact_carries_the_weight_above():
    n = 5
    state = sphere_state([[2.0, 2.0, 0.5 + k] for k in range(n)])
    params = StepParameters(time_step=H, tolerance=1e-8, max_iterations=20000)
    pairs = [(k + 1, k, (0, 0, 0)) for k in range(n - 1)]
    contacts, infos = run(state, params, pairs, [0], 30)
    assert infos[-1].converged
    weight = state.mass[0]
    force = contacts.impulse[:, 2] / H
    # pair (k+1, k) carries the spheres k+1..n-1; the wall carries all
    np.testing.assert_allclose(force[: n - 1], weight * np.arange(n - 1, 0, -1), rtol=1e-6)
    assert force[n - 1] == pytest.approx(n * weight, rel=1e-6)
    assert np.abs(state.velocity).max() < 1e-6
    assert infos[-1].n_warm == n


def test_warm_start_converges_on_the_first_check():
    n = 5
    state = sphere_state([[2.0, 2.0, 0.5 + k] for k in range(n)])
    params = StepParameters(time_step=H, tolerance=1e-6, max_iterations=20000)
    pairs = [(k + 1, k, (0, 0, 0)) for k in range(n - 1)]
    _, cold = run(state, params, pairs, [0], 1)
    warm, _ = run(state, params, pairs, [0], 20)
    _, hot = run(state, params, pairs, [0], 1, warm=warm)
    assert hot[0].n_warm == n
    assert hot[0].iterations == params.check_every < cold[0].iterations


@pytest.mark.parametrize("restitution", [0.0, 0.5, 1.0])
def test_head_on_collision_conserves_momentum_exactly(restitution):
    # spheres of diameters 1 and 0.5 (mass ratio 8) meet head-on; the gap at the predicted configuration is -1e-9
    sep = 0.75 + 0.5 * H * 1.5 - 1e-9
    state = sphere_state([[3.0, 4.0, 4.0], [3.0 + sep, 4.0, 4.0]], diameters=[1.0, 0.5], velocity=[[1.0, 0.1, 0], [-0.5, 0.1, 0]])
    params = StepParameters(time_step=H, restitution=restitution, tolerance=1e-12)
    m = state.mass
    p0 = m @ state.velocity
    run(state, params, [(1, 0, (0, 0, 0))], [], 3)
    p1 = m @ state.velocity
    # gravity removes m g t along z only
    np.testing.assert_allclose(p1[:2], p0[:2], rtol=0, atol=1e-15)
    assert p1[2] == pytest.approx(p0[2] - m.sum() * 3 * H, abs=1e-15)
    assert state.velocity[1, 0] - state.velocity[0, 0] == pytest.approx(1.5 * restitution, abs=1e-12)
    assert state.velocity[0, 1] == 0.1


def test_contact_through_the_periodic_boundary():
    # body 1 near x = lx moves +x and hits body 0 near x = 0 through its image x_1 - lx
    lx = 4.0
    x1 = lx - 0.6 - 0.5 * H + 1e-9
    state = sphere_state([[0.4, 2.0, 2.0], [x1, 2.0, 2.0]], box=lx, velocity=[[0.0, 0, 0], [1.0, 0, 0]])
    run(state, StepParameters(time_step=H, tolerance=1e-12), [(0, 1, (-lx, 0, 0))], [], 1)
    np.testing.assert_allclose(state.velocity[:, 0], [0.5, 0.5], atol=1e-12)
    assert np.all((state.position[:, 0] >= 0) & (state.position[:, 0] < lx))


def test_solver_residual_is_small_and_independent_of_warm_start(rng):
    # a random stack-like problem: spheres resting on the wall and on each other in a square lattice
    pos = [[0.5 + i, 0.5 + j, 0.5 + k] for i in range(4) for j in range(4) for k in range(3)]
    state = sphere_state(pos, box=4.0)
    params = StepParameters(time_step=H)
    pr = predict(state, params)
    idx = {tuple(np.round(p, 6)): n for n, p in enumerate(pos)}
    pairs = [(idx[(p[0], p[1], p[2] + 1)], n, (0, 0, 0)) for n, p in enumerate(pos) if (p[0], p[1], p[2] + 1) in idx]
    walls = [n for n, p in enumerate(pos) if p[2] == 0.5]
    contacts = sphere_contacts(pr.state, pairs, walls)
    problem = assemble(contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, H)
    r, info = solve(problem, NLGSOptions(tolerance=1e-10, max_iterations=100000))
    assert info.converged
    assert problem.residual(r) < 1e-8
    v = problem.velocity(r)
    assert np.abs(v[:-1]).max() < 1e-8
    assert kinetic_energy(state) == 0.0


def _lattice_problem(layers=3):
    """A 4 x 4 x ``layers`` lattice of touching unit spheres on the wall, every neighbour pair a
    contact (across the periodic boundary too): its state and assembled problem."""
    pos = [[0.5 + i, 0.5 + j, 0.5 + k] for i in range(4) for j in range(4) for k in range(layers)]
    state = sphere_state(pos, box=4.0)
    params = StepParameters(time_step=H)
    pr = predict(state, params)
    idx = {tuple(np.round(p, 6)): n for n, p in enumerate(pos)}
    pairs = []
    for n, p in enumerate(pos):
        for axis in range(3):
            q = list(p)
            q[axis] += 1.0
            shift = [0.0, 0.0, 0.0]
            if axis < 2 and q[axis] > 4.0:
                q[axis] -= 4.0
                shift[axis] = 4.0
            if tuple(np.round(q, 6)) in idx:
                pairs.append((idx[tuple(np.round(q, 6))], n, tuple(shift)))
    walls = [n for n, p in enumerate(pos) if p[2] == 0.5]
    contacts = sphere_contacts(pr.state, pairs, walls)
    return state, pr, contacts


def test_nncg_solves_a_tall_stack_to_the_same_velocities_in_fewer_sweeps():
    """The NNCG momentum (:func:`granpack.nscd.nlgs._solve_frictionless`) converges to the
    velocities of plain NLGS (unique, unlike the impulses) on a 4 x 4 x 12 lattice from a cold
    start, the case where Gauss-Seidel carries the weight down one layer per sweep."""
    state, pr, contacts = _lattice_problem(layers=12)
    problem = assemble(contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, H)
    plain, info_plain = solve(problem, NLGSOptions(tolerance=1e-8, max_iterations=200000))
    nncg, info_nncg = solve(problem, NLGSOptions(tolerance=1e-8, max_iterations=200000, nncg=True))
    assert info_plain.converged and info_nncg.converged
    assert problem.residual(nncg) < 1e-6
    np.testing.assert_allclose(problem.velocity(nncg), problem.velocity(plain), atol=1e-8)
    assert info_nncg.iterations < 0.5 * info_plain.iterations


def test_two_thread_sweeps_solve_the_same_problem():
    """The two-part NLGS (points split by the part of the pile, lower or upper, their bodies lie
    in; the two parts swept at once, the pairs across them after) converges to the velocities of
    the sequential sweeps, with and without the NNCG momentum: a 4 x 4 x 4 lattice of spheres,
    every point in one of the three groups."""
    from granpack.nscd.integrator import _sides
    from granpack.nscd.nlgs import _two_parts

    state, pr, contacts = _lattice_problem(layers=4)
    problem = assemble(contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, H,
                       side=_sides(pr.x_tt, contacts.point[:, 2]))
    order, bounds = _two_parts(problem)
    assert np.all(np.diff(bounds) > 0)  # both parts and the pairs across them
    for nncg in (False, True):
        r_seq, info_seq = solve(problem, NLGSOptions(tolerance=1e-12, max_iterations=200000, nncg=nncg))
        r_par, info_par = solve(problem, NLGSOptions(tolerance=1e-12, max_iterations=200000, parallel_points=1,
                                                     nncg=nncg))
        assert info_seq.converged and info_par.converged
        assert problem.residual(r_par) < 1e-10
        v_seq, v_par = problem.velocity(r_seq), problem.velocity(r_par)
        np.testing.assert_allclose(v_par, v_seq, atol=1e-10)  # V^{n+1} is unique (impulses need not be)


def test_two_part_sweeps_do_not_depend_on_the_thread_count():
    """The two parts share no body, so one thread sweeping them in turn gives the impulses of two
    threads sweeping them at once, bit for bit (a run is the same on any machine)."""
    import numba

    from granpack.nscd.integrator import _sides

    state, pr, contacts = _lattice_problem(layers=6)
    problem = assemble(contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, H,
                       side=_sides(pr.x_tt, contacts.point[:, 2]))
    options = NLGSOptions(tolerance=1e-6, max_iterations=50, parallel_points=1, nncg=True)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        r_one, info_one = solve(problem, options)
    finally:
        numba.set_num_threads(threads)
    r_two, info_two = solve(problem, options)
    assert info_one.iterations == info_two.iterations == 50  # stopped mid-way: the iterates, not a limit
    np.testing.assert_array_equal(r_one, r_two)
    assert numba.get_num_threads() == threads


def test_two_part_parallel_build_gives_the_serial_builds_bits():
    """The parallel build of the two-part sweeps (two threads launched once per solve, meeting
    through atomic words) gives the serial build's impulses, velocities and sweeps bit for bit,
    converged or stopped mid-way, with and without the NNCG momentum."""
    from granpack.nscd.integrator import _sides
    from granpack.nscd.nlgs import _gather_points, _solve_frictionless_two_parts, _two_parts

    state, pr, contacts = _lattice_problem(layers=6)
    problem = assemble(contacts, pr.x_tt, pr.inv_mass, pr.inv_inertia_world, pr.start_velocity, pr.free_velocity, H,
                       side=_sides(pr.x_tt, contacts.point[:, 2]))
    order, bounds = _two_parts(problem)
    body, data, offset, r0 = _gather_points.serial(order, problem.body, problem.normal_data, problem.offset,
                                                   np.zeros(problem.n_points))
    for nncg, tol, sweeps in ((False, 1e-10, 200000), (True, 1e-10, 200000), (True, 1e-6, 51)):
        out = []
        for build in (_solve_frictionless_two_parts.serial, _solve_frictionless_two_parts.parallel):
            r, v = r0.copy(), problem.velocity(np.zeros((problem.n_points, 3)))
            info = build(body, data, offset, r, v, bounds, tol, sweeps, 10, nncg)
            out.append((r, v, info))
        (r_s, v_s, info_s), (r_p, v_p, info_p) = out
        assert info_s == info_p and info_s[0] > 1
        np.testing.assert_array_equal(r_p, r_s)
        np.testing.assert_array_equal(v_p, v_s)


def test_sides_split_the_bodies_at_the_median_height_of_the_points():
    """Bodies whose centre is at or above the median height of the contact points are side 1;
    the wall row is side 0."""
    from granpack.nscd.integrator import _sides

    position = np.array([[0.0, 0.0, z] for z in (0.5, 1.5, 2.5, 3.5)])
    side = _sides(position, np.array([0.0, 1.0, 2.0, 3.0, 3.0]))  # median 2.0
    np.testing.assert_array_equal(side, [0, 0, 1, 1, 0])
    np.testing.assert_array_equal(_sides(position, np.zeros(0)), [0, 0, 0, 0, 0])