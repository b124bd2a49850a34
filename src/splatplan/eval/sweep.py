"""``splatplan sweep SPEC.yaml --out DIR``: a grid of plan or check jobs over many scene files.

The spec is a small YAML mapping (every key is a field of :class:`SweepSpec`; an unknown key is an
error)::

    scenes: ["captures/*.ply", "builtin:tabletop"]  # globs relative to the spec file, or builtin:NAME
    job: plan               # plan (start -> goal) | check (random configurations)
    robot: panda            # any --robot name: sphere:R, ellipsoid:A,B,C, panda, a URDF path
    n_sigma: [0.0, 1.0]     # conservatism values (a number or a list)
    seeds: [0, 1, 2]        # planner / sampler seeds (a number or a list)
    planners: [rrt, ompl:RRTConnect, ompl:BITstar]   # plan jobs
    time_limit: 5.0         # plan jobs: seconds per plan
    pairs: 4                # plan jobs: random collision-free start/goal pairs per scene, or a list
                            #   [{start: [...], goal: [...]}, ...] used for every scene

The grid is scenes x n_sigma x planners x pairs x seeds (plan) or scenes x n_sigma x seeds (check);
each cell is one task of :func:`splatplan.eval.engine.run_tasks`, so ``--workers N`` /
``--scheduler ADDR`` run it on Dask, a rerun skips finished cells, and every scene is loaded once
per worker. Random pairs are drawn from the task's own seed (``pair_seed``, the pair index and the
scene's name), free at the largest n_sigma of the spec, so every n_sigma, planner and seed plans the
same pairs, on any worker.

Outputs in ``DIR``: ``results.jsonl`` (one line per cell, streamed), ``results.parquet`` (the same
rows, when pyarrow is installed), ``summary.json`` (the spec, the engine, one row per scene x
n_sigma x planner) and ``summary.md``.
"""

from __future__ import annotations

import dataclasses
import glob
import hashlib
import json
import math
import time
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..errors import PlanningError, SplatplanError
from ..robots.builtin import DEFAULT_POINT_ROBOT

__all__ = ["SweepSpec", "load_spec", "report", "run_sweep"]


@dataclass
class SweepSpec:
    """A sweep: the YAML file's keys (see the module docstring)."""

    #: scene files (globs, relative to the spec file) and built-in scenes (builtin:NAME)
    scenes: list[str] = field(default_factory=list)
    #: plan (start -> goal per pair) or check (random configurations, collision fraction and rate)
    job: str = "plan"
    #: robot name as for --robot (sphere:R, ellipsoid:A,B,C, panda, go2, a URDF path)
    robot: str = DEFAULT_POINT_ROBOT
    #: n_sigma values (a number or a list)
    n_sigma: list[float] = field(default_factory=lambda: [1.0])
    #: seeds of the planner (plan) or of the configuration sampler (check)
    seeds: list[int] = field(default_factory=lambda: [0])
    #: plan jobs: planners, "rrt" (ours) or "ompl:NAME"
    planners: list[str] = field(default_factory=lambda: ["rrt"])
    #: plan jobs: wall-clock budget per plan (s)
    time_limit: float = 10.0
    #: plan jobs: RRT iteration budget (None = the time limit decides; set it for runs that must
    #: give the same results on any machine)
    max_iters: int | None = None
    #: plan jobs: zeroth-order refinement of our RRT's path
    refine: bool = False
    #: plan jobs: number of random collision-free start/goal pairs per scene, or a list of
    #: {start: [...], goal: [...]} used for every scene
    pairs: int | list = 3
    #: seed of the random pairs
    pair_seed: int = 0
    #: check jobs: random configurations per job
    n_configs: int = 10_000
    #: drop floaters when loading scene files (the default rule of 'splatplan check')
    filter_floaters: bool = True
    #: built-in scenes: splat count (None = the scene's default)
    n_splats: int | None = None
    #: device of the checker (cpu keeps one core per worker; auto = CUDA when present)
    device: str = "cpu"

    def validate(self) -> "SweepSpec":
        if not self.scenes:
            raise SplatplanError("sweep spec: 'scenes' must list at least one glob or builtin:NAME")
        if self.job not in ("plan", "check"):
            raise SplatplanError(f"sweep spec: job must be 'plan' or 'check', got {self.job!r}")
        if not self.n_sigma or any(not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0) for v in self.n_sigma):
            raise SplatplanError(f"sweep spec: n_sigma must be finite numbers >= 0, got {self.n_sigma}")
        if not self.seeds or any(not isinstance(s, int) or isinstance(s, bool) or s < 0 for s in self.seeds):
            raise SplatplanError(f"sweep spec: seeds must be integers >= 0, got {self.seeds}")
        for p in self.planners:
            if p != "rrt" and not str(p).startswith("ompl:"):
                raise SplatplanError(f"sweep spec: planner {p!r}: 'rrt' or 'ompl:NAME'")
        if not (isinstance(self.time_limit, (int, float)) and self.time_limit > 0):
            raise SplatplanError(f"sweep spec: time_limit must be > 0, got {self.time_limit}")
        if self.max_iters is not None and (not isinstance(self.max_iters, int) or self.max_iters < 1):
            raise SplatplanError(f"sweep spec: max_iters must be an integer >= 1, got {self.max_iters}")
        if isinstance(self.pairs, bool) or not (isinstance(self.pairs, int) and self.pairs >= 1 or isinstance(self.pairs, list) and self.pairs):
            raise SplatplanError("sweep spec: pairs must be an integer >= 1 or a list of {start: [...], goal: [...]}")
        if isinstance(self.pairs, list):
            for i, p in enumerate(self.pairs):
                if not isinstance(p, dict) or set(p) != {"start", "goal"}:
                    raise SplatplanError(f"sweep spec: pairs[{i}] must be {{start: [...], goal: [...]}}")
        import re

        if not re.fullmatch(r"auto|cpu|cuda(:\d+)?", str(self.device)):
            raise SplatplanError(f"sweep spec: device must be auto, cpu, cuda or cuda:N, got {self.device!r}")
        if not isinstance(self.n_configs, int) or self.n_configs < 1:
            raise SplatplanError(f"sweep spec: n_configs must be an integer >= 1, got {self.n_configs}")
        self._check_sizes()
        return self

    def _check_sizes(self) -> None:
        """The declared ranges of the spec's numbers and the resource guard of its sizes
        (``pairs: 1e9`` or ``n_configs: 1e11`` must fail at once), before any scene is loaded."""
        from .._resources import require_bytes, require_work

        if not all(v <= 1e3 for v in self.n_sigma):
            raise SplatplanError(f"sweep spec: n_sigma must be <= 1000, got {self.n_sigma}")
        if any(s > 2**32 - 1 for s in self.seeds):
            raise SplatplanError(f"sweep spec: seeds must be <= {2**32 - 1}, got {self.seeds}")
        if not (math.isfinite(self.time_limit) and self.time_limit <= 1e6):
            raise SplatplanError(f"sweep spec: time_limit must be a finite number of seconds <= 1e6, got {self.time_limit}")
        if self.max_iters is not None and self.max_iters > 10**12:
            raise SplatplanError(f"sweep spec: max_iters must be <= 1e12, got {self.max_iters}")
        if not isinstance(self.pair_seed, int) or isinstance(self.pair_seed, bool) or not 0 <= self.pair_seed <= 2**32 - 1:
            raise SplatplanError(f"sweep spec: pair_seed must be an integer in [0, {2**32 - 1}], got {self.pair_seed}")
        if self.n_splats is not None and (not isinstance(self.n_splats, int) or isinstance(self.n_splats, bool) or not 1 <= self.n_splats <= 10**9):
            raise SplatplanError(f"sweep spec: n_splats must be an integer in [1, 1e9] or absent, got {self.n_splats}")
        if isinstance(self.pairs, list):
            for i, p in enumerate(self.pairs):
                for k in ("start", "goal"):
                    v = p[k] if isinstance(p[k], list) else [p[k]]
                    if not v or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and abs(x) <= 1e6 for x in v):
                        raise SplatplanError(f"sweep spec: pairs[{i}].{k} must be a list of finite numbers within +-1e6, got {p[k]!r}")
        n_pairs = len(self.pairs) if isinstance(self.pairs, list) else self.pairs
        cells = float(len(self.scenes)) * len(self.n_sigma) * len(self.seeds) * ((len(self.planners) * n_pairs) if self.job == "plan" else 1)
        require_work(cells, MAX_SWEEP_CELLS, "the sweep's grid", "scenes, n_sigma, seeds, planners or pairs in the spec")
        if self.job == "check":
            require_bytes(float(self.n_configs) * CONFIG_BYTES, f"sweep spec: {self.n_configs:,} random configurations per check job",
                          "n_configs in the spec")
        else:  # random pairs are drawn from at most this many candidate configurations per scene
            require_bytes(float(n_pairs) * PAIR_BYTES, f"sweep spec: {n_pairs:,} start/goal pairs per scene", "pairs in the spec")


#: the most cells (tasks) one sweep may hold, and the bytes of one random configuration (the
#: configurations, their FK and the metric's outputs) and one random pair (its candidates)
MAX_SWEEP_CELLS = 1e6
CONFIG_BYTES = 2048
PAIR_BYTES = 1 << 16


def _as_list(v, kind):
    vals = v if isinstance(v, list) else [v]
    try:
        return [kind(x) if not isinstance(x, bool) else x for x in vals]
    except (TypeError, ValueError):
        raise SplatplanError(f"sweep spec: cannot read {v!r} as {kind.__name__} values") from None


def load_spec(path: str | Path) -> tuple[SweepSpec, Path]:
    """Read and validate a sweep YAML. Returns (spec, the spec file's folder).

    Raises:
        SplatplanError: unreadable YAML, not a mapping, an unknown key, a bad value.
    """
    from .._files import read_yaml

    doc = read_yaml(path, "sweep spec")
    if not isinstance(doc, dict):
        raise SplatplanError(f"sweep spec {path}: expected a mapping of keys (scenes, job, robot, ...), got {type(doc).__name__}")
    known = {f.name for f in dataclasses.fields(SweepSpec)}
    unknown = sorted(set(doc) - known)
    if unknown:
        raise SplatplanError(f"sweep spec {path}: unknown key(s) {', '.join(map(str, unknown))}; known: {', '.join(sorted(known))}")
    kw = dict(doc)
    for name, kind in (("scenes", str), ("planners", str), ("n_sigma", float), ("seeds", int)):
        if name in kw:
            kw[name] = _as_list(kw[name], kind)
    return SweepSpec(**kw).validate(), Path(path).parent


def expand_scenes(spec: SweepSpec, base: Path) -> list[str]:
    """Scene ids: 'builtin:NAME' or absolute file paths (globs expanded, sorted, de-duplicated)."""
    from ..scenes.builtin import BUILTIN_SCENES

    out: list[str] = []
    for s in spec.scenes:
        if s.startswith("builtin:"):
            if s[8:] not in BUILTIN_SCENES:
                raise SplatplanError(f"sweep spec: unknown built-in scene {s!r}; built-ins: {', '.join('builtin:' + n for n in BUILTIN_SCENES)}")
            out.append(s)
            continue
        pat = s if Path(s).is_absolute() else str(base / s)
        hits = sorted(glob.glob(pat, recursive=True))
        if not hits:
            raise SplatplanError(f"sweep spec: scene glob {s!r} matches no file (relative to {base})")
        out.extend(str(Path(h).resolve()) for h in hits if Path(h).is_file())
    return list(dict.fromkeys(out))


# ---------------------------------------------------------------------------- the per-worker context
class SweepContext:
    """What every task of a sweep needs, built once per worker: the robot, and each scene (loaded
    on first use, kept) with its checkers per n_sigma."""

    def __init__(self, robot: str, device: str, filter_floaters: bool, n_splats: int | None) -> None:
        from ..robots import load_robot

        self.robot = load_robot(robot)
        self.device = device
        self.filter_floaters = filter_floaters
        self.n_splats = n_splats
        self._scenes: dict = {}
        self._checkers: dict = {}
        self.n_scene_loads = 0

    def splats(self, scene: str):
        if scene not in self._scenes:
            if scene.startswith("builtin:"):
                from ..scenes.builtin import build_builtin
                from ..scenes.filters import filter_floaters

                sp, _ = build_builtin(scene[8:], n_splats=self.n_splats)
                if self.filter_floaters:
                    sp, _ = filter_floaters(sp)
            else:
                from ..scenes.load import load_scene

                sp = load_scene(scene, filter_floaters=self.filter_floaters)
            self._scenes[scene] = sp
            self.n_scene_loads += 1
        return self._scenes[scene]

    def checker(self, scene: str, n_sigma: float):
        key = (scene, float(n_sigma))
        if key not in self._checkers:
            from ..metric import CollisionChecker

            base = next((c for (s, _), c in self._checkers.items() if s == scene), None)
            self._checkers[key] = base.with_config(n_sigma=float(n_sigma)) if base is not None else CollisionChecker(self.splats(scene), n_sigma=float(n_sigma), device=self.device)
        return self._checkers[key]


def make_context(robot: str, device: str, filter_floaters: bool, n_splats: int | None) -> SweepContext:
    return SweepContext(robot, device, filter_floaters, n_splats)


def _sample_box(ctx: SweepContext, scene: str) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) (D,) where random configurations are drawn: joint limits, or the robust scene box
    for a point robot's position."""
    from ..planners.rrt import robust_scene_box

    robot = ctx.robot
    lim = np.asarray(robot.joint_limits, dtype=np.float64).reshape(robot.dof, 2)
    if np.all(np.isfinite(lim)):
        return lim[:, 0], lim[:, 1]
    if robot.is_point:
        return robust_scene_box(ctx.splats(scene))
    raise SplatplanError(f"sweep: random configurations need joint limits or a point robot; {robot.name} has unlimited joints: give 'pairs' explicitly")


def _free_configs(ctx: SweepContext, scene: str, n_sigma: float, rng: np.random.Generator, n: int, max_rounds: int = 40) -> np.ndarray:
    """(n, D) random collision-free configurations (at ``n_sigma``)."""
    from ..planners import robot_collides

    lo, hi = _sample_box(ctx, scene)
    ch = ctx.checker(scene, n_sigma)
    got = []
    for _ in range(max_rounds):
        q = lo + rng.random((256, lo.size)) * (hi - lo)
        got.extend(q[~robot_collides(ch, ctx.robot, q).any(axis=-1)])
        if len(got) >= n:
            return np.asarray(got[:n])
    raise PlanningError(f"sweep: fewer than {n} collision-free configurations of {ctx.robot.name} in {max_rounds * 256} samples in {scene}")


def sweep_task(spec: dict, ctx: SweepContext) -> dict:
    """One cell of the grid (the task function of :func:`run_tasks`); seeded from ``spec`` only."""
    scene, ns, seed = spec["scene"], float(spec["n_sigma"]), int(spec["seed"])
    ch = ctx.checker(scene, ns)
    if spec["job"] == "check":
        from ..planners import robot_collides

        lo, hi = _sample_box(ctx, scene)
        q = lo + np.random.default_rng([seed, zlib.crc32(scene.encode())]).random((int(spec["n_configs"]), lo.size)) * (hi - lo)
        robot_collides(ch, ctx.robot, q[:8])  # warm-up (kernel load) outside the timing
        t0 = time.perf_counter()
        hit = robot_collides(ch, ctx.robot, q).any(axis=-1)  # (n,) any ellipsoid in collision
        dt = time.perf_counter() - t0
        return {"n_configs": len(q), "colliding_fraction": float(hit.mean()), "configs_per_s": len(q) / max(dt, 1e-12), "seconds": dt}
    from ..planners import RRTConfig, plan

    if spec.get("start") is not None:
        start, goal = np.asarray(spec["start"], np.float64), np.asarray(spec["goal"], np.float64)
    else:
        rng = np.random.default_rng([int(spec["pair_seed"]), int(spec["pair"]), zlib.crc32(scene.encode())])
        start, goal = _free_configs(ctx, scene, float(spec["n_sigma_max"]), rng, 2)
    cfg = RRTConfig(time_limit_s=float(spec["time_limit"]), max_iters=spec.get("max_iters"))
    row = {"start": start.tolist(), "goal": goal.tolist()}
    try:
        res = plan(ch, start, goal, robot=ctx.robot, refine=bool(spec["refine"]), seed=seed, rrt_config=cfg, planner=spec["planner"])
    except PlanningError as exc:
        return {**row, "success": False, "length": None, "time_s": None, "n_nodes": 0, "message": str(exc)}
    return {
        **row,
        "success": bool(res.success),
        "length": float(res.length) if np.isfinite(res.length) else None,
        "time_s": float(res.time_s),
        "n_nodes": int(res.n_nodes),
        "n_vertices": int(len(res.path)),
        "message": res.message,
    }


def _signature(spec: SweepSpec) -> str:
    """A short hash of the settings that change a cell's result (not the grid axes): resume keys
    of a changed spec never match old results."""
    from .engine import code_version

    d = asdict(spec)
    for k in ("scenes", "n_sigma", "seeds", "planners"):
        d.pop(k)
    d["code"] = code_version()
    return hashlib.sha1(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:8]


def build_tasks(spec: SweepSpec, scenes: list[str]):
    from .engine import Task

    sig = _signature(spec)
    tasks = []
    common = {"job": spec.job, "n_sigma_max": max(spec.n_sigma)}
    for scene in scenes:
        for ns in spec.n_sigma:
            for seed in spec.seeds:
                if spec.job == "check":
                    tasks.append(Task(f"{sig}|{scene}|ns={ns:g}|seed={seed}", {**common, "scene": scene, "n_sigma": ns, "seed": seed, "n_configs": spec.n_configs}))
                    continue
                n_pairs = len(spec.pairs) if isinstance(spec.pairs, list) else spec.pairs
                for planner in spec.planners:
                    for i in range(n_pairs):
                        t = {**common, "scene": scene, "n_sigma": ns, "seed": seed, "planner": planner, "pair": i, "pair_seed": spec.pair_seed,
                             "time_limit": spec.time_limit, "max_iters": spec.max_iters, "refine": spec.refine}  # fmt: skip
                        if isinstance(spec.pairs, list):
                            t["start"], t["goal"] = list(map(float, spec.pairs[i]["start"])), list(map(float, spec.pairs[i]["goal"]))
                        tasks.append(Task(f"{sig}|{scene}|ns={ns:g}|{planner}|pair={i}|seed={seed}", t))
    return tasks


def _median(v):
    v = [x for x in v if x is not None]
    return float(np.median(v)) if v else None


def run_sweep(spec: SweepSpec, base: Path, out_dir: Path, engine=None, progress: bool = True) -> dict:
    """Run a sweep and write its outputs into ``out_dir`` (see the module docstring).

    Returns:
        The summary (as in ``summary.json``): ``spec``, ``engine``, ``groups`` (one per scene x
        n_sigma x planner), ``n_tasks``, ``n_failed`` (tasks that raised; their errors in ``errors``).
    """
    import functools

    from .engine import run_tasks

    spec.validate()
    if spec.job == "plan" and any(p.startswith("ompl:") for p in spec.planners):
        from ..planners.ompl_bridge import available_planners

        names = available_planners()  # the missing extra is named before any work
        bad = [p for p in spec.planners if p.startswith("ompl:") and p[5:] not in names]
        if bad:
            raise SplatplanError(f"sweep spec: unknown OMPL planner(s) {', '.join(bad)}; available: {', '.join(names)}")
    scenes = expand_scenes(spec, base)
    tasks = build_tasks(spec, scenes)
    out_dir = Path(out_dir)
    factory = functools.partial(make_context, spec.robot, spec.device, spec.filter_floaters, spec.n_splats)
    res = run_tasks(tasks, sweep_task, factory, engine, out_dir / "results.jsonl", progress=progress, desc="sweep")
    groups: dict[tuple, list] = {}
    for t in tasks:
        if t.key in res.rows:
            groups.setdefault((t.spec["scene"], t.spec["n_sigma"], t.spec.get("planner", "-")), []).append(res.rows[t.key])
    rows = []
    for (scene, ns, planner), rs in groups.items():
        g = {"scene": scene, "n_sigma": ns, "planner": planner, "n": len(rs)}
        if spec.job == "plan":
            ok = [r for r in rs if r["success"]]
            g.update(solved=len(ok), median_time_s=_median([r["time_s"] for r in ok]), median_length=_median([r["length"] for r in ok]))
        else:
            g.update(colliding_fraction=float(np.mean([r["colliding_fraction"] for r in rs])), median_configs_per_s=_median([r["configs_per_s"] for r in rs]))
        rows.append(g)
    summary = {
        "spec": asdict(spec),
        "scenes": scenes,
        "engine": res.engine,
        "n_tasks": len(tasks),
        "n_run": res.n_run,
        "n_skipped": res.n_skipped,
        "n_failed": len(res.errors),
        "errors": dict(list(res.errors.items())[:20]),
        "groups": rows,
        "wall_s": res.wall_s,
    }
    from .._files import atomic_path
    from .._json import write_json

    write_json(out_dir / "summary.json", summary)
    with atomic_path(out_dir / "summary.md") as tmp:
        tmp.write_text(report(summary))
    _write_parquet(out_dir / "results.parquet", tasks, res)
    return summary


def _write_parquet(path: Path, tasks, res) -> None:
    """The rows as one flat table (task fields + result fields), when pyarrow is installed."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return
    recs = []
    for t in tasks:
        r = res.records.get(t.key)
        if r is None:
            continue
        row = {"key": t.key, **{k: v for k, v in t.spec.items() if not isinstance(v, list)}, "ok": bool(r.get("ok")), "error": r.get("error")}
        row.update({k: v for k, v in (r.get("row") or {}).items() if not isinstance(v, list)})
        recs.append(row)
    from .._files import atomic_path

    with atomic_path(path) as tmp:
        pq.write_table(pa.Table.from_pylist(recs), tmp)


def report(summary: dict) -> str:
    """The markdown table of a sweep."""
    eng = summary["engine"]
    e = "serial" if eng["kind"] == "serial" else f"dask, {eng['workers']} worker(s) at {eng['scheduler']}"
    sp = summary["spec"]
    lines = [f"# sweep: {sp['job']} jobs, robot {sp['robot']}", "", f"{summary['n_tasks']} task(s) on {e}; {summary['n_failed']} failed.", ""]
    if sp["job"] == "plan":
        lines += ["| scene | n_sigma | planner | solved | median time (s) | median length |", "|---|---|---|---|---|---|"]
        for g in summary["groups"]:
            t = "n/a" if g["median_time_s"] is None else f"{g['median_time_s']:.3f}"
            ln = "n/a" if g["median_length"] is None else f"{g['median_length']:.4f}"
            lines.append(f"| {Path(g['scene']).name} | {g['n_sigma']:g} | {g['planner']} | {g['solved']}/{g['n']} | {t} | {ln} |")
    else:
        lines += ["| scene | n_sigma | jobs | colliding fraction | median configurations/s |", "|---|---|---|---|---|"]
        for g in summary["groups"]:
            lines.append(f"| {Path(g['scene']).name} | {g['n_sigma']:g} | {g['n']} | {g['colliding_fraction']:.4f} | {g['median_configs_per_s']:,.0f} |")
    return "\n".join(lines) + "\n"
