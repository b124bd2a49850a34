"""Forward kinematics as a Warp kernel: configurations (B, dof) -> ellipsoid poses (B*E,), CPU or CUDA.

One thread per configuration walks the robot's *frames* in topological order. Frames are the
root link and every link whose joint moves; links attached by fixed joints are folded into their
frame at build time (:func:`..kinematics.rigid_groups`), so the Panda's 13 links become 8 frames
and the Go2 (legs fixed) one. The running pose is kept in registers; a frame whose children are
not its immediate successor is also stored in a per-configuration scratch slot (chains such as
the Panda need none). Each frame writes its ellipsoids' world centres and rotations:
row b*E + e = ellipsoid e of configuration b, rotation = world <- ellipsoid frame.

What a frame writes are *attachments*: (link, link <- attachment transform) pairs, by default the
robot's ellipsoids. :func:`attachments` makes others: a subset of the ellipsoids (the moving ones
of a collision cost) or bare link frames (an end effector's pose), same kernel, E = their count.

Float32 throughout; the float64 numpy reference is :meth:`Robot.link_poses` /
:meth:`Robot.ellipsoid_frames`, and tests compare both on random configurations.
"""

from __future__ import annotations

import numpy as np

from .._warp import launch_split
from .._warp import wp as _wp
from .kinematics import FIXED, PLANAR, PRISMATIC, REVOLUTE, TRANSLATION, skew

wp = _wp()
wp.set_module_options({"enable_backward": False})  # forward only: halves compile time

#: CPU launches per worker thread for one batch.
CHUNKS_PER_THREAD = 4
#: Below this batch size a CPU launch runs on the calling thread.
MIN_SPLIT = 4096


@wp.struct
class FKModel:
    """Flat robot model on one device (F frames, E ellipsoids)."""

    n_frames: int
    n_ell: int
    n_slots: int
    parent: wp.array(dtype=wp.int32)  # (F,) parent frame, -1 for the root
    jtype: wp.array(dtype=wp.int32)  # (F,) kinematics joint type
    qidx: wp.array(dtype=wp.int32)  # (F,) first dof, -1 when fixed
    mult: wp.array(dtype=wp.float32)  # (F,) mimic multiplier
    offset: wp.array(dtype=wp.float32)  # (F,) mimic offset
    axis: wp.array(dtype=wp.vec3)  # (F,) unit joint axis (joint frame)
    orot: wp.array(dtype=wp.mat33)  # (F,) parent frame <- joint frame rotation at zero value
    arot: wp.array(dtype=wp.mat33)  # (F,) orot @ [axis]_x (revolute: orot @ R(v) = c orot + s arot + (1 - c) brot)
    brot: wp.array(dtype=wp.mat33)  # (F,) orot @ axis axis^T
    opos: wp.array(dtype=wp.vec3)  # (F,) parent frame <- joint frame translation
    slot: wp.array(dtype=wp.int32)  # (F,) scratch slot, -1 when not stored
    ell_start: wp.array(dtype=wp.int32)  # (F+1,) ellipsoids of frame f: ell_start[f]..ell_start[f+1]
    ell_id: wp.array(dtype=wp.int32)  # (E,) output index of each (frame-sorted) ellipsoid
    erot: wp.array(dtype=wp.mat33)  # (E,) frame <- ellipsoid rotation (frame-sorted)
    epos: wp.array(dtype=wp.vec3)  # (E,) ellipsoid centre in the frame (frame-sorted)


@wp.func
def axis_angle_mat(k: wp.vec3, angle: float):
    """Rodrigues: rotation by ``angle`` about the unit axis ``k``."""
    c = wp.cos(angle)
    s = wp.sin(angle)
    t = 1.0 - c
    return wp.mat33(
        t * k[0] * k[0] + c, t * k[0] * k[1] - s * k[2], t * k[0] * k[2] + s * k[1],
        t * k[0] * k[1] + s * k[2], t * k[1] * k[1] + c, t * k[1] * k[2] - s * k[0],
        t * k[0] * k[2] - s * k[1], t * k[1] * k[2] + s * k[0], t * k[2] * k[2] + c,
    )  # fmt: skip


@wp.func
def other_joint(m: FKModel, f: int, q: wp.array2d(dtype=wp.float32), b: int):
    """Local transform (parent frame <- frame) of a fixed, prismatic, planar or translation joint."""
    lrot = m.orot[f]
    lpos = m.opos[f]
    jt = m.jtype[f]
    qi = m.qidx[f]
    if jt == 2:  # prismatic
        lpos = lpos + lrot @ (m.axis[f] * (q[b, qi] * m.mult[f] + m.offset[f]))
    elif jt == 3:  # planar base: Trans(x, y, 0) Rz(yaw)
        lpos = lpos + lrot @ wp.vec3(q[b, qi], q[b, qi + 1], 0.0)
        lrot = lrot @ axis_angle_mat(wp.vec3(0.0, 0.0, 1.0), q[b, qi + 2])
    elif jt == 4:  # translation base
        lpos = lpos + lrot @ wp.vec3(q[b, qi], q[b, qi + 1], q[b, qi + 2])
    return lrot, lpos


@wp.func
def fk_config(
    m: FKModel,
    q: wp.array2d(dtype=wp.float32),  # (B, dof)
    b: int,  # the configuration (row of q)
    scratch_rot: wp.array(dtype=wp.mat33),  # (B * n_slots,) or (1,)
    scratch_pos: wp.array(dtype=wp.vec3),
    out_centers: wp.array(dtype=wp.vec3),  # (B * E,) world frame
    out_rots: wp.array(dtype=wp.mat33),  # (B * E,) world <- ellipsoid
):
    """The FK of configuration b: its ellipsoids' poses into rows b E .. b E + E - 1 (the body of
    :func:`fk_kernel`, for kernels that compute configurations themselves)."""
    # Pose of the previous frame; for the root (f = 0, parent -1 = f - 1) the identity.
    rot = wp.identity(n=3, dtype=float)
    pos = wp.vec3(0.0, 0.0, 0.0)
    for f in range(m.n_frames):
        par = m.parent[f]
        if par != f - 1:  # parent is not the previous frame: read its stored pose
            s = b * m.n_slots + m.slot[par]
            rot = scratch_rot[s]
            pos = scratch_pos[s]
        lrot = wp.mat33()
        lpos = wp.vec3()
        if m.jtype[f] == 1:  # revolute (the common case), Rodrigues folded into precomputed matrices
            v = q[b, m.qidx[f]] * m.mult[f] + m.offset[f]
            c = wp.cos(v)
            lrot = m.orot[f] * c + m.arot[f] * wp.sin(v) + m.brot[f] * (1.0 - c)
            lpos = m.opos[f]
        else:
            lrot, lpos = other_joint(m, f, q, b)
        pos = rot @ lpos + pos
        rot = rot @ lrot
        if m.slot[f] >= 0:
            s = b * m.n_slots + m.slot[f]
            scratch_rot[s] = rot
            scratch_pos[s] = pos
        for k in range(m.ell_start[f], m.ell_start[f + 1]):
            o = b * m.n_ell + m.ell_id[k]
            out_centers[o] = rot @ m.epos[k] + pos
            out_rots[o] = rot @ m.erot[k]


@wp.kernel
def fk_kernel(
    m: FKModel,
    q: wp.array2d(dtype=wp.float32),  # (B, dof)
    b0: int,  # first configuration of this launch
    scratch_rot: wp.array(dtype=wp.mat33),  # (B * n_slots,) or (1,)
    scratch_pos: wp.array(dtype=wp.vec3),
    out_centers: wp.array(dtype=wp.vec3),  # (B * E,) world frame
    out_rots: wp.array(dtype=wp.mat33),  # (B * E,) world <- ellipsoid
):
    """One thread per configuration (:func:`fk_config`)."""
    fk_config(m, q, wp.tid() + b0, scratch_rot, scratch_pos, out_centers, out_rots)


assert (FIXED, REVOLUTE, PRISMATIC, PLANAR, TRANSLATION) == (0, 1, 2, 3, 4)  # codes used in the kernel


class Attachments:
    """What the FK kernel writes per configuration: A (link, link <- attachment) pairs.

    Attributes:
        key: hashable identity (model cache key).
        links: (A,) int link indices.
        local: (A, 4, 4) link <- attachment transforms.
    """

    def __init__(self, key, links, local) -> None:
        self.key = key
        self.links = np.asarray(links, dtype=np.int64).reshape(-1)
        self.local = np.asarray(local, dtype=np.float64).reshape(-1, 4, 4)
        if self.links.size == 0:
            raise ValueError("attachments: at least one is needed")


def attachments(robot, ellipsoids=None, links=None) -> Attachments | None:
    """None (every ellipsoid, the default), a subset of the ellipsoids (a list of indices, output
    in that order), or the frames of the links ``links`` (indices; identity local transforms)."""
    if links is not None:
        li = tuple(int(i) for i in np.asarray(links).reshape(-1))
        return Attachments(("links", li), li, np.broadcast_to(np.eye(4), (len(li), 4, 4)))
    if ellipsoids is None:
        return None
    ei = tuple(int(i) for i in np.asarray(ellipsoids).reshape(-1))
    if ei == tuple(range(robot.n_ellipsoids)):
        return None
    return Attachments(("ellipsoids", ei), robot.ellipsoid_link[list(ei)], robot.ellipsoid_local[list(ei)])


def model_arrays(robot, attach: Attachments | None = None) -> dict[str, np.ndarray]:
    """The flat frame model of a robot as numpy arrays (float32/int32), device independent;
    ``attach``: what each configuration writes (default: every ellipsoid)."""
    kin = robot.kin
    frames = [l for l in range(kin.n_links) if kin.parent[l] < 0 or kin.jtype[l] != FIXED]
    fid = {l: i for i, l in enumerate(frames)}
    fol, rel = robot.frame_of_link, robot.link_in_frame
    parent = np.array([fid[int(fol[kin.parent[l]])] if kin.parent[l] >= 0 else -1 for l in frames], dtype=np.int32)
    origin = np.stack([kin.origin[l] if kin.parent[l] < 0 else rel[kin.parent[l]] @ kin.origin[l] for l in frames])
    kids: dict[int, list[int]] = {}
    for i, p in enumerate(parent):
        kids.setdefault(int(p), []).append(i)
    need = [i for i in range(len(frames)) if any(c != i + 1 for c in kids.get(i, []))]
    slot = -np.ones(len(frames), dtype=np.int32)
    slot[need] = np.arange(len(need), dtype=np.int32)
    a_link = robot.ellipsoid_link if attach is None else attach.links
    a_local = robot.ellipsoid_local if attach is None else attach.local
    ell_frame = np.array([fid[int(fol[l])] for l in a_link], dtype=np.int64)
    order = np.argsort(ell_frame, kind="stable")
    local = rel[a_link] @ a_local  # (E, 4, 4) frame <- ellipsoid
    start = np.searchsorted(ell_frame[order], np.arange(len(frames) + 1)).astype(np.int32)
    return {
        "parent": parent,
        "jtype": kin.jtype[frames].astype(np.int32),
        "qidx": kin.qidx[frames].astype(np.int32),
        "mult": kin.mult[frames].astype(np.float32),
        "offset": kin.offset[frames].astype(np.float32),
        "axis": kin.axis[frames].astype(np.float32),
        "orot": origin[:, :3, :3].astype(np.float32),
        "arot": (origin[:, :3, :3] @ np.stack([skew(k) for k in kin.axis[frames]])).astype(np.float32),
        "brot": (origin[:, :3, :3] @ np.einsum("fi,fj->fij", kin.axis[frames], kin.axis[frames])).astype(np.float32),
        "opos": origin[:, :3, 3].astype(np.float32),
        "slot": slot,
        "ell_start": start,
        "ell_id": order.astype(np.int32),
        "erot": local[order][:, :3, :3].astype(np.float32),
        "epos": local[order][:, :3, 3].astype(np.float32),
    }


def fk_model(robot, device, attach: Attachments | None = None) -> FKModel:
    key = ("model", str(device), None if attach is None else attach.key)
    with robot._lock:
        m = robot._wp_cache.get(key)
        if m is None:
            a = model_arrays(robot, attach)
            m = FKModel()
            m.n_frames = len(a["parent"])
            m.n_ell = len(a["ell_id"])
            m.n_slots = int((a["slot"] >= 0).sum())
            for name in ("parent", "jtype", "qidx", "slot", "ell_start", "ell_id"):
                setattr(m, name, wp.array(a[name], dtype=wp.int32, device=device))
            for name in ("mult", "offset"):
                setattr(m, name, wp.array(a[name], dtype=wp.float32, device=device))
            for name in ("axis", "opos", "epos"):
                setattr(m, name, wp.array(a[name], dtype=wp.vec3, device=device))
            for name in ("orot", "arot", "brot", "erot"):
                setattr(m, name, wp.array(a[name], dtype=wp.mat33, device=device))
            robot._wp_cache[key] = m
        return m


def _scratch(robot, m: FKModel, batch: int, device):
    """Scratch slots: per call for tree-shaped robots (so concurrent calls never share them), a
    cached 1-element placeholder for chains (no slots, nothing allocated per call)."""
    if m.n_slots > 0:
        n = batch * m.n_slots
        return wp.empty(n, dtype=wp.mat33, device=device), wp.empty(n, dtype=wp.vec3, device=device)
    key = ("scratch", str(device))
    with robot._lock:
        s = robot._wp_cache.get(key)
        if s is None:
            s = (wp.empty(1, dtype=wp.mat33, device=device), wp.empty(1, dtype=wp.vec3, device=device))
            robot._wp_cache[key] = s
        return s


def launch_fk(robot, q_wp, out_centers, out_rots, attach: Attachments | None = None) -> None:
    """Validate shapes/dtypes (O(1) host work) and launch :func:`fk_kernel` (see ``Robot.fk_wp``)."""
    from ..errors import SplatplanError

    if not isinstance(q_wp, wp.array) or q_wp.ndim != 2 or q_wp.dtype != wp.float32 or q_wp.shape[1] != robot.dof:
        raise SplatplanError(f"fk_wp: q must be a wp.array of float32 with shape (B, {robot.dof})")
    b = q_wp.shape[0]
    e = robot.n_ellipsoids if attach is None else len(attach.links)
    dev = q_wp.device
    for name, arr, dt in (("out_centers", out_centers, wp.vec3), ("out_rots", out_rots, wp.mat33)):
        if not isinstance(arr, wp.array) or arr.dtype != dt or arr.ndim != 1 or arr.shape[0] < b * e or arr.device != dev:
            raise SplatplanError(f"fk_wp: {name} must be a wp.array of {dt.__name__} with at least B*E = {b * e} rows on {dev}")
    if b == 0:
        return
    m = fk_model(robot, dev, attach)
    sr, sp = _scratch(robot, m, b, dev)
    pool = robot._thread_pool() if dev.is_cpu and b >= MIN_SPLIT else None
    launch_split(fk_kernel, b, [m, q_wp, 0, sr, sp, out_centers, out_rots], dev, pool, offset_at=2, min_split=MIN_SPLIT, min_step=MIN_SPLIT // 4, chunks_per_thread=CHUNKS_PER_THREAD)


def record_fk(robot, q_wp, out_centers, out_rots):
    """A recorded launch of :func:`fk_kernel` (``wp.launch(..., record_cmd=True)``) over every
    row of ``q_wp`` (capacity, dof) into ``out_centers`` / ``out_rots`` (capacity * E,), every
    ellipsoid, for callers that run the same FK many times on small batches: ``cmd.set_dim(b);
    cmd.launch()`` computes rows [0, b). Returns (the command, the arrays it points at: keep them
    alive as long as the command)."""
    dev = q_wp.device
    m = fk_model(robot, dev)
    sr, sp = _scratch(robot, m, int(q_wp.shape[0]), dev)
    cmd = wp.launch(fk_kernel, dim=int(q_wp.shape[0]), inputs=[m, q_wp, 0, sr, sp, out_centers, out_rots], device=dev, record_cmd=True)
    return cmd, (m, sr, sp, q_wp, out_centers, out_rots)
