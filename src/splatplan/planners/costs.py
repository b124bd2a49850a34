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
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import numpy as np

from .._config import ConfigTerms, bounded
from ..errors import SplatplanError
from ..metric.config import QueryResult
from ..robots.kinematics import chain_pose, link_chain
from ..robots.robot import Robot
from .dynamics import Dynamics, DynamicsModel
from .robot_links import LinkGeometry

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker


@dataclass
class Rollout:
    """K sampled trajectories of horizon T.

    Attributes:
        states: (K, T, dx) states after each control step (x_1 .. x_T).
        controls: (K, T, du) controls.
        dt: control period (s).
        goal_step: index of the step at the goal time (a shrinking-horizon MPC: T - 1 - s after s
            executed steps); costs that end at the goal time (:class:`ImageCost`,
            :class:`UntilGoalCost`) read it. None = the last step.
        cache: a private memo of the costs (link poses, their collision query) so that several
            costs share them; what a cost reports goes into its :class:`CostValue` instead.
    """

    states: np.ndarray
    controls: np.ndarray
    dt: float
    goal_step: int | None = None
    cache: dict = field(default_factory=dict)

    @property
    def k(self) -> int:
        return int(self.states.shape[0])


def reduce_time(c, k: int, what: str) -> np.ndarray:
    """(K,) or (K, T, ...) costs -> (K,) (summed over everything but K)."""
    c = np.asarray(c, dtype=np.float64)
    if c.shape == (k,):
        return c
    if c.ndim >= 2 and c.shape[0] == k:
        return c.reshape(k, -1).sum(axis=1)
    raise SplatplanError(f"{what} must return (K,) or (K, T) costs for K = {k}, got shape {c.shape}")


class _DynamicsLinks:
    """The link ellipsoids of a dynamics model built without a Robot (``HolonomicPoint()``,
    ``PlanarBase(height=...)``): queries only, no configuration metric. Goes once every dynamics
    model carries a Robot."""

    robot = None
    weights = None
    dof = None

    def __init__(self, dynamics: Dynamics) -> None:
        self.dynamics = dynamics
        self.n_queries = 0

    def query(self, checker: CollisionChecker, q: np.ndarray) -> QueryResult:
        res = checker.query(*self.dynamics.link_poses(np.asarray(q, dtype=np.float64)))
        self.n_queries += int(np.size(res.min_s2))
        return res


def link_geometry(source: Robot | Dynamics | LinkGeometry) -> LinkGeometry | _DynamicsLinks:
    """The link geometry of a Robot or of a dynamics model (its ``robot``; its own ``link_poses``
    when it has no Robot), or a geometry given as is."""
    if isinstance(source, (LinkGeometry, _DynamicsLinks)):
        return source
    if isinstance(source, Robot):
        return LinkGeometry(source)
    if isinstance(source, Dynamics):
        robot = getattr(source, "robot", None)  # a model built from a Robot carries it (DynamicsModel.robot)
        return LinkGeometry(robot) if robot is not None else _DynamicsLinks(source)
    raise SplatplanError(f"cannot get robot geometry from {type(source).__name__}: give a Robot or a dynamics model")


@dataclass
class CostValue:
    """What one cost reports on a batch of K rollouts (:meth:`Cost.evaluate`).

    Attributes:
        terms: name -> (K,) weighted terms (summed into the total).
        values: name -> per-sample diagnostics, unweighted (e.g. "image_raw": (K,)).
        query: the collision QueryResult (K, T', L) of a collision cost, else None.
    """

    terms: dict
    values: dict = field(default_factory=dict)
    query: QueryResult | None = None


class Cost:
    """Base class: ``terms(rollout) -> {name: (K,)}``, ``__call__(rollout) -> (K,)`` (weighted);
    ``evaluate(rollout) -> CostValue`` adds what the cost has to report beside its terms."""

    name = "cost"

    def terms(self, rollout: Rollout) -> dict[str, np.ndarray]:
        return {self.name: self(rollout)}

    def evaluate(self, rollout: Rollout) -> CostValue:
        return CostValue(self.terms(rollout))

    def __call__(self, rollout: Rollout) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError


class CollisionCost(Cost):
    """CollisionSplatting cost over every robot ellipsoid (paper Eq. 12).

    ``weight * sum_{t, e} cost_{kte} + hit_weight * #{(t, e): ellipsoid e in collision at t}``, from
    **one** ``query_robot`` (or ``query`` after host FK) on the whole (K, T, dof) batch.

    Static ellipsoids (``robot.static_ellipsoids``: on links fixed to the world, e.g. the Panda's
    link0) have the same pose in every sample and step, so their query result is computed once
    (per checker config) and only the moving ellipsoids are queried on the (K, T) batch; the
    result (and every cost) is the same as querying all of them (``static_shortcut=False``),
    up to the float32 summation order of the per-splat cost sum.

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker`.
        robot: a Robot, a dynamics model, or a :class:`LinkGeometry`.
        weight: weight of the summed collision cost.
        hit_weight: extra cost per (time step, ellipsoid) in collision.
        s2_cap: neighbourhood of the query (the checker's ``s2_cap``): beyond it a splat's cost
            ``d_max exp(-gamma (s2~ - 1))`` is below ``exp(-gamma (cap - 1))``; a smaller cap is a
            much smaller search radius. None = the checker's own.
        self_collision_weight: cost per time step with a self-collision (``robot.self_collision``);
            0 = off.
        time_stride: evaluate every ``time_stride``-th step only (the last step always), the sums
            scaled by ``time_stride``: ``time_stride`` times fewer queries, at the risk of stepping
            over a thin obstacle between evaluated steps. 1 (default) = every step (the paper).
            ``"auto"``: the largest stride s with ``s * m <= max_gap_m``, where
            ``m = sum_j motion_bound_j * speed_bound_j * dt`` bounds how far any point of any
            ellipsoid moves in one control step (:attr:`Robot.motion_bound`); so no ellipsoid point
            moves more than ``max_gap_m`` between two evaluated steps (stride 1 when one step
            already moves more).
        max_gap_m: the gap of ``time_stride="auto"`` (scene units); None = half the smallest
            semi-axis of the moving ellipsoids.
        speed_bound: (dof,) bound on ``|dq_j / dt|`` for ``time_stride="auto"``; None = from the
            dynamics model given as ``robot`` (a :class:`JointIntegrator`'s velocity clip, a
            :class:`PlanarBase`'s body-frame limits), else ``robot.velocity_limits``.
        static_shortcut: query static ellipsoids once (see above); False = query every ellipsoid
            on the whole batch.
    """

    name = "collision"

    def __init__(
        self,
        checker: CollisionChecker,
        robot: Robot | Dynamics | LinkGeometry,
        weight: float = 1.0,
        hit_weight: float = 10.0,
        s2_cap: float | None = 2.0,
        self_collision_weight: float = 0.0,
        time_stride: int | str = 1,
        max_gap_m: float | None = None,
        speed_bound=None,
        static_shortcut: bool = True,
    ) -> None:
        self.checker = checker.with_config(s2_cap=s2_cap) if s2_cap is not None else checker
        self.geometry = link_geometry(robot)
        self.weight = float(weight)
        self.hit_weight = float(hit_weight)
        self.self_collision_weight = float(self_collision_weight)
        rob = self.geometry.robot
        use_static = static_shortcut and rob is not None and bool(np.any(rob.static_ellipsoids))
        #: (E,) bool static ellipsoids answered from the cache, or None (every ellipsoid queried)
        self.static = np.asarray(rob.static_ellipsoids, dtype=bool) if use_static else None
        self._static_cache: dict = {}
        self.auto_stride = isinstance(time_stride, str)
        if self.auto_stride:
            if time_stride != "auto":
                raise SplatplanError(f"CollisionCost.time_stride must be an integer >= 1 or 'auto', got {time_stride!r}")
            if self.geometry.weights is None:
                raise SplatplanError("CollisionCost(time_stride='auto') needs a Robot (its motion_bound): build the dynamics model from one")
            self.speed_bound = _speed_bound(robot, self.geometry) if speed_bound is None else np.asarray(speed_bound, dtype=np.float64).reshape(-1)
            if self.speed_bound.shape != (self.geometry.dof,) or not np.all(np.isfinite(self.speed_bound)) or np.any(self.speed_bound < 0):
                raise SplatplanError(f"CollisionCost: speed_bound must be {self.geometry.dof} finite values >= 0, got {self.speed_bound}")
            if max_gap_m is None:
                ax = np.asarray(rob.semi_axes, dtype=np.float64)
                moving = ax if self.static is None or self.static.all() else ax[~self.static]
                max_gap_m = 0.5 * float(moving.min())
            if not (np.isfinite(max_gap_m) and max_gap_m > 0):
                raise SplatplanError(f"CollisionCost.max_gap_m must be finite and > 0, got {max_gap_m}")
            self.max_gap_m = float(max_gap_m)
            self.time_stride = 1
        else:
            if int(time_stride) < 1:
                raise SplatplanError(f"CollisionCost.time_stride must be >= 1, got {time_stride}")
            self.time_stride = int(time_stride)
            self.max_gap_m = None
            self.speed_bound = None

    def step_motion(self, dt: float) -> float:
        """Bound on how far any ellipsoid point moves in one control step of ``dt`` s ("auto" mode)."""
        return float(self.geometry.motion(self.speed_bound * float(dt)))

    def stride(self, dt: float, t_len: int) -> int:
        """The time stride used for a horizon of ``t_len`` steps of ``dt`` s (see ``time_stride``)."""
        if not self.auto_stride:
            return self.time_stride
        m = self.step_motion(dt)
        if m <= 0:
            return max(1, int(t_len))
        return int(min(max(1, np.floor(self.max_gap_m / m * (1 + 1e-12))), max(1, t_len)))

    def steps(self, t_len: int, dt: float | None = None) -> np.ndarray:
        """Indices of the evaluated time steps (every stride-th, ending at the last)."""
        s = self.time_stride if dt is None else self.stride(dt, t_len)
        return np.arange(t_len - 1, -1, -s)[::-1]

    def _static_result(self) -> QueryResult:
        """Query result (E_static,) of the static ellipsoids, computed once per checker config."""
        key = (id(self.checker), repr(self.checker.config))
        hit = self._static_cache.get(key)
        if hit is None:
            rob = self.geometry.robot
            res = self.checker.query_robot(rob, np.asarray(rob.q_default, dtype=np.float64)[None])  # (1, E)
            hit = QueryResult(**{f: np.asarray(v)[0, self.static].copy() for f, v in res.as_dict().items()})
            self._static_cache = {key: hit}
        return hit

    def _query_states(self, states: np.ndarray):
        """QueryResult (..., E) of every ellipsoid at configurations ``states`` (..., dof)."""
        if self.static is None:
            return self.geometry.query(self.checker, states)
        rob = self.geometry.robot
        st = self.static
        mv = ~st
        static = self._static_result()
        lead = states.shape[:-1]
        if not mv.any():
            return QueryResult(**{f: np.broadcast_to(v, lead + v.shape).copy() for f, v in static.as_dict().items()})
        # FK of the moving ellipsoids and the metric on the checker's device (self.static implies query_robot)
        res = self.checker.query_robot(rob, states, ellipsoids=np.flatnonzero(mv))  # (..., E_moving)
        self.geometry.n_queries += int(np.size(res.min_s2))
        out = {}
        for f, v in res.as_dict().items():
            v = np.asarray(v)
            a = np.empty(lead + (st.size,), dtype=v.dtype)
            a[..., mv] = v
            a[..., st] = getattr(static, f)
            out[f] = a
        return QueryResult(**out)

    def query(self, rollout: Rollout):
        """The QueryResult of the evaluated steps, (K, T', L) (computed once per rollout)."""
        key = ("collision_query", id(self))
        if key not in rollout.cache:
            t_len = rollout.states.shape[1]
            s = self.stride(rollout.dt, t_len)
            states = rollout.states if s == 1 else rollout.states[:, self.steps(t_len, rollout.dt)]
            rollout.cache[key] = (self._query_states(states), s)
        return rollout.cache[key][0]

    def _sums(self, res, k: int, scale: float) -> dict[str, np.ndarray]:
        """The weighted "collision" and "hit" sums (k,) of a QueryResult (k, ...), times ``scale``."""
        return {
            "collision": scale * self.weight * np.asarray(res.cost, dtype=np.float64).reshape(k, -1).sum(axis=1),
            "hit": scale * self.hit_weight * np.asarray(res.in_collision).reshape(k, -1).sum(axis=1).astype(np.float64),
        }

    def self_terms(self, rollout: Rollout) -> dict[str, np.ndarray]:
        """{"self_collision": (K,)} when ``self_collision_weight`` > 0, else {}."""
        robot = self.geometry.robot
        if self.self_collision_weight > 0 and robot is not None:
            return {"self_collision": self.self_collision_weight * np.asarray(robot.self_collision(rollout.states)).reshape(rollout.k, -1).sum(axis=1).astype(np.float64)}
        return {}

    def chunk_terms(self, states: np.ndarray, scale: float) -> dict[str, np.ndarray]:
        """"collision" and "hit" sums (K',) of configurations ``states`` (K', t', dof) over their steps
        and ellipsoids, times ``scale`` (the time stride): :meth:`terms` for a part of the evaluated
        steps, so that a pruned evaluation (``MPPIConfig.prune_margin``) can add them up chunk by chunk."""
        return self._sums(self._query_states(states), states.shape[0], scale)

    def terms(self, rollout: Rollout) -> dict[str, np.ndarray]:
        return self.evaluate(rollout).terms

    def evaluate(self, rollout: Rollout) -> CostValue:
        res = self.query(rollout)
        scale = float(rollout.cache[("collision_query", id(self))][1])
        return CostValue({**self._sums(res, rollout.k, scale), **self.self_terms(rollout)}, query=res)

    def __call__(self, rollout: Rollout) -> np.ndarray:
        return np.sum(list(self.terms(rollout).values()), axis=0)


@dataclass
class CollisionTerms(ConfigTerms):
    """The collision-cost fields of a task config (flat in it: ``--arm-w-hit``); a config sets its
    own defaults as class keywords (:class:`~splatplan._config.ConfigTerms`)."""

    #: conservatism of the metric (n_sigma)
    n_sigma: float = bounded(1.0, ge=0)
    #: weight of the summed CollisionSplatting cost (every ellipsoid, every step)
    w_collision: float = bounded(2.0, ge=0)
    #: cost per (step, ellipsoid) in collision
    w_hit: float = bounded(20.0, ge=0)
    #: neighbourhood of the rollouts' collision cost (checker s2_cap for MPPI queries; at most 16:
    #: beyond it a splat's cost is below exp(-60) of its peak, and the search radius grows as sqrt(cap))
    collision_s2_cap: float = bounded(2.0, ge=1, le=16)

    def collision_cost(self, checker: CollisionChecker, robot: Robot | Dynamics | LinkGeometry, **kw) -> CollisionCost:
        """The :class:`CollisionCost` of these terms on ``checker`` (``kw``: its other arguments)."""
        return CollisionCost(checker, robot, weight=self.w_collision, hit_weight=self.w_hit, s2_cap=self.collision_s2_cap, **kw)


@dataclass
class StridedCollisionTerms(CollisionTerms):
    """:class:`CollisionTerms` that query every ``collision_stride``-th step of the horizon."""

    #: query the collision cost on every stride-th step of the horizon (1 = every step)
    collision_stride: int = bounded(1, ge=1)

    def collision_cost(self, checker: CollisionChecker, robot: Robot | Dynamics | LinkGeometry, **kw) -> CollisionCost:
        return super().collision_cost(checker, robot, time_stride=self.collision_stride, **kw)


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


def _speed_bound(source: Robot | Dynamics | LinkGeometry, geometry: LinkGeometry) -> np.ndarray:
    """(dof,) bound on |dq_j / dt| of the robot configuration: the dynamics model's own
    (:meth:`DynamicsModel.speed_bound`), else the robot's velocity limits."""
    if isinstance(source, DynamicsModel):
        return np.asarray(source.speed_bound(), dtype=np.float64).copy()
    if geometry.robot is None:
        raise SplatplanError("CollisionCost(time_stride='auto') needs a Robot or speed_bound")
    return np.asarray(geometry.robot.velocity_limits, dtype=np.float64).copy()


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
            key = ("link_pose_fk", self.link_index)
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
        if self.r_goal is not None and self.orientation_weight > 0:
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


def evaluate_costs(costs: list[Cost], rollout: Rollout) -> tuple[np.ndarray, dict[str, np.ndarray], dict, QueryResult | None]:
    """Sum of a list of costs on one rollout batch: total (K,), {term name: (K,)}, the values they
    report and the first collision query (None without one)."""
    terms: dict[str, np.ndarray] = {}
    values: dict = {}
    query = None
    for c in costs:
        cv = c.evaluate(rollout)
        for name, v in cv.terms.items():
            v = np.asarray(v, dtype=np.float64)
            terms[name] = terms[name] + v if name in terms else v
        values.update(cv.values)
        query = cv.query if query is None else query
    total = np.sum(list(terms.values()), axis=0) if terms else np.zeros(rollout.k)
    return total, terms, values, query


def total_cost(costs: list[Cost], rollout: Rollout) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Sum of a list of costs on one rollout batch: total (K,), {term name: (K,)}."""
    total, terms, _, _ = evaluate_costs(costs, rollout)
    return total, terms
