"""The sampling planners' configuration, the settings a search used and its result.

:class:`RRTConfig` (the knobs), :class:`RRTSettings` (the values one search used, user-given or
derived) and :class:`PlanResult`; :func:`path_length` in the planners' weighted metric. Shared by
:mod:`.rrt`, :mod:`.rrt_connect` and the OMPL bridge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._config import bounded, check_config
from ..errors import SplatplanError
from .robot_links import EDGE_FRACTION

@dataclass
class RRTConfig:
    """Knobs of the batched RRT. Lengths are in scene units of robot motion (the weighted
    configuration distance |motion_bound * dq|; plain distance for a point robot). Every None is
    derived from the scene and the robot (see the module docstring)."""

    #: samples drawn (and edges checked) per iteration; None = the planner's own: 32 for the
    #: goal-biased RRT (the paper grows 32 nodes at a time), 16 for RRT-Connect (two trees, each
    #: growing every other iteration: fewer wasted checks per iteration)
    batch_size: int | None = bounded(None, ge=1)
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
    #: skip edge check samples that a checked neighbour proves free (the checker's rigid slack: a
    #: configuration stays free while no point of an ellipsoid moves farther than that ellipsoid's
    #: clearance, read near surfaces too); the same answers with fewer checks
    edge_slack: bool = True
    #: with edge_slack: an edge that only has to be free or not is checked by one compiled walk
    #: along it (the checker's SLACK WALK, CollisionChecker.edges_free) instead of edge_stages
    #: batched calls; the same answers with fewer checks near surfaces
    edge_walk: bool = True
    #: RRT-Connect: lazy search: check only the new nodes while the trees grow and the edges of a
    #: candidate path once the trees meet (removing what collides); the returned path is checked at
    #: edge_resolution either way. False: every edge checked when it is grown (the eager search)
    lazy: bool = True
    #: shortcut: screen each vertex's candidate edges at every this-many-th check sample first and
    #: check the survivors whole, farthest first (the same path, fewer checks); None: check every
    #: candidate whole
    shortcut_screen: int | None = bounded(64, ge=1)

    def validate(self) -> "RRTConfig":
        check_config(self)  # each field's declared range (splatplan._config); cross-field rules below
        if self.batch_size is not None and self.batch_size < 1:
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
        info: the planner's extras as a dict (what the typed properties below read, and
            planner-specific keys such as ``tree_sizes`` or ``stride``).

    Typed views of the extras users read (properties; ``info`` keeps the same values under the
    same names): :attr:`planner`, :attr:`n_configs`, :attr:`n_queries`, :attr:`time_split`,
    :attr:`settings`, :attr:`path_shortcut`, :attr:`length_shortcut`, :attr:`refine_message`.
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

    @property
    def planner(self) -> str:
        """The planner that ran (``"rrt"``, ``"rrtconnect"``, ``"ompl:NAME"``; "" when unknown)."""
        return str(self.info.get("planner", ""))

    @property
    def n_configs(self) -> int:
        """Robot configurations collision-checked by the call (search, validation and shortcut)."""
        return int(self.info.get("n_configs", 0))

    @property
    def n_queries(self) -> int:
        """Collision-checker calls made by the call."""
        return int(self.info.get("n_queries", 0))

    @property
    def time_split(self) -> dict[str, float]:
        """Seconds by phase (``sampling``, ``nearest``, ``collision``, ``shortcut``, ``refine``,
        ``other``; they sum to :attr:`time_s` after :func:`splatplan.planners.plan`)."""
        return {str(k): float(v) for k, v in dict(self.info.get("time_split", {})).items()}

    @property
    def settings(self) -> dict:
        """The search's settings as used (derived or given; :class:`RRTSettings` as a dict)."""
        return dict(self.info.get("settings") or {})

    @property
    def path_shortcut(self) -> np.ndarray:
        """(P, D) the shortcut search path, before any refinement (= :attr:`path` when not refined)."""
        p = self.info.get("path_shortcut")
        return np.asarray(self.path if p is None else p)

    @property
    def length_shortcut(self) -> float:
        """Length of :attr:`path_shortcut` in the planner's metric (as :attr:`length`)."""
        return float(self.info.get("length_rrt", self.length))

    @property
    def refine_message(self) -> str:
        """Why the refinement was accepted or not ("" when it did not run)."""
        return str(self.info.get("refine_message", ""))


def path_length(path: np.ndarray, weights: np.ndarray | None = None) -> float:
    """Sum of segment lengths of a polyline (P, D) (coordinates scaled by ``weights`` (D,) first);
    0 for P < 2."""
    p = np.asarray(path, dtype=np.float64)
    if weights is not None:
        p = p * np.asarray(weights, dtype=np.float64)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum()) if len(p) > 1 else 0.0
