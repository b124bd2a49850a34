"""The planners' view of a robot: collision checks of configurations, and a configuration metric.

Planners and costs take a :class:`splatplan.robots.Robot` (or a name for
:func:`~splatplan.robots.load_robot`, e.g. ``"sphere:0.015"``); :class:`LinkGeometry` is their
private adapter over it (built only from a Robot), not a second robot type.

The functions :func:`robot_collides`, :func:`configs_collide`, :func:`configs_collide_slack`,
:func:`robot_collides_slack` and :func:`robot_query` are the **only** places where a planner asks
the :class:`~splatplan.metric.CollisionChecker` about a robot (its device-resident
``collides_robot`` / ``collides_configs`` / ``query_robot``, FK on the checker's device).

Configuration metric (what "stride", "edge resolution" and "goal tolerance" are measured in):

* ``motion(dq)`` bounds how far **any point of any ellipsoid** moves when the configuration changes
  by ``dq`` along a straight line in configuration space: ``sum_j motion_bound[j] |dq_j|`` (scene
  units, from :attr:`Robot.motion_bound`), and exactly ``|dq|`` for a point robot
  (:attr:`Robot.is_point`: a sphere or ellipsoid whose configuration is its centre).
* distances between configurations (nearest neighbours, stride) are the weighted Euclidean norm
  ``|motion_bound * dq|_2`` (scene units; the plain Euclidean distance for a point robot), which is
  never more than ``motion(dq)`` and never less than ``motion(dq) / sqrt(dof)``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import SplatplanError
from ..robots.robot import Robot

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..metric.config import QueryResult

#: default fraction of the robot's smallest semi-axis that bounds how far any ellipsoid point moves
#: between two consecutive collision checks along an edge
EDGE_FRACTION = 0.25


def as_robot(robot: Robot | str | None) -> Robot:
    """A :class:`~splatplan.robots.Robot` from a Robot (returned as is) or a name for
    :func:`~splatplan.robots.load_robot` ("panda", "go2", "sphere:0.015", a URDF path).

    Raises:
        SplatplanError: ``robot`` is None (a point robot is ``"sphere:R"``, e.g.
            :data:`~splatplan.robots.DEFAULT_POINT_ROBOT`) or an unknown name.
    """
    if robot is None:
        from ..robots import DEFAULT_POINT_ROBOT

        raise SplatplanError(f"give the robot: a Robot or a name such as 'panda', 'go2' or '{DEFAULT_POINT_ROBOT}' (a sphere robot), e.g. load_robot('{DEFAULT_POINT_ROBOT}')")
    if isinstance(robot, str):
        from ..robots import load_robot

        return load_robot(robot)
    if not isinstance(robot, Robot):
        raise SplatplanError(f"the robot must be a Robot or a name for load_robot, got {type(robot).__name__}")
    return robot


def robot_collides(checker: CollisionChecker, robot: Robot, q: np.ndarray) -> np.ndarray:
    """(..., dof) configurations -> (..., E) bool: ellipsoid e of configuration q is in collision."""
    return np.asarray(checker.collides_robot(robot, q))


def configs_collide(checker: CollisionChecker, robot: Robot, q: np.ndarray, out=None) -> np.ndarray:
    """(..., dof) configurations -> (...,) bool: any ellipsoid of configuration q in collision (the
    checker's per-configuration kernel: the answer of :func:`robot_collides` ``.any(-1)``, cheaper).
    ``out``: the checker's workspace to reuse (the result is a copy either way)."""
    return np.array(checker.collides_configs(robot, q, out=out))


def configs_collide_slack(checker: CollisionChecker, robot: Robot, q: np.ndarray, out=None, rigid_target=None) -> tuple[np.ndarray, np.ndarray]:
    """(..., dof) -> (any ellipsoid in collision (...,) bool, slack (..., E) float): as
    :func:`robot_collides_slack`, per configuration (the checker's per-configuration kernel; its
    slack may differ from the per-ellipsoid one's but holds the same promise); ``rigid_target``:
    the checker's RIGID SLACK (:meth:`CollisionChecker.collides_configs_slack`)."""
    hit, slack = checker.collides_configs_slack(robot, q, out=out, rigid_target=rigid_target)
    return np.array(hit), np.array(slack)


def robot_collides_slack(checker: CollisionChecker, robot: Robot, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(..., dof) -> (hits (..., E) bool, slack (..., E) float): ellipsoid e of configuration q is in
    collision, and a distance its centre may move (its orientation anyhow) with it staying free
    (the checker's FREE SLACK; zeros from its reference backend: nothing proven)."""
    hit, slack = checker.collides_robot_slack(robot, q)
    return np.asarray(hit), np.asarray(slack)


def robot_query(checker: CollisionChecker, robot: Robot, q: np.ndarray) -> QueryResult:
    """(..., dof) configurations -> :class:`~splatplan.metric.QueryResult` with fields (..., E)."""
    return checker.query_robot(robot, q)


class LinkGeometry:
    """Collision geometry + configuration metric of a Robot, as the planners need it (internal).

    Attributes:
        robot: the :class:`~splatplan.robots.Robot`.
        dof: configuration dimension D.
        weights: (D,) per-coordinate weights of the configuration distance (motion_bound; ones for
            translating robots).
        translation: the configuration is the robot's position (a point robot,
            :attr:`Robot.is_point`: |dq| is the exact displacement).
        sphere: a single translating sphere (edges may use the inflation test, see the RRT).
        min_semi_axis: smallest ellipsoid semi-axis (scene units).
        max_semi_axis: largest ellipsoid semi-axis (scene units), used to pad sampling boxes.
        n_queries: ellipsoid checks issued so far (statistics).
        n_configs: configurations checked so far (statistics; a configuration counts once
            whatever its number of ellipsoids).
    """

    def __init__(self, robot: Robot) -> None:
        if not isinstance(robot, Robot):
            raise SplatplanError(f"LinkGeometry needs a Robot, got {type(robot).__name__}")
        self.robot = robot
        self.n_queries = 0
        self.n_configs = 0
        self.dof = int(robot.dof)
        self.translation = robot.is_point
        ax = np.asarray(robot.semi_axes, dtype=np.float64)
        self.weights = np.ones(self.dof) if self.translation else np.asarray(robot.motion_bound, dtype=np.float64).reshape(self.dof)
        if not np.all(np.isfinite(self.weights)) or np.any(self.weights < 0):
            raise SplatplanError(f"robot {robot.name}: motion_bound must be finite and >= 0, got {self.weights}")
        self.min_semi_axis = float(robot.min_semi_axis)
        self.max_semi_axis = float(ax.max())
        self.sphere = self.translation and ax.shape[0] == 1 and bool(np.allclose(ax, ax[0, 0]))
        #: (E, D) per-ellipsoid motion bounds (:meth:`Robot.ellipsoid_motion_bounds`) or None (then
        #: ``motion`` bounds every ellipsoid: translating robots, robots without them)
        self.ellipsoid_bounds = None
        if not self.translation:
            b = np.asarray(robot.ellipsoid_motion_bounds(), dtype=np.float64)
            if b.shape == (int(robot.n_ellipsoids), self.dof) and np.all(np.isfinite(b)) and np.all(b >= 0):
                self.ellipsoid_bounds = b
        if self.translation:  # fast path: centres = q + offset, fixed orientations (no FK on the host)
            q0 = np.asarray(robot.q_default, dtype=np.float64)
            c0, quat0, _ = robot.ellipsoids(q0[None])
            self._offset = np.asarray(c0[0], dtype=np.float64) - q0  # (E, 3)
            self._quat = np.asarray(quat0[0], dtype=np.float64)  # (E, 4) wxyz
            self._axes = ax

    def _workspace(self, checker: CollisionChecker):
        """This thread's reusable output buffers on ``checker``: the checker's own per-thread
        workspace, shared by every search on the checker."""
        return checker.thread_workspace()

    # ------------------------------------------------------------------ metric
    def bind(self, q: np.ndarray) -> None:
        """Check that a configuration (D,) has the robot's D entries."""
        if q.shape != (self.dof,):
            raise SplatplanError(f"robot {self.robot.name} has {self.dof} degrees of freedom, got a configuration of {q.size}: {np.array2string(q, precision=4)}")

    def motion(self, dq: np.ndarray) -> np.ndarray:
        """(..., D) configuration differences -> (...,) bound on the displacement of any ellipsoid
        point along the straight segment (scene units)."""
        dq = np.asarray(dq, dtype=np.float64)
        if self.translation:
            return np.linalg.norm(dq, axis=-1)
        return np.abs(dq) @ self.weights

    def ellipsoid_motion(self, dq: np.ndarray) -> np.ndarray:
        """(..., D) configuration differences -> (..., E) bound on the displacement of any point of
        each ellipsoid along the straight segment (scene units; <= :meth:`motion`)."""
        dq = np.abs(np.asarray(dq, dtype=np.float64))
        if self.ellipsoid_bounds is None:
            m = self.motion(dq)
            return np.repeat(m[..., None], int(self.robot.n_ellipsoids), axis=-1)
        return dq @ self.ellipsoid_bounds.T

    def distance_scale(self) -> np.ndarray:
        """(D,) multipliers that turn configurations into the metric space of the RRT."""
        return self.weights

    # ------------------------------------------------------------------ collisions
    def ellipsoids(self, q: np.ndarray):
        """(..., D) -> centers (..., L, 3), quats (..., L, 4), semi_axes (L, 3)."""
        if self.translation:
            q = np.asarray(q, dtype=np.float64)
            c = q[..., None, :] + self._offset  # (..., E, 3)
            return c, np.broadcast_to(self._quat, c.shape[:-1] + (4,)), self._axes
        return self.robot.ellipsoids(q)

    def collides(self, checker: CollisionChecker, q: np.ndarray, margin: float | np.ndarray = 0.0) -> np.ndarray:
        """(..., D) -> (...,) bool: any ellipsoid in collision. ``margin`` (scalar or (...,)) grows
        every semi-axis (used by the sphere edge test)."""
        q = np.asarray(q, dtype=np.float64)
        e = int(self.robot.n_ellipsoids)
        if np.all(np.asarray(margin) == 0):
            hit = configs_collide(checker, self.robot, q, out=self._workspace(checker))  # (...,)
            self.n_queries += hit.size * e
            self.n_configs += hit.size
            return hit
        else:
            c, quat, ax = self.ellipsoids(q)  # (..., L, 3)
            m = np.asarray(margin, dtype=np.float64)
            axes = np.asarray(ax, dtype=np.float64) + (m[..., None, None] if m.ndim else m)  # (..., L, 3)
            hit = checker.collides(c, quat, axes)
        hit = np.asarray(hit)
        self.n_queries += hit.size
        self.n_configs += hit.size // max(hit.shape[-1], 1) if hit.ndim else 1
        return np.any(hit, axis=-1)

    def collides_slack(self, checker: CollisionChecker, q: np.ndarray, target: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """(..., D) -> (any ellipsoid in collision (...,) bool, slack (..., E) float): each
        ellipsoid's RIGID SLACK (:meth:`CollisionChecker.collides_configs_slack`) for ``target``
        (scalar or (..., E)): the ellipsoid is free wherever a rigid motion moves none of its
        points farther than that (a bound on every ellipsoid point's motion along an edge,
        :meth:`Robot.ellipsoid_motion_bounds`, keeps it)."""
        hit, slack = configs_collide_slack(checker, self.robot, np.asarray(q, dtype=np.float64), out=self._workspace(checker), rigid_target=target)  # (...,), (..., E)
        self.n_queries += slack.size
        self.n_configs += hit.size
        return hit, slack

    def query(self, checker: CollisionChecker, q: np.ndarray) -> QueryResult:
        """(..., D) -> QueryResult with fields (..., L)."""
        res = robot_query(checker, self.robot, np.asarray(q, dtype=np.float64))
        self.n_queries += int(np.size(res.min_s2))
        return res

    def describe_collision(self, checker: CollisionChecker, q: np.ndarray) -> str | None:
        """None when configuration ``q`` (D,) is free, else a sentence naming the worst link, what
        blocks it (how many splats, how faint and large, where) and the remedy that fits."""
        q = np.asarray(q, dtype=np.float64)
        res = self.query(checker, q[None])  # (1, L)
        if not bool(np.any(res.in_collision)):
            return None
        j = int(np.argmin(res.min_s2[0]))
        link = ""
        if len(self.robot.link_names) and res.min_s2.shape[-1] > 1:
            li = int(np.asarray(self.robot.ellipsoid_link)[j])
            link = f" (link {self.robot.link_names[li]}, ellipsoid {j})"
        colliding = np.nonzero(np.asarray(res.in_collision[0]))[0]
        text = (
            f"min_s2 = {float(res.min_s2[0, j]):.4g} < 1{link}: {int(res.n_colliding[0, j])} splat(s) inside the robot "
            f"at n_sigma = {checker.n_sigma:g}, {colliding.size} of {res.min_s2.shape[-1]} ellipsoid(s) in collision"
        )
        c, quat, ax = self.ellipsoids(q[None])
        b = checker.blockers(np.asarray(c)[0, j], None if quat is None else np.asarray(quat)[0, j], np.asarray(ax).reshape(-1, 3)[j])
        if b.n:
            text += f"; at that ellipsoid {b.summary()}: {b.remedy()}"
        return text