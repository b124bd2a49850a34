"""Endpoint escape: leave an endpoint that the safety margin blocks, with the margin's guarantee kept.

A planning problem's endpoints are often millimetres from the scene: a grasp has the fingers
around the object. The safety margin of a splat scene (:func:`~splatplan.scenes.margin_for`),
``m = rho + r / 2``, has two parts: ``rho`` estimates the covering radius of the real surface by
the splats (every surface point within rho of a splat), ``r / 2`` covers the motion between two
checked configurations of an edge sampled at resolution ``r`` (no robot point moves more than r
from one check to the next). At a configuration closer to the splats than ``m`` the robot grown
by ``m`` collides, and a planner that checks every configuration with that robot cannot start.

**The trade.** An edge sampled at a finer resolution ``r / f`` needs only ``rho + r / (2 f)``: each
configuration of the edge lies within ``r / (2 f)`` (displacement of any robot point) of a checked
sample, whose ellipsoids grown by ``rho + r / (2 f)`` hold no splat, so the robot there keeps rho
from every splat, the same clearance as the planner's own edges. :func:`escape_endpoint` uses this
near a blocked endpoint: it finds the smallest divisor ``f`` (of ``fine``) whose smaller margin
frees the endpoint, then a short straight segment from the endpoint, checked at ``r / f`` with
that margin, to the first configuration the full margin frees. The planner plans from there with
the full margin; the segment is the path's first (or last) edge.

**A higher n_sigma for the segment.** The same argument holds at every checker n_sigma n: the
splats' n-sigma ellipsoids cover the surface more closely than their means (each reaches at least
n s_t along it, s_t the splats' tangential std), so their covering radius rho(n) is smaller, and a
segment checked at n with the margin ``rho(n) + r / (2 f)`` keeps every robot point rho(n) away from
every n-sigma ellipsoid, hence out of the real surface. Where the planner's own n_sigma cannot free
the endpoint even at the finest divisor, the segment is checked at a higher n_sigma with the
margin's estimate of rho there (:meth:`~splatplan.scenes.SplatMargin.covering_at`: needs the
splats' tangential std, which :func:`~splatplan.scenes.margin_for` records). By default the first
is the n_sigma at which the estimate reaches its floor
(:attr:`~splatplan.scenes.SplatMargin.floor_n_sigma`, at most :data:`MAX_ESCAPE_N_SIGMA`): all
the margin a higher n_sigma can save. A robot beside a flat surface gains most: its splats'
ellipsoids grow along the surface, not towards the robot. Beside an edge (a thin bar, a shelf's
rim) the same growth reaches past the edge towards the robot, so the whole numbers below the floor
n_sigma follow, from the highest down (:func:`escape_n_sigmas`). Each costs one more check per
divisor, and the checker's search grids for that n_sigma, built once, only for an endpoint the
planner's own n_sigma cannot free. The escape configuration is still freed by the planner's own
check (its n_sigma, the full margin).

**Which segments.** The first round tries ``n_directions`` straight segments: towards the other
endpoint, then random (seeded). Where none gets out, a second round tries ``retry`` x as many, led by
the *push directions* (:func:`push_directions`): the joint motions that move the blocking ellipsoids
away from the splats around them. On MotionBenchMaker's blocked grasp goals a random segment gets out
one time in three to five, a push direction nearly always (``benchmarks/mbm_escapes.py``).

What it cannot do: free an endpoint whose splats lie closer than rho(n) plus the finest
``r / (2 f)`` at every n tried (the check says so), which no check that keeps the guarantee can.

    esc = escape_endpoint(checker, robot, q_goal, margin, toward=q_start)
    esc.path          # (K, D): q_goal first, the escape configuration last (K = 1: q_goal was free)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..errors import PlanningError, SplatplanError
from .edges import EdgeChecker, edge_samples
from .robot_links import LinkGeometry

if TYPE_CHECKING:
    from ..metric.checker import CollisionChecker
    from ..robots.robot import Robot
    from ..scenes.margin import SplatMargin

#: resolution divisors tried, smallest first (the smallest that frees the endpoint is used)
FINE_DIVISORS = (2, 4, 8, 16)
#: the escape configuration lies up to this many times farther along its segment than the first one
#: the full margin frees (while the segment's check and the full margin free it)
DEPTH = 2.0
#: segments of the escape's second round (only where the first finds none), as a multiple of ``n_directions``
RETRY_FACTOR = 4
#: push directions tried first (:func:`push_directions`: all blocked ellipsoids at once, then the most crowded alone)
MAX_PUSH = 4
#: the highest checker n_sigma a segment's check uses by default (the margin's floor n_sigma, capped)
MAX_ESCAPE_N_SIGMA = 3.0


@dataclass
class Escape:
    """A free straight segment from an endpoint to a configuration the full margin frees.

    Attributes:
        path: (K, D) the endpoint first, the escape configuration last; K = 1 when the full
            margin frees the endpoint (no escape needed), else K = 2.
        divisor: f, the resolution divisor of the segment's check (1: no escape, or the escape
            robot at the full margin and resolution).
        margin: the margin the segment was checked with, ``rho(n) + r / (2 f)`` (scene units).
        resolution: the segment's edge resolution ``r / f`` (scene units of motion).
        displacement: bound on any robot point's motion along the segment (scene units).
        n_configs: configurations checked to find it.
    """

    path: np.ndarray
    divisor: int
    margin: float
    resolution: float
    displacement: float = 0.0
    n_configs: int = 0
    info: dict = field(default_factory=dict)
    #: the checker n_sigma of the segment's check (the planner's own, or a higher one of ``n_sigmas``)
    n_sigma: float | None = None

    @property
    def escaped(self) -> bool:
        """Whether the endpoint needed an escape segment."""
        return len(self.path) > 1


def endpoint_divisor(checker: CollisionChecker, robot: Robot, q: np.ndarray, margin: SplatMargin, fine: tuple[int, ...] = FINE_DIVISORS, first: int = 1) -> int | None:
    """The smallest resolution divisor f in (1, *fine), from ``first`` on, whose margin
    ``rho + r / (2 f)`` frees ``robot`` at configuration ``q`` (D,) at the checker's n_sigma
    (f = 1: the full margin), or None: blocked even at the finest."""
    found = endpoint_check(checker, robot, q, margin, fine, first, n_sigmas=())
    return None if found is None else found[1]


def endpoint_check(checker: CollisionChecker, robot: Robot, q: np.ndarray, margin: SplatMargin, fine: tuple[int, ...] = FINE_DIVISORS, first: int = 1,
                   n_sigmas: tuple[float, ...] | None = None) -> tuple[float, int] | None:  # fmt: skip
    """The first (n, f) whose margin ``rho(n) + r / (2 f)`` frees ``robot`` at configuration ``q``
    (D,) for the checker at n_sigma n: n the checker's own n_sigma, then those of ``n_sigmas``
    above it, in order, where the margin estimates rho(n) (None: :func:`escape_n_sigmas`; (): the
    checker's own only); f in (1, *fine) from ``first`` on, smallest first. None: blocked at every
    one (module docstring)."""
    found = _first_free(_checks(checker, margin, n_sigmas), robot, q, float(margin.edge_resolution), fine, first)
    return None if found is None else (found[0], found[3])


def _first_free(checks: list[tuple[float, CollisionChecker, float]], robot: Robot, q: np.ndarray, r: float, fine: tuple[int, ...],
                first: int) -> tuple[float, CollisionChecker, float, int] | None:  # fmt: skip
    """:func:`endpoint_check` over the (n, checker at n, rho(n)) of :func:`_checks`: the first
    (n, checker, rho(n), f) that frees ``robot`` at ``q``, or None."""
    q = np.asarray(q, dtype=np.float64).reshape(1, -1)
    for n, check, rho in checks:
        for f in (x for x in (1, *sorted(int(x) for x in fine)) if x >= first):
            geom = LinkGeometry(robot.inflated(rho + 0.5 * r / f))
            if not bool(geom.collides(check, q)[0]):
                return n, check, rho, f
    return None


def escape_n_sigmas(margin: SplatMargin, own: float) -> tuple[float, ...]:
    """The default n_sigma of an escape segment's check after the planner's own ``own``: the
    margin's floor n_sigma (at most :data:`MAX_ESCAPE_N_SIGMA`), then the whole numbers between
    ``own`` and it, highest first; () where the margin cannot estimate rho at another n_sigma."""
    top = margin.floor_n_sigma
    if top is None:
        return ()
    top = min(float(top), MAX_ESCAPE_N_SIGMA)
    return (top, *(float(k) for k in range(math.ceil(top) - 1, 0, -1) if float(own) < k < top))


def _checks(checker: CollisionChecker, margin: SplatMargin, n_sigmas: tuple[float, ...] | None) -> list[tuple[float, CollisionChecker, float]]:
    """(n, checker at n, the margin's rho(n)): the checker's own n_sigma first, then those of
    ``n_sigmas`` above it, in order (None: :func:`escape_n_sigmas`), whose covering radius the
    margin estimates."""
    own = float(checker.n_sigma)
    rho_own = margin.covering_at(own)  # (the margin's own estimate when it was made for this n_sigma or cannot say)
    out = [(own, checker, float(margin.covering_estimate if rho_own is None else rho_own))]
    seen = {own}
    for n in (float(x) for x in (escape_n_sigmas(margin, own) if n_sigmas is None else n_sigmas)):
        rho = margin.covering_at(n)
        if n > own and n not in seen and rho is not None and rho >= 0:
            seen.add(n)
            out.append((n, checker.with_config(n_sigma=n), float(rho)))
    return out


def escape_endpoint(
    checker: CollisionChecker,
    robot: Robot,
    q,
    margin: SplatMargin,
    *,
    toward=None,
    seed: int = 0,
    fine: tuple[int, ...] = FINE_DIVISORS,
    n_directions: int = 12,
    reach: float | None = None,
    what: str = "endpoint",
    geometry: LinkGeometry | None = None,
    box: tuple | None = None,
    escape_robot: Robot | None = None,
    depth: float = DEPTH,
    n_sigmas: tuple[float, ...] | None = None,
    retry: int = RETRY_FACTOR,
) -> Escape:
    """A free segment from ``q`` to a configuration that ``robot`` grown by the full margin clears.

    Args:
        checker: the scene's :class:`~splatplan.metric.CollisionChecker`.
        robot: the robot's own model (not grown: the margins are applied here).
        q: (D,) the endpoint (joint limits respected).
        margin: the scene's :class:`~splatplan.scenes.SplatMargin` (its covering estimate
            ``margin - r / 2`` and resolution r).
        toward: (D,) the other endpoint: the first direction tried (then random ones, seeded,
            ``n_directions`` in all).
        seed: seeds the random directions.
        fine: the resolution divisors allowed (module docstring).
        n_directions: straight segments tried in the first round (one batched check each for the
            finer margin, one for the full margin); where none reaches a freed configuration, a
            second round tries ``retry`` x as many: first up to :data:`MAX_PUSH` that
            move the blocking ellipsoids away from their splats (:func:`push_directions`), then
            random ones.
        reach: longest motion of any robot point along a segment (scene units; default 4 x the
            full margin).
        what: the endpoint's name in messages ("start", "goal").
        geometry: the :class:`~.robot_links.LinkGeometry` of ``robot`` grown by the full margin
            to reuse (a planner's: its buffers are warm); built here when None.
        box: (lo (D,), hi (D,)) the planner's sampling box: the escape configuration stays in it
            (besides the joint limits); coordinates with hi <= lo are held fixed.
        escape_robot: a tighter model of the same robot (same kinematics; ellipsoids that still
            contain every link) for the segment's finer check, e.g. one with more ellipsoids at the
            wrist and hand; the escape configuration is still checked with ``robot`` (the
            planner's model). None: ``robot``.
        depth: the escape configuration is the farthest sample of the chosen segment within
            ``depth`` x the displacement of its first sample the full margin frees (and free for
            it, the segment's check free up to it): 1 = that first sample.
        n_sigmas: checker n_sigma tried for the segment's check where the checker's own cannot
            free ``q`` (those above it, in order; each with the margin's rho(n),
            :meth:`~splatplan.scenes.SplatMargin.covering_at`); None: :func:`escape_n_sigmas`
            (the margin's floor n_sigma, then the whole numbers below it); (): the checker's own only.
        retry: the second round's segments as a multiple of ``n_directions`` (0: no second round).

    Returns:
        :class:`Escape`; ``path`` is ``q`` alone when the full margin frees it.

    Raises:
        PlanningError: ``q`` is blocked even with the finest divisor at every n_sigma tried (its
            splats lie closer than rho(n) plus ``r / (2 max(fine))``), or no segment reaches a
            configuration the full margin frees within ``reach``.
        SplatplanError: bad arguments.
    """
    q = np.asarray(q, dtype=np.float64).reshape(-1)
    if q.shape != (int(robot.dof),) or not np.all(np.isfinite(q)):
        raise SplatplanError(f"escape_endpoint: the {what} must be {robot.dof} finite numbers, got {np.array2string(q, precision=4)}")
    if int(n_directions) < 1:
        raise SplatplanError(f"escape_endpoint: n_directions must be >= 1, got {n_directions}")
    if int(retry) < 0:
        raise SplatplanError(f"escape_endpoint: retry must be >= 0, got {retry}")
    if not fine or min(int(f) for f in fine) < 2:
        raise SplatplanError(f"escape_endpoint: fine must hold divisors >= 2, got {fine}")
    m, r = float(margin.margin), float(margin.edge_resolution)
    if m - 0.5 * r < 0:
        raise SplatplanError(f"escape_endpoint: the margin {m:.4g} is smaller than half its edge resolution {r:.4g}")
    full = LinkGeometry(robot.inflated(m)) if geometry is None else geometry
    if not bool(full.collides(checker, q[None])[0]):
        return Escape(q[None].copy(), 1, m, r, 0.0, 1, n_sigma=float(checker.n_sigma))
    tight = robot if escape_robot is None else escape_robot
    if int(tight.dof) != int(robot.dof):
        raise SplatplanError(f"escape_endpoint: the escape robot has {tight.dof} degrees of freedom, the robot {robot.dof}")
    checks = _checks(checker, margin, n_sigmas)
    found = _first_free(checks, tight, q, r, fine, 1 if escape_robot is not None else 2)
    if found is None:
        finest = _endpoint_margin(margin, max(int(x) for x in fine))
        tried = ", ".join(f"{n:g}" for n, _, _ in checks)
        raise PlanningError(
            f"the {what} {np.array2string(q, precision=4)} is in collision even for the finest endpoint check: splats lie "
            f"within {1000 * finest:.2f} mm of the robot there (the covering estimate {1000 * margin.covering_estimate:.2f} mm "
            f"plus r/{max(int(x) for x in fine)}/2; n_sigma tried: {tried}), closer than the margin's guarantee allows; "
            f"move the {what} away from the scene"
        )
    n_e, check, rho_e, f = found
    m_e = rho_e + 0.5 * r / f
    weak = LinkGeometry(tight.inflated(m_e))  # (f = 1: a tighter model at the full margin)
    r_f = r / f
    reach_m = 4.0 * m if reach is None else float(reach)
    if not (math.isfinite(reach_m) and reach_m > 0):
        raise SplatplanError(f"escape_endpoint: reach must be finite and > 0, got {reach}")
    tw = None if toward is None else np.asarray(toward, dtype=np.float64).reshape(-1)
    best, n_cfg, n_dirs, n_push, rounds = None, 1, 0, 0, 0
    for k in range(2 if int(retry) > 0 else 1):  # a second, larger round only where the first finds none: pushes first, then random
        if k == 0:
            dirs = _directions(q, tw, int(n_directions), seed, full)
        else:
            push = push_directions(checker, full, q)  # (K, D) the blocked ellipsoids moved away from their splats
            n_push = len(push)
            dirs = _directions(q, None, int(retry) * int(n_directions), (seed, 1), full, push)
        best, n_c, n_d = _segments(checker, robot, q, dirs, box, reach_m, weak, full, check, r_f, depth)
        n_cfg, n_dirs, rounds = n_cfg + n_c, n_dirs + n_d, k + 1
        if best is not None:
            break
    if best is None and n_dirs == 0:
        raise PlanningError(f"the {what} is blocked by the margin and the joint limits leave no direction to leave it by")
    if best is None:
        raise PlanningError(
            f"the {what} {np.array2string(q, precision=4)} is blocked by the margin ({1000 * m:.2f} mm) and none of "
            f"{n_dirs} straight segments of up to {1000 * reach_m:.1f} mm reaches a configuration it frees"
        )
    return Escape(np.stack([q, best[0]]), int(f), float(m_e), r_f, best[1], int(n_cfg),
                  {"directions": int(n_dirs), "push_directions": int(n_push), "rounds": rounds}, n_sigma=float(n_e))  # fmt: skip


def _segments(checker: CollisionChecker, robot: Robot, q: np.ndarray, dirs: np.ndarray, box: tuple | None, reach_m: float, weak: LinkGeometry,
              full: LinkGeometry, check: CollisionChecker, r_f: float, depth: float) -> tuple[tuple[np.ndarray, float] | None, int, int]:  # fmt: skip
    """Try the straight segments from ``q`` along ``dirs`` (M, D): (the escape configuration and its
    displacement bound, or None; configurations checked; segments tried). Each segment is checked
    with ``weak`` at resolution ``r_f`` (on ``check``), its free samples with ``full``."""
    w0, f0 = weak.n_configs, full.n_configs
    limits = np.asarray(robot.joint_limits, dtype=np.float64).copy()  # (D, 2)
    if box is not None:
        lo, hi = (np.broadcast_to(np.asarray(x, dtype=np.float64), q.shape) for x in box)
        frozen = hi <= lo
        dirs[:, frozen] = 0.0
        limits[:, 0], limits[:, 1] = np.maximum(limits[:, 0], np.where(frozen, -np.inf, lo)), np.minimum(limits[:, 1], np.where(frozen, np.inf, hi))
        mot = weak.motion(dirs)
        dirs = dirs / np.where(mot > 0, mot, 1.0)[:, None]
    t_max = _limit_steps(q, dirs, limits, reach_m, weak)  # (M,)
    keep = t_max > 0
    dirs, t_max = dirs[keep], t_max[keep]
    if len(dirs) == 0:
        return None, 0, 0
    a = np.repeat(q[None], len(dirs), axis=0)
    b = q + t_max[:, None] * dirs  # (M, D)
    edges = EdgeChecker(check, weak, r_f, stages=3)  # (coarse to fine: a segment's checks stop at its first hit; at n_e)
    k, n = edges.free_prefix(a, b)  # (M,), (M,) free samples of each segment at r / f
    pts, idx, _ = edge_samples(a, b, weak.motion(b - a), r_f)  # (P, D), the same samples
    loc = np.arange(idx.size) - (np.cumsum(n) - n)[idx] + 1  # (P,) 1..n_e
    cand = np.nonzero(loc <= k[idx])[0]  # the samples in each segment's free prefix
    best = None
    if cand.size:
        ok = ~full.collides(checker, pts[cand])  # (C,) free for the full margin
        if ok.any():
            c = cand[ok]
            disp = weak.motion(pts[c] - q)  # (C,) the segment's displacement bound
            j = int(np.argmin(disp))
            # on the same segment, the farthest free sample within ``depth`` x that displacement: room
            # for the search to leave it (a configuration barely free for the full margin is a narrow start)
            same = (idx[c] == idx[c[j]]) & (disp <= float(depth) * disp[j] + 1e-12)
            j = int(np.flatnonzero(same)[np.argmax(disp[same])])
            best = (pts[c[j]], float(disp[j]))
    return best, (weak.n_configs - w0) + (full.n_configs - f0), len(dirs)


def _endpoint_margin(margin: SplatMargin, f: int) -> float:
    """``rho + r / (2 f)``: the margin of an edge checked at resolution r / f."""
    return float(margin.covering_estimate) + 0.5 * float(margin.edge_resolution) / int(f)


def _directions(q: np.ndarray, toward: np.ndarray | None, n: int, seed: int | tuple[int, ...], geom: LinkGeometry, push: np.ndarray | None = None) -> np.ndarray:
    """(n, D) unit-motion directions (each moves some robot point by at most 1 scene unit per unit
    step): towards ``toward`` first, then the ``push`` directions (K, D) (at most n - 1 of them), then
    random ones (seeded by ``seed``, an int or a tuple of ints), zero where the robot does not move."""
    rng = np.random.default_rng(seed)
    d = rng.standard_normal((n, q.size)) / np.maximum(geom.weights, 1e-12)  # (n, D) isotropic in the metric
    k = 0
    if toward is not None and toward.shape == q.shape and np.any(toward != q):
        d[0] = toward - q
        k = 1
    if push is not None and len(push):
        m = min(len(push), n - k)
        d[k : k + m] = push[:m]
    mot = geom.motion(d)
    return d / np.where(mot > 0, mot, 1.0)[:, None]


def push_directions(checker: CollisionChecker, full: LinkGeometry, q: np.ndarray, max_dirs: int = MAX_PUSH) -> np.ndarray:
    """(K, D) joint-space directions that move the ellipsoids which block ``q`` (D,) at the full
    margin (``full``: the robot grown by it) away from the splats around them: each blocked
    ellipsoid's push is the unit vector from the mean of the splat means within its bounding sphere
    to its centre; a direction is the Jacobian transpose (finite differences of the centres) times
    the pushes, the joint motion that increases ``sum_e push_e . c_e(q)`` fastest: first for all
    blocked ellipsoids at once, then for each of the (at most ``max_dirs - 1``) most crowded ones
    alone. (On MotionBenchMaker's blocked grasps it beat the least-squares and damped least-squares
    motions towards the pushes: the one of every ellipsoid at once may ask for more than the joints
    can give.) Empty where nothing blocks ``q`` or the pushes are undefined. A heuristic for which
    directions to try first: every segment along them is checked like any other."""
    robot = full.robot
    hit = np.asarray(checker.collides_robot(robot, q[None]))[0]  # (E,)
    if not hit.any():
        return np.zeros((0, q.size))
    c, _, ax = robot.ellipsoids(q[None])  # (1, E, 3), (E, 3)
    c = np.asarray(c[0], dtype=np.float64)
    blocked = np.flatnonzero(hit)  # (B,)
    radius = np.asarray(ax, dtype=np.float64)[blocked].max(axis=1)  # (B,) bounding spheres
    lo, hi = (c[blocked] - radius[:, None]).min(axis=0), (c[blocked] + radius[:, None]).max(axis=0)
    near = _means_in_box(np.asarray(checker.scene.means), lo, hi)  # (N', 3): a box around every blocked sphere
    pushes, counts, rows = [], [], []
    for e, r in zip(blocked.tolist(), radius.tolist()):
        inside = near[np.sum((near - c[e]) ** 2, axis=1) <= r * r]
        if len(inside) == 0:
            continue
        v = c[e] - inside.mean(axis=0)
        nv = float(np.linalg.norm(v))
        if not nv > 1e-12:
            continue
        pushes.append(v / nv)
        counts.append(len(inside))
        rows.append(e)
    if not rows:
        return np.zeros((0, q.size))
    jac = _center_jacobian(robot, q, np.asarray(rows))  # (B', 3, D)
    order = np.argsort(counts, kind="stable")[::-1]
    systems = [(jac.reshape(-1, q.size), np.concatenate(pushes))] + [(jac[i], pushes[i]) for i in order[: max(0, int(max_dirs) - 1)] if len(rows) > 1]
    out = []
    for a, b in systems:
        dq = a.T @ b  # (D,) the gradient of sum_e push_e . c_e(q): every blocked centre's motion along its push, to first order
        if np.all(np.isfinite(dq)) and full.motion(dq[None])[0] > 0:
            out.append(dq)
    return np.asarray(out).reshape(-1, q.size)


def _means_in_box(means: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(N', 3) float64: the rows of ``means`` (N, 3) within the box lo..hi (3,) (axis by axis, each
    pass over the rows left)."""
    idx = np.flatnonzero((means[:, 0] >= lo[0]) & (means[:, 0] <= hi[0]))
    for a in (1, 2):
        v = means[idx, a]
        idx = idx[(v >= lo[a]) & (v <= hi[a])]
    return means[idx].astype(np.float64)


def _center_jacobian(robot: Robot, q: np.ndarray, rows: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """(len(rows), 3, D): d centre / d q of the ellipsoids ``rows`` at ``q`` (central differences)."""
    d = q.size
    qs = np.concatenate([q + h * np.eye(d), q - h * np.eye(d)])  # (2D, D)
    c = np.asarray(robot.ellipsoids(qs)[0], dtype=np.float64)[:, rows]  # (2D, B, 3)
    return np.transpose((c[:d] - c[d:]) / (2.0 * h), (1, 2, 0))


def _limit_steps(q: np.ndarray, dirs: np.ndarray, limits: np.ndarray, reach: float, geom: LinkGeometry) -> np.ndarray:
    """(M,) the step along each direction: ``reach`` of motion, shortened to stay within the joint
    limits (0 where the direction leaves them at once)."""
    lo, hi = limits[:, 0], limits[:, 1]
    t = np.full(len(dirs), float(reach))
    with np.errstate(divide="ignore", invalid="ignore"):
        up = np.where(dirs > 0, (hi - q) / dirs, np.inf)
        dn = np.where(dirs < 0, (lo - q) / dirs, np.inf)
    t = np.minimum(t, np.minimum(up, dn).min(axis=1))
    t[~np.isfinite(t) | (t < 0)] = 0.0
    t[geom.motion(dirs) <= 0] = 0.0
    return t
