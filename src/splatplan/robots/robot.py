"""The one robot type: a kinematic tree whose links carry collision ellipsoids.

Frames and units: z-up world, metres, radians; quaternions wxyz. ``link_poses(q)`` are world <-
link transforms; each ellipsoid is given in its link's frame (centre, rotation link <- ellipsoid,
semi-axes) and ``ellipsoids(q)`` returns it in the world frame.

Configurations ``q`` have shape (..., dof). FK and collision queries accept any q that is finite;
joint limits are checked only by :meth:`Robot.check_q` (``clip=True`` clips instead of raising),
which the CLI applies to user-supplied configurations.

What kind of robot it is, the robot says itself (code asks these, never the robot's name):

* :attr:`Robot.base` - how its root link moves: ``"fixed"`` (an arm on its mount), ``"planar"``
  (the first three dofs are x, y, yaw in the floor frame of ``base_pose``) or ``"translation"``
  (the first three dofs are x, y, z). It is read from the kinematics (the root joint), so it cannot
  disagree with them.
* :attr:`Robot.is_point` - a free-flying rigid body: a translation base and no other dof (the
  ``sphere:R`` / ``ellipsoid:A,B,C`` robots), so its configuration is its position.
* :attr:`Robot.walks_on_terrain` - a ground robot (planar base only): it stands on the floor, whose
  splats are terrain to walk on rather than obstacles (``scenes/terrain.py``). Set by
  :func:`~splatplan.robots.load_robot` (``go2``; a URDF with ``walks_on_terrain=True``).
"""

from __future__ import annotations

import copy
import threading
from collections.abc import Set as AbstractSet
from concurrent.futures import ThreadPoolExecutor
from typing import Literal

import numpy as np

from .._warp import LazyThreadPool, OwnsThreadPool
from ..errors import SplatplanError
from .fit import EllipsoidSet
from .kinematics import FIXED, PLANAR, PRISMATIC, TRANSLATION, Kinematics, link_poses_ref, rigid_groups

#: How a robot's root link moves (:attr:`Robot.base`); the same words as ``load_robot(base=...)``.
BaseKind = Literal["fixed", "planar", "translation"]
_BASE_OF_JOINT: dict[int, BaseKind] = {FIXED: "fixed", PLANAR: "planar", TRANSLATION: "translation"}


class Robot(OwnsThreadPool):
    """A robot: flat kinematics + collision ellipsoids (see the module docstring).

    Attributes:
        name: str.
        dof: number of configuration entries.
        joint_names: (dof,) names ("x", "y", "yaw" / "z" for bases).
        link_names: (L,) every link (frame) of the tree, topological order.
        joint_limits: (dof, 2) float64 [lower, upper]; +-inf for free translations.
        velocity_limits: (dof,) float64 (rad/s or m/s).
        continuous: (dof,) bool, True for joints that wrap around (continuous joints).
        q_default: (dof,) home / standing configuration.
        base_pose: (4, 4) world <- robot base (the root link's frame at q = 0).
        ellipsoid_link: (E,) int index into link_names.
        ellipsoid_local: (E, 4, 4) link <- ellipsoid frame.
        semi_axes: (E, 3) float64 metres.
        motion_bound: (dof,) metres per unit of joint motion; see :meth:`_motion_bound`.
        static_links: (L,) bool, True for links fixed to the world (no actuated or mimic joint
            between the root and the link): their pose never changes with q.
        static_ellipsoids: (E,) bool, True for ellipsoids on static links (e.g. Panda's link0).
        fit_report: link -> {source, n, geometry_volume, ellipsoid_volume, volume_ratio}.
        self_collision_pairs: (P, 2) int ellipsoid pairs checked by :meth:`self_collision`.
        walks_on_terrain: a ground robot (planar base): the floor's splats are terrain it walks
            on, not obstacles (see the module docstring; :attr:`base` and :attr:`is_point` say
            the rest of what kind of robot it is).
    """

    def __init__(
        self,
        name: str,
        kin: Kinematics,
        joint_names: list[str],
        joint_limits: np.ndarray,
        velocity_limits: np.ndarray,
        q_default: np.ndarray,
        ellipsoids: EllipsoidSet,
        continuous: np.ndarray | None = None,
        disabled_pairs: AbstractSet[frozenset[str | None]] | None = None,
        info: dict | None = None,
        walks_on_terrain: bool = False,
    ):
        self.name = name
        self.kin = kin
        self.dof = len(joint_names)
        kin.validate(self.dof)
        self.walks_on_terrain = bool(walks_on_terrain)
        if self.walks_on_terrain and self.base != "planar":
            raise SplatplanError(f"robot {name}: only a planar base (x, y, yaw) walks on terrain; this one's base is {self.base!r}")
        self.joint_names = list(joint_names)
        self.link_names = list(kin.link_names)
        self.joint_limits = np.asarray(joint_limits, dtype=np.float64).reshape(self.dof, 2)
        self.velocity_limits = np.asarray(velocity_limits, dtype=np.float64).reshape(self.dof)
        self.continuous = np.zeros(self.dof, dtype=bool) if continuous is None else np.asarray(continuous, dtype=bool)
        self.q_default = np.asarray(q_default, dtype=np.float64).reshape(self.dof)
        self.info = dict(info or {})
        index = {n: i for i, n in enumerate(self.link_names)}
        missing = [n for n in ellipsoids.link if n not in index]
        if missing:
            raise SplatplanError(f"robot {name}: ellipsoids name unknown links {sorted(set(missing))}")
        if ellipsoids.n == 0:
            raise SplatplanError(f"robot {name}: no collision ellipsoids")
        # Ellipsoids in link order (stable), so the kernel and the reference agree on row order.
        order = sorted(range(ellipsoids.n), key=lambda i: index[ellipsoids.link[i]])
        self.ellipsoid_link = np.array([index[ellipsoids.link[i]] for i in order], dtype=np.int64)
        local = np.tile(np.eye(4), (len(order), 1, 1))
        local[:, :3, :3] = ellipsoids.rot[order]
        local[:, :3, 3] = ellipsoids.center[order]
        self.ellipsoid_local = local
        self.semi_axes = np.ascontiguousarray(ellipsoids.semi_axes[order], dtype=np.float64)
        self.fit_report = dict(ellipsoids.report)
        self.skipped_links = list(ellipsoids.skipped)
        self.frame_of_link, self.link_in_frame = rigid_groups(kin)
        self.motion_bound = self._motion_bound()
        # a link is static when its rigid group's frame is the root and the root is fixed to the world
        self.static_links = (kin.parent[self.frame_of_link] < 0) & (kin.jtype[self.frame_of_link] == FIXED)
        self.static_ellipsoids = self.static_links[self.ellipsoid_link]
        self.self_collision_pairs = self._pairs(disabled_pairs or set())
        self._lock = threading.Lock()
        self._pool = LazyThreadPool(name=f"splatplan-fk-{name}")
        self._wp_cache: dict = {}

    # ------------------------------------------------------------------ basic properties

    @property
    def n_ellipsoids(self) -> int:
        return len(self.ellipsoid_link)

    @property
    def base_pose(self) -> np.ndarray:
        return self.kin.origin[0].copy()

    @property
    def min_semi_axis(self) -> float:
        return float(self.semi_axes.min())

    @property
    def base(self) -> BaseKind:
        """How the root link moves: "fixed", "planar" (dofs 0-2 are x, y, yaw) or "translation"
        (dofs 0-2 are x, y, z); read from the root joint of the kinematics."""
        jt = int(self.kin.jtype[0])
        if jt not in _BASE_OF_JOINT:  # pragma: no cover - Kinematics.validate admits no other root joint
            raise SplatplanError(f"robot {self.name}: its root joint is neither fixed, planar nor a translation")
        return _BASE_OF_JOINT[jt]

    @property
    def is_point(self) -> bool:
        """A point robot: a rigid body whose configuration is its position (x, y, z): a translation
        base and no other dof, e.g. ``load_robot("sphere:R")`` / ``"ellipsoid:A,B,C"`` (decided by
        the kinematics, not the name)."""
        return self.base == "translation" and self.dof == 3

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, dof={self.dof}, links={len(self.link_names)}, ellipsoids={self.n_ellipsoids})"

    def inflated(self, margin_m: float) -> "Robot":
        """A copy whose every ellipsoid contains all points within ``margin_m`` of the original one
        (its Minkowski sum with a ball of radius ``margin_m``); see :func:`inflate_semi_axes`.

        Same kinematics, ellipsoid centres and orientations, joint limits and self-collision pairs;
        new semi-axes and motion bound. ``info["inflated_by_m"]`` records the margin.
        """
        m = float(margin_m)
        if not (np.isfinite(m) and m >= 0):
            raise SplatplanError(f"robot {self.name}: the inflation margin must be finite and >= 0, got {margin_m}")
        self.__dict__.setdefault("_motion_terms_cache", {})  # (kinematic motion terms, shared with the copy: same kinematics)
        out = copy.copy(self)
        with self._lock:  # the FK models on devices (kinematics and ellipsoid poses only): shared with the copy
            models = {k: v for k, v in self._wp_cache.items() if k[0] == "model"}
        out.__dict__.update(_lock=threading.Lock(), _pool=copy.copy(self._pool), _wp_cache=models)
        out.semi_axes = inflate_semi_axes(self.semi_axes, m)
        out.motion_bound = out._motion_bound()
        out.info = {**self.info, "inflated_by_m": m + float(self.info.get("inflated_by_m", 0.0))}
        return out

    # ------------------------------------------------------------------ validation

    def check_q(self, q, *, clip: bool = False, check_limits: bool = True) -> np.ndarray:
        """Validate configurations (..., dof): shape, finiteness and (optionally) joint limits.

        Returns a float64 copy. Outside the limits (tolerance 1e-9): raises SplatplanError, or
        clips into them when ``clip=True``; ``check_limits=False`` skips the limit check.
        """
        try:
            arr = np.array(q, dtype=np.float64)
        except (TypeError, ValueError):
            raise SplatplanError(f"robot {self.name}: configurations must be numeric arrays of shape (..., {self.dof})") from None
        if arr.ndim == 0 or arr.shape[-1] != self.dof:
            raise SplatplanError(
                f"robot {self.name}: configurations need {self.dof} values ({', '.join(self.joint_names)}), got shape {arr.shape}"
            )
        finite = np.isfinite(arr).all(axis=-1)
        if not finite.all():
            bad = np.argwhere(~finite)[0]
            raise SplatplanError(f"robot {self.name}: configuration {tuple(int(i) for i in bad)} contains NaN or Inf")
        if check_limits:
            lo, hi = self.joint_limits[:, 0], self.joint_limits[:, 1]
            if clip:
                arr = np.clip(arr, lo, hi)
            else:
                out = (arr < lo - 1e-9) | (arr > hi + 1e-9)
                if out.any():
                    idx = np.argwhere(out)[0]
                    j = int(idx[-1])
                    raise SplatplanError(
                        f"robot {self.name}: configuration {tuple(int(i) for i in idx[:-1])} has {self.joint_names[j]} = {arr[tuple(idx)]:.6g}"
                        f" outside its limits [{lo[j]:.6g}, {hi[j]:.6g}] (clip it, e.g. check_q(q, clip=True))"
                    )
        return arr

    # ------------------------------------------------------------------ numpy reference FK

    def link_poses(self, q) -> np.ndarray:
        """q (..., dof) -> (..., L, 4, 4) float64 world <- link (numpy reference)."""
        return link_poses_ref(self.kin, self.check_q(q, check_limits=False))

    def ellipsoid_frames(self, q) -> tuple[np.ndarray, np.ndarray]:
        """q (..., dof) -> (centres (..., E, 3) world, rotations (..., E, 3, 3) world <- ellipsoid)."""
        poses = self.link_poses(q)[..., self.ellipsoid_link, :, :] @ self.ellipsoid_local  # (..., E, 4, 4)
        return poses[..., :3, 3], poses[..., :3, :3]

    def ellipsoids(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """q (..., dof) -> (centres (..., E, 3) world, quats (..., E, 4) wxyz world <- ellipsoid, semi_axes (E, 3))."""
        from ..scenes.splats import rotmat_to_quat

        c, r = self.ellipsoid_frames(q)
        return c, rotmat_to_quat(r), self.semi_axes.copy()

    # ------------------------------------------------------------------ Warp FK

    def fk_wp(self, q_wp, out_centers, out_rots, ellipsoids=None) -> None:
        """Device-resident FK (Warp kernel; CPU launches split across this robot's thread pool).

        Args:
            q_wp: wp.array(dtype=float32, ndim=2) (B, dof) on any device.
            out_centers: wp.array(dtype=wp.vec3) (B*E,) world frame, same device.
            out_rots: wp.array(dtype=wp.mat33) (B*E,) world <- ellipsoid frame, same device.
            ellipsoids: None (all E) or a list of ellipsoid indices (then E = its length, rows in
                its order), e.g. only the moving ones.
        Row b*E + e holds ellipsoid e of configuration b. Nothing is copied to the host.
        """
        from .wp_fk import attachments, launch_fk

        launch_fk(self, q_wp, out_centers, out_rots, attachments(self, ellipsoids=ellipsoids))

    def fk(self, q, device: str | None = "auto", ellipsoids=None, links=None) -> tuple[np.ndarray, np.ndarray]:
        """Convenience: numpy q (..., dof) -> Warp FK -> numpy (centres (..., E, 3), rotations (..., E, 3, 3)) float32.

        ``ellipsoids``: a subset of ellipsoid indices (E = its length); ``links``: link indices
        instead (their frames' origins and world <- link rotations; E = its length)."""
        from .._warp import resolve_device
        from .._warp import wp as _wp
        from .wp_fk import attachments, launch_fk

        wp = _wp()
        arr = self.check_q(q, check_limits=False)
        lead = arr.shape[:-1]
        flat = np.ascontiguousarray(arr.reshape(int(np.prod(lead, dtype=np.int64)), self.dof), dtype=np.float32)
        dev = resolve_device(device)
        b = flat.shape[0]
        att = attachments(self, ellipsoids=ellipsoids, links=links)
        e = self.n_ellipsoids if att is None else len(att.links)
        qw = wp.array(flat, dtype=wp.float32, device=dev)
        oc = wp.empty(b * e, dtype=wp.vec3, device=dev)
        orr = wp.empty(b * e, dtype=wp.mat33, device=dev)
        launch_fk(self, qw, oc, orr, att)
        return oc.numpy().reshape(lead + (e, 3)), orr.numpy().reshape(lead + (e, 3, 3))

    def _thread_pool(self) -> ThreadPoolExecutor:
        return self._pool.get()

    def __getstate__(self) -> dict:  # picklable (worker processes): no threads, lock or device arrays
        state = self.__dict__.copy()
        state.update(_lock=None, _wp_cache={})  # the LazyThreadPool pickles without threads
        return state

    def __setstate__(self, state: dict) -> None:
        state.setdefault("walks_on_terrain", False)
        self.__dict__.update(state)
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ motion bound

    def _subtree(self) -> list[list[int]]:
        kids = self.kin.children()
        out: list[list[int]] = [[] for _ in range(self.kin.n_links)]
        for l in reversed(range(self.kin.n_links)):
            out[l] = [l] + [x for c in kids[l] for x in out[c]]
        return out

    def _motion_bound(self) -> np.ndarray:
        """(dof,) b with |x(q1) - x(q2)| <= sum_j b_j |q1_j - q2_j| for every point x of every ellipsoid.

        Per joint: a prismatic joint (or base translation) moves downstream points by |dv|, so it
        contributes 1; a revolute joint (or the base yaw) moves a point at distance rho from its
        axis by at most rho |dv|, so it contributes max rho over downstream ellipsoid points.
        rho is bounded by |perpendicular part of the ellipsoid centre| + largest semi-axis when
        the ellipsoid is rigidly attached to the joint's link, otherwise by the triangle
        inequality along the chain: the distance of the next moving joint's origin from the axis
        (fixed in the joint's frame), plus the lengths of the later joint offsets, prismatic
        travel, the centre offset and the largest semi-axis, which holds in every configuration. A dof driving several joints
        (mimic) sums |multiplier| x bound over them. Integrating the point's speed along the
        straight segment q1 -> q2 gives the stated inequality for any pair of configurations.
        """
        bound = np.zeros(self.dof)
        smax = self.semi_axes.max(axis=1)  # (E,)
        for lin, rot, ells, geo in self._motion_terms():
            for sl, c in lin:
                bound[sl] += c
            if rot is not None:
                bound[rot[0]] += rot[1] * (float((geo + smax[ells]).max()) if len(ells) else 0.0)
        return bound

    def ellipsoid_motion_bounds(self) -> np.ndarray:
        """(E, dof) B with |x(q1) - x(q2)| <= sum_j B[e, j] |q1_j - q2_j| for every point x of ellipsoid e.

        The per-ellipsoid form of :attr:`motion_bound` (same argument, see :meth:`_motion_bound`):
        joint j contributes to the ellipsoids downstream of it only, a revolute joint by the
        ellipsoid's own distance bound from its axis. ``B.max(axis=0) <= motion_bound``; a row of
        zeros is an ellipsoid that no joint moves (a fixed base link). Used by the planners' edge
        checks to prove samples free from a checked neighbour. Cached (by the semi-axes: an
        :meth:`inflated` copy computes its own).
        """
        key = self.semi_axes.tobytes()
        hit = self.__dict__.get("_ell_motion_cache")
        if hit is not None and hit[0] == key:
            return hit[1].copy()
        bound = np.zeros((self.n_ellipsoids, self.dof))
        smax = self.semi_axes.max(axis=1)  # (E,)
        for lin, rot, ells, geo in self._motion_terms():
            for sl, c in lin:
                bound[ells, sl] += c
            if rot is not None:
                bound[ells, rot[0]] += rot[1] * (geo + smax[ells])
        self.__dict__["_ell_motion_cache"] = (key, bound)
        return bound.copy()

    def _motion_terms(self) -> list:
        """Per moving joint, the terms both motion bounds sum (the argument of :meth:`_motion_bound`):
        ``(lin, rot, ells, geo)`` with ``lin`` [(dof slice, coefficient)] of its translations (each
        moves every downstream point by that much per unit), ``rot`` (dof index, |multiplier|) of its
        rotation or None, ``ells`` (k,) the ellipsoids it moves and ``geo`` (k,) the kinematic part
        of their distance bounds from the rotation axis (:meth:`_axis_distance_geometry`: less the
        largest semi-axis; 0 for a pure translation). Kinematics only: cached, shared with
        :meth:`inflated` copies (which grow the semi-axes alone)."""
        cache = self.__dict__.setdefault("_motion_terms_cache", {})
        key = (np.asarray(self.ellipsoid_link).tobytes(), np.asarray(self.ellipsoid_local).tobytes())
        hit = cache.get(key)
        if hit is not None:
            return hit
        kin = self.kin
        sub = self._subtree()
        ell_of_link = self._ellipsoids_of_link()
        terms: list[tuple[list, tuple[int, float] | None, np.ndarray, np.ndarray]] = []
        for l in range(kin.n_links):
            jt = int(kin.jtype[l])
            if jt == FIXED:
                continue
            qi, m = int(kin.qidx[l]), abs(float(kin.mult[l]))
            down = [(d, e) for d in sub[l] for e in ell_of_link.get(d, [])]
            ells = np.array([e for _, e in down], dtype=np.int64)
            if jt in (PRISMATIC, TRANSLATION):
                n_lin = 3 if jt == TRANSLATION else 1
                terms.append(([(slice(qi, qi + n_lin), m if jt == PRISMATIC else 1.0)], None, ells, np.zeros(len(ells))))
                continue
            if jt == PLANAR:
                lin, qi_rot, factor, axis = [(slice(qi, qi + 2), 1.0)], qi + 2, 1.0, np.array([0.0, 0.0, 1.0])
            else:
                lin, qi_rot, factor, axis = [], qi, m, kin.axis[l]
            terms.append((lin, (qi_rot, factor), ells, np.array([self._axis_distance_geometry(l, d, e, axis) for d, e in down], dtype=np.float64)))
        cache[key] = terms
        return terms

    def _ellipsoids_of_link(self) -> dict[int, list[int]]:
        """Link index -> the indices of the ellipsoids it carries (the motion bounds' bookkeeping)."""
        out: dict[int, list[int]] = {}
        for e, l in enumerate(self.ellipsoid_link):
            out.setdefault(int(l), []).append(e)
        return out

    def _axis_distance_geometry(self, l: int, d: int, e: int, axis: np.ndarray) -> float:
        """Bound on the distance of ellipsoid e (on link d, below joint l) from l's axis, without the
        ellipsoid's own size (its largest semi-axis is added by the motion bounds)."""
        kin = self.kin
        path = []  # links from d up to (excluding) l
        k = d
        while k != l:
            path.append(k)
            k = int(kin.parent[k])
        if all(kin.jtype[k] == FIXED for k in path):  # rigid: exact centre in l's frame
            t = np.eye(4)
            for k in reversed(path):
                t = t @ kin.origin[k]
            c = (t @ self.ellipsoid_local[e])[:3, 3]
            return float(np.linalg.norm(c - (c @ axis) * axis))
        # Down the path from l: the origin of the first moving joint k* is fixed in l's frame, so its
        # distance from the axis is exact; below it, each hop adds its offset length (and travel).
        down = list(reversed(path))
        t = np.eye(4)
        first = 0
        for first, k in enumerate(down):
            t = t @ kin.origin[k]
            if kin.jtype[k] != FIXED:
                break
        p = t[:3, 3]
        total = float(np.linalg.norm(p - (p @ axis) * axis))
        total += float(np.linalg.norm(self.ellipsoid_local[e][:3, 3]))
        for i, k in enumerate(down):
            if i > first:
                total += float(np.linalg.norm(kin.origin[k][:3, 3]))
            if kin.jtype[k] == PRISMATIC:
                lo, hi = self.joint_limits[int(kin.qidx[k])]
                total += max(abs(lo), abs(hi)) * abs(float(kin.mult[k])) + abs(float(kin.offset[k]))
        return total

    # ------------------------------------------------------------------ self-collision

    def _pairs(self, disabled: AbstractSet[frozenset[str | None]]) -> np.ndarray:
        """Ellipsoid pairs to check: different rigid bodies, not adjacent, not disabled, apart at q_default."""
        kin, fr = self.kin, self.frame_of_link
        parent_frame = {int(f): (int(fr[kin.parent[f]]) if kin.parent[f] >= 0 else -1) for f in set(fr.tolist())}
        kept: list[tuple[int, int]] = []
        for i in range(self.n_ellipsoids):
            for j in range(i + 1, self.n_ellipsoids):
                li, lj = int(self.ellipsoid_link[i]), int(self.ellipsoid_link[j])
                fi, fj = int(fr[li]), int(fr[lj])
                if fi == fj or parent_frame[fi] == fj or parent_frame[fj] == fi:
                    continue
                if frozenset((self.link_names[li], self.link_names[lj])) in disabled:
                    continue
                kept.append((i, j))
        pairs = np.array(kept, dtype=np.int64).reshape(-1, 2)
        if len(pairs):
            c, r = self.ellipsoid_frames(self.q_default)
            hit = _maybe_overlap(c[pairs[:, 0]], r[pairs[:, 0]], self.semi_axes[pairs[:, 0]], c[pairs[:, 1]], r[pairs[:, 1]], self.semi_axes[pairs[:, 1]])
            pairs = pairs[~hit]  # touching in the home pose: treated as always in contact (MoveIt's "Default")
        return pairs

    def self_collision(self, q) -> np.ndarray | np.bool_:
        """(...,) bool: True where some checked ellipsoid pair may overlap (conservative: never misses a true overlap).

        Pairs are those of ``self_collision_pairs``: ellipsoids on different rigid bodies whose
        links are not adjacent, not disabled in the SRDF, and not already overlapping in
        ``q_default``. The test reports "separate" only with a proof: the bounding spheres are
        apart, or the projections on one of 7 directions (centre line, the 6 ellipsoid axes) are.
        """
        c, r = self.ellipsoid_frames(q)
        lead = c.shape[:-2]
        if len(self.self_collision_pairs) == 0:
            return np.zeros(lead, dtype=bool)
        i, j = self.self_collision_pairs[:, 0], self.self_collision_pairs[:, 1]
        hit = _maybe_overlap(c[..., i, :], r[..., i, :, :], self.semi_axes[i], c[..., j, :], r[..., j, :, :], self.semi_axes[j])
        return hit.any(axis=-1)

    # ------------------------------------------------------------------ report

    def describe(self) -> dict:
        """JSON-able summary (``splatplan robot info``)."""
        return {
            "name": self.name,
            "dof": self.dof,
            "base": self.base,
            "walks_on_terrain": self.walks_on_terrain,
            "joints": [
                {"name": n, "lower": float(lo), "upper": float(hi), "velocity": float(v), "continuous": bool(c), "default": float(d), "motion_bound_m": float(mb)}
                for n, (lo, hi), v, c, d, mb in zip(self.joint_names, self.joint_limits, self.velocity_limits, self.continuous, self.q_default, self.motion_bound)
            ],
            "links": self.link_names,
            "base_pose": self.base_pose.tolist(),
            "n_ellipsoids": self.n_ellipsoids,
            "ellipsoids": [
                {"link": self.link_names[l], "center": self.ellipsoid_local[e, :3, 3].tolist(), "semi_axes": self.semi_axes[e].tolist()}
                for e, l in enumerate(self.ellipsoid_link)
            ],
            "fit": self.fit_report,
            "links_without_geometry": self.skipped_links,
            "self_collision_pairs": len(self.self_collision_pairs),
            "min_semi_axis": self.min_semi_axis,
            **({"info": self.info} if self.info else {}),
        }


def inflate_semi_axes(semi_axes: np.ndarray, margin: float) -> np.ndarray:
    """Semi-axes (..., 3) of an ellipsoid (same centre and axes) containing the Minkowski sum of the
    ellipsoid ``semi_axes`` (..., 3) with a ball of radius ``margin`` >= 0.

    Growing every semi-axis by m is **not** enough unless the ellipsoid is a sphere: containment of
    convex bodies is the order of their support functions, and with weights w_i = n_i^2 (a unit
    direction n in the ellipsoid frame) ``|diag(a + m) n|^2 = E[a^2] + 2m E[a] + m^2`` falls short
    of ``(|diag(a) n| + m)^2 = E[a^2] + 2m sqrt(E[a^2]) + m^2`` since ``E[a] <= sqrt(E[a^2])``.

    Construction: ``b_i = sqrt((a_i + m)^2 + 2 m t)`` with ``t = (sqrt(a_max) - sqrt(a_min))^2 / 2``.
    Proof: ``|diag(b) n|^2 = E[a^2] + 2m (E[a] + t) + m^2``, and ``sqrt(E[a^2]) - E[a] <= t`` for any
    weights: it equals Var(a) / (sqrt(E[a^2]) + E[a]) <= (mu - lo)(hi - mu) / (2 mu) (Bhatia-Davis,
    mu = E[a] in [lo, hi]), whose maximum over mu (at mu = sqrt(lo hi)) is t. So
    ``|diag(b) n| >= |diag(a) n| + m`` for every n: the support function of the new ellipsoid is at
    least the Minkowski sum's. For a sphere t = 0 and b = a + m (exact); otherwise b_i exceeds
    a_i + m by at most ``m t / (a_i + m)``.
    """
    a = np.asarray(semi_axes, dtype=np.float64)
    m = float(margin)
    if m == 0:
        return a.copy()
    t = 0.5 * (np.sqrt(a.max(axis=-1, keepdims=True)) - np.sqrt(a.min(axis=-1, keepdims=True))) ** 2
    return np.sqrt((a + m) ** 2 + 2.0 * m * t)


def _support(n: np.ndarray, r: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Half-width of an ellipsoid (rotation r (..., 3, 3), semi-axes s (..., 3)) along unit n (..., 3)."""
    return np.linalg.norm(np.einsum("...i,...ik->...k", n, r) * s, axis=-1)


def _maybe_overlap(c1, r1, s1, c2, r2, s2) -> np.ndarray:
    """Conservative overlap test for ellipsoid pairs (..., P): False only when proven apart."""
    d = c2 - c1
    dist = np.linalg.norm(d, axis=-1)
    s1 = np.broadcast_to(s1, r1.shape[:-1])
    s2 = np.broadcast_to(s2, r2.shape[:-1])
    maybe = dist <= s1.max(axis=-1) + s2.max(axis=-1)
    dirs = [d / np.maximum(dist, 1e-300)[..., None]] + [r1[..., :, k] for k in range(3)] + [r2[..., :, k] for k in range(3)]
    for n in dirs:
        gap = np.abs(np.einsum("...i,...i->...", d, n)) - _support(n, r1, s1) - _support(n, r2, s2)
        maybe &= ~(gap > 0)
    return maybe
