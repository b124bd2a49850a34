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
checked with the same grown model (``start_free``, ``goal_free``). With ``check_margin`` the
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
import os
import time
from collections import OrderedDict
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._config import bounded, check_config
from ..errors import SplatplanError
from ..planners.clearance import dense_path, exact_clearance, path_min_clearance  # noqa: F401 - (also importable from here)
from ..scenes.margin import covering_radius, derived_margin  # noqa: F401 (the margin lives in the scene stage; these names stay importable here)

if TYPE_CHECKING:
    from ..robots.robot import Robot

#: the repository root (src/splatplan/eval/mbm.py -> 3 levels up); shared data lives beside it
_REPO = Path(__file__).resolve().parents[3]
#: environment variable naming the MBM data folder (``problems/`` + ``panda/``) when --problems /
#: --robot are not given
MBM_DATA_ENV = "SPLATPLAN_MBM_DATA"
DEFAULT_MBM = _REPO / ".." / "shared" / "data" / "mbm"  # a source checkout's sibling data folder


def mbm_data_dir() -> Path:
    """The MBM data folder: ``$SPLATPLAN_MBM_DATA``, else the source checkout's ``../shared/data/mbm``
    (an installed package has none: then give --problems and --robot, or set the variable)."""
    env = os.environ.get(MBM_DATA_ENV, "").strip()
    return Path(env) if env else DEFAULT_MBM

#: Published reference numbers (../shared/data/mbm/README.md): same 700 problems, 7 families.
PUBLISHED = {
    "VAMP": {
        "solved": "699/700 (99.86%)", "median_time_s": 35e-6, "mean_time_s": 76e-6, "p95_time_s": 343e-6,
        "robot_model": "59 spheres (0.90x the mesh volume, 26-73% of each link's surface covered)",
        "scene": "exact primitives (also a point cloud via CAPT: median 111 us + 2-7 ms to build)",
        "hardware": "one core of an AMD Ryzen 9 7950X (SIMD RRT-Connect)",
    },
    "cuRobo v2": {
        "solved": "99.73%", "median_time_s": 35e-3, "mean_time_s": None, "p95_time_s": None,
        "robot_model": "spheres", "scene": "exact primitives (MBM + MpiNets problems)",
        "hardware": "GPU, NVIDIA RTX 6000 Ada",
    },
}  # fmt: skip


@dataclass
class MBMConfig:
    """Knobs of the MBM benchmark (defaults = the full run; :meth:`quick` = the CI smoke version)."""

    #: folder holding <family>_panda/sceneNNNN.yaml + requestNNNN.yaml; none = <repo>/../shared/data/mbm/problems
    problems: str | None = None
    #: families to run (folder names without the "_panda" suffix)
    families: tuple[str, ...] = ("table_pick", "box", "bookshelf_small")
    #: problems per family (the first N by index); none = all
    n_per_family: int | None = bounded(None, ge=1)
    #: metric conservatism of the planner's collision checks (0 = splat means, the default: with the
    #: derived margin the least conservative safe setting; see the module docstring)
    n_sigma: float = bounded(0.0, ge=0)
    #: surface sampling spacing of each scene (m; the built-in real-capture look): a scene gets
    #: (exposed area / spacing^2) splats (scenes.builtin.surface_splats.n_splats_for_spacing), so a
    #: large cell is sampled as densely as a small one. The safety margin is ~3.4x the splats'
    #: median nearest-neighbour spacing h (~0.6x this): 3.5 mm gives h ~ 2.2 mm and a ~7.6 mm margin,
    #: below the ~1 cm between a grasp pose's fingers and its object (on the MBM workcells, 5.7-6.5
    #: m^2 of surface: 480-560k splats; a real capture of such a cell has 0.3-3M). At 100k splats
    #: (h ~ 5 mm, margin ~16 mm) most grasp goals cannot be called free
    splat_spacing_m: float = bounded(3.5e-3, gt=0, le=1.0)
    #: a fixed splat count per scene instead (none = from splat_spacing_m)
    n_splats: int | None = bounded(None, ge=1000)
    #: most splats per scene from splat_spacing_m (a larger scene is sampled more coarsely; each
    #: row records its count and spacing, and the derived margin follows the coarser spacing)
    max_splats: int = bounded(3_000_000, ge=1000)
    #: after the paper's floater filter, also drop the faint isolated splats it keeps
    #: (:func:`~splatplan.scenes.filters.isolated_mask`: opacity < 0.3 and a mean 8-NN distance above
    #: 3x the scene's median; surfaces are dense and opaque splats are never dropped, so the margin's
    #: covering argument is untouched). Real captures and the sampler's look both carry such floaters
    #: in free space, and the denser the scene, the more of them stand in a robot's way
    drop_isolated: bool = True
    #: planning time limit per problem (s)
    time_limit: float = bounded(10.0, gt=0)
    #: robot URDF (or a built-in name, e.g. panda); none = <repo>/../shared/data/mbm/panda/panda.urdf
    robot: str | None = None
    #: planning margin (m) added around every ellipsoid (Robot.inflated); none = derived per scene
    #: from the splats and n_sigma (see margin_spacing_factor); 0 = plan with the robot's own model
    margin_m: float | None = bounded(None, ge=0)
    #: derived margin = max(this x h - n_sigma x s_t, margin_floor_factor x h) + r/2, h = median
    #: nearest-neighbour distance of the splat means, s_t = median middle std of the splats (the
    #: sampler's covering radius measured 2.3-2.6 h at n_sigma 0: 3 keeps the bound with room)
    margin_spacing_factor: float = bounded(3.0, ge=0)
    #: the derived margin's estimate of the covering radius never drops below this x h, whatever
    #: n_sigma (the splats' offsets along the surface normal are not covered by their tangential extent)
    margin_floor_factor: float = bounded(0.5, ge=0)
    #: measure the true covering radius rho(n_sigma) from the ground truth (diagnostic: did
    #: m >= rho + r/2 hold? ~1 s per scene at n_sigma 0, tens of seconds above; off by default)
    check_margin: bool = False
    #: iteration budget of our planners' searches (reproducible benchmark mode: the search and
    #: shortcut then run without a wall-clock limit, so no row depends on the machine's speed; the
    #: summary counts solutions slower than time_limit as solved_late); none = time_limit ends the search
    max_iters: int | None = bounded(None, ge=1)
    #: scene sampling and planner seed (an integer >= 0)
    seed: int = bounded(0, ge=0)
    #: planners to compare, each on the same checker, time limit and margin: auto / rrt / rrtconnect
    #: (ours, seeded) or ompl:NAME (an OMPL geometric planner, e.g. ompl:RRTConnect, ompl:BITstar,
    #: ompl:PRM; the 'ompl' extra; not seedable)
    planners: tuple[str, ...] = ("auto",)

    @classmethod
    def quick(cls) -> "MBMConfig":
        """One problem per family, 30k splats, 5 s limit: the CI smoke version (< ~30 s)."""
        return cls(n_per_family=1, n_splats=30_000, time_limit=5.0)

    def validate(self) -> "MBMConfig":
        check_config(self)  # every field's range and finiteness (named Class.field)
        if not self.families:
            raise SplatplanError("MBMConfig.families: give at least one family")
        check_planners(self.planners)
        return self

    def problems_dir(self) -> Path:
        d = Path(self.problems) if self.problems else mbm_data_dir() / "problems"
        if not d.is_dir():
            how = "" if self.problems else f" (the default: ${MBM_DATA_ENV}/problems, else the source checkout's ../shared/data/mbm)"
            raise SplatplanError(f"MBM problems folder {d} not found{how}: pass --problems DIR (holding <family>_panda/sceneNNNN.yaml + "
                                 f"requestNNNN.yaml) or set {MBM_DATA_ENV}")  # fmt: skip
        return d

    def robot_path(self) -> Path | str:
        """The URDF path (or a built-in robot name such as "panda")."""
        from ..robots import KNOWN

        if self.robot in KNOWN:
            return self.robot
        p = Path(self.robot) if self.robot else mbm_data_dir() / "panda" / "panda.urdf"
        if not p.is_file():
            raise SplatplanError(f"robot URDF {p} not found: pass --robot URDF" + ("" if self.robot else f" or set {MBM_DATA_ENV}"))
        return p


def check_planners(names) -> tuple[str, ...]:
    """Validate planner names (ours, or ``ompl:NAME`` with the extra installed and NAME one of
    OMPL's geometric planners); a one-line :class:`SplatplanError` otherwise."""
    from ..planners import PLANNERS

    names = tuple(names)
    if not names:
        raise SplatplanError("MBMConfig.planners: give at least one planner (e.g. auto,ompl:RRTConnect)")
    if len(set(names)) != len(names):
        raise SplatplanError(f"MBMConfig.planners: a planner is listed twice in {','.join(names)}")
    for n in names:
        if n in PLANNERS:
            continue
        if not n.startswith("ompl:"):
            raise SplatplanError(f"MBMConfig.planners: unknown planner {n!r}: use {', '.join(PLANNERS)} or ompl:NAME (e.g. ompl:RRTConnect)")
        from ..planners.ompl_bridge import available_planners  # the install hint when the extra is missing

        have = available_planners()
        if n[5:] not in have:
            raise SplatplanError(f"MBMConfig.planners: unknown OMPL planner {n[5:]!r}: available: {', '.join(have)}")
    return names


@dataclass(frozen=True)
class MBMTask:
    """One (problem, planner): what a worker needs to solve it (plain data, picklable, JSON-able).

    ``objects`` (the parsed scene, :meth:`AnalyticScene.to_json`) and ``q_start`` / ``q_goal`` come
    from :func:`check_inputs`, which parses every YAML once before the run, so the workers never
    parse them again; without them (a task built by hand) the worker reads the files."""

    family: str
    index: int
    scene: str  # path of sceneNNNN.yaml
    request: str  # path of requestNNNN.yaml
    planner: str = "auto"  # a name of MBMConfig.planners
    objects: dict | None = None  # the parsed scene (AnalyticScene.to_json), or None
    q_start: tuple[float, ...] | None = None  # (dof,) from the request, or None
    q_goal: tuple[float, ...] | None = None  # (dof,)


@dataclass
class MBMContext:
    """Per-process state shared by the tasks: the config, the robot (loaded once) and the last
    ``max_scenes`` prepared scenes (by scene file), so the planners of one problem share them."""

    config: MBMConfig
    robot: object  # splatplan.robots.Robot
    scenes: OrderedDict = field(default_factory=OrderedDict)  # scene path -> _Prepared (LRU)
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

    splats: object  # splatplan.scenes.Splats, floaters filtered (metres, z-up)
    scene: object  # splatplan.scenes.builtin.analytic_scene.AnalyticScene: the exact primitives
    checker: object  # CollisionChecker on the splats at config.n_sigma (cpu)
    margin: float  # planning margin (m)
    spacing_nn: float  # median NN distance of the means (m; nan with a fixed margin)
    resolution: float  # edge resolution r (m)
    rho: float  # measured covering radius (m; nan when not checked)
    n_isolated: int  # faint isolated splats dropped (MBMConfig.drop_isolated)
    n_sampled: int  # splats sampled (floaters included, before any filter)
    base_spacing: float  # the sampler's grid spacing (m)
    endpoints: dict = field(default_factory=dict)  # request path -> (q0, q1, exact clearance (2,), hit (2,), hit_own (2,))


@dataclass
class MBMResult:
    """Rows, per-family and overall summaries, and what was run."""

    config: MBMConfig
    rows: list[dict]  # one per (problem, planner) that finished, problem-major
    summary: dict[str, dict]  # family / "overall" -> summary, of the first planner (ours by default)
    setup: dict = field(default_factory=dict)
    time_s: float = 0.0
    summary_by_planner: dict[str, dict] = field(default_factory=dict)  # planner -> family -> summary
    failures: list[dict] = field(default_factory=list)  # tasks recorded as failed, with their error

    def to_json(self) -> dict:
        return {"study": "mbm", "config": asdict(self.config), "engine": self.setup.get("engine", {"kind": "serial"}), "setup": self.setup,
                "summary": self.summary, "summary_by_planner": self.summary_by_planner, "rows": self.rows, "failures": self.failures,
                "published": PUBLISHED, "time_s": self.time_s}  # fmt: skip


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

    return MBMContext(config, load_robot(config.robot_path()))


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
# exact clearance and the margin
# ---------------------------------------------------------------------------------------------




# ---------------------------------------------------------------------------------------------
# one problem
# ---------------------------------------------------------------------------------------------


def _plan(checker, start, goal, robot, time_limit: float, seed: int, edge_resolution: float, planner: str = "auto", max_iters: int | None = None):
    """The public planner with the time limit and the edge resolution the margin was derived with
    (that of the un-inflated robot: the inflated one's default would be coarser and need a larger
    margin), no refinement. With ``max_iters`` our planners run to that iteration budget without a
    wall-clock limit (reproducible); OMPL's keep the time limit."""
    from ..planners import RRTConfig, plan

    ours = not planner.startswith("ompl:")
    if max_iters is not None and ours:
        cfg = RRTConfig(time_limit_s=None, max_iters=int(max_iters), edge_resolution=edge_resolution)
    else:
        cfg = RRTConfig(time_limit_s=time_limit, edge_resolution=edge_resolution)
    return plan(checker, start, goal, robot=robot, seed=seed, refine=False, planner=planner, rrt_config=cfg)


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
        margin, h_nn, res = derived_margin(robot, splats.means, cfg.margin_spacing_factor, n_sigma=cfg.n_sigma, scales=splats.scales,
                                           floor_factor=cfg.margin_floor_factor)  # fmt: skip
    else:
        margin, h_nn, res = float(cfg.margin_m), float("nan"), 0.25 * robot.min_semi_axis
    rho = covering_radius(scene, splats, base_spacing, n_sigma=cfg.n_sigma, seed=cfg.seed) if cfg.check_margin else float("nan")
    checker = CollisionChecker(splats, n_sigma=cfg.n_sigma, device="cpu")
    return _Prepared(splats, scene, checker, margin, h_nn, res, rho, n_isolated, n, base_spacing)


def solve_problem(task: MBMTask, ctx: MBMContext) -> dict:
    """Solve one MBM problem with ``task.planner`` (pure: the row depends only on ``task`` and the
    config, whatever the context has cached); returns its row."""
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
        hit = hit_e.any(axis=-1)
        hit_own = np.asarray(robot_collides(checker, robot, ends)).any(axis=-1) if plan_robot is not robot else hit
        prep.endpoints[task.request] = (q0, q1, exact_clearance(scene, robot, ends), hit, hit_own, _blocking(scene, robot, ends, hit_e))
    q0, q1, clear, hit, hit_own, block = prep.endpoints[task.request]
    row.update(start_blocked_by=block[0], goal_blocked_by=block[1])
    row.update(start_valid=bool(clear[0] > 0), goal_valid=bool(clear[1] > 0), start_clearance_m=float(clear[0]), goal_clearance_m=float(clear[1]))
    row.update(start_free=bool(not hit[0]), goal_free=bool(not hit[1]), start_free_unmargined=bool(not hit_own[0]), goal_free_unmargined=bool(not hit_own[1]))
    row.update(solved=False, time_s=None, cpu_s=None, n_configs=None, n_nodes=None, path_length=None, path=None, min_exact_clearance_m=None, message="", timed_out=False)
    if row["start_free"] and row["goal_free"]:
        cpu0 = time.process_time()
        res_p = _plan(checker, q0, q1, plan_robot, cfg.time_limit, cfg.seed + task.index, res, task.planner, cfg.max_iters)
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
            row["min_exact_clearance_m"] = path_min_clearance(scene, robot, dense_path(robot, path))
    else:
        row["message"] = "endpoint in collision for the planning model against the splats"
    row["wall_s"] = time.perf_counter() - t0
    return row


def _blocking(scene, robot, ends: np.ndarray, hit_e: np.ndarray) -> list:
    """Per endpoint (2, dof): None when free for the planning model, else the link and ellipsoid the
    margin makes collide that is nearest the exact geometry, with that ellipsoid's own exact
    clearance (m): what keeps the endpoint from being called free."""
    out = []
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


def _pct(v: np.ndarray, q: float) -> float | None:
    return float(np.percentile(v, q)) if len(v) else None


def _rho(r: dict) -> float:
    """A row's measured rho (nan when not measured: the results file stores NaN as null)."""
    v = r.get("rho_measured_m")
    return float("nan") if v is None else float(v)


def _any_rho(rows: list[dict]) -> bool:
    """Whether rho was measured for any of the rows."""
    return any(np.isfinite(_rho(r)) for r in rows)


def summarise(rows: list[dict], time_limit: float | None = None) -> dict:
    """Valid / free endpoints, solved / free, median / p95 time, worst clearance (for a list of
    rows); with ``time_limit`` (the iteration-budget mode), also how many solutions took longer."""
    n = len(rows)
    both_free = [r for r in rows if r["start_free"] and r["goal_free"]]
    solved = [r for r in both_free if r["solved"]]
    t = np.array([r["time_s"] for r in solved], dtype=np.float64)
    clear = np.array([r["min_exact_clearance_m"] for r in solved], dtype=np.float64)
    return {
        "n_problems": n,
        "valid_endpoints": int(sum(r["start_valid"] + r["goal_valid"] for r in rows)),
        "valid_endpoints_frac": sum(r["start_valid"] + r["goal_valid"] for r in rows) / (2 * n) if n else None,
        "problems_both_valid": int(sum(r["start_valid"] and r["goal_valid"] for r in rows)),
        "free_endpoints": int(sum(r["start_free"] + r["goal_free"] for r in rows)),
        "free_endpoints_frac": sum(r["start_free"] + r["goal_free"] for r in rows) / (2 * n) if n else None,
        "free_endpoints_unmargined_frac": sum(r["start_free_unmargined"] + r["goal_free_unmargined"] for r in rows) / (2 * n) if n else None,
        "problems_both_free": len(both_free),
        "solved": len(solved),
        "solved_of_free_frac": len(solved) / len(both_free) if both_free else None,
        "median_time_s": _pct(t, 50),
        "p95_time_s": _pct(t, 95),
        "median_cpu_s": _pct(np.array([r["cpu_s"] for r in solved if r.get("cpu_s") is not None], dtype=np.float64), 50),
        "median_configs": _pct(np.array([r["n_configs"] for r in solved if r.get("n_configs") is not None], dtype=np.float64), 50),
        "worst_exact_clearance_m": float(clear.min()) if len(clear) else None,
        "negative_clearance_paths": int(np.sum(clear < 0)),
        "solved_late": None if time_limit is None else int(np.sum(t > time_limit)),
        "margin_m_median": _pct(np.array([r["margin_m"] for r in rows]), 50),
        "rho_measured_m_max": float(np.nanmax([_rho(r) for r in rows])) if rows and _any_rho(rows) else None,
        "bound_holds": int(sum(bool(r["bound_holds"]) for r in rows)),
        "not_free_below_margin": _not_free_below_margin(rows),
        "blocked_by_link": _blocked_by_link(rows),
    }


def _blocked_by_link(rows: list[dict]) -> dict[str, int]:
    """How many endpoints that are not free each link blocks (``*_blocked_by``)."""
    out: dict[str, int] = {}
    for r in rows:
        for end in ("start", "goal"):
            b = r.get(f"{end}_blocked_by")
            if b:
                out[b["link"]] = out.get(b["link"], 0) + 1
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def _not_free_below_margin(rows: list[dict]) -> int:
    """Endpoints that are not free for the planning model and whose exact clearance (own model vs
    the primitives) is below the row's margin: no check from the splats alone that keeps the
    zero-negative-clearance guarantee (margin >= rho + r/2) can call those free at this splat
    density; only more splats (rho ~ spacing ~ 1/sqrt(n_splats)) can."""
    n = 0
    for r in rows:
        for end in ("start", "goal"):
            c = r.get(f"{end}_clearance_m")
            n += int(not r[f"{end}_free"] and c is not None and c < r["margin_m"])
    return n


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
    setup = {
        "robot": str(cfg.robot_path()), "robot_name": robot.name, "n_ellipsoids": robot.n_ellipsoids,
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


def _engine_text(e: dict | None) -> str:
    if not e or e.get("kind") != "dask":
        return "serial"
    return f"dask ({e.get('workers')} workers at {e.get('scheduler')})"


def _frac_pct(v) -> str:
    return "" if v is None else f" ({100 * v:.0f}%)"


def _fmt(v, spec: str, scale: float = 1.0, none: str = "-") -> str:
    return none if v is None else format(v * scale, spec)


def _margin_text(cfg: MBMConfig) -> str:
    if cfg.margin_m is not None:
        return format(cfg.margin_m, "g") + " m"
    f, fl = format(cfg.margin_spacing_factor, "g"), format(cfg.margin_floor_factor, "g")
    return f"derived (max({f} h - {cfg.n_sigma:g} s_t, {fl} h) + r/2)" if cfg.n_sigma > 0 else f"derived ({f} x NN spacing h + r/2)"


def _density_text(rows: list[dict], cfg: MBMConfig) -> str:
    """How densely the scenes were sampled: the fixed count, or the spacing and the counts it gave."""
    if cfg.n_splats:
        return f"{cfg.n_splats:,} splats per scene"
    n = [r["n_splats_sampled"] for r in rows if r.get("n_splats_sampled")]
    got = f" ({min(n):,}-{max(n):,} splats per scene)" if n else ""
    return f"sampled at {1e3 * cfg.splat_spacing_m:g} mm spacing{got}"


def report(result: MBMResult) -> str:
    """Markdown: one row per family and overall, then the published numbers and what differs."""
    cfg = result.config
    lines = [
        f"MBM on splats: {_density_text(result.rows, cfg)} (floaters: the paper's rule{', then isolated faint splats' if cfg.drop_isolated else ''}), n_sigma {cfg.n_sigma:g}, "
        f"margin {_margin_text(cfg)}, "
        f"time limit {cfg.time_limit:g} s{'' if cfg.max_iters is None else f' (searches run to {cfg.max_iters:,} iterations, no wall-clock limit)'}, robot {Path(result.setup.get('robot', '?')).name} ({result.setup.get('n_ellipsoids')} ellipsoids), "
        f"planner {cfg.planners[0]} (table below: every planner), engine {_engine_text(result.setup.get('engine'))}",
        "",
        "| family | problems | valid endpoints | free endpoints (own model) | both free | solved / free | median time (s) | p95 time (s) | worst exact clearance (mm) | paths < 0 | margin (mm) | rho max (mm) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for fam, s in result.summary.items():
        n = s["n_problems"]
        if not n:
            continue
        lines.append(
            f"| {fam} | {n} | {s['valid_endpoints']}/{2 * n} ({100 * s['valid_endpoints_frac']:.0f}%) | "
            f"{s['free_endpoints']}/{2 * n} ({100 * s['free_endpoints_frac']:.0f}%; {100 * s['free_endpoints_unmargined_frac']:.0f}%) | {s['problems_both_free']} | "
            f"{s['solved']}/{s['problems_both_free']}{_frac_pct(s['solved_of_free_frac'])} | "
            f"{_fmt(s['median_time_s'], '.3g')} | {_fmt(s['p95_time_s'], '.3g')} | {_fmt(s['worst_exact_clearance_m'], '+.2f', 1e3)} | "
            f"{s['negative_clearance_paths']} | {_fmt(s['margin_m_median'], '.1f', 1e3)} | {_fmt(s['rho_measured_m_max'], '.1f', 1e3)} |"
        )
    o = result.summary.get("overall", {})
    if o.get("n_problems") and o.get("not_free_below_margin") is not None:
        n_not = 2 * o["n_problems"] - o["free_endpoints"]
        lines += ["", f"Endpoints not free for the planning model: {n_not}; of them {o['not_free_below_margin']} lie closer to the "
                      "real geometry (exact clearance) than the margin, so no splat-only check that keeps the guarantee can free them "
                      "at this splat density (the margin scales with the splat spacing, ~1/sqrt(n_splats))."]  # fmt: skip
    late = result.summary.get("overall", {}).get("solved_late")
    if late is not None:
        lines += ["", (f"Searches ran to {cfg.max_iters:,} iterations with no wall-clock limit (reproducible anywhere): "
                       f"{late} of the solutions took longer than the {cfg.time_limit:g} s time limit on this machine.")]  # fmt: skip
    if result.summary_by_planner:
        lines += ["", "Planners (same splats, checker, margin, edge resolution and time limit; ours seeded, OMPL's not):", "",
                  "| planner | family | solved / free | median time (s) | p95 time (s) | worst exact clearance (mm) | paths < 0 |",
                  "|---|---|---|---|---|---|---|"]  # fmt: skip
        for p, per in result.summary_by_planner.items():
            for fam, s in per.items():
                if not s["n_problems"]:
                    continue
                lines.append(f"| {p} | {fam} | {s['solved']}/{s['problems_both_free']}{_frac_pct(s['solved_of_free_frac'])} | "
                             f"{_fmt(s['median_time_s'], '.3g')} | {_fmt(s['p95_time_s'], '.3g')} | "
                             f"{_fmt(s['worst_exact_clearance_m'], '+.2f', 1e3)} | {s['negative_clearance_paths']} |")  # fmt: skip
    if result.failures:
        lines += ["", f"{len(result.failures)} task(s) failed (see failures in mbm.json): "
                  + "; ".join(f"{f['family']}/{f['index']} {f['planner']}: {f['error'][:120]}" for f in result.failures[:5])]  # fmt: skip
    lines += ["", "Published (same benchmark, 7 families x 100 problems; see ../shared/data/mbm/README.md):", "",
              "| planner | solved | median time | p95 time | robot model | scene | hardware |", "|---|---|---|---|---|---|---|"]  # fmt: skip
    for name, p in PUBLISHED.items():
        lines.append(f"| {name} | {p['solved']} | {_fmt(p['median_time_s'], '.3g')} s | {_fmt(p['p95_time_s'], '.3g')} s | {p['robot_model']} | {p['scene']} | {p['hardware']} |")
    lines += [
        "",
        "What differs here: the scene is splats sampled from the exact primitives (the published planners check the primitives "
        "themselves or a point cloud); the robot is the URDF's ellipsoid model grown by the safety margin; collision checks run "
        "on this machine's shared CPU cores (Warp kernels), timings are contended; only the families listed above were run.",
        "",
    ]
    return "\n".join(lines)
