"""Synthetic packings with known answers, shared by the analysis and GSD tests."""

from __future__ import annotations

import itertools
import math

import numpy as np

from granpack.box import Box
from granpack.contact.contacts import ContactSet
from granpack.packing import Packing
from granpack.rotations import random_quaternions
from granpack.shapes import Pinacoid, ShapeTable, Sphere, platonic
from granpack.state import ParticleState

H = 5e-3  # time step used by the builders


def contact_set(manifolds: list[dict]) -> ContactSet:
    """ContactSet from dicts with keys i, j, shift, normal, ctype, points (k, 3), gaps (k,), forces (k, 3)."""
    if not manifolds:
        return ContactSet.empty()
    start = np.concatenate([[0], np.cumsum([len(m["points"]) for m in manifolds])])
    return ContactSet(
        body_i=np.array([m["i"] for m in manifolds], dtype=np.int64),
        body_j=np.array([m["j"] for m in manifolds], dtype=np.int64),
        shift=np.array([m.get("shift", (0.0, 0.0, 0.0)) for m in manifolds], dtype=np.float64),
        normal=np.array([m["normal"] for m in manifolds], dtype=np.float64),
        ctype=np.array([m.get("ctype", 1) for m in manifolds], dtype=np.int64),
        point_start=start.astype(np.int64),
        point=np.concatenate([np.asarray(m["points"], dtype=np.float64).reshape(-1, 3) for m in manifolds]),
        gap=np.concatenate([np.asarray(m.get("gaps", np.zeros(len(m["points"]))), dtype=np.float64) for m in manifolds]),
        impulse=H * np.concatenate([np.asarray(m["forces"], dtype=np.float64).reshape(-1, 3) for m in manifolds]),
    )


def identity_quaternions(n: int) -> np.ndarray:
    q = np.zeros((n, 4))
    q[:, 0] = 1.0
    return q


def fcc_spheres(cells_xy: int = 4, cells_z: int = 6, diameter: float = 1.0, forces: bool = True):
    """FCC crystal of touching spheres, (001) planes horizontal, bottom layer on the wall.

    Returns ``(packing, a)`` with ``a = sqrt(2) d`` the cubic lattice constant. Every touching pair
    (12 per sphere, with images) is a manifold carrying a unit normal force when ``forces``; the
    bottom layer touches the wall.
    """
    a = math.sqrt(2.0) * diameter
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    cells = np.array(list(itertools.product(range(cells_xy), range(cells_xy), range(cells_z))), dtype=float)
    pos = ((cells[:, None, :] + basis[None]).reshape(-1, 3) + 0.25) * a
    pos[:, 2] += 0.5 * diameter - 0.25 * a
    box = Box.square(cells_xy * a)
    n = len(pos)
    state = ParticleState(
        box=box,
        shapes=ShapeTable.from_shapes([Sphere(diameter)]),
        kind=np.zeros(n, np.int64),
        population=np.zeros(n, np.int64),
        position=pos,
        quaternion=identity_quaternions(n),
    )
    manifolds = []
    for i in range(n):
        delta_all = box.minimum_image(pos[i] - pos[i + 1:])
        touching = np.flatnonzero(np.abs(np.linalg.norm(delta_all, axis=1) - diameter) < 1e-9)
        for j, delta in zip(touching + i + 1, delta_all[touching]):
            shift = pos[i] - delta - pos[j]
            normal = delta / diameter
            manifolds.append(
                dict(i=i, j=int(j), shift=shift, normal=normal, points=[pos[i] - 0.5 * diameter * normal],
                     forces=[normal * (1.0 if forces else 0.0)])
            )
        if pos[i, 2] < diameter:
            manifolds.append(dict(i=i, j=-1, normal=(0, 0, 1), points=[pos[i] - (0, 0, 0.5 * diameter)], forces=[(0, 0, 1.0)]))
    return Packing(state, contact_set(manifolds), H, ["spheres"], {"seed": 7}), a


def cubic_cubes(cells_xy: int = 3, layers: int = 8):
    """Simple cubic stack of axis-aligned cubes (circumscribed diameter 1) face to face.

    Returns ``(packing, edge)``. Face contacts carry four corner points with the weight above
    (vertical) or a unit force (lateral); the bottom layer rests on the wall.
    """
    cube = platonic("cube", 1.0)
    e = 1.0 / math.sqrt(3.0)
    cells = np.array(list(itertools.product(range(cells_xy), range(cells_xy), range(layers))), dtype=float)
    pos = (cells + 0.5) * e
    n = len(pos)
    box = Box.square(cells_xy * e)
    state = ParticleState(
        box=box,
        shapes=ShapeTable.from_shapes([cube]),
        kind=np.zeros(n, np.int64),
        population=np.zeros(n, np.int64),
        position=pos,
        quaternion=identity_quaternions(n),
    )
    index = {tuple(c.astype(int)): k for k, c in enumerate(cells)}
    corners = np.array([[s, t] for s in (-0.5, 0.5) for t in (-0.5, 0.5)]) * e
    weight = cube.volume
    manifolds = []
    for (ix, iy, iz), lower in index.items():
        for axis in range(3):
            other = [ix, iy, iz]
            other[axis] += 1
            shift = np.zeros(3)
            if axis == 2 and other[2] == layers:
                continue
            if axis < 2 and other[axis] == cells_xy:
                other[axis] = 0
                shift[axis] = -cells_xy * e
            upper = index[tuple(other)]
            normal = np.eye(3)[axis]  # from j = lower to i = upper
            rest = [k for k in range(3) if k != axis]
            pts = np.repeat((pos[upper] - 0.5 * e * normal)[None], 4, axis=0)
            pts[:, rest[0]] += corners[:, 0]
            pts[:, rest[1]] += corners[:, 1]
            load = weight * (layers - iz - 1) if axis == 2 else 1.0
            manifolds.append(dict(i=upper, j=lower, shift=shift, normal=normal, ctype=3, points=pts,
                                  forces=np.repeat((normal * load / 4)[None], 4, axis=0)))
        i = lower
        if iz == 0:
            pts = np.repeat((pos[i] - (0, 0, 0.5 * e))[None], 4, axis=0)
            pts[:, 0] += corners[:, 0]
            pts[:, 1] += corners[:, 1]
            manifolds.append(dict(i=i, j=-1, normal=(0, 0, 1), ctype=3, points=pts,
                                  forces=np.repeat(np.array([[0, 0, weight * layers / 4]]), 4, axis=0)))
    return Packing(state, contact_set(manifolds), H, ["cubes"], {"seed": 3}), e


def sphere_column(side: int = 3, layers: int = 6, diameter: float = 1.0, overlap: float = 0.0):
    """Simple cubic stack of spheres; vertical contacts carry the weight above, lateral ones zero force.

    The box side is ``side * diameter`` so lateral neighbours touch (also across the boundary).
    With ``overlap`` (in units of ``diameter``) every vertical contact and the wall contact
    interpenetrate by ``overlap * diameter`` (gap ``-overlap * diameter``): the centres are at
    ``z = (1/2 - overlap + k (1 - overlap)) diameter``.
    """
    cells = np.array(list(itertools.product(range(side), range(side), range(layers))), dtype=float)
    pos = (cells + 0.5) * diameter
    pos[:, 2] = (0.5 - overlap + cells[:, 2] * (1.0 - overlap)) * diameter
    gap = -overlap * diameter
    n = len(pos)
    sphere = Sphere(diameter)
    state = ParticleState(
        box=Box.square(side * diameter),
        shapes=ShapeTable.from_shapes([sphere]),
        kind=np.zeros(n, np.int64),
        population=np.zeros(n, np.int64),
        position=pos,
        quaternion=identity_quaternions(n),
    )
    index = {tuple(c.astype(int)): k for k, c in enumerate(cells)}
    m = sphere.volume
    manifolds = []
    for (ix, iy, iz), i in index.items():
        point = pos[i] - (0, 0, (1.0 - overlap) * diameter / 2) if iz else pos[i] - (0, 0, (0.5 - overlap) * diameter)
        if iz == 0:
            manifolds.append(dict(i=i, j=-1, normal=(0, 0, 1), points=[point], gaps=[gap], forces=[(0, 0, m * layers)]))
        else:
            j = index[(ix, iy, iz - 1)]
            manifolds.append(dict(i=i, j=j, normal=(0, 0, 1), points=[point], gaps=[gap], forces=[(0, 0, m * (layers - iz))]))
        for axis in range(2):
            other = [ix, iy, iz]
            other[axis] = (other[axis] + 1) % side
            shift = np.zeros(3)
            if other[axis] == 0:
                shift[axis] = side * diameter
            j = index[tuple(other)]
            normal = -np.eye(3)[axis]
            manifolds.append(dict(i=i, j=j, shift=shift, normal=normal, points=[pos[i] + 0.5 * diameter * np.eye(3)[axis]],
                                  forces=[(0.0, 0.0, 0.0)]))
    return Packing(state, contact_set(manifolds), H, ["spheres"], {"seed": 1})


def single(shape, position=(0.0, 0.0, 0.0), quaternion=(1.0, 0.0, 0.0, 0.0), lateral=4.0) -> Packing:
    """One grain, no contacts."""
    state = ParticleState(
        box=Box.square(lateral),
        shapes=ShapeTable.from_shapes([shape]),
        kind=np.zeros(1, np.int64),
        population=np.zeros(1, np.int64),
        position=np.array([position], dtype=float),
        quaternion=np.array([quaternion], dtype=float),
    )
    return Packing(state, ContactSet.empty(), H, ["grain"], {})


def random_pinacoids(n: int, rng, lateral: float = 8.0, height: float = 12.0, small_fraction: float = 0.3,
                     contacts_per_particle: float = 3.0) -> Packing:
    """Random positions in a slab, random orientations, two populations, random contacts with forces."""
    big = Pinacoid.family("isometric", 1.0)
    small = Pinacoid.family("isometric", 1.0 / 3.0)
    kind = (rng.random(n) < small_fraction).astype(np.int64)
    pos = np.column_stack([rng.random(n) * lateral, rng.random(n) * lateral, 0.5 + rng.random(n) * (height - 1.0)])
    state = ParticleState(
        box=Box.square(lateral),
        shapes=ShapeTable.from_shapes([big, small]),
        kind=kind,
        population=kind.copy(),
        position=pos,
        quaternion=random_quaternions(n, rng),
    )
    m = int(contacts_per_particle * n / 2)
    i = rng.integers(0, n, m)
    j = rng.integers(0, n, m)
    keep = i != j
    i, j = i[keep], j[keep]
    m = len(i)
    npts = rng.integers(1, 5, m)
    start = np.concatenate([[0], np.cumsum(npts)]).astype(np.int64)
    p = int(start[-1])
    delta = state.box.minimum_image(pos[i] - pos[j])
    normal = delta / np.linalg.norm(delta, axis=1)[:, None]
    shift = pos[i] - delta - pos[j]
    seg = np.repeat(np.arange(m), npts)
    mid = pos[j][seg] + shift[seg] + 0.5 * delta[seg]
    contacts = ContactSet(
        body_i=i.astype(np.int64),
        body_j=j.astype(np.int64),
        shift=shift,
        normal=normal,
        ctype=np.minimum(npts, 3).astype(np.int64),
        point_start=start,
        point=mid + 0.01 * rng.standard_normal((p, 3)),
        gap=-1e-4 * rng.random(p),
        impulse=H * normal[seg] * rng.random(p)[:, None],
    )
    return Packing(state, contacts, H, ["large", "small"], {"seed": 11})


def relabelled(packing: Packing, population, names: list[str]) -> Packing:
    """The same grains and contacts with another population index per grain."""
    s = packing.state
    state = ParticleState(box=s.box, shapes=s.shapes, kind=s.kind.copy(), population=np.asarray(population, dtype=np.int64),
                          position=s.position.copy(), quaternion=s.quaternion.copy())
    return Packing(state, packing.contacts, packing.time_step, list(names), dict(packing.metadata))


def points(position, lateral: float, diameter: float = 1.0) -> Packing:
    """Spheres at arbitrary (possibly overlapping) centres, no contacts: a point set for g(r)."""
    position = np.asarray(position, dtype=float)
    n = len(position)
    state = ParticleState(
        box=Box.square(lateral),
        shapes=ShapeTable.from_shapes([Sphere(diameter)]),
        kind=np.zeros(n, np.int64),
        population=np.zeros(n, np.int64),
        position=position,
        quaternion=identity_quaternions(n),
    )
    return Packing(state, ContactSet.empty(), H, ["points"], {})


def oriented_pinacoids(quaternions, rng, lateral: float = 8.0, height: float = 8.0, family: str = "isometric") -> Packing:
    """Pinacoids with the given orientations ``(n, 4)`` at random centres, no contacts."""
    quaternions = np.asarray(quaternions, dtype=float)
    n = len(quaternions)
    pos = np.column_stack([rng.random(n) * lateral, rng.random(n) * lateral, 0.5 + rng.random(n) * (height - 1.0)])
    state = ParticleState(
        box=Box.square(lateral),
        shapes=ShapeTable.from_shapes([Pinacoid.family(family, 1.0)]),
        kind=np.zeros(n, np.int64),
        population=np.zeros(n, np.int64),
        position=pos,
        quaternion=quaternions,
    )
    return Packing(state, ContactSet.empty(), H, [family], {})


def cube_on_cube(axis=(1.0, 0.0, 0.0), tilt: float = 0.0, gap: float = 0.0, alert: float = 0.02,
                 loaded_within: float = 1e-9) -> Packing:
    """Two cubes (circumscribed diameter 1), the upper one face down on the lower one's top face.

    The upper cube is turned by ``tilt`` (rad) about the horizontal ``axis`` through its centre,
    then lowered until its lowest point is ``gap`` above the top face: about an edge direction
    (e.g. x) it rests on an edge, about a face-diagonal normal (e.g. (1, -1, 0)) on a vertex. Both
    grains are far above the wall. The manifold is the real one of :func:`granpack.contact.detect`
    (every point within ``alert``); its points with gap at most ``loaded_within`` above the
    smallest one carry the unit normal force evenly, the others none.
    """
    from granpack.contact import detect
    from granpack.rotations import quat_from_axis_angle, quat_to_matrix

    cube = platonic("cube", 1.0)
    e = 1.0 / math.sqrt(3.0)
    q = quat_from_axis_angle(np.asarray(axis, float) / np.linalg.norm(axis), tilt)
    lowest = (cube.vertices @ quat_to_matrix(q).T)[:, 2].min()
    lower = np.array([1.5, 1.5, 3.0])
    upper = lower + (0.0, 0.0, 0.5 * e + gap - lowest)
    state = ParticleState(
        box=Box.square(3.0),
        shapes=ShapeTable.from_shapes([cube]),
        kind=np.zeros(2, np.int64),
        population=np.zeros(2, np.int64),
        position=np.array([lower, upper]),
        quaternion=np.array([[1.0, 0.0, 0.0, 0.0], q]),
    )
    contacts = detect(state, alert)
    loaded = contacts.gap <= contacts.gap.min() + loaded_within
    normal = contacts.normal[contacts.point_manifold]
    contacts.impulse = H * normal * (loaded / loaded.sum())[:, None]
    return Packing(state, contacts, H, ["cubes"], {})


def cylinder_column(wall_loads, pushes, lift: float = 0.0, container: str = "cylinder", metadata=None) -> Packing:
    """Layers of two spheres of size 1 side by side in a cylinder of diameter 2 (or a 2 x 1 box:
    ``container = "box"``), at rest: layer k (from the floor) centred at ``z = k + 1/2 + lift``, each
    sphere pressed against its wall by the horizontal force ``pushes[k]`` (the pair between the two
    spheres pushes them apart as much) and held up by the wall's vertical force ``wall_loads[k]``;
    each sphere stands on the one below (on the floor, layer 0) with the weight above it less the
    walls' share. Every grain's net force is zero."""
    n = len(wall_loads)
    pos = np.array([[x, 1.0 if container == "cylinder" else 0.5, k + 0.5 + lift] for k in range(n) for x in (0.5, 1.5)])
    box = Box(2.0, 2.0, "cylinder") if container == "cylinder" else Box(2.0, 1.0, "box")
    state = ParticleState(box=box, shapes=ShapeTable.from_shapes([Sphere(1.0)]), kind=np.zeros(2 * n, np.int64),
                          population=np.zeros(2 * n, np.int64), position=pos, quaternion=identity_quaternions(2 * n))
    weight = state.mass[0]
    load = np.cumsum((weight - np.asarray(wall_loads, float))[::-1])[::-1]  # carried by each layer's spheres
    walls = {"cylinder": (-6, -6), "box": (-2, -3)}[container]
    manifolds = []
    for k in range(n):
        left, right = 2 * k, 2 * k + 1
        manifolds.append(dict(i=right, j=left, normal=(1, 0, 0), points=[pos[left] + (0.5, 0, 0)], forces=[(pushes[k], 0, 0)]))
        for grain, side, wall in ((left, 1.0, walls[0]), (right, -1.0, walls[1])):
            manifolds.append(dict(i=grain, j=wall, normal=(side, 0, 0), points=[pos[grain] - (0.5 * side, 0, 0)],
                                  forces=[(side * pushes[k], 0, wall_loads[k])]))
            below = (grain - 2, (0, 0, 1)) if k else (-1, (0, 0, 1))
            manifolds.append(dict(i=grain, j=below[0], normal=below[1], points=[pos[grain] - (0, 0, 0.5)],
                                  forces=[(0, 0, load[k])]))
    return Packing(state, contact_set(manifolds), H, ["spheres"], dict(metadata or {"seed": 1}))
