"""Contact detection: broad phase + narrow phase -> :class:`~granpack.contact.contacts.ContactSet`.

API:

- ``detect(state, alert, previous=None) -> ContactSet``: one-shot detection (the grid search is
  done every call).
- ``Detector(skin=..., eps_f=None, threads=None)``: the same with state kept between steps; ``skin
  > 0`` keeps the broad-phase pair list (Verlet list) while no grain has moved more than ``skin /
  2``; ``threads`` narrow-phase threads (default: Numba's thread count).
  ``Detector.detect(state, alert, previous=None)`` has the signature of :func:`detect`; the
  counters ``n_candidates`` (pairs in the list), ``n_tested`` (pairs whose bounding spheres are
  within ``alert``, i.e. narrow-phase tests) and ``n_builds`` describe the last call.

Every pair with a gap (exact distance, or negative penetration depth) of at most ``alert`` gives
one manifold: bodies ``i < j`` (``j < 0`` a wall of the cell, :mod:`granpack.contact.contacts`;
a polyhedron has one manifold per vertex near a cylinder), the image shift of ``j`` (zero in a
box or a cylinder, whose positions are never wrapped), the
normal from ``j`` to ``i``, its points with their gaps (every vertex of a contact polygon), and
the contact type 1/2/3 from the rank of the points (docs/method/contact-detection.md#contact-types). Manifolds are ordered by ``i``, then ``j`` with the
walls first (the floor, then the box's walls or the cylinder's vertices), independently of the Verlet state, so results do not depend on the skin.

``previous`` (the manifolds of the previous step, e.g. the solver's last ``ContactSet``) gives
temporal hysteresis between polyhedra: a pair keeps the separating axis family (face of ``j``,
face of ``i``, edge-edge) whose axis is closest to its previous normal while that axis is within
``eps_f`` of the best separation, so contact points and types do not flip between equivalent
axes from one step to the next.

Conventions: lengths in d; ``alert`` is the largest gap reported (at least twice the largest
displacement per step, docs/method/nscd.md#alert-distance-and-substeps); the box must satisfy ``lx, ly > 2 (d_max + alert)``.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor


from granpack._numba import thread_count
import numpy as np

from granpack.contact.broadphase import VerletList
from granpack.contact.contacts import ContactSet
from granpack.contact.narrowphase import (
    CandidatePairs,
    KindBounds,
    KindTables,
    PreviousNormals,
    narrow_phase,
    world_geometry,
)
from granpack.contact.separating_axes import SymmetricTables
from granpack.shapes import ShapeTable
from granpack.state import ParticleState

__all__ = ["Detector", "detect"]

#: fewest candidate pairs per narrow-phase thread: below, one thread (a thread's hand-off costs
#: tens of microseconds, about a hundred pair tests)
_PAIRS_PER_THREAD = 2000


def _edge_direction_index(shapes: ShapeTable) -> np.ndarray:
    """``(NE,)`` local index, in its kind's ``edge_directions``, of every edge's direction."""
    out = np.zeros(len(shapes.edges), dtype=np.int64)
    for k in range(shapes.n_kinds):
        v = shapes.vertices[shapes.vertex_start[k]:shapes.vertex_start[k + 1]]
        dirs = shapes.edge_directions[shapes.direction_start[k]:shapes.direction_start[k + 1]]
        for e in range(shapes.edge_start[k], shapes.edge_start[k + 1]):
            a, b = shapes.edges[e]
            u = v[b] - v[a]
            u = u / np.linalg.norm(u)
            out[e] = int(np.argmax(np.abs(dirs @ u)))
    return out


def _antipodal_halves(shapes: ShapeTable) -> tuple[np.ndarray, np.ndarray]:
    """CSR over kinds of one vertex (local index) of each antipodal pair ``(v, -v)``; the block of
    a kind is empty unless the kind is a centrally symmetric polyhedron."""
    blocks = []
    for k in range(shapes.n_kinds):
        v = shapes.vertices[shapes.vertex_start[k]:shapes.vertex_start[k + 1]]
        tol = 1e-9 * max(float(np.abs(v).max()), 1e-300) if len(v) else 0.0
        keep = []
        for a in range(len(v)):
            partner = np.flatnonzero(np.linalg.norm(v + v[a], axis=1) < tol)
            if len(partner) != 1:
                keep = []
                break
            if a < partner[0]:
                keep.append(a)
        blocks.append(np.array(keep, dtype=np.int64))
    start = np.zeros(shapes.n_kinds + 1, dtype=np.int64)
    start[1:] = np.cumsum([len(b) for b in blocks])
    return start, np.concatenate(blocks).astype(np.int64)


def _axis_support(shapes: ShapeTable) -> np.ndarray:
    """``(NA,)`` support ``max_v |a . v|`` of each kind along each of its face axes ``a``, d."""
    out = np.zeros(len(shapes.face_axes))
    for k in range(shapes.n_kinds):
        v = shapes.vertices[shapes.vertex_start[k]:shapes.vertex_start[k + 1]]
        rows = slice(shapes.axis_start[k], shapes.axis_start[k + 1])
        if len(v):
            out[rows] = np.abs(shapes.face_axes[rows] @ v.T).max(axis=1)
    return out


def _axis_extent(shapes: ShapeTable) -> np.ndarray:
    """``(NA, 2)`` least and largest ``a . v`` over each kind's vertices ``v`` along each of its
    face axes ``a``, d."""
    out = np.zeros((len(shapes.face_axes), 2))
    for k in range(shapes.n_kinds):
        v = shapes.vertices[shapes.vertex_start[k]:shapes.vertex_start[k + 1]]
        rows = slice(shapes.axis_start[k], shapes.axis_start[k + 1])
        if len(v):
            h = shapes.face_axes[rows] @ v.T
            out[rows, 0], out[rows, 1] = h.min(axis=1), h.max(axis=1)
    return out


def _edge_arcs(shapes: ShapeTable) -> np.ndarray:
    """``(NE, 2)`` per edge, the cosine ``c = n1 . n2`` between the normals of its two faces and
    ``1 / cos(theta / 2) = sqrt(2 / (1 + c))``, theta the angle between them: the arc of the edge on
    the Gauss map, whose points ``u`` have ``u . o <= max(n1 . o, n2 . o) / cos(theta / 2)`` for
    any ``o`` with a positive right side (the cheap bound of the separating-axis test)."""
    kind_of_edge = np.repeat(np.arange(shapes.n_kinds), np.diff(shapes.edge_start))
    normals = shapes.face_normals[shapes.face_start[kind_of_edge][:, None] + shapes.edge_faces]
    cos = np.einsum("ij,ij->i", normals[:, 0], normals[:, 1])
    return np.column_stack([cos, np.sqrt(2.0 / np.maximum(1.0 + cos, 1e-300))])


class _Tables:
    """Kernel tables derived once per :class:`ShapeTable`."""

    def __init__(self, shapes: ShapeTable):
        self.shapes = shapes
        face_sizes = np.diff(shapes.face_vertex_start)
        vert_counts = np.diff(shapes.vertex_start)
        max_face = int(face_sizes.max()) if len(face_sizes) else 0
        self.max_points = max(2 * max_face + 2, int(vert_counts.max()) if len(vert_counts) else 0, 4)
        self.edge_dir = _edge_direction_index(shapes)
        self.half_start, self.half = _antipodal_halves(shapes)
        self.axis_support = _axis_support(shapes)
        self.axis_extent = _axis_extent(shapes)
        self.edge_arc = _edge_arcs(shapes)
        self.symmetric = SymmetricTables(self.half_start, self.half, shapes.axis_start, self.axis_support)
        self.bounds = KindBounds(shapes.is_sphere, shapes.radius, self.axis_extent, self.edge_arc)
        self.d_min = 2.0 * float(shapes.radius.min())
        self.d_max = 2.0 * float(shapes.radius.max())

    def tab(self, kind: np.ndarray) -> KindTables:
        """The narrow phase's :class:`~granpack.contact.narrowphase.KindTables` for particles of
        these kinds (``(N,)`` int64)."""
        s = self.shapes
        return KindTables(s.face_start, s.face_offsets, s.face_vertex_start, s.face_vertices, s.edge_start, s.edges,
                          self.edge_dir, s.edge_faces, kind)


class Detector:
    """Contact detection with a broad-phase pair list kept between calls.

    Args:
        skin: Verlet skin, d; 0 (default) searches the grid at every call. A skin pays when
            grains move little per step (settling, static packings); see docs/design-notes.md.
        eps_f: feature band, rank tolerance and axis hysteresis, d; default ``1e-3 d_min``
            with ``d_min`` the smallest grain size of the shape table.
        threads: narrow-phase threads; default ``thread_count()`` (the CPUs, or
            ``NUMBA_NUM_THREADS``). The candidate pairs are cut into that many row ranges of about
            equal pair counts, each tested by one thread (the kernel releases the GIL); the
            manifolds are the same as with one thread, in the same order.

    Attributes:
        n_candidates: candidate pairs in the list at the last call.
        n_tested: pairs whose bounding spheres were within ``alert`` at the last call.
        n_builds: grid searches done so far.
    """

    def __init__(self, skin: float = 0.0, eps_f: float | None = None, threads: int | None = None):
        self.verlet = VerletList(skin)
        if eps_f is not None and not eps_f > 0:
            raise ValueError(f"eps_f must be > 0, got {eps_f}")
        if threads is not None and threads < 1:
            raise ValueError(f"threads must be >= 1, got {threads}")
        self.eps_f = eps_f
        self.threads = int(threads) if threads is not None else thread_count()
        self._pool: ThreadPoolExecutor | None = None
        self._tables: _Tables | None = None
        self._pair_axis: np.ndarray | None = None  # separating-axis cache, one code per candidate pair
        self.n_candidates = 0
        self.n_tested = 0

    @property
    def n_builds(self) -> int:
        return self.verlet.n_builds

    def detect(self, state: ParticleState, alert: float, previous: ContactSet | None = None,
               reach: np.ndarray | None = None) -> ContactSet:
        """All contact manifolds with gaps up to ``alert`` (see the module docstring).

        Args:
            state: positions (x, y wrapped or not) and orientations.
            alert: alert distance, d (>= 0).
            previous: manifolds of the previous step (temporal hysteresis), or None.
            reach: ``(N,)`` per-body share of the alert distance, d, or None (``alert / 2`` each):
                the pair ``(i, j)`` is kept up to a gap ``min(alert, reach_i + reach_j)``, the
                wall pair of ``i`` up to ``min(alert, 2 reach_i)``. Grains that move slowly need
                no more than the base alert distance even while one grain moves fast.

        Returns:
            The manifolds, ordered by ``i`` then ``j`` (wall first).

        Raises:
            ValueError: negative alert, or a box too small for one periodic image per pair.
        """
        alert = float(alert)
        if not alert >= 0.0:
            raise ValueError(f"alert distance must be >= 0, got {alert}")
        if self._tables is None or self._tables.shapes is not state.shapes:
            self._tables = _Tables(state.shapes)
            self._pair_axis = None
        tables = self._tables
        box = state.box
        limit = 2.0 * (tables.d_max + alert + self.verlet.skin)
        if not (box.lx > limit and box.ly > limit):
            # the cell grid is periodic for every container: with this bound it finds each pair once
            raise ValueError(
                f"box {box.lx:g} x {box.ly:g} too small: periods must exceed 2 (d_max + alert + skin) = {limit:g}"
            )
        shapes = state.shapes
        radius = shapes.radius[state.kind]
        if self.verlet.update(state.position, radius, box.lx, box.ly, alert) or self._pair_axis is None:
            self._pair_axis = np.full(len(self.verlet.pair_j), -1, np.int64)
        geo = world_geometry.sized(state.n)(state.position, state.quaternion, state.kind, shapes.vertex_start, shapes.vertices,
                             shapes.face_start, shapes.face_normals, shapes.axis_start, shapes.face_axes,
                             shapes.direction_start, shapes.edge_directions, self.threads)
        eps_f = self.eps_f if self.eps_f is not None else 1e-3 * tables.d_min
        pairs = CandidatePairs(self.verlet.pair_start, self.verlet.pair_j, self._pair_axis)
        args = (state.position, geo, tables.tab(state.kind), tables.bounds, tables.symmetric, pairs,
                _previous_normals(previous, state.n), box.lx, box.ly, box.code, alert, _reach(reach, state.n, alert), eps_f,
                tables.max_points)
        bounds = _row_ranges(self.verlet.pair_start, self.threads)
        if len(bounds) == 2:
            parts = [narrow_phase(*args, 0, state.n)]
        else:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="granpack-narrow-phase")
            jobs = [self._pool.submit(narrow_phase, *args, int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:])]
            parts = [job.result() for job in jobs]
        self.n_candidates = int(self.verlet.pair_start[-1])
        self.n_tested = sum(int(part[8]) for part in parts)
        return _concatenate(parts)


def _row_ranges(pair_start: np.ndarray, threads: int) -> np.ndarray:
    """Row boundaries ``0 = b_0 < ... < b_T = N`` cutting the candidate pairs (CSR over rows)
    into ``T <= threads`` ranges of about equal pair counts; ``[0, N]`` when there are fewer than
    ``_PAIRS_PER_THREAD`` pairs per thread."""
    n = len(pair_start) - 1
    total = int(pair_start[-1])
    t = min(threads, total // _PAIRS_PER_THREAD, n)
    if t <= 1:
        return np.array([0, n], np.int64)
    cuts = np.searchsorted(pair_start, total * np.arange(1, t) / t)
    return np.unique(np.concatenate(([0], cuts, [n]))).astype(np.int64)


def _concatenate(parts: list[tuple]) -> ContactSet:
    """One :class:`ContactSet` from the narrow-phase outputs of consecutive row ranges."""
    if len(parts) == 1:
        body_i, body_j, shift, normal, ctype, point_start, point, gap, _ = parts[0]
    else:
        body_i, body_j, shift, normal, ctype, point, gap = (np.concatenate([p[k] for p in parts])
                                                          for k in (0, 1, 2, 3, 4, 6, 7))
        offsets = np.cumsum([0] + [len(p[6]) for p in parts[:-1]])
        point_start = np.concatenate([[0]] + [p[5][1:] + off for p, off in zip(parts, offsets)]).astype(np.int64)
    return ContactSet(body_i=body_i, body_j=body_j, shift=shift, normal=normal, ctype=ctype,
                      point_start=point_start, point=point, gap=gap, impulse=None)


def _reach(reach: np.ndarray | None, n: int, alert: float) -> np.ndarray:
    """``(N,)`` float64 per-body reach: ``reach`` checked, or ``alert / 2`` for every body."""
    if reach is None:
        return np.full(n, 0.5 * alert)
    reach = np.ascontiguousarray(reach, dtype=np.float64)
    if reach.shape != (n,) or not np.all(reach >= 0.0):
        raise ValueError(f"reach must be {n} non-negative distances, got shape {reach.shape}")
    return reach


def _previous_normals(previous: ContactSet | None, n: int) -> PreviousNormals:
    """Previous pairs (``i < j``) sorted by ``(i, j)`` with their normals, for the merge walk."""
    if previous is None or previous.n_manifolds == 0:
        return PreviousNormals(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)))
    i = np.asarray(previous.body_i, dtype=np.int64)
    j = np.asarray(previous.body_j, dtype=np.int64)
    keep = (j > i) & (j < n)
    i, j, nrm = i[keep], j[keep], np.asarray(previous.normal, dtype=np.float64)[keep]
    key = i * (n + 1) + j
    if len(key) > 1 and np.any(np.diff(key) < 0):
        order = np.argsort(key, kind="stable")
        i, j, nrm = i[order], j[order], nrm[order]
    return PreviousNormals(np.ascontiguousarray(i), np.ascontiguousarray(j), np.ascontiguousarray(nrm))


def detect(state: ParticleState, alert: float, previous: ContactSet | None = None) -> ContactSet:
    """One-shot contact detection (grid search every call); see the module docstring.

    Args:
        state: the particles (use the predicted configuration of the time step).
        alert: alert distance, d.
        previous: manifolds of the previous step for temporal axis hysteresis, or None.

    Returns:
        All manifolds with gaps up to ``alert``.
    """
    return Detector(skin=0.0).detect(state, alert, previous)
