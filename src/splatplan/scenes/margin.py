"""The safety margin from the splat spacing: how much to grow a robot so that planning against the
splats keeps it out of the real surface.

A splat scene is a sample of a surface: a link can slip between splats and cut the surface while
every checked configuration is free. A margin that covers the gaps makes that impossible, and it
can be estimated from the splats alone (no ground truth), as every real capture needs:

    from splatplan.scenes import margin_for
    m = margin_for(splats, robot, n_sigma=0.0)
    checker = CollisionChecker(splats, n_sigma=0.0)
    res = plan(checker, q0, q1, robot=robot.inflated(m.margin),
               rrt_config=RRTConfig(edge_resolution=m.edge_resolution))

:func:`margin_for` returns a :class:`SplatMargin` (the margin m, the splat spacing h and the edge
resolution r the margin assumes; plan with that resolution or a finer one).
:func:`covering_radius` measures the quantity the margin estimates, rho(n), when the exact surface
is known (a built-in or MoveIt scene), to check ``m >= rho(n) + r / 2``. :func:`derived_margin` is
the same estimate as a tuple ``(m, h, r)`` (the form ``splatplan.eval.mbm`` has always used).

**The safety margin, at every n_sigma.** Let ``E_i(n) = {mu_i + R_i diag(s_i) u : |u| <= n}`` be
splat i's n-sigma ellipsoid (its mean at n = 0), ``rho(n)`` the covering radius of the exposed
surface by their union (every surface point lies within rho(n) of some E_i(n)), and r the edge
resolution (no ellipsoid point moves more than r between consecutive checked configurations; by
default a quarter of the robot's own smallest semi-axis).

*Claim:* if the planner checks, at n_sigma = n, the robot grown by ``m >= rho(n) + r / 2`` (each
ellipsoid replaced by one containing its Minkowski sum with a ball of radius m,
:meth:`Robot.inflated <splatplan.robots.Robot.inflated>`) and every checked configuration is free,
then no configuration along the edge has a surface point inside the real robot's ellipsoids.

1. *The checker is conservative for E_i(n).* ``s2(p) = (p - c)^T A (p - c)`` is convex, so for
   ``p = mu + R diag(s) u``, ``|u| <= n``: ``s2(p) >= s2(mu) + g . (p - mu) >= s2 - n sigma`` (g the
   gradient at mu; Cauchy-Schwarz gives ``|g . R diag(s) u| <= n |diag(s) R^T g| = n sigma``). A
   point of E_i(n) inside the link (s2(p) < 1) therefore makes ``s2~ = max(0, s2 - n sigma) < 1``:
   the splat is counted. Free means no point of any E_i(n) inside any (grown) link.
2. A surface point x inside a link at a configuration between two checked ones is within r/2 of
   the same link at the nearer checked configuration (the motion bound is linear along an edge);
   some point p of some E_i(n) lies within rho(n) of x, hence within rho(n) + r/2 <= m of that
   link: inside the grown link (x is interior, so strictly), which the checker would have counted.
3. A robot cannot get into a solid without a surface point inside it along a continuous path from
   a valid start, so the path's exact clearance stays >= 0.

Nothing is exempted at the endpoints: they are checked with the same grown model. rho(n) needs the
ground truth; the derived margin estimates it from the splats alone:
``m = max(spacing_factor h - n s_t, floor_factor h) + r/2`` with h the median nearest-neighbour
distance of the means and s_t the median middle std (a splat's smaller tangential std: its
n-sigma ellipsoid reaches at least n s_t along the surface, closing the gaps between means; the
floor covers the means' offsets along the normal, which flat splats do not). On the built-in
sampler's look the measured rho(0) is 2.3-2.6 h, so the default ``spacing_factor`` 3 keeps the
bound with room (:func:`covering_radius` measures it; the MotionBenchMaker study reports it as
``rho_measured_m`` / ``bound_holds``).

What it assumes: the splats sample the surface with roughly uniform density (the median spacing
stands for the largest gap); a capture with holes (unobserved surfaces) has a larger rho than any
estimate from the spacing, and no margin covers a surface the capture does not contain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np

from ..errors import SplatplanError
from .builtin.analytic_scene import AnalyticScene
from .builtin.ellipsoid_clearance import project_to_ellipsoid
from .builtin.surface_splats import sample_faces
from .splats import Splats, quat_to_rotmat

__all__ = ["EDGE_FRACTION", "HasMinSemiAxis", "SplatMargin", "covering_radius", "derived_margin", "margin_for", "splat_spacing"]

#: Default edge resolution, as a fraction of the robot's own smallest semi-axis.
EDGE_FRACTION = 0.25

#: Means probed for the median nearest-neighbour distance (evenly strided): the median to < 1%.
_SPACING_PROBES = 20_000


class HasMinSemiAxis(Protocol):
    """What the margin reads of a robot: its smallest ellipsoid semi-axis (m), e.g. a
    :class:`~splatplan.robots.Robot`."""

    @property
    def min_semi_axis(self) -> float: ...


@dataclass(frozen=True)
class SplatMargin:
    """The safety margin of a splat scene for one robot and n_sigma (scene units).

    Attributes:
        margin: m, the distance to grow every robot ellipsoid by (``robot.inflated(margin)``).
        spacing: h, the median nearest-neighbour distance of the splat means.
        edge_resolution: r, the largest motion of any robot point between two checked
            configurations that ``margin`` assumes (plan with ``RRTConfig(edge_resolution=r)`` or
            finer).
        n_sigma: the checker's n_sigma the margin is for.
        tangential_std: s_t, the splats' median middle std (scene units), which the estimate of
            rho at another n_sigma needs (:meth:`covering_at`); None: unknown (a margin given by
            hand holds at ``n_sigma`` only).
        spacing_factor: rho(0) estimated as this x ``spacing``.
        floor_factor: the estimate of rho(n) never drops below this x ``spacing``.
    """

    margin: float
    spacing: float
    edge_resolution: float
    n_sigma: float
    tangential_std: float | None = None
    spacing_factor: float = 3.0
    floor_factor: float = 0.5

    @property
    def covering_estimate(self) -> float:
        """The margin's estimate of the covering radius rho(n_sigma): ``margin - r / 2``."""
        return self.margin - 0.5 * self.edge_resolution

    def covering_at(self, n_sigma: float) -> float | None:
        """The estimate of rho(n) at another checker n_sigma ``n`` from the same splats,
        ``max(spacing_factor h - n s_t, floor_factor h)`` (scene units): each splat's n-sigma
        ellipsoid reaches at least n s_t along the surface and closes the gaps between means.
        At the margin's own n_sigma it is :attr:`covering_estimate`; None where it cannot be
        estimated (``tangential_std`` or ``spacing`` unknown)."""
        n = float(n_sigma)
        if n == float(self.n_sigma):
            return self.covering_estimate
        h, s_t = float(self.spacing), self.tangential_std
        if s_t is None or not (math.isfinite(h) and math.isfinite(float(s_t))) or n < 0:
            return None
        return max(float(self.spacing_factor) * h - n * float(s_t), float(self.floor_factor) * h)

    @property
    def floor_n_sigma(self) -> float | None:
        """The smallest n_sigma at which :meth:`covering_at` reaches its floor,
        ``(spacing_factor - floor_factor) h / s_t``: all that a higher n_sigma can take off the
        margin (None where :meth:`covering_at` cannot estimate it; inf when s_t is 0)."""
        h, s_t = float(self.spacing), self.tangential_std
        if s_t is None or not (math.isfinite(h) and math.isfinite(float(s_t))):
            return None
        gap = max(float(self.spacing_factor) - float(self.floor_factor), 0.0) * h
        return gap / float(s_t) if s_t > 0 else (0.0 if gap == 0 else math.inf)

    def at(self, n_sigma: float) -> "SplatMargin | None":
        """The same scene's margin for a checker at ``n_sigma``: :meth:`covering_at` + r / 2 at
        the same edge resolution (None where :meth:`covering_at` is)."""
        rho = self.covering_at(n_sigma)
        if rho is None:
            return None
        return replace(self, margin=float(rho + 0.5 * self.edge_resolution), n_sigma=float(n_sigma))

    def holds(self, rho: float) -> bool:
        """Whether the guarantee holds for a measured covering radius ``rho``
        (:func:`covering_radius`): ``margin >= rho + r / 2``."""
        return bool(self.margin >= float(rho) + 0.5 * self.edge_resolution)


def splat_spacing(means: np.ndarray) -> float:
    """h: the median nearest-neighbour distance of the means (N, 3) (over ~20k of them, evenly strided)."""
    from scipy.spatial import cKDTree

    means = np.asarray(means)
    probe = means[:: max(1, len(means) // _SPACING_PROBES)]  # ~20k evenly strided means: the median to < 1% at a tenth of the cost
    d, _ = cKDTree(means).query(probe, k=2)
    return float(np.median(d[:, 1]))


def _tangential_std(scales: np.ndarray) -> float:
    """s_t: the median middle std of the splats (a surface splat's smaller tangential std)."""
    return float(np.median(np.sort(np.asarray(scales, dtype=np.float64), axis=1)[:, 1]))


def derived_margin(robot: HasMinSemiAxis, means: np.ndarray, factor: float, fraction: float = EDGE_FRACTION, *, n_sigma: float = 0.0,
                   scales: np.ndarray | None = None, floor_factor: float = 0.5) -> tuple[float, float, float]:  # fmt: skip
    """(margin m, spacing estimate h, edge resolution r), from the splats alone:
    ``m = max(factor h - n_sigma s_t, floor_factor h) + r / 2``, h = the median nearest-neighbour
    distance of the means (N, 3) (over ~20k of them, evenly strided), s_t = the median middle std
    of ``scales`` (N, 3) (a surface splat's smaller tangential std; 0 without scales), r =
    ``fraction x`` the robot's own smallest semi-axis (the resolution the planner is asked for,
    whatever the inflation).
    ``factor h`` estimates the covering radius of the surface by the means, rho(0); each splat's
    n_sigma-ellipsoid reaches at least n_sigma s_t from its mean along the surface, which closes
    the gaps between means, so rho(n_sigma) shrinks by about that much, down to the floor (the
    offsets of the means along the normal, which the flat splats do not cover).
    :func:`margin_for` is the same estimate with checked inputs and a typed result."""
    h = splat_spacing(means)
    s_t = _tangential_std(scales) if scales is not None and n_sigma > 0 else 0.0
    r = fraction * robot.min_semi_axis
    return max(factor * h - n_sigma * s_t, floor_factor * h) + 0.5 * r, h, r


def margin_for(
    splats: Splats,
    robot: HasMinSemiAxis,
    n_sigma: float = 0.0,
    *,
    edge_resolution: float | None = None,
    spacing_factor: float = 3.0,
    floor_factor: float = 0.5,
) -> SplatMargin:
    """The safety margin of ``splats`` for ``robot`` checked at ``n_sigma`` (see the module docstring).

    Args:
        splats: the scene (at least 2 splats), in the units the robot is planned in.
        robot: the robot (its smallest semi-axis sets the default edge resolution).
        n_sigma: the collision checker's n_sigma (>= 0).
        edge_resolution: r, the largest motion of any robot point between two checked
            configurations the planner will use; None: :data:`EDGE_FRACTION` x the robot's
            smallest semi-axis.
        spacing_factor: rho(0) estimated as this x the spacing h (>= 0).
        floor_factor: the estimate of rho(n_sigma) never drops below this x h (>= 0).

    Returns:
        :class:`SplatMargin` (margin m, spacing h, edge resolution r, n_sigma).

    Raises:
        SplatplanError: fewer than 2 splats, non-finite means, or a parameter out of range.
    """
    for name, v in (("n_sigma", n_sigma), ("spacing_factor", spacing_factor), ("floor_factor", floor_factor)):
        if not (isinstance(v, (int, float, np.floating, np.integer)) and math.isfinite(v) and v >= 0):
            raise SplatplanError(f"margin_for: {name} must be a finite number >= 0, got {v!r}")
    if len(splats) < 2:
        raise SplatplanError(f"margin_for: the splat spacing needs at least 2 splats, got {len(splats)}")
    means = np.asarray(splats.means, dtype=np.float64)
    if not np.all(np.isfinite(means)):
        raise SplatplanError("margin_for: the splat means hold non-finite values")
    if edge_resolution is None:
        r = EDGE_FRACTION * float(robot.min_semi_axis)
    else:
        r = float(edge_resolution)
        if not (math.isfinite(r) and r > 0):
            raise SplatplanError(f"margin_for: edge_resolution must be a finite number > 0, got {edge_resolution!r}")
    h = splat_spacing(means)
    s_t = _tangential_std(splats.scales)
    m = max(spacing_factor * h - float(n_sigma) * s_t, floor_factor * h) + 0.5 * r
    return SplatMargin(margin=float(m), spacing=h, edge_resolution=r, n_sigma=float(n_sigma), tangential_std=s_t,
                       spacing_factor=float(spacing_factor), floor_factor=float(floor_factor))  # fmt: skip


def covering_radius(scene: AnalyticScene, splats: Splats, spacing: float, n_sigma: float = 0.0, seed: int = 0, oversample: float = 3.0, k: int = 8, chunk: int = 65536) -> float:
    """Measured covering radius rho(n_sigma) (scene units) of the exposed surface of ``scene`` by the splats:
    max over dense surface samples (a grid ``oversample`` times finer than ``spacing``) of the
    Euclidean distance to the nearest splat's n_sigma-ellipsoid (``{mu + R diag(s) u, |u| <=
    n_sigma}``; at n_sigma 0 the mean itself). The nearest ellipsoid is searched among the ``k``
    nearest means (an upper bound of the min over all splats, so of rho: the safe side when
    checking ``m >= rho + r/2``); the samples underestimate the max by at most their spacing.
    Above n_sigma 0, branch and bound: samples in decreasing order of a cheap upper bound (the
    point of the nearest ellipsoids on the segment to their centre), exact distances (Newton
    projection) until no bound can beat the best."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    nb = len(scene.boxes)
    h = spacing / oversample
    x = sample_faces(scene, np.full(nb, h), np.ones((nb, 6), bool), rng, curved_spacing=h)["p"]  # (S, 3) world
    mu = np.asarray(splats.means, dtype=np.float64)
    d, idx = cKDTree(mu).query(x, k=1 if n_sigma == 0 else k)
    if n_sigma == 0:
        return float(d.max())
    rot = quat_to_rotmat(np.asarray(splats.quats, dtype=np.float64)).reshape(-1, 3, 3)  # splat -> world
    semi = n_sigma * np.maximum(np.asarray(splats.scales, dtype=np.float64), 1e-12)  # (N, 3); 2DGS disks: ~0 thick
    ub = np.empty(len(x))
    for s in range(0, len(x), chunk):  # cheap bound: |x - mu| (1 - 1 / m)+, m = x's Mahalanobis radius in units of n_sigma; min over the k
        sl = slice(s, s + chunk)
        u = np.einsum("pkji,pkj->pki", rot[idx[sl]], x[sl, None, :] - mu[idx[sl]])  # (P, k, 3) splat frames
        maha = np.linalg.norm(u / semi[idx[sl]], axis=2)  # in units of the n_sigma-ellipsoid
        ub[sl] = (d[sl] * np.clip(1.0 - 1.0 / np.maximum(maha, 1e-300), 0.0, None)).min(axis=1)
    order = np.argsort(-ub)
    best = 0.0
    for s in range(0, len(order), 4096):
        sel = order[s : s + 4096]
        if ub[sel[0]] <= best:
            break
        u = np.einsum("pkji,pkj->pki", rot[idx[sel]], x[sel, None, :] - mu[idx[sel]]).reshape(-1, 3)
        proj = project_to_ellipsoid(u, semi[idx[sel]].reshape(-1, 3))
        best = max(best, float(np.linalg.norm(u - proj, axis=1).reshape(len(sel), -1).min(axis=1).max()))
    return best
