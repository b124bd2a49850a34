"""Edge checks of the sampling planners: the check samples of an edge, the batched coarse-to-fine
:class:`EdgeChecker` (free prefixes, free slack, screening), the endpoint check and the greedy
shortcut. See :mod:`.rrt` for the edge-resolution guarantee these implement.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from .._resources import require_bytes
from ..errors import PlanningError, SplatplanError
from .robot_links import LinkGeometry

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker

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


def sample_counts(motion: np.ndarray, resolution: float, dof: int) -> np.ndarray:
    """(E,) motion bounds -> (E,) int64 check-sample counts ``max(1, ceil(motion / resolution))``,
    after a resource guard: a huge edge (a goal 1e30 away) or a tiny resolution would ask for more
    checks than memory holds."""
    n_float = np.maximum(1.0, np.ceil(np.asarray(motion, dtype=np.float64) / resolution - 1e-9))  # (E,)
    require_bytes(float(n_float.sum()) * (dof + 2) * 8 * 4, f"{float(n_float.sum()):.3g} collision checks along {len(n_float)} edge(s)",
                  "the edge length (or coarsen the edge resolution)")  # fmt: skip
    return n_float.astype(np.int64)


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
    n = sample_counts(motion, resolution, a.shape[-1])
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
        walk: with ``slack``, :meth:`edges_free` runs the checker's SLACK WALK
            (:meth:`CollisionChecker.edges_free`: one compiled call, the same answers) instead of
            the batched stages.

    **Free slack (``slack``).** Each checked ellipsoid comes back with the checker's RIGID SLACK
    (:meth:`CollisionChecker.collides_configs_slack`): a rigid motion that moves none of its points
    farther keeps it free. Far from every splat it comes from the mean-distance grid at no cost;
    near splats, a check asks for the slack that would prove the samples up to the next check of
    its stage (:attr:`SLACK_TARGET_STEPS`), and links short of it read the splats that far around
    them for the clearance of their closest mean. At a checked free configuration,
    each ellipsoid's slack divided by the bound on its displacement from one sample to the next
    (its own motion bound, :meth:`Robot.ellipsoid_motion_bounds`, over the edge, divided by n)
    is how many samples on either side it stays free (all of them for an ellipsoid that the
    edge does not move, such as a fixed base); the smallest over the ellipsoids is how many
    samples are free as well: they are not checked. The answers are those of checking them (the
    checker would call each of them free), with fewer checks, near surfaces too.
    """

    #: stride ratio between consecutive stages of the coarse-to-fine check
    STAGE_FACTOR = 4
    #: the free slack a check asks for, in samples of its edge (half the stride of its stage, at
    #: most this): a link whose slack from the mean-distance grid falls short reads the splats
    #: around it that far (the checker's RIGID SLACK); more reads more splats per check
    SLACK_TARGET_STEPS = 4.0
    #: :meth:`edges_free` walks (:attr:`walks`) calls of at most this many edges; larger batches (a
    #: planner's candidate edges, many of them colliding) take the batched stages, coarse to fine
    #: and split over the checker's threads, where the walk would run them one after another on one
    WALK_MAX_EDGES = 8

    def __init__(self, checker: CollisionChecker, geometry: LinkGeometry, resolution: float, inflate: bool = False, stages: int = 1, slack: bool = False,
                 walk: bool = False) -> None:  # fmt: skip
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
        #: :meth:`edges_free` by the checker's SLACK WALK (with ``use_slack``, without ``inflate``)
        self.walk = bool(walk)
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

    @property
    def walks(self) -> bool:
        """Whether :meth:`edges_free` runs the checker's SLACK WALK (``walk`` with ``slack``, without ``inflate``)."""
        return self.walk and self.use_slack and not self.inflate

    def edges_free(self, a: np.ndarray, b: np.ndarray, screen: int | None = None) -> np.ndarray:
        """(E, D), (E, D) -> bool (E,): True where the whole edge (end point included, start
        excluded) is collision-free at ``resolution``. An edge's checks stop at its first hit found.
        With :attr:`walks` (and at most :attr:`WALK_MAX_EDGES` edges): the checker's SLACK WALK,
        one call for all edges. ``screen``: first every screen-th sample of each edge
        (:meth:`screen`; inside the walk, edge by edge), the same answers with fewer checks where
        edges collide."""
        if self.walks and len(a) <= self.WALK_MAX_EDGES:
            return self._walk(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64), int(screen or 0))
        ok = np.ones(len(a), dtype=bool) if not screen else self.screen(a, b, int(screen))
        if ok.any():
            k, n = self.free_prefix(np.asarray(a)[ok], np.asarray(b)[ok], exact=np.zeros(int(ok.sum()), dtype=bool))
            ok[ok] = k == n
        return ok

    def _walk(self, a: np.ndarray, b: np.ndarray, screen: int = 0) -> np.ndarray:
        """:meth:`edges_free` by :meth:`CollisionChecker.edges_free` (the samples of :func:`edge_samples`,
        each ellipsoid's step its own motion bound over n, the slack target :attr:`SLACK_TARGET_STEPS`)."""
        if len(a) == 0:
            return np.zeros(0, dtype=bool)
        t0 = time.perf_counter()
        n = sample_counts(self.geometry.motion(b - a), self.resolution, a.shape[-1])  # (E,) as edge_samples
        step = self.geometry.ellipsoid_motion(b - a) / n[:, None]  # (E_edges, E)
        free, checks = self.checker.edges_free(self.geometry.robot, a, b, n, step, target_steps=int(self.SLACK_TARGET_STEPS), screen=screen,
                                                validate=False)  # fmt: skip
        self.geometry.n_configs += int(checks.sum())
        self.geometry.n_queries += int(checks.sum()) * int(self.geometry.robot.n_ellipsoids)
        self.time_s += time.perf_counter() - t0
        return free

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
            if use_slack and stride > 1:  # target: the slack that proves the samples up to the next check of this stride (at most SLACK_TARGET_STEPS); the last stage has no later samples to prove
                want = min(0.5 * stride, self.SLACK_TARGET_STEPS)
                hit, slack = self.geometry.collides_slack(self.checker, pts[s], step[idx[s]] * want)  # (S,), (S, E)
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
            j = first_free(edges, p, i, cand[::-1], int(screen)) or j  # farthest first
        elif cand.size:
            free = edges.edges_free(np.repeat(p[i : i + 1], cand.size, axis=0), p[cand])
            if free.any():
                j = int(cand[np.nonzero(free)[0].max()])
        out.append(p[j])
        i = j
    return np.asarray(out)


def first_free(edges: EdgeChecker, p: np.ndarray, i: int, cand: np.ndarray, screen: int) -> int | None:
    """The first vertex c of ``cand`` (in that order) whose edge p[i] -> p[c] is free, each screened
    at every ``screen``-th sample first (0: not screened), or None. With :attr:`EdgeChecker.walks` each candidate is one
    walk with its screen, and the candidates after the first free one are not looked at; else all
    are screened in one call and the survivors checked whole in turn."""
    if edges.walks:
        for c in cand.tolist():
            if edges.edges_free(p[i : i + 1], p[c : c + 1], screen=screen)[0]:
                return int(c)
        return None
    ok = edges.screen(np.repeat(p[i : i + 1], cand.size, axis=0), p[cand], screen) if screen else np.ones(cand.size, dtype=bool)
    for c in cand[ok].tolist():
        if edges.edges_free(p[i : i + 1], p[c : c + 1])[0]:
            return int(c)
    return None
