"""CollisionChecker: the public entry point of the metric stage.

    checker = CollisionChecker(scene, n_sigma=1.0, device="cpu")
    res = checker.query(centers, None, (0.015, 0.015, 0.015))   # a sphere of radius 0.015, any batch shape
    res.min_s2, res.n_colliding, res.in_collision, res.softmin, res.cost
    hits = checker.collides_robot(robot, q)          # q (..., dof) -> (..., E) bool, FK on the device

Query batches may have any leading shape, e.g. (K, T, links) for MPPI rollouts; every output has
that shape. Frames: ``centers`` are link centres in the scene's world frame (scene units),
``quats`` wxyz link orientations (link frame -> world) or ``rots`` the same as 3x3 matrices,
``semi_axes`` the link's (a, b, c) along its own x, y, z axes.

Inputs may be numpy arrays, torch tensors (CPU or CUDA) or ``wp.array``s; results come back as the
type of ``centers`` (or ``q``) on its device (see :mod:`.interop` for the rules: numpy inputs are
validated on the host as before; device inputs cost O(1) host work, zero-copy). Pass
``out=checker.workspace()`` to reuse preallocated output buffers across calls in a hot loop.

The checker owns a CPU thread pool (created on first use): ``checker.close()``, ``with
CollisionChecker(...) as checker:`` or garbage collection shuts it down.
"""

from __future__ import annotations

import contextlib
import threading
import warnings
from dataclasses import replace
from typing import TYPE_CHECKING, overload

import numpy as np

from .._arrays import array_kind, host_array
from ..errors import SplatplanError
from ..scenes.splats import Splats
from .blockers import Blockers, find_blockers
from .config import MetricConfig, QueryResult
from .configs_launch import MAX_BATCH, fast_collides_configs, fast_path_robot, fill_target, launcher_for, rigid_targets
from .groups import robot_groups
from .interop import (
    MetricWorkspace,
    as_host_queries,
    axes_medians,
    check_device,
    convert_out,
    device_axes_medians,
    device_rows,
    device_side_rows,
    host_link_batch,
    torch_device_name,
    warp_device_name,
)

if TYPE_CHECKING:
    from ..robots.robot import Robot
    from .wp_metric import WarpMetric

_FIELDS = ("min_s2", "n_colliding", "in_collision", "softmin", "cost")
_DTYPES = {"min_s2": np.float32, "n_colliding": np.int32, "in_collision": bool, "softmin": np.float32, "cost": np.float32}


@overload
def _tile(x: np.ndarray, period: int, b: int) -> np.ndarray: ...
@overload
def _tile(x: None, period: int, b: int) -> None: ...
@overload
def _tile(x: np.ndarray | None, period: int, b: int) -> np.ndarray | None: ...
def _tile(x: np.ndarray | None, period: int, b: int) -> np.ndarray | None:
    """Rows of a compact (P, ...) array for every query (row q % P)."""
    if x is None or period == b:
        return x
    return np.tile(x, (b // max(period, 1),) + (1,) * (x.ndim - 1))


class CollisionChecker:
    """Batched CollisionSplatting queries against one scene.

    Args:
        scene: the splats (validated; floaters are *not* filtered here, do that when loading).
        n_sigma: conservatism knob (>= 0), shortcut for ``config.n_sigma``.
        device: "cpu", "cuda", "cuda:N" or None/"auto".
        config: full :class:`MetricConfig`; ``n_sigma`` overrides its field when given.
        backend: "warp" (the streaming kernel) or "reference" (numpy brute force, slow).
        tiers: how splats are binned into tiers (:class:`~splatplan.metric.tiers.TierConfig`,
            a performance knob; results are exact either way).
    """

    def __init__(
        self,
        scene: Splats,
        n_sigma: float | None = None,
        device: str | None = "auto",
        config: MetricConfig | None = None,
        backend: str = "warp",
        tiers=None,
    ) -> None:
        cfg = config or MetricConfig()
        if n_sigma is not None:
            cfg = replace(cfg, n_sigma=float(n_sigma))
        self.config = cfg.validate()
        if len(scene) == 0:
            raise SplatplanError("the scene has no splats to check against")
        self.scene = scene.validate()
        if backend not in ("warp", "reference"):
            raise SplatplanError(f"unknown backend {backend!r}: use 'warp' or 'reference'")
        self.backend = backend
        self._impl: WarpMetric | None = None  # the kernels (None: the reference backend)
        self._robot_axes: dict = {}  # semi-axes bytes -> (wp.array (E,) vec3, a_min median, a_max median)
        self._lock = threading.Lock()
        if backend == "warp":
            from .wp_metric import WarpMetric

            self._impl = WarpMetric(scene, device=device, tiers=tiers)
            self.device = self._impl.device
        else:
            from .._warp import resolve_device

            self.device = resolve_device(device) if device not in (None, "auto") else "cpu"

    # ------------------------------------------------------------------ life cycle
    def close(self) -> None:
        """Release the CPU thread pool (the checker stays usable: a later query starts a new one)."""
        if self._impl is not None:
            self._impl.close()

    def _kernels(self) -> WarpMetric:
        """The Warp implementation: the calls that reach the kernels come from the warp backend."""
        if self._impl is None:
            raise AssertionError("the reference backend has no kernels")
        return self._impl

    def __enter__(self) -> "CollisionChecker":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    @property
    def n_sigma(self) -> float:
        return self.config.n_sigma

    def with_config(self, **changes) -> "CollisionChecker":
        """A checker sharing this one's scene data, grids and thread pool with some config fields changed."""
        other = object.__new__(CollisionChecker)
        other.__dict__.update(self.__dict__)
        other.config = replace(self.config, **changes).validate()
        return other

    def workspace(self, capacity: int = 0) -> MetricWorkspace:
        """Preallocated output buffers on this checker's device, for ``out=`` (see :class:`MetricWorkspace`)."""
        return MetricWorkspace(self.device).reserve(capacity)

    def thread_workspace(self) -> MetricWorkspace:
        """The calling thread's workspace kept by this checker: callers that check many batches on one
        thread (the planners, search after search) share its buffers and recorded launches. Results
        written into it are valid until the thread's next call with it: copy what you keep."""
        with self._lock:
            held = self.__dict__.get("_thread_ws")
            if held is None or held[0] != id(self):  # (a checker from with_config copied this one's)
                held = self.__dict__["_thread_ws"] = (id(self), threading.local())
        ws = getattr(held[1], "ws", None)
        if ws is None:
            ws = held[1].ws = self.workspace()
        return ws

    # ------------------------------------------------------------------ queries
    def query(self, centers, quats, semi_axes, *, rots=None, out=None, validate=False) -> QueryResult:
        """All five outputs for a batch of link poses (see :class:`QueryResult`).

        Args:
            centers: (..., 3) link centres, world frame: numpy, torch or wp (vec3 or float32).
            quats: (..., 4) wxyz world <- link, or None (axis-aligned, or ``rots`` given); broadcast
                over the batch.
            semi_axes: the link's semi-axes (scene units): (3,), a scalar (a sphere's radius), or
                (..., 3) broadcast over the batch. No default: a robot's size is the caller's
                (``query_robot`` takes a Robot).
            rots: (..., 3, 3) world <- link rotation matrices instead of ``quats``.
            out: a :meth:`workspace` whose buffers receive the results (returned as views of them).
            validate: device inputs only: raise on non-finite input (one device sync). Without
                it, invalid queries read in_collision = True with NaN distances.
        """
        return self._run(centers, quats, rots, semi_axes, out, validate, full=True)

    def collides(self, centers, quats, semi_axes, *, rots=None, out=None, validate=False):
        """Boolean collision state only (n_colliding > k_collide); stops at the (k+1)-th hit.

        Much cheaper than :meth:`query` for RRT edge checks. Shape: the batch shape; type: the
        input's (arguments as in :meth:`query`).
        """
        return self._run(centers, quats, rots, semi_axes, out, validate, full=False)

    def _run(self, centers, quats, rots, semi_axes, out, validate: bool, full: bool):
        """:meth:`query` (``full``: a QueryResult) or :meth:`collides` (the in_collision array): the
        numpy reference for what the kernels do not take, the empty batch, or the kernel into a
        workspace; the inputs stay referenced (``keep``) until the kernel is done."""
        with _torch_stream(centers):
            prep = self._prepare(centers, quats, rots, semi_axes)
            if prep is None:
                return self._reference(centers, quats, rots, semi_axes, full=full)
            kind, shape, b, links, amin, amax, keep = prep
            if b == 0:
                return QueryResult(**{k: self._empty(kind, shape, _DTYPES[k]) for k in _FIELDS}) if full else self._empty(kind, shape, bool)
            ws = self._workspace(out, b)
            if kind != "numpy":
                ws.reset_bad()
            if full:
                self._kernels().query(links, b, amin, amax, self.config, ws.outputs(), ws.scratch())
            else:
                self._kernels().collides(links, b, amin, amax, self.config, ws.in_collision, ws.bad, ws.scratch())
            self._raise_bad(ws, kind, validate)
        del keep
        if full:
            return QueryResult(**{k: convert_out(getattr(ws, k), b, shape, kind, False) for k in _FIELDS})
        return convert_out(ws.in_collision, b, shape, kind, False)

    def blockers(self, center, quat, semi_axes) -> "Blockers":
        """What makes one ellipsoid collide: the splats it counts (s2~ < 1), summarised.

        Host numpy over the splats near the ellipsoid (the reference formulas; one query, for error
        messages and diagnostics, not a hot loop). ``center`` (3,) world frame, ``quat`` (4,) wxyz
        world <- link or None, ``semi_axes`` (3,) scene units.
        """
        return find_blockers(self.scene, self.config, center, quat, semi_axes)

    # ------------------------------------------------------------------ robots
    def query_robot(self, robot: Robot, q, *, ellipsoids=None, out=None, validate=False) -> QueryResult:
        """All five outputs for every collision ellipsoid of ``robot`` at joint configurations ``q``.

        ``q`` (..., dof) (numpy, torch or wp float32) -> forward kinematics on the device
        (``robot.fk_wp``) -> the metric, with no host round trip; outputs shaped (..., E), of the
        type of ``q``. numpy ``q`` is validated by ``robot.check_q`` (shape, NaN); device ``q`` costs
        O(1) host work (NaN joint values make their ellipsoids read in_collision = True, or raise
        with ``validate=True``). Joint limits are not enforced: the geometry of any configuration is
        checked (clip first with ``robot.check_q(q, clip=True)`` where limits matter).
        ``ellipsoids``: only these ellipsoid indices (outputs (..., len(ellipsoids)) in that order),
        e.g. the moving ones when the static ones were queried once.
        """
        with _torch_stream(q):
            return self._robot(robot, q, out, validate, full=True, subset=ellipsoids)

    def collides_robot(self, robot: Robot, q, *, ellipsoids=None, out=None, validate=False, slack=None):
        """(..., E) collision state of every ellipsoid of ``robot`` at ``q`` (see :meth:`query_robot`).

        A configuration collides when any of its ellipsoids does: ``collides_robot(...).any(-1)``;
        :meth:`collides_configs` answers that directly, cheaper. With the FREE SLACK:
        :meth:`collides_robot_slack`. (``slack=True`` is deprecated: it changed the return type.)
        """
        if slack is not None:
            warnings.warn("collides_robot(slack=...) is deprecated and goes in 0.3: use collides_robot_slack(robot, q) for (hits, slack)", DeprecationWarning, stacklevel=2)
        with _torch_stream(q):
            return self._robot(robot, q, out, validate, full=False, subset=ellipsoids, slack=bool(slack))

    def collides_robot_slack(self, robot: Robot, q, *, ellipsoids=None, out=None, validate=False, rigid_target=None):
        """(hits (..., E), slack (..., E) float32, both of the type of ``q``): :meth:`collides_robot`
        and each ellipsoid's FREE SLACK, a distance (scene units) such that the same ellipsoid, in any
        orientation, with its centre within ``slack`` of this one's, is free too (:mod:`.wp_metric_kernel`);
        0 where nothing is proven (a link near splats, the reference backend, or
        ``collide_distance_grid`` off). ``rigid_target`` (scene units; a scalar or (..., E)): the
        RIGID SLACK instead, a weaker promise kept near splats too: the ellipsoid moved rigidly so
        that no point of it moves farther than ``slack`` is free. One whose FREE SLACK is below its
        target reads the splats out to it (at most its smallest semi-axis) for the clearance of its
        closest mean. Planners, which bound every link point's motion along an edge, use it."""
        with _torch_stream(q):
            return self._robot(robot, q, out, validate, full=False, subset=ellipsoids, slack=True, target=rigid_target)

    def collides_configs(self, robot: Robot, q, *, out=None, validate=False):
        """(...,) collision state of whole configurations: True where any ellipsoid of ``robot`` at
        ``q`` (..., dof) collides; the same answer as ``collides_robot(robot, q).any(-1)``.

        One thread per configuration (GROUP BOUND, :mod:`.wp_metric_kernel`): the ellipsoids of a
        link are proven free together by one read of the mean-distance grid when the link is far
        from every splat, and a configuration stops at its first colliding ellipsoid. The cheap
        check for planners' edge checks (CPU, numpy: recorded launches in ``out`` or the calling thread's
        workspace, the result then a copy). Other arguments as in :meth:`collides_robot`.
        """
        with _torch_stream(q):
            return self._robot(robot, q, out, validate, full=False, per_config=True)

    def collides_configs_slack(self, robot: Robot, q, *, out=None, validate=False, rigid_target=None):
        """(hits (...,), slack (..., E) float32): :meth:`collides_configs` and each ellipsoid's FREE
        SLACK (with ``rigid_target``: RIGID SLACK) as in :meth:`collides_robot_slack` (for free configurations)."""
        with _torch_stream(q):
            return self._robot(robot, q, out, validate, full=False, slack=True, per_config=True, target=rigid_target)

    def edges_free(self, robot: Robot, starts, ends, n_samples, step, *, target_steps: int = 4, screen: int = 0, validate: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Whether N straight configuration-space edges of ``robot`` are collision-free at their
        check samples, by a SLACK WALK (:mod:`.edge_walk`): the answer of checking every sample with
        :meth:`collides_configs`, with far fewer checks (a checked sample's RIGID SLACK proves its
        neighbours free).

        Args:
            robot: the :class:`~splatplan.robots.Robot`.
            starts: (N, dof) edge starts (not checked: a planner checked them already).
            ends: (N, dof) edge ends.
            n_samples: (N,) int >= 1: edge i is checked at ``starts + (k / n)(ends - starts)``, k = 1..n.
            step: (N, E) float >= 0 (scene units): a bound on how far any point of ellipsoid e moves
                between consecutive samples of edge i (:meth:`Robot.ellipsoid_motion_bounds` times
                |dq| over n).
            target_steps: the slack each check asks for, in samples (more reads more splats per check).
            screen: > 0: first check samples screen, 2 screen, ... < n without slack, stopping at a
                hit (an edge that collides costs few checks; a free one ~n / screen more).
            validate: check the values (finite, n >= 1, step >= 0, ...); False: shapes only, for
                callers that built them (a planner's edges; ~10 us a call).

        Returns (free (N,) bool, checks (N,) int64: configurations checked per edge, up to its first
        colliding sample): one kernel launch on a CPU checker, one checker call per check elsewhere
        (the same answers). Raises SplatplanError for shapes that do not match the robot, non-finite
        values, n < 1 or step < 0.
        """
        from .edge_walk import edge_inputs, walk_with_checker

        a, b, n, st, t, scr = edge_inputs(starts, ends, n_samples, step, int(robot.dof), int(robot.n_ellipsoids), target_steps, screen, validate)
        if len(a) and self.backend != "reference" and self.device == "cpu" and self._impl is not None and len(a) <= MAX_BATCH and fast_path_robot(robot):
            free, checks = launcher_for(self._impl, self.config, self._axes_for, robot, self.thread_workspace(), len(a)).walk(a, b, n, st, t, scr)
            return free.copy(), checks.astype(np.int64)
        return walk_with_checker(self, robot, a, b, n, st, t, scr)

    def _robot(self, robot, q, out, validate, full: bool, subset=None, slack: bool = False, per_config: bool = False, target=None):
        kind = array_kind(q)
        sub = None if subset is None else [int(i) for i in np.asarray(subset).reshape(-1)]
        if sub is not None and (not sub or min(sub) < 0 or max(sub) >= robot.n_ellipsoids):
            raise SplatplanError(f"ellipsoids must be a non-empty list of indices in 0..{robot.n_ellipsoids - 1}, got {subset}")
        e = int(robot.n_ellipsoids) if sub is None else len(sub)
        dof = int(robot.dof)
        if self.backend == "reference":
            qn = robot.check_q(host_array(q), check_limits=False)
            c, quat, ax = robot.ellipsoids(qn)
            if sub is not None:
                c, quat, ax = c[..., sub, :], quat[..., sub, :], ax[sub]
            res = self.query(c, quat, ax) if full else self.collides(c, quat, ax)
            if per_config:
                res = np.asarray(res).any(axis=-1)
            res = _convert_host(res, kind, _device_of(q, self.device))
            if slack:
                return res, _from_host(np.zeros(np.shape(qn)[:-1] + (e,), dtype=np.float32), kind, _device_of(q, self.device))
            return res
        if per_config and sub is None and kind == "numpy" and self.device == "cpu" and self._impl is not None:  # the lean path
            lean = self.thread_workspace() if out is None else self._workspace(out, 1)
            fast = fast_collides_configs(self._impl, self.config, self._axes_for, robot, q, lean, slack, target)
            if fast is not None:  # (without ``out``: a copy, the thread's buffers are reused)
                return fast if out is not None else ((fast[0].copy(), fast[1].copy()) if slack else fast.copy())
        from .._warp import wp as _wp
        from .wp_metric_kernel import LinkBatch

        wp = _wp()
        ws = None
        if kind == "numpy":
            qn = robot.check_q(q, check_limits=False)  # (..., dof) float64, validated (shape, NaN)
            shape = tuple(qn.shape[:-1])
            if out is not None and self.device == "cpu" and qn.size:  # into the workspace's buffer: no allocation
                ws = self._workspace(out, 1)
                qw = ws.reserve_q(qn.size // dof, dof)
                qw.numpy()[:] = qn.reshape(-1, dof)
            else:
                qw = wp.array(np.ascontiguousarray(qn.reshape(-1, dof), dtype=np.float32), dtype=wp.float32, device=self.device)
        else:
            if tuple(q.shape[-1:]) != (dof,):
                raise SplatplanError(f"q must have shape (..., {dof}) for robot {robot.name!r}, got {tuple(q.shape)}")
            shape = tuple(q.shape[:-1])
            qw = _device_q(q, kind, dof, self.device)
        b = int(np.prod(shape, dtype=np.int64)) if shape else 1
        oshape = shape + (e,)
        n = b * e
        tgt = None if target is None or not slack else rigid_targets(target, oshape)  # (n,) float32
        if n == 0:
            if per_config:
                hits = self._empty(kind, shape, bool)
                return (hits, self._empty(kind, oshape, np.float32)) if slack else hits
            if full:
                return QueryResult(**{k: self._empty(kind, oshape, _DTYPES[k]) for k in _FIELDS})
            if slack:
                return self._empty(kind, oshape, bool), self._empty(kind, oshape, np.float32)
            return self._empty(kind, oshape, bool)
        ws = self._workspace(out, n)
        ws.reserve_fk(n)
        if per_config and sub is None:  # whole buffers (the kernels read rows < n only): no per-call views
            return self._configs(robot, qw, ws, b, n, e, shape, kind, validate, slack, out is not None, tgt)
        centers, rots = ws.fk_centers[:n], ws.fk_rots[:n]
        if sub is None:  # robots of other types may take no subset (the duck-typed fk_wp of the docs)
            robot.fk_wp(qw, centers, rots)
        else:
            robot.fk_wp(qw, centers, rots, ellipsoids=sub)
        axes, amin, amax = self._axes_for(robot, sub)
        links = LinkBatch()
        links.centers, links.rots, links.axes = centers, rots, axes
        links.rot_mode, links.rot_period, links.axes_period = 2, n, e
        if kind != "numpy":
            ws.reset_bad()
        if per_config:
            sl = (ws.reserve_slack(n) if out is not None else wp.empty(n, dtype=wp.float32, device=self.device)) if slack else None
            self._kernels().collides_configs(links, b, robot_groups(robot), amin, amax, self.config, ws.in_collision, ws.bad, slack=fill_target(sl, tgt, n), rigid=tgt is not None)
            self._raise_bad(ws, kind, validate)
            hits = convert_out(ws.in_collision, b, shape, kind, False)
            return (hits, convert_out(sl, n, oshape, kind, False)) if slack else hits
        if full:
            self._kernels().query(links, n, amin, amax, self.config, ws.outputs(), ws.scratch())
        else:
            sl = wp.empty(n, dtype=wp.float32, device=self.device) if slack else None
            self._kernels().collides(links, n, amin, amax, self.config, ws.in_collision, ws.bad, ws.scratch(), robot_batch=True, slack=fill_target(sl, tgt, n), rigid=tgt is not None)
        self._raise_bad(ws, kind, validate)
        if full:
            return QueryResult(**{k: convert_out(getattr(ws, k), n, oshape, kind, False) for k in _FIELDS})
        if slack:
            return convert_out(ws.in_collision, n, oshape, kind, False), convert_out(sl, n, oshape, kind, False)
        return convert_out(ws.in_collision, n, oshape, kind, False)

    def _configs(self, robot, qw, ws: MetricWorkspace, b: int, n: int, e: int, shape, kind: str, validate: bool, slack: bool, reuse: bool, tgt=None):
        """:meth:`collides_configs` after the configuration checks: FK into the workspace, the
        per-configuration kernel, the outputs (the LinkBatch cached in the workspace)."""
        from .._warp import wp as _wp
        from .wp_metric_kernel import LinkBatch

        wp = _wp()
        robot.fk_wp(qw, ws.fk_centers, ws.fk_rots)
        axes, amin, amax = self._axes_for(robot)
        hit = ws._cache.get("configs_links")
        # reuse the struct only while it points at these very buffers (identity, not id(): an id can
        # be reused by a new array once the old one is freed)
        if hit is not None and hit[1] is ws.fk_centers and hit[2] is ws.fk_rots and hit[3] is axes and hit[4] == e:
            links = hit[0]
        else:
            links = LinkBatch()
            links.centers, links.rots, links.axes = ws.fk_centers, ws.fk_rots, axes
            links.rot_mode, links.rot_period, links.axes_period = 2, int(ws.fk_centers.shape[0]), e
            ws._cache["configs_links"] = (links, ws.fk_centers, ws.fk_rots, axes, e)  # (the buffers kept alive with it)
        if kind != "numpy":
            ws.reset_bad()
        sl = (ws.reserve_slack(n) if reuse else wp.empty(n, dtype=wp.float32, device=self.device)) if slack else None
        self._kernels().collides_configs(links, b, robot_groups(robot), amin, amax, self.config, ws.in_collision, ws.bad, slack=fill_target(sl, tgt, n), rigid=tgt is not None)
        self._raise_bad(ws, kind, validate)
        hits = convert_out(ws.in_collision, b, shape, kind, False)
        return (hits, convert_out(sl, n, shape + (e,), kind, False)) if slack else hits

    def _axes_for(self, robot, subset=None):
        """Robot semi-axes (E,) (or of the ellipsoids ``subset``) on the device plus their
        grid-sizing medians (cached by value)."""
        from .._warp import wp as _wp

        wp = _wp()
        ax = np.asarray(robot.semi_axes, dtype=np.float64).reshape(-1, 3)
        ax = np.ascontiguousarray(ax if subset is None else ax[subset])
        key = ax.tobytes()
        hit = self._robot_axes.get(key)
        if hit is None:
            if not np.all(np.isfinite(ax)) or np.any(ax <= 0):
                raise SplatplanError(f"robot {robot.name!r} has semi-axes that are not finite and > 0")
            hit = (wp.array(ax.astype(np.float32), dtype=wp.vec3, device=self.device), *axes_medians(ax))
            with self._lock:
                if len(self._robot_axes) >= 16:
                    self._robot_axes.clear()
                self._robot_axes[key] = hit
        return hit

    # ------------------------------------------------------------------ plumbing
    def _prepare(self, centers, quats, rots, semi_axes):
        """(kind, batch shape, B, LinkBatch, a_min, a_max, keep-alive) or None for the reference backend."""
        kind = array_kind(centers)
        if self.backend == "reference":
            return None
        if kind == "numpy":
            h = as_host_queries(centers, quats, semi_axes, rots)
            b = h.centers.shape[0]
            if b == 0:
                return kind, h.shape, 0, None, 0.0, 0.0, None
            links, keep = host_link_batch(h, self.device)
            return (kind, h.shape, b, links, *axes_medians(h.axes), keep)
        from .wp_metric_kernel import LinkBatch

        if quats is not None and rots is not None:
            raise SplatplanError("give link orientations as quats or as rots, not both")
        carr, shape, keep_c = device_rows(centers, kind, "centers", (3,), self.device)
        b = int(np.prod(shape, dtype=np.int64)) if shape else 1
        if b == 0:
            return kind, shape, 0, None, 0.0, 0.0, None
        links = LinkBatch()
        links.centers = carr
        links.rot_mode, links.rot_period, links.use_order = 0, 1, 0
        keep = [keep_c, carr]
        if quats is not None:
            links.quats, links.rot_period, k, _ = device_side_rows(quats, "quats", (4,), shape, self.device)
            links.rot_mode = 1
            keep.append(k)
        elif rots is not None:
            links.rots, links.rot_period, k, _ = device_side_rows(rots, "rots", (3, 3), shape, self.device)
            links.rot_mode = 2
            keep.append(k)
        links.axes, links.axes_period, k, host_axes = device_side_rows(semi_axes, "semi_axes", (3,), shape, self.device)
        keep.append(k)
        if host_axes is not None:
            if not np.all(np.isfinite(host_axes)) or np.any(host_axes <= 0):
                raise SplatplanError("semi_axes must be finite and > 0")
            amin, amax = axes_medians(host_axes)
        else:
            amin, amax = device_axes_medians(links.axes, self.device)
        return kind, shape, b, links, amin, amax, keep

    def _workspace(self, out, n: int) -> MetricWorkspace:
        if out is None:
            return MetricWorkspace(self.device).reserve(n)
        if not isinstance(out, MetricWorkspace):
            raise SplatplanError("out must be a workspace from checker.workspace()")
        if out.device != self.device:
            raise SplatplanError(f"the workspace is on {out.device} but the checker runs on {self.device}")
        return out.reserve(n)

    @staticmethod
    def _raise_bad(ws: MetricWorkspace, kind: str, validate: bool) -> None:
        if validate and kind != "numpy":
            i = ws.first_bad()
            if i is not None:
                raise SplatplanError(
                    f"query {i} (flat index) is invalid: a NaN/Inf centre, rotation or semi-axis, a zero quaternion "
                    "or a semi-axis <= 0"
                )

    def _empty(self, kind: str, shape, dtype):
        return _from_host(np.zeros(shape, dtype=dtype), kind, self.device)

    def _reference(self, centers, quats, rots, semi_axes, full: bool):
        """The numpy brute force on any input type (converted to and from the host)."""
        from .reference import collision_metric_ref

        kind = array_kind(centers)
        h = as_host_queries(centers, quats, semi_axes, rots)
        b = h.centers.shape[0]
        dev = _device_of(centers, self.device)
        if b == 0:
            res = QueryResult(**{k: np.zeros(h.shape, dtype=_DTYPES[k]) for k in _FIELDS})
        else:
            s = self.scene
            r = collision_metric_ref(
                s.means, s.quats, s.scales, h.centers, _tile(h.quats, h.rot_period, b), _tile(h.axes, h.axes_period, b),
                self.config, opacities=s.opacities, rots=_tile(h.rots, h.rot_period, b),
            )  # fmt: skip
            res = QueryResult(
                r.min_s2.astype(np.float32), r.n_colliding.astype(np.int32), r.in_collision,
                r.softmin.astype(np.float32), r.cost.astype(np.float32),
            ).reshape(h.shape)  # fmt: skip
        return _convert_host(res if full else res.in_collision, kind, dev)



def _torch_stream(x):
    """For a CUDA torch tensor: run Warp on torch's current stream (so zero-copy reads and writes are
    ordered with the caller's torch work); a no-op otherwise."""
    if array_kind(x) == "torch" and x.device.type == "cuda":
        from .._warp import wp as _wp

        wp = _wp()
        return wp.ScopedStream(wp.stream_from_torch(x.device))
    return contextlib.nullcontext()


def _device_of(x, default: str) -> str:
    k = array_kind(x)
    if k == "torch":
        return torch_device_name(x)
    if k == "warp":
        return warp_device_name(x)
    return default


def _from_host(a: np.ndarray, kind: str, device: str):
    """A host array as the caller's type on ``device``."""
    if kind == "numpy":
        return a
    if kind == "torch":
        import torch

        return torch.from_numpy(np.ascontiguousarray(a)).to(device)
    from .._warp import wp as _wp

    wp = _wp()
    flat = np.ascontiguousarray(a).reshape(-1) if a.ndim == 0 else np.ascontiguousarray(a)
    return wp.array(flat, dtype=wp.bool if a.dtype == bool else wp.dtype_from_numpy(a.dtype), device=device)


def _convert_host(res, kind: str, device: str):
    if isinstance(res, QueryResult):
        return QueryResult(**{k: _from_host(v, kind, device) for k, v in res.as_dict().items()})
    return _from_host(res, kind, device)


def _device_q(q, kind: str, dof: int, device: str):
    """Joint configurations (..., dof) on the device as a float32 (B, dof) wp.array: O(1) host work."""
    from .._warp import wp as _wp

    wp = _wp()
    if kind == "torch":
        import torch

        check_device("q", torch_device_name(q), device)
        if not q.is_floating_point():
            raise SplatplanError(f"q must be a floating-point tensor, got {q.dtype}")
        t = q.detach().to(torch.float32).contiguous().reshape(-1, dof)
        return wp.from_torch(t, dtype=wp.float32)
    check_device("q", warp_device_name(q), device)
    if q.dtype != wp.float32 or not q.is_contiguous:
        raise SplatplanError(f"q as a wp.array must be contiguous float32 shaped (..., {dof})")
    n = int(np.prod(q.shape[:-1], dtype=np.int64)) if q.ndim > 1 else 1
    return q.reshape((n, dof))
