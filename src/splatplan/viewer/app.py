"""The splatplan viewer: a ``viser`` server showing splats, a robot, its conservatism and plans.

A layer on top of the library (nothing in scenes/metric/robots/planners imports it):

    from splatplan.viewer import SplatViewer, ViewerConfig
    v = SplatViewer(scene, robot=load_robot("sphere:0.015"), plan=path, config=ViewerConfig(port=8080))
    v.start(); print(v.url); ...; v.stop()

Frames: the scene's world frame and units, as loaded (no axis conversion); quaternions wxyz.
Every GUI callback that changes the robot pose recomputes its collision state with the
CollisionSplatting metric (one ``checker.query`` over the robot's ellipsoids) and records the
time it took (``timings``, and the ``--status-file`` log).
"""

from __future__ import annotations

import json
from collections import deque
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from .._config import bounded, check_config
from .._resources import require_bytes
from ..errors import SplatplanError
from .geometry import colormap, ellipsoid_mesh, polyline_segments, splat_s2_tilde, tree_segments
from .ports import free_port, port_free

if TYPE_CHECKING:
    import viser
    from viser.extras import ViserUrdf

    from ..robots.robot import Robot
    from ..scenes.splats import Splats


@dataclass
class ViewerConfig:
    """Knobs of :class:`SplatViewer`."""

    #: Interface to listen on (loopback by default: the viewer is not meant to be exposed).
    host: str = "127.0.0.1"
    #: TCP port of the web page.
    port: int = bounded(8080, ge=1, le=65535)
    #: Initial conservatism n_sigma of the collision colouring and re-planning (slider in the GUI, 0..3).
    n_sigma: float = bounded(1.0, ge=0, le=3)
    #: Scenes with more splats are randomly decimated to this many for the browser (the metric
    #: still uses every splat); the viewer says so on stdout.
    max_splats: int = bounded(1_000_000, ge=1)
    #: Device of the collision checker: auto | cpu | cuda | cuda:N.
    device: str = "auto"
    #: Resolution (cells per side) of the collision-field slice.
    field_res: int = bounded(96, ge=2)
    #: When set, one JSON line per event (ready, client, n_sigma, pose, plan) is appended here:
    #: a log for tests and benchmarks.
    status_file: str | None = None

    def validate(self) -> "ViewerConfig":
        """Check every field's declared range (:mod:`splatplan._config`); returns self."""
        return check_config(self)


def _vec3(a) -> tuple[float, float, float]:
    """A viser position from 3 numbers."""
    return (float(a[0]), float(a[1]), float(a[2]))


def _wxyz(a) -> tuple[float, float, float, float]:
    """A viser orientation from a wxyz quaternion."""
    return (float(a[0]), float(a[1]), float(a[2]), float(a[3]))


def _robot_kind(robot: Robot) -> Literal["point", "planar", "joints"]:
    """How the viewer moves the robot, from what the robot is: 'point' (dofs x, y, z: dragged),
    'planar' (a planar base whose dofs are x, y, yaw: dragged and turned) or 'joints' (sliders)."""
    if robot.is_point:
        return "point"
    if robot.base == "planar" and robot.dof == 3:
        return "planar"
    return "joints"


@dataclass
class _State:
    q: np.ndarray
    n_sigma: float
    colour_by_metric: bool = True
    show_ellipsoids: bool = True
    field_z: float = 0.0
    show_field: bool = True
    #: the last 1,000 pose-update times (ms), for the status line and the benchmark
    timings: dict = field(default_factory=lambda: {"pose_update_ms": deque(maxlen=1000)})


class SplatViewer:
    """A viser app over one scene (and optionally a robot, a plan, an MPC run and an RRT tree).

    Args:
        scene: :class:`~splatplan.scenes.splats.Splats`, scene frame and units.
        robot: a :class:`~splatplan.robots.Robot` (or None: a sphere robot sized to the scene).
        plan: optional path (P, dof) in the robot's configuration space.
        trajectory: optional executed MPC trajectory (T, dof) (animated with a time slider).
        tree: optional RRT tree (nodes (N, D), parents (N,)).
        config: :class:`ViewerConfig`.
        collision_scene: the splats the collision checks see (default ``scene``); for a ground
            robot, the scene without its terrain (:func:`splatplan.scenes.terrain.remove_terrain`).
    """

    _field: viser.ImageHandle  # the collision-field image (set by the first _update_field that draws it)

    def __init__(self, scene: Splats, robot: Robot | None = None, plan=None, trajectory=None, tree=None, config: ViewerConfig | None = None,
                 collision_scene: Splats | None = None) -> None:
        from ..metric import CollisionChecker

        self.config = cfg = (config or ViewerConfig()).validate()
        # the field slice: res^2 probe points, their metric outputs and an RGB image (an estimate per cell)
        require_bytes(float(cfg.field_res) ** 2 * 128, f"the collision-field slice of {cfg.field_res}^2 cells", "--field-res")
        self.scene = scene
        lo, hi = scene.bounds()
        # robust bounds for the GUI ranges (outliers far away do not stretch the sliders)
        self.lo = np.quantile(scene.means, 0.005, axis=0).astype(np.float64)
        self.hi = np.quantile(scene.means, 0.995, axis=0).astype(np.float64)
        self.extent = float(np.max(self.hi - self.lo))
        if robot is None:
            from ..robots import load_robot, point_radius

            robot = load_robot(f"sphere:{point_radius() * self.extent:.6g}")  # the default sphere, scaled by the scene's extent
        self.robot = robot
        self.kind = _robot_kind(robot)
        self.checker = CollisionChecker(scene if collision_scene is None else collision_scene, n_sigma=cfg.n_sigma, device=cfg.device)
        self.plan = None if plan is None else np.asarray(plan, dtype=np.float64)
        self.trajectory = None if trajectory is None else np.asarray(trajectory, dtype=np.float64)
        self.tree = tree
        for what, arr in (("plan", self.plan), ("trajectory", self.trajectory)):
            if arr is not None and (arr.ndim != 2 or arr.shape[1] != robot.dof):
                raise SplatplanError(f"{what}: expected shape (P, {robot.dof}) for robot {robot.name}, got {arr.shape}")
        q0 = np.asarray(robot.q_default, dtype=np.float64).copy()
        if self.kind == "point":
            q0 = 0.5 * (self.lo + self.hi)
        elif self.kind == "planar":
            q0[:2] = 0.5 * (self.lo[:2] + self.hi[:2])
        if self.plan is not None:
            q0 = self.plan[0].copy()
        elif self.trajectory is not None:
            q0 = self.trajectory[0].copy()
        # the field slice starts at the height of the robot's ellipsoids (clipped to the scene)
        z0 = float(np.mean(np.asarray(robot.ellipsoids(q0)[0])[..., 2]))
        self.state = _State(q=q0, n_sigma=cfg.n_sigma, field_z=float(np.clip(z0, self.lo[2], self.hi[2])), show_field=self.kind == "point")
        self._syncing = False  # True while set_q moves the joint sliders (their callbacks then do nothing)
        self.server: viser.ViserServer | None = None
        self._lock = threading.Lock()
        self._plan_thread: threading.Thread | None = None
        self.warnings: list[str] = []
        self._check_inside(self.plan, "plan")
        self._check_inside(self.trajectory, "trajectory")
        # the colouring's candidate search: a KD-tree over the means
        from scipy.spatial import cKDTree

        self._kdtree = cKDTree(scene.means)
        self._smax = float(scene.scales.max())

    # ------------------------------------------------------------------ checks
    def _check_inside(self, arr, what: str) -> None:
        """Warn (stdout) when a plan's points lie outside the scene bounds grown by what the robot needs
        (:func:`~splatplan.planners.bounds.box_margin`: a ground robot's footprint diameter, a point
        robot's size), and 10% of the scene's extent: a plan for another scene?"""
        if arr is None or self.kind == "joints":
            return
        from ..planners.bounds import box_margin

        pts = arr[:, : 2 if self.kind == "planar" else 3]
        pad = max(0.1 * self.extent, box_margin(self.robot))
        out = np.any((pts < self.lo[: pts.shape[1]] - pad) | (pts > self.hi[: pts.shape[1]] + pad), axis=1)
        if out.any():
            msg = f"warning: {int(out.sum())} of {len(pts)} {what} points lie outside the scene bounds (a {what} for another scene?)"
            self.warnings.append(msg)
            print(msg, flush=True)

    # ------------------------------------------------------------------ status log
    def _log(self, event: str, **data) -> None:
        if not self.config.status_file:
            return
        rec = {"event": event, "t": time.time(), **data}
        with self._lock, open(self.config.status_file, "a") as f:
            f.write(json.dumps(rec) + "\n")

    @property
    def url(self) -> str:
        return f"http://{self.config.host}:{self.config.port}"

    # ------------------------------------------------------------------ robot state
    def collision_state(self, q: np.ndarray | None = None) -> dict:
        """Per-link collision counts at q: {"collides", "per_link": {link: n_colliding}, "min_s2", "ms"}."""
        return self._collision_state(*self.robot.ellipsoids(self.state.q if q is None else q))

    def _collision_state(self, c, quat, ax) -> dict:
        t0 = time.perf_counter()
        res = self.checker.with_config(n_sigma=self.state.n_sigma).query(c, quat, ax)
        per_link: dict[str, int] = {}
        links = np.asarray(self.robot.ellipsoid_link)
        for e, n in enumerate(np.asarray(res.n_colliding).reshape(-1)):
            name = self.robot.link_names[int(links[e])]
            per_link[name] = per_link.get(name, 0) + int(n)
        ms = 1e3 * (time.perf_counter() - t0)
        return {"collides": bool(np.any(res.in_collision)), "per_link": per_link, "min_s2": float(np.min(res.min_s2)), "ms": ms}

    def splat_distances(self, q: np.ndarray | None = None, cap: float = 2.0) -> np.ndarray:
        """Per-splat min over the robot's ellipsoids of s2~ at q (N,); +inf beyond the search ball."""
        return self._splat_distances(*self.robot.ellipsoids(self.state.q if q is None else q), cap=cap)

    def _splat_distances(self, c, quat, ax, cap: float = 2.0) -> np.ndarray:
        from ..metric.wp_metric_kernel import search_radius  # the metric's one exactness radius

        ax = np.broadcast_to(ax, c.shape)
        cand = []
        for e in range(len(c)):
            rho = float(search_radius(self.state.n_sigma, self._smax, float(ax[e].min()), float(ax[e].max()), cap))
            cand.append(np.asarray(self._kdtree.query_ball_point(c[e], rho), dtype=np.int64))
        s = self.scene
        return splat_s2_tilde(s.means, s.quats, s.scales, c, quat, ax, self.state.n_sigma, cand)

    # ------------------------------------------------------------------ server
    def start(self) -> None:
        import viser

        cfg = self.config
        try:
            free_port(cfg.host)  # the host must be an address of this machine (binds port 0)
        except OSError as exc:  # gaierror (unknown name), EADDRNOTAVAIL (another machine's address)
            raise SplatplanError(f"cannot listen on host {cfg.host!r} ({exc.strerror or exc}); use an address of this machine, e.g. 127.0.0.1 or 0.0.0.0") from None
        if not port_free(cfg.host, cfg.port):
            raise SplatplanError(f"port {cfg.port} on {cfg.host} is in use; try --port {free_port(cfg.host)}")
        self.server = srv = viser.ViserServer(host=cfg.host, port=cfg.port, verbose=False)
        srv.scene.set_up_direction("+z")
        self._add_splats()
        self._add_robot()
        self._add_paths()
        self._add_gui()
        self._update_pose()
        self._update_field()

        @srv.on_client_connect
        def _(client) -> None:
            client.camera.position = tuple(self.hi + 0.6 * (self.hi - self.lo) * np.array([0.2, -1.0, 1.0]))
            client.camera.look_at = tuple(0.5 * (self.lo + self.hi))
            client.camera.up_direction = (0.0, 0.0, 1.0)
            self._log("client", id=int(client.client_id))

        self._log("ready", url=self.url, n_splats=int(self._n_shown), robot=str(self.robot.name), nodes=self.node_names())

    def node_names(self) -> list[str]:
        """Names of the scene nodes this viewer added (splats, robot, plans, metric overlays)."""
        names = ["/splats"] + [f"/robot/ellipsoids/{e}" for e in range(len(self._ell_handles))]
        if self._urdf is not None:
            names.append("/robot/urdf")
        if self.tree is not None:
            names.append("/plans/tree")
        names += [f"/plans/{n}" for n, a in (("plan", self.plan), ("trajectory", self.trajectory)) if a is not None and len(a) > 1]
        return names + (["/metric/field"] if self.state.show_field else [])

    def stop(self) -> None:
        if self.server is not None:
            self.server.stop()
            self.server = None

    def _add_splats(self) -> None:
        s = self.scene
        n = len(s)
        idx = np.arange(n)
        if n > self.config.max_splats:
            rng = np.random.default_rng(0)
            idx = np.sort(rng.choice(n, self.config.max_splats, replace=False))
            print(f"showing {len(idx):,} of {n:,} splats in the browser (decimated; the metric uses all of them)", flush=True)
        self._n_shown = len(idx)
        sub = s.subset(idx)
        self._server().scene.add_gaussian_splats(
            "/splats",
            centers=sub.means.astype(np.float32),
            covariances=sub.covariances().astype(np.float32),
            rgbs=np.clip(sub.colors, 0.0, 1.0).astype(np.float32),
            opacities=sub.opacities.reshape(-1, 1).astype(np.float32),
        )

    def _server(self) -> viser.ViserServer:
        """The running server (the scene and the GUI are built by :meth:`start`, after it is set)."""
        assert self.server is not None  # (start() set it)
        return self.server

    def _add_robot(self) -> None:
        srv = self._server()
        c, quat, ax = self.robot.ellipsoids(self.state.q)
        ax = np.broadcast_to(ax, c.shape)
        self._ell_handles = []
        for e in range(len(c)):
            v, f = ellipsoid_mesh(np.zeros(3), np.array([1.0, 0, 0, 0]), ax[e])
            h = srv.scene.add_mesh_simple(f"/robot/ellipsoids/{e}", v, f, color=(90, 200, 255), opacity=0.55,
                                          position=tuple(c[e]), wxyz=tuple(quat[e]))  # fmt: skip
            self._ell_handles.append(h)
        self._urdf: ViserUrdf | None = None
        self._urdf_fixed: dict[str | None, list[float]] = {}  # SRDF joint values (lists)
        info = self.robot.info
        if info.get("urdf") and self.kind in ("joints", "planar"):
            try:
                from viser.extras import ViserUrdf

                if info.get("srdf"):
                    from ..robots.urdf import read_srdf

                    states = read_srdf(info["srdf"]).group_states
                    self._urdf_fixed = dict(states.get("standing" if self.kind == "planar" else "default", {}))
                self._urdf_frame = srv.scene.add_frame("/robot/urdf", show_axes=False)
                self._urdf = ViserUrdf(srv, Path(info["urdf"]), root_node_name="/robot/urdf")
            except Exception as exc:  # meshes are decoration: the ellipsoids are what the metric sees
                self._urdf = None
                print(f"note: robot meshes not shown ({exc.__class__.__name__}: {exc})", flush=True)
        self._hits = srv.scene.add_point_cloud("/metric/colliding_splats", np.zeros((1, 3), np.float32), (255, 0, 0),
                                               point_size=0.004 * self.extent, visible=False)  # fmt: skip
        if self.kind in ("point", "planar"):
            self._gizmo = srv.scene.add_transform_controls("/robot/gizmo", scale=0.15 * self.extent, position=self._q_to_position(self.state.q),
                                                           wxyz=self._q_to_wxyz(self.state.q),
                                                           disable_rotations=self.kind == "point")  # fmt: skip

            @self._gizmo.on_update
            def _(_) -> None:
                self.set_q(self._gizmo_to_q())

    def _q_to_position(self, q) -> tuple:
        if self.kind == "point":
            return tuple(float(v) for v in q[:3])
        c, _, _ = self.robot.ellipsoids(q)
        return (float(q[0]), float(q[1]), float(np.mean(c[:, 2])))

    def _q_to_wxyz(self, q) -> tuple:
        if self.kind == "planar":
            return (float(np.cos(q[2] / 2)), 0.0, 0.0, float(np.sin(q[2] / 2)))
        return (1.0, 0.0, 0.0, 0.0)

    def _gizmo_to_q(self) -> np.ndarray:
        p = np.asarray(self._gizmo.position, dtype=np.float64)
        q = self.state.q.copy()
        if self.kind == "point":
            q[:3] = p
        else:
            w, x, y, z = self._gizmo.wxyz
            q[0], q[1] = p[0], p[1]
            q[2] = float(np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z)))
        return q

    def _add_paths(self) -> None:
        srv = self._server()
        if self.tree is not None:
            nodes, parents = self.tree
            seg = tree_segments(self._trace(np.asarray(nodes, dtype=np.float64)), parents)
            if len(seg):
                srv.scene.add_line_segments("/plans/tree", seg, (150, 150, 150), thickness=0.002 * self.extent)
        for name, arr, colour in (("plan", self.plan, (255, 140, 0)), ("trajectory", self.trajectory, (40, 220, 90))):
            if arr is not None and len(arr) > 1:
                srv.scene.add_line_segments(f"/plans/{name}", polyline_segments(self._trace(arr)), colour, thickness=0.004 * self.extent)

    def _trace(self, qs: np.ndarray) -> np.ndarray:
        """Configurations (P, dof) -> points drawn for them (P, 3): the point, the base or the last link."""
        if self.kind == "point":
            return qs[:, :3]
        c, _, _ = self.robot.ellipsoids(qs)
        if self.kind == "planar":
            return np.concatenate([qs[:, :2], c[:, :, 2].mean(1, keepdims=True)], axis=1)
        return c[:, -1, :]

    def _add_gui(self) -> None:
        gui = self._server().gui
        st = self.state
        self._md = gui.add_markdown("**Robot**: ...")
        self.gui_n_sigma = gui.add_slider("n_sigma", min=0.0, max=3.0, step=0.25, initial_value=float(st.n_sigma),
                                          hint="conservatism: s2~ = max(0, s2 - n_sigma sigma)")  # fmt: skip

        @self.gui_n_sigma.on_update
        def _(_) -> None:
            st.n_sigma = float(self.gui_n_sigma.value)
            self._log("n_sigma", value=st.n_sigma)
            self._update_pose()
            self._update_field()

        cb = gui.add_checkbox("colour colliding splats (s2~ < 1) red", True)

        @cb.on_update
        def _(_) -> None:
            st.colour_by_metric = bool(cb.value)
            self._update_pose()

        ce = gui.add_checkbox("show collision ellipsoids", True)

        @ce.on_update
        def _(_) -> None:
            for h in self._ell_handles:
                h.visible = bool(ce.value)

        if self.kind == "joints":
            with gui.add_folder("joints"):
                self._sliders = []
                lim = np.asarray(self.robot.joint_limits, dtype=np.float64)
                for j, name in enumerate(self.robot.joint_names):
                    lo, hi = (float(v) for v in lim[j])
                    s = gui.add_slider(name, min=lo, max=hi, step=(hi - lo) / 200.0, initial_value=float(np.clip(st.q[j], lo, hi)))

                    def on(_, j=j, s=s) -> None:
                        if self._syncing:
                            return
                        q = self.state.q.copy()
                        q[j] = float(s.value)
                        self.set_q(q)

                    s.on_update(on)
                    self._sliders.append(s)
        anim = self.trajectory if self.trajectory is not None else self.plan
        if anim is not None:
            t = gui.add_slider("time step (plan / MPC)", min=0, max=len(anim) - 1, step=1, initial_value=0)

            @t.on_update
            def _(_) -> None:
                self.set_q(anim[int(t.value)])

        with gui.add_folder("collision field slice"):
            show = gui.add_checkbox("show the metric on a plane", self.kind == "point")

            @show.on_update
            def _(_) -> None:
                st.show_field = bool(show.value)
                self._update_field()

            z = gui.add_slider("plane z", min=float(self.lo[2]), max=float(self.hi[2]), step=float(self.hi[2] - self.lo[2]) / 100.0,
                               initial_value=float(st.field_z))  # fmt: skip

            @z.on_update
            def _(_) -> None:
                st.field_z = float(z.value)
                self._update_field()

        if self.kind in ("point", "planar"):
            with gui.add_folder("plan (RRT)"):
                gui.add_markdown("Drag the green goal gizmo; the robot gizmo is the start.")
                g0 = self.plan[-1] if self.plan is not None else self.state.q.copy()
                self._goal = self._server().scene.add_transform_controls("/plans/goal", scale=0.1 * self.extent, position=self._q_to_position(g0),
                                                                      disable_rotations=True)  # fmt: skip
                btn = gui.add_button("plan from robot to goal")
                self._plan_md = gui.add_markdown("")

                @btn.on_click
                def _(_) -> None:
                    self.replan_async()

    # ------------------------------------------------------------------ updates
    def set_q(self, q) -> None:
        self.state.q = np.asarray(q, dtype=np.float64).copy()
        if self.server is not None and self.kind == "joints" and getattr(self, "_sliders", None):
            self._syncing = True
            try:
                for s, v in zip(self._sliders, self.state.q):
                    if abs(float(s.value) - float(v)) > 1e-9:
                        s.value = float(np.clip(v, s.min, s.max))  # type: ignore[misc]  # viser types the slider's value read-only; it has a setter
            finally:
                self._syncing = False
        self._update_pose()

    def _update_pose(self) -> dict:
        if self.server is None:
            return {}
        st = self.state
        t0 = time.perf_counter()
        c, quat, ax = self.robot.ellipsoids(st.q)  # once per update: state, handles and colouring share it
        info = self._collision_state(c, quat, ax)
        colour = (255, 60, 60) if info["collides"] else (90, 200, 255)
        for e, h in enumerate(self._ell_handles):
            h.position = _vec3(c[e])
            h.wxyz = _wxyz(quat[e])
            h.color = colour
        if self._urdf is not None:
            self._set_urdf(st.q)
        if st.colour_by_metric:
            d = self._splat_distances(c, quat, ax)
            hit = np.flatnonzero(d < 1.0)
            self._hits.points = self.scene.means[hit] if len(hit) else np.zeros((1, 3), np.float32)
            self._hits.colors = np.tile(np.array([[255, 0, 0]], np.uint8), (max(1, len(hit)), 1))
            self._hits.visible = bool(len(hit))
        else:
            self._hits.visible = False
        lines = [f"**Robot** `{self.robot.name}` ({self.kind}), n_sigma = {st.n_sigma:g}: "
                 + ("**IN COLLISION**" if info["collides"] else "collision-free")
                 + f" (min s2~ = {info['min_s2']:.3g})"]  # fmt: skip
        hits = {k: v for k, v in info["per_link"].items() if v}
        if hits:
            lines.append("colliding splats per link: " + ", ".join(f"{k}: {v}" for k, v in hits.items()))
        ms = 1e3 * (time.perf_counter() - t0)
        lines.append(f"update: {ms:.1f} ms (metric {info['ms']:.1f} ms)")
        self._md.content = "\n\n".join(lines)
        st.timings["pose_update_ms"].append(ms)
        self._log("pose", q=[float(v) for v in st.q], collides=info["collides"], per_link=info["per_link"], ms=ms, n_sigma=st.n_sigma)
        return info

    def _set_urdf(self, q) -> None:
        assert self._urdf is not None  # (called when the URDF meshes loaded)
        names = list(self._urdf.get_actuated_joint_names())
        ours = {} if self.kind == "planar" else {n: float(v) for n, v in zip(self.robot.joint_names, q)}
        cfg = np.array([ours.get(n, float(np.ravel(self._urdf_fixed.get(n, 0.0))[0])) for n in names])  # SRDF values are lists
        self._urdf.update_cfg(cfg)
        base = np.asarray(self.robot.base_pose, dtype=np.float64)
        if self.kind == "planar":  # world <- base = base_pose * (x, y, yaw)
            pose = np.eye(4)
            c, s = np.cos(q[2]), np.sin(q[2])
            pose[:2, :2] = [[c, -s], [s, c]]
            pose[:2, 3] = q[:2]
            base = base @ pose
        from ..scenes.splats import rotmat_to_quat

        self._urdf_frame.position = _vec3(base[:3, 3])
        self._urdf_frame.wxyz = _wxyz(rotmat_to_quat(base[:3, :3]))

    def _update_field(self) -> None:
        srv = self.server  # one reference: stop() may clear self.server while this callback runs
        if srv is None:
            return
        st = self.state
        if not st.show_field:
            if getattr(self, "_field", None) is not None:
                self._field.visible = False
            return
        res = int(self.config.field_res)
        r = float(np.min(self.robot.semi_axes))  # a probe sphere as small as the robot's smallest semi-axis
        xs = np.linspace(self.lo[0], self.hi[0], res)
        ys = np.linspace(self.lo[1], self.hi[1], res)
        gx, gy = np.meshgrid(xs, ys)  # [iy, ix]
        pts = np.stack([gx, gy, np.full_like(gx, st.field_z)], axis=-1)
        field = self.checker.with_config(n_sigma=st.n_sigma).query(pts, None, r).min_s2  # (res, res)
        img = colormap(np.minimum(field, 4.0), 0.0, 4.0)
        img[field < 1.0] = (img[field < 1.0] * 0.4).astype(np.uint8)  # darker inside the collision boundary
        if self.server is None:
            return  # stopped during the query: nothing to draw on (srv still guards a stop right after this check)
        self._field = srv.scene.add_image(
            "/metric/field", img[::-1].copy(),  # row 0 of the image is drawn at +y
            render_width=float(self.hi[0] - self.lo[0]), render_height=float(self.hi[1] - self.lo[1]),
            position=(float(xs.mean()), float(ys.mean()), float(st.field_z)),
        )

    def replan_async(self) -> threading.Thread:
        """Plan with RRT from the robot's pose to the goal gizmo in a worker thread (GUI stays responsive)."""
        if self._plan_thread is not None and self._plan_thread.is_alive():
            return self._plan_thread
        start = self.state.q.copy()
        goal = start.copy()
        gp = np.asarray(self._goal.position, dtype=np.float64)
        if self.kind == "point":
            goal[:3] = gp
        else:
            goal[:2] = gp[:2]
        n_sigma = self.state.n_sigma
        srv = self.server  # one reference: stop() may clear self.server while the worker runs

        def work() -> None:
            from ..planners import plan

            self._plan_md.content = "planning ..."
            t0 = time.perf_counter()
            try:
                res = plan(self.checker.with_config(n_sigma=n_sigma), start, goal, robot=self.robot)
            except SplatplanError as exc:
                self._plan_md.content = f"cannot plan: {exc}"
                self._log("plan", success=False, message=str(exc))
                return
            dt = time.perf_counter() - t0
            if res.success:
                path = np.asarray(res.path, dtype=np.float64)
                assert srv is not None  # (the GUI that asks for a plan runs on it)
                srv.scene.add_line_segments("/plans/replanned", polyline_segments(self._trace(path)), (255, 0, 200),
                                            thickness=0.005 * self.extent)  # fmt: skip
                self._plan_md.content = f"path found: length {res.length:.3f}, {dt:.2f} s (n_sigma {n_sigma:g})"
            else:
                self._plan_md.content = f"no path found ({res.message}), {dt:.2f} s"
            self._log("plan", success=bool(res.success), seconds=dt, n_sigma=n_sigma)

        self._plan_thread = threading.Thread(target=work, daemon=True, name="splatplan-viewer-rrt")
        self._plan_thread.start()
        return self._plan_thread
