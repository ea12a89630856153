"""The demo's figures that README.md and docs/getting-started.md quote, taken from a demo run.

    granpack demo --out DIR                  # on one thread: NUMBA_NUM_THREADS=1
    python benchmarks/demo_figures.py DIR    # writes benchmarks/demo.json, fills in the two pages

Each figure on those pages stands between markers, ``<!-- demo:KEY -->VALUE<!-- /demo -->``, so
that no one types it: this script writes the values of :func:`figures` there, and
tests/test_docs.py holds the pages to benchmarks/demo.json and its cap to the packaged demo
config. Prints the figures as JSON.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "benchmarks" / "demo.json"
PAGES = (ROOT / "README.md", ROOT / "docs" / "getting-started.md")
MARKER = re.compile(r"<!-- demo:(\w+) -->(.*?)<!-- /demo -->")


def figures(run_dir: Path) -> dict[str, str]:
    """The quoted figures of a finished, analysed demo run, as the pages print them: ``max_time``
    (the config's cap, sqrt(d/g)), ``rest_time`` (when it was certified at rest, or stopped),
    ``status``, ``phi`` (bulk solid fraction), ``Nc`` (contacts per grain of the force network),
    ``cpu_seconds`` (the whole run, pour included)."""
    import tomllib

    config = tomllib.loads((run_dir / "config.toml").read_text(encoding="utf-8"))
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    analysis = json.loads((run_dir / "analysis.json").read_text(encoding="utf-8"))
    return {
        "max_time": f"{config['equilibrium']['max_time']:g}",
        "rest_time": f"{summary['simulated_time']:.1f}",
        "status": "certified at rest" if summary["status"] == "equilibrium" else "not at rest",
        "phi": f"{analysis['solid_fraction']['bulk']:.3f}",
        "Nc": f"{analysis['coordination']['Nc']:.1f}",
        "cpu_seconds": f"{summary['cpu_time']:.0f}",
    }


def fill(text: str, values: dict[str, str]) -> str:
    """``text`` with every marked figure replaced by its value (KeyError for an unknown key)."""
    return MARKER.sub(lambda m: f"<!-- demo:{m.group(1)} -->{values[m.group(1)]}<!-- /demo -->", text)


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python benchmarks/demo_figures.py DEMO_RUN_DIR", file=sys.stderr)
        return 2
    values = figures(Path(argv[0]))
    RECORD.write_text(json.dumps(values, indent=2) + "\n", encoding="utf-8")
    for page in PAGES:
        page.write_text(fill(page.read_text(encoding="utf-8"), values), encoding="utf-8")
    print(json.dumps(values))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
