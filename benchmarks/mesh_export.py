"""Benchmark of ``granpack export --format stl`` and ``granpack mesh`` on a settled packing.

Prints one JSON document: the packing (grains, shapes), the seconds to write every grain's surface
(STL, with periodic images), and for the volume mesh of the default region (the cell's full width
over the bulk's height, periodic images filling it) the seconds of each stage (plan, geometry,
fragment, mesh, write), the grains and elements in the box, the element quality, the aggregate
fraction against its exact value and the peak resident memory of the process (gmsh included).

Packing: ``RUN_DIR/final.gsd`` of a finished run, e.g. the demo's (300 isometric pinacoids,
``granpack run src/granpack/data/demo.toml --out RUN_DIR``, a few minutes). Needs the mesh extra.

Usage::

    python benchmarks/mesh_export.py RUN_DIR [--out FOLDER] [--periodic] [--size-factor F] [--curvature N] [--itz T] [--tile K] [--no-surfaces] [--box X0 Y0 Z0 X1 Y1 Z1] [--picture PNG]

``RUN_DIR`` is any run folder with a ``final.gsd`` (copy it out of a campaign's folder first: the
files of ``--out`` go where it says, nothing into ``RUN_DIR``). The JSON also gives the process's CPU
seconds (user + system, gmsh's threads included) beside the wall seconds, and the load average
before and after: on a shared machine the wall seconds are upper bounds.

``--tile K`` meshes the packing repeated K x K times across its periodic cell (a packing at rest
too, K^2 times the grains, the same overlaps), for the cost of larger boxes without a longer run.
``--picture`` draws the box's bottom face, a plane cut through the packing, with its triangles
coloured by the phase of the tetrahedron they bound (the how-to's figure).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import tempfile
import time
from pathlib import Path

from granpack.io.gsd import read_packing
from granpack.mesh.region import MeshOptions
from granpack.mesh.surfaces import write_surfaces
from granpack.mesh.volume import write_mesh


def tiled(packing, k: int):
    """``packing`` repeated ``k x k`` times across its periodic cell (its contact list kept: the
    meshing reads only its largest overlap, the same in the copies)."""
    import numpy as np

    from granpack.box import Box
    from granpack.packing import Packing
    from granpack.state import ParticleState

    s = packing.state
    lx, ly = packing.box.lx, packing.box.ly
    shifts = np.array([(i * lx, j * ly, 0.0) for i in range(k) for j in range(k)])
    position = (s.position[None, :, :] + shifts[:, None, :]).reshape(-1, 3)
    state = ParticleState(box=Box(k * lx, k * ly), shapes=s.shapes, kind=np.tile(s.kind, k * k),
                          population=np.tile(s.population, k * k), position=position,
                          quaternion=np.tile(s.quaternion, (k * k, 1)))
    return Packing(state, packing.contacts, packing.time_step, packing.population_names, packing.metadata)


def draw_cut(mesh_path: Path, picture: Path) -> None:
    """The triangles of the ``zmin`` face of the mesh in ``mesh_path`` (.msh), by phase, to ``picture``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import meshio
    import numpy as np
    from matplotlib.colors import ListedColormap

    mesh = meshio.read(mesh_path)
    tetra = mesh.get_cells_type("tetra")
    phase = mesh.get_cell_data("gmsh:physical", "tetra")
    triangles = mesh.get_cells_type("triangle")
    tri_group = mesh.get_cell_data("gmsh:physical", "triangle")
    zmin = mesh.field_data["zmin"][0]
    bottom = triangles[tri_group == zmin]
    # the phase of each bottom triangle: that of the one tetrahedron it bounds
    faces = np.sort(tetra[:, [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]]].reshape(-1, 3), axis=1)
    owner = np.repeat(np.arange(len(tetra)), 4)
    keys = {tuple(f): o for f, o in zip(faces.tolist(), owner.tolist())}
    colour = np.array([phase[keys[tuple(f)]] for f in np.sort(bottom, axis=1).tolist()])
    fig, ax = plt.subplots(figsize=(5, 5), dpi=150)
    ax.tripcolor(mesh.points[:, 0], mesh.points[:, 1], bottom, facecolors=colour, edgecolors="k", linewidth=0.1,
                 cmap=ListedColormap(["#8c8c8c", "#e8d9b0", "#c0504d"]), vmin=0.5, vmax=3.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x (d)")
    ax.set_ylabel("y (d)")
    ax.set_title(f"cut at z = {mesh.points[bottom[0, 0], 2]:.2f} d: aggregate grey, matrix light, ITZ red", fontsize=9)
    fig.tight_layout()
    fig.savefig(picture)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--out", type=Path, default=None, help="folder for the files (default: a temporary one)")
    parser.add_argument("--periodic", action="store_true")
    parser.add_argument("--size-factor", type=float, default=0.2)
    parser.add_argument("--curvature", type=int, default=None, help="elements per turn on spheres (default: the mesher's)")
    parser.add_argument("--itz", type=float, default=0.0)
    parser.add_argument("--picture", type=Path, default=None)
    parser.add_argument("--tile", type=int, default=1)
    parser.add_argument("--no-surfaces", action="store_true", help="skip the STL of every grain (minutes for thousands of spheres on a busy machine)")
    parser.add_argument("--box", type=float, nargs=6, default=None, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"))
    args = parser.parse_args()
    load_before = os.getloadavg()
    packing = read_packing(args.run_dir / "final.gsd")
    if args.tile > 1:
        packing = tiled(packing, args.tile)
    with tempfile.TemporaryDirectory() as scratch:
        out = args.out or Path(scratch)
        out.mkdir(parents=True, exist_ok=True)
        bodies, surfaces = None, None
        if not args.no_surfaces:
            start = time.perf_counter()
            _, bodies = write_surfaces(packing, out / "grains.stl", "stl", images=True)
            surfaces = round(time.perf_counter() - start, 2)
        start = time.perf_counter()
        box = tuple(args.box) if args.box else None
        extra = {} if args.curvature is None else {"curvature": args.curvature}
        options = MeshOptions(box=box, periodic=args.periodic, size_factor=args.size_factor, itz=args.itz, **extra)
        cpu_start = resource.getrusage(resource.RUSAGE_SELF)
        _, report = write_mesh(out / "mesh.msh", packing, options)
        total = time.perf_counter() - start
        cpu_end = resource.getrusage(resource.RUSAGE_SELF)
        cpu = (cpu_end.ru_utime - cpu_start.ru_utime) + (cpu_end.ru_stime - cpu_start.ru_stime)
        if args.picture:
            draw_cut(out / "mesh.msh", args.picture)
    print(json.dumps({
        "machine": f"{platform.node()} {platform.processor() or platform.machine()}",
        "grains": packing.state.n,
        "shapes": sorted({type(s).__name__ for s in packing.state.shapes.shapes}),
        "surfaces": {"bodies": bodies, "seconds": surfaces},
        "mesh": {
            "seconds": round(total, 2),
            "cpu_seconds": round(cpu, 2),
            "load_average": {"before": [round(v, 2) for v in load_before], "after": [round(v, 2) for v in os.getloadavg()]},
            "size_factor": args.size_factor,
            "curvature": options.curvature,
            "stages": {k: round(v, 2) for k, v in report["seconds"].items()},
            "box": [round(v, 4) for v in report["box"]],
            "periodic": args.periodic,
            "itz": args.itz,
            "grains_in_box": report["grains"],
            "nodes": report["nodes"],
            "elements": report["elements"],
            "quality": {k: round(v, 4) for k, v in report["quality"].items()},
            "aggregate_fraction": report["aggregate_fraction"],
            "grain_volume_error": report["grain_volume_error"],
            "checks": report["checks"],
            "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024),
        },
    }, indent=2))


if __name__ == "__main__":
    main()
