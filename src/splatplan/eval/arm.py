"""Arm study: the Panda reaching end-effector targets behind the front wall of ``tabletop``, with
and without the collision cost (paper Table IV without the image cost).

Targets: random positions in :data:`~splatplan.scenes.builtin.tabletop.TARGET_REGION` (inside the
bin, behind its 0.24 m front wall) with the gripper pointing down at a random yaw in [-0.4, 0.4]
rad; a target is kept only when IK finds a goal configuration whose exact clearance to the boxes is
at least 1 cm (so a collision-free goal exists). Each target is run twice from :data:`START_Q`:
MPPI with the collision cost over every Panda ellipsoid, and without it.

The start holds the gripper (pointing down) *in front of* the front wall, 9 cm below its top
(tool centre at (0.34, 0, 0.06) m, world frame): the target is behind the wall as seen from the
hand, so the direct motion cuts through the wall and the arm must lift over it. From the home
configuration (hand 0.49 m up, far above the 0.15 m wall top) the unconstrained motion mostly
passes over the wall by itself (1 of 5 targets penetrated), which tests little.

``run(ArmStudyConfig()) -> ArmStudyResult``; ``report(result, out)`` writes ``arm.json`` =
{"rows": [{config, min_clearance_m [mean, std], final_error_m [mean, std], successes, trials, ...}],
"trials": [...]} and ``arm.md``.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._config import NESTED_SKIP, bounded
from ..robots.builtin import DEFAULT_MODEL, PANDA_MODELS
from ..tasks._common import replace_mppi
from ..tasks.arm import ArmConfig
from ._common import config_rows
from ._study import StudyResult, TaskStudyConfig, write_outputs

if TYPE_CHECKING:
    from ..robots.robot import Robot

#: Start configuration of the study (rad): gripper down, tool centre at (0.34, 0, 0.06) m in front of
#: the front wall (IK of that pose; 4.5 cm exact clearance of the moving links).
START_Q = (0.0, 0.1053, 0.0, -2.8923, 0.0, 2.9976, 0.7854)


def pick_targets(n: int, seed: int = 0, min_goal_clearance: float = 0.01, max_tries: int = 40, robot: Robot | str = "panda") -> list[tuple[np.ndarray, np.ndarray]]:
    """``n`` (position (3,), wxyz quat (4,)) targets behind the wall with a collision-free IK goal
    (the goal clearance of ``robot``'s ellipsoids, a Robot or a name)."""
    from ..robots import load_robot
    from ..scenes.builtin.tabletop import TARGET_REGION, tabletop_layout
    from ..robots.ik import solve_ik
    from ..robots.ik import down_quat

    robot = load_robot(robot)
    gt = tabletop_layout(seed).scene
    rng = np.random.default_rng([seed, 77])
    lo, hi = TARGET_REGION
    out: list[tuple[np.ndarray, np.ndarray]] = []
    for _ in range(max_tries):
        if len(out) == n:
            break
        p = lo + rng.random(3) * (hi - lo)
        quat = down_quat(rng.uniform(-0.4, 0.4))
        q, pe, re = solve_ik(robot, p, quat, link="panda_hand_tcp", n_seeds=24, n_iters=60, seed=int(rng.integers(1 << 30)))
        ok = (pe < 3e-3) & (re < np.deg2rad(2.0))
        if not ok.any():
            continue
        c, qq, a = robot.ellipsoids(q[ok])
        if gt.ellipsoid_clearance(c, qq, a).min(axis=-1).max() >= min_goal_clearance:
            out.append((p, quat))
    return out


def arm_throughput(n_samples: int = 256, horizon: int = 32, n_steps: int = 3, device: str | None = "auto", n_splats: int = 200_000, robot: Robot | str = "panda") -> dict:
    """MPC steps/s of the Panda (``robot``: a Robot or a name) under MPPI with the collision cost on
    every ellipsoid at every step of the horizon (stride 1, one iteration per step), on a
    ``n_splats`` tabletop (warm-up step first). The issue's target: >= 5 steps/s at K = 256, T = 32
    on a 200k-splat scene (CPU)."""
    from ..robots import load_robot
    from ..tasks._common import load_task_scene
    from ..robots.ik import down_quat
    from ..tasks.arm import ArmConfig, run_arm

    robot = load_robot(robot)
    ts = load_task_scene("tabletop", device=device, n_splats=n_splats)
    base = ArmConfig()
    cfg = replace(replace_mppi(base, n_samples=n_samples, horizon=horizon), collision_stride=1, max_steps=1, stop_tol=0.0)
    run_arm(robot, ts, [0.64, 0.0, 0.0], down_quat(), config=cfg, check_goal=False, device=device)  # warm-up (kernels, grids)
    r = run_arm(robot, ts, [0.64, 0.0, 0.0], down_quat(), config=replace(cfg, max_steps=n_steps), check_goal=False, device=device)
    return {"n_samples": n_samples, "horizon": horizon, "n_splats": len(ts.splats), "n_ellipsoids": robot.n_ellipsoids, "collision_stride": 1,
            "steps_per_s": r.steps_per_s, "device": str(ts.checker.device)}  # fmt: skip


def _study_task() -> "ArmConfig":
    from ..tasks.arm import ArmConfig

    return ArmConfig(max_steps=150)


@dataclass
class ArmStudyConfig(TaskStudyConfig):
    """Knobs of the arm study (defaults = the full run; :meth:`quick_config` = the smoke version)."""

    #: targets behind the wall (each run with and without the collision cost)
    n_targets: int = bounded(5, ge=1)
    #: the arm task's settings (its noise seed is seed + target index)
    task: ArmConfig = field(default_factory=_study_task, metadata={NESTED_SKIP: ("mppi.seed",)})
    #: measure the MPC rate at K = 256, T = 32 on a 200k-splat tabletop (arm_throughput)
    throughput: bool = True
    #: target and noise seed (an integer >= 0)
    seed: int = bounded(0, ge=0)
    #: the built-in Panda's collision model (tight: certified, several ellipsoids per link; coarse: one per link)
    robot_model: str = bounded(DEFAULT_MODEL, choices=tuple(PANDA_MODELS))

    @classmethod
    def quick_config(cls) -> "ArmStudyConfig":
        """2 targets with the full run's task settings, no throughput row (< 1 min on 2 cores). Fewer
        samples, a shorter horizon or a collision stride above 1 let the arm touch the wall or stop short."""
        return cls(n_targets=2, throughput=False, quick=True)


@dataclass
class ArmStudyResult(StudyResult):
    """What the arm study measured: ``data`` is the content of ``arm.json``."""

    @property
    def rows(self) -> list[dict]:
        return self.data["rows"]


def run(config: ArmStudyConfig | None = None, engine=None) -> ArmStudyResult:
    """Run the arm study (module docstring); writes nothing (see :func:`report`). ``engine`` is
    accepted for the study convention; the runs are serial."""
    from ..robots import load_robot
    from ..tasks._common import load_task_scene
    from ..tasks.arm import run_arm

    cfg = (config or ArmStudyConfig()).validate()
    seed, device, task = cfg.seed, cfg.device, replace_mppi(cfg.task, seed=cfg.seed)
    t0 = time.perf_counter()
    robot = load_robot("panda", model=cfg.robot_model)
    targets = pick_targets(cfg.n_targets, seed=seed, robot=robot)
    ts = load_task_scene("tabletop", n_sigma=task.n_sigma, device=device)
    trials = []
    for i, (p, quat) in enumerate(targets):
        for collision in (True, False):
            r = run_arm(robot, ts, p, quat, config=replace_mppi(task, seed=seed + i), collision=collision, q0=np.asarray(START_Q), device=device)
            trials.append({
                "target": i, "config": "with_collision" if collision else "without_collision", "goal_position": p.round(4).tolist(),
                "goal_quat_wxyz": quat.round(4).tolist(), "success": r.success, "min_clearance_m": r.min_clearance_m, "min_clearance_moving_links_m": r.extra["min_clearance_moving_links_m"],
                "final_error_m": r.final_position_error_m, "final_orientation_error_deg": r.final_orientation_error_deg,
                "n_steps": r.extra["n_steps"], "time_s": r.time_s, "steps_per_s": r.steps_per_s,
            })  # fmt: skip
            print(f"  target {i} {'with   ' if collision else 'without'} collision cost: error {r.final_position_error_m * 100:.2f} cm, "
                  f"{r.final_orientation_error_deg:.1f} deg, clearance {r.min_clearance_m * 100:+.2f} cm, {r.steps_per_s:.2f} steps/s", flush=True)  # fmt: skip
    rows = config_rows(trials, ("min_clearance_m", "min_clearance_moving_links_m", "final_error_m", "final_orientation_error_deg"))
    throughput = arm_throughput(device=device, robot=robot) if cfg.throughput else None
    return ArmStudyResult({
        "throughput": throughput,
        "study": "arm", "quick": bool(cfg.quick), "seed": int(seed), "robot": "panda", "robot_model": cfg.robot_model,
        "n_ellipsoids": robot.n_ellipsoids, "scene": "tabletop", "n_splats": len(ts.splats), "config": asdict(task), "time_s": time.perf_counter() - t0,
        "clearance": "exact signed distance from every Panda ellipsoid (incl. the fixed base link, 2.2 cm above the table) to the boxes, over the executed trajectory densified to <= 1 cm motion",
        "start_q": list(START_Q),
        "success": "final end-effector position error < 2 cm and positive clearance throughout",
        "rows": rows, "trials": trials,
    })  # fmt: skip


def markdown(result: ArmStudyResult) -> str:
    """The arm study's table."""
    md = ["| config | min clearance (m) | min clearance, moving links (m) | final error (m) | orientation error (deg) | successes | positive clearance | steps/s |", "|---|---|---|---|---|---|---|---|"]
    for r in result.rows:
        md.append(f"| {r['config']} | {r['min_clearance_m'][0]:+.4f} ± {r['min_clearance_m'][1]:.4f} | {r['min_clearance_moving_links_m'][0]:+.4f} ± {r['min_clearance_moving_links_m'][1]:.4f} | {r['final_error_m'][0]:.4f} ± {r['final_error_m'][1]:.4f} | "
                  f"{r['final_orientation_error_deg'][0]:.1f} ± {r['final_orientation_error_deg'][1]:.1f} | {r['successes']}/{r['trials']} | {r['positive_clearance']}/{r['trials']} | {r['steps_per_s'][0]:.2f} |")  # fmt: skip
    return "\n".join(md) + "\n"


def report(result: ArmStudyResult, out_dir) -> list[Path]:
    """Write ``arm.json`` and ``arm.md`` into ``out_dir`` (an existing folder); returns their paths."""
    return write_outputs(out_dir, "arm", result.to_json(), markdown(result), indent=1)
