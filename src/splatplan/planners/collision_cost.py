"""The collision cost of MPPI rollouts: the CollisionSplatting metric summed over every link
ellipsoid and step (paper Eq. 12), and the config fields that set it (:class:`CollisionTerms`).

The robot's links come from a :class:`~splatplan.robots.Robot`, a dynamics model (its robot, or its
own ``link_poses``) or a :class:`~.robot_links.LinkGeometry` (:func:`link_geometry`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._config import ConfigTerms, bounded
from ..errors import SplatplanError
from ..metric.config import QueryResult
from ..robots.robot import Robot
from .cost_base import Cost, CostValue, Rollout
from .dynamics import Dynamics, DynamicsModel
from .robot_links import LinkGeometry

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker

__all__ = ["CollisionCost", "CollisionTerms", "StridedCollisionTerms", "link_geometry"]


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


def link_geometry(source: Robot | Dynamics | LinkGeometry | _DynamicsLinks) -> LinkGeometry | _DynamicsLinks:
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
        robot: Robot | Dynamics | LinkGeometry | _DynamicsLinks,
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
        self.static = np.asarray(rob.static_ellipsoids, dtype=np.bool_) if use_static and rob is not None else None
        self._static_cache: dict = {}
        self.auto_stride = isinstance(time_stride, str)
        if self.auto_stride:
            if time_stride != "auto":
                raise SplatplanError(f"CollisionCost.time_stride must be an integer >= 1 or 'auto', got {time_stride!r}")
            if not isinstance(self.geometry, LinkGeometry):  # (the geometry without weights)
                raise SplatplanError("CollisionCost(time_stride='auto') needs a Robot (its motion_bound): build the dynamics model from one")
            self.speed_bound: np.ndarray | None = _speed_bound(robot, self.geometry) if speed_bound is None else np.asarray(speed_bound, dtype=np.float64).reshape(-1)
            if self.speed_bound.shape != (self.geometry.dof,) or not np.all(np.isfinite(self.speed_bound)) or np.any(self.speed_bound < 0):
                raise SplatplanError(f"CollisionCost: speed_bound must be {self.geometry.dof} finite values >= 0, got {self.speed_bound}")
            if max_gap_m is None:
                ax = np.asarray(self.geometry.robot.semi_axes, dtype=np.float64)
                moving = ax if self.static is None or self.static.all() else ax[~self.static]
                max_gap_m = 0.5 * float(moving.min())
            if not (np.isfinite(max_gap_m) and max_gap_m > 0):
                raise SplatplanError(f"CollisionCost.max_gap_m must be finite and > 0, got {max_gap_m}")
            self.max_gap_m: float | None = float(max_gap_m)
            self.time_stride = 1
        else:
            if int(time_stride) < 1:
                raise SplatplanError(f"CollisionCost.time_stride must be >= 1, got {time_stride}")
            self.time_stride = int(time_stride)
            self.max_gap_m = None
            self.speed_bound = None

    def step_motion(self, dt: float) -> float:
        """Bound on how far any ellipsoid point moves in one control step of ``dt`` s ("auto" mode)."""
        if self.speed_bound is None or not isinstance(self.geometry, LinkGeometry):  # (both set by time_stride="auto")
            raise TypeError("CollisionCost.step_motion needs time_stride='auto'")
        return float(self.geometry.motion(self.speed_bound * float(dt)))

    def stride(self, dt: float, t_len: int) -> int:
        """The time stride used for a horizon of ``t_len`` steps of ``dt`` s (see ``time_stride``)."""
        if not self.auto_stride or self.max_gap_m is None:  # (max_gap_m is set by time_stride="auto")
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
            assert rob is not None  # (self.static is set only with a robot)
            res = self.checker.query_robot(rob, np.asarray(rob.q_default, dtype=np.float64)[None])  # (1, E)
            hit = QueryResult(**{f: np.asarray(v)[0, self.static].copy() for f, v in res.as_dict().items()})
            self._static_cache = {key: hit}
        return hit

    def _query_states(self, states: np.ndarray):
        """QueryResult (..., E) of every ellipsoid at configurations ``states`` (..., dof)."""
        if self.static is None:
            return self.geometry.query(self.checker, states)
        rob = self.geometry.robot
        assert rob is not None  # (self.static is set only with a robot)
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



def _speed_bound(source: Robot | Dynamics | LinkGeometry | _DynamicsLinks, geometry: LinkGeometry) -> np.ndarray:
    """(dof,) bound on |dq_j / dt| of the robot configuration: the dynamics model's own
    (:meth:`DynamicsModel.speed_bound`), else the robot's velocity limits."""
    if isinstance(source, DynamicsModel):
        return np.asarray(source.speed_bound(), dtype=np.float64).copy()
    if geometry.robot is None:
        raise SplatplanError("CollisionCost(time_stride='auto') needs a Robot or speed_bound")
    return np.asarray(geometry.robot.velocity_limits, dtype=np.float64).copy()
