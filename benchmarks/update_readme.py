"""Refresh the README's result tables from benchmarks/results/ (JSON and markdown written by the studies).

Each table lives between ``<!-- BEGIN:name -->`` and ``<!-- END:name -->`` markers in README.md;
a section whose result file is missing is left as it is.

    python benchmarks/update_readme.py
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


def metric_throughput() -> str | None:
    p = RESULTS / "metric_throughput.json"
    if not p.exists():
        return None
    from metric_throughput import PAPER  # type: ignore

    r = json.loads(p.read_text())
    lines = [
        f"Device: {r['device']} ({r['threads']} threads, {r['cpu']}); {r['n_splats']:,} splats; sphere r = {r['radius']}, n_sigma = {r['n_sigma']}.",
        "",
        "| variant | batch | checks/s (ours, this machine) | extra peak memory (MB) | paper CPU checks/s (16 cores) | paper GPU checks/s | paper GPU memory (GB) |",
        "|---|---|---|---|---|---|---|",
    ]
    for row in r["rows"]:
        g, c, m = PAPER.get(row["batch"], (float("nan"),) * 3)
        lines.append(
            f"| {row['method']} | {row['batch']:,} | {row['checks_per_s']:,.0f} | {row['peak_mem_mb']:.1f} | {c:,.1f} | {g:,.1f} | {m} |"
        )
    return "\n".join(lines)


def markdown_file(name: str):
    def read() -> str | None:
        p = RESULTS / name
        if not p.exists():
            return None
        lines = p.read_text().strip().splitlines()
        if lines and lines[0].startswith("# "):  # the README gives each study its own heading
            lines = lines[1:]
        return "\n".join(lines).strip()

    return read


SECTIONS = {
    "metric_throughput": metric_throughput,
    "pr": markdown_file("pr.md"),
    "throughput": markdown_file("throughput.md"),
    "conservatism": markdown_file("conservatism.md"),
    "linearization": markdown_file("linearization.md"),
    "planners": markdown_file("planners.md"),
    "encoders": markdown_file("encoders.md"),
    "scene_load": markdown_file("scene_load.md"),
    "arm": markdown_file("arm.md"),
    "base": markdown_file("base.md"),
    "reach": markdown_file("reach.md"),
    "navigate": markdown_file("navigate.md"),
}


def main() -> int:
    sys.path.insert(0, str(Path(__file__).parent))
    readme = ROOT / "README.md"
    text = readme.read_text()
    for name, fn in SECTIONS.items():
        body = fn()
        if body is None:
            continue
        pat = re.compile(rf"(<!-- BEGIN:{name} -->\n).*?(\n<!-- END:{name} -->)", re.S)
        if not pat.search(text):
            print(f"README has no section {name}; skipped")
            continue
        text = pat.sub(lambda m: m.group(1) + body + m.group(2), text)
        print(f"updated {name}")
    readme.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
