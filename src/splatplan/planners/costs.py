"""Composable MPPI cost terms over batches of rollouts (paper Sec. II-D, Eq. 12).

Every cost is a small object; calling it on a :class:`Rollout` of K sampled trajectories of
horizon T returns (K,) float64 costs, **its weight already applied**. :class:`~splatplan.planners.MPPI`
sums a list of them:

    costs = [
        CollisionCost(checker, robot, weight=1.0, hit_weight=10.0),   # every link ellipsoid, one query
        GoalPoseCost(robot, position=(0.5, 0.2, 0.3), quat=(0, 1, 0, 0), link="panda_hand"),
        ControlEffortCost(weight=0.01),
        JointLimitCost(robot, weight=100.0),
        TerminalCost(image_cost, weight=1.0),                          # states at T -> (K,)
    ]
    mppi = MPPI(JointIntegrator(robot), checker, config, costs=costs)

A cost may report several named parts through ``terms(rollout) -> {name: (K,)}`` (the collision
cost reports "collision" and "hit"); ``__call__`` is their sum. Rollout arrays: states (K, T, dx)
after each control step, controls (K, T, du), ``dt`` seconds; quantities derived from the states
that several costs need (the collision query, link poses) are computed once and cached on the
rollout.

The base types (:class:`Rollout`, :class:`Cost`, :func:`evaluate_costs`) live in
:mod:`.cost_base`, the collision cost in :mod:`.collision_cost`; this module holds the goal,
effort, limit and state costs and keeps every cost name importable from here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from .._config import ConfigTerms, bounded
from ..errors import SplatplanError
from ..robots.kinematics import chain_pose, link_chain
from ..robots.robot import Robot
from .collision_cost import CollisionCost, CollisionTerms, StridedCollisionTerms, link_geometry
from .cost_base import Cost, CostValue, Rollout, evaluate_costs, reduce_time, total_cost

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker

__all__ = [
    "CollisionCost", "CollisionTerms", "ControlEffortCost", "Cost", "CostValue", "GoalPoseCost", "JointLimitCost", "JointVelocityTerms",
    "Rollout", "StateCost", "StridedCollisionTerms", "TerminalCost", "UntilGoalCost", "evaluate_costs", "fk_device", "link_geometry",
    "reduce_time", "total_cost",
]  # fmt: skip


@dataclass
class JointVelocityTerms(ConfigTerms):
    """The joint-velocity control fields of an arm task's config (flat in it: ``--arm-w-limits``):
    the velocity bound, and the control-effort and joint-limit costs."""

    #: joint velocity bound as a fraction of the robot's velocity limits
    velocity_scale: float = bounded(0.4, gt=0, le=1)
    #: weight of the control effort sum |qdot|^2 dt
    w_control: float = bounded(0.01, ge=0)
    #: weight of the joint-limit penalty
    w_limits: float = bounded(100.0, ge=0)

    def velocity_bound(self, robot: Robot) -> np.ndarray:
        """(dof,) joint velocity bound (rad/s): ``velocity_scale`` x the robot's velocity limits."""
        return self.velocity_scale * np.asarray(robot.velocity_limits, np.float64)

    def joint_costs(self, robot: Robot) -> list[Cost]:
        """[:class:`ControlEffortCost`, :class:`JointLimitCost` (5 cm / 0.05 rad margin)] of these weights."""
        return [ControlEffortCost(self.w_control), JointLimitCost(robot, weight=self.w_limits, margin=0.05)]


def fk_device(checker: CollisionChecker) -> str:
    """The FK device of :class:`GoalPoseCost` for a checker: the checker's device (the Warp FK kernel
    there, float32). Panda MPPI, K = 256, T = 32, 2-core CPU: 3.3 ms per step against 14 ms for the
    float64 host chain (controls within 1.3e-5 rad/s of it after 12 steps); ~50x on a GPU at K = 1024."""
    return str(getattr(checker, "device", "cpu"))


def _rotation_angle(r: np.ndarray, r_goal: np.ndarray) -> np.ndarray:
    """Geodesic angle (rad) between rotations r (..., 3, 3) and r_goal (3, 3)."""
    tr = np.einsum("...ij,ij->...", r, r_goal)  # trace(r_goal^T r)
    return np.arccos(np.clip(0.5 * (tr - 1.0), -1.0, 1.0))


class GoalPoseCost(Cost):
    """Distance of the end effector (a named link) or of the base / point robot to a goal pose.

    Per time step ``position_weight * |p_t - p_goal| + orientation_weight * angle(R_t, R_goal)``
    (metres / radians), summed over the horizon; the last step is weighted by
    ``1 + terminal_factor``.

    Args:
        robot: a Robot (with ``link``: the link's pose from ``robot.link_poses``); None = the
            position is read from the state itself (``state_dims``, e.g. (0, 1) for a base's x, y
            or (0, 1, 2) for a point robot).
        position: (3,) goal position (world frame) or (len(state_dims),).
        quat: (4,) goal orientation, wxyz, world <- link; None = position only.
        link: link name (default: the robot's last link, e.g. the Panda's hand).
        state_dims: state coordinates that are the position when ``robot`` is None.
        position_weight, orientation_weight: weights of the two parts.
        terminal_factor: extra weight on the final step.
        device: where the link's forward kinematics runs: None = float64 numpy on the host (its
            chain only: the reference); a device name ("cuda:0", "cpu") = the Warp FK kernel there
            (float32): 4x faster on CPU, ~50x on a GPU for K = 1024, T = 32 batches (pass
            :func:`fk_device` of the checker).
    """

    name = "goal"

    def __init__(
        self,
        robot: Robot | None = None,
        position=(0.0, 0.0, 0.0),
        quat=None,
        link: str | None = None,
        state_dims: tuple[int, ...] = (0, 1, 2),
        position_weight: float = 1.0,
        orientation_weight: float = 0.2,
        terminal_factor: float = 0.0,
        device: str | None = None,
    ) -> None:
        self.robot = robot
        self.device = None if device is None else str(device)
        self.position = np.asarray(position, dtype=np.float64).reshape(-1)
        self.state_dims = tuple(int(i) for i in state_dims)
        self.position_weight = float(position_weight)
        self.orientation_weight = float(orientation_weight)
        self.terminal_factor = float(terminal_factor)
        self.r_goal = None
        if quat is not None:
            from ..scenes.splats import quat_to_rotmat

            q = np.asarray(quat, dtype=np.float64).reshape(4)
            if not np.isfinite(q).all() or np.linalg.norm(q) < 1e-8:
                raise SplatplanError(f"GoalPoseCost: the goal quaternion must be finite and non-zero (wxyz), got {quat}")
            self.r_goal = quat_to_rotmat(q / np.linalg.norm(q))
        self.link_index = None
        self._chain = None
        if robot is not None:
            names = list(robot.link_names)
            name = link if link is not None else names[-1]
            if name not in names:
                raise SplatplanError(f"GoalPoseCost: robot {robot.name} has no link {name!r}; links: {', '.join(names)}")
            self.link_index = names.index(name)
            self._chain = link_chain(robot.kin, self.link_index)
            if self.position.shape != (3,):
                raise SplatplanError(f"GoalPoseCost: the goal position must be (3,) for a link, got {self.position.shape}")
        elif self.position.shape != (len(self.state_dims),):
            raise SplatplanError(f"GoalPoseCost: the goal has {self.position.size} coordinates, state_dims has {len(self.state_dims)}")
        if self.r_goal is not None and robot is None:
            raise SplatplanError("GoalPoseCost: an orientation goal needs a robot (link poses)")

    def pose(self, rollout: Rollout) -> tuple[np.ndarray, np.ndarray | None]:
        """Positions (K, T, 3 or len(state_dims)) and rotations (K, T, 3, 3) | None."""
        if self.robot is None:
            return rollout.states[..., list(self.state_dims)], None
        if self.device is not None:
            key: str | tuple[str, int | None] = ("link_pose_fk", self.link_index)
            if key not in rollout.cache:
                c, r = self.robot.fk(rollout.states, device=self.device, links=[self.link_index])  # (K, T, 1, 3), (K, T, 1, 3, 3)
                rollout.cache[key] = (c[..., 0, :].astype(np.float64), r[..., 0, :, :].astype(np.float64))
            return rollout.cache[key]
        if self._chain is None:
            key = "link_poses"
            if key not in rollout.cache:
                rollout.cache[key] = np.asarray(self.robot.link_poses(rollout.states))  # (K, T, L, 4, 4)
            t = rollout.cache[key][..., self.link_index, :, :]
        else:
            key = ("link_pose", self.link_index)
            if key not in rollout.cache:
                rollout.cache[key] = chain_pose(self._chain, np.asarray(rollout.states, dtype=np.float64))  # (K, T, 4, 4)
            t = rollout.cache[key]
        return t[..., :3, 3], t[..., :3, :3]

    def per_step(self, rollout: Rollout) -> np.ndarray:
        """(K, T) weighted cost of every step (before the time sum)."""
        p, r = self.pose(rollout)
        c = self.position_weight * np.linalg.norm(p - self.position, axis=-1)
        if self.r_goal is not None and self.orientation_weight > 0 and r is not None:  # (r_goal needs a robot: r is set)
            c = c + self.orientation_weight * _rotation_angle(r, self.r_goal)
        return c

    def __call__(self, rollout: Rollout) -> np.ndarray:
        c = self.per_step(rollout)
        return c.sum(axis=1) + self.terminal_factor * c[:, -1]


class ControlEffortCost(Cost):
    """``weight * sum_t |u_t|^2 dt + sum_d dim_weights[d] * sum_t u_td^2 dt`` (controls in the
    dynamics' units; ``dim_weights`` {control dimension: extra weight}, e.g. {2: w} for a base's yaw rate)."""

    name = "control"

    def __init__(self, weight: float = 0.01, dim_weights: dict[int, float] | None = None) -> None:
        self.weight = float(weight)
        self.dim_weights = {int(d): float(w) for d, w in (dim_weights or {}).items()}

    def __call__(self, rollout: Rollout) -> np.ndarray:
        c = self.weight * np.sum(rollout.controls**2, axis=(1, 2)) * rollout.dt
        for d, w in self.dim_weights.items():
            c = c + w * np.sum(rollout.controls[..., d] ** 2, axis=1) * rollout.dt
        return c


class JointLimitCost(Cost):
    """Penalty for states near or beyond joint limits: ``weight * sum_{t, j} (max(0, lo_j + m - q) +
    max(0, q - hi_j + m))^2`` with margin m (rad or m), over joints with finite limits."""

    name = "joint_limits"

    def __init__(self, robot: Robot | None = None, weight: float = 100.0, margin: float = 0.0, lower=None, upper=None) -> None:
        if robot is not None:
            lim = np.asarray(robot.joint_limits, dtype=np.float64)
            lower, upper = lim[:, 0], lim[:, 1]
        if lower is None or upper is None:
            raise SplatplanError("JointLimitCost needs a robot or lower and upper limits")
        self.lower = np.asarray(lower, dtype=np.float64).reshape(-1)
        self.upper = np.asarray(upper, dtype=np.float64).reshape(-1)
        self.weight = float(weight)
        self.margin = float(margin)

    def __call__(self, rollout: Rollout) -> np.ndarray:
        q = rollout.states[..., : self.lower.size]
        lo = np.where(np.isfinite(self.lower), self.lower + self.margin, -np.inf)
        hi = np.where(np.isfinite(self.upper), self.upper - self.margin, np.inf)
        v = np.maximum(0.0, lo - q) + np.maximum(0.0, q - hi)  # (K, T, n)
        return self.weight * np.sum(v**2, axis=(1, 2))


class StateCost(Cost):
    """Wraps a callable on the whole state trajectory: states (K, T, dx) -> (K,) or (K, T) (summed).
    ``name`` defaults to the class's (``task``)."""

    name = "task"

    def __init__(self, fn: Callable[[np.ndarray], np.ndarray], weight: float = 1.0, name: str | None = None) -> None:
        self.fn = fn
        self.weight = float(weight)
        self.name = type(self).name if name is None else name

    def states(self, rollout: Rollout) -> np.ndarray:
        """What ``fn`` sees: the whole state trajectory (K, T, dx)."""
        return rollout.states

    def __call__(self, rollout: Rollout) -> np.ndarray:
        return self.weight * reduce_time(self.fn(self.states(rollout)), rollout.k, f"{self.name}_cost")


class TerminalCost(StateCost):
    """Wraps a callable on the terminal states: (K, dx) -> (K,) (e.g. the image cost); ``name``
    defaults to ``terminal``."""

    name = "terminal"

    def states(self, rollout: Rollout) -> np.ndarray:
        """What ``fn`` sees: the terminal states (K, dx)."""
        return rollout.states[:, -1]


class UntilGoalCost(Cost):
    """Path costs on the rollout steps up to the goal time only (:attr:`Rollout.goal_step`; all of
    them when it is None): in a shrinking-horizon MPC the tail beyond the goal time is never
    executed, and costing it (a held velocity carrying the arm into a wall) would trade the goal
    for a phantom collision. Reports the wrapped costs' terms, values and query."""

    name = "path"

    def __init__(self, costs: list[Cost]) -> None:
        self.costs = list(costs)

    def evaluate(self, rollout: Rollout) -> CostValue:
        n = rollout.states.shape[1] if rollout.goal_step is None else int(rollout.goal_step) + 1
        inner = Rollout(rollout.states[:, :n], rollout.controls[:, :n], rollout.dt)
        _, terms, values, query = evaluate_costs(self.costs, inner)
        return CostValue(terms, values, query)

    def terms(self, rollout: Rollout) -> dict[str, np.ndarray]:
        return self.evaluate(rollout).terms

    def __call__(self, rollout: Rollout) -> np.ndarray:
        return np.sum(list(self.terms(rollout).values()), axis=0)
