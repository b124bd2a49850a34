"""Plug-in dynamics for MPPI (and link geometry for RRT), one common protocol.

Every model maps a start state and K control sequences to K state trajectories, and states to
robot link ellipsoids in the scene's world frame:

    states = dyn.rollout(x0, controls, dt)      # (dx,), (K, T, du) -> (K, T, dx)
    centers, quats, semi_axes = dyn.link_poses(states)
    # centers (..., L, 3) scene units, quats (..., L, 4) wxyz link->world or None (axis-aligned),
    # semi_axes (L, 3) in each link's own frame

``states[:, t]`` is the state *after* applying ``controls[:, t]`` for ``dt`` seconds, so a
rollout of horizon T contains x_1 .. x_T (not x_0). All integrators are explicit (forward) Euler
on numpy float64; they are cheap next to the collision query that follows them.
``link_poses`` accepts any leading batch shape (the RRT calls it on (N, n_edge_pts, dx)).

Each model is built from a :class:`~splatplan.robots.Robot` whose configuration is the state, of
the kind the model moves (``HolonomicPoint(load_robot("sphere:0.015"))``: a point robot,
``PlanarBase(load_robot("go2"))``: a planar base over (x, y, yaw), ``JointIntegrator(load_robot("panda"))``:
any robot, over its dofs); its ``robot`` attribute then lets the collision cost use the checker's
``query_robot`` (FK on the device) and ``link_poses`` is ``robot.ellipsoids``. ``HolonomicPoint()``
and ``PlanarBase(height=...)`` without a robot keep their own simple geometry (a sphere, body
ellipsoids). Deprecated forms (0.3.0, removed in 0.4.0; each warns): ``JointIntegrator(fk, q_min,
q_max, semi_axes)`` with a forward-kinematics callable, ``HolonomicPoint((a, b, c))`` with the
semi-axes positionally, ``PlanarBase(0.06)`` with the height positionally.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, runtime_checkable

import numpy as np

from ..errors import SplatplanError
from ..robots.robot import Robot

if TYPE_CHECKING:
    from collections.abc import Callable


@runtime_checkable
class Dynamics(Protocol):
    """What MPPI needs from a robot model."""

    #: dimension of the state x
    state_dim: int
    #: dimension of the control u
    control_dim: int

    def rollout(self, x0: np.ndarray, controls: np.ndarray, dt: float) -> np.ndarray:
        """(dx,), (K, T, du), seconds -> states (K, T, dx) after each control step."""
        ...

    def link_poses(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """(..., dx) -> centers (..., L, 3), quats (..., L, 4) wxyz or None, semi_axes (L, 3)."""
        ...


def _check_rollout_args(x0, controls, state_dim: int, control_dim: int) -> tuple[np.ndarray, np.ndarray]:
    x0 = np.asarray(x0, dtype=np.float64).reshape(-1)
    u = np.asarray(controls, dtype=np.float64)
    if x0.shape != (state_dim,):
        raise SplatplanError(f"x0 must have shape ({state_dim},), got {x0.shape}")
    if u.ndim != 3 or u.shape[-1] != control_dim:
        raise SplatplanError(f"controls must have shape (K, T, {control_dim}), got {u.shape}")
    return x0, u


def _integrate(x0: np.ndarray, u: np.ndarray, step) -> np.ndarray:
    """(K, T, dx) states of a sequential model, vectorised over K: ``x = step(x, u_t)`` from ``x0``
    (dx,) over the controls ``u`` (K, T, du); ``step`` may update ``x`` (K, dx) in place."""
    k, t_len, _ = u.shape
    out = np.empty((k, t_len, x0.shape[-1]))
    x = np.broadcast_to(x0, (k, x0.shape[-1])).copy()
    for t in range(t_len):
        x = step(x, u[:, t])
        out[:, t] = x
    return out


def _deprecated(old: str, new: str, stacklevel: int = 4) -> None:
    """A DeprecationWarning pointing at the caller's line (``stacklevel``: 4 from a dataclass's
    ``__post_init__``, 3 from an ``__init__``)."""
    warnings.warn(f"{old} is deprecated since splatplan 0.3.0 and goes in 0.4.0: {new}", DeprecationWarning, stacklevel=stacklevel)


def _check_robot(robot: object, model: str) -> Robot | None:
    """``robot`` as given, after checking that it is a :class:`~splatplan.robots.Robot` (or None)."""
    if robot is not None and not isinstance(robot, Robot):
        raise SplatplanError(f"{model}: robot must be a Robot (load_robot(...)), got {type(robot).__name__}")
    return robot


class DynamicsModel:
    """What the built-in models share: the :class:`~splatplan.robots.Robot` they move (or None, then
    their own geometry) and the bound on how fast the state can change that the collision cost's
    ``time_stride="auto"`` needs."""

    #: the Robot whose configuration is the state, or None (the model's own geometry)
    robot: Robot | None

    def link_poses(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
        """The robot's ellipsoids when the model has a ``robot``, else the model's own geometry
        (see :class:`Dynamics`)."""
        s = np.asarray(states, dtype=np.float64)
        if self.robot is not None:
            return self.robot.ellipsoids(s)
        return self._own_link_poses(s)

    def _own_link_poses(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:  # pragma: no cover - abstract
        raise NotImplementedError

    def speed_bound(self) -> np.ndarray:
        """(state_dim,) bound on ``|dx_j / dt|`` under this model's clipping of the controls.

        Raises:
            SplatplanError: the model does not bound its speed (give the collision cost a
                ``speed_bound``).
        """
        raise SplatplanError(f"CollisionCost(time_stride='auto'): {type(self).__name__} does not bound its speed; give speed_bound")


@dataclass
class HolonomicPoint(DynamicsModel):
    """A point robot (a sphere or axis-aligned ellipsoid) moving with commanded world-frame velocity.

    State x = (x, y, z) position of the centre (scene units, world frame); control u = (vx, vy, vz)
    (scene units / s). ``x_{t+1} = x_t + u_t dt``.

    ``HolonomicPoint(robot)`` with a point :class:`~splatplan.robots.Robot` (``robot.is_point``:
    ``sphere:R`` / ``ellipsoid:A,B,C``); ``HolonomicPoint(semi_axes=(a, b, c))`` without one.
    """

    #: a point Robot (``sphere:R`` / ``ellipsoid:A,B,C``) whose configuration is its centre; when
    #: given, its ellipsoids replace ``semi_axes``
    robot: Robot | None = None
    #: semi-axes (a, b, c) in scene units, world-aligned, when there is no robot; a sphere of radius
    #: r is (r, r, r)
    semi_axes: tuple[float, float, float] = (0.015, 0.015, 0.015)
    state_dim: int = field(default=3, init=False)
    control_dim: int = field(default=3, init=False)

    def __post_init__(self) -> None:
        if self.robot is not None and not isinstance(self.robot, Robot):  # HolonomicPoint((a, b, c)): the old positional semi-axes
            _deprecated("HolonomicPoint(semi_axes) with the semi-axes positionally", "give HolonomicPoint(semi_axes=(a, b, c)) or HolonomicPoint(robot)")
            self.robot, self.semi_axes = None, self.robot
        if self.robot is not None and not self.robot.is_point:
            raise SplatplanError(f"HolonomicPoint needs a point robot (dofs x, y, z: sphere:R, ellipsoid:A,B,C); {self.robot.name} is not one "
                                 f"(base {self.robot.base!r}, {self.robot.dof} dofs)")  # fmt: skip

    def rollout(self, x0: np.ndarray, controls: np.ndarray, dt: float) -> np.ndarray:
        x0, u = _check_rollout_args(x0, controls, 3, 3)
        return x0 + np.cumsum(u * dt, axis=1)  # (K, T, 3)

    def _own_link_poses(self, s: np.ndarray):
        return s[..., None, :3], None, np.asarray(self.semi_axes, dtype=np.float64).reshape(1, 3)


def yaw_to_quat(yaw: np.ndarray) -> np.ndarray:
    """wxyz quaternions (..., 4) of rotations by ``yaw`` (radians) about the world z axis."""
    yaw = np.asarray(yaw, dtype=np.float64)
    q = np.zeros(yaw.shape + (4,))
    q[..., 0] = np.cos(0.5 * yaw)
    q[..., 3] = np.sin(0.5 * yaw)
    return q


@dataclass
class PlanarBase(DynamicsModel):
    """A mobile base moving in the plane z = ``height`` with body-frame velocity commands.

    State x = (x, y, yaw): base origin in the world frame (scene units, z-up world) and heading
    (radians, about +z, yaw = 0 looks along +x). Control u = (vx, vy, wz): forward / left velocity
    in the *body* frame (scene units / s) and yaw rate (rad / s). Forward Euler with the heading at
    the start of the step:

        x_{t+1}   = x_t + (cos(yaw_t) vx - sin(yaw_t) vy) dt
        y_{t+1}   = y_t + (sin(yaw_t) vx + cos(yaw_t) vy) dt
        yaw_{t+1} = yaw_t + wz dt

    Links are ellipsoids rigidly attached to the body: link l has centre ``offsets[l]`` (body frame,
    relative to the base origin at height ``height``) and semi-axes ``semi_axes[l]`` along the body
    axes, so its world orientation is the yaw rotation. The default is one quadruped-like body
    ellipsoid (long along x) sized for the normalised built-in scenes. It costs MPPI about 4x the
    time of a sphere of radius 0.015 (benchmarks/planners.py): the metric kernel has a fast path
    for spheres only, and its search radius grows with the largest semi-axis and with the ratio
    largest / smallest semi-axis. Give ``semi_axes=[[r, r, r]]`` for a fast spherical body.

    ``PlanarBase(robot)`` with a planar-base :class:`~splatplan.robots.Robot` (e.g. ``go2``, whose
    configuration is (x, y, yaw)) integrates the same body-frame commands and takes every body and
    leg ellipsoid from ``robot.ellipsoids`` (the robot fixes the height); ``velocity_limits`` of
    the robot clip the commands.
    """

    #: a planar-base Robot over (x, y, yaw) (e.g. go2); None = the ellipsoids below
    robot: Robot | None = None
    #: height z of the base origin in the world frame (scene units)
    height: float = 0.06
    #: (L, 3) link centres in the body frame (x forward, y left, z up), scene units
    offsets: np.ndarray = field(default_factory=lambda: np.zeros((1, 3)))
    #: (L, 3) link semi-axes along the body axes, scene units
    semi_axes: np.ndarray = field(default_factory=lambda: np.array([[0.03, 0.015, 0.012]]))
    state_dim: int = field(default=3, init=False)
    control_dim: int = field(default=3, init=False)

    def __post_init__(self) -> None:
        if isinstance(self.robot, (int, float)):  # PlanarBase(0.06): the old positional height
            _deprecated("PlanarBase(height) with the height positionally", "give PlanarBase(height=h) or PlanarBase(robot)")
            self.robot, self.height = None, float(self.robot)
        _check_robot(self.robot, "PlanarBase")
        if self.robot is not None and not (self.robot.base == "planar" and self.robot.dof == 3):
            raise SplatplanError(f"PlanarBase needs a planar-base robot with 3 dof (x, y, yaw), {self.robot.name} has base {self.robot.base!r} and {self.robot.dof} dofs")
        self.offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        self.semi_axes = np.asarray(self.semi_axes, dtype=np.float64).reshape(-1, 3)
        if self.offsets.shape != self.semi_axes.shape:
            raise SplatplanError(f"PlanarBase: offsets {self.offsets.shape} and semi_axes {self.semi_axes.shape} must both be (L, 3)")

    def rollout(self, x0: np.ndarray, controls: np.ndarray, dt: float) -> np.ndarray:
        x0, u = _check_rollout_args(x0, controls, 3, 3)
        if self.robot is not None:
            vmax = np.asarray(self.robot.velocity_limits, dtype=np.float64).reshape(3)
            u = np.clip(u, -vmax, vmax)

        def step(x, ut):  # x (K, 3) updated in place, ut (K, 3)
            c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
            vx, vy, wz = ut[:, 0], ut[:, 1], ut[:, 2]
            x[:, 0] += (c * vx - s * vy) * dt
            x[:, 1] += (s * vx + c * vy) * dt
            x[:, 2] += wz * dt
            return x

        return _integrate(x0, u, step)

    def speed_bound(self) -> np.ndarray:
        """(3,) bound on |dx/dt|, |dy/dt|, |dyaw/dt| from the robot's velocity limits: the body-frame
        (vx, vy) rotated into the world has |dx|, |dy| <= |(vx, vy)|."""
        if self.robot is None:
            return super().speed_bound()
        v = np.asarray(self.robot.velocity_limits, dtype=np.float64).reshape(3)
        xy = float(np.hypot(v[0], v[1]))
        return np.array([xy, xy, v[2]])

    def _own_link_poses(self, s: np.ndarray):
        yaw = s[..., 2]
        c, sn = np.cos(yaw)[..., None], np.sin(yaw)[..., None]  # (..., 1)
        ox, oy, oz = self.offsets[:, 0], self.offsets[:, 1], self.offsets[:, 2]  # (L,)
        centers = np.stack(
            [s[..., 0:1] + c * ox - sn * oy, s[..., 1:2] + sn * ox + c * oy, np.broadcast_to(self.height + oz, c.shape[:-1] + oz.shape)],
            axis=-1,
        )  # (..., L, 3)
        quats = np.broadcast_to(yaw_to_quat(yaw)[..., None, :], centers.shape[:-1] + (4,))  # (..., L, 4)
        return centers, quats, self.semi_axes


class JointIntegrator(DynamicsModel):
    """A joint-space single integrator: state q (n joints, rad or m), control qdot (rad/s or m/s).

    ``q_{t+1} = clip(q_t + clip(qdot_t, -v_max, v_max) dt, q_min, q_max)`` (joint position limits
    by saturation, velocity limits by clipping the command).

    ``JointIntegrator(robot)``: limits from ``robot.joint_limits`` / ``robot.velocity_limits``
    (``q_min``, ``q_max``, ``velocity_limits`` override them) and link ellipsoids from
    ``robot.ellipsoids`` (the collision cost then runs FK on the checker's device through
    ``query_robot``).

    Deprecated (0.3.0, removed in 0.4.0): ``JointIntegrator(fk, q_min, q_max, semi_axes)`` with a
    forward-kinematics callable ``fk(q (..., n)) -> (centers (..., L, 3), quats (..., L, 4) wxyz |
    None)`` in the scene's world frame and fixed per-link ``semi_axes`` (L, 3); it warns. Load the
    robot instead (``load_robot(PATH.urdf)``) and give it.
    """

    def __init__(self, robot: Robot, q_min=None, q_max=None, semi_axes=None, velocity_limits=None) -> None:
        #: the deprecated forward-kinematics callable, or None
        self.fk: Callable | None = None
        if isinstance(robot, Robot):
            if semi_axes is not None:
                raise SplatplanError("JointIntegrator(robot): the semi-axes are the robot's; give no semi_axes")
            self.robot = robot
            lim = np.asarray(robot.joint_limits, dtype=np.float64).reshape(-1, 2)
            q_min = lim[:, 0] if q_min is None else q_min
            q_max = lim[:, 1] if q_max is None else q_max
            velocity_limits = robot.velocity_limits if velocity_limits is None else velocity_limits
            self.semi_axes = np.asarray(robot.semi_axes, dtype=np.float64)
        elif callable(robot):  # deprecated: JointIntegrator(fk, q_min, q_max, semi_axes)
            _deprecated("JointIntegrator(fk, q_min, q_max, semi_axes) with a forward-kinematics callable",
                        "load the robot (load_robot(PATH.urdf)) and give JointIntegrator(robot)", stacklevel=3)  # fmt: skip
            if q_min is None or q_max is None or semi_axes is None:
                raise SplatplanError("JointIntegrator(fk, q_min, q_max, semi_axes): give all four, or a Robot")
            self.robot = None
            self.fk = robot
            self.semi_axes = np.asarray(semi_axes, dtype=np.float64).reshape(-1, 3)
        else:
            raise SplatplanError(f"JointIntegrator needs a Robot (load_robot(...)), got {type(robot).__name__}")
        self.q_min = np.asarray(q_min, dtype=np.float64).reshape(-1)
        self.q_max = np.asarray(q_max, dtype=np.float64).reshape(-1)
        if self.q_min.shape != self.q_max.shape or np.any(self.q_min > self.q_max):
            raise SplatplanError("JointIntegrator: q_min and q_max must have the same shape and q_min <= q_max")
        self.v_max = None if velocity_limits is None else np.broadcast_to(np.asarray(velocity_limits, dtype=np.float64), self.q_min.shape).copy()
        #: dimension of the state (joints)
        self.state_dim = int(self.q_min.size)
        #: dimension of the control (joint velocities)
        self.control_dim = self.state_dim

    def rollout(self, x0: np.ndarray, controls: np.ndarray, dt: float) -> np.ndarray:
        q0, u = _check_rollout_args(x0, controls, self.state_dim, self.control_dim)
        if self.v_max is not None:
            u = np.clip(u, -self.v_max, self.v_max)
        if np.all(np.isinf(self.q_min)) and np.all(np.isinf(self.q_max)):
            return q0 + np.cumsum(u * dt, axis=1)
        return _integrate(q0, u, lambda q, ut: np.clip(q + ut * dt, self.q_min, self.q_max))  # saturation makes the steps sequential

    def speed_bound(self) -> np.ndarray:
        """(n,) bound on |dq_j/dt|: the velocity clip ``v_max`` (the robot's velocity limits unless
        ``velocity_limits`` was given)."""
        if self.v_max is None:
            raise SplatplanError("CollisionCost(time_stride='auto') needs a Robot or speed_bound")
        return self.v_max.copy()

    def _own_link_poses(self, s: np.ndarray):  # the deprecated forward-kinematics callable
        if self.fk is None:  # (set only with the callable)
            raise TypeError("these dynamics have no forward-kinematics callable")
        centers, quats = self.fk(s)
        return np.asarray(centers, dtype=np.float64), None if quats is None else np.asarray(quats, dtype=np.float64), self.semi_axes
