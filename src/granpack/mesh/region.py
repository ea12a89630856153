"""What a finite-element mesh of a packing holds, decided before any meshing (numpy only).

Conventions owned here (docs/method/meshing.md):

- **Region**: an axis-aligned box ``[x0, x1] x [y0, y1] x [z0, z1]`` in d. By default the full
  periodic width of the cell over the bulk region's height (:func:`~granpack.analysis.solid_fraction.bulk_range`),
  its origin ``(x0, y0)`` and its two z planes moved by less than a tenth of the smallest grain so that no
  plane grazes a grain (a grain reaching less than :data:`GRAZE` times its size past a plane
  would leave a sliver no mesher survives). The grains cut by the box's faces are cut; with the full
  width, the periodic images of the grains across the x and y faces fill the box, so the
  aggregate in it is exactly the packing's grain volume between the two z planes.
- **Shrink** (touching grains): every grain is scaled about its centroid by

  .. math:: s_k = 1 - \\frac{g}{2 h_k},

  ``g`` the gap and ``h_k`` the distance from the centroid to the nearest face (the radius for a
  sphere), so every point of its surface moves inwards by at least ``g / 2`` along the normal: two
  grains that touched are at least ``g`` apart, less their overlap in the packing. The grain keeps its
  shape and its faces, so the mesh stays exact for polyhedra, and its volume becomes ``s_k^3 V_k``.
- **ITZ**: a shell around each shrunk grain, its outer surface the shrunk grain scaled by
  ``1 + t / (s_k h_k)``: thickness ``t`` on the faces nearest the centroid, ``t h_f / h_k`` on
  face ``f`` (the ratio ``max h_f / h_k`` is reported). Shells never reach a neighbour: ``t`` must
  leave matrix between the shells of two grains that touched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from granpack.errors import InputError
from granpack.packing import Packing
from granpack.shapes import ConvexPolyhedron, ShapeTable, Sphere
from granpack.state import ParticleState

__all__ = ["MeshOptions", "MeshPlan", "Instances", "plan_mesh", "GAP_FACTOR", "SIZE_FACTOR", "CURVATURE", "GRAZE"]

#: default gap, times the smallest grain's size (circumscribed diameter)
GAP_FACTOR = 0.02
#: default element size, times the smallest grain's size
SIZE_FACTOR = 0.2
#: default elements per full turn on a sphere (its meshed volume within 0.5 % of the sphere's)
CURVATURE = 60
#: a box plane may not pass within GRAZE x (grain size) of a grain's lowest or highest point
GRAZE = 0.02


@dataclass(frozen=True)
class MeshOptions:
    """How to mesh a packing (lengths in d).

    Attributes:
        box: ``(x0, y0, z0, x1, y1, z1)`` of the region; ``None``: the bulk box (module docstring).
        gap: the clearance ``g`` the shrink opens between touching grains; ``None``:
            :data:`GAP_FACTOR` times the smallest grain size.
        size: element size; ``None``: ``size_factor`` times the smallest grain size.
        size_factor: element size relative to the smallest grain size (used when ``size`` is None).
        curvature: elements per full turn on a curved surface (a sphere's great circle): the
            linear facets lose about ``(pi / curvature)^2`` of a sphere's volume (measured:
            1.6 % at 24, 0.8 % at 36, 0.44 % at 48 on an FCC crystal, 0.62 % at 48 and 0.40 %
            at 60 on a poured pile); polyhedra are meshed exactly.
        itz: ITZ shell thickness ``t`` (0: no ITZ).
        periodic: matching nodes on opposite x and y faces (needs the full cell width).
        grain_groups: one physical group per grain besides ``aggregate``.
        threads: gmsh threads (0: gmsh's default).
    """

    box: tuple[float, float, float, float, float, float] | None = None
    gap: float | None = None
    size: float | None = None
    size_factor: float = SIZE_FACTOR
    curvature: int = CURVATURE
    itz: float = 0.0
    periodic: bool = False
    grain_groups: bool = False
    threads: int = 0


@dataclass(frozen=True)
class Instances:
    """The grain bodies placed in the region: a grain, or one of its periodic images.

    Attributes:
        grain: ``(M,)`` grain index in the packing.
        position: ``(M, 3)`` centroid of the instance (``x + shift``), d.
        rotation: ``(M, 3, 3)`` body -> world.
        kind: ``(M,)`` shape kind.
    """

    grain: np.ndarray
    position: np.ndarray
    rotation: np.ndarray
    kind: np.ndarray


@dataclass(frozen=True)
class MeshPlan:
    """Everything the mesher needs, and the exact figures its mesh is checked against.

    Attributes:
        box: ``(x0, y0, z0, x1, y1, z1)`` of the region, d.
        full_width: the box spans the cell's full x and y periods (periodic images fill it).
        shapes: the shrunk shape of each kind.
        scale: ``(K,)`` shrink factor ``s_k`` of each kind.
        itz_scale: ``(K,)`` factor from the shrunk grain to the ITZ shell's outer surface (1: none).
        instances: the bodies to mesh.
        gap: ``g``, d.
        size: element size, d.
        min_clearance: the smallest clearance between shrunk grains guaranteed (``g`` less the
            largest overlap of the packing), d.
        max_overlap: the packing's largest grain-grain overlap, d.
        itz_ratio: largest ITZ thickness over ``t`` (``max h_f / h_k``; 1 for spheres).
        grain_volume: ``(N,)`` exact volume of each shrunk grain inside the region (full width:
            by slicing; otherwise only for grains wholly inside, ``nan`` for the cut ones), d^3.
        solid_fraction: exact solid fraction of the shrunk grains in the region (``nan`` when the
            box is not full width: no exact slicing reference).
        solid_fraction_unshrunk: the same for the packing as it is.
        options: the options.
    """

    box: tuple[float, float, float, float, float, float]
    full_width: bool
    shapes: ShapeTable
    scale: np.ndarray
    itz_scale: np.ndarray
    instances: Instances
    gap: float
    size: float
    min_clearance: float
    max_overlap: float
    itz_ratio: float
    grain_volume: np.ndarray
    solid_fraction: float
    solid_fraction_unshrunk: float
    options: MeshOptions = field(repr=False)

    @property
    def volume(self) -> float:
        """Volume of the region, d^3."""
        x0, y0, z0, x1, y1, z1 = self.box
        return (x1 - x0) * (y1 - y0) * (z1 - z0)


def _inradius(shape) -> float:
    """Distance from the centroid to the nearest face (sphere: the radius), d."""
    if isinstance(shape, Sphere):
        return float(shape.radius)
    return float(np.min(shape.face_offsets))


def _outradius(shape) -> float:
    """Distance from the centroid to the farthest face plane (sphere: the radius), d."""
    if isinstance(shape, Sphere):
        return float(shape.radius)
    return float(np.max(shape.face_offsets))


def _extent(packing: Packing, axis: int, table: ShapeTable) -> tuple[np.ndarray, np.ndarray]:
    """``(lo, hi)``: each grain's lowest and highest coordinate along ``axis`` (exact for polyhedra)."""
    from granpack.rotations import quat_to_matrix

    state = packing.state
    lo = np.empty(state.n)
    hi = np.empty(state.n)
    rot = quat_to_matrix(state.quaternion)
    for k, shape in enumerate(table.shapes):
        members = np.flatnonzero(state.kind == k)
        if not len(members):
            continue
        if isinstance(shape, Sphere):
            reach = np.full(len(members), shape.radius)
            lo[members] = state.position[members, axis] - reach
            hi[members] = state.position[members, axis] + reach
        else:
            coord = np.einsum("nj,vj->nv", rot[members, axis, :], shape.vertices)
            lo[members] = state.position[members, axis] + coord.min(axis=1)
            hi[members] = state.position[members, axis] + coord.max(axis=1)
    return lo, hi


def _clear_plane(want: float, lo: np.ndarray, hi: np.ndarray, band: np.ndarray, reach: float, period: float | None) -> float:
    """The plane nearest ``want`` (within ``reach``) that no grain's extreme ``lo``/``hi`` comes
    within ``band`` of (periodic: the same for ``want + period``); ``want`` if none is found."""
    extremes = np.concatenate([lo, hi])
    widths = np.concatenate([band, band])
    if period is not None:
        extremes = np.concatenate([extremes - period, extremes, extremes + period])
        widths = np.tile(widths, 3)
    for step in np.linspace(0.0, reach, 201):
        for candidate in (want + step, want - step):
            if np.all(np.abs(extremes - candidate) >= widths):
                return float(candidate)
    return float(want)


def _max_overlap(packing: Packing) -> float:
    c = packing.contacts
    if not c.n_points:
        return 0.0
    grain_pair = np.repeat(c.body_j >= 0, np.diff(c.point_start))
    depth = -c.gap[grain_pair]
    return float(max(0.0, depth.max(initial=0.0)))


def _check_options(options: MeshOptions) -> None:
    def positive(value, name):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{name} must be a number > 0 (d), got {value}")

    positive(options.gap, "--gap")
    positive(options.size, "--size")
    positive(options.size_factor, "--size-factor")
    if not (isinstance(options.curvature, int) and options.curvature >= 8):
        raise InputError(f"--curvature must be a whole number >= 8 (elements per turn), got {options.curvature}")
    if not (math.isfinite(options.itz) and options.itz >= 0):
        raise InputError(f"--itz must be a thickness >= 0 (d; 0: no ITZ), got {options.itz}")


def _region(packing: Packing, options: MeshOptions, table: ShapeTable) -> tuple[tuple[float, ...], bool]:
    """The box (module docstring) and whether it spans the full cell width."""
    from granpack.analysis.solid_fraction import bulk_range

    state = packing.state
    lx, ly = packing.box.lx, packing.box.ly
    sizes = 2.0 * state.radius
    d_min, d_max = float(sizes.min()), float(sizes.max())
    top = float(np.max(state.position[:, 2] + state.radius))
    band = GRAZE * sizes
    if options.box is None:
        z_bottom, z_top, valid = bulk_range(packing)
        if not valid:
            raise InputError(f"the packing has no bulk region to cut the mesh's box from (its free surface is too low "
                             f"for 2 d above the wall, 1 d of bulk and 2 d below the surface): give the region with "
                             f"--box X0 Y0 Z0 X1 Y1 Z1 (d, inside 0..{lx:.4g} x 0..{ly:.4g} x 0..{top:.4g})")
        reach = 0.1 * d_min
        lo_z, hi_z = _extent(packing, 2, table)
        z0 = _clear_plane(z_bottom, lo_z, hi_z, band, reach, None)
        z1 = _clear_plane(z_top, lo_z, hi_z, band, reach, None)
        lo_x, hi_x = _extent(packing, 0, table)
        lo_y, hi_y = _extent(packing, 1, table)
        x0 = _clear_plane(0.0, lo_x, hi_x, band, reach, lx)
        y0 = _clear_plane(0.0, lo_y, hi_y, band, reach, ly)
        return (x0, y0, z0, x0 + lx, y0 + ly, z1), True
    box = tuple(float(v) for v in options.box)
    if len(box) != 6 or not all(math.isfinite(v) for v in box):
        raise InputError(f"--box takes six numbers X0 Y0 Z0 X1 Y1 Z1 (d), got {options.box}")
    x0, y0, z0, x1, y1, z1 = box
    if not (0.0 <= x0 < x1 <= lx and 0.0 <= y0 < y1 <= ly and 0.0 <= z0 < z1 <= top):
        raise InputError(f"--box {' '.join(f'{v:g}' for v in box)}: outside the packing; the box must lie in "
                         f"0..{lx:.4g} x 0..{ly:.4g} x 0..{top:.4g} (d) with X0 < X1, Y0 < Y1, Z0 < Z1")
    thinnest = min(x1 - x0, y1 - y0, z1 - z0)
    if thinnest < d_max:
        raise InputError(f"--box {' '.join(f'{v:g}' for v in box)}: {thinnest:.4g} d thick, thinner than the largest "
                         f"grain ({d_max:.4g} d); each side must be at least one grain size")
    full = math.isclose(x1 - x0, lx, rel_tol=1e-12) and math.isclose(y1 - y0, ly, rel_tol=1e-12)
    return box, full


def _instances(state: ParticleState, outer: np.ndarray, box) -> Instances:
    """Grains and their periodic images (bodies of circumscribed radius ``outer[kind]``) that reach into the box;
    in a box or a cylinder (:class:`granpack.box.Box`) the grains alone, where they are."""
    from granpack.rotations import quat_to_matrix

    x0, y0, z0, x1, y1, z1 = box
    lx, ly = state.box.lx, state.box.ly
    rot = quat_to_matrix(state.quaternion)
    reach = outer[state.kind]
    # wrap centres into [x0, x0 + lx) x [y0, y0 + ly): the images needed are then the +-1 shifts
    pos = state.position.copy()
    if state.box.periodic:
        pos[:, 0] = x0 + np.mod(pos[:, 0] - x0, lx)
        pos[:, 1] = y0 + np.mod(pos[:, 1] - y0, ly)
    shifts = [(i * lx, j * ly) for i in (-1, 0, 1) for j in (-1, 0, 1)] if state.box.periodic else [(0.0, 0.0)]
    grains, where = [], []
    lo_box, hi_box = np.array([x0, y0, z0]), np.array([x1, y1, z1])
    for sx, sy in shifts:
        p = pos + np.array([sx, sy, 0.0])
        nearest = np.clip(p, lo_box, hi_box)
        inside = np.linalg.norm(p - nearest, axis=1) < reach
        grains.append(np.flatnonzero(inside))
        where.append(p[inside])
    grain = np.concatenate(grains)
    order = np.argsort(grain, kind="stable")
    grain = grain[order]
    return Instances(grain=grain, position=np.concatenate(where)[order], rotation=rot[grain], kind=state.kind[grain])


def _whole_inside(instances: Instances, shapes: ShapeTable, box) -> np.ndarray:
    """``(M,)`` True for the instances that lie wholly inside the box (no face cuts them)."""
    lo_box, hi_box = np.array(box[:3]), np.array(box[3:])
    whole = np.zeros(len(instances.grain), bool)
    for k, shape in enumerate(shapes.shapes):
        members = np.flatnonzero(instances.kind == k)
        if not len(members):
            continue
        if isinstance(shape, Sphere):
            lo = instances.position[members] - shape.radius
            hi = instances.position[members] + shape.radius
        else:
            world = np.einsum("nij,vj->nvi", instances.rotation[members], shape.vertices)
            lo = instances.position[members] + world.min(axis=1)
            hi = instances.position[members] + world.max(axis=1)
        whole[members] = np.all(lo > lo_box, axis=1) & np.all(hi < hi_box, axis=1)
    return whole


def plan_mesh(packing: Packing, options: MeshOptions) -> MeshPlan:
    """Check ``options`` against ``packing`` and decide region, shrink, ITZ and element size.

    Raises:
        InputError: a bad option (one line naming it and what is allowed).
    """
    from granpack.analysis.solid_fraction import slice_volumes

    _check_options(options)
    state = packing.state
    if state.n == 0:
        raise InputError("the packing holds no grain: nothing to mesh")
    table = state.shapes
    used = np.unique(state.kind)
    d_min = float(2.0 * table.radius[used].min())
    gap = options.gap if options.gap is not None else GAP_FACTOR * d_min
    size = options.size if options.size is not None else options.size_factor * d_min
    inner = np.array([_inradius(s) for s in table.shapes])
    outer_plane = np.array([_outradius(s) for s in table.shapes])
    scale = 1.0 - gap / (2.0 * inner)
    if np.any(scale[used] < 0.5):
        most = float(inner[used].min())
        raise InputError(f"--gap {gap:.4g}: too large for the smallest grain (its faces are {most:.4g} d from its "
                         f"centroid); the gap must be at most {most:.4g} d (a grain shrunk to half its size at most)")
    overlap = _max_overlap(packing)
    if overlap > 0.5 * gap:
        raise InputError(f"--gap {gap:.4g}: the packing's grains overlap by up to {overlap:.3g} d; the gap must be at "
                         f"least twice that ({2 * overlap:.3g} d) to separate them")
    clearance = gap - overlap
    itz_ratio = float(np.max(outer_plane[used] / inner[used]))
    if options.itz > 0:
        allowed = 0.5 * clearance / itz_ratio
        if options.itz > 0.5 * allowed:
            raise InputError(f"--itz {options.itz:.4g}: thicker than the gaps allow; the shells of two grains that "
                             f"touched must leave matrix between them: --itz at most {0.5 * allowed:.4g} d with "
                             f"--gap {gap:.4g} (half the {allowed:.4g} d at which they would meet), or a larger --gap")
        itz_scale = 1.0 + options.itz / (scale * inner)
    else:
        itz_scale = np.ones(len(table.shapes))
    shrunk = ShapeTable.from_shapes([s.scaled(f) for s, f in zip(table.shapes, scale)])
    box, full_width = _region(packing, options, shrunk)
    if options.periodic and not packing.box.periodic:
        raise InputError(f"--periodic needs a periodic cell: this packing lies in a {packing.box.container} "
                         "(container.shape); leave --periodic out")
    if options.periodic and not full_width:
        raise InputError(f"--periodic needs the cell's full width: leave --box out, or give X1 - X0 = {packing.box.lx:.6g} "
                         f"and Y1 - Y0 = {packing.box.ly:.6g} (d)")
    reach = np.array([s.circumscribed_radius for s in shrunk.shapes]) * itz_scale
    instances = _instances(state, reach, box)

    shrunk_packing = Packing(
        ParticleState(box=state.box, shapes=shrunk, kind=state.kind, population=state.population,
                      position=state.position, quaternion=state.quaternion),
        packing.contacts, packing.time_step, packing.population_names, packing.metadata,
    )
    x0, y0, z0, x1, y1, z1 = box
    height = z1 - z0
    if full_width:
        per_grain = slice_volumes(shrunk_packing, z0, height, 1, groups=np.arange(state.n))[:, 0]
        area = packing.box.area
        fraction = float(per_grain.sum() / (area * height))
        unshrunk = float(slice_volumes(packing, z0, height, 1).sum() / (area * height))
    else:
        per_grain = np.full(state.n, np.nan)
        whole = _whole_inside(instances, shrunk, box)
        per_grain[instances.grain[whole]] = shrunk.volume[instances.kind[whole]]
        fraction = unshrunk = math.nan
    return MeshPlan(box=box, full_width=full_width, shapes=shrunk, scale=scale, itz_scale=itz_scale,
                    instances=instances, gap=float(gap), size=float(size), min_clearance=float(clearance),
                    max_overlap=overlap, itz_ratio=itz_ratio, grain_volume=per_grain, solid_fraction=fraction,
                    solid_fraction_unshrunk=unshrunk, options=options)
