"""Batched inverse kinematics by damped least squares (numeric Jacobian), for goal reachability.

Used before a reaching run to decide whether a goal pose is reachable at all (an unreachable goal
is reported before any MPPI step) and to find collision-free goal configurations for the studies.
"""

from __future__ import annotations

import numpy as np
from typing import TYPE_CHECKING

from ..errors import SplatplanError
from ..scenes.splats import quat_to_rotmat

if TYPE_CHECKING:
    from ..robots.robot import Robot


def rotation_error(r: np.ndarray, r_goal: np.ndarray) -> np.ndarray:
    """Axis-angle vector (..., 3) of ``r_goal r^T`` (world frame; rotates r onto r_goal)."""
    m = np.einsum("ij,...kj->...ik", r_goal, r)  # r_goal @ r^T
    angle = np.arccos(np.clip(0.5 * (np.trace(m, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0))
    v = 0.5 * np.stack([m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], axis=-1)
    s = np.sin(angle)[..., None]
    small = s < 1e-6
    axis = np.where(small, v, v / np.where(small, 1.0, s))
    out = np.where(small, v, axis * angle[..., None])
    # angle ~ pi: the antisymmetric part vanishes; use the symmetric part's dominant column
    near_pi = angle > np.pi - 1e-3
    if np.any(near_pi):
        b = 0.5 * (m[near_pi] + np.eye(3))
        col = np.argmax(np.einsum("pii->pi", b), axis=1)
        ax = b[np.arange(len(b)), :, col]
        ax /= np.linalg.norm(ax, axis=1, keepdims=True)
        out[near_pi] = ax * angle[near_pi][:, None]
    return out


def solve_ik(
    robot: Robot,
    position,  # (3,) world
    quat=None,  # (4,) wxyz world <- link, or None (position only)
    *,
    link: str,
    n_seeds: int = 64,
    n_iters: int = 150,
    rot_weight: float = 0.3,
    damping: float = 1e-3,
    seed: int = 0,
    q_init: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Damped-least-squares IK from ``n_seeds`` random starts (plus ``q_init``), within joint limits.

    Returns:
        q (S, dof) final configurations, position errors (S,) metres, orientation errors (S,) rad,
        sorted by ``pos_err + rot_weight * rot_err`` (best first).
    """
    rng = np.random.default_rng(seed)
    lim = np.asarray(robot.joint_limits, dtype=np.float64)
    lo, hi = lim[:, 0], lim[:, 1]
    dof = robot.dof
    q = lo + rng.random((n_seeds, dof)) * (hi - lo)
    q[0] = robot.q_default
    if q_init is not None:
        q = np.concatenate([np.asarray(q_init, np.float64).reshape(-1, dof), q])
    li = list(robot.link_names).index(link)
    p_goal = np.asarray(position, dtype=np.float64).reshape(3)
    r_goal = None if quat is None else quat_to_rotmat(np.asarray(quat, np.float64) / np.linalg.norm(quat))
    eps = 1e-6
    w = np.array([1.0, 1.0, 1.0] + [rot_weight] * 3) if r_goal is not None else np.ones(3)

    def residual(qq: np.ndarray) -> np.ndarray:  # (..., 6) or (..., 3)
        t = robot.link_poses(qq)[..., li, :, :]
        e = p_goal - t[..., :3, 3]
        if r_goal is None:
            return e
        return np.concatenate([e, rotation_error(t[..., :3, :3], r_goal)], axis=-1)

    for _ in range(n_iters):
        b = q.shape[0]
        qp = np.repeat(q[:, None, :], dof + 1, axis=1)  # (B, dof+1, dof)
        qp[:, 1:, :] += eps * np.eye(dof)
        res = residual(qp)  # (B, dof+1, m)
        e = res[:, 0] * w  # (B, m)
        jac = -(res[:, 1:] - res[:, :1]).transpose(0, 2, 1) / eps * w[None, :, None]  # (B, m, dof): d(-e)/dq
        jt = jac.transpose(0, 2, 1)
        a = jt @ jac + damping * np.eye(dof)
        dq = np.linalg.solve(a, np.einsum("bdm,bm->bd", jt, e)[..., None])[..., 0]
        step = np.clip(dq, -0.3, 0.3)
        q = np.clip(q + step, lo, hi)
    res = residual(q)
    pos_err = np.linalg.norm(res[:, :3], axis=1)
    rot_err = np.linalg.norm(res[:, 3:], axis=1) if r_goal is not None else np.zeros(len(q))
    order = np.argsort(pos_err + rot_weight * rot_err)
    return q[order], pos_err[order], rot_err[order]


def link_pose(robot: Robot, q: np.ndarray, link: str) -> np.ndarray:
    """(7,) pose ``X,Y,Z,QW,QX,QY,QZ`` of ``link`` at configuration ``q`` (dof,): world frame,
    metres, wxyz: the format of ``--goal-pose``."""
    from ..scenes.splats import rotmat_to_quat

    t = robot.link_poses(np.asarray(q, np.float64).reshape(1, -1))[0, list(robot.link_names).index(link)]  # (4, 4) world <- link
    quat = np.asarray(rotmat_to_quat(t[None, :3, :3]), np.float64).reshape(4)
    return np.concatenate([t[:3, 3], quat * (1.0 if quat[0] >= 0 else -1.0)])  # w >= 0: one spelling of each rotation


def format_pose(pose: np.ndarray) -> str:
    """``X,Y,Z,QW,QX,QY,QZ`` to 4 decimals (0.1 mm, about 0.01 deg): pasteable as ``--goal-pose``."""
    return ",".join(f"{v:.4f}" for v in np.asarray(pose, np.float64).reshape(7))


def unreachable_message(robot: Robot, q_best: np.ndarray, pos_err: float, rot_err: float, link: str, n_seeds: int) -> str:
    """The part of an "unreachable goal pose" error every caller shares: how far the best IK
    solution (of ``n_seeds`` starts) lands from the goal, and the pose it does reach, in the format
    of ``--goal-pose`` (the nearest reachable pose the solver found)."""
    return (f"the closest IK solution ({n_seeds} starts) misses it by {pos_err * 100:.2f} cm / {np.degrees(rot_err):.1f} deg; "
            f"the nearest reachable pose found is --goal-pose {format_pose(link_pose(robot, q_best, link))}")  # fmt: skip


def collision_report(robot: Robot, checker, q: np.ndarray, near: np.ndarray | None = None, max_links: int = 3) -> str:
    """Which links of ``robot`` collide at the configurations ``q`` (S, dof), and where: how many of
    the S each link hits, then, at the one nearest to ``near`` (the first without it), the splats
    each colliding link hits (:meth:`~splatplan.metric.checker.CollisionChecker.blockers`: count
    and centroid, world frame) and the remedy for the first. One clause, for error messages."""
    q = np.asarray(q, np.float64).reshape(-1, robot.dof)
    hit = np.asarray(checker.collides_robot(robot, q), bool).reshape(len(q), -1)  # (S, E)
    owner = np.asarray(robot.ellipsoid_link)  # (E,) link index of each ellipsoid
    names = list(robot.link_names)
    links = sorted({int(li) for li in owner[hit.any(axis=0)]}, key=lambda li: -int(hit[:, owner == li].any(axis=1).sum()))
    counts = ", ".join(f"{names[li]} in {int(hit[:, owner == li].any(axis=1).sum())}" for li in links[:max_links])
    k = 0 if near is None else int(np.argmin(np.linalg.norm(q - np.asarray(near, np.float64).reshape(1, -1), axis=1)))
    c, quat, axes = robot.ellipsoids(q[k])
    parts, remedy = [], ""
    for li in [li for li in links if hit[k, owner == li].any()][:max_links]:
        e = [int(j) for j in np.nonzero((owner == li) & hit[k])[0]]
        bs = [checker.blockers(c[j], quat[j], axes[j]) for j in e]
        n = sum(b.n for b in bs)
        cen = np.mean([b.centroid for b in bs if b.n], axis=0) if n else np.asarray(c[e[0]], np.float64)
        parts.append(f"{names[li]} hits {n} splat(s) around ({', '.join(f'{v:.3f}' for v in cen)})")
        if not remedy and n:
            remedy = next(b for b in bs if b.n).remedy()
    where = "the one nearest the start" if near is not None else "the best one"
    text = f"colliding links: {counts or 'none'}; at {where}: {'; '.join(parts) or 'no link'}"
    return text + (f" ({remedy})" if remedy else "")


def collision_free_ik(
    robot: Robot,
    checker,
    position,  # (3,) world
    quat,  # (4,) wxyz world <- link
    *,
    link: str,
    near: np.ndarray | None = None,  # (dof,) prefer the solution closest to this (e.g. the start)
    pos_tol: float = 0.005,
    rot_tol: float = np.radians(2.0),
    n_seeds: int = 64,
    seed: int = 0,
) -> np.ndarray:
    """A configuration (dof,) placing ``link`` at the pose, within the tolerances and free of
    collision under ``checker`` (its n_sigma); the free solution nearest to ``near`` in joint space.

    Raises:
        SplatplanError: no IK solution reaches the pose (the message gives the nearest reachable
            pose found, in the format of ``--goal-pose``), or every one collides (the message names
            the links and the splats they hit).
    """
    q, pe, re = solve_ik(robot, position, quat, link=link, n_seeds=n_seeds, seed=seed, q_init=near)
    ok = (pe < pos_tol) & (re < rot_tol)
    if not ok.any():
        raise SplatplanError(f"goal pose unreachable for {robot.name}: {unreachable_message(robot, q[0], pe[0], re[0], link, len(q))}; "
                             "plan there, or move the goal or the robot's base (--base-pose)")  # fmt: skip
    q = q[ok]
    free = ~np.asarray(checker.collides_robot(robot, q)).any(axis=-1)
    if not free.any():
        raise SplatplanError(f"goal pose: all {len(q)} IK solutions of {robot.name} are in collision (n_sigma = {checker.n_sigma:g}): "
                             f"{collision_report(robot, checker, q, near)}; move the goal or the base, or lower n_sigma")  # fmt: skip
    q = q[free]
    if near is not None:
        q = q[np.argsort(np.linalg.norm(q - np.asarray(near, np.float64), axis=1))]
    return q[0]


def down_quat(yaw: float = 0.0) -> np.ndarray:
    """wxyz quaternion of a gripper pointing straight down (tool z = world -z), turned by ``yaw``."""
    return np.array([0.0, np.cos(yaw / 2), np.sin(yaw / 2), 0.0])


def check_reachable(robot: Robot, position, quat, link: str, tol_m: float = 0.003, tol_deg: float = 2.0, n_seeds: int = 24, seed: int = 0) -> np.ndarray:
    """IK (damped least squares from ``n_seeds`` starts) for the goal pose; returns the solutions
    (S, dof) that reach it, best first. Raises "unreachable goal pose" when none does."""
    p = np.asarray(position, np.float64).reshape(3)
    base = robot.base_pose[:3, 3]
    reach = float(robot.info.get("reach_m", 1.2))
    q, pe, re = solve_ik(robot, p, quat, link=link, n_seeds=n_seeds, n_iters=60, seed=seed)
    ok = (pe < tol_m) & (re < np.deg2rad(tol_deg))
    far = float(np.linalg.norm(p - base))
    if far > reach or not np.any(ok):
        why = f"{p.round(3).tolist()} is {far:.2f} m from the base of {robot.name} (reach < {reach:.2f} m)" if far > reach else (
            f"position {p.round(3).tolist()}, quat {np.round(quat, 3).tolist()}")  # fmt: skip
        raise SplatplanError(f"unreachable goal pose: {why}: {unreachable_message(robot, q[0], pe[0], re[0], link, len(q))}; "
                             "pick a pose inside the workspace")  # fmt: skip
    return q[ok]
