"""Packings as GSD files (HOOMD schema; OVITO draws the true grain shapes).

One frame per file. Layout:

- ``configuration/box`` = ``[Lx, Ly, Lz, 0, 0, 0]`` with ``Lz`` = highest grain top + 1 d (GSD has no
  open boundaries; periodicity is recorded in ``log/granpack/periodic``).
- GSD wants positions centred in the box, so ``particles/position`` holds ``x - origin`` with
  ``origin = (Lx/2, Ly/2, Lz/2)`` (stored in ``log/granpack/origin``): the wall z = 0 is at
  ``-Lz/2`` in the viewer. These schema fields are float32, so the exact double-precision arrays
  are stored alongside, uncentred, in ``log/granpack/position``, ``log/granpack/orientation`` and
  ``log/granpack/velocity``; :func:`read_packing` reads those, hence the round trip is exact.
- ``particles/orientation`` (w, x, y, z), ``particles/types``, ``particles/type_shapes``
  (``Shape.gsd_shape()``) and ``particles/typeid``: one type per distinct shape among the grains
  (kinds of equal ``gsd_shape()`` share a type, kinds that no grain has get none), so a population
  of mesh files or rocks has one type per file or rock; grains of a graded population differ in
  size, hence in shape (GSD scales no polyhedron per particle), and take one type each.
  ``particles/diameter`` (circumscribed), ``particles/mass``, ``particles/moment_inertia``,
  ``particles/velocity``.
- Per-particle logs (OVITO shows them as properties): ``log/particles/kind`` (int64, the grain's
  kind in the shape table), ``log/particles/population`` (int64) and ``log/particles/omega``
  (float64, body frame).
- Contacts (:class:`~granpack.contact.ContactSet` arrays, float64/int64):
  ``log/contacts/{body_i, body_j, shift, normal, ctype, point_start, point, gap, impulse}``.
- Run data: ``log/granpack/{format, lateral_size, time, time_step, periodic, wall, origin}``
  (``periodic`` ``(1, 1, 0)`` for a periodic cell, ``(0, 0, 0)`` in a box or a cylinder, whose
  walls OVITO does not draw from the file: the box's walls are the GSD box's sides, the cylinder
  is inscribed in them; a run writes their surface beside ``final.gsd``, :mod:`granpack.io.container`) and JSON text stored as uint8 arrays:
  ``log/granpack/container`` (:meth:`granpack.box.Box.to_dict`; absent in the files written
  before containers: periodic), ``log/granpack/shapes`` (the shape specs that rebuild the
  :class:`~granpack.shapes.ShapeTable` exactly), ``log/granpack/population_names``,
  ``log/granpack/metadata``.

Files are written to a temporary name in the same folder and renamed (atomic). Format 1 (before
types were shared between kinds) had one type per kind and no ``log/particles/kind``: its
``typeid`` is the kind, and :func:`read_packing` reads it so.
"""

from __future__ import annotations

import json
import os
from collections import Counter
from pathlib import Path

import gsd.hoomd
import numpy as np

from granpack.box import Box
from granpack.contact.contacts import ContactSet
from granpack.errors import InputError
from granpack.io.atomic import atomic_path
from granpack.io.json import to_jsonable
from granpack.packing import Packing
from granpack.shapes import ConvexPolyhedron, Pinacoid, Shape, ShapeTable, Sphere
from granpack.state import ParticleState

__all__ = ["frame_origin", "write_packing", "append_frame", "truncate_frames", "read_packing", "shape_spec", "shape_from_spec"]

#: version of the layout above, stored in ``log/granpack/format``
FORMAT_VERSION = 2
#: the formats :func:`read_packing` reads (1: ``particles/typeid`` is the kind)
READ_FORMATS = (1, 2)

_CONTACT_FIELDS = ("body_i", "body_j", "shift", "normal", "ctype", "point_start", "point", "gap", "impulse")


def shape_spec(shape: Shape, index_of: dict[int, int] | None = None) -> dict:
    """A JSON-able description that :func:`shape_from_spec` turns back into the same shape.

    Pinacoids keep their defining dimensions (rebuilt bit for bit); other polyhedra keep their
    body-frame vertices (and the ``convexity`` of the surface a grain from a file is the hull of);
    spheres their diameter. A polyhedron scaled from another shape of the same
    table (a graded grain; ``index_of`` maps ``id(shape)`` to its kind) keeps that kind and the
    factor, ``{"type": "scaled", "of": k, "factor": f}``.
    """
    scale_of = getattr(shape, "scale_of", None)
    if scale_of is not None and index_of is not None and id(scale_of[0]) in index_of:
        return {"type": "scaled", "of": index_of[id(scale_of[0])], "factor": scale_of[1]}
    if isinstance(shape, Sphere):
        return {"type": "sphere", "diameter": shape.diameter}
    if isinstance(shape, Pinacoid):
        return {
            "type": "pinacoid",
            "length": shape.length,
            "width": shape.width,
            "thickness": shape.thickness,
            "alpha_deg": shape.alpha_deg,
            "name": shape.name,
        }
    if isinstance(shape, ConvexPolyhedron):
        spec = {"type": "polyhedron", "vertices": shape.vertices.tolist(), "name": shape.name}
        if shape.source_convexity is not None:
            spec["convexity"] = shape.source_convexity
        return spec
    raise TypeError(f"cannot store shape {shape!r}")


def shape_from_spec(spec: dict, earlier: list[Shape] | None = None) -> Shape:
    """Inverse of :func:`shape_spec`; ``earlier``: the shapes of the kinds before (a scaled one's base)."""
    kind = spec["type"]
    if kind == "scaled":
        return earlier[int(spec["of"])].scaled(float(spec["factor"]))
    if kind == "sphere":
        return Sphere(spec["diameter"])
    if kind == "pinacoid":
        return Pinacoid(spec["length"], spec["width"], spec["thickness"], spec["alpha_deg"], name=spec["name"])
    if kind == "polyhedron":
        shape = ConvexPolyhedron(np.asarray(spec["vertices"], dtype=np.float64), name=spec["name"])
        shape.source_convexity = spec.get("convexity")
        return shape
    raise ValueError(f"unknown shape type {kind!r}")


def _types(state: ParticleState) -> tuple[list[str], list[dict], np.ndarray]:
    """The GSD types of ``state``: one per distinct shape among its grains' kinds.

    Kinds whose ``gsd_shape()`` are equal (the same JSON: every number the same float) share a
    type, which takes the first such kind's shape name (``sphere`` for spheres), suffixed by the
    type's index where that name is repeated; kinds that no grain has get no type (all kinds get
    one when there is no grain).

    Returns:
        ``(names, type_shapes, type_of)``: the type names, their ``type_shapes`` entries, and the
        ``(n_kinds,)`` int64 type of each kind (-1 for a kind without a type).
    """
    shapes = state.shapes.shapes
    used = np.unique(state.kind) if state.n else np.arange(len(shapes))
    type_of = np.full(len(shapes), -1, dtype=np.int64)
    index: dict[str, int] = {}
    entries: list[dict] = []
    base: list[str] = []
    for k in used.tolist():
        entry = shapes[k].gsd_shape()
        t = index.setdefault(json.dumps(entry, sort_keys=True), len(entries))
        if t == len(entries):
            entries.append(entry)
            base.append(shapes[k].name if isinstance(shapes[k], ConvexPolyhedron) else "sphere")
        type_of[k] = t
    repeated = Counter(base)
    names = [b if repeated[b] == 1 else f"{b}-{t}" for t, b in enumerate(base)]
    return names, entries, type_of


def _text(obj) -> np.ndarray:
    return np.frombuffer(json.dumps(to_jsonable(obj)).encode("utf-8"), dtype=np.uint8).copy()


def _untext(arr) -> object:
    return json.loads(np.asarray(arr, dtype=np.uint8).tobytes().decode("utf-8"))


def frame_origin(packing: Packing) -> np.ndarray:
    """The centre of the GSD box of ``packing``, ``(Lx/2, Ly/2, Lz/2)`` with ``Lz`` the highest
    grain's top + 1 d: the file's positions are the packing's less this (module docstring)."""
    state, box = packing.state, packing.box
    top = float(np.max(state.position[:, 2] + state.radius)) if state.n else 0.0
    return np.array([0.5 * box.lx, 0.5 * box.ly, 0.5 * (max(top, 0.0) + 1.0)])


def _frame(packing: Packing) -> gsd.hoomd.Frame:
    state, contacts, box = packing.state, packing.contacts, packing.box
    shapes = state.shapes.shapes
    origin = frame_origin(packing)
    lz = 2.0 * origin[2]

    f = gsd.hoomd.Frame()
    f.configuration.step = int(packing.metadata.get("step", 0))
    f.configuration.box = [box.lx, box.ly, lz, 0.0, 0.0, 0.0]
    f.particles.N = state.n
    names, entries, type_of = _types(state)
    f.particles.types = names
    f.particles.type_shapes = entries
    f.particles.typeid = type_of[state.kind].astype(np.uint32)
    f.particles.position = (state.position - origin).astype(np.float32)
    f.particles.orientation = state.quaternion.astype(np.float32)
    f.particles.velocity = state.velocity.astype(np.float32)
    f.particles.diameter = (2.0 * state.radius).astype(np.float32)
    f.particles.mass = state.mass.astype(np.float32)
    f.particles.moment_inertia = state.inertia.astype(np.float32)

    log = f.log
    log["particles/kind"] = state.kind.astype(np.int64)
    log["particles/population"] = state.population.astype(np.int64)
    log["particles/omega"] = state.omega.astype(np.float64)
    for name in _CONTACT_FIELDS:
        log[f"contacts/{name}"] = np.ascontiguousarray(getattr(contacts, name))
    log["granpack/format"] = np.array([FORMAT_VERSION], dtype=np.int64)
    log["granpack/lateral_size"] = np.array([box.lx, box.ly])
    log["granpack/time"] = np.array([state.time])
    log["granpack/time_step"] = np.array([packing.time_step])
    log["granpack/periodic"] = np.array([1, 1, 0] if box.periodic else [0, 0, 0], dtype=np.uint8)
    log["granpack/container"] = _text(box.to_dict())
    log["granpack/wall"] = np.array([0.0, 0.0, 1.0, 0.0])  # plane n . x = 0, normal +z
    log["granpack/origin"] = origin
    log["granpack/position"] = state.position.astype(np.float64)
    log["granpack/orientation"] = state.quaternion.astype(np.float64)
    log["granpack/velocity"] = state.velocity.astype(np.float64)
    index_of = {id(s): k for k, s in enumerate(shapes)}
    log["granpack/shapes"] = _text([shape_spec(s, index_of) for s in shapes])
    log["granpack/population_names"] = _text(list(packing.population_names))
    log["granpack/metadata"] = _text(packing.metadata)
    return f


def write_packing(path: str | os.PathLike, packing: Packing) -> Path:
    """Write ``packing`` as a one-frame GSD file, atomically.

    Args:
        path: destination (``.gsd``); its folder must exist.
        packing: the packing to store.

    Returns:
        The path written.
    """
    path = Path(path)
    frame = _frame(packing)
    with atomic_path(path) as tmp, gsd.hoomd.open(tmp, mode="w") as traj:
        traj.append(frame)
    return path


def append_frame(path: str | os.PathLike, packing: Packing) -> Path:
    """Append ``packing`` as one more frame of the trajectory ``path`` (created if missing).

    Frames are self-contained (same layout as :func:`write_packing`); OVITO plays them as an
    animation and :func:`read_packing` reads the last one.
    """
    path = Path(path)
    with gsd.hoomd.open(path, mode="a" if path.is_file() else "w") as traj:
        traj.append(_frame(packing))
    return path


def truncate_frames(path: str | os.PathLike, last_step: int) -> None:
    """Keep only the frames of the trajectory ``path`` whose step is at most ``last_step``
    (rewritten atomically; used when a run resumes from an earlier checkpoint)."""
    path = Path(path)
    if not path.is_file():
        return
    with gsd.hoomd.open(path, mode="r") as traj:
        frames = [f for f in traj if int(f.configuration.step) <= last_step]
    with atomic_path(path) as tmp, gsd.hoomd.open(tmp, mode="w") as out:
        for f in frames:
            out.append(f)


def read_packing(path: str | os.PathLike) -> Packing:
    """Read a packing written by :func:`write_packing` (the last frame if there are several).

    Raises:
        InputError: the file is missing, is not a readable GSD file, or lacks the granpack data
            (one-line message naming the file).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: file not found")
    try:
        with gsd.hoomd.open(path, mode="r") as traj:
            if len(traj) == 0:
                raise InputError(f"{path}: GSD file holds no frame")
            frame = traj[len(traj) - 1]
    except InputError:
        raise
    except Exception as exc:  # gsd raises RuntimeError/OSError/ValueError on damaged files
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{path}: not a readable GSD file ({msg})") from None
    try:
        return _decode(frame)
    except KeyError as exc:
        raise InputError(f"{path}: not a granpack packing (missing {exc.args[0]!r})") from None
    except (ValueError, TypeError, UnicodeDecodeError) as exc:
        msg = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"{path}: inconsistent granpack packing ({msg})") from None


def _decode(frame: gsd.hoomd.Frame) -> Packing:
    log = frame.log
    if "granpack/format" not in log:
        raise KeyError("log/granpack/format")
    fmt = int(np.asarray(log["granpack/format"])[0])
    if fmt not in READ_FORMATS:
        raise ValueError(f"unsupported granpack GSD format {fmt} (this version reads "
                         f"{', '.join(map(str, READ_FORMATS))})")
    n = int(frame.particles.N)
    built: list[Shape] = []
    for spec in _untext(log["granpack/shapes"]):
        built.append(shape_from_spec(spec, built))
    shapes = ShapeTable.from_shapes(built)
    lx, ly = (float(v) for v in log["granpack/lateral_size"])
    container = _untext(log["granpack/container"])["shape"] if "granpack/container" in log else "periodic"
    state = ParticleState(
        box=Box(lx, ly, container),
        shapes=shapes,
        kind=np.asarray(frame.particles.typeid if fmt == 1 else log["particles/kind"], dtype=np.int64).reshape(n),
        population=np.asarray(log["particles/population"], dtype=np.int64).reshape(n),
        position=np.asarray(log["granpack/position"], dtype=np.float64).reshape(n, 3),
        quaternion=np.asarray(log["granpack/orientation"], dtype=np.float64).reshape(n, 4),
        velocity=np.asarray(log["granpack/velocity"], dtype=np.float64).reshape(n, 3),
        omega=np.asarray(log["particles/omega"], dtype=np.float64).reshape(n, 3),
        time=float(np.asarray(log["granpack/time"])[0]),
    )
    if n and (state.kind.min() < 0 or state.kind.max() >= shapes.n_kinds):
        raise ValueError("particle kind outside the stored shapes")
    arrays = {name: np.asarray(log[f"contacts/{name}"]) for name in _CONTACT_FIELDS}
    m, p = len(arrays["body_i"]), len(arrays["gap"])
    contacts = ContactSet(
        body_i=arrays["body_i"].astype(np.int64).reshape(m),
        body_j=arrays["body_j"].astype(np.int64).reshape(m),
        shift=arrays["shift"].astype(np.float64).reshape(m, 3),
        normal=arrays["normal"].astype(np.float64).reshape(m, 3),
        ctype=arrays["ctype"].astype(np.int64).reshape(m),
        point_start=arrays["point_start"].astype(np.int64).reshape(m + 1),
        point=arrays["point"].astype(np.float64).reshape(p, 3),
        gap=arrays["gap"].astype(np.float64).reshape(p),
        impulse=arrays["impulse"].astype(np.float64).reshape(p, 3),
    )
    if contacts.point_start[-1] != p:
        raise ValueError("contact point offsets do not match the number of points")
    return Packing(
        state=state,
        contacts=contacts,
        time_step=float(np.asarray(log["granpack/time_step"])[0]),
        population_names=[str(s) for s in _untext(log["granpack/population_names"])],
        metadata=dict(_untext(log["granpack/metadata"])),
    )
