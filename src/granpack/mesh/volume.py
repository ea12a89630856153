"""The volume mesh of a packing written to a file a solver reads, with its report.

:func:`mesh_packing` plans (:mod:`granpack.mesh.region`) and meshes (:mod:`granpack.mesh._gmsh`);
:func:`write_mesh` writes the file (format from the suffix, :data:`SUFFIXES`) and the report
``FILE.json`` beside it (:func:`mesh_report`), both whole or not at all.

Formats: ``.msh`` is gmsh's own (MSH 4.1: physical volumes ``aggregate``, ``matrix``, ``itz``,
``grain_<i>`` with ``--grain-groups``, physical surfaces ``xmin`` ... ``zmax``, the periodic node
pairs); ``.inp`` (Abaqus: C3D4 elements, ELSETs by phase and grain, NSETs of the box faces),
``.xdmf`` (with its ``.h5``) and ``.vtu`` go through meshio, with the cell data ``phase``
(:data:`~granpack.mesh._gmsh.PHASES`) and ``grain`` (grain index, -1 outside the aggregate).
"""

from __future__ import annotations

import json
import math
import os
import secrets
import shutil
from pathlib import Path

import numpy as np

from granpack.errors import InputError
from granpack.mesh._gmsh import PHASES, VolumeMesh, build_mesh, require_gmsh
from granpack.mesh.region import MeshOptions, MeshPlan, plan_mesh
from granpack.packing import Packing

__all__ = ["SUFFIXES", "TOLERANCE", "MEAN_GAMMA", "check_suffix", "require_gmsh", "mesh_packing", "tetra_volumes", "mesh_report", "write_mesh"]

#: the mesh formats, by file suffix
SUFFIXES = {".msh": "gmsh", ".inp": "abaqus", ".xdmf": "xdmf", ".vtu": "vtu"}
#: relative tolerance of the checks in the report (aggregate fraction, each grain's volume)
TOLERANCE = 0.005
#: the mean quality the report checks for: gmsh's gamma averaged over the tetrahedra (1: all regular)
MEAN_GAMMA = 0.3


def check_suffix(path: Path) -> str:
    """The meshio format name of ``path``'s suffix, once it is known that it can be written there.

    Raises:
        InputError: an unknown suffix (naming the allowed ones), ``.xdmf`` without h5py, or a report
            ``path.json`` that would replace a file which is not a mesh report.
    """
    fmt = SUFFIXES.get(path.suffix.lower())
    if fmt is None:
        raise InputError(f"--out {path}: unknown suffix {path.suffix or '(none)'!r}; one of {', '.join(SUFFIXES)}")
    if fmt == "xdmf":
        try:
            import h5py  # noqa: F401
        except ImportError:
            raise InputError(f'--out {path}: XDMF needs h5py (in the mesh extra): pip install "granpack[mesh]"') from None
    report = path.with_suffix(".json")
    if report.exists():
        try:
            earlier = json.loads(report.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            earlier = None
        if not (isinstance(earlier, dict) and {"file", "aggregate_fraction", "checks"} <= set(earlier)):
            raise InputError(f"--out {path}: its report would replace {report}, which is not a mesh report; "
                             f"choose another name")
    return fmt


def mesh_packing(packing: Packing, options: MeshOptions, msh_path: Path | None = None) -> tuple[MeshPlan, VolumeMesh]:
    """Plan and mesh ``packing``; with ``msh_path`` gmsh writes its own file there too."""
    require_gmsh()
    plan = plan_mesh(packing, options)
    return plan, build_mesh(plan, msh_path=msh_path)


def tetra_volumes(points: np.ndarray, tetra: np.ndarray) -> np.ndarray:
    """``(T,)`` signed volumes ``((b - a) x (c - a)) . (d - a) / 6`` of the tetrahedra, d^3 (> 0: positively oriented)."""
    a, b, c, d = (points[tetra[:, k]] for k in range(4))
    return np.einsum("ij,ij->i", np.cross(b - a, c - a), d - a) / 6.0


def _number(value: float) -> float | None:
    return None if not math.isfinite(value) else float(value)


def mesh_report(plan: MeshPlan, mesh: VolumeMesh) -> dict:
    """What the mesh holds and how well it matches the packing (lengths in d, volumes in d^3).

    ``aggregate_fraction``: ``exact`` is the shrunk grains' volume in the box over the box's (exact
    slicing, full-width boxes only), ``meshed`` the aggregate tetrahedra's, ``relative_error``
    ``meshed / exact - 1``; ``before_shrink`` the packing's own. ``grain_volume_error``: the largest
    ``|meshed - exact| / V`` over the grains, ``V`` the whole shrunk grain's volume (full width: every
    grain in the box, cut or not, so a cap the box cuts off is held to its grain's accuracy, not to a
    relative one its few facets cannot reach; otherwise the grains wholly inside). ``checks``: each within :data:`TOLERANCE`, no tetrahedron of volume <= 0 (nor SICN <= 0), a mean gamma of
    at least :data:`MEAN_GAMMA`.
    """
    volume = tetra_volumes(mesh.points, mesh.tetra)
    by_phase = {name: float(volume[mesh.phase == code].sum()) for name, code in PHASES.items()}
    meshed_fraction = by_phase["aggregate"] / plan.volume
    n = len(plan.grain_volume)
    meshed_grain = np.bincount(mesh.grain[mesh.grain >= 0], weights=volume[mesh.grain >= 0], minlength=n)
    whole = np.zeros(n)
    whole[plan.instances.grain] = plan.shapes.volume[plan.instances.kind]
    known = np.isfinite(plan.grain_volume) & (plan.grain_volume > 0)
    grain_error = float(np.max(np.abs(meshed_grain[known] - plan.grain_volume[known]) / whole[known], initial=0.0))
    fraction_error = meshed_fraction / plan.solid_fraction - 1.0 if math.isfinite(plan.solid_fraction) else math.nan
    periodic_mismatch = math.nan
    if len(mesh.periodic):
        gap = mesh.points[mesh.periodic[:, 0]] - mesh.points[mesh.periodic[:, 1]]
        width = np.array(plan.box[3:5]) - np.array(plan.box[:2])
        gap[:, :2] = np.abs(gap[:, :2])
        moved = np.isclose(gap[:, 0], width[0], rtol=1e-6)
        gap[moved, 0] = 0.0
        gap[~moved, 1] -= width[1]
        periodic_mismatch = float(np.abs(gap).max())
    used = np.unique(plan.instances.kind)
    return {
        "length_unit": "d, the largest grain's circumscribed diameter",
        "box": list(plan.box),
        "full_width": plan.full_width,
        "periodic": plan.options.periodic,
        "element_size": plan.size,
        "curvature_segments": plan.options.curvature,
        "shrink": {
            "gap": plan.gap,
            "scale_min": float(plan.scale[used].min()),
            "scale_max": float(plan.scale[used].max()),
            "max_overlap": plan.max_overlap,
            "min_clearance": plan.min_clearance,
        },
        "itz": {"thickness": plan.options.itz, "max_thickness_ratio": plan.itz_ratio},
        "aggregate_fraction": {
            "before_shrink": _number(plan.solid_fraction_unshrunk),
            "exact": _number(plan.solid_fraction),
            "meshed": meshed_fraction,
            "relative_error": _number(fraction_error),
        },
        "grain_volume_error": grain_error,
        "grains": int(np.count_nonzero(meshed_grain > 0)),
        "volumes": {"box": plan.volume, **by_phase},
        "nodes": int(len(mesh.points)),
        "elements": {"tetra": int(len(mesh.tetra)), **{name: int(np.count_nonzero(mesh.phase == code)) for name, code in PHASES.items()}},
        "quality": {"min_sicn": float(mesh.sicn.min()), "mean_sicn": float(mesh.sicn.mean()),
                    "min_gamma": float(mesh.gamma.min()), "mean_gamma": float(mesh.gamma.mean())},
        "periodic_pairs": int(len(mesh.periodic)),
        "periodic_mismatch": _number(periodic_mismatch),
        "checks": {
            "aggregate_fraction": bool(abs(fraction_error) <= TOLERANCE) if math.isfinite(fraction_error) else None,
            "grain_volumes": bool(grain_error <= TOLERANCE),
            "positive_volumes": bool(volume.min() > 0 and mesh.sicn.min() > 0),
            "mean_quality": bool(mesh.gamma.mean() >= MEAN_GAMMA),
        },
        "seconds": mesh.timings,
    }


def _meshio_mesh(plan: MeshPlan, mesh: VolumeMesh, fmt: str):
    """The mesh for meshio: cell data ``phase`` and ``grain``; for Abaqus the element and node sets."""
    import meshio

    cell_data = {"phase": [mesh.phase.astype(np.int32)], "grain": [mesh.grain.astype(np.int32)]}
    if fmt != "abaqus":
        return meshio.Mesh(mesh.points, [("tetra", mesh.tetra)], cell_data=cell_data)

    cell_sets = {name: [np.flatnonzero(mesh.phase == code)] for name, code in PHASES.items()
                 if np.any(mesh.phase == code)}
    if plan.options.grain_groups:
        order = np.argsort(mesh.grain, kind="stable")
        grains, first = np.unique(mesh.grain[order], return_index=True)
        for g, members in zip(grains, np.split(order, first[1:])):
            if g >= 0:
                cell_sets[f"grain_{g}"] = [np.sort(members)]
    point_sets = {name: np.unique(faces) for name, faces in mesh.faces.items()}
    return meshio.Mesh(mesh.points, [("tetra", mesh.tetra)], cell_sets=cell_sets, point_sets=point_sets)


def write_mesh(path: str | os.PathLike, packing: Packing, options: MeshOptions) -> tuple[list[Path], dict]:
    """Mesh ``packing`` and write ``path`` (its suffix one of :data:`SUFFIXES`) and ``path.json``.

    The files are made in a temporary folder beside ``path`` and moved in place only when all are
    complete: on any error nothing is left (an existing file of the same name stays as it was).

    Returns:
        ``(paths written, the report)``.

    Raises:
        InputError: an unknown suffix, a bad option (:func:`~granpack.mesh.region.plan_mesh`) or no gmsh.
    """
    path = Path(path)
    fmt = check_suffix(path)
    require_gmsh()
    report_path = path.with_suffix(".json")
    stage = path.parent / f".{path.stem}.{secrets.token_hex(4)}.tmp"
    stage.mkdir()
    try:
        staged = stage / path.name
        plan, mesh = mesh_packing(packing, options, msh_path=staged if fmt == "gmsh" else None)
        if fmt != "gmsh":
            _meshio_mesh(plan, mesh, fmt).write(staged, file_format=fmt)
        report = mesh_report(plan, mesh)
        report["file"] = path.name
        (stage / report_path.name).write_text(json.dumps(report, indent=2) + "\n", encoding="utf-8")
        written = sorted(stage.iterdir(), key=lambda p: p == staged)  # the mesh file last: its companions first
        for item in written:
            os.replace(item, path.parent / item.name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return [path.parent / item.name for item in written], report
