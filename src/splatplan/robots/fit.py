"""Enclosing ellipsoids for robot links: analytic for primitives, fitted to meshes, YAML I/O.

An ellipsoid is (centre c (3,), rotation R (3, 3) link <- ellipsoid frame, semi-axes s (3,)), all
in the link frame, metres. A point x lies inside when |diag(1/s) R^T (x - c)| <= 1.

Per link:

* ``<sphere>``, ``<cylinder>`` and ``<capsule>`` elements each get their own analytic enclosing
  ellipsoid (the minimum-volume one among ellipsoids sharing the primitive's axes).
* ``<box>`` elements and meshes are polytopes: their vertices (box corners, mesh vertices) are
  pooled per link and enclosed by k ellipsoids. k = 1: the minimum-volume enclosing ellipsoid of
  the convex hull vertices (Khachiyan's algorithm). k > 1: the link is cut into k slabs of equal
  width along its principal axis; each slab's ellipsoid encloses the vertices inside it plus the
  points where mesh edges cross the slab's bounding planes, so the union of the k ellipsoids
  contains every point of every triangle (and hence the solid), not only the vertices.
* Guarantee: after Khachiyan's iterations stop, every ellipsoid is rescaled by its largest
  Mahalanobis radius over its points (times 1 + 1e-9), so each point it must contain lies inside
  exactly, whatever the tolerance. ``tests/robots`` re-checks the shipped YAML files.

Three methods (``fit_model(method=...)``; the default is ``"split"``):

* ``"opt"``: per link, a few ellipsoids optimised together (gradient descent on the volume outside
  the mesh, a coverage hinge and a reach hinge) and then certified to contain the link's meshes
  and boxes (:mod:`splatplan.robots.fit_opt`); ``load_robot`` fits URDFs this way by default.
* ``"cover"``: per link, a greedy union of candidate ellipsoids, certified the same way
  (:mod:`splatplan.robots.fit_cover`). The fit quality of any model is measured by
  :mod:`splatplan.robots.fit_measure`.
* ``"split"``: the enclosing ellipsoids described below (k per link; k = 1 is the coarse model).

The volume ratio of a link is (volume of the union of its ellipsoids; Monte Carlo when there are
several) / (sum of its collision elements' volumes; a mesh that is not watertight counts with its
convex hull): 1 is a perfect fit; overlaps between collision elements make it slightly optimistic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast

import numpy as np

from .._progress import progress
from .._resources import require_work
from ..errors import SplatplanError
from .ellipsoid import CONTAIN_EPS, ellipsoid_volume, mahalanobis, mvee, union_volume  # noqa: F401 (re-exported)
from . import fit_cover, fit_opt  # called through the modules: tests replace a fitter with monkeypatch
from .solids import check_size, mesh_volume, polytope
from .urdf import Geom, UrdfModel

#: the old private name of :func:`~splatplan.robots.solids.polytope` (benchmarks and tests read it)
_polytope = polytope

#: Most ellipsoids per link: each is an iterative MVEE fit of one slab (and the volume report is a
#: Monte Carlo over all of them), so k = 100,000 would run for hours; slabs this thin are already
#: finer than any link mesh's detail.
MAX_PER_LINK = 64
#: the most ellipsoids one fit makes (all links together): the work guard of a URDF with
#: thousands of links (the optimised fit takes seconds per link)
MAX_FIT_ELLIPSOIDS = 1024


@dataclass
class EllipsoidSet:
    """E ellipsoids attached to links (link frame) plus a per-link fit report."""

    link: list[str]  # (E,) link names
    center: np.ndarray  # (E, 3) link frame, metres
    rot: np.ndarray  # (E, 3, 3) link <- ellipsoid frame
    semi_axes: np.ndarray  # (E, 3) metres
    report: dict[str, dict] = field(default_factory=dict)  # link -> {source, n, geometry_volume, ellipsoid_volume, volume_ratio}
    skipped: list[str] = field(default_factory=list)  # links without geometry (no ellipsoid)

    @property
    def n(self) -> int:
        return len(self.link)


# --------------------------------------------------------------------------- fitting primitives


def _cylinder_like(radius: float, half: float, cap: float) -> tuple[float, float]:
    """Semi-axes (a, c) of the minimum-volume z-aligned ellipsoid enclosing a capsule (cap = r)
    or a cylinder (cap = 0) of radius r and half-length ``half`` of its straight part."""
    if cap == 0.0:
        return radius * math.sqrt(1.5), half * math.sqrt(3.0)
    z = np.linspace(0.0, cap, 4001)  # hemisphere profile above the straight part
    x2 = np.maximum(radius**2 - z**2, 0.0)
    best = None
    for cz in np.geomspace((half + cap) * (1 + 1e-6), (half + cap) * 20.0, 4000):
        a2 = float(np.max(x2 / (1.0 - ((half + z) / cz) ** 2)))
        v = a2 * cz
        if best is None or v < best[0]:
            best = (v, math.sqrt(a2), cz)
    assert best is not None  # (the loop above runs 4000 times)
    _, a, cz = best
    return a * (1.0 + 1e-4), cz  # 1e-4 margin covers the sampling of the profile


def primitive_ellipsoid(g: Geom) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Enclosing ellipsoid of a sphere/cylinder/capsule/box in the link frame + the primitive's volume.

    The primitive's extreme points lie on the ellipsoid's surface; semi-axes get the relative
    margin CONTAIN_EPS so float rounding never puts them outside.
    """
    c, r, s, v = _primitive_ellipsoid(g)
    return c, r, s * (1.0 + CONTAIN_EPS), v


def _primitive_ellipsoid(g: Geom) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    rot, ctr = g.origin[:3, :3], g.origin[:3, 3]
    if g.kind == "sphere":
        r = float(g.size[0])
        return ctr.copy(), rot.copy(), np.full(3, r), 4.0 / 3.0 * math.pi * r**3
    if g.kind == "cylinder":
        r, ln = float(g.size[0]), float(g.size[1])
        a, c = _cylinder_like(r, ln / 2.0, 0.0)
        return ctr.copy(), rot.copy(), np.array([a, a, c]), math.pi * r * r * ln
    if g.kind == "capsule":
        r, ln = float(g.size[0]), float(g.size[1])
        a, c = _cylinder_like(r, ln / 2.0, r)
        return ctr.copy(), rot.copy(), np.array([a, a, c]), math.pi * r * r * ln + 4.0 / 3.0 * math.pi * r**3
    if g.kind == "box":
        h = np.asarray(g.size, dtype=np.float64) / 2.0
        return ctr.copy(), rot.copy(), h * math.sqrt(3.0), float(np.prod(2 * h))
    raise ValueError(g.kind)


def split_fit(verts: np.ndarray, edges: np.ndarray, k: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """k ellipsoids enclosing a triangle mesh (vertices (N, 3), unique edges (M, 2)): see module doc."""
    if k <= 1 or len(verts) < 8:
        return [mvee(verts)]
    ctr = verts.mean(axis=0)
    axis = np.linalg.svd(verts - ctr, full_matrices=False)[2][0]
    t = (verts - ctr) @ axis
    bounds = np.linspace(t.min(), t.max(), k + 1)
    ta, tb = t[edges[:, 0]], t[edges[:, 1]]
    out = []
    for i in range(k):
        lo, hi = bounds[i], bounds[i + 1]
        parts = [verts[(t >= lo) & (t <= hi)]]
        for plane, interior in ((lo, i > 0), (hi, i < k - 1)):
            if not interior:
                continue
            cross = (ta - plane) * (tb - plane) < 0
            if cross.any():
                e = edges[cross]
                w = ((plane - ta[cross]) / (tb[cross] - ta[cross]))[:, None]
                parts.append(verts[e[:, 0]] + w * (verts[e[:, 1]] - verts[e[:, 0]]))
        pts = np.concatenate(parts)
        if len(pts):
            out.append(mvee(pts))
    return out


def fit_link(link: str, geoms: list[Geom], k: int = 1, method: str = "split", config=None, alternatives: list | None = None) -> tuple[list, float]:
    """Ellipsoids [(c, R, s), ...] in the link frame for one link's geometry + its geometry volume.

    Spheres, cylinders and capsules always get their analytic enclosing ellipsoid; meshes and boxes
    get ``k`` split ellipsoids (``method="split"``), the optimised union (``method="opt"``,
    :func:`~splatplan.robots.fit_opt.fit_link_opt`) or the greedy cover (``method="cover"``,
    :func:`~splatplan.robots.fit_cover.fit_link_cover`), each with ``config``). ``alternatives``
    (``method="opt"``): a list that receives every count the fitter tried, as (ellipsoids on the
    link, excess volume m^3, measured reach m, the link's ellipsoids), for a robot-wide budget."""
    import trimesh

    ells, vol, polys = [], 0.0, []
    for g in geoms:
        check_size(g, link) if g.kind != "mesh" else None
        if g.kind in ("sphere", "cylinder", "capsule"):
            c, r, s, v = primitive_ellipsoid(g)
            ells.append((c, r, s))
            vol += v
        else:
            m = polytope(g, link)
            vol += mesh_volume(m) if g.kind == "mesh" else float(np.prod(g.size))
            polys.append(m)
    if polys and method == "opt":
        best, stats = fit_opt.fit_link_opt(polys, config or fit_opt.OptConfig())
        if alternatives is not None:  # every count tried, whole-link: (n, excess volume m^3, reach m, ellipsoids)
            pv = stats["solid_volume"]
            alternatives += [(len(ells) + len(e), (ratio - 1.0) * pv, reach, ells + list(e)) for _, e, ratio, reach in stats["candidates"]]
        ells += best
    elif polys and method == "cover":
        ells += fit_cover.fit_link_cover(polys, config or fit_cover.FitConfig())[0]
    elif polys:
        merged = cast("trimesh.Trimesh", trimesh.util.concatenate(polys)) if len(polys) > 1 else polys[0]  # (meshes join into a mesh)
        ells += split_fit(np.asarray(merged.vertices, dtype=np.float64), np.asarray(merged.edges_unique), k)
    return ells, vol


def link_points(geoms: list[Geom], link: str) -> np.ndarray:
    """Every vertex (mesh vertices, box corners) of a link's polytope elements, link frame (N, 3)."""
    pts = [np.asarray(polytope(g, link).vertices) for g in geoms if g.kind in ("mesh", "box")]
    return np.concatenate(pts) if pts else np.zeros((0, 3))


#: Fitting methods of :func:`fit_model`.
METHODS = ("opt", "cover", "split")


def fit_work_guard(model, per_link=1, from_visual: bool = False, links=None) -> None:
    """The work guard of a fit (:data:`MAX_FIT_ELLIPSOIDS` over all links), before it starts."""
    fit_links = [n for n in model.kin.link_names if (links is None or n in links)
                 and (model.collisions.get(n) or (model.visuals.get(n) if from_visual else None))]
    total = sum(int(per_link) if isinstance(per_link, int) else int(per_link.get(n, 1)) for n in fit_links)
    require_work(float(total), MAX_FIT_ELLIPSOIDS, f"fitting {len(fit_links):,} link(s) with geometry ({total:,} ellipsoids)",
                 "--per-link or the number of links with geometry (a robot has tens)")


def fit_model(
    model: UrdfModel,
    per_link: int | dict[str, int] = 1,
    from_visual: bool = False,
    links: list[str] | None = None,
    method: str = "split",
    config=None,
) -> EllipsoidSet:
    """Fit ellipsoids to every link of a URDF model (links in the model's order).

    Args:
        per_link: k ellipsoids for each link's polytopes (int, or {link: k} with default 1);
            ``method="split"`` only.
        method: "split" (k enclosing ellipsoids per link), "opt" (optimised and certified, see
            :mod:`splatplan.robots.fit_opt`; ``config`` is its :class:`OptConfig`) or "cover"
            (the greedy union, see :mod:`splatplan.robots.fit_cover`; ``config`` is its
            :class:`FitConfig`).
        from_visual: fit links that have no collision geometry to their visual geometry.
        links: restrict to these links (default: all).
    Links with no usable geometry are listed in ``skipped``.
    """
    if method not in METHODS:
        raise SplatplanError(f"unknown fit method {method!r}: use one of {', '.join(METHODS)}")
    for k in [per_link] if isinstance(per_link, int) else list(per_link.values()):
        if int(k) < 1:
            raise SplatplanError(f"--per-link must be >= 1, got {k}")
        require_work(int(k), MAX_PER_LINK, f"fitting {k} ellipsoids per link", "--per-link")
    fit_work_guard(model, per_link, from_visual, links)  # before any (slow) fit starts
    for link in model.kin.link_names:  # every mesh file is there before any (slow) fit starts
        for g in model.collisions.get(link, []) or (model.visuals.get(link, []) if from_visual else []):
            if g.kind == "mesh" and (links is None or link in links):
                polytope(g, link)  # a missing, unreadable, NaN or flat mesh: one line now, not after minutes of fitting
    names, cs, rs, ss, report, skipped = [], [], [], [], {}, []
    budget = method == "opt" and (config is None or config.budget_per_link > 0)
    fitted, options = {}, {}  # link -> (ells, geometry volume, geoms, source); link -> alternatives
    bar = {} if method != "split" else {"disable": True}  # (split fits take milliseconds)
    for link in progress(model.kin.link_names, desc=f"fit ({method})", unit="link", **bar):
        if links is not None and link not in links:
            continue
        geoms, source = model.collisions.get(link, []), "collision"
        if not geoms and from_visual:
            geoms, source = model.visuals.get(link, []), "visual"
        if not geoms:
            skipped.append(link)
            continue
        k = per_link if isinstance(per_link, int) else int(per_link.get(link, 1))
        alt: list | None = [] if budget else None
        ells, gvol = fit_link(link, geoms, k, method, config, alternatives=alt)
        fitted[link] = (ells, gvol, geoms, source)
        if alt:
            options[link] = alt
    if options:
        cfg = config or fit_opt.OptConfig()
        n_fixed = sum(len(f[0]) for link, f in fitted.items() if link not in options)
        pick = fit_opt.allocate({link: [a[:3] for a in alt] for link, alt in options.items()}, int(cfg.budget_per_link * len(fitted)) - n_fixed, cfg.reach)
        for link, i in pick.items():
            fitted[link] = (options[link][i][3],) + fitted[link][1:]
    for link, (ells, gvol, geoms, source) in fitted.items():
        evol = union_volume(ells)
        for c, r, s in ells:
            names.append(link)
            cs.append(c)
            rs.append(r)
            ss.append(s)
        report[link] = {
            "source": source,
            "method": method,
            "geometry": sorted({g.kind for g in geoms}),
            "n": len(ells),
            "geometry_volume": gvol,
            "ellipsoid_volume": evol,
            "volume_ratio": evol / gvol if gvol > 0 else float("inf"),
        }
    if not names:
        raise SplatplanError(f"URDF {model.path}: no link has collision geometry" + ("" if from_visual else " (try --from-visual)"))
    return EllipsoidSet(names, np.array(cs), np.array(rs), np.array(ss), report, skipped)


# --------------------------------------------------------------------------- YAML


def save_yaml(ells: EllipsoidSet, path: str | Path, robot: str = "", urdf: str = "", note: str = "") -> None:
    """Write an ellipsoid set as YAML (quaternions wxyz, link frame, metres)."""
    import yaml

    from ..scenes.splats import rotmat_to_quat

    quats = rotmat_to_quat(ells.rot) if ells.n else np.zeros((0, 4))
    doc = {
        "robot": robot,
        "urdf": urdf,
        "note": note or "collision ellipsoids per link: centre and wxyz quaternion (link <- ellipsoid) in the link frame, semi-axes in metres",
        "ellipsoids": [
            {
                "link": ells.link[i],
                "center": [float(v) for v in ells.center[i]],
                "quat": [float(v) for v in quats[i]],
                "semi_axes": [float(v) for v in ells.semi_axes[i]],
            }
            for i in range(ells.n)
        ],
        "links": {k: {kk: (float(f"{vv:.6g}") if isinstance(vv, float) else vv) for kk, vv in v.items()} for k, v in ells.report.items()},
        "skipped_links": list(ells.skipped),
    }
    from .._files import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(yaml.safe_dump(doc, sort_keys=False, width=200))


def load_yaml(path: str | Path, link_names: list[str] | None = None) -> EllipsoidSet:
    """Read an ellipsoid YAML written by :func:`save_yaml` (or by hand: link, center, semi_axes, optional quat)."""
    import yaml

    from ..scenes.splats import quat_to_rotmat

    path = Path(path)
    if not path.is_file():
        raise SplatplanError(f"ellipsoid file {path} does not exist")
    try:
        doc = yaml.load(path.read_text(), Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        raise SplatplanError(f"ellipsoid file {path} is not valid YAML ({str(exc).splitlines()[0]})") from None
    items = doc.get("ellipsoids") if isinstance(doc, dict) else None
    if not isinstance(items, list) or not items:
        raise SplatplanError(f"ellipsoid file {path}: expected a non-empty list under 'ellipsoids'")
    names, cs, qs, ss = [], [], [], []
    for i, it in enumerate(items):
        try:
            link = str(it["link"])
            c = np.asarray(it["center"], dtype=np.float64).reshape(3)
            s = np.asarray(it["semi_axes"], dtype=np.float64).reshape(3)
            q = np.asarray(it.get("quat", [1.0, 0.0, 0.0, 0.0]), dtype=np.float64).reshape(4)
        except (KeyError, TypeError, ValueError):
            raise SplatplanError(f"ellipsoid file {path}: entry {i} needs 'link', 'center' (3 numbers), 'semi_axes' (3 numbers), optional 'quat' (wxyz)") from None
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(q)) and np.all(np.isfinite(s))) or np.any(s <= 0) or np.linalg.norm(q) < 1e-8:
            raise SplatplanError(f"ellipsoid file {path}: entry {i} (link {link!r}) has non-finite values, a zero quaternion or semi-axes <= 0")
        if link_names is not None and link not in link_names:
            raise SplatplanError(f"ellipsoid file {path}: entry {i} names link {link!r}, which the robot does not have")
        names.append(link)
        cs.append(c)
        qs.append(q / np.linalg.norm(q))
        ss.append(s)
    report = doc.get("links") or {}
    return EllipsoidSet(names, np.array(cs), quat_to_rotmat(np.array(qs)), np.array(ss), dict(report), list(doc.get("skipped_links") or []))
