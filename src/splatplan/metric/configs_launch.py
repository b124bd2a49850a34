"""The lean CPU path of :meth:`CollisionChecker.collides_configs` (and ``_slack``) for planners.

A sampling planner calls the per-configuration check tens of times per plan, most calls with
tens of configurations: there, Python work around the two kernels (argument packing, buffer
lookups, validation) costs as much as the kernels. :class:`ConfigsLauncher` does that work once
per (workspace, robot): it owns the configuration, FK and output buffers at a capacity, and
Warp launch commands recorded for them (``wp.launch(..., record_cmd=True)``); a call copies the
configurations in, sets the launch size and runs the two commands. Larger batches split the
collision kernel over the checker's CPU threads as the general path does.

The kernels, their inputs and so every answer are those of the general path
(``tests/metric/test_configs_launch.py`` compares them on random and near-surface batches, with
and without slack, and across a capacity growth).
"""

from __future__ import annotations

import weakref
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from .._warp import launch_split
from .._warp import wp as _wp
from .groups import robot_groups

if TYPE_CHECKING:
    from ..robots.robot import Robot
    from .interop import MetricWorkspace
    from .wp_metric import WarpMetric

#: smallest capacity (configurations) of a launcher's buffers
MIN_CAPACITY = 64
#: larger batches take the general path (a launcher's buffers hold ~2.3 kB per configuration of a
#: 45-ellipsoid robot; planners' batches are far smaller)
MAX_BATCH = 8192


def fast_path_robot(robot: Any) -> bool:
    """Whether ``robot`` computes its FK with the library's kernel (a :class:`~splatplan.robots.Robot`
    whose ``fk_wp`` is not overridden): only then can its FK launch be recorded."""
    from ..robots.robot import Robot

    return isinstance(robot, Robot) and type(robot).fk_wp is Robot.fk_wp


class ConfigsLauncher:
    """Recorded FK + per-configuration collision launches of one robot on one checker (CPU).

    Args:
        impl: the checker's :class:`~.wp_metric.WarpMetric`.
        robot: the robot (its semi-axes, groups and FK model are read once).
        axes: (device semi-axes (E,) vec3, a_min median, a_max median) of the robot.
        config: the checker's :class:`~.config.MetricConfig`.
        capacity: configurations the buffers hold (grown by a new launcher).
    """

    def __init__(self, impl: WarpMetric, robot: Robot, axes: tuple, config, capacity: int) -> None:
        from ..robots.wp_fk import record_fk
        from .wp_metric import CHUNKS_PER_THREAD, CONFIG_MIN_SPLIT, CONFIG_MIN_STEP, metric_params
        from .wp_metric_kernel import LinkBatch, robot_collide_kernel

        wp = _wp()
        dev = impl.device
        self.robot_key = robot.semi_axes.tobytes()
        self.dof = int(robot.dof)
        self.n_ell = e = int(robot.n_ellipsoids)
        self.capacity = cap = max(int(capacity), MIN_CAPACITY)
        self.impl = impl
        self.q = wp.empty((cap, self.dof), dtype=wp.float32, device=dev)  # (cap, dof)
        self.q_np = self.q.numpy()  # a view of the host buffer
        self.centers = wp.empty(cap * e, dtype=wp.vec3, device=dev)  # (cap E,) world frame
        self.rots = wp.empty(cap * e, dtype=wp.mat33, device=dev)  # (cap E,) world <- ellipsoid
        self.hits = wp.empty(cap, dtype=wp.bool, device=dev)  # (cap,)
        self.hits_np = self.hits.numpy()
        self.slack = wp.empty(cap * e, dtype=wp.float32, device=dev)  # (cap E,) FREE SLACK
        self.slack_np = self.slack.numpy()
        self.bad = wp.empty(1, dtype=wp.int32, device=dev)
        self.fk, keep = record_fk(robot, self.q, self.centers, self.rots)
        self._keep = [keep, axes]  # (everything the recorded commands point at stays alive)
        ax, a_min, a_max = axes
        gs = impl.gridset(config.n_sigma, 1.0, a_min, a_max, collide=True)
        dgrid = impl.mean_distance_grid()
        rg = impl.robot_groups(robot_groups(robot), gs, config.n_sigma)
        params = metric_params(config, 0, impl.tiers.collide_row_clip)
        links = LinkBatch()
        links.centers, links.rots, links.axes = self.centers, self.rots, ax
        links.rot_mode, links.rot_period, links.axes_period, links.use_order = 2, cap * e, e, 0
        self._keep += [gs, dgrid, rg, params, links]
        # kernel arguments after the offset, without and with slack
        self._args = [[links, gs.tiers, dgrid, params, rg, self.hits, self.bad, impl.no_slack_array(), 0],
                      [links, gs.tiers, dgrid, params, rg, self.hits, self.bad, self.slack, 1]]  # fmt: skip
        self.collide = [wp.launch(robot_collide_kernel, dim=cap, inputs=[0, *a], device=dev, record_cmd=True) for a in self._args]
        self._kernel = robot_collide_kernel
        self._split = (CONFIG_MIN_SPLIT, CONFIG_MIN_STEP, CHUNKS_PER_THREAD)

    def run(self, q: np.ndarray, slack: bool):
        """Check configurations ``q`` (B, dof) finite float, B <= capacity: hits (B,) bool and,
        with ``slack``, the slack (B, E) float32, both views of this launcher's buffers (valid
        until its next call)."""
        b = int(q.shape[0])
        self.q_np[:b] = q
        self.fk.set_dim(b)
        self.fk.launch()
        min_split, min_step, chunks = self._split
        pool = self.impl.executor() if b >= min_split else None
        if pool is not None and getattr(pool, "_max_workers", 1) > 1:
            launch_split(self._kernel, b, [0, *self._args[int(slack)]], self.impl.device, pool, min_split=min_split, min_step=min_step, chunks_per_thread=chunks)
        else:
            cmd = self.collide[int(slack)]
            cmd.set_dim(b)
            cmd.launch()
        hits = self.hits_np[:b]
        if slack:
            return hits, self.slack_np[: b * self.n_ell].reshape(b, self.n_ell)
        return hits


def fast_collides_configs(impl: WarpMetric, config, axes_for: Callable, robot: Any, q: Any, ws: MetricWorkspace, slack: bool):
    """:meth:`CollisionChecker.collides_configs` (``slack``: ``collides_configs_slack``) of numpy
    configurations ``q`` (..., dof) through the launcher cached in the workspace ``ws`` (CPU
    checkers; ``impl``, ``config``: the checker's kernels and MetricConfig; ``axes_for(robot)``: its
    cached device semi-axes), or None where this path does not apply: another robot type, an empty batch or one
    over :data:`MAX_BATCH`, or input that the general path must validate (and reject)."""
    a = q if isinstance(q, np.ndarray) else None
    if a is None or a.dtype.kind != "f" or a.ndim < 1 or a.shape[-1] != robot.dof:
        return None
    hit = ws._cache.get("configs_launcher")  # (weak reference to the robot, its launcher)
    if hit is not None and hit[0]() is not robot:
        hit = None
    if hit is None and not fast_path_robot(robot):
        return None
    shape = a.shape[:-1]
    a2 = a.reshape(-1, a.shape[-1])
    b = a2.shape[0]
    if b == 0 or b > MAX_BATCH or not np.isfinite(a2).all():
        return None
    if hit is None or hit[1].robot_key != robot.semi_axes.tobytes() or hit[1].capacity < b:
        cap = b if hit is None else max(b, 2 * hit[1].capacity)
        launcher = ConfigsLauncher(impl, robot, axes_for(robot), config, cap)
        ws._cache["configs_launcher"] = hit = (weakref.ref(robot), launcher)
        ws.reallocations += 1
    res = hit[1].run(a2, slack)
    if slack:
        return res[0].reshape(shape), res[1].reshape(shape + (robot.n_ellipsoids,))
    return res.reshape(shape)
