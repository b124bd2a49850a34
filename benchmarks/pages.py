"""The benchmark tables of the documentation site, built from benchmarks/results/ (one number, one place).

The studies and benchmark scripts write JSON and markdown under ``benchmarks/results/``; the site's
benchmark pages (``docs/benchmarks/*.md``) hold a line ``<!-- results: NAME -->`` where the table
NAME goes, and the MkDocs hook (``docs/hooks/generate.py``) replaces it with :func:`section`. Each
table comes with the machine and the date it was measured on: the result's own fields where it
records them, else the date of the commit that last changed the result file. The MotionBenchMaker
plot (:func:`mbm_plot`) is drawn from ``results/mbm_speed/*.json`` with matplotlib.

    python benchmarks/pages.py            # lists the sections and whether their results exist
    python benchmarks/pages.py pr         # prints one section
    python benchmarks/pages.py --readme   # regenerates the README's headline table (make bench runs it)
"""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"


# ------------------------------------------------------------------------------------ provenance
def _git_date(path: Path) -> str | None:
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%cs", "--", str(path)], cwd=ROOT, capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip() or None


def _machine(d: dict) -> str | None:
    m = d.get("machine")
    if isinstance(m, dict):
        cores = m.get("cores", m.get("cpus"))
        plat = str(m.get("platform", "")).split("-with-")[0]
        return ", ".join(x for x in (plat, f"{cores} cores" if cores else "") if x)
    if isinstance(m, str):
        return m
    dev = d.get("device_name") or d.get("device")
    cpu = d.get("cpu") or d.get("platform")
    threads = d.get("threads") or d.get("cpu_threads") or d.get("torch_threads") or d.get("cores") or d.get("cpu_count")
    parts = [str(x) for x in (dev, cpu, f"{threads} threads" if threads else None) if x]
    return ", ".join(parts) or None


def provenance(json_path: Path) -> str:
    """One line: where a result comes from, on which machine and when."""
    rel = json_path.relative_to(ROOT)
    d = {}
    if json_path.suffix == ".json" and json_path.exists():
        try:
            d = json.loads(json_path.read_text())
        except ValueError:
            d = {}
    date = d.get("date") or d.get("date_utc") or d.get("when") if isinstance(d, dict) else None
    date = str(date)[:10] if date else _git_date(json_path)
    machine = _machine(d) if isinstance(d, dict) else None
    return f"*Measured on: {machine or 'machine not recorded in the result'}; {date or 'date not recorded'}. Source: `{rel}`.*"


# ------------------------------------------------------------------------------------ sections
def _strip_title(text: str) -> str:
    lines = text.strip().splitlines()
    if lines and lines[0].startswith("# "):  # the page gives each study its own heading
        lines = lines[1:]
    return "\n".join(lines).strip()


def markdown_file(name: str, json_name: str | None = None):
    """A section that is a study's own markdown, with the provenance of its JSON."""

    def read() -> str | None:
        p = RESULTS / name
        if not p.exists():
            return None
        j = RESULTS / (json_name or name.rsplit(".", 1)[0] + ".json")
        return _strip_title(p.read_text()) + "\n\n" + provenance(j if j.exists() else p)

    return read


def metric_throughput(name: str = "metric_throughput.json"):
    def read() -> str | None:
        p = RESULTS / name
        if not p.exists():
            return None
        sys.path.insert(0, str(Path(__file__).parent))
        from metric_throughput import PAPER  # type: ignore

        r = json.loads(p.read_text())
        lines = [
            f"{r['n_splats']:,} splats; sphere r = {r['radius']}, n_sigma = {r['n_sigma']}. The paper's columns are its published figures (16-core CPU; GPU).",
            "",
            "| variant | batch | checks/s (ours) | extra peak memory (MB) | paper CPU checks/s | paper GPU checks/s | paper GPU memory (GB) |",
            "|---|---|---|---|---|---|---|",
        ]
        for row in r["rows"]:
            g, c, m = PAPER.get(row["batch"], (float("nan"),) * 3)
            mem = f"{row['peak_mem_mb']:.1f}" if "peak_mem_mb" in row else "-"
            lines.append(f"| {row['method']} | {row['batch']:,} | {row['checks_per_s']:,.0f} | {mem} | {c:,.1f} | {g:,.1f} | {m} |")
        dev = {(x["method"], x["batch"]): x["checks_per_s"] for x in r.get("device_rows", [])}
        if dev:
            lines += ["", "| variant | batch | checks/s, numpy inputs | checks/s, device inputs + workspace |", "|---|---|---|---|"]
            for x in r["rows"]:
                lines.append(f"| {x['method']} | {x['batch']:,} | {x['checks_per_s']:,.0f} | {dev.get((x['method'], x['batch']), float('nan')):,.0f} |")
        return "\n".join(lines) + "\n\n" + provenance(p)

    return read


def gpu() -> str | None:
    """The GPU results: MPC rates, the lanes and cell-width tuning."""
    p = RESULTS / "gpu_rates.json"
    if not p.exists():
        return None
    r = json.loads(p.read_text())
    md = RESULTS / "gpu_rates.md"
    lines = [_strip_title(md.read_text())] if md.exists() else []
    pr = r.get("pruned_run")
    if pr:
        a, b = pr["pruned"], pr["unpruned"]
        lines += ["", f"Pruned MPPI (`prune_margin` = {a['prune_margin']:g}), K = {a['K']}: {a['steps_per_s']:.1f} MPC steps/s against "
                      f"{b['steps_per_s']:.1f} unpruned, back to back ({a['pruned_samples_per_step']:.0f} of {a['K']} samples pruned per step)."]  # fmt: skip
    q = {p_["K"]: p_.get("query_only_s", {}) for p_ in r.get("panda", [])}
    if q:
        lanes = sorted({int(k.split("_")[1]) for v in q.values() for k in v if k.startswith("lanes_") and k != "lanes_default"})
        lines += ["", "Panda collision query alone (moving ellipsoids, q on the device), ms, by threads per query (`TierConfig.lanes`):", "",
                  "| configurations | " + " | ".join(f"lanes {n}" for n in lanes) + " |", "|---|" + "---|" * len(lanes)]  # fmt: skip
        for k, v in q.items():
            lines.append(f"| {k * 32:,} (K = {k}) | " + " | ".join(f"{1e3 * v.get(f'lanes_{n}', float('nan')):.1f}" for n in lanes) + " |")
    t = r.get("tune")
    if t:
        cf = lambda x: x.get("elongated_cell_factor", x.get("slab_cell_factor"))  # noqa: E731 (older results name the field differently)
        fs = sorted({cf(x) for x in t["rows"]})
        ls = sorted({x["lanes"] for x in t["rows"]})
        lines += ["", f"Grid cell width for elongated links (`elongated_cell_factor`) x lanes, Panda query alone, ms ({t['rows'][0]['configs']:,} configurations):", "",
                  "| elongated_cell_factor | " + " | ".join(f"lanes {n}" for n in ls) + " |", "|---|" + "---|" * len(ls)]  # fmt: skip
        for g in sorted({bool(x.get("group_links", False)) for x in t["rows"]}):
            for f in fs:
                cell = {x["lanes"]: x["seconds"] for x in t["rows"] if cf(x) == f and bool(x.get("group_links", False)) == g}
                if cell:
                    lines.append(f"| {f}{', group_links' if g else ''} | " + " | ".join(f"{1e3 * cell[n]:.1f}" if n in cell else "-" for n in ls) + " |")
    return "\n".join(lines) + "\n\n" + provenance(p)


def render(name: str = "render.json"):
    def read() -> str | None:
        p = RESULTS / name
        if not p.exists():
            return None
        r = json.loads(p.read_text())
        lines = [f"Scene: {r['scene']}; cameras: {r['cameras']}.", "", "| backend | device | size | batch | images/s | CPU ms / image | target images/s |", "|---|---|---|---|---|---|---|"]
        for x in r["rows"]:
            cpu = f"{x['cpu_ms_per_image']:.1f}" if x.get("cpu_ms_per_image") is not None else "-"
            lines.append(f"| {x['backend']} | {x.get('device', '-')} | {x['size']}x{x['size']} | {x.get('batch', '-')} | {x['images_per_s']:,.1f} | {cpu} | {x.get('target_images_per_s', '-')} |")
        return "\n".join(lines) + "\n\n" + provenance(p)

    return read


def robots_fk(name: str = "robots_fk.json"):
    def read() -> str | None:
        p = RESULTS / name
        if not p.exists():
            return None
        r = json.loads(p.read_text())
        lines = [f"{r['robot']}, {r['dof']} dof, {r['n_ellipsoids']} ellipsoids.", "", "| method | device | batch | configurations/s |", "|---|---|---|---|"]
        lines += [f"| {x['method']} | {x['device']} | {x['batch']:,} | {x['configs_per_s']:,.0f} |" for x in r["rows"]]
        return "\n".join(lines) + "\n\n" + provenance(p)

    return read


def encoders_cuda() -> str | None:
    p = RESULTS / "encoders_cuda.json"
    if not p.exists():
        return None
    e = json.loads(p.read_text())
    lines = [f"Batch {e['batch']}, {e['size']}x{e['size']} inputs.", "", "| encoder | images/s |", "|---|---|"]
    lines += [f"| {x['encoder']} | {x['images_per_s']:,.0f} |" for x in e["rows"]]
    return "\n".join(lines) + "\n\n" + provenance(p)


def viewer() -> str | None:
    p = RESULTS / "viewer.json"
    if not p.exists():
        return None
    r = json.loads(p.read_text())
    lines = ["| measure | value | target |", "|---|---|---|"]
    for b in r["browser"]:
        what = f"{b['n_splats']:,} splats" + (f" (decimated, `--max-splats {b['max_splats']}`)" if b.get("max_splats") else "")
        lines.append(f"| page request -> client connected, {what} | {b['client_connected_s']:.1f} s | |")
        vis = f"{b['splats_visible_s']:.0f} s" if b.get("splats_visible_s") is not None else "no frame within the timeout"
        lines.append(f"| page request -> splats visible, {what} | {vis} | < 5 s |")
    for u in r["pose_update"]:
        lines.append(f"| pose update, {u['robot']} ({u['n_ellipsoids']} ellipsoids) on {u['scene']}, median / p90 | {u['median_ms']:.1f} / {u['p90_ms']:.1f} ms | < 100 ms |")
    return "\n".join(lines) + "\n\n" + provenance(p)


SECTIONS = {
    "metric_throughput": metric_throughput(),
    "metric_throughput_cuda": metric_throughput("metric_throughput_cuda.json"),
    "gpu": gpu,
    "render": render(),
    "render_cuda": render("render_cuda.json"),
    "robots_fk": robots_fk(),
    "robots_fk_cuda": robots_fk("robots_fk_cuda.json"),
    "encoders": markdown_file("encoders.md"),
    "encoders_cuda": encoders_cuda,
    "viewer": viewer,
    "pr": markdown_file("pr.md"),
    "pr_gap": markdown_file("pr_gap.md"),
    "throughput": markdown_file("throughput.md"),
    "conservatism": markdown_file("conservatism.md"),
    "linearization": markdown_file("linearization.md"),
    "planners": markdown_file("planners.md"),
    "scene_load": markdown_file("scene_load.md"),
    "arm": markdown_file("arm.md"),
    "base": markdown_file("base.md"),
    "reach": markdown_file("reach.md"),
    "reach_behind_wall": markdown_file("reach_behind_wall.md"),
    "reach_goal_filters": markdown_file("reach_goal_filters.md"),
    "reach_basin": markdown_file("reach_basin.md"),
    "navigate": markdown_file("navigate.md"),
    "gpu_arm": markdown_file("gpu_studies/arm.md"),
    "gpu_base": markdown_file("gpu_studies/base.md"),
    "gpu_reach": markdown_file("gpu_studies/reach.md"),
    "real_rooms": markdown_file("real_rooms.md"),
    "real_go2": markdown_file("real_go2.md"),
    "engine": markdown_file("engine.md"),
    "engine_mbm_default": markdown_file("engine_mbm_default.md"),
    "engine_mbm_100k": markdown_file("engine_mbm_100k.md"),
    "mbm_default": markdown_file("mbm/default_budget/mbm.md", "mbm/default_budget/cpu_summary.json"),
    "mbm_held_out": markdown_file("mbm/first30_default/mbm.md", "mbm/first30_default/mbm.json"),
    "mbm_escapes": markdown_file("mbm/escapes.md"),
    "mbm_speed_ns0": markdown_file("mbm_speed/ns0.md"),
    "mbm_speed_ns1": markdown_file("mbm_speed/ns1.md"),
    "fit_frontier": markdown_file("fit_frontier_v2/fit_frontier.md"),
}


def section(name: str) -> str:
    """The markdown of section NAME; a note when its result file is missing (the page still builds)."""
    if name not in SECTIONS:
        raise KeyError(f"no benchmark section {name!r}; known: {', '.join(SECTIONS)}")
    body = SECTIONS[name]()
    return body if body is not None else f"*No result yet: run the benchmark that writes this section (`{name}`), then rebuild the site.*"


# ------------------------------------------------------------------------------------ the MBM plot
def mbm_plot() -> bytes | None:
    """PNG bytes: median planning time per family, ours (after) and VAMP's (exact and CAPT), from
    ``results/mbm_speed/*.json``; None without matplotlib or results."""
    files = sorted((RESULTS / "mbm_speed").glob("*.json"))
    if not files:
        return None
    try:
        from matplotlib.figure import Figure
    except ImportError:
        return None
    import statistics

    fig = Figure(figsize=(9.0, 3.6), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    series: dict[str, dict[str, float]] = {}
    families: list[str] = []
    for f in files:
        d = json.loads(f.read_text())
        families = families or list(d["families"])
        rows = d["after"]["rows"]
        series[f"splatplan, n_sigma {d['n_sigma']:g}"] = {
            fam: statistics.median(r["time_s"] for r in rows if r["family"] == fam and r.get("solved")) for fam in families if any(r["family"] == fam and r.get("solved") for r in rows)
        }
        for mode, vr in (d.get("vamp") or {}).items():
            if not isinstance(vr, list):  # "meta" and "summary" are dicts; each mode's rows a list
                continue
            ok = [r for r in vr if r.get("solved")]
            series[f"VAMP ({mode}), plan + simplify, one core"] = {
                fam: statistics.median(r["plan_s"] + r.get("simplify_s", 0.0) for r in ok if r["family"] == fam) for fam in families if any(r["family"] == fam for r in ok)
            }
    width = 0.8 / max(len(series), 1)
    for i, (label, per) in enumerate(series.items()):
        xs = [j + i * width for j, fam in enumerate(families) if fam in per]
        ax.bar(xs, [1e3 * per[fam] for fam in families if fam in per], width, label=label)
    ax.set_xticks([j + 0.4 - width / 2 for j in range(len(families))], families)
    ax.set_yscale("log")
    ax.set_ylabel("median plan time (ms, log)")
    ax.set_title("MotionBenchMaker Panda problems, solved problems only")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


# ------------------------------------------------------------------------------------ the README's table
def _load(rel: str) -> dict | None:
    p = RESULTS / rel
    return json.loads(p.read_text()) if p.exists() else None


def _duration(seconds: float) -> str:
    """A duration with its unit: ms below a second, else s."""
    return f"{seconds * 1e3:.1f} ms" if seconds < 1.0 else f"{seconds:.2f} s"


def headline() -> str:
    """The README's headline table: a few numbers from the results, each linked to its page."""
    rows = ["| what | result | page |", "|---|---|---|"]
    pr = _load("pr.json")
    if pr:
        m = pr["methods"]
        best = max((k for k in m if not k.startswith("collisionsplatting")), key=lambda k: m[k]["ap"])
        rows.append(f"| E1 collision classification, Stonehenge (AP) | ours {m['collisionsplatting']['ap']:.3f} at n_sigma 1, "
                    f"{m['collisionsplatting_nsigma0']['ap']:.3f} at 0; best baseline ({best}) {m[best]['ap']:.3f} | [E1](docs/benchmarks/pr.md) |")  # fmt: skip
    t = _load("throughput.json")
    if t:
        ours = max((r for r in t["rows"] if r["method"] == "collisionsplatting"), key=lambda r: r["batch"])
        base = max((r for r in t["rows"] if not r["method"].startswith("collisionsplatting")), key=lambda r: r["checks_per_s"])
        rows.append(f"| E2 throughput, {t.get('cores', '?')} CPU cores | {ours['checks_per_s']:,.0f} checks/s (batch {ours['batch']:,}); "
                    f"fastest baseline ({base['method']}) {base['checks_per_s']:,.0f} | [E2](docs/benchmarks/throughput.md) |")  # fmt: skip
    mb = _load("mbm/first30_default/mbm.json")
    if mb:
        o = mb["summary"]["overall"]
        rows.append(f"| MotionBenchMaker, Panda on splats of {o['n_problems']} MoveIt problems | {o['problems_started']}/{o['n_problems']} started, "
                    f"{o['solved']}/{o['problems_started']} solved, {o['negative_clearance_paths']} paths with negative exact clearance, "
                    f"median plan {_duration(o['median_time_s'])} | [MBM](docs/benchmarks/mbm.md) |")  # fmt: skip
    arm, base_ = _load("arm.json"), _load("base.json")
    if arm and base_:
        a = {r["config"]: r for r in arm["rows"]}
        b = {r["config"]: r for r in base_["rows"]}
        wc, nc = a.get("with_collision"), a.get("without_collision")
        mem = b.get("with_collision_memory")
        if wc and nc and mem:
            rows.append(f"| Arm behind a wall; Go2 across rooms | arm {wc['successes']}/{wc['trials']} with the collision cost, "
                        f"{nc['successes']}/{nc['trials']} without; Go2 {mem['successes']}/{mem['trials']} with the obstacle memory | [Tasks](docs/benchmarks/tasks.md) |")  # fmt: skip
    return "\n".join(rows)


def readme_with_headline(text: str) -> str:
    """README text with its ``<!-- BEGIN:headline -->`` .. ``<!-- END:headline -->`` block regenerated."""
    import re

    pat = re.compile(r"(<!-- BEGIN:headline -->\n).*?(\n<!-- END:headline -->)", re.S)
    return pat.sub(lambda m: m.group(1) + headline() + m.group(2), text)


def main(argv: list[str]) -> int:
    if argv == ["--readme"]:
        readme = ROOT / "README.md"
        readme.write_text(readme_with_headline(readme.read_text()))
        print("README.md: headline table regenerated")
        return 0
    if argv:
        for name in argv:
            print(section(name))
        return 0
    for name, fn in SECTIONS.items():
        print(f"{name:24s} {'ok' if fn() is not None else 'no result yet'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
