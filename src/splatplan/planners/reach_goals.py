"""Goals of the visual reaching studies (paper Sec. IV-A, E5; :mod:`splatplan.tasks.reach`): a
start view (:data:`START_VIEWS`: above the tabletop scene's bin, the default, or in front of it just
above its front wall) and random goal configurations near it whose wrist view is informative
(:func:`make_reach_goals`), first those whose camera is **hidden from the start camera by the
scene** (the straight segment between the two cameras passes through the exact geometry,
:func:`line_of_sight_m`): goals behind the bin's front wall as seen from the start, as in the
paper, where a controller that moves the camera straight to the goal cuts the wall. The rule uses
the cameras and the exact scene only, not the robot's collision model. From the default start above
the bin, the tabletop in front of the bin's front wall below its top is hidden (a camera move of
about 30 cm back over the wall); from ``before_wall``, the inside of the bin is.

Units: metres, radians; world frame z up (the tabletop scene's).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import SplatplanError

__all__ = ["BEHIND_WALL", "START_CAMERA", "START_VIEWS", "ReachCandidates", "line_of_sight_m", "make_reach_goals", "reach_candidates", "reach_start"]

_DOWN = np.array([[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]])
#: The studies' start view: the wrist camera above the bin, just behind its front wall, looking straight down
#: (world frame, metres; the rotation of the Panda's default TCP: x along world x, z down).
START_CAMERA = (np.array([0.56, 0.0, 0.22]), _DOWN)
#: Start views by name: ``above_bin`` (:data:`START_CAMERA`, the default) and ``before_wall``: in front of
#: the bin, 5 cm before its front wall (x = 0.43..0.45) and 2 cm above its top (z = 0.15), looking straight
#: down; the inside of the bin below the wall's top is hidden from it.
START_VIEWS = {"above_bin": START_CAMERA, "before_wall": (np.array([0.38, 0.0, 0.17]), _DOWN)}
#: Sampler settings of the studies, which find goals hidden from either start view: a wider joint spread,
#: camera moves up to 35 cm for a goal behind the wall or hidden from the start (the move
#: around the wall), more candidates (hidden ones are rare: about 1 in 700 from ``above_bin``).
HIDDEN_GOAL_SAMPLER: dict[str, Any] = {"n_candidates": 8192, "spread": 0.8, "behind_spread": 0.8, "behind_max_move_m": 0.35}
#: Camera region counted as "behind the wall": inside the bin (x, y) and below the front wall's top.
BEHIND_WALL = (np.array([0.46, -0.28, -0.09]), np.array([0.84, 0.28, 0.15]))


def reach_start(robot, camera_link: str = "panda_hand_tcp", view: str = "above_bin") -> np.ndarray:
    """The studies' start configuration: IK of the start view ``view`` (:data:`START_VIEWS`) nearest ``q_default``."""
    from ..robots.ik import solve_ik
    from ..scenes.splats import rotmat_to_quat

    if view not in START_VIEWS:
        raise SplatplanError(f"unknown reach start view {view!r}; choose one of {', '.join(START_VIEWS)}")
    p, r = START_VIEWS[view]
    q, pe, re = solve_ik(robot, p, rotmat_to_quat(r), link=camera_link, n_seeds=8, n_iters=150, seed=0, q_init=robot.q_default)
    ok = (pe < 0.002) & (re < np.radians(1.0))
    if not np.any(ok):
        raise SplatplanError(f"the reach start view is not reachable by {robot.name} (IK error {pe[0] * 100:.1f} cm)")
    q = q[ok]
    return q[int(np.argmin(np.sum((q - robot.q_default) ** 2, axis=1)))]


#: A goal view is filled by the scene when its mean alpha exceeds this (at most 2 % background).
VIEW_MIN_ALPHA = 0.98
#: ... and has contrast when its :func:`view_contrast` exceeds this (default ``min_contrast``).
VIEW_MIN_CONTRAST = 0.12


def view_contrast(rgb: np.ndarray) -> np.ndarray:
    """Spatial contrast of views (M, P, 3) (P pixels, RGB in [0, 1]): each colour channel's std
    over the pixels, averaged over the channels. A view of one flat colour has 0, whatever the
    colour (the std of the flattened pixels and channels would count a flat red as contrast)."""
    return np.asarray(rgb, dtype=np.float64).std(axis=1).mean(axis=1)


#: Points along the camera-to-camera segment at which :func:`line_of_sight_m` evaluates the exact distance.
LINE_OF_SIGHT_POINTS = 200


def line_of_sight_m(analytic, p_from, p_to, n_points: int = LINE_OF_SIGHT_POINTS) -> np.ndarray:
    """Smallest exact signed distance (m) to the scene along the straight segments from ``p_from``
    (3,) to each of ``p_to`` (M, 3), end points excluded (negative: the segment passes through the
    geometry, the goal is hidden from the start; with 200 points a 2 cm wall is crossed at any
    segment up to 2 m long). The cameras and the exact scene only: no robot model enters."""
    p_to = np.asarray(p_to, np.float64).reshape(-1, 3)
    if not len(p_to):
        return np.zeros(0)
    s = np.linspace(0.0, 1.0, n_points + 2)[1:-1][None, :, None]
    pts = np.asarray(p_from, np.float64).reshape(1, 1, 3) * (1.0 - s) + p_to[:, None, :] * s  # (M, n, 3)
    return analytic.sdf(np.ascontiguousarray(pts.reshape(-1, 3)), broad_phase=False).reshape(len(p_to), n_points).min(axis=1)


#: The filters of :func:`reach_candidates`, in the order they are applied.
FILTERS = ("move", "turn", "clearance", "metric", "self_collision", "view")


@dataclass
class ReachCandidates:
    """Every random candidate of :func:`make_reach_goals` and what each filter said of it.

    Attributes:
        q: (M, dof) candidate configurations (rad).
        camera_pose: (M, 4, 4) world <- camera at each candidate.
        behind_wall: (M,) bool, camera inside :data:`BEHIND_WALL`.
        line_of_sight_m: (M,) :func:`line_of_sight_m` from the start camera (NaN where not evaluated:
            only the candidates within the longer move bound that turn little enough; +inf without an
            analytic scene).
        passed: filter name (:data:`FILTERS`) -> (M,) bool; a filter is evaluated only on the
            candidates that passed the filters before it (False elsewhere), except that the metric
            and self-collision checks see every candidate that passed move and turn.
        clearance_m: (M,) smallest exact clearance of any link ellipsoid (+inf without an analytic
            scene; NaN where not evaluated).
        alpha_mean / alpha_min / view_std: (M,) of the rendered check view (NaN where not rendered).
    """

    q: np.ndarray
    camera_pose: np.ndarray
    behind_wall: np.ndarray
    passed: dict
    clearance_m: np.ndarray
    alpha_mean: np.ndarray
    alpha_min: np.ndarray
    view_std: np.ndarray
    line_of_sight_m: np.ndarray | None = None

    @property
    def occluded(self) -> np.ndarray:
        """(M,) bool: the goal camera is hidden from the start camera by the exact scene."""
        if self.line_of_sight_m is None:
            return np.zeros(len(self.q), bool)
        return np.nan_to_num(self.line_of_sight_m, nan=np.inf) < 0.0

    @property
    def kept(self) -> np.ndarray:
        """(M,) bool: passed every filter."""
        return np.logical_and.reduce([self.passed[f] for f in FILTERS])

    def counts(self) -> list[tuple[str, int, int, int]]:
        """(filter, candidates left, behind-wall candidates left, hidden-from-the-start candidates left) after each filter in turn."""
        left, out = np.ones(len(self.q), bool), []
        for f in FILTERS:
            left = left & self.passed[f]
            out.append((f, int(left.sum()), int((left & self.behind_wall).sum()), int((left & self.occluded).sum())))
        return out


def reach_candidates(
    robot, scene, renderer, camera, *, q_start=None, spread: float = 0.35, margin_m: float = 0.02, min_move_m: float = 0.05, max_move_m: float = 0.15,
    max_turn_deg: float = 30.0, n_candidates: int = 1024, seed: int = 0, behind_spread: float = 0.45, behind_max_move_m: float = 0.2,
    min_contrast: float = VIEW_MIN_CONTRAST, view_check_px: int = 64,
) -> ReachCandidates:
    """The random candidates of :func:`make_reach_goals` (same arguments) and every filter's verdict."""
    rng = np.random.default_rng(seed)
    q_start = np.asarray(robot.q_default if q_start is None else q_start, np.float64)
    lim = np.asarray(robot.joint_limits, np.float64)
    half = n_candidates // 2
    sp = np.concatenate([np.full(half, spread), np.full(n_candidates - half, behind_spread)])[:, None]
    q = np.clip(q_start + rng.uniform(-1.0, 1.0, (n_candidates, robot.dof)) * sp, lim[:, 0] + 0.05, lim[:, 1] - 0.05)
    li = camera._link_index(robot)
    t_start = robot.link_poses(q_start)[li] @ camera.offset
    t = robot.link_poses(q)[:, li] @ camera.offset  # (M, 4, 4)
    move = np.linalg.norm(t[:, :3, 3] - t_start[:3, 3], axis=1)
    turn = np.degrees(np.arccos(np.clip(0.5 * (np.einsum("ij,kij->k", t_start[:3, :3], t[:, :3, :3]) - 1.0), -1.0, 1.0)))
    lo_b, hi_b = BEHIND_WALL
    in_b = np.all((t[:, :3, 3] > lo_b) & (t[:, :3, 3] < hi_b), axis=1)
    m = len(q)
    passed = {f: np.zeros(m, bool) for f in FILTERS}
    clear, a_mean, a_min, std, los = (np.full(m, np.nan) for _ in range(5))
    # the line of sight decides the move bound (a hidden goal takes the longer move around the wall): evaluated on
    # every candidate within the longer bound that turns little enough
    idx = np.flatnonzero((move > min_move_m) & (move < max(max_move_m, behind_max_move_m)) & (turn < max_turn_deg))
    if len(idx):
        los[idx] = line_of_sight_m(scene.analytic, t_start[:3, 3], t[idx, :3, 3]) if scene.analytic is not None else np.inf
    long_move = in_b | (np.nan_to_num(los, nan=np.inf) < 0.0)
    passed["move"] = (move > min_move_m) & (move < np.where(long_move, behind_max_move_m, max_move_m))
    passed["turn"] = passed["move"] & (turn < max_turn_deg)
    idx = np.flatnonzero(passed["turn"])
    if len(idx):
        if scene.analytic is not None:
            c, qu, ax = robot.ellipsoids(q[idx])
            clear[idx] = scene.analytic.ellipsoid_clearance(c, qu, ax).min(axis=-1)
        else:
            clear[idx] = np.inf
        passed["clearance"][idx] = clear[idx] > margin_m
        passed["metric"][idx] = ~np.asarray(scene.checker.collides_robot(robot, q[idx])).any(axis=-1)
        passed["self_collision"][idx] = ~np.asarray(robot.self_collision(q[idx]))
    idx = np.flatnonzero(passed["clearance"] & passed["metric"] & passed["self_collision"])
    if len(idx):
        res = camera.scaled(min(camera.width, view_check_px)).render(renderer, robot, q[idx])
        rgb, alpha = np.asarray(res.rgb).reshape(len(idx), -1, 3), np.asarray(res.alpha).reshape(len(idx), -1)  # (M, P, 3), (M, P)
        a_mean[idx], a_min[idx], std[idx] = alpha.mean(axis=1), alpha.min(axis=1), view_contrast(rgb)
        passed["view"][idx] = (a_mean[idx] > VIEW_MIN_ALPHA) & (std[idx] > min_contrast)
    return ReachCandidates(q, t, in_b, passed, clear, a_mean, a_min, std, los)


def make_reach_goals(
    robot, scene, renderer, camera, *, n: int = 5, q_start=None, spread: float = 0.35, n_behind: int = 2, n_occluded: int | None = None,
    margin_m: float = 0.02, min_move_m: float = 0.05, max_move_m: float = 0.15, max_turn_deg: float = 30.0, n_candidates: int = 1024, seed: int = 0,
    behind_spread: float = 0.45, behind_max_move_m: float = 0.2, min_contrast: float = VIEW_MIN_CONTRAST, view_check_px: int = 64,
) -> list[dict]:
    """Random reachable, collision-free goal configurations near ``q_start`` whose wrist view is
    informative: first ``n_occluded`` (default: all ``n``) whose camera is hidden from the start
    camera by the exact scene (:func:`line_of_sight_m` < 0: the straight camera path runs through
    the geometry), then behind-wall ones up to ``n_behind`` with the camera behind the bin's front
    wall (:data:`BEHIND_WALL`), then any; fewer of a kind when the candidates hold fewer. The hidden
    goals are taken most textured view first (largest :func:`view_contrast` of the check view): the image cost
    has only the view to go by, and a plain view (floor, or floor and one wall edge) recurs
    elsewhere in the scene (the bin's walls look alike), where the controller can settle in a
    look-alike; the others far apart from each other (greedy farthest point in camera position).

    Candidates ``q_start + U(-spread, spread)^7`` (clipped to the limits) are kept when every link
    ellipsoid clears the exact geometry by ``margin_m``, the metric finds no collision, there is no
    self-collision, the camera moves ``min_move_m``..``max_move_m`` from the start and turns by at
    most ``max_turn_deg`` (half the candidates use ``behind_spread``; a camera behind the wall or
    hidden from the start may move up to ``behind_max_move_m``: reaching around a wall takes a
    longer move), and the view
    is filled by the scene (mean alpha > 0.98: at most 2 % of the view's colour is background) with
    contrast (:func:`view_contrast` > ``min_contrast``: a plain view of floor and wall is ambiguous for any
    encoder). The fill is a mean over the view, not a per-pixel minimum: a close view resolves the
    gaps between single splats (isolated pixels of alpha 0.8..0.97, the start view has them too),
    and a per-pixel bar rejected nearly every view from inside the bin, i.e. every behind-wall
    goal. The view is judged at most ``view_check_px`` pixels wide (same field of view, scaled
    intrinsics), so that the goals do not depend on the image size.

    The candidates and every filter's verdict: :func:`reach_candidates`.

    Returns:
        [{"name", "q" (7,), "camera_pose" (4, 4) world <- camera, "clearance_m", "behind_wall"}].
    """
    cands = reach_candidates(
        robot, scene, renderer, camera, q_start=q_start, spread=spread, margin_m=margin_m, min_move_m=min_move_m, max_move_m=max_move_m,
        max_turn_deg=max_turn_deg, n_candidates=n_candidates, seed=seed, behind_spread=behind_spread, behind_max_move_m=behind_max_move_m,
        min_contrast=min_contrast, view_check_px=view_check_px,
    )
    keep = cands.kept
    q, t, clear, behind = cands.q[keep], cands.camera_pose[keep], cands.clearance_m[keep], cands.behind_wall[keep]
    los_all = cands.line_of_sight_m if cands.line_of_sight_m is not None else np.full(len(cands.q), np.inf)
    occl, los, std = cands.occluded[keep], los_all[keep], cands.view_std[keep]
    chosen: list[int] = []

    def pick(pool: np.ndarray, count: int, textured: bool = False) -> None:  # greedy farthest point in camera position
        for _ in range(max(count, 0)):
            cand = [int(i) for i in pool if int(i) not in chosen]
            if not cand:
                return
            if textured:  # the hidden goals: the most textured view first
                chosen.append(cand[int(np.argmax(std[cand]))])
            elif not chosen:
                chosen.append(cand[int(np.argmax(clear[cand]))])
            else:
                d = np.min(np.linalg.norm(t[cand][:, None, :3, 3] - t[chosen][None, :, :3, 3], axis=-1), axis=1)
                chosen.append(cand[int(np.argmax(d))])

    pick(np.flatnonzero(occl), min(n if n_occluded is None else n_occluded, n), textured=True)
    pick(np.flatnonzero(behind), min(min(n_behind, n) - int(sum(behind[i] for i in chosen)), n - len(chosen)))
    pick(np.arange(len(q)), n - len(chosen))
    return [
        {"name": f"goal{j}" + ("_behind_wall" if behind[i] else ""), "q": q[i], "camera_pose": t[i], "clearance_m": float(clear[i]), "behind_wall": bool(behind[i]),
         "occluded": bool(occl[i]), "line_of_sight_m": float(los[i])}
        for j, i in enumerate(chosen)
    ]
