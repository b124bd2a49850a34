"""Batched RRT (paper Sec. II-E) on the CollisionSplatting checker, in a robot's configuration space.

Each iteration draws ``batch_size`` samples (goal-biased), finds the nearest tree node of every
sample (one vectorised distance matrix), steers from it by at most ``stride``, discretises every
new edge (see *Edge resolution*) and checks all edges together over every robot ellipsoid: a few
batched collision calls, coarse to fine, an edge's checks stopping at its first hit
(``edge_stages``, :class:`EdgeChecker`). Collision-free edges become new nodes.

* **Goal mode** (``goal`` given): new nodes within ``connect_radius`` of the goal try a direct,
  collision-checked edge to the goal (one batched call); the first iteration with a free one ends
  the search and the goal itself becomes the path's last vertex. The path can then be shortcut
  greedily (batched edge checks).
* **Exploration mode** (``goal=None``): grows the tree until the node / iteration / time budget
  and returns it (nodes + parents), e.g. for image-goal retrieval (E6).

**Configuration space.** The robot is a :class:`~splatplan.robots.Robot`: joint space for an arm
(sampled within the joint limits), (x, y, yaw) for a planar base (x, y within the scene's robust
bounds, yaw in [-pi, pi]), R^3 for a sphere or ellipsoid point robot. Distances (stride, goal
tolerance, connect radius) are the weighted Euclidean norm ``|motion_bound * dq|_2`` in scene units
(plain Euclidean distance for a point robot; see :mod:`splatplan.planners.robot_links`).

**Edge resolution (the guarantee).** An edge a -> b is checked at the configurations
``q_k = a + (k / n)(b - a)``, k = 1..n (q_0 = a is already a checked tree node), with
``n = ceil(M(b - a) / edge_resolution)`` and ``M(dq) = sum_j motion_bound_j |dq_j|`` (``|dq|`` for
a translating point robot), which bounds the displacement of every point of every ellipsoid
along the segment. Hence **no point of any robot ellipsoid moves more than ``edge_resolution``
between two consecutive checked configurations**; the default ``edge_resolution`` is
``edge_fraction`` (1/4) of the robot's smallest semi-axis. For a single translating sphere the
inner samples are additionally checked with the radius grown by half the sample spacing (<= r/8
by default): every point of the swept volume lies within that distance of a sample centre, so at
n_sigma = 0 the edge is free between the samples too, not only at them. (Growing every semi-axis
of an anisotropic ellipsoid by m does not contain its Minkowski sum with a ball of radius m, so
this extra test is used for spheres only.)

**Scene-scaled defaults.** Lengths the user leaves unset are derived from the scene and the robot
(:meth:`RRT.settings`): the sampling box is the 0.5-99.5 percentile box of the splat means padded
by the robot's largest semi-axis (joint limits for joints; [-pi, pi] for an unlimited yaw), the
stride 1/32 of the largest side of that box in the weighted metric (``(hi - lo) * motion_bound``),
the goal tolerance half the smallest semi-axis, and the search runs until
``time_limit_s`` (default 10 s) rather than a node count. The chosen values are returned in
``PlanResult.info["settings"]``; :meth:`RRTSettings.summary` prints them on one line.

The tree lives in numpy arrays on the CPU, grown in place (doubled when full). That is deliberate:
nearest-neighbour search over it is a (32 x n) distance matrix, and the expensive part (collision
checks) runs on the checker's own device.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.distance import cdist

from .._config import bounded, check_config
from .._resources import require_bytes
from ..errors import PlanningError, SplatplanError
from .robot_links import EDGE_FRACTION, LinkGeometry, as_robot

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot

#: percentile of the splat means that bounds the default sampling box on each side (robust to outliers)
BOX_PERCENTILE = 0.5
#: the default stride is this fraction of the largest side of the sampling box
STRIDE_FRACTION = 1.0 / 32.0


@dataclass
class RRTConfig:
    """Knobs of the batched RRT. Lengths are in scene units of robot motion (the weighted
    configuration distance |motion_bound * dq|; plain distance for a point robot). Every None is
    derived from the scene and the robot (see the module docstring)."""

    #: samples drawn (and edges checked) per iteration; the paper grows 32 nodes at a time
    batch_size: int = bounded(32, ge=1)
    #: maximum edge length: a sample farther than this from its nearest node is pulled back to it;
    #: None = 1/32 of the largest side of the sampling box
    stride: float | None = bounded(None, gt=0)
    #: largest displacement of any robot ellipsoid point between two consecutive collision checks
    #: along an edge (scene units); None = edge_fraction * the robot's smallest semi-axis
    edge_resolution: float | None = bounded(None, gt=0)
    #: default edge_resolution as a fraction of the robot's smallest semi-axis
    edge_fraction: float = bounded(EDGE_FRACTION, gt=0, le=1)
    #: probability that a sample is the goal itself (RRT, goal mode only)
    goal_bias: float = bounded(0.1, ge=0, le=1)
    #: RRT: a node closer than this to the goal ends the search even if the last edge to the goal is not
    #: free (the path then ends at that node); None = half the robot's smallest semi-axis; 0 = exact
    goal_tolerance: float | None = bounded(None, ge=0)
    #: RRT: new nodes within this distance of the goal try a direct collision-checked edge to it;
    #: None = 4 * stride
    connect_radius: float | None = bounded(None, gt=0)
    #: iteration budget (None = unlimited: the time limit decides)
    max_iters: int | None = bounded(None, ge=1)
    #: node budget (None = unlimited: the time limit decides)
    max_nodes: int | None = bounded(None, ge=2)
    #: wall-clock budget in seconds (None = unlimited); through plan() / the CLI it bounds the whole
    #: call: search, shortcut and refinement
    time_limit_s: float | None = bounded(10.0, gt=0)
    #: seed of the sampler
    seed: int = bounded(0, ge=0)
    #: sampling box lower corner (D,); None = derived (robust scene bounds / joint limits).
    #: A side with lo == hi freezes that coordinate (e.g. planar planning at a fixed z)
    box_lo: tuple[float, ...] | None = None
    #: sampling box upper corner (D,); see box_lo
    box_hi: tuple[float, ...] | None = None
    #: configuration coordinates held at the start's value (planar planning with a derived box,
    #: e.g. (2,) keeps z of a point robot fixed); the goal must have the same values there
    frozen: tuple[int, ...] | None = bounded(None, ge=0)
    #: greedily shortcut the found path (batched edge checks at edge_resolution)
    shortcut: bool = True
    #: RRT-Connect: new nodes per iteration (those closest to the other tree) that the other tree
    #: tries to connect to
    connect_attempts: int = bounded(4, ge=1)
    #: RRT-Connect: longest connect run per attempt, in strides (None = all the way to the target)
    connect_strides: float | None = bounded(4.0, gt=0)
    #: batched calls per edge check, coarse to fine (samples at every 4^(s-1)-th, ..., 4th, every
    #: index); checks stop at an edge's first hit; 1 = every sample in one call (same answers)
    edge_stages: int = bounded(4, ge=1, le=8)
    #: skip edge check samples that a checked neighbour proves free (the checker's free slack: a
    #: configuration far from every splat stays free while no ellipsoid centre moves more than its
    #: distance to the splats minus the link's reach); the same answers with fewer checks
    edge_slack: bool = True
    #: RRT-Connect: lazy search: check only the new nodes while the trees grow and the edges of a
    #: candidate path once the trees meet (removing what collides); the returned path is checked at
    #: edge_resolution either way. False: every edge checked when it is grown (the eager search)
    lazy: bool = True
    #: shortcut: screen each vertex's candidate edges at every this-many-th check sample first and
    #: check the survivors whole, farthest first (the same path, fewer checks); None: check every
    #: candidate whole
    shortcut_screen: int | None = bounded(16, ge=1)

    def validate(self) -> "RRTConfig":
        check_config(self)  # each field's declared range (splatplan._config); cross-field rules below
        if self.batch_size < 1:
            raise SplatplanError(f"RRTConfig.batch_size must be >= 1, got {self.batch_size}")
        for name in ("stride", "edge_resolution", "connect_radius", "time_limit_s"):
            v = getattr(self, name)
            if v is not None and not (v > 0 and math.isfinite(v)):
                raise SplatplanError(f"RRTConfig.{name} must be finite and > 0, got {v}")
        if self.connect_attempts < 1:
            raise SplatplanError(f"RRTConfig.connect_attempts must be >= 1, got {self.connect_attempts}")
        if self.connect_strides is not None and not (self.connect_strides >= 1 and math.isfinite(self.connect_strides)):
            raise SplatplanError(f"RRTConfig.connect_strides must be finite and >= 1 (or None), got {self.connect_strides}")
        if not 0.0 < self.edge_fraction <= 1.0:
            raise SplatplanError(f"RRTConfig.edge_fraction must lie in (0, 1], got {self.edge_fraction}")
        if not 0.0 <= self.goal_bias <= 1.0:
            raise SplatplanError(f"RRTConfig.goal_bias must lie in [0, 1], got {self.goal_bias}")
        if self.goal_tolerance is not None and not self.goal_tolerance >= 0:
            raise SplatplanError(f"RRTConfig.goal_tolerance must be >= 0, got {self.goal_tolerance}")
        if (self.max_nodes is not None and self.max_nodes < 2) or (self.max_iters is not None and self.max_iters < 1):
            raise SplatplanError("RRTConfig.max_nodes must be >= 2 and max_iters >= 1")
        return self


@dataclass
class RRTSettings:
    """The values one RRT search actually used (user-given or derived).

    Attributes:
        box_lo, box_hi: (D,) sampling box.
        stride, edge_resolution, goal_tolerance, connect_radius: lengths (scene units of motion).
        time_limit_s: wall-clock budget (None = unlimited).
        derived: names of the values derived from the scene / robot (not set by the user).
        notes: remarks (e.g. the box was widened to include the start).
    """

    box_lo: np.ndarray
    box_hi: np.ndarray
    stride: float
    edge_resolution: float
    goal_tolerance: float
    connect_radius: float
    time_limit_s: float | None
    derived: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def summary(self) -> str:
        """One line: every value, derived ones marked with '*'."""

        def tag(name: str) -> str:
            return "*" if name in self.derived else ""

        box = "[" + ", ".join(f"{a:.3g}..{b:.3g}" for a, b in zip(self.box_lo, self.box_hi)) + "]"
        tl = "unlimited" if self.time_limit_s is None else f"{self.time_limit_s:g} s"
        line = (
            f"stride{tag('stride')} {self.stride:.4g}, edge resolution{tag('edge_resolution')} {self.edge_resolution:.4g}, "
            f"goal tolerance{tag('goal_tolerance')} {self.goal_tolerance:.4g}, box{tag('box')} {box}, "
            f"time limit{tag('time_limit_s')} {tl}"
        )
        if self.derived:
            line += " (* = derived from the scene and robot)"
        return line

    def as_dict(self) -> dict:
        return {
            "box_lo": self.box_lo.tolist(), "box_hi": self.box_hi.tolist(), "stride": self.stride,
            "edge_resolution": self.edge_resolution, "goal_tolerance": self.goal_tolerance,
            "connect_radius": self.connect_radius, "time_limit_s": self.time_limit_s,
            "derived": list(self.derived), "notes": list(self.notes),
        }  # fmt: skip


@dataclass
class PlanResult:
    """Outcome of a planning call.

    Attributes:
        success: goal mode: a path was found; exploration mode: the tree was grown (always True).
        path: (P, D) path vertices from start to goal (empty (0, D) when none was found or in
            exploration mode); after refinement a densely sampled smooth curve.
        length: length of ``path`` in the planner's metric (|motion_bound * dq| summed over the
            segments; plain Euclidean length for a point robot); inf when no path.
        time_s: wall-clock seconds of the whole call (search + shortcut + refinement).
        n_nodes: nodes in the tree (root included).
        n_iters: RRT iterations run.
        tree_nodes: (n_nodes, D) tree node configurations.
        tree_parents: (n_nodes,) int64 parent index of each node, -1 for the root.
        message: why it stopped, in words.
        path_rrt: (P0, D) the search's path before the final shortcut / refinement (goal mode; the
            raw tree path, except for the lazy RRT-Connect, whose path is shortcut once while it is
            checked: the tree edges a shortcut jumps over are never checked).
        refined: whether ``path`` is the accepted output of the zeroth-order refinement.
        info: extras: ``settings`` (the :class:`RRTSettings` as a dict), ``n_queries``,
            ``edge_resolution``, ``time_limit_hit``.
    """

    success: bool
    path: np.ndarray
    length: float
    time_s: float
    n_nodes: int
    n_iters: int
    tree_nodes: np.ndarray
    tree_parents: np.ndarray
    message: str = ""
    path_rrt: np.ndarray | None = None
    refined: bool = False
    info: dict = field(default_factory=dict)


def path_length(path: np.ndarray, weights: np.ndarray | None = None) -> float:
    """Sum of segment lengths of a polyline (P, D) (coordinates scaled by ``weights`` (D,) first);
    0 for P < 2."""
    p = np.asarray(path, dtype=np.float64)
    if weights is not None:
        p = p * np.asarray(weights, dtype=np.float64)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0


def edge_points(a: np.ndarray, b: np.ndarray, resolution: float, include_start: bool = False) -> np.ndarray:
    """Points along E straight edges a[e] -> b[e], spaced at most ``resolution`` apart (Euclidean).

    Every edge gets the same number of points ``n = ceil(max_len / resolution)`` (shorter edges are
    sampled more densely), at parameters ``k / n`` for k = 1..n (k = 0..n with include_start), so
    the edge's end point is always included.

    Args:
        a: (E, D) edge starts.
        b: (E, D) edge ends.
        resolution: maximum spacing (configuration units).

    Returns:
        (E, n_pts, D) points.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    lmax = float(np.linalg.norm(b - a, axis=-1).max()) if len(a) else 0.0
    n = max(1, int(math.ceil(lmax / resolution - 1e-9)))
    t = np.arange(0 if include_start else 1, n + 1) / n  # (n_pts,)
    return a[:, None, :] + t[None, :, None] * (b - a)[:, None, :]


def edge_samples(a: np.ndarray, b: np.ndarray, motion: np.ndarray, resolution: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check configurations of E edges, each edge with its own count (see the module docstring).

    Args:
        a: (E, D) edge starts; b: (E, D) edge ends.
        motion: (E,) bound on any ellipsoid point's displacement along each edge (scene units).
        resolution: largest displacement allowed between consecutive checks.

    Returns:
        points (P, D) = a_e + (k / n_e)(b_e - a_e) for k = 1..n_e, edge index (P,), n (E,) with
        ``n_e = max(1, ceil(motion_e / resolution))``.
    """
    n_float = np.maximum(1.0, np.ceil(np.asarray(motion, dtype=np.float64) / resolution - 1e-9))  # (E,)
    # resource guard: a huge edge (a goal 1e30 away) or a tiny resolution would ask for more points than memory holds
    require_bytes(float(n_float.sum()) * (a.shape[-1] + 2) * 8 * 4, f"{float(n_float.sum()):.3g} collision checks along {len(a)} edge(s)",
                  "the edge length (or coarsen the edge resolution)")
    n = n_float.astype(np.int64)
    idx = np.repeat(np.arange(len(a)), n)  # (P,)
    first = np.cumsum(n) - n  # (E,)
    k = np.arange(idx.size) - first[idx] + 1  # 1..n_e
    t = k / n[idx]
    return a[idx] + t[:, None] * (b - a)[idx], idx, n


class EdgeChecker:
    """Batched straight-edge collision checks of a robot against a checker.

    **Coarse to fine (``stages`` > 1).** The check samples of all edges are checked in ``stages``
    batched calls, from coarse to fine: call j takes the samples whose index along their edge is a
    multiple of ``4^(stages - 1 - j)`` (the first call also each edge's end point), and only those
    still needed: samples before the first hit found so far on edges whose free prefix is asked
    for (:meth:`free_prefix`), nothing more on an edge that only has to be free or not
    (:meth:`edges_free`, or ``exact=False``) once a hit is found. The last call has stride 1, so
    every sample before an edge's first hit is checked: the answers are exactly those of checking
    every sample in one call (``stages=1``, the reference; ``tests/planners/test_edge_stages.py``),
    with fewer checks where edges collide (an RRT's extension edges often do, and every sample
    after the first hit was checked for nothing) at the cost of more, smaller calls.

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker`.
        geometry: the robot's :class:`~splatplan.planners.robot_links.LinkGeometry`.
        resolution: largest displacement of any ellipsoid point between consecutive checks.
        inflate: check inner samples with the semi-axes grown by half the sample spacing (valid
            for translating spheres only; see the module docstring).
        stages: batched calls per check, coarse to fine (1 = every sample in one call).
        slack: skip samples proven free (below; robots on a Warp checker; not with ``inflate``).

    **Free slack (``slack``).** With the checker's mean-distance grid, an ellipsoid far from every
    splat mean comes back with a slack: its centre may move that far, its orientation anyhow, with
    it staying free (:meth:`CollisionChecker.collides_robot`). At a checked free configuration,
    each ellipsoid's slack divided by the bound on its displacement from one sample to the next
    (its own motion bound, :meth:`Robot.ellipsoid_motion_bounds`, over the edge, divided by n)
    is how many samples on either side it stays free (all of them for an ellipsoid that the
    edge does not move, such as a fixed base); the smallest over the ellipsoids is how many
    samples are free as well: they are not checked. The answers are those of checking them (the
    checker would call each of them free), with fewer checks in free space.
    """

    #: stride ratio between consecutive stages of the coarse-to-fine check
    STAGE_FACTOR = 4

    def __init__(self, checker: CollisionChecker, geometry: LinkGeometry, resolution: float, inflate: bool = False, stages: int = 1, slack: bool = False) -> None:
        self.checker = checker
        self.geometry = geometry
        self.resolution = float(resolution)
        self.inflate = bool(inflate)
        if int(stages) < 1:
            raise SplatplanError(f"EdgeChecker stages must be >= 1, got {stages}")
        self.stages = int(stages)
        #: skip check samples that a checked one proves free (FREE SLACK of the checker: the same
        #: answers, fewer checks); robots checked with ``collides_robot`` only
        self.use_slack = bool(slack)
        #: wall-clock seconds spent in collision checks (statistics)
        self.time_s = 0.0

    @property
    def n_queries(self) -> int:
        """Ellipsoid checks issued so far."""
        return self.geometry.n_queries

    @property
    def n_configs(self) -> int:
        """Configurations checked so far."""
        return self.geometry.n_configs

    def configs_collide(self, configs: np.ndarray, margin: float | np.ndarray = 0.0) -> np.ndarray:
        """(..., D) -> bool (...): any link in collision (semi-axes grown by ``margin``)."""
        return self.geometry.collides(self.checker, configs, margin)

    def edges_free(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """(E, D), (E, D) -> bool (E,): True where the whole edge (end point included, start
        excluded) is collision-free at ``resolution``. An edge's checks stop at its first hit found."""
        k, n = self.free_prefix(a, b, exact=np.zeros(len(a), dtype=bool))
        return k == n

    def free_prefix(self, a: np.ndarray, b: np.ndarray, exact: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """How far along each of E edges the check samples stay free (``stages`` batched calls).

        Args:
            a: (E, D) edge starts (assumed checked already); b: (E, D) edge ends.
            exact: (E,) bool, the edges whose free prefix is needed (default: all); for the others
                only whether they are free (k == n) is, and their checks stop at the first hit.

        Returns:
            k (E,) int64: the number of leading free check samples of each edge (samples
            ``a + (i / n)(b - a)``, i = 1..k, are free; k == n: the whole edge is free); where
            ``exact`` is False and the edge collides, some k < n (a hit at sample k + 1);
            n (E,) int64: the edge's sample count (see :func:`edge_samples`).
        """
        a = np.asarray(a, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        if len(a) == 0:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        t0 = time.perf_counter()
        pts, idx, n = edge_samples(a, b, self.geometry.motion(b - a), self.resolution)  # (P, D)
        first = np.cumsum(n) - n  # (E,) offset of each edge's first sample
        loc = np.arange(idx.size) - first[idx] + 1  # (P,) 1..n_e: the sample's index along its edge
        margin = None
        if self.inflate:
            spacing = np.linalg.norm(b - a, axis=-1) / n  # (E,)
            margin = 0.5 * spacing[idx]
            margin[loc == n[idx]] = 0.0  # the end point with the true size
        exact = np.ones(len(a), dtype=bool) if exact is None else np.asarray(exact, dtype=bool).reshape(len(a))
        hit_at = n + 1  # (E,) 1-based index of the first hit found so far (n + 1: none)
        todo = np.ones(idx.size, dtype=bool)  # (P,) samples not checked (nor proven free) yet
        use_slack = self.use_slack and margin is None
        if use_slack:  # bound on each ellipsoid's displacement from one sample to the next, per edge
            step = self.geometry.ellipsoid_motion(b - a) / n[:, None]  # (E_edges, E)
            last = (first + n - 1)[idx]  # (P,) global index of the edge's last sample
        for j in range(self.stages):
            stride = self.STAGE_FACTOR ** (self.stages - 1 - j)
            sel = todo & (loc < hit_at[idx]) & (exact | (hit_at > n))[idx]
            if stride > 1:
                sel &= (loc % stride == 0) | (loc == n[idx]) if j == 0 else (loc % stride == 0)
            s = np.nonzero(sel)[0]
            if s.size == 0:
                continue
            if use_slack:
                hit, slack = self.geometry.collides_slack(self.checker, pts[s])  # (S,), (S, E)
                _prove_free(todo, s, hit, slack, step[idx[s]], first[idx[s]], last[s])
            else:
                hit = self.configs_collide(pts[s]) if margin is None else self.configs_collide(pts[s], margin[s])  # (S,)
            todo[s] = False
            h = s[hit]
            np.minimum.at(hit_at, idx[h], loc[h])
        self.time_s += time.perf_counter() - t0
        return np.minimum(hit_at - 1, n), n

    def screen(self, a: np.ndarray, b: np.ndarray, every: int) -> np.ndarray:
        """(E, D), (E, D) -> bool (E,): no hit among every ``every``-th check sample of each edge
        (samples k = every, 2 every, ... < n of :meth:`free_prefix`'s grid; the end point is not
        checked). A subset of the edge's own samples: an edge that :meth:`edges_free` calls free
        always passes, so screening first changes no answer, only how many checks an edge that
        collides costs. One batched call."""
        a = np.asarray(a, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        ok = np.ones(len(a), dtype=bool)
        if len(a) == 0:
            return ok
        t0 = time.perf_counter()
        n = np.maximum(1.0, np.ceil(self.geometry.motion(b - a) / self.resolution - 1e-9)).astype(np.int64)  # (E,) as edge_samples
        m = np.maximum((n - 1) // int(every), 0)  # (E,) screened samples per edge
        if m.sum() > 0:
            require_bytes(float(m.sum()) * (a.shape[-1] + 2) * 8 * 4, f"{int(m.sum()):,} screening checks along {len(a)} edge(s)", "the edge length")
            idx = np.repeat(np.arange(len(a)), m)  # (S,)
            k = (np.arange(idx.size) - (np.cumsum(m) - m)[idx] + 1) * int(every)  # (S,) sample index along its edge
            pts = a[idx] + (k / n[idx])[:, None] * (b - a)[idx]
            hit = self.configs_collide(pts)
            ok[np.unique(idx[hit])] = False
        self.time_s += time.perf_counter() - t0
        return ok

    def path_free(self, path: np.ndarray) -> bool:
        """Whether every point of a polyline (P, D), sampled at ``resolution``, is collision-free."""
        p = np.asarray(path, dtype=np.float64)
        if len(p) == 1:
            return not bool(self.configs_collide(p).any())
        return bool(self.edges_free(p[:-1], p[1:]).all()) and not bool(self.configs_collide(p[:1]).any())


def _prove_free(todo: np.ndarray, s: np.ndarray, hit: np.ndarray, slack: np.ndarray, step: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
    """Clear ``todo`` (P,) for the samples proven free by the checked samples ``s`` (S,).

    Sample s, free (``hit`` False), with each ellipsoid's FREE SLACK ``slack`` (S, E) (the
    ellipsoid is free wherever its centre lies within it of its centre at s) and ``step`` (S, E)
    bounding each ellipsoid's displacement from one sample of the edge to the next, proves free
    the samples of its edge (global indices ``lo``..``hi``) within ``min_e floor(slack_e / step_e)``
    of it; an ellipsoid that does not move along the edge (step 0) is free at all of them."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ke = np.where(step > 0, np.floor(slack / np.where(step > 0, step, 1.0)), np.inf)  # (S, E)
    k = np.where(hit, 0.0, ke.min(axis=1) if ke.shape[1] else np.inf)
    k = np.minimum(k, float(len(todo)))
    ok = k >= 1
    if not ok.any():
        return
    s, k, lo, hi = s[ok], k[ok].astype(np.int64), lo[ok], hi[ok]
    diff = np.zeros(len(todo) + 1, dtype=np.int64)
    np.add.at(diff, np.maximum(s - k, lo), 1)
    np.add.at(diff, np.minimum(s + k, hi) + 1, -1)
    todo &= np.cumsum(diff[:-1]) == 0


def check_endpoint(checker: CollisionChecker, geometry: LinkGeometry, x: np.ndarray, what: str) -> None:
    """Raise :class:`PlanningError` when configuration ``x`` (D,) is in collision."""
    if not bool(geometry.collides(checker, np.asarray(x, dtype=np.float64)[None])[0]):
        return  # (the cheap collision-only check; the full query only to describe a collision)
    why = geometry.describe_collision(checker, x)
    if why is not None:
        raise PlanningError(
            f"the {what} {np.array2string(np.asarray(x), precision=4)} is in collision: {why}; "
            f"move the {what}, shrink the robot or lower n_sigma"
        )


def shortcut_path(edges: EdgeChecker, path: np.ndarray, deadline: float | None = None, candidates: str = "all", screen: int | None = None) -> np.ndarray:
    """Greedy shortcutting: from each kept vertex jump to the farthest vertex reachable by a free
    straight edge (all candidate edges of a vertex checked in one batched call).

    ``candidates``: "all" tries every later vertex; "doubling" tries the vertices i + 2, i + 3,
    i + 5, i + 9, ... (offsets 1 + 2^m) and the last one, O(log P) edges per vertex instead of
    O(P): for long paths of many short edges (RRT-Connect's connect runs), where checking every
    long candidate edge costs more than the search.

    ``screen``: first check every ``screen``-th sample of all candidate edges of a vertex in one
    call (:meth:`EdgeChecker.screen`), then check the survivors whole, farthest first, until one
    is free. The same path as without it (the farthest free candidate passes the screen, and the
    ones beyond it fail), with fewer checks: the long free candidates short of the farthest are not
    checked whole.

    The result is collision-free at the checker's resolution whenever the input was (its vertices
    are input vertices, its edges checked ones), never longer than the input, and keeps both
    endpoints. Past ``deadline`` (a ``time.perf_counter()`` value) the rest of the path is kept
    as it is.
    """
    p = np.asarray(path, dtype=np.float64)
    if len(p) <= 2:
        return p.copy()
    if candidates not in ("all", "doubling"):
        raise SplatplanError(f"shortcut candidates must be 'all' or 'doubling', got {candidates!r}")
    if screen is not None and int(screen) < 1:
        raise SplatplanError(f"shortcut screen must be >= 1 (or None), got {screen}")
    out = [p[0]]
    i = 0
    while i < len(p) - 1:
        if deadline is not None and time.perf_counter() > deadline:
            out.extend(p[i + 1 :])
            break
        if candidates == "all":
            cand = np.arange(i + 2, len(p))
        else:
            off = 1 + 2 ** np.arange(int(math.log2(max(1, len(p) - 1 - i))) + 1)  # 2, 3, 5, 9, ...
            cand = np.unique(np.append(i + off[i + off < len(p) - 1], len(p) - 1))
            cand = cand[cand >= i + 2]
        j = i + 1
        if cand.size and screen is not None:
            cand = cand[::-1]  # farthest first
            ok = edges.screen(np.repeat(p[i : i + 1], cand.size, axis=0), p[cand], int(screen))
            for c in cand[ok].tolist():
                if edges.edges_free(p[i : i + 1], p[c : c + 1])[0]:
                    j = c
                    break
        elif cand.size:
            free = edges.edges_free(np.repeat(p[i : i + 1], cand.size, axis=0), p[cand])
            if free.any():
                j = int(cand[np.nonzero(free)[0].max()])
        out.append(p[j])
        i = j
    return np.asarray(out)


def robust_scene_box(scene, percentile: float = BOX_PERCENTILE) -> tuple[np.ndarray, np.ndarray]:
    """(lo (3,), hi (3,)): the [p, 100 - p] percentile box of the splat means (world frame, scene
    units); robust to outlier splats far outside the captured room."""
    m = np.asarray(scene.means)
    lo, hi = np.percentile(m, [percentile, 100.0 - percentile], axis=0)
    return lo.astype(np.float64), hi.astype(np.float64)


@dataclass
class Search:
    """What one search (:meth:`RRT.plan`, :meth:`RRTConnect.plan`) sets up before its first iteration."""

    t0: float  # time.perf_counter() when the call began
    st: RRTSettings
    start: np.ndarray  # (D,)
    goal: np.ndarray | None  # (D,) or None (exploration)
    w: np.ndarray  # (D,) configuration -> metric space (motion bound per coordinate)
    edges: EdgeChecker
    q0: int  # the geometry's query count when the search began
    rng: np.random.Generator
    frozen: np.ndarray  # (D,) bool: coordinates held fixed (lo == hi)
    span: np.ndarray  # (D,) hi - lo (0 where frozen)
    end: float  # time.perf_counter() value the search stops at (inf: none)
    deadline: float | None  # the caller's deadline
    c0: int = 0  # the geometry's configuration count when the search began

    def sample(self, n: int) -> np.ndarray:
        """(n, D) uniform samples of the sampling box."""
        return self.st.box_lo + self.rng.random((n, self.start.size)) * self.span

    def stop(self, config: RRTConfig, it: int, n_nodes: int, info: dict) -> str | None:
        """Why the search stops before iteration ``it + 1`` (None: it goes on); a time-out sets
        ``info["time_limit_hit"]``."""
        if config.max_iters is not None and it >= config.max_iters:
            return f"within the iteration budget ({config.max_iters:,} iterations, {n_nodes:,} nodes)"
        if config.max_nodes is not None and n_nodes >= config.max_nodes:
            return f"within the node budget ({config.max_nodes:,} nodes)"
        if time.perf_counter() > self.end:
            limit = self.st.time_limit_s if self.st.time_limit_s is not None else self.deadline - self.t0  # the budget the user gave
            info["time_limit_hit"] = True
            return f"within {limit:.1f} s ({n_nodes:,} nodes)"
        return None


class RRT:
    """Batched RRT over a robot's configuration space (see the module docstring).

    Args:
        checker: a :class:`~splatplan.metric.CollisionChecker` (any backend).
        config: :class:`RRTConfig`.
        robot: (required) a :class:`~splatplan.robots.Robot` or a name for
            :func:`~splatplan.robots.load_robot` ("panda", "go2", "sphere:0.015", "ellipsoid:A,B,C",
            a URDF path).
    """

    #: the planner's name in :data:`~splatplan.planners.PLANNERS`
    name = "rrt"

    def __init__(self, checker: CollisionChecker, config: RRTConfig | None = None, *, robot: Robot | str) -> None:
        self.checker = checker
        self.config = (config or RRTConfig()).validate()
        self.geometry = LinkGeometry(as_robot(robot))
        #: a translating sphere: edges are checked between their samples too
        self.inflate_edges = self.geometry.sphere

    @property
    def robot(self):
        """The :class:`~splatplan.robots.Robot`."""
        return self.geometry.robot

    # ------------------------------------------------------------------ setup
    def _derived_box(self, start: np.ndarray, goal: np.ndarray | None, notes: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """Sampling box from joint limits and the scene's robust bounds (see the module docstring)."""
        geom, d = self.geometry, start.size
        robot = geom.robot
        lim = np.asarray(robot.joint_limits, dtype=np.float64).reshape(d, 2)
        ref = np.asarray(robot.q_default, dtype=np.float64).reshape(d).copy()
        pad = geom.max_semi_axis
        c_ref = np.asarray(robot.ellipsoids(ref[None])[0], dtype=np.float64)[0].mean(axis=0)  # (3,) robot centre
        trans_dirs = np.full((d, 3), np.nan)
        for j in np.nonzero(~np.isfinite(lim).all(axis=1))[0]:
            q1 = ref.copy()
            q1[j] += 1.0
            c1, quat1, _ = robot.ellipsoids(np.stack([ref, q1]))
            u = np.asarray(c1[1] - c1[0], dtype=np.float64)  # (E, 3)
            rot_same = quat1 is None or np.allclose(np.abs(np.sum(quat1[0] * quat1[1], axis=-1)), 1.0, atol=1e-9)
            if rot_same and np.allclose(u, u[:1], atol=1e-9) and abs(np.linalg.norm(u[0]) - 1.0) < 1e-6:
                trans_dirs[j] = u[0]
        lo, hi = lim[:, 0].copy(), lim[:, 1].copy()
        need_scene = [j for j in range(d) if not (np.isfinite(lo[j]) and np.isfinite(hi[j]))]
        if need_scene:
            s_lo, s_hi = robust_scene_box(self.checker.scene)
            r_lo, r_hi = self.checker.scene.bounds()
            corners = np.array([[x, y, z] for x in (s_lo[0], s_hi[0]) for y in (s_lo[1], s_hi[1]) for z in (s_lo[2], s_hi[2])])
            raw = np.array([[x, y, z] for x in (r_lo[0], r_hi[0]) for y in (r_lo[1], r_hi[1]) for z in (r_lo[2], r_hi[2])])
            for j in need_scene:
                u = trans_dirs[j]
                if not np.all(np.isfinite(u)):  # an unlimited rotation (e.g. a base's yaw)
                    lo[j], hi[j] = -math.pi, math.pi
                    continue
                off = ref[j] - float(u @ c_ref)  # q_j = off + u . (robot centre)
                lo[j], hi[j] = off + float((corners @ u).min()) - pad, off + float((corners @ u).max()) + pad
                raw_lo, raw_hi = off + float((raw @ u).min()) - pad, off + float((raw @ u).max()) + pad
                for name, x in (("start", start), ("goal", goal)):
                    if x is None:
                        continue
                    if x[j] < raw_lo - 1e-9 or x[j] > raw_hi + 1e-9:
                        raise PlanningError(
                            f"the {name} {np.array2string(x, precision=4)} lies outside the scene bounds: coordinate {j} = {x[j]:.4g} "
                            f"is not within {raw_lo:.4g}..{raw_hi:.4g} (splat means, padded by the robot size); "
                            f"give a {name} inside the scene or set the sampling box (box_lo/box_hi, --box)"
                        )
                    if x[j] < lo[j] or x[j] > hi[j]:
                        notes.append(f"box widened on coordinate {j} to include the {name} (outside the {BOX_PERCENTILE:g}-{100 - BOX_PERCENTILE:g} percentile box)")
                        lo[j], hi[j] = min(lo[j], x[j]), max(hi[j], x[j])
        if self.config.frozen:
            for j in self.config.frozen:
                if not 0 <= int(j) < d:
                    raise PlanningError(f"RRTConfig.frozen names coordinate {j}, the configuration has {d}")
                lo[int(j)] = hi[int(j)] = start[int(j)]
        return lo, hi

    def _box(self, start: np.ndarray, goal: np.ndarray | None, notes: list[str]) -> tuple[np.ndarray, np.ndarray]:
        cfg, d = self.config, start.size
        if cfg.box_lo is None or cfg.box_hi is None:
            lo, hi = self._derived_box(start, goal, notes)
            if cfg.box_lo is not None:
                lo = np.asarray(cfg.box_lo, dtype=np.float64).reshape(-1)
            if cfg.box_hi is not None:
                hi = np.asarray(cfg.box_hi, dtype=np.float64).reshape(-1)
        else:
            lo = np.asarray(cfg.box_lo, dtype=np.float64).reshape(-1)
            hi = np.asarray(cfg.box_hi, dtype=np.float64).reshape(-1)
        if lo.shape != (d,) or hi.shape != (d,):
            raise PlanningError(f"the sampling box has dimension {lo.shape}/{hi.shape}, the start has {d}")
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise PlanningError(f"the sampling box must be finite: lo {lo}, hi {hi}")
        if np.any(hi < lo):
            raise PlanningError(f"the sampling box is empty: lo {lo} > hi {hi} somewhere")
        for name, x in (("start", start), ("goal", goal)):
            if x is None:
                continue
            tol = 1e-9 * max(1.0, float(np.abs(x).max()))
            if np.any(x < lo - tol) or np.any(x > hi + tol):
                raise PlanningError(
                    f"the {name} {np.array2string(x, precision=4)} lies outside the sampling box "
                    f"lo={np.array2string(lo, precision=4)} hi={np.array2string(hi, precision=4)} "
                    f"(joint limits, the given box, or a frozen coordinate lo == hi that must equal the {name}'s)"
                )
        return lo, hi

    def settings(self, start, goal=None) -> RRTSettings:
        """The values a search from ``start`` to ``goal`` will use: the config's where given, else
        derived from the scene and the robot (see the module docstring). Raises like :meth:`plan`."""
        cfg = self.config
        start = np.asarray(start, dtype=np.float64).reshape(-1)
        goal = None if goal is None else np.asarray(goal, dtype=np.float64).reshape(-1)
        self.geometry.bind(start)
        if goal is not None and goal.shape != start.shape:
            raise PlanningError(f"start has {start.size} coordinates but goal has {goal.size}")
        if not np.all(np.isfinite(start)) or (goal is not None and not np.all(np.isfinite(goal))):
            raise PlanningError("start and goal must be finite")
        notes: list[str] = []
        derived: list[str] = []
        lo, hi = self._box(start, goal, notes)
        if cfg.box_lo is None or cfg.box_hi is None:
            derived.append("box")
        geom = self.geometry
        w = geom.distance_scale()
        if cfg.stride is None:
            side = float(np.max((hi - lo) * w)) if np.any(hi > lo) else 1.0
            stride = side * STRIDE_FRACTION
            derived.append("stride")
        else:
            stride = float(cfg.stride)
        if cfg.edge_resolution is None:
            res = cfg.edge_fraction * geom.min_semi_axis
            derived.append("edge_resolution")
        else:
            res = float(cfg.edge_resolution)
        if cfg.goal_tolerance is None:
            tol = 0.5 * geom.min_semi_axis
            derived.append("goal_tolerance")
        else:
            tol = float(cfg.goal_tolerance)
        if not (math.isfinite(stride) and stride > 0 and math.isfinite(res) and res > 0):
            raise PlanningError(f"derived stride {stride} / edge resolution {res} are not usable; set RRTConfig.stride and edge_resolution")
        connect = 4.0 * stride if cfg.connect_radius is None else float(cfg.connect_radius)
        return RRTSettings(lo, hi, stride, res, tol, connect, cfg.time_limit_s, derived, notes)

    def _setup(self, start, goal, deadline: float | None) -> Search:
        """Settings, edge checker, endpoint checks, sampler and deadline of one search (raises like :meth:`plan`)."""
        t0 = time.perf_counter()
        st = self.settings(start, goal)
        start = np.asarray(start, dtype=np.float64).reshape(-1)
        goal = None if goal is None else np.asarray(goal, dtype=np.float64).reshape(-1)
        geom = self.geometry
        edges = EdgeChecker(self.checker, geom, st.edge_resolution, inflate=self.inflate_edges, stages=self.config.edge_stages,
                            slack=self.config.edge_slack)  # fmt: skip
        q0 = geom.n_queries
        check_endpoint(self.checker, geom, start, "start")
        if goal is not None:
            check_endpoint(self.checker, geom, goal, "goal")
        frozen = st.box_hi <= st.box_lo
        end = math.inf if deadline is None else float(deadline)
        if st.time_limit_s is not None:
            end = min(end, t0 + st.time_limit_s)
        return Search(t0, st, start, goal, geom.distance_scale(), edges, q0, np.random.default_rng(self.config.seed), frozen,
                       np.where(frozen, 0.0, st.box_hi - st.box_lo), end, deadline, geom.n_configs)  # fmt: skip

    # ------------------------------------------------------------------ search
    def plan(self, start, goal=None, deadline: float | None = None) -> PlanResult:
        """Grow a tree from ``start``; towards ``goal`` (goal mode) or everywhere (goal=None).

        ``deadline`` (a ``time.perf_counter()`` value) ends the search and the shortcut besides
        ``RRTConfig.time_limit_s`` (:func:`~splatplan.planners.plan` shares one budget this way).
        ``info["time_split"]`` gives the seconds spent sampling (and steering), in nearest
        neighbours, in collision checks, shortcutting and the rest.

        Raises:
            PlanningError: start or goal in collision, outside the sampling box / scene bounds /
                joint limits, or a bad box.
        """
        cfg = self.config
        s = self._setup(start, goal, deadline)
        t0, st, start, goal, w, edges, q0, rng = s.t0, s.st, s.start, s.goal, s.w, s.edges, s.q0, s.rng
        d, lo, frozen, geom = start.size, st.box_lo, s.frozen, self.geometry
        connect_r = st.connect_radius

        # the tree: numpy on CPU, grown in place (see module docstring); zs = nodes * w (metric space)
        cap_max = math.inf if cfg.max_nodes is None else int(cfg.max_nodes)
        cap = int(min(cap_max, 4096))
        nodes = np.empty((cap, d))  # (cap, D) configurations
        zs = np.empty((cap, d))  # (cap, D) the same in the weighted metric
        parents = np.full(cap, -1, dtype=np.int64)  # (cap,)
        cost = np.zeros(cap)  # path length from the root (metric)
        nodes[0], zs[0] = start, start * w
        n = 1
        goal_z = None if goal is None else goal * w
        info = {"settings": st.as_dict(), "edge_resolution": st.edge_resolution, "stride": st.stride, "planner": "rrt"}
        clock = {"sampling": 0.0, "nearest": 0.0}

        def result(success: bool, path: np.ndarray | None, message: str, it: int) -> PlanResult:
            p = np.zeros((0, d)) if path is None else path
            return PlanResult(
                success=success,
                path=p,
                length=path_length(p, w) if path is not None else (math.inf if goal is not None else 0.0),
                time_s=time.perf_counter() - t0,
                n_nodes=n,
                n_iters=it,
                tree_nodes=nodes[:n].copy(),
                tree_parents=parents[:n].copy(),
                message=message,
                path_rrt=None if path is None else path.copy(),
                info={**info, "n_queries": geom.n_queries - q0, "n_configs": geom.n_configs - s.c0, "time_split": _split(time.perf_counter() - t0, clock, edges.time_s, 0.0)},
            )

        def trace(i: int) -> np.ndarray:
            idx = []
            while i >= 0:
                idx.append(i)
                i = int(parents[i])
            return nodes[idx[::-1]].copy()

        if goal is not None and np.linalg.norm(goal_z - zs[0]) <= connect_r and edges.edges_free(start[None], goal[None])[0]:
            raw = np.stack([start, goal])
            return self._finish(result(True, raw, "direct edge from start to goal is free", 0), edges, t0, w, q0, clock, deadline, s.c0)

        it = 0
        while (message := s.stop(cfg, it, n, info)) is None:
            it += 1
            nb = cfg.batch_size
            t1 = time.perf_counter()
            samples = s.sample(nb)  # (N, D)
            if goal is not None and cfg.goal_bias > 0:
                samples[rng.random(nb) < cfg.goal_bias] = goal
            sz = samples * w
            t2 = time.perf_counter()
            near = np.argmin(cdist(sz, zs[:n], "sqeuclidean"), axis=1)  # (N,)
            t3 = time.perf_counter()
            clock["sampling"] += t2 - t1
            clock["nearest"] += t3 - t2
            base = nodes[near]  # (N, D)
            delta = samples - base
            dist = np.linalg.norm(sz - zs[near], axis=1)  # metric distance
            ok = dist > 1e-12
            if not ok.any():
                continue
            base, near, delta, dist = base[ok], near[ok], delta[ok], dist[ok]
            step = np.minimum(dist, st.stride) / dist
            new = base + delta * step[:, None]  # steer: at most `stride` towards the sample
            new[:, frozen] = lo[frozen]
            free = edges.edges_free(base, new)  # every edge point and ellipsoid in edge_stages batched calls
            if not free.any():
                continue
            k = int(min(free.sum(), cap_max - n))
            if n + k > cap:  # grow the tree arrays (doubling)
                cap = int(min(cap_max, max(2 * cap, n + k)))
                nodes, zs = _grow(nodes, cap), _grow(zs, cap)
                parents = _grow(parents, cap, fill=-1)
                cost = _grow(cost, cap)
            sel = np.nonzero(free)[0][:k]
            ids = np.arange(n, n + k)
            nodes[ids] = new[sel]
            zs[ids] = new[sel] * w
            parents[ids] = near[sel]
            cost[ids] = cost[near[sel]] + (dist[sel] * step[sel])
            n += k
            if goal is None:
                continue
            dg = np.linalg.norm(zs[ids] - goal_z, axis=1)
            cand = ids[dg <= connect_r]
            if cand.size:
                ok_goal = edges.edges_free(nodes[cand], np.repeat(goal[None], cand.size, axis=0))
                if ok_goal.any():
                    good = cand[ok_goal]
                    best = int(good[np.argmin(cost[good] + np.linalg.norm(zs[good] - goal_z, axis=1))])
                    raw = np.vstack([trace(best), goal[None]])
                    if n < cap:
                        nodes[n], zs[n], parents[n] = goal, goal_z, best
                        cost[n] = cost[best] + float(np.linalg.norm(goal_z - zs[best]))
                        n += 1
                    return self._finish(result(True, raw, f"goal reached after {it} iterations", it), edges, t0, w, q0, clock, deadline, s.c0)
            if st.goal_tolerance > 0 and np.any(dg <= st.goal_tolerance):
                best = int(ids[np.argmin(dg)])
                return self._finish(result(True, trace(best), f"within goal_tolerance after {it} iterations", it), edges, t0, w, q0, clock, deadline, s.c0)

        if goal is None:
            return result(True, None, f"exploration finished: {message}", it)
        return result(False, None, f"no path found {message}", it)

    def _finish(self, res: PlanResult, edges: EdgeChecker, t0: float, w: np.ndarray, q0: int, clock: dict, deadline: float | None, c0: int = 0) -> PlanResult:
        c_search = edges.time_s
        t1 = time.perf_counter()
        if self.config.shortcut and len(res.path) > 2:
            res.path = shortcut_path(edges, res.path, deadline=deadline, screen=self.config.shortcut_screen)
            res.length = path_length(res.path, w)
        res.info["n_queries"] = edges.n_queries - q0
        res.info["n_configs"] = edges.n_configs - c0
        res.time_s = time.perf_counter() - t0
        res.info["time_split"] = _split(res.time_s, clock, c_search, time.perf_counter() - t1)
        return res


def _split(total: float, clock: dict, collision: float, shortcut: float) -> dict:
    """The time split of a search: sampling, nearest, collision, shortcut, other (= the rest) seconds."""
    out = {"sampling": clock["sampling"], "nearest": clock["nearest"], "collision": collision, "shortcut": shortcut}
    out["other"] = max(0.0, total - sum(out.values()))
    return out


def _grow(a: np.ndarray, cap: int, fill=0) -> np.ndarray:
    out = np.full((cap,) + a.shape[1:], fill, dtype=a.dtype)
    out[: len(a)] = a
    return out
