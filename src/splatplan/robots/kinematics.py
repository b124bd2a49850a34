"""Flat kinematic trees and the numpy reference forward kinematics (float64).

A robot's kinematics is kept in flat arrays over its links in topological order (every parent
before its children), so forward kinematics is one loop over links:

    T_world<-link[l] = T_world<-link[parent[l]] @ origin[l] @ motion(jtype[l], axis[l], value)

``origin[l]`` is the joint frame in the parent link's frame at zero joint value (for the root link:
world <- robot base, the base pose). ``value`` is ``q[qidx[l]] * mult[l] + offset[l]``: an actuated
joint has (mult, offset) = (1, 0); a mimic joint points at the dof it follows with the URDF's
multiplier and offset. Joints that are not degrees of freedom of the robot (Panda's fingers, Go2's
legs) are baked into ``origin`` as fixed joints at load time.

Joint types (``jtype``): fixed, revolute (rotation about ``axis``; also URDF "continuous"),
prismatic (translation along ``axis``), planar base (3 dofs x, y, yaw: Trans(x, y, 0) @ Rz(yaw)),
translation base (3 dofs x, y, z: Trans(x, y, z)). Units: metres and radians, z-up world.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FIXED, REVOLUTE, PRISMATIC, PLANAR, TRANSLATION = 0, 1, 2, 3, 4
JOINT_TYPE_NAMES = {FIXED: "fixed", REVOLUTE: "revolute", PRISMATIC: "prismatic", PLANAR: "planar", TRANSLATION: "translation"}
#: Number of configuration entries each joint type consumes.
JOINT_NQ = {FIXED: 0, REVOLUTE: 1, PRISMATIC: 1, PLANAR: 3, TRANSLATION: 3}


@dataclass
class Kinematics:
    """A kinematic tree as flat arrays over L links in topological order."""

    link_names: list[str]  # (L,)
    joint_names: list[str]  # (L,) name of the joint into each link ("" for a root without joint)
    parent: np.ndarray  # (L,) int64, -1 for the root
    jtype: np.ndarray  # (L,) int64, one of FIXED..TRANSLATION
    axis: np.ndarray  # (L, 3) float64 unit axis in the joint frame
    origin: np.ndarray  # (L, 4, 4) float64 parent link <- joint frame at zero value (root: world <- base)
    qidx: np.ndarray  # (L,) int64 first dof driving the joint, -1 for fixed joints
    mult: np.ndarray  # (L,) float64 mimic multiplier (1 for actuated joints)
    offset: np.ndarray  # (L,) float64 mimic offset (0 for actuated joints)

    @property
    def n_links(self) -> int:
        return len(self.link_names)

    def validate(self, dof: int) -> None:
        assert self.parent[0] == -1 and np.all(self.parent[1:] < np.arange(1, self.n_links)), "links not in topological order"
        for l in range(self.n_links):
            n = JOINT_NQ[int(self.jtype[l])]
            if n:
                assert 0 <= self.qidx[l] and self.qidx[l] + n <= dof, f"joint of link {self.link_names[l]} has no dof"

    def children(self) -> list[list[int]]:
        out: list[list[int]] = [[] for _ in range(self.n_links)]
        for l in range(1, self.n_links):
            out[int(self.parent[l])].append(l)
        return out


def skew(k: np.ndarray) -> np.ndarray:
    """Cross-product matrix [k]x (3, 3) of a vector k (3,): [k]x v = k x v."""
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def axis_angle_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotation by ``angle`` (...,) about the unit ``axis`` (3,): (..., 3, 3) (Rodrigues)."""
    k = np.asarray(axis, dtype=np.float64)
    c, s = np.cos(angle)[..., None, None], np.sin(angle)[..., None, None]
    return c * np.eye(3) + s * skew(k) + (1.0 - c) * np.outer(k, k)


def joint_motion(jtype: int, axis: np.ndarray, q: np.ndarray, qidx: int, mult: float, offset: float) -> np.ndarray | None:
    """Motion transform (..., 4, 4) of one joint for configurations q (..., dof); None when fixed."""
    if jtype == FIXED:
        return None
    m = np.broadcast_to(np.eye(4), q.shape[:-1] + (4, 4)).copy()
    if jtype == REVOLUTE:
        m[..., :3, :3] = axis_angle_matrix(axis, q[..., qidx] * mult + offset)
    elif jtype == PRISMATIC:
        m[..., :3, 3] = (q[..., qidx] * mult + offset)[..., None] * axis
    elif jtype == PLANAR:
        m[..., 0, 3] = q[..., qidx]
        m[..., 1, 3] = q[..., qidx + 1]
        m[..., :3, :3] = axis_angle_matrix(np.array([0.0, 0.0, 1.0]), q[..., qidx + 2])
    elif jtype == TRANSLATION:
        m[..., :3, 3] = q[..., qidx : qidx + 3]
    else:  # pragma: no cover - validated at construction
        raise ValueError(f"unknown joint type {jtype}")
    return m


def link_poses_ref(kin: Kinematics, q: np.ndarray) -> np.ndarray:
    """Numpy reference FK: q (..., dof) float64 -> (..., L, 4, 4) world <- link."""
    q = np.asarray(q, dtype=np.float64)
    out = np.empty(q.shape[:-1] + (kin.n_links, 4, 4))
    for l in range(kin.n_links):
        p = int(kin.parent[l])
        t = kin.origin[l] if p < 0 else out[..., p, :, :] @ kin.origin[l]
        m = joint_motion(int(kin.jtype[l]), kin.axis[l], q, int(kin.qidx[l]), float(kin.mult[l]), float(kin.offset[l]))
        out[..., l, :, :] = t if m is None else t @ m
    return out


def link_chain(kin: Kinematics, link: int) -> tuple[list, np.ndarray]:
    """The moving joints from the root down to ``link`` with the constant transforms between them:
    ([(fixed (4, 4) before the joint, jtype, axis, qidx, mult, offset), ...], fixed (4, 4) after the last)."""
    path = []
    k = int(link)
    while k >= 0:
        path.append(k)
        k = int(kin.parent[k])
    segments, pre = [], np.eye(4)
    for l in reversed(path):  # root first; the root's origin is world <- base
        pre = pre @ kin.origin[l]
        if int(kin.jtype[l]) != FIXED:
            segments.append((pre, int(kin.jtype[l]), kin.axis[l], int(kin.qidx[l]), float(kin.mult[l]), float(kin.offset[l])))
            pre = np.eye(4)
    return segments, pre


def chain_pose(chain: tuple[list, np.ndarray], q: np.ndarray) -> np.ndarray:
    """World <- link (..., 4, 4) of the link of ``chain`` at configurations q (..., dof): the
    reference FK of :func:`link_poses_ref` restricted to the link's ancestors, fixed joints folded
    into constant transforms (what a cost on one link needs, without FK of every link)."""
    segments, tail = chain
    t = None
    for pre, jtype, axis, qidx, mult, offset in segments:
        t = np.broadcast_to(pre, q.shape[:-1] + (4, 4)) if t is None else t @ pre
        t = t @ joint_motion(jtype, axis, q, qidx, mult, offset)
    if t is None:
        return np.broadcast_to(tail, q.shape[:-1] + (4, 4)).copy()
    return t @ tail


def bake_fixed(kin: Kinematics, keep: np.ndarray, values: np.ndarray) -> Kinematics:
    """Turn every joint with ``keep[l] == False`` into a fixed joint at ``values[l]`` (its joint value)."""
    origin = kin.origin.copy()
    jtype, qidx = kin.jtype.copy(), kin.qidx.copy()
    mult, offset = kin.mult.copy(), kin.offset.copy()
    for l in range(kin.n_links):
        if keep[l] or jtype[l] == FIXED:
            continue
        if jtype[l] not in (REVOLUTE, PRISMATIC):
            raise ValueError("only revolute and prismatic joints can be fixed")
        m = joint_motion(int(jtype[l]), kin.axis[l], np.array([float(values[l])]), 0, 1.0, 0.0)
        origin[l] = origin[l] @ m
        jtype[l], qidx[l], mult[l], offset[l] = FIXED, -1, 1.0, 0.0
    return Kinematics(list(kin.link_names), list(kin.joint_names), kin.parent.copy(), jtype, kin.axis.copy(), origin, qidx, mult, offset)


def rigid_groups(kin: Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """Collapse fixed joints: (frame_of_link (L,) int, link_in_frame (L, 4, 4) frame <- link).

    A "frame" is the root link or a link whose joint moves; every link rigidly attached to a frame
    (through fixed joints) is expressed in it. Frame ids are link indices of the frame links.
    """
    frame = np.empty(kin.n_links, dtype=np.int64)
    rel = np.empty((kin.n_links, 4, 4))
    for l in range(kin.n_links):
        p = int(kin.parent[l])
        if p < 0 or kin.jtype[l] != FIXED:
            frame[l], rel[l] = l, np.eye(4)
        else:
            frame[l], rel[l] = frame[p], rel[p] @ kin.origin[l]
    return frame, rel
