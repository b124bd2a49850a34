"""Arm planning speed on MotionBenchMaker (MBM): splatplan before / after, and VAMP, in one run.

    python benchmarks/mbm_speed.py [--families table_pick,box,bookshelf_small] [--n-per-family 10]
        [--n-sigma 0] [--before REV] [--no-vamp] [--out benchmarks/results/mbm_speed/NAME]

Everything runs on this machine in one process tree, family by family (the before run of a family, then
its after run), so the ratios hold on a shared machine:

* **after**: ``eval mbm`` at its defaults (splats sampled per surface area, derived margin, the
  library's default planner) over the first N problems of each family; per problem the wall and CPU
  time of ``plan`` (search + shortcut), the configurations it checked, the path length and the path's
  exact clearance against the primitives;
* **before** (``--before REV``, e.g. a commit or tag): the same run with the code of REV (a temporary
  ``git worktree`` under ``build/``, run in a subprocess with its ``src`` first on the path);
* **per configuration**: the collision cost of one configuration (the MBM Panda's ellipsoids grown by
  the margin, the first scene of each family), single-thread CPU microseconds, for configurations along
  the solved paths (densified: near surfaces) and uniform in the joint limits, through the planners'
  per-configuration check (``collides_configs``) and the per-ellipsoid one (``collides_robot``);
* **per scene**: the time and memory to build the checker's structures (hash grids, mean-distance
  grid) that a user pays once per scene;
* **VAMP** (unless ``--no-vamp``, skipped with the reason where its wheel does not install): the same
  problems with exact primitives and with its point-cloud tree (CAPT) on our splats' means (floaters
  dropped, thinned to 2 cm), VAMP's own planning + simplification time, its paths checked by our exact
  clearance (our robot model against the primitives; negative = the path cuts the geometry).

Writes OUT.json (every row and setting, with the date and machine) and OUT.md (the table), prints the
table. Timings are measurements of this machine at that moment: compare ratios within one file.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
#: the shared MBM problems and Panda (the same for the before tree, which lives elsewhere)
MBM_DATA = Path(os.environ.get("SPLATPLAN_MBM_DATA", REPO / ".." / "shared" / "data" / "mbm")).resolve()

#: the row fields the table and the before run need (a before tree may lack the newer ones)
ROW_KEYS = ("family", "index", "start_free", "goal_free", "started", "start_escape", "goal_escape", "solved", "time_s", "cpu_s", "n_configs", "path_length", "min_exact_clearance_m",
            "n_splats_sampled", "margin_m", "path")  # fmt: skip

#: the run of one tree (this one or a before tree through PYTHONPATH), as a subprocess script
RUN_SCRIPT = r"""
import json, sys, time
import splatplan.eval.mbm as mbm
cfg = mbm.MBMConfig(families=tuple(sys.argv[1].split(",")), n_per_family=int(sys.argv[2]), n_sigma=float(sys.argv[3]),
                    problems=sys.argv[7] + "/problems", robot=sys.argv[7] + "/panda/panda.urdf")
last = {}
orig = mbm._plan
def timed(*a, **k):
    c = time.process_time()
    r = orig(*a, **k)
    last["cpu_s"] = time.process_time() - c
    info = r.info or {}
    last["n_configs"] = info.get("n_configs", int(info.get("n_queries", 0)) // int(a[3].n_ellipsoids))
    return r
mbm._plan = timed
orig_solve = mbm.solve_problem
def solve(task, ctx):
    last.clear()
    row = orig_solve(task, ctx)
    for k in ("cpu_s", "n_configs"):  # (a tree from before these row fields)
        if row.get(k) is None and k in last:
            row[k] = last[k]
    return row
mbm.solve_problem = solve
res = mbm.run_mbm(cfg, sys.argv[4], progress=False)
keys = json.loads(sys.argv[5])
json.dump([{k: r.get(k) for k in keys} for r in res.rows], open(sys.argv[6], "w"))
"""


def run_tree(src: Path | None, families: str, n: int, n_sigma: float, scratch: Path) -> list[dict]:
    """Rows of ``eval mbm`` with the code in ``src`` (None: this tree) in a subprocess."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = str(src) + os.pathsep + env.get("PYTHONPATH", "")
    env.setdefault("SPLATPLAN_NO_TQDM", "1")
    out = scratch / ("before" if src is not None else "after")
    out.mkdir(parents=True, exist_ok=True)
    rows_path = out / "rows.json"
    cmd = [sys.executable, "-c", RUN_SCRIPT, families, str(n), str(n_sigma), str(out), json.dumps(ROW_KEYS), str(rows_path), str(MBM_DATA)]
    p = subprocess.run(cmd, env=env, cwd=str(REPO), capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"the {'before' if src else 'after'} run failed:\n{p.stderr[-3000:]}")
    return json.loads(rows_path.read_text())


def before_tree(rev: str, scratch: Path) -> Path:
    """A worktree of ``rev`` under build/ (removed by the caller); returns its src folder."""
    wt = scratch / f"tree_{rev.replace('/', '_')}"
    subprocess.run(["git", "-C", str(REPO), "worktree", "add", "--detach", str(wt), rev], check=True, capture_output=True)
    return wt


def per_config_costs(families: list[str], n_sigma: float, after_rows: list[dict], n_uniform: int = 2000) -> list[dict]:
    """Single-thread CPU microseconds per configuration (module docstring), and the per-scene build."""
    os.environ["SPLATPLAN_CPU_THREADS"] = "1"  # one thread: CPU time per configuration, not wall
    import splatplan.eval.mbm as mbm
    from splatplan.metric import CollisionChecker
    from splatplan.metric.tiers import TierConfig

    out = []
    cfg = mbm.MBMConfig(families=tuple(families), n_per_family=1, n_sigma=n_sigma)
    ctx = mbm.make_context(cfg)
    robot = ctx.robot
    rng = np.random.default_rng(0)
    lim = np.asarray(robot.joint_limits)
    for task in mbm.list_tasks(cfg):
        prep = ctx.prepared(task)
        plan_robot = robot.inflated(prep.margin)
        rss0 = _rss()
        t0 = time.perf_counter()
        ch = CollisionChecker(prep.splats, n_sigma=n_sigma, device="cpu")
        ch.collides_configs(plan_robot, np.asarray(robot.q_default)[None])  # grids and the mean-distance grid
        build_s = time.perf_counter() - t0
        build_mb = (_rss() - rss0) / 2**20
        paths = [np.asarray(r["path"]) for r in after_rows if r["family"] == task.family and r.get("path")]
        near = np.concatenate([mbm.dense_path(robot, p) for p in paths]) if paths else np.zeros((0, robot.dof))
        uni = lim[:, 0] + rng.random((n_uniform, robot.dof)) * (lim[:, 1] - lim[:, 0])
        row = {"family": task.family, "n_splats": len(prep.splats), "build_s": build_s, "build_rss_mb": build_mb, "n_ellipsoids": plan_robot.n_ellipsoids}
        off = CollisionChecker(prep.splats, n_sigma=n_sigma, device="cpu", tiers=TierConfig(collide_cover=False))  # the same check without the cover spheres
        for name, q in (("near", near[:4000]), ("uniform", uni)):
            if len(q) == 0:
                continue
            calls = {"collides_configs": ch.collides_configs, "collides_robot": ch.collides_robot, "collides_configs_nocover": off.collides_configs}
            best = dict.fromkeys(calls, np.inf)
            for f in calls.values():
                f(plan_robot, q[:64])
            for _ in range(3):  # (interleaved: the machine's drift hits every variant alike)
                for key, f in calls.items():
                    c = time.process_time()
                    f(plan_robot, q)
                    best[key] = min(best[key], time.process_time() - c)
            for key, b in best.items():
                row[f"us_{name}_{key}"] = 1e6 * b / len(q)
            row[f"n_{name}"] = len(q)
        ch.close()
        off.close()
        out.append(row)
    os.environ.pop("SPLATPLAN_CPU_THREADS", None)
    return out


def _rss() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    return 0


def run_vamp(families: list[str], n: int, after_rows: list[dict]) -> dict:
    """VAMP exact and CAPT on the same problems; its paths checked by our exact clearance."""
    import vamp_compare as vc

    import splatplan.eval.mbm as mbm
    from splatplan.scenes.builtin.primitives import AnalyticScene

    py, why = vc.vamp_python(str(REPO / "build" / "vamp-venv"))
    if py is None:
        return {"skipped": why}
    problems, robot = vc.load_problems(families, n)
    counts = {(r["family"], r["index"]): r.get("n_splats_sampled") for r in after_rows}
    out: dict = {"meta": {}}
    for mode in ("exact", "capt"):
        probs = []
        for p in problems:
            q = dict(p)
            if mode == "capt":
                q["points"] = vc.scene_points(p["objects"], int(counts.get((p["family"], p["index"])) or 500_000)).tolist()
            probs.append(q)
        meta: dict = {}
        res = vc.solve_vamp(py, probs, mode, meta=meta)
        out["meta"][mode] = meta
        for p, r in zip(problems, res):
            r.pop("points", None)
            if r.get("solved") and r.get("path"):
                scene = AnalyticScene.from_json(p["objects"])
                r["min_exact_clearance_m"] = float(mbm.path_min_clearance(scene, robot, mbm.dense_path(robot, np.asarray(r["path"]))))
            r.pop("path", None)
        out[mode] = res
    return out


def _pct(v, q):
    v = [x for x in v if x is not None]
    return float(np.percentile(v, q)) if v else None


def summarise(rows: list[dict]) -> dict:
    both = [r for r in rows if r["start_free"] and r["goal_free"]]
    started = [r for r in rows if r.get("started") or (r.get("started") is None and r["start_free"] and r["goal_free"])]  # (a tree without escapes: both free)
    sol = [r for r in started if r["solved"]]
    sol_both = [r for r in sol if r["start_free"] and r["goal_free"]]
    return {
        "problems": len(rows), "both_free": len(both), "started": len(started), "solved": len(sol),
        "median_wall_both_free_s": _pct([r["time_s"] for r in sol_both], 50),
        "median_wall_s": _pct([r["time_s"] for r in sol], 50), "p95_wall_s": _pct([r["time_s"] for r in sol], 95),
        "median_cpu_s": _pct([r.get("cpu_s") for r in sol], 50), "median_configs": _pct([r.get("n_configs") for r in sol], 50),
        "median_length": _pct([r["path_length"] for r in sol], 50), "mean_length": float(np.mean([r["path_length"] for r in sol])) if sol else None,
        "negative_clearance": int(sum(r["min_exact_clearance_m"] < 0 for r in sol)),
        "worst_clearance_m": min((r["min_exact_clearance_m"] for r in sol), default=None),
    }  # fmt: skip


def summarise_vamp(res: list[dict]) -> dict:
    sol = [r for r in res if r.get("solved")]
    tot = [r["plan_s"] + (r.get("simplify_s") or 0.0) for r in sol]
    return {
        "problems": len(res), "solved": len(sol), "median_plan_s": _pct([r["plan_s"] for r in sol], 50),
        "median_total_s": _pct(tot, 50), "p95_total_s": _pct(tot, 95), "median_build_s": _pct([r.get("build_s") for r in sol], 50),
        "cut_geometry": int(sum((r.get("min_exact_clearance_m") or 0.0) < 0 for r in sol)),
        "cut_deeper_than_5mm": int(sum((r.get("min_exact_clearance_m") or 0.0) < -0.005 for r in sol)),
    }  # fmt: skip


def _f(v, fmt=".3g", scale=1.0, unit=""):
    return "-" if v is None else f"{v * scale:{fmt}}{unit}"


def table(result: dict) -> str:
    lines = [f"MBM planning speed ({result['date']}, {result['machine']}; n_sigma {result['n_sigma']:g}, first {result['n_per_family']} problems per family)", ""]
    lines += ["| run | family | both free / problems | started (escapes) | solved | median wall | median wall, both free | p95 wall | median CPU | configs / plan | median length | paths < 0 |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for run in ("before", "after"):
        for fam, s in (result.get(run) or {}).get("summary", {}).items():
            st = s.get("started", s["both_free"])
            lines.append(f"| {run} | {fam} | {s['both_free']}/{s['problems']} | {st} ({st - s['both_free']}) | {s['solved']} | {_f(s['median_wall_s'], '.1f', 1e3, ' ms')} | "
                         f"{_f(s.get('median_wall_both_free_s'), '.1f', 1e3, ' ms')} | "
                         f"{_f(s['p95_wall_s'], '.1f', 1e3, ' ms')} | {_f(s['median_cpu_s'], '.1f', 1e3, ' ms')} | {_f(s['median_configs'], '.0f')} | "
                         f"{_f(s['median_length'], '.2f')} | {s['negative_clearance']} |")  # fmt: skip
    if result.get("before") and result.get("after"):
        b, a = result["before"]["summary"]["all"], result["after"]["summary"]["all"]
        bb, ab = b.get("median_wall_both_free_s") or b["median_wall_s"], a.get("median_wall_both_free_s") or a["median_wall_s"]
        if b["median_wall_s"] and a["median_wall_s"] and bb and ab:
            lines += ["", f"After / before, on the problems both runs plan (both endpoints free): median wall {bb / ab:.2f}x faster. "
                          f"Over every problem each run solves (after: escaped ones too, which cost more): median wall "
                          f"{b['median_wall_s'] / a['median_wall_s']:.2f}x, median CPU "
                          f"{_f(b['median_cpu_s'] / a['median_cpu_s'] if b['median_cpu_s'] and a['median_cpu_s'] else None, '.2f')}x, "
                          f"configurations per plan {_f(b['median_configs'] / a['median_configs'] if b['median_configs'] and a['median_configs'] else None, '.2f')}x."]  # fmt: skip
    v = result.get("vamp") or {}
    if v.get("skipped"):
        lines += ["", f"VAMP: skipped ({v['skipped']})"]
    elif v:
        lines += ["", "| VAMP (one core) | solved | median plan | median plan + simplify | p95 | CAPT build | paths < 0 for our certified model | deeper than 5 mm |",
                  "|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for mode in ("exact", "capt"):
            s = v["summary"][mode]
            lines.append(f"| {mode} | {s['solved']}/{s['problems']} | {_f(s['median_plan_s'], '.0f', 1e6, ' us')} | {_f(s['median_total_s'], '.0f', 1e6, ' us')} | "
                         f"{_f(s['p95_total_s'], '.0f', 1e6, ' us')} | {_f(s['median_build_s'], '.1f', 1e3, ' ms')} | {s['cut_geometry']} | {s['cut_deeper_than_5mm']} |")  # fmt: skip
        a = (result.get("after") or {}).get("summary", {}).get("all", {})
        if a.get("median_wall_s") and v["summary"]["exact"]["median_total_s"]:
            lines += ["", f"splatplan / VAMP exact (median wall, every started problem): {a['median_wall_s'] / v['summary']['exact']['median_total_s']:.0f}x; "
                          f"/ VAMP CAPT: {a['median_wall_s'] / (v['summary']['capt']['median_total_s'] or float('nan')):.0f}x"]  # fmt: skip
    pc = result.get("per_config") or []
    if pc:
        lines += ["", "| scene | splats | build | build memory | near-surface configs: per-configuration check | the same without cover spheres | per-ellipsoid check | "
                      "uniform: per-configuration | without cover spheres | per-ellipsoid |",
                  "|---|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
        for r in pc:
            lines.append(f"| {r['family']} | {r['n_splats']:,} | {r['build_s']:.2f} s | {r['build_rss_mb']:.0f} MB | {_f(r.get('us_near_collides_configs'), '.2f', 1, ' us')} | "
                         f"{_f(r.get('us_near_collides_configs_nocover'), '.2f', 1, ' us')} | {_f(r.get('us_near_collides_robot'), '.2f', 1, ' us')} | "
                         f"{_f(r.get('us_uniform_collides_configs'), '.2f', 1, ' us')} | {_f(r.get('us_uniform_collides_configs_nocover'), '.2f', 1, ' us')} | "
                         f"{_f(r.get('us_uniform_collides_robot'), '.2f', 1, ' us')} |")  # fmt: skip
        lines += ["", f"(per configuration: single-thread CPU time, the Panda's {pc[0]['n_ellipsoids']} ellipsoids grown by the margin; without cover spheres: "
                      "`TierConfig(collide_cover=False)`, same answers, measured interleaved with the default)"]  # fmt: skip
    if v and not v.get("skipped"):
        lines += ["", "VAMP's paths are checked with our certified ellipsoids, which reach up to 1.5 cm beyond the arm's mesh "
                      "(VAMP's own 59 spheres cover 26-73% of it): a path < 0 there comes closer to the geometry than our model "
                      "allows, not necessarily through it."]  # fmt: skip
    return "\n".join(lines)


def main(argv=None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--families", default="table_pick,box,bookshelf_small")
    ap.add_argument("--n-per-family", type=int, default=10)
    ap.add_argument("--n-sigma", type=float, default=0.0)
    ap.add_argument("--before", default=None, help="a git revision to time in the same run (e.g. a commit before a change)")
    ap.add_argument("--no-vamp", action="store_true")
    ap.add_argument("--no-per-config", action="store_true")
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "mbm_speed" / "default"))
    ap.add_argument("--from-json", default=None, help="only rewrite OUT.md (and print the table) from an earlier OUT.json")
    args = ap.parse_args(argv)
    if args.from_json:
        result = json.loads(Path(args.from_json).read_text())
        Path(args.out).with_suffix(".md").write_text(table(result) + "\n")
        print(table(result))
        return result
    fams = args.families.split(",")
    result: dict = {"date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                    "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_version()}", "load_avg_1min": [os.getloadavg()[0]],
                    "n_sigma": args.n_sigma, "families": fams, "n_per_family": args.n_per_family, "before_rev": args.before}  # fmt: skip
    (REPO / "build").mkdir(exist_ok=True)
    with tempfile.TemporaryDirectory(dir=REPO / "build", prefix="mbm_speed_") as tmp:
        scratch = Path(tmp)
        wt = None
        before_rows: list[dict] = []
        rows = []
        try:
            if args.before:
                wt = before_tree(args.before, scratch)
            for fam in fams:  # family by family, before then after: a machine that slows down mid-run biases neither
                if wt is not None:
                    before_rows += run_tree(wt / "src", fam, args.n_per_family, args.n_sigma, scratch)
                rows += run_tree(None, fam, args.n_per_family, args.n_sigma, scratch)
        finally:
            if wt is not None:
                subprocess.run(["git", "-C", str(REPO), "worktree", "remove", "--force", str(wt)], capture_output=True)
        if wt is not None:
            result["before"] = {"rows": before_rows, "summary": _summaries(before_rows, fams)}
    result["after"] = {"rows": rows, "summary": _summaries(rows, fams)}
    if not args.no_per_config:
        result["per_config"] = per_config_costs(fams, args.n_sigma, rows)
    if not args.no_vamp:
        v = run_vamp(fams, args.n_per_family, rows)
        if "skipped" not in v:
            v["summary"] = {m: summarise_vamp(v[m]) for m in ("exact", "capt")}
        result["vamp"] = v
    result["load_avg_1min"].append(os.getloadavg()[0])
    text = table(result)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    for r in (result.get("before") or {}).get("rows", []) + result["after"]["rows"]:
        r.pop("path", None)
    out.with_suffix(".json").write_text(json.dumps(result, indent=1))
    out.with_suffix(".md").write_text(text + "\n")
    print(text)
    return result


def _summaries(rows: list[dict], fams: list[str]) -> dict:
    s = {f: summarise([r for r in rows if r["family"] == f]) for f in fams}
    s["all"] = summarise(rows)
    return s


if __name__ == "__main__":
    main(sys.argv[1:])
