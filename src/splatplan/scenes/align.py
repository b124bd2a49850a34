"""Put a real capture into the robot's world: find the up axis and the floor, scale, crop.

After :func:`align_scene` the scene's world frame is **z-up, floor at z = 0**, in metres when the
capture is metric (``scale`` fixes one that is not). Every splat is kept, in order, except with
``crop`` or ``drop_floaters`` (the result says how many each dropped). Rotations rotate the splats' wxyz quaternions
and scaling scales their stds (:mod:`splatplan.scenes.transforms`).

How ``up = "auto"`` works (all on the splat means, weighted by opacity):

1. **Shell rejection.** Captures are often wrapped in a far "sky shell" of huge splats. Only the
   means inside the robust box (the ``box_percentile`` .. 100 - ``box_percentile`` percentiles of
   every axis, each splat weighted by opacity / largest std^2 so that a shell of many huge splats
   hardly counts, padded by ``box_pad`` of its size) take part in the fit; the rest are reported
   as the shell (and still kept in the output). A shell of many *small* opaque splats is not
   recognised this way (the percentiles then include it; use ``crop``).
2. **Plane candidates.** A one-point RANSAC: each hypothesis is a flat splat (smallest std below
   0.3x the middle one) taken as a plane through its mean with its normal; the inliers are the
   means within ``plane_tol`` (a fraction of the robust box's diagonal) whose own normal, when
   flat, agrees within 25 degrees. The best plane is refined by a weighted least-squares fit on
   its inliers, removed, and the search repeats (``n_planes`` planes).
3. **Support planes.** A floor (or the table under an object) has the scene on one side and
   the scene's mass over it: a candidate has at most ``max_below`` of the robust mass beyond it
   (a *bounding* plane, its normal oriented towards the scene) **and** at least ``min_coverage``
   of the off-plane mass projects inside the convex hull of its inliers (a table disc covers the
   house on it, the hidden patch under the house included; a chair's back, also a bounding
   plane, leaves the seat and the legs hanging beyond its edges and is no support).
4. **Choice, or a refusal.** Rooms have several supports (floor, ceiling, walls). Each scores
   ``mass * coverage * (0.25 + max(0, n . up_hint))``: its share of the splat mass, favouring the
   capture convention's up axis (``up_hint``, default ``-y`` for INRIA/COLMAP-style y-down
   captures) as a tie-break between perpendicular planes. The margin is
   ``1 - runner_up / best`` over the supports more than 30 degrees from the best. ``up = auto``
   **refuses** (:class:`AlignmentRefused`, asking for ``--up``) rather than guess when no plane
   supports the scene, when the best support is more than ``max_hint_angle`` from the capture
   convention (a wall behind a fixture, or a file in another convention) or when the margin is
   below ``min_margin`` (two planes could be the floor). The confidence reported is
   ``one_sided * coverage * margin``; ``hint_decides`` says when only the convention separated
   the best from the runner-up.

The floor height is the opacity-weighted median height of the chosen plane's inliers after the
rotation (so the floor's splats straddle z = 0). With an explicit ``up`` axis the floor is the
densest bounding layer perpendicular to it (the same candidates, restricted to normals within
10 degrees of the axis).

**Wall fixtures** (``wall``, e.g. a shower tap): the largest bounding plane within 30 degrees of
vertical is the wall; up is ``up`` when given, else the capture convention's up made exactly
parallel to the wall; the wall's normal (pointing out of the wall, towards the fixture) is turned
to the ``wall`` axis and the wall moved to 0 along it.

**Background shells** (:func:`~splatplan.scenes.filters.far_shell_mask`: splats beyond a wide
empty gap in the distances from the scene's centre, e.g. a 240 m sphere around a 1 m object) are
dropped from the output unless ``keep_shell``; the result counts them.

What it cannot do: know an object's up without a support plane (a chair without its floor, a
person: ``up = auto`` refuses and asks for ``--up``), see a sloped floor (one plane), or find the
up of a room captured in another convention than ``up_hint`` (it refuses; give ``--up``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from .._config import bounded, check_config
from ..errors import SplatplanError
from .floor import floor_surface_mask, splat_normals
from .conventions import capture_convention
from .filters import far_shell_mask, floater_mask, isolated_mask
from .planes import Plane, describe_plane, fit_planes, nearest_axis, robust_box, rotation_to_z, shell_weights, support_coverage
from .splats import Splats
from .transforms import apply_rigid, scale as scale_scene

#: axis names accepted by ``up`` / ``up_hint`` -> unit vectors
AXES = {
    "+x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0), "+y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0), "+z": (0.0, 0.0, 1.0), "-z": (0.0, 0.0, -1.0),
    "x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0),
}  # fmt: skip


#: the largest coordinate (input units) of a floor height, a translation or a crop corner: float32
#: positions lose all sub-unit precision beyond it (and overflow at 3e38)
MAX_ALIGN_COORD = 1e9
#: the largest scale factor (and 1 / the smallest) of ``scale align --scale``
MAX_ALIGN_SCALE = 1e6


@dataclass
class AlignConfig:
    """Options of :func:`align_scene` (the flags of ``splatplan scene align``)."""

    #: the scene's up axis: auto (normal of the dominant bounding plane, see the module doc) or
    #: +x, -x, +y, -y, +z, -z (INRIA/COLMAP captures are usually -y)
    up: str = bounded("auto", choices=("auto", "+x", "-x", "+y", "-y", "+z", "-z", "x", "y", "z"))
    #: floor height: auto (fitted, moved to z = 0), none (no vertical shift), or a number: the
    #: floor's height along the up axis in the input's units (moved to z = 0)
    floor: str = "auto"
    #: uniform scale applied after the rotation (e.g. to make a normalised capture metric)
    scale: float = bounded(1.0, gt=0)
    #: rotation about the new z axis (degrees), after the up rotation
    rotate_z: float = 0.0
    #: translation X,Y,Z (output units) added last
    translate: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: keep only splats whose aligned mean lies in this box LO..HI (6 numbers: x0,y0,z0,x1,y1,z1;
    #: none keeps every splat)
    crop: tuple[float, ...] | None = None
    #: drop faint isolated splats, floaters in free space (opacity < 0.3 and mean 8-NN distance above
    #: 3x the scene's median; the floor's flat splats left out, scenes/floor.py floor_surface_mask; scenes/filters.py
    #: isolated_mask); the count is reported
    drop_floaters: bool = False
    #: keep a detected background shell (far splats beyond an empty gap, scenes/filters.py
    #: far_shell_mask); by default it is dropped and counted
    keep_shell: bool = False
    #: wall fixture: turn the largest wall-like plane's normal (out of the wall) to this axis and move
    #: the wall to 0 along it; up from ``up`` or the capture convention (none: no wall alignment)
    wall: str = bounded("none", choices=("none", "+x", "-x", "+y", "-y"))
    #: auto up: the capture convention that breaks ties between perpendicular bounding planes
    up_hint: str = bounded("-y", choices=("+x", "-x", "+y", "-y", "+z", "-z", "x", "y", "z"))
    #: robust box: per-axis percentile of the means that bounds the fit (and info's robust bounds)
    box_percentile: float = bounded(1.0, ge=0, le=25)
    #: robust box: padding as a fraction of the box's size on each side
    box_pad: float = bounded(0.1, ge=0, le=10)
    #: plane inlier distance, as a fraction of the robust box's diagonal
    plane_tol: float = bounded(0.005, ge=1e-6, le=0.5)
    #: number of planes extracted by the sequential RANSAC
    n_planes: int = bounded(6, ge=1, le=64)
    #: a bounding plane has at most this fraction of the robust mass beyond it
    max_below: float = bounded(0.1, ge=0, le=0.5)
    #: a plane needs at least this fraction of the robust splat mass
    min_plane_mass: float = bounded(0.02, ge=0, le=1)
    #: auto up: a support plane has at least this fraction of the off-plane mass over its inliers' hull
    min_coverage: float = bounded(0.6, ge=0, le=1)
    #: auto up: refuse when 1 - runner_up / best score is below this (two planes could be the floor)
    min_margin: float = bounded(0.3, ge=0, le=1)
    #: auto up: refuse when the best support's normal is further than this from up_hint (degrees)
    max_hint_angle: float = bounded(45.0, ge=0, le=180)
    #: means used by the fit (a seeded random subset of the robust box)
    max_points: int = bounded(30000, ge=1, le=10_000_000)
    #: RANSAC hypotheses per plane
    n_hypotheses: int = bounded(800, ge=1, le=1_000_000)
    #: random seed of the subset and the RANSAC
    seed: int = bounded(0, ge=0, le=2**32 - 1)

    def validate(self) -> "AlignConfig":
        """Raise :class:`SplatplanError` naming the first bad field."""
        check_config(self)  # declared ranges, choices and finiteness
        if self.up != "auto" and self.up not in AXES:
            raise SplatplanError(f"up {self.up!r}: use auto or one of +x, -x, +y, -y, +z, -z")
        if self.up_hint not in AXES:
            raise SplatplanError(f"up_hint {self.up_hint!r}: use one of +x, -x, +y, -y, +z, -z")
        if self.floor not in ("auto", "none"):
            try:
                z = float(self.floor)
            except ValueError:
                raise SplatplanError(f"floor {self.floor!r}: use auto, none or a number") from None
            if not np.isfinite(z):
                raise SplatplanError(f"floor {self.floor!r} must be finite")
            if abs(z) > MAX_ALIGN_COORD:
                raise SplatplanError(f"floor {self.floor!r} must be within +-{MAX_ALIGN_COORD:g} (input units)")
        if not (np.isfinite(self.scale) and 1.0 / MAX_ALIGN_SCALE <= self.scale <= MAX_ALIGN_SCALE):
            raise SplatplanError(f"scale must be a number in [{1.0 / MAX_ALIGN_SCALE:g}, {MAX_ALIGN_SCALE:g}], got {self.scale}")
        if not (np.isfinite(self.rotate_z) and abs(self.rotate_z) <= 3600.0):
            raise SplatplanError(f"rotate_z must be a finite angle within +-3600 degrees, got {self.rotate_z}")
        t = np.asarray(self.translate, np.float64)
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise SplatplanError(f"translate must be 3 finite numbers X,Y,Z, got {self.translate}")
        if np.any(np.abs(t) > MAX_ALIGN_COORD):
            raise SplatplanError(f"translate must be within +-{MAX_ALIGN_COORD:g}, got {self.translate}")
        if self.crop is not None:
            c = np.asarray(self.crop, np.float64)
            if c.shape != (6,) or not np.all(np.isfinite(c)) or np.any(c[3:] <= c[:3]) or np.any(np.abs(c) > MAX_ALIGN_COORD):
                raise SplatplanError(f"crop must be 6 finite numbers x0,y0,z0,x1,y1,z1 with LO < HI, got {self.crop}")
        for name, lo, hi in (("box_percentile", 0.0, 25.0), ("box_pad", 0.0, 10.0), ("plane_tol", 1e-6, 0.5), ("max_below", 0.0, 0.5), ("min_plane_mass", 0.0, 1.0)):
            v = getattr(self, name)
            if not (np.isfinite(v) and lo <= v <= hi):
                raise SplatplanError(f"{name} must lie in [{lo:g}, {hi:g}], got {v}")
        for name in ("n_planes", "max_points", "n_hypotheses"):
            if int(getattr(self, name)) < 1:
                raise SplatplanError(f"{name} must be >= 1, got {getattr(self, name)}")
        return self


class AlignmentRefused(SplatplanError):
    """``up = auto`` will not guess: no plane supports the scene, the best one disagrees with the
    capture convention, or two planes could be the floor. The message says which and asks for
    ``--up``; ``candidates`` holds the bounding planes that were weighed (input frame)."""

    def __init__(self, message: str, candidates: list[Plane] | None = None):
        super().__init__(message)
        self.candidates = list(candidates or [])


@dataclass
class UpGuess:
    """Result of :func:`guess_up`: the up axis and the floor in the input frame."""

    up: np.ndarray  # (3,) unit vector, input frame
    floor_height: float  # floor height along ``up`` (input units)
    confidence: float  # 0..1 (see the module docstring)
    plane: Plane | None  # the chosen plane (None when the axis was given and no plane matched)
    candidates: list[Plane]  # every bounding plane considered
    method: str
    margin: float = 1.0  # 1 - runner_up / best score over the supports (1: no rival; auto only)
    hint_decides: bool = False  # only the capture convention (up_hint) separated best and runner-up

    def to_json(self) -> dict:
        return {
            "up": np.round(self.up, 6).tolist(),
            "up_axis": nearest_axis(self.up),
            "floor_height": round(float(self.floor_height), 6),
            "confidence": round(float(self.confidence), 3),
            "margin": round(float(self.margin), 3),
            "hint_decides": bool(self.hint_decides),
            "method": self.method,
            "plane_mass": None if self.plane is None else round(self.plane.mass, 4),
            "plane_coverage": None if self.plane is None else round(self.plane.coverage, 3),
            "n_bounding_planes": len(self.candidates),
        }


@dataclass
class AlignResult:
    """What :func:`align_scene` did: ``x_out = scale * R x_in + t`` for the kept splats."""

    transform: np.ndarray  # (4, 4) float64 similarity [[s R, t], [0, 1]], output <- input
    scale: float
    up: UpGuess | None
    n_in: int
    n_out: int
    n_cropped: int
    n_shell: int
    config: AlignConfig
    n_floaters: int = 0
    n_shell_dropped: int = 0  # background-shell splats dropped (0 with keep_shell)
    wall: dict | None = None  # the wall of ``wall`` alignment (WallFit.to_json), None otherwise

    def floor_z(self) -> float | None:
        """The floor's height in the output (output units): ``translate``'s z when the floor was
        fitted or given, None with ``floor = none`` (z = 0 is then the input's origin)."""
        return None if self.config.floor == "none" else float(self.config.translate[2])

    def frame_text(self) -> str:
        """One line: the output frame (up, floor, wall, units)."""
        fz = self.floor_z()
        floor = "floor not moved (z = 0 is the input's origin along up)" if fz is None else f"floor at z = {fz:g}"
        wall = "" if self.wall is None else f", wall normal {self.wall['axis']} with the wall at 0 along it"
        return f"z-up, {floor}{wall}, units = input units * {self.scale:g}"

    def to_json(self) -> dict:
        return {
            "transform": np.round(self.transform, 9).tolist(),
            "scale": float(self.scale),
            "convention": "x_out = T @ [x_in, 1] (T = [[scale * R, t], [0, 1]]); quaternions q_out = q_R * q_in (wxyz); stds * scale",
            "frame": self.frame_text(),
            "up": None if self.up is None else self.up.to_json(),
            "n_in": self.n_in,
            "n_out": self.n_out,
            "n_cropped": self.n_cropped,
            "n_floaters_dropped": self.n_floaters,
            "n_shell_dropped": self.n_shell_dropped,
            "n_shell_outside_robust_box": self.n_shell,
            "wall": self.wall,
            "options": {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self.config).items()},
        }


def _choose_support(bounding: list[Plane], cfg: AlignConfig) -> tuple[Plane, float, float, bool]:
    """(best plane, confidence, margin, hint_decides) of ``up = auto``; raises :class:`AlignmentRefused`."""
    hint = np.asarray(AXES[cfg.up_hint], np.float64)
    ask = "give the up axis with --up (+x, -x, +y, -y, +z, -z; --png draws what you get)"
    if not bounding:
        raise AlignmentRefused(
            "no plane to align to: no large plane bounds the scene (an object scan without a table or floor?); "
            f"{ask} and the floor with --floor Z or --floor none"
        )
    supports = [p for p in bounding if p.coverage >= cfg.min_coverage]
    if not supports:
        p = max(bounding, key=lambda q: q.mass)
        raise AlignmentRefused(
            f"no plane supports the scene: the largest one-sided plane ({describe_plane(p)}) leaves "
            f"{1 - p.coverage:.0%} of the rest hanging beyond its edges (a chair's back or a wall, not a floor); "
            f"{ask}; the capture convention says {cfg.up_hint}", bounding)  # fmt: skip

    def score(p: Plane, with_hint: bool = True) -> float:
        return p.mass * p.coverage * ((0.25 + max(0.0, float(p.normal @ hint))) if with_hint else 1.0)

    def margin_of(best: Plane, with_hint: bool) -> float:
        rivals = [score(p, with_hint) for p in supports if float(p.normal @ best.normal) < np.cos(np.radians(30.0))]
        return 1.0 - (max(rivals) / score(best, with_hint) if rivals else 0.0)

    best = max(supports, key=score)
    angle = float(np.degrees(np.arccos(np.clip(best.normal @ hint, -1.0, 1.0))))
    if angle > cfg.max_hint_angle:
        raise AlignmentRefused(
            f"the only clear support plane ({describe_plane(best)}) is {angle:.0f} degrees from the capture convention's "
            f"up ({cfg.up_hint}): a chair's back, a wall behind a fixture (then use --wall) or the floor of a file in another "
            f"convention (then --up {nearest_axis(best.normal)}; check with --png)", bounding)  # fmt: skip
    margin = margin_of(best, True)
    if margin < cfg.min_margin:
        rival = max((p for p in supports if p is not best and float(p.normal @ best.normal) < np.cos(np.radians(30.0))), key=score)
        raise AlignmentRefused(
            f"ambiguous up: two planes could be the floor ({describe_plane(best)}; {describe_plane(rival)}; "
            f"margin {margin:.2f} < {cfg.min_margin:g}); {ask}", bounding)  # fmt: skip
    plain_best = max(supports, key=lambda p: score(p, False))
    hint_decides = plain_best is not best or margin_of(best, False) < cfg.min_margin
    return best, best.one_sided * best.coverage * margin, margin, hint_decides


def guess_up(splats: Splats, config: AlignConfig | None = None) -> UpGuess:
    """The up axis and floor height of a scene in its own frame (see the module docstring).

    Raises:
        AlignmentRefused: ``up = auto`` and no plane supports the scene, the best one disagrees
            with ``up_hint`` or two planes could be the floor (the message asks for ``--up``).
    """
    cfg = (config or AlignConfig()).validate()
    m, w, bounding = _bounding_planes(splats, cfg)
    margin, hint_decides = 1.0, False
    plane: Plane | None
    if cfg.up == "auto":
        plane, conf, margin, hint_decides = _choose_support(bounding, cfg)
        up, method = plane.normal, "support-plane"
        floor = _floor_along(up, plane, m, w, cfg)
    else:
        up = np.asarray(AXES[cfg.up], np.float64)
        floor, plane = _floor_for_axis(up, bounding, m, w, cfg)
        conf, method = 1.0, "given"
    return UpGuess(np.asarray(up, np.float64), float(floor), float(conf), plane, bounding, method, float(margin), hint_decides)


def _bounding_planes(splats: Splats, cfg: AlignConfig) -> tuple[np.ndarray, np.ndarray, list[Plane]]:
    """(fit means (M, 3), weights (M,), bounding planes with their coverage): steps 1-3 of the module doc."""
    if len(splats) < 10:
        raise SplatplanError(f"cannot fit a floor to {len(splats)} splat(s); give --up and --floor")
    lo, hi, inside = robust_box(splats.means, cfg.box_percentile, cfg.box_pad, shell_weights(splats))
    idx = np.flatnonzero(inside)
    rng = np.random.default_rng(cfg.seed)
    if len(idx) > cfg.max_points:
        idx = np.sort(rng.choice(idx, cfg.max_points, replace=False))
    normals, flat = splat_normals(splats.subset(idx))
    m = splats.means[idx].astype(np.float64)
    w = splats.opacities[idx].astype(np.float64)
    tol = cfg.plane_tol * float(np.linalg.norm(hi - lo))
    planes = fit_planes(m, normals, flat, w, tol, cfg.n_planes, cfg.n_hypotheses, cfg.seed)
    bounding = [p for p in planes if p.one_sided >= 1.0 - cfg.max_below and p.mass >= cfg.min_plane_mass]
    for p in bounding:
        p.coverage = support_coverage(m, w, p, tol)
    return m, w, bounding


def _floor_for_axis(up: np.ndarray, bounding: list[Plane], m: np.ndarray, w: np.ndarray, cfg: AlignConfig) -> tuple[float, Plane | None]:
    """(floor height along ``up``, its plane or None): the densest bounding plane within 10 degrees
    of ``up``, else the robust bottom of the scene (the ``box_percentile`` percentile along up)."""
    match = [p for p in bounding if float(p.normal @ up) > np.cos(np.radians(10.0))]
    plane = max(match, key=lambda p: p.mass) if match else None
    return _floor_along(up, plane, m, w, cfg), plane


def _floor_along(up: np.ndarray, plane: Plane | None, m: np.ndarray, w: np.ndarray, cfg: AlignConfig) -> float:
    if plane is not None:  # the opacity-weighted median height of the plane's inliers
        return _weighted_median(m[plane.inliers] @ up, w[plane.inliers])
    return float(np.percentile(m @ up, cfg.box_percentile))


@dataclass
class WallFit:
    """The wall of ``wall`` alignment (input frame): the plane, its horizontal normal, the up axis used."""

    plane: Plane  # the wall (normal towards the fixture)
    normal: np.ndarray  # (3,) unit, the wall's normal made perpendicular to ``up``
    offset: float  # the wall's position along ``normal`` (input units; weighted median of its inliers)
    up: np.ndarray  # (3,) unit, input frame
    up_source: str  # "given" or "capture convention <axis>"

    def to_json(self, axis: str) -> dict:
        return {"axis": axis, "normal_in": np.round(self.normal, 6).tolist(), "offset_in": round(float(self.offset), 6),
                "plane_mass": round(self.plane.mass, 4), "up_source": self.up_source}  # fmt: skip


def fit_wall(splats: Splats, config: AlignConfig | None = None) -> tuple[WallFit, UpGuess]:
    """The wall of a wall-fixture capture and the up axis (see ``wall`` in the module docstring).

    Returns:
        (the wall, an :class:`UpGuess` with the floor along up: a floor plane when one bounds the
        scene, else the robust bottom of the scene).

    Raises:
        AlignmentRefused: no large one-sided plane within 30 degrees of vertical, or (up from the
            capture convention) the wall is nearly perpendicular to the convention's up.
    """
    cfg = (config or AlignConfig()).validate()
    m, w, bounding = _bounding_planes(splats, cfg)
    given = cfg.up != "auto"
    up0 = np.asarray(AXES[cfg.up if given else cfg.up_hint], np.float64)
    src = "given" if given else f"capture convention {cfg.up_hint}"
    walls = [p for p in bounding if abs(float(p.normal @ up0)) < np.sin(np.radians(30.0))]
    if not walls:
        seen = "; ".join(describe_plane(p) for p in bounding) or "none"
        raise AlignmentRefused(f"no wall: no large one-sided plane within 30 degrees of vertical (up {nearest_axis(up0)}, {src}); "
                               f"bounding planes: {seen}; give the up axis with --up", bounding)  # fmt: skip
    wall = max(walls, key=lambda p: p.mass)
    n = wall.normal
    up = up0 if given else up0 - float(up0 @ n) * n  # the convention's up made parallel to the wall
    up = up / np.linalg.norm(up)
    h = n - float(n @ up) * up
    h = h / np.linalg.norm(h)
    offset = _weighted_median(m[wall.inliers] @ h, w[wall.inliers])
    floor, plane = _floor_for_axis(up, bounding, m, w, cfg)
    return WallFit(wall, h, offset, up, src), UpGuess(up, floor, 1.0, plane, bounding, f"wall (up {src})")


def _rz(angle: float) -> np.ndarray:
    """(3, 3) rotation by ``angle`` radians about +z."""
    c, sn = np.cos(angle), np.sin(angle)
    return np.array([[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]])


def _weighted_median(x: np.ndarray, w: np.ndarray) -> float:
    o = np.argsort(x)
    cw = np.cumsum(w[o])
    return float(x[o][np.searchsorted(cw, 0.5 * cw[-1])])


def align_scene(splats: Splats, config: AlignConfig | None = None) -> tuple[Splats, AlignResult]:
    """Rotate the scene's up axis to +z, move the floor to z = 0, scale, rotate about z, translate, crop.

    ``x_out = s R x_in + t`` with R = Rz(rotate_z) R_up (R_up the smallest rotation taking up to
    +z), s = ``scale``, t = Rz-rotated, scaled floor shift plus ``translate``. Splats keep their
    order; ``crop`` drops those outside the box (counted in the result).

    Raises:
        SplatplanError: bad options, no plane to align to, or a transform that puts the whole
            scene below the floor (z < 0).
    """
    cfg = (config or AlignConfig()).validate()
    if len(splats) == 0:
        raise SplatplanError("the scene has no splats")
    shell = far_shell_mask(splats.means)
    core = splats.subset(~shell) if shell.any() else splats  # the fit never sees the shell
    guess, wall = None, None
    if cfg.wall != "none":
        wall, guess = fit_wall(core, cfg)
        up = wall.up
    elif cfg.up == "auto" or cfg.floor == "auto":
        guess = guess_up(core, cfg)
        up = guess.up
    else:
        up = np.asarray(AXES[cfg.up], np.float64)
    if cfg.floor == "auto":
        assert guess is not None  # (floor "auto" takes one of the guessing branches above)
        floor = guess.floor_height
    elif cfg.floor == "none":
        floor = 0.0
    else:
        floor = float(cfg.floor)
    r = rotation_to_z(up)
    s = float(cfg.scale)
    t = np.array([0.0, 0.0, -s * floor])
    if wall is not None:  # turn the wall's normal to the wall axis, the wall to 0 along it
        axis = np.asarray(AXES[cfg.wall], np.float64)
        h = r @ wall.normal
        turn = np.arctan2(axis[1], axis[0]) - np.arctan2(h[1], h[0])
        r = _rz(turn) @ r
        t = t - s * wall.offset * axis
    rz = _rz(np.radians(cfg.rotate_z))
    r = rz @ r
    t = rz @ t + np.asarray(cfg.translate, np.float64)
    src = splats.subset(~shell) if shell.any() and not cfg.keep_shell else splats
    out = scale_scene(apply_rigid(src, r, np.zeros(3)), s)
    out = apply_rigid(out, np.eye(3), t)
    _, _, inside = robust_box(out.means, cfg.box_percentile, cfg.box_pad, shell_weights(out))
    z90 = float(np.percentile(out.means[inside, 2], 90.0))
    if z90 < 0.0:
        raise SplatplanError(
            f"the transform puts the scene below the floor (90% of the splats under z = {z90:.3g}); check --up (its sign), --floor and --translate"
        )
    n_floaters = 0
    if cfg.drop_floaters:
        # the floor's surface is left out of the test (its own splats and their neighbours), the rest of
        # the step band is not: a faint upright splat standing alone on the floor blocks a ground robot
        on_floor = floor_surface_mask(out, 0.0, 0.05 * s) if cfg.floor != "none" else np.zeros(len(out), bool)
        iso = isolated_mask(out.means, out.opacities, candidates=~on_floor)
        n_floaters = int(iso.sum())
        out = out.subset(~iso)
    n_cropped = 0
    if cfg.crop is not None:
        c = np.asarray(cfg.crop, np.float64)
        keep = np.all((out.means >= c[:3]) & (out.means <= c[3:]), axis=1)
        n_cropped = int((~keep).sum())
        if not keep.any():
            raise SplatplanError(f"crop {list(cfg.crop)} keeps no splat; the aligned scene spans {out.means.min(0).round(3).tolist()} .. {out.means.max(0).round(3).tolist()}")
        out = out.subset(keep)
    transform = np.eye(4)
    transform[:3, :3] = s * r
    transform[:3, 3] = t
    n_shell = 0 if cfg.keep_shell else int(shell.sum())
    wall_doc = None if wall is None else wall.to_json(cfg.wall)
    res = AlignResult(transform, s, guess, len(splats), len(out), n_cropped, int((~inside).sum()), cfg, n_floaters, n_shell, wall_doc)
    out.info["align"] = res.to_json()
    return out, res


def oversized_splats(splats: Splats, fraction: float = 0.25, percentile: float = 1.0) -> np.ndarray:
    """(N,) bool: splats whose largest std exceeds ``fraction`` of the robust box's diagonal (e.g.
    a 2 m std in a 0.5 m scene): sky-shell or broken splats that a collision query would see as
    huge obstacles. Scene-relative sizes only; values no sane file has (non-finite-looking
    coordinates, zero-volume 3D splats) are :func:`splatplan.scenes.sanity.absurd_splats`."""
    lo, hi, _ = robust_box(splats.means, percentile, 0.0, shell_weights(splats))
    return splats.scales.max(axis=1) > fraction * float(np.linalg.norm(hi - lo))


def default_up_hint(path) -> str:
    """The ``up_hint`` for a scene file: ``+z`` when splatplan wrote it (a ``.align.json`` or
    ``.gt.json`` sidecar beside it) or a nerfstudio ``.ply`` header says so, else ``-y`` (the
    INRIA/COLMAP convention); :func:`splatplan.scenes.conventions.capture_convention`."""
    return capture_convention(path)[0]


def describe_frame(splats: Splats, config: AlignConfig | None = None) -> dict:
    """Frame facts for ``splatplan info``: robust bounds, up/floor guess, shell, scale note,
    transparency and absurd splats (a JSON-ready dict; notes and warnings as sentences)."""
    cfg = config or AlignConfig()
    m = splats.means.astype(np.float64)
    w = shell_weights(splats)
    lo1, hi1, _ = robust_box(m, cfg.box_percentile, 0.0, w)
    blo, bhi, inside = robust_box(m, cfg.box_percentile, cfg.box_pad, w)
    centre = 0.5 * (lo1 + hi1)
    out_r = np.linalg.norm(m[~inside] - centre, axis=1)
    d: dict = {
        "robust_bounds_min": lo1.round(6).tolist(),
        "robust_bounds_max": hi1.round(6).tolist(),
        "robust_percentiles": [cfg.box_percentile, 100.0 - cfg.box_percentile],
        "shell": {
            "count": int((~inside).sum()),
            "radius_median": float(np.median(out_r)) if len(out_r) else None,
            "radius_max": float(out_r.max()) if len(out_r) else None,
            "rule": f"means outside the {cfg.box_percentile:g}-{100 - cfg.box_percentile:g} percentile box (weighted by opacity / std^2) padded by {cfg.box_pad:g} of its size",
        },
        "warnings": [],
    }
    far = far_shell_mask(m)
    far_r = np.linalg.norm(m[far] - np.median(m, axis=0), axis=1)
    d["background_shell"] = {
        "count": int(far.sum()),
        "radius_median": float(np.median(far_r)) if far.any() else None,
        "rule": "splats beyond the first wide empty gap in the distances from the scene's centre (scenes/filters.py far_shell_mask); "
                "`splatplan scene align` drops them (--keep-shell keeps them)",
    }  # fmt: skip
    core = splats.subset(~far) if far.any() else splats
    try:
        g = guess_up(core, cfg)
        d["up_guess"] = g.to_json()
        height = float(np.percentile(m[inside] @ g.up, 100.0 - cfg.box_percentile) - g.floor_height)
        d["height_above_floor"] = height
    except SplatplanError as exc:
        g, height = None, None
        d["up_guess"] = None
        d["up_note"] = str(exc)
    ext = float(np.max(hi1 - lo1))
    if g is not None and height is not None and 1.8 <= height <= 4.5 and g.confidence > 0.3:
        note = f"looks metric: {height:.2f} units from the floor to the top, a room's height in metres"
    elif 0.5 <= ext <= 5.0 and g is None:
        note = f"cannot tell: the robust extent is {ext:.3g} units (an object in metres and a normalised capture look alike); use --scale if you know a size"
    elif ext < 0.5:
        note = f"small: the robust extent is {ext:.3g} units (a metric object, or mm/cm units would be far larger)"
    elif ext > 200:
        note = f"large: the robust extent is {ext:.3g} units (millimetres or a city-scale capture?)"
    else:
        note = f"plausibly metric: robust extent {ext:.3g} units; check one known size (a door is ~2 m)"
    d["scale_note"] = note
    transparent = float(np.mean(splats.opacities < 0.1))
    d["transparent_fraction"] = transparent
    if np.median(splats.opacities) < 0.1:
        d["warnings"].append(f"most splats are nearly transparent (median opacity {float(np.median(splats.opacities)):.3g}; {transparent:.0%} below 0.1): "
                             "opacity may be stored as a logit or the file is mostly haze; collision checks may see little")  # fmt: skip
    if far.any():
        d["warnings"].append(f"a background shell of {int(far.sum()):,} splat(s) at median radius {d['background_shell']['radius_median']:.3g} units: "
                             "`splatplan scene align IN --out OUT.ply` drops it (--keep-shell keeps it)")  # fmt: skip
    absurd = oversized_splats(splats, percentile=cfg.box_percentile)
    d["absurd_splats"] = int(absurd.sum())
    rest = absurd & ~far
    if rest.any():
        faint = int((rest & floater_mask(splats.opacities, splats.scales)[0]).sum())
        how = (f"{faint} of them are faint and large: the default floater filter drops those when a scene is loaded; " if faint else "") + (
            "remove the others with `splatplan scene align IN --out OUT.ply --crop LO HI` (a box in the aligned frame)" if faint < int(rest.sum()) else "")
        d["warnings"].append(f"{int(rest.sum())} absurd splat(s) outside any background shell: largest std up to {float(splats.scales[rest].max()):.3g} units "
                             f"in a scene of robust extent {ext:.3g}; {how}".rstrip("; "))  # fmt: skip
    return d
