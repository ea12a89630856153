"""The pictures of the docs' home page (docs/index.md), rendered by granpack from three small runs.

    NUMBA_NUM_THREADS=1 python benchmarks/home_pictures.py WORKDIR [NAME ...]

For each picture (all three, or the NAMEs given: pinacoids, rocks, scans), one after the other:
``granpack run CONFIG --out WORKDIR/NAME`` (skipped when the run folder already holds its
``final.gsd``; a killed run is resumed), then ``granpack export WORKDIR/NAME --format png``, whose
``packing.png`` is copied to ``docs/images/NAME.png``. The scans' library is written first by
``examples/pictures/make_scans.py`` when missing. Prints each run's status, simulated time, CPU
seconds and the picture's size (a picture over 300 kB is stored in 256 colours).

Configs: ``examples/demo.toml`` (the demo: 300 isometric pinacoids), ``examples/pictures/rocks.toml``
(300 generated rocks), ``examples/pictures/scans.toml`` (300 scan-like grains, 20 mesh files). On
one thread each run takes some 5 to 15 CPU minutes.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IMAGES = ROOT / "docs" / "images"
PICTURES = {
    "pinacoids": ROOT / "examples" / "demo.toml",
    "rocks": ROOT / "examples" / "pictures" / "rocks.toml",
    "scans": ROOT / "examples" / "pictures" / "scans.toml",
}
#: the largest picture kept in the docs, bytes
MAX_BYTES = 300_000


def granpack(*args: str) -> None:
    """Run the ``granpack`` command of this interpreter's environment (raises on failure)."""
    subprocess.run([sys.executable, "-m", "granpack", *args], check=True)


def make_picture(name: str, workdir: Path) -> dict:
    """Run (or resume) the picture's packing, render it and copy it into docs/images; a summary."""
    config = PICTURES[name]
    run = workdir / name
    if name == "scans" and not any((config.parent / "scans").glob("*.stl")):
        subprocess.run([sys.executable, str(config.parent / "make_scans.py")], check=True)
    if not (run / "final.gsd").is_file():
        granpack("run", str(config), "--out", str(run), *(["--resume"] if (run / "checkpoint.gsd").is_file() else []))
    granpack("export", str(run), "--format", "png")
    IMAGES.mkdir(parents=True, exist_ok=True)
    picture = IMAGES / f"{name}.png"
    shutil.copyfile(run / "packing.png", picture)
    summary = json.loads((run / "summary.json").read_text(encoding="utf-8"))
    if picture.stat().st_size > MAX_BYTES:  # 256 colours lose little of the flat-shaded faces
        from PIL import Image

        with Image.open(run / "packing.png") as image:
            image.convert("RGB").quantize(colors=256).save(picture, optimize=True)
    size = picture.stat().st_size
    return {"picture": str(picture.relative_to(ROOT)), "bytes": size, "config": str(config.relative_to(ROOT)),
            "status": summary["status"], "simulated_time": summary["simulated_time"],
            "cpu_seconds": round(summary["cpu_time"])}


def main(argv: list[str]) -> int:
    if not argv or any(name not in PICTURES for name in argv[1:]):
        print(f"usage: python benchmarks/home_pictures.py WORKDIR [{' | '.join(PICTURES)} ...]", file=sys.stderr)
        return 2
    workdir = Path(argv[0])
    for name in argv[1:] or list(PICTURES):
        print(json.dumps({name: make_picture(name, workdir)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
