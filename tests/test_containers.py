"""Containers (box and cylinder): wall contacts on hand-built configurations with exact answers,
and the dynamics of grains held by them.

Expected gaps, normals and points come from the world vertices and the container's geometry
(a plane's height, ``R - |v_xy|`` for the cylinder), computed here in plain numpy.
"""

from __future__ import annotations

import math

import meshio
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from granpack.box import Box
from granpack.config import load_config_dict
from granpack.contact import SIMPLE, TRIPLE, ContactSet, detect
from granpack.deposit import deposit
from granpack.equilibrium import wall_force
from granpack.io.container import container_surface, write_container_stl
from granpack.io.gsd import frame_origin, read_packing, write_packing
from granpack.io.json import read_json
from granpack.io.vtk import write_vtk
from granpack.mesh.surfaces import grain_surfaces
from granpack.nscd import StepParameters, step, total_energy
from granpack.packing import Packing
from granpack.simulation import run_packing
from granpack.rotations import quat_from_axis_angle, quat_multiply, quat_to_matrix, random_quaternions
from granpack.shapes import Pinacoid, ShapeTable, Sphere, platonic
from granpack.state import ParticleState

ALERT = 0.02
L = 4.0
AXIS = np.array([0.5 * L, 0.5 * L])
R_CYL = 0.5 * L
IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
#: inward unit normal of each of the box's walls, by wall id
BOX_WALLS = {-2: (1.0, 0.0), -3: (-1.0, 0.0), -4: (0.0, 1.0), -5: (0.0, -1.0)}


def state_of(shapes, kinds, positions, quaternions, container, lateral=L) -> ParticleState:
    n = len(kinds)
    return ParticleState(box=Box.square(lateral, container), shapes=ShapeTable.from_shapes(shapes),
                         kind=np.asarray(kinds, np.int64), population=np.zeros(n, np.int64),
                         position=np.asarray(positions, float).reshape(n, 3),
                         quaternion=np.asarray(quaternions, float).reshape(n, 4))


def manifolds(cs: ContactSet) -> list[dict]:
    out = []
    for m in range(cs.n_manifolds):
        s = slice(cs.point_start[m], cs.point_start[m + 1])
        out.append(dict(i=int(cs.body_i[m]), j=int(cs.body_j[m]), normal=cs.normal[m], ctype=int(cs.ctype[m]),
                        points=cs.point[s], gaps=cs.gap[s], shift=cs.shift[m]))
    return out


def world_vertices(shape, q, x) -> np.ndarray:
    return np.asarray(x) + shape.vertices @ quat_to_matrix(np.asarray(q)).T


def wall_height(wall: int, p: np.ndarray) -> np.ndarray:
    """Height of points ``p`` (..., 3) above the box's wall ``wall``, d."""
    return {-2: p[..., 0], -3: L - p[..., 0], -4: p[..., 1], -5: L - p[..., 1]}[wall]


# ---------------------------------------------------------------------------------------------
# the box


@pytest.mark.parametrize("wall", sorted(BOX_WALLS))
@pytest.mark.parametrize("gap", [0.01, 0.0, -0.004])
def test_sphere_against_each_box_wall(wall, gap):
    r = 0.5
    wx, wy = BOX_WALLS[wall]
    centre = np.array([0.5 * L, 0.5 * L, 1.7])
    # the centre moved towards the wall until its gap is `gap`
    centre[:2] -= (0.5 * L - r - gap) * np.array([wx, wy])
    ms = manifolds(detect(state_of([Sphere(2 * r)], [0], [centre], [IDENTITY], "box"), ALERT))
    assert [m["j"] for m in ms] == [wall]
    m = ms[0]
    assert m["ctype"] == SIMPLE
    np.testing.assert_allclose(m["normal"], [wx, wy, 0.0], atol=1e-12)
    np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
    np.testing.assert_allclose(m["points"][0], centre - (r + 0.5 * gap) * np.array([wx, wy, 0.0]), atol=1e-12)
    np.testing.assert_allclose(m["shift"], 0.0)


@pytest.mark.parametrize("corner", [(-2, -4), (-2, -5), (-3, -4), (-3, -5)])
def test_sphere_in_a_box_corner_touches_the_floor_and_two_walls(corner):
    r, gaps = 0.5, {-1: 0.003, corner[0]: -0.002, corner[1]: 0.007}
    centre = np.zeros(3)
    centre[2] = r + gaps[-1]
    for wall in corner:
        wx, wy = BOX_WALLS[wall]
        axis = 0 if wx else 1
        inward = wx + wy
        centre[axis] = r + gaps[wall] if inward > 0 else L - r - gaps[wall]
    ms = manifolds(detect(state_of([Sphere(2 * r)], [0], [centre], [IDENTITY], "box"), ALERT))
    assert [m["j"] for m in ms] == sorted(gaps, reverse=True)  # the floor, then the walls by id
    for m in ms:
        np.testing.assert_allclose(m["gaps"], [gaps[m["j"]]], atol=1e-12)
        normal = [0.0, 0.0, 1.0] if m["j"] == -1 else [*BOX_WALLS[m["j"]], 0.0]
        np.testing.assert_allclose(m["normal"], normal, atol=1e-12)
        np.testing.assert_allclose(m["points"][0], centre - (r + 0.5 * gaps[m["j"]]) * np.asarray(normal), atol=1e-12)


@pytest.mark.parametrize("wall", sorted(BOX_WALLS))
@pytest.mark.parametrize("gap", [0.004, -0.002])
def test_pinacoid_face_to_face_with_a_box_wall(wall, gap):
    sh = Pinacoid.from_size(1.0, 2.0, 3.0)
    f = int(np.argmax([sh.face_offsets[k] for k in range(len(sh.faces))]))  # a large face: the farthest
    wx, wy = BOX_WALLS[wall]
    outward = -np.array([wx, wy, 0.0])
    # the smallest rotation taking the face's normal onto the wall's outward direction
    n = sh.face_normals[f]
    c = np.cross(n, outward)
    q = quat_from_axis_angle(c, math.atan2(np.linalg.norm(c), n @ outward)) if np.linalg.norm(c) > 1e-12 else \
        (IDENTITY if n @ outward > 0 else quat_from_axis_angle([0.0, 0.0, 1.0], math.pi))
    centre = np.array([0.5 * L, 0.5 * L, 2.0]) + (0.5 * L - sh.face_offsets[f] - gap) * outward
    ms = manifolds(detect(state_of([sh], [0], [centre], [q], "box"), ALERT))
    assert [m["j"] for m in ms] == [wall]
    m = ms[0]
    assert m["ctype"] == TRIPLE
    np.testing.assert_allclose(m["normal"], -outward, atol=1e-12)
    v = world_vertices(sh, q, centre)[sh.faces[f]]
    assert len(m["gaps"]) == len(v)
    np.testing.assert_allclose(m["gaps"], gap, atol=1e-12)
    np.testing.assert_allclose(wall_height(wall, v), gap, atol=1e-12)
    expected = v + 0.5 * gap * outward
    assert np.linalg.norm(m["points"][:, None] - expected[None], axis=2).min(axis=1).max() < 1e-12


def test_a_box_has_no_periodic_images():
    r = 0.5
    positions = [[r + 0.01, 2.0, 1.5], [L - r - 0.01, 2.0, 1.5]]  # touching across x = 0 if periodic
    periodic = detect(state_of([Sphere(2 * r)], [0, 0], positions, [IDENTITY, IDENTITY], "periodic"), ALERT)
    assert [(int(i), int(j)) for i, j in zip(periodic.body_i, periodic.body_j)] == [(0, 1)]
    boxed = detect(state_of([Sphere(2 * r)], [0, 0], positions, [IDENTITY, IDENTITY], "box"), ALERT)
    assert sorted((int(i), int(j)) for i, j in zip(boxed.body_i, boxed.body_j)) == [(0, -2), (1, -3)]


# ---------------------------------------------------------------------------------------------
# the cylinder


@pytest.mark.parametrize("angle", [0.0, 0.7, 2.5, -1.9])
@pytest.mark.parametrize("gap", [0.012, 0.0, -0.003])
def test_sphere_in_the_cylinder(angle, gap):
    r = 0.5
    u = np.array([math.cos(angle), math.sin(angle), 0.0])
    centre = np.array([*AXIS, 0.9]) + (R_CYL - r - gap) * u
    ms = manifolds(detect(state_of([Sphere(2 * r)], [0], [centre], [IDENTITY], "cylinder"), ALERT))
    assert [m["j"] for m in ms] == [-6]
    m = ms[0]
    assert m["ctype"] == SIMPLE
    np.testing.assert_allclose(m["normal"], -u, atol=1e-12)
    np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
    np.testing.assert_allclose(m["points"][0], centre + (r + 0.5 * gap) * u, atol=1e-12)
    # the point lies midway between the sphere and the cylinder
    assert abs(np.linalg.norm(m["points"][0][:2] - AXIS) - (R_CYL - 0.5 * gap)) < 1e-12


def _cylinder_case(shape, q, angle, gap):
    """The grain turned by ``q``, moved from the axis along the direction ``angle`` until its
    farthest vertex from the axis has the gap ``gap``; returns its centre and its world vertices.

    A vertex at ``(a, b)`` along and across ``u`` (relative to the centre) is at ``R - gap`` from
    the axis when the centre is at ``sqrt((R - gap)^2 - b^2) - a`` along ``u``: the least of these
    over the vertices."""
    u = np.array([math.cos(angle), math.sin(angle), 0.0])
    across = np.array([-u[1], u[0], 0.0])
    v = world_vertices(shape, q, np.zeros(3))
    t = float(np.min(np.sqrt((R_CYL - gap) ** 2 - (v @ across) ** 2) - v @ u))
    centre = np.array([*AXIS, 1.2]) + t * u
    return centre, v + centre


def _edge_out(shape) -> np.ndarray:
    """A body-frame turn that puts a horizontal edge of ``shape`` outermost along +x (its two
    vertices at the largest x, equal y magnitude): the edge's midpoint direction onto +x, the edge
    along y."""
    a, b = shape.edges[0]
    va, vb = shape.vertices[a], shape.vertices[b]
    mid, along = 0.5 * (va + vb), vb - va
    along = along / np.linalg.norm(along)
    mid = mid - (mid @ along) * along
    frame = np.array([mid / np.linalg.norm(mid), along, np.cross(mid / np.linalg.norm(mid), along)])
    # rows of `frame` are the body directions that go to x, y, z: the rotation body -> world is `frame`
    x, y, z, w = Rotation.from_matrix(frame).as_quat()
    return np.array([w, x, y, z])


def _vertex_out(shape) -> np.ndarray:
    """A turn that puts vertex 0 of ``shape`` outermost along +x."""
    v = shape.vertices[0] / np.linalg.norm(shape.vertices[0])
    c = np.cross(v, [1.0, 0.0, 0.0])
    if np.linalg.norm(c) < 1e-12:
        return IDENTITY if v[0] > 0 else quat_from_axis_angle([0.0, 0.0, 1.0], math.pi)
    return quat_from_axis_angle(c, math.atan2(np.linalg.norm(c), v[0]))


@pytest.mark.parametrize("name", ["cube", "octahedron"])
@pytest.mark.parametrize("touch, count", [("vertex", 1), ("edge", 2)])
@pytest.mark.parametrize("angle", [0.0, 1.1, -2.6])
@pytest.mark.parametrize("gap", [0.006, -0.002])
def test_polyhedron_touching_the_cylinder(name, touch, count, angle, gap):
    sh = platonic(name, 1.0)
    body = _vertex_out(sh) if touch == "vertex" else _edge_out(sh)
    q = quat_multiply(quat_from_axis_angle([0.0, 0.0, 1.0], angle), body)
    centre, v = _cylinder_case(sh, q, angle, gap)
    rho = np.linalg.norm(v[:, :2] - AXIS, axis=1)
    expected = np.flatnonzero(R_CYL - rho < ALERT)
    ms = [m for m in manifolds(detect(state_of([sh], [0], [centre], [q], "cylinder"), ALERT)) if m["j"] == -6]
    assert len(expected) == count and len(ms) == count
    for m in ms:
        assert m["ctype"] == SIMPLE and len(m["gaps"]) == 1
        # the manifold's vertex: the one its point lies beside
        k = expected[np.argmin(np.linalg.norm(v[expected] - m["points"][0], axis=1))]
        u = np.array([*((v[k, :2] - AXIS) / rho[k]), 0.0])
        np.testing.assert_allclose(m["gaps"], [R_CYL - rho[k]], atol=1e-12)
        np.testing.assert_allclose(m["gaps"], [gap], atol=1e-12)
        np.testing.assert_allclose(m["normal"], -u, atol=1e-12)
        np.testing.assert_allclose(m["points"][0], v[k] + 0.5 * gap * u, atol=1e-12)


# ---------------------------------------------------------------------------------------------
# dynamics: grains held by the container

H = 5e-3


def run_steps(state, params, steps):
    warm = None
    for _ in range(steps):
        warm, _ = step(state, params, warm)
    return warm


def forces_by_wall(contacts, h=H) -> dict:
    """``{wall id: total force of that wall on the grains}``."""
    on = contacts.body_j[contacts.point_manifold]
    return {int(w): contacts.impulse[on == w].sum(axis=0) / h for w in np.unique(on[on < 0])}


def test_a_ball_at_rest_in_the_cylinder_on_the_floor_stays_put():
    r = 0.5
    u = np.array([math.cos(0.3), math.sin(0.3), 0.0])
    start = np.array([*AXIS, r]) + (R_CYL - r) * u  # on the floor, touching the cylinder
    state = state_of([Sphere(2 * r)], [0], [start], [IDENTITY], "cylinder")
    warm = run_steps(state, StepParameters(time_step=H), 200)
    assert np.abs(state.position[0] - start).max() < 1e-9
    assert np.abs(state.velocity).max() < 1e-9
    walls = forces_by_wall(warm)
    np.testing.assert_allclose(walls[-1], [0.0, 0.0, state.mass[0]], atol=1e-9)
    np.testing.assert_allclose(walls.get(-6, np.zeros(3)), 0.0, atol=1e-9)
    assert wall_force(warm, H) == pytest.approx(state.mass[0], rel=1e-9)


@pytest.mark.parametrize("mu, sliding", [(0.6, 0.0), (0.2, 0.3)])
def test_a_block_against_a_box_wall_slides_at_the_walls_friction(mu, sliding):
    """A cube pressed against the wall x = 0 by gravity (-1, 0, -1/2), far above the floor: the
    wall's Coulomb friction (the grains' is 0) holds it when mu >= 1/2, else it slides down at
    (1/2 - mu) g."""
    cube = platonic("cube", 1.0)
    half = float(cube.vertices[:, 0].max())
    state = state_of([cube], [0], [[half, 2.0, 3.0]], [IDENTITY], "box")
    params = StepParameters(time_step=H, friction=0.0, wall_friction=mu, gravity=(-1.0, 0.0, -0.5))
    run_steps(state, params, 100)
    assert state.velocity[0, 2] == pytest.approx(-sliding * 100 * H, abs=1e-9)
    assert abs(state.position[0, 0] - half) < 1e-9


def _poured(container, n=80, seed=3):
    """``n`` pinacoids on the centres of a deposit inside ``container``, heights stretched so they
    fall."""
    rng = np.random.default_rng(seed)
    x = deposit(np.full(n, 0.5), L, rng, lateral="walls" if container == "box" else "cylinder")
    x[:, 2] = 0.5 + 1.3 * (x[:, 2] - 0.5)
    sh = Pinacoid.from_size(1.0, 1.0, 1.0)
    return state_of([sh], np.zeros(n, int), x, random_quaternions(n, rng), container)


def _outside(state) -> float:
    """How far the farthest vertex of any grain lies beyond the container's walls, d."""
    v = np.concatenate([world_vertices(state.shapes.shapes[0], q, x)
                        for q, x in zip(state.quaternion, state.position)])
    if state.box.container == "cylinder":
        return float((np.linalg.norm(v[:, :2] - AXIS, axis=1) - R_CYL).max())
    return float(max(-v[:, :2].min(), (v[:, :2] - L).max()))


@pytest.mark.parametrize("container", ["box", "cylinder"])
def test_a_pile_poured_into_a_container_never_gains_energy_and_stays_inside(container):
    state = _poured(container)
    assert _outside(state) < 0.0
    params = StepParameters(time_step=H, theta=1.0)
    e0 = total_energy(state)
    warm = None
    for _ in range(300):
        before = total_energy(state)
        warm, info = step(state, params, warm)
        assert total_energy(state) - before - info.correction_energy < 1e-12 * e0
    assert total_energy(state) < e0 - 0.5  # the pour dissipated
    assert _outside(state) < 2e-3  # within the overlap the solver allows
    walls = set(np.unique(warm.body_j[warm.body_j < 0]).tolist())
    assert walls <= ({-1, -2, -3, -4, -5} if container == "box" else {-1, -6}) and len(walls) > 1


# ---------------------------------------------------------------------------------------------
# outputs


@pytest.mark.parametrize("container", ["box", "cylinder"])
def test_gsd_and_vtk_carry_the_container(tmp_path, container):
    state = _poured(container, n=60)
    warm = run_steps(state, StepParameters(time_step=H), 300)
    sides = set(warm.body_j[warm.body_j < -1].tolist())
    assert sides and sides <= ({-2, -3, -4, -5} if container == "box" else {-6})
    packing = Packing(state, warm, H, ["pinacoids"], {"seed": 3})
    back = read_packing(write_packing(tmp_path / "final.gsd", packing))
    assert back.box == state.box
    np.testing.assert_array_equal(back.contacts.body_j, warm.body_j)
    paths = write_vtk(back, tmp_path / "vtk")
    assert [p.name for p in paths] == ["grains.vtu", "centres.vtu", "contacts.vtu", "container.vtu"]
    mesh = meshio.read(tmp_path / "vtk" / "container.vtu")
    walls = np.concatenate(mesh.cell_data["wall"])
    assert set(walls.tolist()) == ({-1, -2, -3, -4, -5} if container == "box" else {-1, -6})
    xy = mesh.points[:-1, :2]  # the floor's centre last
    if container == "cylinder":
        np.testing.assert_allclose(np.linalg.norm(xy - AXIS, axis=1), R_CYL, atol=1e-12)
    else:
        assert set(np.round(xy.ravel(), 12).tolist()) == {0.0, L}
    # every contact line with a side wall goes from the centre along the normal to the wall's
    # tangent plane at the contact
    lines = meshio.read(tmp_path / "vtk" / "contacts.vtu")
    ends = lines.points.reshape(-1, 2, 3)
    side = warm.body_j < -1
    first = warm.point_start[:-1][side]
    n = warm.normal[side]
    on_wall = warm.point[first] - 0.5 * warm.gap[first][:, None] * n
    np.testing.assert_allclose(np.einsum("ij,ij->i", ends[side, 1] - on_wall, n), 0.0, atol=1e-12)
    np.testing.assert_allclose(np.cross(ends[side, 0] - ends[side, 1], n), 0.0, atol=1e-12)
    if container == "box":
        for wall in sides:
            np.testing.assert_allclose(wall_height(wall, ends[warm.body_j == wall, 1]), 0.0, atol=1e-12)

@pytest.mark.parametrize("container", ["box", "cylinder"])
def test_the_container_for_ovito_lies_where_the_gsd_file_puts_the_grains_and_faces_them(tmp_path, container):
    state = _poured(container, n=30)
    packing = Packing(state, ContactSet.empty(), H, ["pinacoids"], {})
    final = write_packing(tmp_path / "final.gsd", packing)
    import gsd.hoomd

    with gsd.hoomd.open(final) as frames:
        frame = frames[0]
    origin = frame.log["granpack/origin"]
    np.testing.assert_array_equal(origin, frame_origin(packing))
    mesh = meshio.read(write_container_stl(tmp_path / "container.stl", packing))
    triangles = mesh.cells_dict["triangle"]
    k = 4 if container == "box" else 96
    assert len(triangles) == 3 * k  # the floor's fan, two per wall facet
    lz = frame.configuration.box[2]
    z = mesh.points[:, 2]  # float32 in STL
    np.testing.assert_allclose([z.min(), z.max()], [-0.5 * lz, 0.5 * lz], atol=1e-5)
    xy = mesh.points[:, :2] + origin[:2]
    side = np.abs(z + 0.5 * lz) > 1e-4
    if container == "cylinder":  # every corner off the floor's centre on the cylinder
        rim = np.linalg.norm(xy - AXIS, axis=1) > 1e-4
        np.testing.assert_allclose(np.linalg.norm(xy[rim] - AXIS, axis=1), R_CYL, atol=1e-5)
    else:
        assert set(np.round(xy[side].ravel(), 5).tolist()) == {0.0, L}
    # every facet faces into the container: the floor up, the walls towards the axis
    p = mesh.points[triangles]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    centroid = p.mean(axis=1) + origin
    np.testing.assert_array_less(0.0, normal[:k, 2])
    inward = np.column_stack([AXIS - centroid[k:, :2], np.zeros(2 * k)])
    np.testing.assert_array_less(0.0, np.einsum("ij,ij->i", normal[k:], inward))
    surface = container_surface(packing)
    assert len(surface.triangles) == len(surface.quads) == len(surface.wall) == k


def test_a_periodic_cell_has_no_container_surface():
    state = state_of([Sphere(1.0)], [0], [[1.0, 1.0, 0.5]], [IDENTITY], "periodic")
    with pytest.raises(ValueError, match="periodic"):
        container_surface(Packing(state, ContactSet.empty(), H, ["spheres"], {}))


def test_grain_surfaces_in_a_container_are_the_grains_where_they_are():
    state = _poured("box", n=10)
    state.position[0, 0] = -1e-4  # pressed slightly into the wall x = 0: not wrapped to x = L
    surfaces = grain_surfaces(Packing(state, ContactSet.empty(), H, ["pinacoids"], {}), images=True)
    assert [s.grain for s in surfaces] == list(range(10))
    assert all(s.shift == (0, 0) for s in surfaces)
    np.testing.assert_allclose(surfaces[0].mesh.vertices.mean(axis=0)[0], -1e-4, atol=0.2)


def test_a_periodic_packing_reads_back_periodic_and_writes_no_container(tmp_path):
    state = state_of([Sphere(1.0)], [0], [[1.0, 1.0, 0.5]], [IDENTITY], "periodic")
    packing = Packing(state, ContactSet.empty(), H, ["spheres"], {})
    back = read_packing(write_packing(tmp_path / "final.gsd", packing))
    assert back.box.container == "periodic"
    assert [p.name for p in write_vtk(back, tmp_path / "vtk")] == ["grains.vtu", "centres.vtu", "contacts.vtu"]


# ---------------------------------------------------------------------------------------------
# a run


@pytest.mark.parametrize("container", ["box", "cylinder"])
def test_a_run_pours_and_settles_inside_its_container(tmp_path, container):
    config = load_config_dict({
        "seed": 2, "n_particles": 40, "lateral_size": L,
        "populations": [{"shape": "pinacoid", "size": 1.0, "volume_fraction": 1.0}],
        "container": {"shape": container, "wall_friction": 0.3},
        "equilibrium": {"max_time": 1.5},
    })
    summary = run_packing(config, tmp_path, progress=False)
    assert read_json(tmp_path / "summary.json")["container"] == Box.square(L, container).to_dict()
    packing = read_packing(tmp_path / "final.gsd")
    assert packing.box == Box.square(L, container) and summary["steps"] == 300
    assert _outside(packing.state) < 2e-3
    sides = packing.contacts.body_j[packing.contacts.body_j < -1]
    assert len(sides) and set(sides.tolist()) <= ({-2, -3, -4, -5} if container == "box" else {-6})
    assert meshio.read(tmp_path / "container.stl").points.shape[0] > 0


def test_each_vertex_on_the_cylinder_is_warm_started_from_its_own_manifold():
    """A cube on the floor pressed by a tilted gravity against the cylinder by a vertical edge (two
    cylinder manifolds, one per vertex of the edge's ends, each loaded): at rest every point,
    those of both cylinder manifolds included, takes its previous impulse."""
    cube = platonic("cube", 1.0)
    half = float(cube.vertices[:, 0].max())
    q = quat_from_axis_angle([0.0, 0.0, 1.0], math.pi / 4)  # a vertical edge towards +x
    x = np.array([AXIS[0] + R_CYL - half * math.sqrt(2.0), AXIS[1], half])
    state = state_of([cube], [0], [x], [q], "cylinder")
    params = StepParameters(time_step=H, gravity=(0.3, 0.0, -1.0))
    warm = None
    for _ in range(60):
        warm, info = step(state, params, warm)
    on_cylinder = warm.body_j == -6
    assert on_cylinder.sum() == 2
    assert info.n_warm == warm.n_points
    load = np.array([warm.impulse[warm.point_start[m]] @ warm.normal[m] for m in np.flatnonzero(on_cylinder)]) / H
    np.testing.assert_allclose(load.sum(), 0.3 * state.mass[0], rtol=1e-6)
