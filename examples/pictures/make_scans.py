"""Write 20 scan-like grains into scans/ beside this file: noisy tessellated ellipsoids, 642
vertices each, about 10 mm long (the lines of docs/how-to/scanned-aggregate.md), for scans.toml.

    python examples/pictures/make_scans.py
"""

from pathlib import Path

import numpy as np
import trimesh

SCANS = Path(__file__).resolve().parent / "scans"


def main(folder: Path = SCANS) -> Path:
    """Write the 20 grains into ``folder`` (created); returns it."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    for k in range(20):
        mesh = trimesh.creation.icosphere(3)
        axes = 10.0 * np.array([1.0, rng.uniform(0.55, 0.9), rng.uniform(0.35, 0.6)])  # mm
        noise = 1.0 + 0.03 * rng.standard_normal((len(mesh.vertices), 1))
        trimesh.Trimesh(mesh.vertices * axes * noise, mesh.faces).export(folder / f"grain-{k:02d}.stl")
    return folder


if __name__ == "__main__":
    print(f"wrote 20 scan-like grains in {main()}")
