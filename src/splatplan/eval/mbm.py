"""MotionBenchMaker (MBM): the field's arm-planning benchmark, on splats sampled from its scenes.

For every problem (``<family>_panda/sceneNNNN.yaml`` + ``requestNNNN.yaml``, MoveIt YAML; see
``../shared/data/mbm/README.md``) the exact scene (boxes, cylinders, spheres) is sampled into
splats at ``splat_spacing_m`` (a count per surface area; or a fixed ``n_splats``) with the built-in real-capture look (:func:`~splatplan.scenes.moveit.build_moveit`,
floaters then filtered as :func:`~splatplan.scenes.load.load_scene` does and, with ``drop_isolated``,
the faint isolated ones that rule keeps), and the robot plans with
:func:`splatplan.planners.plan` against the splats. Each row records:

* ``start_valid`` / ``goal_valid``: the robot's own ellipsoids are free against the exact primitives
  (exact clearance > 0);
* ``start_free`` / ``goal_free``: the *planning* model (the robot inflated by ``margin_m``) is free
  against the splats at ``n_sigma``: the planner can start; ``start_blocked_by`` /
  ``goal_blocked_by``: for an endpoint that is not, the link and ellipsoid nearest the exact
  geometry among those the margin makes collide, and that ellipsoid's exact clearance;
* ``solved``, ``time_s`` (wall), ``cpu_s`` (this process's CPU seconds, the checker's threads
  included), ``n_configs`` (configurations collision-checked), ``n_nodes``, ``path_length`` (the planner's metric), ``path`` (joint
  configurations, when solved);
* ``min_exact_clearance_m``: the path resampled so that no ellipsoid point moves more than a quarter
  of the smallest semi-axis between samples (``Robot.motion_bound``, as the RRT's edge checks),
  each sample checked against the exact primitives with the robot's own (un-inflated) ellipsoids;
  negative = the path cuts the real geometry.

**The safety margin, at every n_sigma.** A link can slip between splats and cut the surface; the
planner checks the robot grown by a margin ``m >= rho(n) + r / 2`` (rho(n) the covering radius of
the surface by the splats' n-sigma ellipsoids, r the edge resolution), which makes that
impossible: the claim, its proof and the estimate of m from the splats alone are in
:mod:`splatplan.scenes.margin` (:func:`~splatplan.scenes.margin.derived_margin` with
``margin_spacing_factor`` and ``margin_floor_factor``; the benchmark asks the planner for r = a
quarter of the robot's own smallest semi-axis). Nothing is exempted at the endpoints: they are
checked with the same grown model (``start_free``, ``goal_free``); with ``endpoint_escape`` (the
default) an endpoint the margin blocks is left by a short segment checked at a finer resolution
with the smaller margin that keeps the same guarantee (:mod:`splatplan.planners.escape`;
``start_escape`` / ``goal_escape``: the resolution divisor used, 1 = free, None = blocked even at
the finest: the problem is not started; ``start_escape_n_sigma`` / ``goal_escape_n_sigma``: the
checker n_sigma of that check, the benchmark's own or a higher one,
:func:`~splatplan.planners.escape.escape_n_sigmas`). With ``check_margin`` the
benchmark measures rho(n) (:func:`~splatplan.scenes.margin.covering_radius`, ``rho_measured_m``)
and reports whether ``m >= rho(n) + r / 2`` held (``bound_holds``).

**Why the default n_sigma is 0.** The margin shrinks with n, but the checker's own reach grows
faster: the linearisation ``s2 - n sigma`` reaches about ``sqrt(a^2 + (n s_t)^2) - a`` beyond a
link of semi-axis a towards a splat beside it, which for the largest splats (s_t ~ 1.5x the sample
spacing) and the Panda's thinnest links is more than the margin saves: fewer endpoints are free at
n_sigma 1, 2, 3 than at 0 (README, MotionBenchMaker). n_sigma 0 with the derived margin is the
least conservative setting that keeps the guarantee.

**Planners.** ``MBMConfig.planners`` lists the planners compared: ``auto`` (ours: RRT-Connect for
the arm), ``rrt``, ``rrtconnect``, or ``ompl:NAME`` (any OMPL geometric planner through
:mod:`splatplan.planners.ompl_bridge`, the ``ompl`` extra). All run on the same checker, time limit,
margin and edge resolution; each (problem, planner) is one row with a ``planner`` field. Ours are
seeded per task (``seed + index``); OMPL's sampler is not seedable from the bridge, so OMPL rows are
not reproducible run to run (``row["seeded"]`` says which rows are).

**The job engine.** Each (problem, planner) is one :class:`~splatplan.eval.engine.Task` whose key
holds a hash of the settings that change a row (not ``families``, ``n_per_family`` or
``planners``: growing a run reuses what is done) and :func:`~splatplan.eval.engine.code_version`.
:func:`run_mbm` maps the pure, module-level :func:`mbm_task` / :func:`solve_problem` over them with
:func:`~splatplan.eval.engine.run_tasks`: serial, or on Dask (``--workers N`` / ``--scheduler
ADDR``). Per worker process, :func:`make_context` loads the robot once and :class:`MBMContext`
caches the last few prepared scenes (splats, exact scene, margin, checker) by problem, so the
planners of one problem share one sampled scene. Results stream to ``OUT/mbm.results.jsonl``; a
rerun resumes; a failed task is recorded (``failures`` in ``mbm.json``). For the same seed a
distributed run gives the same rows as a serial one, except the timing fields
(:data:`TIMING_FIELDS`) and OMPL's rows (see :func:`comparable`).
"""

from __future__ import annotations

import functools
import hashlib
import json
import time
from collections import OrderedDict
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PlanningError, SplatplanError
from ..planners.clearance import dense_path, exact_clearance, path_min_clearance  # noqa: F401 - (also importable from here)
from ..scenes.margin import SplatMargin, covering_radius, derived_margin, margin_for  # noqa: F401 (the margin lives in the scene stage; these names stay importable here)
from ._mbm_config import DEFAULT_MBM, MBM_DATA_ENV, PUBLISHED, MBMConfig, MBMResult, MBMTask, check_planners, mbm_data_dir
from ._mbm_report import report, summarise

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot
    from ..scenes.builtin.analytic_scene import AnalyticScene
    from ..scenes.splats import Splats

__all__ = [
    "DEFAULT_MBM", "MBM_DATA_ENV", "PUBLISHED", "TIMING_FIELDS", "MBMConfig", "MBMContext", "MBMResult", "MBMTask", "check_inputs",
    "check_planners", "comparable", "escape_robot", "list_tasks", "make_context", "mbm_data_dir", "mbm_task", "report", "run_mbm", "settings_hash",
    "solve_problem", "summarise", "task_key",
]  # fmt: skip


@dataclass
class MBMContext:
    """Per-process state shared by the tasks: the config, the robot (loaded once) and the last
    ``max_scenes`` prepared scenes (by scene file), so the planners of one problem share them."""

    config: MBMConfig
    robot: Robot
    scenes: OrderedDict = field(default_factory=OrderedDict)  # scene path -> _Prepared (LRU)
    escape_robot: Robot | None = None  # the tighter model of the escape segments (MBMConfig.escape_ellipsoids)
    max_scenes: int = 2

    def prepared(self, task: "MBMTask") -> "_Prepared":
        """The prepared scene of ``task`` (built on first use, keyed by its scene file; deterministic
        in the config)."""
        scene_path = task.scene
        p = self.scenes.get(scene_path)
        if p is None:
            p = _prepare(task, self.config, self.robot)
            self.scenes[scene_path] = p
            while len(self.scenes) > self.max_scenes:
                _, old = self.scenes.popitem(last=False)
                old.checker.close()
        self.scenes.move_to_end(scene_path)
        return p


@dataclass
class _Prepared:
    """One problem's scene as every planner sees it (all derived from the config's seed)."""

    splats: Splats  # floaters filtered (metres, z-up)
    scene: AnalyticScene  # the exact primitives
    checker: CollisionChecker  # on the splats at config.n_sigma (cpu)
    margin: float  # planning margin (m)
    spacing_nn: float  # median NN distance of the means (m; nan with a fixed margin)
    resolution: float  # edge resolution r (m)
    rho: float  # measured covering radius (m; nan when not checked)
    n_isolated: int  # faint isolated splats dropped (MBMConfig.drop_isolated)
    n_sampled: int  # splats sampled (floaters included, before any filter)
    base_spacing: float  # the sampler's grid spacing (m)
    splat_margin: SplatMargin  # the margin as the planner and the escapes take it (a fixed one knows no tangential std)
    endpoints: dict = field(default_factory=dict)  # request path -> (q0, q1, exact clearance (2,), hit (2,), hit_own (2,), blockers, escapes)


def list_tasks(config: MBMConfig) -> list[MBMTask]:
    """The problems of the configured families, sorted by index (the first ``n_per_family``), each
    once per planner of ``config.planners`` (problem-major: a problem's planners are adjacent)."""
    root = config.problems_dir()
    tasks = []
    for fam in config.families:
        d = root / f"{fam}_panda"
        if not d.is_dir():
            d = root / fam
        if not d.is_dir():
            have = sorted(p.name.removesuffix("_panda") for p in root.iterdir() if p.is_dir())
            raise SplatplanError(f"MBM family {fam!r} not found in {root} (available: {', '.join(have) or 'none'})")
        scenes = sorted(d.glob("scene[0-9]*.yaml"))
        fam_tasks = []
        for s in scenes:
            idx = int(s.stem.removeprefix("scene"))
            req = d / f"request{s.stem.removeprefix('scene')}.yaml"
            if req.is_file():
                fam_tasks += [MBMTask(fam, idx, str(s), str(req), p) for p in config.planners]
        if not fam_tasks:
            raise SplatplanError(f"MBM family {fam!r}: no sceneNNNN.yaml / requestNNNN.yaml pairs in {d}")
        tasks += fam_tasks[: None if config.n_per_family is None else config.n_per_family * len(config.planners)]
    return tasks


def check_inputs(tasks: list[MBMTask], robot: Robot) -> list[MBMTask]:
    """Parse every problem's scene and request once (no sampling), so that bad input stops the run
    with one line before any work (YAML that does not parse, an unknown primitive or a mesh, a
    scene with no objects, joints the robot does not have, a goal outside the joint limits), and
    return the tasks carrying the parsed scene and joint configurations (the workers parse nothing)."""
    from dataclasses import replace

    from ..scenes.moveit import load_moveit_request, load_moveit_scene

    parsed: dict[tuple[str, str], tuple] = {}
    out = []
    for t in tasks:
        if (t.scene, t.request) not in parsed:  # a problem's planners share one parse
            q0, q1 = load_moveit_request(t.request, robot)
            parsed[t.scene, t.request] = (load_moveit_scene(t.scene).to_json(), tuple(map(float, q0)), tuple(map(float, q1)))
        objects, q0, q1 = parsed[t.scene, t.request]
        out.append(replace(t, objects=objects, q_start=q0, q_goal=q1))
    return out


def make_context(config: MBMConfig) -> MBMContext:
    """Load the robot once per process (the job engine calls this once per worker)."""
    from ..robots import load_robot

    return MBMContext(config, load_robot(config.robot_path()), escape_robot=escape_robot(config))


#: the shipped escape model of MBM's Panda (MBMConfig.escape_ellipsoids = "builtin")
BUILTIN_ESCAPE = Path(__file__).resolve().parents[1] / "robots" / "data" / "mbm_panda_tight_wrist.yaml"
#: the URDF it fits: :func:`~splatplan.robots.fit_cache.fit_key` (opt, one per link) of MBM's panda.urdf
#: (collision geometry and mesh contents, not the path: a copy elsewhere matches)
BUILTIN_ESCAPE_URDF = "e8babbe47abe9c3565d2e8d5488424a4"


def escape_robot(config: MBMConfig) -> Robot | None:
    """The escape segments' model (:attr:`MBMConfig.escape_ellipsoids`), or None (the planning model)."""
    from ..robots import load_robot

    e = config.escape_ellipsoids
    if e is None or not config.endpoint_escape:
        return None
    path = config.robot_path()
    if e == "builtin":
        from ..robots.fit_cache import fit_key
        from ..robots.urdf import read_urdf

        if not Path(path).is_file() or fit_key(read_urdf(path), "opt", 1, False)[:32] != BUILTIN_ESCAPE_URDF:
            return None  # (the shipped model is a fit of MBM's own Panda URDF)
        e = str(BUILTIN_ESCAPE)
    return load_robot(path, ellipsoids=e)


#: settings that do not change a row (left out of the task keys: growing a run reuses its rows)
_KEY_FREE = ("families", "n_per_family", "planners")


def settings_hash(config: MBMConfig) -> str:
    """Hash of the settings that change a row, and of splatplan's source (the task keys' prefix)."""
    from .engine import code_version

    d = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(config).items() if k not in _KEY_FREE}
    d["problems"] = str(config.problems_dir().resolve())
    d["robot"] = str(config.robot_path())
    d["code"] = code_version()
    return hashlib.sha1(json.dumps(d, sort_keys=True).encode()).hexdigest()[:10]


def task_key(task: MBMTask, config: MBMConfig, sig: str) -> str:
    """The stable resume key of one (problem, planner)."""
    return f"{sig}/{task.family}/{task.index:04d}/{task.planner}/ns={config.n_sigma:g}"



# ---------------------------------------------------------------------------------------------
# one problem
# ---------------------------------------------------------------------------------------------


def _plan(checker, start, goal, robot, time_limit: float, seed: int, edge_resolution: float, planner: str = "auto", max_iters: int | None = None,
          margin=None, escape_robot=None):  # fmt: skip
    """The public planner with the time limit and the edge resolution the margin was derived with
    (that of the un-inflated robot: the inflated one's default would be coarser and need a larger
    margin), no refinement. With ``max_iters`` our planners run to that iteration budget without a
    wall-clock limit (reproducible); OMPL's keep the time limit. With ``margin`` (a SplatMargin),
    ``robot`` is the robot's own model and the planner grows it and escapes blocked endpoints."""
    from ..planners import RRTConfig, plan

    ours = not planner.startswith("ompl:")
    if max_iters is not None and ours:
        cfg = RRTConfig(time_limit_s=None, max_iters=int(max_iters), edge_resolution=edge_resolution)
    else:
        cfg = RRTConfig(time_limit_s=time_limit, edge_resolution=edge_resolution)
    return plan(checker, start, goal, robot=robot, seed=seed, refine=False, planner=planner, rrt_config=cfg, margin=margin, escape_robot=escape_robot)


def _prepare(task: "MBMTask", cfg: MBMConfig, robot) -> _Prepared:
    """Sample the task's scene into splats (from the parsed scene it carries, else its file), derive
    the margin, measure rho when asked, build the checker."""
    from ..metric import CollisionChecker
    from ..scenes.filters import filter_floaters, isolated_mask
    from ..scenes.builtin.analytic_scene import AnalyticScene
    from ..scenes.builtin.surface_splats import n_splats_for_spacing
    from ..scenes.moveit import build_moveit, load_moveit_scene

    src = AnalyticScene.from_json(task.objects) if task.objects is not None else load_moveit_scene(task.scene)
    n = cfg.n_splats or min(n_splats_for_spacing(src, cfg.splat_spacing_m, seed=cfg.seed), cfg.max_splats)
    splats, scene = build_moveit(src, n_splats=n, seed=cfg.seed)
    base_spacing = float(splats.info["base_spacing"])
    splats, _ = filter_floaters(splats)
    n_isolated = 0
    if cfg.drop_isolated:
        iso = isolated_mask(splats.means, splats.opacities)
        n_isolated = int(iso.sum())
        if n_isolated:
            splats = splats.subset(~iso)
    if cfg.margin_m is None:
        sm = margin_for(splats, robot, cfg.n_sigma, spacing_factor=cfg.margin_spacing_factor, floor_factor=cfg.margin_floor_factor)
    else:
        sm = SplatMargin(float(cfg.margin_m), float("nan"), 0.25 * robot.min_semi_axis, float(cfg.n_sigma))
    rho = covering_radius(scene, splats, base_spacing, n_sigma=cfg.n_sigma, seed=cfg.seed) if cfg.check_margin else float("nan")
    checker = CollisionChecker(splats, n_sigma=cfg.n_sigma, device="cpu")
    return _Prepared(splats, scene, checker, sm.margin, sm.spacing, sm.edge_resolution, rho, n_isolated, n, base_spacing, sm)


def solve_problem(task: MBMTask, ctx: MBMContext) -> dict:
    """Solve one MBM problem with ``task.planner`` (pure: the row depends only on ``task`` and the
    config, whatever the context has cached); returns its row."""
    from ..planners.escape import endpoint_check
    from ..planners.robot_links import robot_collides
    from ..scenes.moveit import load_moveit_request

    cfg, robot = ctx.config, ctx.robot
    t0 = time.perf_counter()
    ours = not task.planner.startswith("ompl:")
    row: dict = {"family": task.family, "index": task.index, "planner": task.planner, "seeded": ours}
    prep = ctx.prepared(task)
    scene, checker, margin, res, rho = prep.scene, prep.checker, prep.margin, prep.resolution, prep.rho
    plan_robot = robot.inflated(margin) if margin > 0 else robot
    row.update(n_splats_sampled=prep.n_sampled, sample_spacing_m=prep.base_spacing, margin_m=margin, spacing_nn_m=prep.spacing_nn, n_isolated_dropped=prep.n_isolated, rho_measured_m=rho, edge_resolution_m=res,
               bound_holds=bool(margin >= rho + 0.5 * res - 1e-12) if cfg.check_margin else None)  # fmt: skip
    if task.request not in prep.endpoints:  # the same for every planner of the problem
        if task.q_start is not None and task.q_goal is not None:
            q0, q1 = np.asarray(task.q_start, dtype=np.float64), np.asarray(task.q_goal, dtype=np.float64)
        else:
            q0, q1 = load_moveit_request(task.request, robot)
        ends = np.stack([q0, q1])
        hit_e = np.asarray(robot_collides(checker, plan_robot, ends))  # (2, E)
        hit = np.asarray(hit_e.any(axis=-1), dtype=bool)  # (2,)
        hit_own = np.asarray(robot_collides(checker, robot, ends)).any(axis=-1) if plan_robot is not robot else hit
        smargin = prep.splat_margin
        can = cfg.endpoint_escape and margin >= 0.5 * res > 0  # (an escape needs a margin with room for r / 2)
        tight = ctx.escape_robot or robot
        escape = [(float(cfg.n_sigma), 1) if not h else (endpoint_check(checker, tight, q, smargin) if can else None) for q, h in zip(ends, hit)]
        prep.endpoints[task.request] = (q0, q1, exact_clearance(scene, robot, ends), hit, hit_own, _blocking(scene, robot, ends, hit_e), escape)
    q0, q1, clear, hit, hit_own, block, escape = prep.endpoints[task.request]
    row.update(start_blocked_by=block[0], goal_blocked_by=block[1])
    row.update(start_valid=bool(clear[0] > 0), goal_valid=bool(clear[1] > 0), start_clearance_m=float(clear[0]), goal_clearance_m=float(clear[1]))
    row.update(start_free=bool(not hit[0]), goal_free=bool(not hit[1]), start_free_unmargined=bool(not hit_own[0]), goal_free_unmargined=bool(not hit_own[1]))
    escapes = ours and cfg.endpoint_escape and margin >= 0.5 * res > 0
    row.update(start_escape=escape[0][1] if escapes and escape[0] else None, goal_escape=escape[1][1] if escapes and escape[1] else None,
               start_escape_n_sigma=escape[0][0] if escapes and escape[0] else None, goal_escape_n_sigma=escape[1][0] if escapes and escape[1] else None)  # fmt: skip
    row["started"] = bool((row["start_free"] and row["goal_free"]) or (escapes and escape[0] is not None and escape[1] is not None))
    row.update(solved=False, time_s=None, cpu_s=None, n_configs=None, n_nodes=None, path_length=None, path=None, min_exact_clearance_m=None, message="", timed_out=False)
    res_p = None
    if row["started"]:
        cpu0 = time.process_time()
        if escapes:  # the planner grows the robot and leaves blocked endpoints (planners.escape)
            try:
                res_p = _plan(checker, q0, q1, robot, cfg.time_limit, cfg.seed + task.index, res, task.planner, cfg.max_iters,
                              margin=prep.splat_margin, escape_robot=ctx.escape_robot)  # fmt: skip
            except PlanningError as exc:  # the endpoint check passed but no escape segment reaches a configuration the full margin frees
                row.update(started=False, message=f"not started: {exc}")
        else:
            res_p = _plan(checker, q0, q1, plan_robot, cfg.time_limit, cfg.seed + task.index, res, task.planner, cfg.max_iters)
    if res_p is not None:
        cpu_s = time.process_time() - cpu0  # this process's CPU seconds (the checker's threads included)
        row.update(solved=bool(res_p.success), time_s=float(res_p.time_s), cpu_s=cpu_s, n_nodes=int(res_p.n_nodes),
                   n_configs=(res_p.info or {}).get("n_configs"), message=str(getattr(res_p, "message", "")))  # fmt: skip
        # the search ran out of its wall-clock budget: how far it got (n_nodes) depends on the machine
        row["timed_out"] = bool(not res_p.success and res_p.time_s >= 0.99 * cfg.time_limit) if (cfg.max_iters is None or not ours) else False
        times = (res_p.info or {}).get("time_split") or (res_p.info or {}).get("times")
        if times is not None:
            row["time_split"] = {k: float(v) for k, v in dict(times).items()}
        if res_p.success:
            path = np.asarray(res_p.path, dtype=np.float64)
            length = getattr(res_p, "length", None)
            if length is None:
                from ..planners.rrt_types import path_length

                length = path_length(path, plan_robot.motion_bound)
            row.update(path_length=float(length), path=path.round(6).tolist())
            row["min_exact_clearance_m"] = _path_clearance(scene, robot, ctx.escape_robot, path, (res_p.info or {}).get("escape"))
    elif not row["message"]:
        row["message"] = ("endpoint in collision for the planning model against the splats, even for the finest endpoint check (an escape)"
                          if escapes else "endpoint in collision for the planning model against the splats")
    row["wall_s"] = time.perf_counter() - t0
    return row


def _path_clearance(scene, robot, escape_robot, path: np.ndarray, escape: dict | None) -> float:
    """The path's exact clearance: each escape segment (the first / last edge of an escaped start /
    goal) with the model it was checked with, the rest with ``robot``."""
    if escape_robot is None or not escape:
        return path_min_clearance(scene, robot, dense_path(robot, path))
    lo = 1 if escape["start"]["escaped"] else 0
    hi = len(path) - 1 if escape["goal"]["escaped"] else len(path)
    parts = [path_min_clearance(scene, robot, dense_path(robot, path[lo:hi]))] if hi - lo >= 1 else []
    for seg in ([path[:2]] if lo else []) + ([path[-2:]] if hi < len(path) else []):
        parts.append(path_min_clearance(scene, escape_robot, dense_path(escape_robot, seg)))
    return float(min(parts))


def _blocking(scene, robot, ends: np.ndarray, hit_e: np.ndarray) -> list:
    """Per endpoint (2, dof): None when free for the planning model, else the link and ellipsoid the
    margin makes collide that is nearest the exact geometry, with that ellipsoid's own exact
    clearance (m): what keeps the endpoint from being called free."""
    out: list[dict | None] = []
    names, link = list(robot.link_names), np.asarray(robot.ellipsoid_link)
    for k in range(len(ends)):
        idx = np.nonzero(hit_e[k])[0]
        if not idx.size:
            out.append(None)
            continue
        c, quat, a = robot.ellipsoids(ends[k : k + 1])
        cl = np.asarray(scene.ellipsoid_clearance(c[0, idx], quat[0, idx], a[idx]), dtype=np.float64)  # (n,)
        j = int(idx[int(np.argmin(cl))])
        out.append({"link": names[int(link[j])] if names else str(j), "ellipsoid": j, "exact_clearance_m": float(cl.min())})
    return out


def mbm_task(spec: dict, ctx: MBMContext) -> dict:
    """The job engine's task function: ``spec`` = the fields of an :class:`MBMTask`."""
    return solve_problem(MBMTask(**spec), ctx)


#: row fields that are wall-clock measurements (differ run to run; left out of :func:`comparable`)
TIMING_FIELDS = ("time_s", "cpu_s", "wall_s", "time_split", "message")


def comparable(row: dict) -> dict | None:
    """The part of a row that a rerun with the same seed reproduces exactly, wherever it runs:
    everything but :data:`TIMING_FIELDS`; None for rows of unseeded planners (OMPL). A search that
    ran out of its wall-clock budget (``timed_out``) reproduces its outcome but not its node count,
    which depends on the machine's speed, so ``n_nodes`` is left out there too."""
    if not row.get("seeded", True):
        return None
    drop = TIMING_FIELDS + (("n_nodes",) if row.get("timed_out") else ())
    return {k: v for k, v in row.items() if k not in drop}



# ---------------------------------------------------------------------------------------------
# the benchmark
# ---------------------------------------------------------------------------------------------


def run_mbm(config: MBMConfig | None = None, out_dir=None, *, engine=None, progress: bool = True) -> MBMResult:
    """Run the benchmark; write ``mbm.results.jsonl`` (streamed), ``mbm.json`` and ``mbm.md`` into
    ``out_dir`` when given (a rerun into the same folder resumes).

    Args:
        config: :class:`MBMConfig` (validated here).
        out_dir: output folder (must exist) or None (results kept in memory only).
        engine: :class:`~splatplan.eval.engine.EngineConfig` or its dict (default serial).
        progress: show the engine's progress bar (on a terminal).
    """
    from .engine import Task, run_tasks

    cfg = (config or MBMConfig()).validate()
    t0 = time.perf_counter()
    robot = make_context(cfg).robot  # the fit is cached: cheap
    # every YAML parsed once, here: bad input is one line before any work (not a failed task per
    # problem), and the tasks carry the parsed scenes and configurations to the workers
    problems = check_inputs(list_tasks(cfg), robot)
    sig = settings_hash(cfg)
    tasks = [Task(task_key(t, cfg, sig), asdict(t)) for t in problems]
    out_path = Path(out_dir) / "mbm.results.jsonl" if out_dir is not None else None
    ran = run_tasks(tasks, mbm_task, functools.partial(make_context, cfg), engine, out_path, progress=progress, desc="mbm")
    rows, failures = [], []
    for t, task in zip(problems, tasks):
        if task.key in ran.rows:
            rows.append(ran.rows[task.key])
        else:
            failures.append({"family": t.family, "index": t.index, "planner": t.planner, "key": task.key, "error": ran.errors.get(task.key, "not run")})
    by_planner = {}
    for p in cfg.planners:
        rp = [r for r in rows if r.get("planner", "auto") == p]
        late = cfg.time_limit if cfg.max_iters is not None else None
        by_planner[p] = {fam: summarise([r for r in rp if r["family"] == fam], late) for fam in cfg.families}
        by_planner[p]["overall"] = summarise(rp, late)
    esc = escape_robot(cfg)
    setup = {
        "robot": str(cfg.robot_path()), "robot_name": robot.name, "n_ellipsoids": robot.n_ellipsoids,
        "escape_model": None if esc is None else {"ellipsoids": str(cfg.escape_ellipsoids if cfg.escape_ellipsoids != "builtin" else BUILTIN_ESCAPE.name),
                                                  "n_ellipsoids": esc.n_ellipsoids},
        "problems": str(cfg.problems_dir()), "device": "cpu",
        "planner": "splatplan.planners.plan (planner=each of config.planners), no refinement",
        "planners": list(cfg.planners),
        "seeding": "ours: seed + problem index per task; OMPL: not seedable (rows not reproducible)",
        "valid": "exact clearance > 0 of the robot's own ellipsoids against the exact primitives (self-collision not checked)",
        "free": "the planning model (robot inflated by margin_m) has no collision against the splats at n_sigma",
        "min_exact_clearance": "path resampled at a quarter of the smallest semi-axis of motion (Robot.motion_bound), own ellipsoids vs exact primitives",
        "timing_note": "wall-clock on this machine (shared CPU cores; contended timings)",
        "engine": ran.engine,
        "tasks": {"total": len(tasks), "run": ran.n_run, "resumed": ran.n_skipped, "failed": len(failures)},
        "settings_hash": sig,
    }  # fmt: skip
    result = MBMResult(cfg, rows, by_planner[cfg.planners[0]], setup, time.perf_counter() - t0, by_planner, failures)
    if out_dir is not None:
        from ._common import write_atomic

        out = Path(out_dir)
        write_atomic(out / "mbm.json", json.dumps(result.to_json(), indent=1) + "\n")
        write_atomic(out / "mbm.md", report(result))
    return result
