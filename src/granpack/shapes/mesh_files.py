"""Grain surfaces from mesh files: STL (ascii and binary), OBJ, PLY and OFF, read with trimesh.

A file holds one grain: a closed triangulated surface, in any length unit. :func:`expand_files`
turns a population's ``files`` (paths or glob patterns, relative to the config file) into a
sorted list of files; :func:`read_mesh` reads one into a :class:`MeshFile`. Every problem is a
:class:`MeshFileError` whose message names the file and the reason in one line.

Vertex order (a convention, owned here): the vertices of a :class:`MeshFile` are the file's
distinct points in the order the file gives them: its vertex list (OBJ, PLY, OFF), or, for STL,
which repeats every point in each triangle and has no vertex list, the order in which they first
appear in its triangles. trimesh's own merging sorts them; this order depends on the file alone,
so a grain's vertex table, hence a packing, is the same whatever trimesh version reads it, and a
grain written with the vertex list of a built-in shape is that shape, bit for bit.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

__all__ = ["MESH_SUFFIXES", "MeshFile", "MeshFileError", "expand_files", "read_mesh"]

#: the file suffixes read (lower case) and trimesh's name of each format
MESH_SUFFIXES: dict[str, str] = {".stl": "stl", ".obj": "obj", ".ply": "ply", ".off": "off"}


class MeshFileError(ValueError):
    """A mesh file that cannot be a grain; the message is ``FILE: reason`` on one line."""


@dataclass(frozen=True)
class MeshFile:
    """One grain surface as read.

    Attributes:
        path: the file (absolute).
        vertices: ``(V, 3)`` float64 distinct points of the triangles, in the file's order (see
            the module docstring), in the file's unit.
        faces: ``(F, 3)`` int64 triangles (indices into ``vertices``) as the file orients them.
        volume: the volume the closed surface encloses, file unit cubed (> 0).
    """

    path: Path
    vertices: np.ndarray
    faces: np.ndarray
    volume: float


def expand_files(patterns: tuple[str, ...] | list[str], base_dir: Path) -> tuple[Path, ...]:
    """The files a population names: each entry a path or a glob pattern (``*``, ``?``, ``[...]``,
    ``**``), relative to ``base_dir`` unless absolute; a pattern's matches sorted by name, the
    entries in their order, a file named twice kept once (at its first place).

    Raises:
        MeshFileError: a pattern that matches nothing, a missing file, a directory, or a suffix
            that is not one of :data:`MESH_SUFFIXES`.
    """
    out: list[Path] = []
    for pattern in patterns:
        full = Path(pattern).expanduser()
        full = full if full.is_absolute() else Path(base_dir) / full
        if glob.has_magic(str(full)):
            matches = sorted(Path(p) for p in glob.glob(str(full), recursive=True))
            matches = [p for p in matches if not p.is_dir()]
            if not matches:
                raise MeshFileError(f"{full}: the pattern matches no file")
        else:
            if full.is_dir():
                raise MeshFileError(f"{full}: is a directory, not a mesh file (a pattern such as "
                                    f"{Path(pattern) / '*.stl'} takes its files)")
            if not full.exists():
                raise MeshFileError(f"{full}: no such file")
            matches = [full]
        for path in matches:
            if path.suffix.lower() not in MESH_SUFFIXES:
                raise MeshFileError(f"{path}: not a mesh file granpack reads (suffix {path.suffix or 'none'}; "
                                    f"allowed: {', '.join(MESH_SUFFIXES)})")
            path = path.resolve()
            if path not in out:
                out.append(path)
    return tuple(out)


def read_mesh(path: str | Path) -> MeshFile:
    """Read one grain surface (cached by path, size and modification time).

    Raises:
        MeshFileError: unreadable file, no triangles, non-finite coordinates, a surface that is
            not closed or not consistently oriented, or that encloses no volume.
    """
    path = Path(path).resolve()
    try:
        stat = path.stat()
    except FileNotFoundError:
        raise MeshFileError(f"{path}: no such file") from None
    except OSError as exc:
        raise MeshFileError(f"{path}: cannot read ({exc.strerror})") from None
    if path.is_dir():
        raise MeshFileError(f"{path}: is a directory, not a mesh file")
    return _read(str(path), stat.st_size, stat.st_mtime_ns)


@lru_cache(maxsize=4096)
def _read(path_text: str, size: int, mtime_ns: int) -> MeshFile:
    """:func:`read_mesh` of a file as it is at ``(size, mtime_ns)`` (the cache key)."""
    import trimesh

    path = Path(path_text)
    kind = MESH_SUFFIXES.get(path.suffix.lower())
    if kind is None:
        raise MeshFileError(f"{path}: not a mesh file granpack reads (allowed: {', '.join(MESH_SUFFIXES)})")
    if size == 0:
        raise MeshFileError(f"{path}: empty file")
    try:
        with open(path, "rb") as stream:
            mesh = trimesh.load(stream, file_type=kind, force="mesh", process=False)
        raw_vertices = np.asarray(mesh.vertices, dtype=np.float64)
        raw_faces = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
    except OSError as exc:
        raise MeshFileError(f"{path}: cannot read ({exc.strerror})") from None
    except Exception as exc:  # noqa: BLE001 (trimesh raises many kinds on a bad file)
        reason = " ".join(str(exc).split())[:120] or type(exc).__name__
        raise MeshFileError(f"{path}: cannot be read as {kind.upper()} ({reason})") from None
    if not len(raw_faces):
        raise MeshFileError(f"{path}: holds no triangles (empty, or not a {kind.upper()} file)")
    if not np.all(np.isfinite(raw_vertices[raw_faces])):
        raise MeshFileError(f"{path}: coordinates that are not finite numbers")
    if kind == "stl":
        vertices, faces = _first_appearance(raw_vertices[raw_faces.ravel()], np.arange(raw_faces.size))
    else:
        used = np.unique(raw_faces)
        vertices, faces = _first_appearance(raw_vertices[used], np.searchsorted(used, raw_faces.ravel()))
    closed = trimesh.Trimesh(vertices=vertices, faces=faces, process=True)
    if not closed.is_watertight:
        raise MeshFileError(f"{path}: the surface is not closed (some edges do not join exactly two "
                            "triangles); repair the mesh (holes, cracks, stray triangles) first")
    if not closed.is_winding_consistent:
        raise MeshFileError(f"{path}: the triangles are not consistently oriented; repair the mesh first")
    with np.errstate(invalid="ignore", divide="ignore"):  # trimesh's centroid of a flat surface
        volume = abs(float(closed.volume))
    extent = float(np.ptp(vertices, axis=0).max())
    if not volume > 1e-9 * extent ** 3:
        raise MeshFileError(f"{path}: the surface encloses no volume (flat or degenerate)")
    return MeshFile(path=path, vertices=vertices, faces=faces, volume=volume)


def _first_appearance(points: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct rows of ``points`` ``(P, 3)`` in the order they first appear, and the triangles
    ``corners`` ``(3F,)`` (indices into ``points``, three per triangle) as ``(F, 3)`` indices into
    them; equal means bit for bit equal."""
    unique, first, inverse = np.unique(points, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return unique[order], rank[np.asarray(inverse).ravel()[corners]].reshape(-1, 3).astype(np.int64)
