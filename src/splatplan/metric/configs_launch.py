"""The lean CPU path of :meth:`CollisionChecker.collides_configs` (and ``_slack``) for planners.

A sampling planner calls the per-configuration check tens of times per plan, most calls with
tens of configurations: there, Python work around the two kernels (argument packing, buffer
lookups, validation) costs as much as the kernels. :class:`ConfigsLauncher` does that work once
per (workspace, robot) (a workspace keeps one for each of the last few robots): it owns the configuration, FK and output buffers at a capacity, and
Warp launch commands recorded for them (``wp.launch(..., record_cmd=True)``); a call copies the
configurations in, sets the launch size and runs the two commands. Larger batches split the
collision kernel over the checker's CPU threads in chunks, each a recorded launch of its own.

The kernels, their inputs and so every answer are those of the general path
(``tests/metric/test_configs_launch.py`` compares them on random and near-surface batches, with
and without slack, and across a capacity growth).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from .._warp import cpu_threads, split_chunks, wait_all
from .._warp import wp as _wp
from ..errors import SplatplanError
from .groups import robot_groups

if TYPE_CHECKING:
    from ..robots.robot import Robot
    from .interop import MetricWorkspace
    from .wp_metric import WarpMetric

#: smallest capacity (configurations) of a launcher's buffers (~0.6 MB for the Panda: a planner's batches rarely
#: outgrow it, so a plan records its launches once)
MIN_CAPACITY = 256
#: launchers a workspace keeps, one per robot model (a planner alternates between a robot grown by a
#: margin, its own model and a tighter model for endpoint checks: each keeps its recorded launches)
MAX_LAUNCHERS = 4
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
        from . import wp_metric
        from .wp_metric_kernel import LinkBatch, robot_collide_kernel

        wp = _wp()
        dev = impl.device
        self.n_ell = e = int(robot.n_ellipsoids)
        self.capacity = cap = max(int(capacity), MIN_CAPACITY)
        self.impl = impl
        self._wm = wp_metric  # (its split thresholds, read per call)
        q = wp.empty((cap, int(robot.dof)), dtype=wp.float32, device=dev)  # (cap, dof)
        self.q_np = q.numpy()  # a view of the host buffer
        centers = wp.empty(cap * e, dtype=wp.vec3, device=dev)  # (cap E,) world frame
        rots = wp.empty(cap * e, dtype=wp.mat33, device=dev)  # (cap E,) world <- ellipsoid
        hits = wp.empty(cap, dtype=wp.bool, device=dev)  # (cap,)
        slack = wp.empty(cap * e, dtype=wp.float32, device=dev)  # (cap E,) FREE SLACK
        self.hits_np, self.slack_np = hits.numpy(), slack.numpy()
        self.fk, self._fk_keep = record_fk(robot, q, centers, rots)  # (the arrays the command points at, kept alive)
        ax, a_min, a_max = axes
        links = LinkBatch()
        links.centers, links.rots, links.axes = centers, rots, ax
        links.rot_mode, links.rot_period, links.axes_period = 2, cap * e, e
        bad = wp.empty(1, dtype=wp.int32, device=dev)
        groups = robot_groups(robot)
        # the kernel's inputs after the offset per slack kind (0 none, 1 FREE SLACK, 2 RIGID SLACK; they keep what they point at alive)
        self._args = [impl.configs_args(links, groups, a_min, a_max, config, hits, bad, sl, rigid) for sl, rigid in ((None, False), (slack, False), (slack, True))]
        self._kernel = robot_collide_kernel
        self.collide: list = [None, None, None]  # per slack kind: the recorded launch (recorded on first use)
        self._chunk_cmds: list[list] = [[], [], []]  # per slack kind: recorded launches for the chunks of a split batch
        self._walk: dict = {}  # (t_steps, screen) -> the recorded SLACK WALK launch (:meth:`walk`)
        self._walk_io: tuple | None = None  # its edge buffers (allocated on first use)

    def run(self, q: np.ndarray, slack: int, target: np.ndarray | None = None):
        """Check configurations ``q`` (B, dof) finite float, B <= capacity: hits (B,) bool and,
        with ``slack`` (1: the FREE SLACK, 2: the RIGID SLACK for ``target`` (B E,) float32), the
        slack (B, E) float32, both views of this launcher's buffers (valid until its next call)."""
        b = int(q.shape[0])
        self.q_np[:b] = q
        if slack == 2:
            self.slack_np[: b * self.n_ell] = target  # (the kernel's input there)
        self.fk.set_dim(b)
        self.fk.launch()
        wm = self._wm
        n_thr = cpu_threads() if b >= wm.CONFIG_MIN_SPLIT else 1
        if n_thr > 1:  # over the checker's threads, in chunks with recorded launches (the general path's chunks)
            self._run_split(b, int(slack), n_thr)
        else:
            cmd = self.collide[int(slack)]
            if cmd is None:
                cmd = self.collide[int(slack)] = self._record(int(slack))
            cmd.set_dim(b)
            cmd.launch()
        hits = self.hits_np[:b]
        if slack:
            return hits, self.slack_np[: b * self.n_ell].reshape(b, self.n_ell)
        return hits

    def walk(self, starts: np.ndarray, ends: np.ndarray, n: np.ndarray, step: np.ndarray, t_steps: int, screen: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """The SLACK WALK (:mod:`.edge_walk`) of N <= capacity edges, one thread each, on the calling
        thread: ``starts``/``ends`` (N, dof) float64, ``n`` (N,) samples, ``step`` (N, E) float64;
        (free (N,) bool, checks (N,) int32), views of this launcher's buffers (valid until its next
        call). Edge i uses row i of the configuration buffers as its scratch."""
        from .wp_metric_kernel import edge_walk_kernel

        wp = _wp()
        b = int(starts.shape[0])
        if self._walk_io is None:
            dev, cap, dof = self.impl.device, self.capacity, int(self.q_np.shape[1])
            arrs = (wp.empty((cap, dof), dtype=wp.float64, device=dev), wp.empty((cap, dof), dtype=wp.float64, device=dev),
                    wp.empty(cap, dtype=wp.int32, device=dev), wp.empty((cap, self.n_ell), dtype=wp.float64, device=dev),
                    wp.empty(cap, dtype=wp.int32, device=dev))  # fmt: skip
            self._walk_io = (arrs, [a.numpy() for a in arrs])
        (a_s, a_e, a_n, a_st, a_c), (s_np, e_np, n_np, st_np, c_np) = self._walk_io
        key = (int(t_steps), int(screen))
        cmd = self._walk.get(key)
        if cmd is None:
            links, tiers, dgrid, params, rg, hits, bad, slack, _want = self._args[2]
            m, sr, sp, q, _c, _r = self._fk_keep
            cmd = self._walk[key] = wp.launch(
                edge_walk_kernel, dim=self.capacity, device=self.impl.device, record_cmd=True,
                inputs=[links, tiers, dgrid, params, rg, bad, slack, m, q, sr, sp, a_s, a_e, a_n, a_st, int(t_steps), int(screen), hits, a_c],
            )  # fmt: skip
        s_np[:b], e_np[:b], n_np[:b], st_np[:b] = starts, ends, n, step
        cmd.set_dim(b)
        cmd.launch()
        return self.hits_np[:b], c_np[:b]

    def _record(self, k: int):
        """A recorded launch of the collision kernel over the buffers (k: the slack kind), offset 0."""
        return _wp().launch(self._kernel, dim=self.capacity, inputs=[0, *self._args[k]], device=self.impl.device, record_cmd=True)

    def _run_split(self, b: int, k: int, n_thr: int) -> None:
        """The collision kernel over b configurations in the general path's chunks (:func:`~splatplan._warp.split_chunks`
        with the checker's CONFIG_MIN_STEP and CHUNKS_PER_THREAD), each a recorded launch of its own with its
        offset (set here, run on the checker's pool, taken as threads free up)."""
        wm = self._wm
        chunks = split_chunks(b, n_thr, wm.CONFIG_MIN_STEP, wm.CHUNKS_PER_THREAD)
        cmds = self._chunk_cmds[k]
        while len(cmds) < len(chunks):
            cmds.append(self._record(k))
        for cmd, (lo, n) in zip(cmds, chunks):
            cmd.set_param_at_index(0, lo)
            cmd.set_dim(n)
        pool = self.impl.executor()
        wait_all([pool.submit(cmd.launch) for cmd in cmds[: len(chunks)]])


def launcher_key(robot: Robot, device) -> tuple:
    """What a launcher depends on: the robot's semi-axes and its FK model on the device (kinematics,
    ellipsoid links and poses; a robot and its :meth:`~splatplan.robots.Robot.inflated` copies share
    it), so a new robot object with the same model and semi-axes reuses the launcher. The launcher
    keeps the model alive, so its ``id`` stays unique while the key is cached."""
    from ..robots.wp_fk import fk_model

    return (robot.semi_axes.tobytes(), id(fk_model(robot, device)))


def fast_collides_configs(impl: WarpMetric, config, axes_for: Callable, robot: Any, q: Any, ws: MetricWorkspace, slack: bool, target=None):
    """:meth:`CollisionChecker.collides_configs` (``slack``: ``collides_configs_slack``, with its ``rigid_target``) of numpy
    configurations ``q`` (..., dof) through the launcher the workspace ``ws`` keeps for this robot
    (:func:`launcher_key`; the last :data:`MAX_LAUNCHERS` robots; CPU checkers; ``impl``, ``config``: the checker's kernels and MetricConfig; ``axes_for(robot)``: its
    cached device semi-axes), or None where this path does not apply: another robot type, an empty batch or one
    over :data:`MAX_BATCH`, or input that the general path must validate (and reject)."""
    a = q if isinstance(q, np.ndarray) else None
    if a is None or a.dtype.kind != "f" or a.ndim < 1 or a.shape[-1] != robot.dof:
        return None
    if not fast_path_robot(robot):
        return None
    shape = a.shape[:-1]
    a2 = a.reshape(-1, a.shape[-1])
    b = a2.shape[0]
    if b == 0 or b > MAX_BATCH or not np.isfinite(a2).all():
        return None
    hit = launcher_for(impl, config, axes_for, robot, ws, b)
    kind = 0 if not slack else (1 if target is None else 2)
    res = hit.run(a2, kind, None if kind != 2 else rigid_targets(target, shape + (robot.n_ellipsoids,)))
    if slack:
        return res[0].reshape(shape), res[1].reshape(shape + (robot.n_ellipsoids,))
    return res.reshape(shape)


def launcher_for(impl: WarpMetric, config, axes_for: Callable, robot: Robot, ws: MetricWorkspace, b: int) -> ConfigsLauncher:
    """The launcher the workspace ``ws`` keeps for ``robot`` (:func:`launcher_key`), grown (or made)
    to hold ``b`` rows; the oldest robot's goes beyond :data:`MAX_LAUNCHERS`."""
    cache = ws._cache.setdefault("configs_launcher", {})  # launcher_key(robot) -> launcher
    key = launcher_key(robot, impl.device)
    hit = cache.get(key)
    if hit is None or hit.capacity < b:
        hit = ConfigsLauncher(impl, robot, axes_for(robot), config, b if hit is None else max(b, 2 * hit.capacity))
        cache.pop(key, None)
        while len(cache) >= MAX_LAUNCHERS:  # the oldest robot's launcher goes
            del cache[next(iter(cache))]
        cache[key] = hit
        ws.reallocations += 1
    return hit


def rigid_targets(target, shape: tuple) -> np.ndarray:
    """A RIGID SLACK target (a scalar or an array broadcastable to ``shape`` = (..., E), scene units,
    finite and >= 0) as a flat float32 array, or a :class:`SplatplanError` naming the problem."""
    t = np.asarray(target, dtype=np.float64)
    try:
        t = np.broadcast_to(t, shape)
    except ValueError:
        raise SplatplanError(f"rigid_target must be a scalar or broadcast to {shape} (one value per ellipsoid), got shape {t.shape}") from None
    if not np.all(np.isfinite(t)) or np.any(t < 0):
        raise SplatplanError("rigid_target must be finite and >= 0 (scene units)")
    return np.ascontiguousarray(t, dtype=np.float32).reshape(-1)


def fill_target(sl, tgt: np.ndarray | None, n: int):
    """Write the RIGID SLACK targets ``tgt`` (n,) into the kernel's slack buffer ``sl`` (its input
    there); returns ``sl``."""
    if sl is None or tgt is None:
        return sl
    wp = _wp()
    if sl.device.is_cpu:
        sl.numpy()[:n] = tgt
    else:
        wp.copy(sl, wp.array(tgt, dtype=wp.float32, device=sl.device), count=n)
    return sl
