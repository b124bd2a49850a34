"""Base study: the Go2 driving from the living room of ``apartment`` to goals in the other rooms,
given **only the goal position** (as the final node of an RRT path would be): with the collision
cost (plain MPPI), with the collision cost and the sensed-obstacle memory
(:class:`~splatplan.planners.memory.ObstacleMemory`, ``BaseConfig.memory``), and without the collision
cost.

Goals: random positions in the bedroom and the kitchen where the Go2 stands collision-free at some
heading with at least 10 cm exact clearance. Start (-2.3, -0.6, yaw 0) in the living room: the
straight line to the kitchen goals runs into the 0.25 m living-kitchen doorway (narrower than the
Go2), a trap that the local planner (:mod:`splatplan.tasks.base`) must get out of through the
0.8 m doorway near the outer wall or through the bedroom. Plain MPPI does not (the kitchen goals
fail with and without the optional stagnation sweeps); with the memory, the goal cost follows the
geodesic distance on the cells sensed so far (unknown = free) that were in the sensor's line of
sight (``BaseConfig.sensor_occlusion``), and the base learns the walls where it sees them. The base's metric runs at
n_sigma = 0.75 (:class:`~splatplan.tasks.base.BaseConfig`; at 1 the 0.8 m living-kitchen doorway
admits no collision-free pose); the reported clearance is the exact one to the boxes.

``run(BaseStudyConfig()) -> BaseStudyResult``; ``report(result, out)`` writes ``base.json`` (same row fields as the arm study, plus the time to
goal; ``rows_meaning`` says what each row is, ``memory_cost`` the time spent sensing (of it
``sight_s`` on the line of sight) and on the geodesic field) and ``base.md``.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from .._config import NESTED_SKIP, bounded
from ..tasks._common import replace_mppi
from ..tasks.base import START, BaseConfig  # START: (-2.3, -0.6, yaw 0) in the living room
from ._common import config_rows, mean_std
from ._study import StudyResult, TaskStudyConfig, write_outputs

#: The rows: config name -> (collision cost, memory, what the row is).
CONFIGS = {
    "with_collision": (True, False, "plain MPPI with the collision cost, straight-line goal term (shows the local minimum)"),
    "with_collision_memory": (True, True, "the same plus the sensed-obstacle memory: geodesic goal term on the cells sensed within sensor_radius_m and in line of sight (the target row)"),
    "without_collision": (False, False, "no collision cost (baseline: drives through the walls)"),
}


def pick_goals(n: int, seed: int = 0, min_clearance: float = 0.1) -> list[np.ndarray]:
    """``n`` goal positions (2,) alternating bedroom / kitchen, free for the Go2 at some heading."""
    from ..scenes.builtin.apartment import ROOMS, apartment_layout
    from ..tasks.base import load_go2

    robot = load_go2()
    gt = apartment_layout(seed).scene
    gt = gt.select(np.array([lab != "floor" for lab in gt.labels]))
    rng = np.random.default_rng([seed, 88])
    rooms = ["bedroom", "kitchen"]
    out: list[np.ndarray] = []
    for k in range(400):
        if len(out) == n:
            break
        lo, hi = (np.asarray(v, np.float64) for v in ROOMS[rooms[len(out) % 2]])
        xy = lo + 0.3 + rng.random(2) * (hi - lo - 0.6)
        yaws = np.linspace(-np.pi, np.pi, 8, endpoint=False)
        q = np.stack([np.full(8, xy[0]), np.full(8, xy[1]), yaws], axis=1)
        c, qq, a = robot.ellipsoids(q)
        if gt.ellipsoid_clearance(c, qq, a).min(axis=-1).max() >= min_clearance:
            out.append(xy)
    return out


def _study_task() -> BaseConfig:
    return BaseConfig(max_steps=250)


@dataclass
class BaseStudyConfig(TaskStudyConfig):
    """Knobs of the base study (defaults = the full run; :meth:`quick_config` = the smoke version)."""

    #: goals, alternating bedroom / kitchen (each run in every row of CONFIGS)
    n_goals: int = bounded(5, ge=1)
    #: the base task's settings (``memory`` is set per row; the noise seed is seed + goal index)
    task: BaseConfig = field(default_factory=_study_task, metadata={NESTED_SKIP: ("mppi.seed", "memory")})
    #: goal and noise seed (an integer >= 0)
    seed: int = bounded(0, ge=0)

    @classmethod
    def quick_config(cls) -> "BaseStudyConfig":
        """2 goals (the bedroom, then the kitchen behind the narrow doorway), 130 MPC steps (< 1 min on 2 cores)."""
        return cls(n_goals=2, task=replace(_study_task(), max_steps=130), quick=True)


@dataclass
class BaseStudyResult(StudyResult):
    """What the base study measured: ``data`` is the content of ``base.json``."""


def _trial(i: int, g: np.ndarray, name: str, r) -> dict:
    """The JSON record of one run."""
    mem = r.extra["memory"] or {}
    keys = ("n_sensed", "n_blocked", "n_queries", "n_recomputes", "sense_s", "first_sense_s", "field_s", "occlusion", "n_rays", "n_occluded", "n_opacity_queries", "sight_s")
    return {
        "goal": i, "config": name, "goal_position": g.round(4).tolist(),
        "success": r.success, "min_clearance_m": r.min_clearance_m, "final_error_m": r.final_position_error_m,
        "time_to_goal_s": r.extra["time_to_goal_s"] if r.success else None, "n_steps": r.extra["n_steps"],
        "time_s": r.time_s, "steps_per_s": r.steps_per_s, "n_detours": sum(e["event"] == "detour" for e in r.extra["events"]),
        "memory": {k: mem.get(k) for k in keys} if mem else None,
    }  # fmt: skip


def run(config: BaseStudyConfig | None = None, engine=None) -> BaseStudyResult:
    """Run the base study (module docstring); writes nothing (see :func:`report`). ``engine`` is
    accepted for the study convention; the runs are serial."""
    from ..tasks._common import base_terrain, load_task_scene
    from ..tasks.base import load_go2, run_base

    cfg = (config or BaseStudyConfig()).validate()
    seed, device, task = cfg.seed, cfg.device, replace_mppi(cfg.task, seed=cfg.seed)
    t0 = time.perf_counter()
    goals = pick_goals(cfg.n_goals, seed=seed)
    robot = load_go2()
    ts = load_task_scene("apartment", n_sigma=task.n_sigma, device=device, terrain=base_terrain(task))
    trials = []
    for i, g in enumerate(goals):
        for name, (collision, memory, _) in CONFIGS.items():
            r = run_base(robot, ts, g, start=START, config=replace(replace_mppi(task, seed=seed + i), memory=memory), collision=collision, device=device)
            trials.append(_trial(i, g, name, r))
            print(f"  goal {i} {g.round(2).tolist()} {name:22s}: distance {r.final_position_error_m:.2f} m, clearance {r.min_clearance_m * 100:+.1f} cm, "
                  f"{'reached' if r.success else 'not reached'}, {r.extra['n_steps']} steps, {r.steps_per_s:.2f} steps/s", flush=True)  # fmt: skip
    rows = config_rows(trials, ("min_clearance_m", "final_error_m"), configs=tuple(CONFIGS),
                        extra=lambda t: {"time_to_goal_s": mean_std([x["time_to_goal_s"] for x in t if x["time_to_goal_s"] is not None])})  # fmt: skip
    mt = [x for x in trials if x["memory"]]
    sensing = {
        "sense_s": float(sum(x["memory"]["sense_s"] for x in mt)), "first_sense_s": float(sum(x["memory"]["first_sense_s"] or 0.0 for x in mt)), "field_s": float(sum(x["memory"]["field_s"] for x in mt)),
        "sight_s": float(sum(x["memory"].get("sight_s") or 0.0 for x in mt)), "occlusion": bool(task.sensor_occlusion), "sensor_height_m": float(task.sensor_height_m),
        "run_s": float(sum(x["time_s"] for x in mt)), "n_steps": int(sum(x["n_steps"] for x in mt)),
    }  # fmt: skip
    return BaseStudyResult({
        "study": "base", "quick": bool(cfg.quick), "seed": int(seed), "robot": "go2", "scene": "apartment", "start": list(START),
        "n_splats": len(ts.splats), "config": asdict(task), "time_s": time.perf_counter() - t0,
        "clearance": "exact signed distance from every Go2 ellipsoid to the boxes other than the floor, over the executed trajectory",
        "success": f"final distance to the goal < {task.goal_tol} m and positive clearance throughout",
        "rows": rows, "rows_meaning": {k: v[2] for k, v in CONFIGS.items()}, "memory_cost": sensing, "trials": trials,
    })  # fmt: skip


def markdown(result: BaseStudyResult) -> str:
    """The base study's table and notes."""
    d = result.to_json()
    sensing = d["memory_cost"]
    md = ["| config | min clearance (m) | final distance (m) | time to goal (s) | successes | positive clearance | steps/s |", "|---|---|---|---|---|---|---|"]
    for r in d["rows"]:
        md.append(f"| {r['config']} | {r['min_clearance_m'][0]:+.4f} ± {r['min_clearance_m'][1]:.4f} | {r['final_error_m'][0]:.3f} ± {r['final_error_m'][1]:.3f} | "
                  f"{r['time_to_goal_s'][0]:.1f} | {r['successes']}/{r['trials']} | {r['positive_clearance']}/{r['trials']} | {r['steps_per_s'][0]:.2f} |")  # fmt: skip
    md.append("")
    md += [f"- `{k}`: {v[2]}" for k, v in CONFIGS.items()]
    if sensing["run_s"] > 0:
        md.append(f"- memory cost over the `with_collision_memory` runs: sensing {sensing['sense_s']:.1f} s + geodesic field {sensing['field_s']:.1f} s "
                  f"of {sensing['run_s']:.1f} s ({100 * (sensing['sense_s'] + sensing['field_s']) / sensing['run_s']:.0f} %, {sensing['n_steps']} MPC steps; "
                  f"the first sense of each run, the whole disc, {sensing['first_sense_s']:.1f} s of it"
                  + (f"; line of sight at z = {sensing['sensor_height_m']:.2f} m, {sensing['sight_s']:.1f} s of the sensing)" if sensing["occlusion"] else "; no occlusion: senses through walls)"))  # fmt: skip
    return "\n".join(md) + "\n"


def report(result: BaseStudyResult, out_dir) -> list[Path]:
    """Write ``base.json`` and ``base.md`` into ``out_dir`` (an existing folder); returns their paths."""
    return write_outputs(out_dir, "base", result.to_json(), markdown(result), indent=1)
