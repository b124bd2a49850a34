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


def gpu() -> str | None:
    """The lent-GPU results: MPC rates (gpu_rates.json), metric, render, encoder and FK throughput on CUDA."""
    p = RESULTS / "gpu_rates.json"
    if not p.exists():
        return None
    r = json.loads(p.read_text())
    md = (RESULTS / "gpu_rates.md").read_text().strip() if (RESULTS / "gpu_rates.md").exists() else ""
    lines = [md]
    if r.get("changes_since"):
        lines += ["", "Changed since these GPU measurements, not yet measured on a GPU:", ""] + [f"- {c}" for c in r["changes_since"]]
    b = r.get("before_this_change")
    if b:
        lines += ["", f"Before the GPU work of this round ({b['note'].split('(')[-1].rstrip(')')}): Panda MPPI {b['panda_K256_steps_per_s']:.1f} steps/s at K = 256 and "
                  f"{b['panda_K1024_steps_per_s']:.1f} at K = 1024 (collision cost {b['panda_K1024_collision_ms']:.0f} ms, goal-pose FK on the host {b['panda_K1024_goal_ms']:.0f} ms per step)."]  # fmt: skip
    pr = r.get("pruned_run")
    if pr:
        a, b = pr["pruned"], pr["unpruned"]
        lines += ["", f"Pruned MPPI (`prune_margin` = {a['prune_margin']:g}) on the GPU, K = {a['K']}, a later lease: {a['steps_per_s']:.1f} MPC steps/s against "
                      f"{b['steps_per_s']:.1f} unpruned back to back ({a['pruned_samples_per_step']:.0f} of {a['K']} samples pruned per step)."]  # fmt: skip
    q = {p_["K"]: p_.get("query_only_s", {}) for p_ in r.get("panda", [])}
    if q:
        lanes = sorted({int(k.split("_")[1]) for v in q.values() for k in v if k.startswith("lanes_") and k != "lanes_default"})
        lines += ["", "Panda collision query alone (moving ellipsoids, q on the device), ms, by threads per query (`TierConfig.lanes`; default 8 on CUDA):", "",
                  "| configurations | " + " | ".join(f"lanes {n}" for n in lanes) + " |", "|---|" + "---|" * len(lanes)]  # fmt: skip
        for k, v in q.items():
            lines.append(f"| {k * 32:,} (K = {k}) | " + " | ".join(f"{1e3 * v.get(f'lanes_{n}', float('nan')):.1f}" for n in lanes) + " |")
    t = r.get("tune")
    if t:
        cf = lambda x: x.get("elongated_cell_factor", x.get("slab_cell_factor"))  # noqa: E731 (the field's name before the slabs went)
        fs = sorted({cf(x) for x in t["rows"]})
        ls = sorted({x["lanes"] for x in t["rows"]})
        lines += ["", f"Grid cell width for elongated links (`elongated_cell_factor`) x lanes, Panda query alone, ms ({t['rows'][0]['configs']:,} configurations):", "",
                  "| elongated_cell_factor | " + " | ".join(f"lanes {n}" for n in ls) + " |", "|---|" + "---|" * len(ls)]  # fmt: skip
        for g in sorted({bool(x.get("group_links", False)) for x in t["rows"]}):
            for f in fs:
                cell = {x["lanes"]: x["seconds"] for x in t["rows"] if cf(x) == f and bool(x.get("group_links", False)) == g}
                if cell:
                    lines.append(f"| {f}{', group_links' if g else ''} | " + " | ".join(f"{1e3 * cell[n]:.1f}" if n in cell else "-" for n in ls) + " |")
    mt = RESULTS / "metric_throughput_cuda.json"
    if mt.exists():
        m = json.loads(mt.read_text())
        lines += ["", f"Metric throughput on {m['device']} ({m['n_splats']:,} splats, sphere r = {m['radius']}, n_sigma = {m['n_sigma']}):", "",
                  "| variant | batch | checks/s, numpy inputs | checks/s, device inputs + workspace |", "|---|---|---|---|"]  # fmt: skip
        dev = {(x["method"], x["batch"]): x["checks_per_s"] for x in m.get("device_rows", [])}
        for x in m["rows"]:
            lines.append(f"| {x['method']} | {x['batch']:,} | {x['checks_per_s']:,.0f} | {dev.get((x['method'], x['batch']), float('nan')):,.0f} |")
    rd = RESULTS / "render_cuda.json"
    if rd.exists():
        rr = json.loads(rd.read_text())
        lines += ["", "Rendering on CUDA (batch of 32 views, Stonehenge 200k splats):", "", "| backend | size | images/s |", "|---|---|---|"]
        lines += [f"| {x['backend']} | {x['size']}x{x['size']} | {x['images_per_s']:,.0f} |" for x in rr["rows"]]
    ec = RESULTS / "encoders_cuda.json"
    if ec.exists():
        e = json.loads(ec.read_text())
        lines += ["", f"Encoders on CUDA (batch {e['batch']}, {e['size']}x{e['size']} inputs):", "", "| encoder | images/s |", "|---|---|"]
        lines += [f"| {x['encoder']} | {x['images_per_s']:,.0f} |" for x in e["rows"]]
    fk = RESULTS / "robots_fk_cuda.json"
    if fk.exists():
        f_ = json.loads(fk.read_text())
        lines += ["", f"Forward kinematics ({f_['robot']}, {f_['n_ellipsoids']} ellipsoids):", "", "| method | device | batch | configurations/s |", "|---|---|---|---|"]
        lines += [f"| {x['method']} | {x['device']} | {x['batch']:,} | {x['configs_per_s']:,.0f} |" for x in f_["rows"]]
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
    "gpu": gpu,
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
    "reach_behind_wall": markdown_file("reach_behind_wall.md"),
    "reach_goal_filters": markdown_file("reach_goal_filters.md"),
    "navigate": markdown_file("navigate.md"),
    "mbm_speed_ns0": markdown_file("mbm_speed/ns0.md"),
    "mbm_speed_ns1": markdown_file("mbm_speed/ns1.md"),
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
