"""The gmsh side of :mod:`granpack.mesh`: geometry (OpenCASCADE), mesh, groups, arrays out.

Every call into gmsh is here. The grains are built as OpenCASCADE solids (a polyhedron from its
vertices, edges and planar faces; a sphere as a sphere), the ITZ shells as larger copies, and one
``fragment`` with the region's box makes them conforming: the pieces inside the box are kept,
each labelled by the bodies it came from (grain -> ``aggregate``, shell only -> ``itz``, box only ->
``matrix``). gmsh is GPL and optional (``pip install "granpack[mesh]"``).
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from granpack.errors import InputError
from granpack.mesh.region import MeshPlan
from granpack.shapes import Sphere

__all__ = ["PHASES", "FACES", "VolumeMesh", "require_gmsh", "build_mesh"]

#: physical group tag of each phase (cell data ``phase`` in the meshio formats)
PHASES = {"aggregate": 1, "matrix": 2, "itz": 3}
#: the box faces, as physical surface groups (``.msh``) and node sets (``.inp``), and their axis/side
FACES = {"xmin": (0, 0), "xmax": (0, 1), "ymin": (1, 0), "ymax": (1, 1), "zmin": (2, 0), "zmax": (2, 1)}
#: first physical tag of the per-grain groups (``grain_<id>`` has tag GRAIN_TAG + id)
GRAIN_TAG = 1000
_TET = 4  # gmsh element type: 4-node tetrahedron
_TRI = 2  # 3-node triangle


def require_gmsh():
    """The gmsh module, or an :class:`InputError` naming the extra that installs it."""
    try:
        import gmsh
    except ImportError:
        raise InputError('granpack mesh needs gmsh (GPL, an optional extra): pip install "granpack[mesh]"') from None
    except OSError as exc:  # the wheel's library needs the system's OpenGL and X11 libraries
        raise InputError(f"granpack mesh: gmsh is installed but does not load ({' '.join(str(exc).split())}); it needs "
                         f"the system's libGLU, libGL and libX11 (Debian, Ubuntu: apt install libglu1-mesa libxcursor1 "
                         f"libxft2 libxinerama1)") from None
    return gmsh


@dataclass
class VolumeMesh:
    """A conforming tetrahedral mesh as arrays (lengths in d).

    Attributes:
        points: ``(P, 3)`` node coordinates.
        tetra: ``(T, 4)`` node indices (0-based) of the linear tetrahedra.
        phase: ``(T,)`` :data:`PHASES` code of each tetrahedron.
        grain: ``(T,)`` grain index of each aggregate tetrahedron (-1 elsewhere).
        faces: ``{name: (F, 3)}`` triangles on each box face (:data:`FACES`).
        sicn: ``(T,)`` gmsh's signed inverse condition number (1 regular, <= 0 inverted).
        gamma: ``(T,)`` gmsh's gamma (inscribed over circumscribed radius, normalised: 1 regular).
        periodic: ``(Q, 2)`` node pairs ``(slave, master)`` on opposite faces (empty unless periodic).
        timings: seconds spent in ``geometry``, ``fragment``, ``mesh``.
    """

    points: np.ndarray
    tetra: np.ndarray
    phase: np.ndarray
    grain: np.ndarray
    faces: dict[str, np.ndarray]
    sicn: np.ndarray
    gamma: np.ndarray
    periodic: np.ndarray
    timings: dict[str, float]


@contextmanager
def _session(gmsh, threads: int):
    gmsh.initialize(interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.Verbosity", 1)
        if threads:
            gmsh.option.setNumber("General.NumThreads", threads)
        gmsh.model.add("granpack")
        yield
    finally:
        gmsh.finalize()


@contextmanager
def _failure(what: str):
    """gmsh's own failure (an ``Exception`` with its last error) as one line that says what to change."""
    try:
        yield
    except Exception as exc:  # gmsh raises plain Exception
        reason = " ".join(str(exc).split()) or "no reason given"
        raise InputError(f"gmsh {what} ({reason}); try a larger --gap, a smaller --size or a --box whose "
                         f"planes do not graze grains") from None


def _add_polyhedron(occ, vertices: np.ndarray, faces: list[np.ndarray], edges: np.ndarray) -> int:
    """An OpenCASCADE solid bounded by the planar polygons ``faces`` over ``vertices`` (world, d)."""
    points = [occ.addPoint(*v) for v in vertices]
    line = {}
    for a, b in edges:
        line[(int(a), int(b))] = line[(int(b), int(a))] = occ.addLine(points[a], points[b])
    surfaces = []
    for face in faces:
        loop = occ.addCurveLoop([line[(int(face[k]), int(face[(k + 1) % len(face)]))] for k in range(len(face))])
        surfaces.append(occ.addPlaneSurface([loop]))
    return occ.addVolume([occ.addSurfaceLoop(surfaces)])


def _add_body(occ, shape, rotation: np.ndarray, position: np.ndarray, factor: float) -> int:
    """The body of ``shape`` scaled by ``factor``, turned by ``rotation`` and placed at ``position``."""
    if isinstance(shape, Sphere):
        return occ.addSphere(*position, shape.radius * factor)
    world = position + (factor * shape.vertices) @ rotation.T
    return _add_polyhedron(occ, world, shape.faces, shape.edges)


def _face_entities(gmsh, box, tol: float) -> dict[str, list[int]]:
    """Surface entities lying on each box face."""
    lo, hi = np.array(box[:3]), np.array(box[3:])
    out = {}
    for name, (axis, side) in FACES.items():
        a, b = lo - tol, hi + tol
        plane = (lo if side == 0 else hi)[axis]
        a[axis], b[axis] = plane - tol, plane + tol
        out[name] = [tag for _, tag in gmsh.model.getEntitiesInBoundingBox(*a, *b, dim=2)]
    return out


def _cut_curved_surfaces_by_delaunay(gmsh, faces: dict[str, list[int]]) -> None:
    """Mesh the curved surfaces that meet a box face (a sphere cut by the box) with gmsh's Delaunay
    surface algorithm: Frontal-Delaunay, used elsewhere for its regular triangles (less volume
    lost on a sphere), can leave such a cap without interior nodes, its triangles then flat in the
    cutting plane (design notes, Meshing)."""
    on_box = {abs(tag) for tags in faces.values() for _, tag in gmsh.model.getBoundary([(2, t) for t in tags], combined=False, oriented=False)}
    for _, tag in gmsh.model.getEntities(2):
        if gmsh.model.getType(2, tag) == "Plane":
            continue
        curves = {abs(c) for _, c in gmsh.model.getBoundary([(2, tag)], combined=False, oriented=False)}
        if curves & on_box:
            gmsh.model.mesh.setAlgorithm(2, tag, 5)


def _set_periodic(gmsh, faces: dict[str, list[int]], box, tol: float) -> None:
    """Make each surface on the max x / y face the periodic copy of its match on the min face."""
    lo, hi = np.array(box[:3]), np.array(box[3:])
    for axis, (low, high) in enumerate((("xmin", "xmax"), ("ymin", "ymax"))):
        shift = np.zeros(3)
        shift[axis] = hi[axis] - lo[axis]
        masters = {tag: np.array(gmsh.model.getBoundingBox(2, tag)) for tag in faces[low]}
        for tag in faces[high]:
            bb = np.array(gmsh.model.getBoundingBox(2, tag))
            bb[:3] -= shift
            bb[3:] -= shift
            match = [m for m, mb in masters.items() if np.all(np.abs(mb - bb) < tol)]
            if len(match) != 1:
                raise RuntimeError(f"no single periodic match for surface {tag} on the {high} face")
            affine = np.eye(4)
            affine[:3, 3] = shift
            gmsh.model.mesh.setPeriodic(2, [tag], [match[0]], affine.ravel().tolist())


def build_mesh(plan: MeshPlan, msh_path: Path | None = None) -> VolumeMesh:
    """Mesh ``plan`` with gmsh and return the arrays (the gmsh model is discarded).

    Sizes: at most ``plan.size`` everywhere, ``plan.options.curvature`` elements per turn on
    curved surfaces; Frontal-Delaunay surfaces, Delaunay volume, gmsh's tetrahedron optimiser
    (HXT, gmsh's parallel Delaunay, is 2x faster on spheres but 15x slower on the gap-thin slabs
    between faces that touched: docs/design-notes.md).

    Args:
        plan: the region, shrunk shapes and bodies (:func:`~granpack.mesh.region.plan_mesh`).
        msh_path: where gmsh writes the mesh in its own format (MSH 4.1, physical groups only).
    """
    gmsh = require_gmsh()
    timings = {}
    options = plan.options
    with _session(gmsh, options.threads):
        occ = gmsh.model.occ
        start = time.perf_counter()
        x0, y0, z0, x1, y1, z1 = plan.box
        box = occ.addBox(x0, y0, z0, x1 - x0, y1 - y0, z1 - z0)
        inst = plan.instances
        shapes = plan.shapes.shapes
        grains = [_add_body(occ, shapes[k], r, p, 1.0) for k, r, p in zip(inst.kind, inst.rotation, inst.position)]
        with_itz = options.itz > 0
        shells = ([_add_body(occ, shapes[k], r, p, plan.itz_scale[k]) for k, r, p in
                   zip(inst.kind, inst.rotation, inst.position)] if with_itz else [])
        timings["geometry"] = time.perf_counter() - start

        start = time.perf_counter()
        tools = [(3, t) for t in grains + shells]
        with _failure("could not cut the grains out of the box"):
            _, pieces = occ.fragment([(3, box)], tools)
        occ.synchronize()
        timings["fragment"] = time.perf_counter() - start
        inside = {tag for _, tag in pieces[0]}
        grain_of: dict[int, int] = {}
        for m, found in enumerate(pieces[1:1 + len(grains)]):
            for _, tag in found:
                if tag in inside:
                    grain_of[tag] = int(inst.grain[m])
        itz = set()
        for found in pieces[1 + len(grains):]:
            itz.update(tag for _, tag in found if tag in inside and tag not in grain_of)
        matrix = sorted(inside - set(grain_of) - itz)
        outside = [(3, tag) for _, tag in gmsh.model.getEntities(3) if tag not in inside]
        if outside:  # from the model, not the OpenCASCADE shapes (30 s against 0.1 s for 300 grains)
            gmsh.model.removeEntities(outside, recursive=True)
        aggregate = sorted(grain_of)
        gmsh.model.addPhysicalGroup(3, aggregate, PHASES["aggregate"], name="aggregate")
        gmsh.model.addPhysicalGroup(3, matrix, PHASES["matrix"], name="matrix")
        if with_itz:
            gmsh.model.addPhysicalGroup(3, sorted(itz), PHASES["itz"], name="itz")
        if options.grain_groups:
            by_grain: dict[int, list[int]] = {}
            for tag, g in grain_of.items():
                by_grain.setdefault(g, []).append(tag)
            for g in sorted(by_grain):
                gmsh.model.addPhysicalGroup(3, sorted(by_grain[g]), GRAIN_TAG + g, name=f"grain_{g}")
        tol = 1e-6 * max(x1 - x0, y1 - y0, z1 - z0)
        face_tags = _face_entities(gmsh, plan.box, tol)
        for k, (name, tags) in enumerate(face_tags.items()):
            gmsh.model.addPhysicalGroup(2, tags, 10 + k, name=name)

        gmsh.option.setNumber("Mesh.MeshSizeMax", plan.size)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.0)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", options.curvature)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        _cut_curved_surfaces_by_delaunay(gmsh, face_tags)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.option.setNumber("Mesh.Optimize", 1)
        if options.periodic:
            _set_periodic(gmsh, face_tags, plan.box, 10 * tol)
        start = time.perf_counter()
        with _failure("could not mesh the box"):
            gmsh.model.mesh.generate(3)
        timings["mesh"] = time.perf_counter() - start
        if msh_path is not None:
            gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
            gmsh.option.setNumber("Mesh.SaveAll", 0)
            gmsh.write(str(msh_path))
        return _arrays(gmsh, aggregate, grain_of, matrix, sorted(itz), face_tags, options.periodic, timings)


def _arrays(gmsh, aggregate, grain_of, matrix, itz, face_tags, periodic, timings) -> VolumeMesh:
    node_tags, coords, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(node_tags.max()) + 1, -1, dtype=np.int64)
    index[node_tags.astype(np.int64)] = np.arange(len(node_tags))
    points = coords.reshape(-1, 3)
    tetra, phase, grain, element_tags = [], [], [], []
    for tags, code in ((aggregate, PHASES["aggregate"]), (matrix, PHASES["matrix"]), (itz, PHASES["itz"])):
        for tag in tags:
            types, elements, nodes = gmsh.model.mesh.getElements(3, tag)
            for t, e, n in zip(types, elements, nodes):
                if t != _TET:
                    raise RuntimeError(f"unexpected element type {t} in volume {tag}")
                tetra.append(index[n.astype(np.int64)].reshape(-1, 4))
                phase.append(np.full(len(e), code, dtype=np.int64))
                grain.append(np.full(len(e), grain_of.get(tag, -1), dtype=np.int64))
                element_tags.append(e)
    element_tags = np.concatenate(element_tags)
    sicn = np.asarray(gmsh.model.mesh.getElementQualities(element_tags, "minSICN"))
    gamma = np.asarray(gmsh.model.mesh.getElementQualities(element_tags, "gamma"))
    faces = {}
    for name, tags in face_tags.items():
        tri = []
        for tag in tags:
            types, _, nodes = gmsh.model.mesh.getElements(2, tag)
            tri += [index[n.astype(np.int64)].reshape(-1, 3) for t, n in zip(types, nodes) if t == _TRI]
        faces[name] = np.concatenate(tri) if tri else np.zeros((0, 3), np.int64)
    pairs = []
    if periodic:
        for tag in face_tags["xmax"] + face_tags["ymax"]:
            _, slaves, masters, _ = gmsh.model.mesh.getPeriodicNodes(2, tag, includeHighOrderNodes=False)
            pairs.append(np.column_stack([index[np.asarray(slaves, np.int64)], index[np.asarray(masters, np.int64)]]))
    return VolumeMesh(points=points, tetra=np.concatenate(tetra), phase=np.concatenate(phase),
                      grain=np.concatenate(grain), faces=faces, sicn=sicn, gamma=gamma,
                      periodic=np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64), timings=timings)
