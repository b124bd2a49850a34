"""`splatplan check`: the CollisionSplatting metric for a batch of link poses or robot configurations.

Two inputs:

* ``--robot sphere:R|ellipsoid:A,B,C --poses POSES.npy``: one link, (B, 3) centres or (B, 7) centre
  + wxyz quaternion (scene frame) -> per-pose outputs, each (B,).
* ``--robot panda|go2|ROBOT.urdf --configs Q.npy``: joint configurations (B, dof) -> per-ellipsoid
  outputs (B, E), per-link collision (B, L) and per-configuration collision (B,).

Long batches run in chunks (``--chunk`` queries per kernel call) so Ctrl-C is honoured between
chunks and a progress bar can move (on a terminal only).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._progress import progress
from .._resources import require_bytes
from ..errors import SplatplanError
from ..robots.builtin import ROBOT_NAME_HELP, parse_robot_name
from ._common import (
    BASE_POSE_HELP, POSITIVE_INT, _load, add_base_pose_arg, add_command, add_device_arg, add_metric_args, atomic_path, load_npy,
    load_poses, metric_config_from_args, parse_base_pose, robot_at, signals_deferred,
)  # fmt: skip

#: queries (link poses) per kernel call: small enough that an interrupt waits < ~1 s on a CPU
DEFAULT_CHUNK = 65_536
#: bytes per link pose of one kernel call (inputs float32/float64 + outputs, host and device): an estimate
CHUNK_BYTES_PER_POSE = 256

_OUTPUTS = ("min_s2", "n_colliding", "in_collision", "softmin", "cost")


def _chunked_query(checker, n: int, chunk: int, query, desc: str) -> dict[str, np.ndarray]:
    """Run ``query(lo, hi) -> QueryResult`` over [0, n) in chunks; concatenate the outputs.

    Each chunk runs with SIGINT/SIGTERM deferred (see :func:`signals_deferred`): an interrupt
    lands between chunks, never while worker threads are inside a kernel.
    """
    parts: dict[str, list[np.ndarray]] = {k: [] for k in _OUTPUTS}
    with progress(total=n, desc=desc, unit="query", unit_scale=True) as bar:
        for lo in range(0, n, chunk):
            hi = min(n, lo + chunk)
            with signals_deferred():
                res = query(lo, hi).as_dict()
            for k in _OUTPUTS:
                parts[k].append(res[k])
            bar.update(hi - lo)
    return {k: np.concatenate(v) if v else np.zeros(0) for k, v in parts.items()}


def _check_link(axes: np.ndarray, centers: np.ndarray, quats: np.ndarray | None, checker, scene, chunk: int) -> dict[str, np.ndarray]:
    """Per-pose outputs (B,) of one link with semi-axes ``axes`` (3,) at ``centers`` (B, 3), ``quats`` (B, 4) wxyz or None."""
    b = len(centers)
    out = _chunked_query(
        checker, b, chunk,
        lambda lo, hi: checker.query(centers[lo:hi], None if quats is None else quats[lo:hi], axes),
        desc="check",
    )  # fmt: skip
    cfg = checker.config
    msg = f"min s2~ = {float(np.min(out['min_s2'])):.4g}" if b else "no poses"
    print(f"{b:,} poses checked against {len(scene):,} splats (n_sigma={cfg.n_sigma:g}, device={checker.device}): "
          f"{int(out['in_collision'].sum()):,} in collision, {msg}")  # fmt: skip
    return out


def _load_configs(args):
    """(robot, q (B, dof) float64) from --robot and --configs, validated (before the slow scene load)."""

    robot = robot_at(args.robot, parse_base_pose(args.base_pose))
    q = load_npy(args.configs, "configs file")
    if q.ndim == 1 and q.shape[0] == robot.dof:
        q = q[None]
    if q.ndim != 2 or q.shape[1] != robot.dof:
        raise SplatplanError(f"configs file {args.configs}: expected shape (B, {robot.dof}) joint configurations of {robot.name} "
                             f"({', '.join(robot.joint_names)}), got {q.shape}")  # fmt: skip
    bad = ~np.isfinite(q).all(axis=1)
    if bad.any():
        raise SplatplanError(f"configs file {args.configs}: {int(bad.sum())} row(s) contain NaN or Inf (first: row {int(np.argmax(bad))})")
    return robot, robot.check_q(q)


def _check_robot(robot, q: np.ndarray, checker, scene, chunk: int) -> dict[str, np.ndarray]:
    lim = np.asarray(robot.joint_limits, dtype=np.float64)
    outside = ((q < lim[:, 0] - 1e-9) | (q > lim[:, 1] + 1e-9)).any(axis=1)
    e = int(robot.n_ellipsoids)
    b = len(q)
    per_chunk = max(1, chunk // max(1, e))  # configurations per chunk (chunk counts link poses)
    query_robot = getattr(checker, "query_robot", None)

    def query(lo: int, hi: int):
        if query_robot is not None:
            res = query_robot(robot, q[lo:hi])
        else:  # the ellipsoids of every configuration, (hi - lo, E, 3/4)
            c, quat, ax = robot.ellipsoids(q[lo:hi])
            res = checker.query(c, quat, ax)
        return res.reshape((-1,))  # (n * E,) rows b * E + e

    flat = _chunked_query(checker, b * e, per_chunk * e, lambda lo, hi: query(lo // e, hi // e), desc="check") if b else {k: np.zeros(0) for k in _OUTPUTS}
    out = {k: v.reshape(b, e) for k, v in flat.items()}  # (B, E) per ellipsoid
    link_idx = np.asarray(robot.ellipsoid_link, dtype=np.int64)  # (E,)
    links = np.unique(link_idx)  # links that carry ellipsoids, (L,)
    hit = out["in_collision"]
    link_hit = np.stack([hit[:, link_idx == li].any(axis=1) for li in links], axis=1) if b else np.zeros((0, len(links)), bool)  # (B, L)
    link_min = np.stack([out["min_s2"][:, link_idx == li].min(axis=1) for li in links], axis=1) if b else np.zeros((0, len(links)), np.float32)
    collision = hit.any(axis=1)  # (B,) scene collision of the whole robot
    with signals_deferred():
        self_hit = np.asarray(robot.self_collision(q), dtype=bool) if b else np.zeros(0, bool)
    names = np.asarray([robot.link_names[li] for li in links])
    res = {
        **out,
        "collision": collision,
        "self_collision": self_hit,
        "outside_joint_limits": outside,
        "link_names": names,
        "link_in_collision": link_hit,
        "link_min_s2": link_min,
        "ellipsoid_link": link_idx,
        "configs": q,
    }
    cfg = checker.config
    worst = ""
    if b and link_hit.any():
        counts = link_hit.sum(axis=0)
        worst = f"; most often hit: {names[int(np.argmax(counts))]} ({int(counts.max()):,} configurations)"
    print(f"{b:,} configurations of {robot.name} ({e} ellipsoids on {len(links)} links) checked against {len(scene):,} splats "
          f"(n_sigma={cfg.n_sigma:g}, device={checker.device}): {int(collision.sum()):,} in collision with the scene, "
          f"{int(self_hit.sum()):,} in self-collision, {int(outside.sum()):,} outside the joint limits{worst}")  # fmt: skip
    return res


def cmd_check(args) -> int:
    from ..metric import CollisionChecker

    try:
        name = parse_robot_name(args.robot)  # fails fast on a malformed sphere:R / ellipsoid:A,B,C
    except SplatplanError as exc:
        raise SplatplanError(f"--robot: {exc}") from None
    link = name.is_point
    axes = np.asarray(name.semi_axes, dtype=np.float64) if link else None  # (3,)
    if (args.poses is None) == (args.configs is None):
        raise SplatplanError("give exactly one of --poses POSES.npy (link poses) or --configs Q.npy (joint configurations)")
    if args.poses is not None and args.base_pose is not None:
        raise SplatplanError("--base-pose places a robot given with --configs; --poses are already world poses")
    if args.poses is not None and not link:
        raise SplatplanError(f"--robot {args.robot!r} is a robot: give --configs Q.npy (B, dof) instead of --poses (which is for a single link: sphere:R or ellipsoid:A,B,C)")
    # one chunk's link poses and outputs (centres, quaternions, semi-axes, five result arrays)
    require_bytes(float(args.chunk) * CHUNK_BYTES_PER_POSE, f"one --chunk of {args.chunk:,} link poses", "--chunk")
    if args.out and not str(args.out).endswith(".npz"):
        raise SplatplanError(f"--out {args.out}: expected a .npz path")
    if args.out and not Path(args.out).parent.exists():
        raise SplatplanError(f"output folder {Path(args.out).parent} does not exist")
    cfg = metric_config_from_args(args)
    # validate the query input before the (slow) scene load
    robot_q = _load_configs(args) if args.configs is not None else load_poses(args.poses)
    scene = _load(args.scene)
    checker = CollisionChecker(scene, device=args.device, config=cfg)
    res = _check_link(axes, *robot_q, checker, scene, args.chunk) if args.poses is not None else _check_robot(*robot_q, checker, scene, args.chunk)
    if args.out:
        with atomic_path(args.out) as tmp:
            with open(tmp, "wb") as f:
                with signals_deferred():  # a half-written archive is removed by atomic_path anyway
                    np.savez(f, **res)
        print(f"wrote {args.out}")
    return 0


def register(sub, eval_sub) -> None:
    s = add_command(sub, "check", cmd_check, "CollisionSplatting metric for a batch of link poses or robot configurations",
                    "CollisionSplatting metric for link poses (--robot sphere:R|ellipsoid:A,B,C --poses) or robot configurations "
                    "(--robot panda|go2|URDF --configs).")  # fmt: skip
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--robot", required=True, help=f"{ROBOT_NAME_HELP}; a point robot (sphere, ellipsoid) takes --poses or --configs, the others --configs")
    s.add_argument("--poses", help="POSES.npy: (B,3) centres or (B,7) centre + wxyz quaternion, scene frame (single-link robots)")
    add_base_pose_arg(s, help=f"--configs robots: {BASE_POSE_HELP}")
    s.add_argument("--configs", help="Q.npy: (B, dof) joint configurations of --robot (rad or m; panda: 7 arm joints, go2: x, y, yaw)")
    s.add_argument("--out", help="OUT.npz with min_s2, n_colliding, in_collision, softmin, cost: (B,) per pose, or (B, E) per "
                   "ellipsoid plus collision (B,), link_in_collision (B, L), link_min_s2 (B, L), link_names (L,) for --configs")  # fmt: skip
    s.add_argument("--chunk", type=POSITIVE_INT, default=DEFAULT_CHUNK, help=f"link poses per kernel call; Ctrl-C is honoured between calls (default {DEFAULT_CHUNK})")
    add_device_arg(s)
    add_metric_args(s)
