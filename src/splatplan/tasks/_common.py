"""Shared pieces of the MPPI tasks: scenes, start checks, clearance of an executed trajectory, results."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._config import check_config
from ..errors import SplatplanError
from ..planners.clearance import densify_by_motion, s2_to_metres

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..scenes.builtin.analytic_scene import AnalyticScene
    from ..scenes.splats import Splats


@dataclass
class TaskScene:
    """A scene for a task: the splats, a checker, and the exact geometry when known.

    Attributes:
        name: built-in name or the file path.
        splats: the (floater-filtered) splats.
        checker: :class:`~splatplan.metric.CollisionChecker` at the task's n_sigma.
        analytic: :class:`~splatplan.scenes.builtin.analytic_scene.AnalyticScene` or None (then the
            clearance comes from the metric).
    """

    name: str
    splats: Splats
    checker: CollisionChecker
    analytic: AnalyticScene | None


#: the most rollout steps (samples x horizon x iterations x MPC steps) one task run may take:
#: about 2,000x the default runs, hours on a CPU
MAX_ROLLOUT_STEPS = 1e10


@dataclass
class TaskConfig:
    """Base of the task configs: a subclass embeds ``mppi: MPPIConfig``; :meth:`validate` checks
    every field's declared range (:mod:`splatplan._config`), the embedded MPPIConfig, then the
    task's cross-field rules (:meth:`check`)."""

    def validate(self):
        """Raise SplatplanError naming the field when a value is not allowed; returns self."""
        check_config(self)
        mppi = getattr(self, "mppi", None)  # (none on the bare base)
        if mppi is not None:
            mppi.validate()
            self._check_work(mppi)
        self.check()
        return self

    def _check_work(self, mppi) -> None:
        """The work guard of a run, before it starts: rollout steps = n_iters x n_samples x horizon
        per MPC step, times max_steps (``--arm-mppi-n-iters 100000000`` ran on for minutes)."""
        from .._resources import require_work

        steps = float(getattr(self, "max_steps", 1) or 1)
        work = float(mppi.n_iters) * float(mppi.n_samples) * float(mppi.horizon) * steps
        require_work(work, MAX_ROLLOUT_STEPS, f"{type(self).__name__}: {mppi.n_iters:,} iterations x {mppi.n_samples:,} samples x "
                     f"{mppi.horizon:,} steps x {int(steps):,} MPC steps of rollouts", "mppi.n_iters, mppi.n_samples, mppi.horizon or max_steps",
                     fields=("mppi.n_iters", "mppi.n_samples", "mppi.horizon", "max_steps"))

    def check(self) -> None:
        """The task's cross-field rules (raise SplatplanError); none by default."""


def replace_mppi(cfg, /, **changes):
    """``cfg`` (a task config embedding ``mppi: MPPIConfig``) with the MPPIConfig fields ``changes`` changed."""
    return replace(cfg, mppi=replace(cfg.mppi, **changes))


def load_filtered_scene(scene, n_splats: int | None = None, seed: int = 0):
    """A built-in name or a splat file -> (floater-filtered splats, analytic ground truth or None);
    a file's ground truth is its ``.gt.json`` beside it when present."""
    from ..scenes.builtin import BUILTIN_SCENES, build_builtin
    from ..scenes.filters import filter_floaters

    name = str(scene)
    if name in BUILTIN_SCENES:
        raw, gt = build_builtin(name, seed=seed, n_splats=n_splats)
    else:
        from ..scenes.load import load_scene
        from ..scenes.builtin.stonehenge import ground_truth_path, load_ground_truth

        p = Path(name)
        if not p.is_file():
            raise SplatplanError(f"scene {name!r} is neither a built-in scene ({', '.join(BUILTIN_SCENES)}) nor a file")
        raw = load_scene(p, filter_floaters=False)
        gt = load_ground_truth(p) if ground_truth_path(p).is_file() else None
    splats, _ = filter_floaters(raw)
    return splats, gt


def load_task_scene(scene, n_sigma: float = 1.0, device: str | None = "auto", n_splats: int | None = None, ground_below: float | None = None, terrain=None) -> TaskScene:
    """A built-in name ("tabletop", "apartment", "stonehenge") or a splat file (its ``.gt.json``
    beside it is used for the exact clearance when present).

    ``terrain``: a :class:`~splatplan.scenes.terrain.TerrainConfig` for ground robots: the floor's
    splats (up to the robot's step height above the aligned floor) are terrain, not obstacles,
    and leave the collision scene; so do the analytic boxes labelled "floor"/"ground".
    ``ground_below`` is the same with ``TerrainConfig(floor_z=ground_below, step_height=0)``.
    """
    from ..metric import CollisionChecker
    from ..scenes.terrain import TerrainConfig, remove_terrain

    if isinstance(scene, TaskScene):
        return scene
    name = str(scene)
    splats, gt = load_filtered_scene(name, n_splats=n_splats)
    if terrain is None and ground_below is not None:
        terrain = TerrainConfig(floor_z=float(ground_below), step_height=0.0, rule="shape")  # an arm's ground plane: flat splats below it
    if terrain is not None:
        splats, rep = remove_terrain(splats, terrain, n_sigma=n_sigma)
        if gt is not None:
            gt = gt.select(np.array([lab not in ("floor", "ground") for lab in gt.labels]))
        name = f"{name} (terrain below z = {rep.floor_z + rep.step_height:.3g} removed)"
    return TaskScene(name, splats, CollisionChecker(splats, n_sigma=n_sigma, device=device), gt)


def base_terrain(cfg):
    """The :class:`~splatplan.scenes.terrain.TerrainConfig` of a ground robot's task config, a
    ``BaseConfig`` or ``NavigateConfig`` (fields ``ground_z``: a height, "auto" = fitted, or None = no terrain; ``ground_band``: step height)."""
    from ..scenes.terrain import TerrainConfig

    if cfg.ground_z is None:
        return None
    floor = None if cfg.ground_z == "auto" else float(cfg.ground_z)
    return TerrainConfig(floor_z=floor, step_height=float(cfg.ground_band))


def check_start(robot, checker, q0: np.ndarray) -> None:
    """Raise a :class:`SplatplanError` naming the links (and splat counts) in collision at ``q0``."""
    res = checker.query_robot(robot, np.asarray(q0, np.float64)[None])
    hit = np.asarray(res.in_collision)[0]
    if np.any(hit):
        per_link: dict[str, int] = {}  # link name -> most splats inside one of its ellipsoids (link order)
        for e in np.flatnonzero(hit):
            name = robot.link_names[int(robot.ellipsoid_link[e])]
            per_link[name] = max(per_link.get(name, 0), int(np.asarray(res.n_colliding)[0][e]))
        parts = ", ".join(f"{n} ({c} splats)" for n, c in per_link.items())
        raise SplatplanError(f"the start configuration of {robot.name} is in collision (n_sigma = {checker.n_sigma:g}): {parts}; "
                             "change the start (--start), move the robot's base (--base-pose) or lower n_sigma")  # fmt: skip


def densify(robot, states: np.ndarray, step_m: float = 0.01) -> np.ndarray:
    """Configurations along an executed trajectory (S, dof), linearly interpolated so that no
    ellipsoid point moves more than ``step_m`` between consecutive ones (``robot.motion_bound``):
    :func:`~splatplan.planners.clearance.densify_by_motion`."""
    return densify_by_motion(robot, states, step_m)


def safe_step(robot, checker, dyn, x: np.ndarray, u: np.ndarray, dt: float, step_m: float = 0.01) -> tuple[np.ndarray, np.ndarray | None]:
    """The executed motion of one control period, checked before it is driven: (control, next
    state) of the first of ``u``, ``u / 2``, ``u / 4`` (du,) whose motion over ``dt`` (s) from the
    state ``x`` (dx,) under the dynamics ``dyn`` is collision-free by the metric at every
    configuration of :func:`densify` (``step_m`` of ellipsoid motion: the reported clearance's
    sampling); (zeros, None) when all three collide, and the caller holds the robot still.
    MPPI's rollouts are checked only at their control steps, so at speed a thin obstacle can
    fall between two of them."""
    x = np.asarray(x, np.float64)
    u = np.asarray(u, np.float64)
    for f in (1.0, 0.5, 0.25):
        uf = u * f
        x1 = dyn.rollout(x, uf[None, None, :], dt)[0, 0]  # (dx,)
        q = densify(robot, np.stack([x, x1]), step_m)
        if not np.asarray(checker.collides_robot(robot, q)).any():
            return uf, x1
    return np.zeros_like(u), None


def run_clearance(robot, scene: TaskScene, states: np.ndarray) -> tuple[float, float, str]:
    """Smallest clearances (m) over the densified trajectory: (every ellipsoid's, the moving ellipsoids'
    (:func:`moving_ellipsoids`; the arm's fixed base link sits at a constant distance from the table),
    source).

    Source "analytic": the exact signed distance to the scene's boxes (the minimum of
    :meth:`AnalyticScene.ellipsoid_clearance`, solving only the ellipsoid-box pairs that can hold it:
    :meth:`AnalyticScene.min_ellipsoid_clearance`); "metric": a lower bound from the
    CollisionSplatting metric, ``(sqrt(min s2~) - 1) * smallest semi-axis`` (to the n_sigma-inflated
    splat centres; capped where min s2~ reaches the checker's s2_cap).
    """
    q = densify(robot, states)
    mov = moving_ellipsoids(robot)
    if scene.analytic is not None:
        c, quat, ax = robot.ellipsoids(q)
        ax = np.broadcast_to(np.asarray(ax, np.float64), c.shape)
        moving = scene.analytic.min_ellipsoid_clearance(c[:, mov], quat[:, mov], ax[:, mov])
        fixed = scene.analytic.min_ellipsoid_clearance(c[:, ~mov], quat[:, ~mov], ax[:, ~mov])
        return float(min(moving, fixed)), float(moving), "analytic"
    res = scene.checker.query_robot(robot, q)
    per_e = s2_to_metres(res.min_s2, robot.semi_axes)  # (S', E)
    return float(per_e.min()), float(per_e[:, mov].min()) if mov.any() else float("inf"), "metric"


def moving_ellipsoids(robot) -> np.ndarray:
    """(E,) bool: ellipsoids whose pose depends on the configuration (not fixed to the base)."""
    rng = np.random.default_rng(0)
    lim = np.asarray(robot.joint_limits, np.float64)
    lo = np.where(np.isfinite(lim[:, 0]), lim[:, 0], -1.0)
    hi = np.where(np.isfinite(lim[:, 1]), lim[:, 1], 1.0)
    c, _, _ = robot.ellipsoids(lo + rng.random((4, robot.dof)) * (hi - lo))
    return np.ptp(c, axis=0).max(axis=-1) > 1e-9


CLEARANCE_NOTES = {
    "analytic": "exact signed distance from every robot ellipsoid to the scene's analytic geometry (negative = penetration)",
    "metric": "no analytic geometry: lower bound (sqrt(min s2~) - 1) * smallest semi-axis from the CollisionSplatting metric at the task's n_sigma",
}


@dataclass
class TaskResult:
    """What a reaching / driving run produced (``to_json`` gives the CLI's result.json)."""

    success: bool
    trajectory: np.ndarray  # (S + 1, dof) executed configurations
    min_clearance_m: float
    final_position_error_m: float
    time_s: float
    steps_per_s: float
    collision_cost: bool
    clearance_source: str
    final_orientation_error_deg: float = float("nan")
    message: str = ""
    goal: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    #: arrays for pictures only, not written to JSON (the base's sensed-obstacle memory: "memory_blocked"
    #: (NX, NY) bool, "memory_sensed" (NX, NY) bool, "memory_origin" (2,) world xy of the grid corner, "memory_cell" m)
    maps: dict = field(default_factory=dict)

    @classmethod
    def of_run(cls, robot, ts, states, error: float, tol: float, elapsed: float, n_steps: int, collision, clearance=None, **fields) -> "TaskResult":
        """The result of a run whose executed configurations ``states`` (S + 1, dof) end ``error`` (m)
        from the goal: success = ``error < tol`` with a positive clearance of the whole executed
        trajectory (:func:`run_clearance`; ``clearance``: its output for ``states`` when the caller
        has it); ``fields``: goal, extra, maps, ..."""
        traj = np.asarray(states)
        clearance, _, source = run_clearance(robot, ts, traj) if clearance is None else clearance
        success = bool(error < tol and clearance > 0)
        return cls(success=success, trajectory=traj, min_clearance_m=clearance, final_position_error_m=error, time_s=elapsed,
                   steps_per_s=n_steps / elapsed if elapsed > 0 else float("nan"), collision_cost=bool(collision), clearance_source=source,
                   message="" if success else ("in collision" if clearance <= 0 else "goal not reached within max_steps"), **fields)  # fmt: skip

    def to_json(self) -> dict:
        d = asdict(self)
        d.pop("maps", None)
        d["trajectory"] = np.asarray(self.trajectory).round(6).tolist()
        d["clearance_note"] = CLEARANCE_NOTES[self.clearance_source]
        if not self.collision_cost:
            d["note"] = "--no-collision: the collision cost was OFF for this run"
        for k, v in list(d.items()):
            if isinstance(v, float) and not np.isfinite(v):
                d[k] = None
        return d
