"""`splatplan check`: the CollisionSplatting metric for a batch of link poses or robot configurations.

Two inputs:

* ``--robot sphere:R|ellipsoid:A,B,C --poses POSES.npy``: one link, (B, 3) centres or (B, 7) centre
  + wxyz quaternion (scene frame) -> per-pose outputs, each (B,).
* ``--robot panda|go2|ROBOT.urdf --configs Q.npy``: joint configurations (B, dof) -> per-ellipsoid
  outputs (B, E), per-link collision (B, L) and per-configuration collision (B,).
* ``--plan PATH.json``: the vertices of a ``splatplan plan`` result, checked as ``--configs`` with
  the robot, base pose, metric settings and (ground robots) terrain the result records, unless
  flags give others (a one-line warning where they differ from the record).

Every output also comes in metres: ``clearance_m``, the estimate
``(sqrt(min s2~) - 1) x smallest semi-axis`` (:func:`~splatplan.planners.clearance.s2_to_metres`:
a lower bound on the distance to the nearest splat mean, smaller by the n_sigma inflation; exact in
s2~ below the metric's s2_cap, "at least" beyond it).

Long batches run in chunks (``--chunk`` queries per kernel call) so Ctrl-C is honoured between
chunks and a progress bar can move (on a terminal only).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from .._progress import progress
from .._resources import require_bytes
from ..errors import SplatplanError
from ..robots.builtin import ROBOT_NAME_HELP, parse_robot_name
from ._results import RecordedFrame, check_scene, fill_robot, metric_differences, note, read_plan, recorded_metric, warn
from ._common import (
    BASE_POSE_HELP, POSITIVE_INT, _load, add_base_pose_arg, add_command, add_device_arg, add_metric_args, atomic_path, load_npy,
    load_poses, metric_config_from_args, parse_base_pose, robot_at, signals_deferred, config_from_args,
)  # fmt: skip

#: queries (link poses) per kernel call: small enough that an interrupt waits < ~1 s on a CPU
DEFAULT_CHUNK = 65_536
#: bytes per link pose of one kernel call (inputs float32/float64 + outputs, host and device): an estimate
CHUNK_BYTES_PER_POSE = 256

_OUTPUTS = ("min_s2", "n_colliding", "in_collision", "softmin", "cost")


def _metres(min_s2: np.ndarray, semi_axes: np.ndarray, cap: float) -> tuple[np.ndarray, str]:
    """(clearance estimates (m) shaped like ``min_s2`` (..., E), "at least " when the smallest is capped
    (the metric looks no farther than s2_cap) else "")."""
    from ..planners.clearance import s2_to_metres

    s2 = np.asarray(min_s2, dtype=np.float64)
    m = s2_to_metres(np.minimum(s2, cap), semi_axes)
    if m.size == 0:
        return m, ""
    return m, ("at least " if not s2.reshape(-1)[int(np.argmin(m))] < cap else "")


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
    out["clearance_m"], least = _metres(out["min_s2"][:, None], np.asarray(axes, np.float64)[None], cfg.s2_cap)
    out["clearance_m"] = out["clearance_m"][:, 0]
    msg = f"min s2~ = {float(np.min(out['min_s2'])):.4g}, clearance {least}{float(np.min(out['clearance_m'])) * 100:.2f} cm" if b else "no poses"
    print(f"{b:,} poses checked against {len(scene):,} splats (n_sigma={cfg.n_sigma:g}, device={checker.device}): "
          f"{int(out['in_collision'].sum()):,} in collision, {msg}")  # fmt: skip
    return out


def _load_configs(args, q: np.ndarray | None = None):
    """(robot, q (B, dof) float64) from --robot and --configs (or the given ``q``, a plan's path),
    validated (before the slow scene load)."""

    robot = robot_at(args.robot, parse_base_pose(args.base_pose))
    what = f"configs file {args.configs}" if q is None else f"--plan {args.plan}: the path"
    q = load_npy(args.configs, "configs file") if q is None else q
    if q.ndim == 2 and q.shape[1] != robot.dof and args.configs is None:
        raise SplatplanError(f"{what} has {q.shape[1]} coordinates per vertex, robot {robot.name} has {robot.dof} dofs ({', '.join(robot.joint_names)}): "
                             "give the --robot it was planned for")  # fmt: skip
    if q.ndim == 1 and q.shape[0] == robot.dof:
        q = q[None]
    if q.ndim != 2 or q.shape[1] != robot.dof:
        raise SplatplanError(f"configs file {args.configs}: expected shape (B, {robot.dof}) joint configurations of {robot.name} "
                             f"({', '.join(robot.joint_names)}), got {q.shape}")  # fmt: skip
    bad = ~np.isfinite(q).all(axis=1)
    if bad.any():
        raise SplatplanError(f"{what}: {int(bad.sum())} row(s) contain NaN or Inf (first: row {int(np.argmax(bad))})")
    return robot, robot.check_q(q)


def _check_robot(robot, q: np.ndarray, checker, scene, chunk: int) -> dict[str, np.ndarray]:
    lim = np.asarray(robot.joint_limits, dtype=np.float64)
    outside = np.any((q < lim[:, 0] - 1e-9) | (q > lim[:, 1] + 1e-9), axis=1)  # (B,)
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
    collision = np.any(hit, axis=1)  # (B,) scene collision of the whole robot
    clear, least = _metres(out["min_s2"], robot.semi_axes, checker.config.s2_cap)  # (B, E) metres
    out["clearance_m"] = clear
    with signals_deferred():
        self_hit = np.asarray(robot.self_collision(q), dtype=bool) if b else np.zeros(0, bool)
    names = np.asarray([robot.link_names[li] for li in links])
    res: dict[str, np.ndarray] = {
        **out,
        "collision": collision,
        "self_collision": self_hit,
        "outside_joint_limits": outside,
        "link_names": names,
        "link_in_collision": link_hit,
        "link_min_s2": link_min,
        "config_clearance_m": clear.min(axis=1) if b else np.zeros(0),  # (B,) metres
        "ellipsoid_link": link_idx,
        "configs": q,
    }
    cfg = checker.config
    worst = ""
    if b and link_hit.any():
        counts = link_hit.sum(axis=0)
        worst = f"; most often hit: {names[int(np.argmax(counts))]} ({int(counts.max()):,} configurations)"
    if b:
        e_min = int(np.argmin(clear.min(axis=0)))
        worst += f"; smallest clearance {least}{float(clear.min()) * 100:.2f} cm ({robot.link_names[int(link_idx[e_min])]}, metric estimate)"
    print(f"{b:,} configurations of {robot.name} ({e} ellipsoids on {len(links)} links) checked against {len(scene):,} splats "
          f"(n_sigma={cfg.n_sigma:g}, device={checker.device}): {int(collision.sum()):,} in collision with the scene, "
          f"{int(self_hit.sum()):,} in self-collision, {int(outside.sum()):,} outside the joint limits{worst}")  # fmt: skip
    return res


def _from_plan(args) -> tuple[np.ndarray, RecordedFrame | None]:
    """--plan: the path (P, dof) and the frame it records; fills --robot and --base-pose from it."""
    if args.configs is not None or args.poses is not None:
        raise SplatplanError("give one of --poses, --configs or --plan")
    path, frame = read_plan(args.plan)
    fill_robot(args, frame)
    if args.robot is None:
        raise SplatplanError(f"--plan {args.plan} records no robot (an older result file): give --robot (and --base-pose) it was planned with")
    return path, frame


def _metric_config(args, frame: RecordedFrame | None):
    """The metric flags over the settings the plan records (else the defaults); one warning where an
    explicit flag departs from the record."""
    rec = recorded_metric(frame)
    if rec is None or frame is None:  # (a recorded metric comes with its frame)
        return metric_config_from_args(args)
    from ..metric import MetricConfig

    cfg = config_from_args(args, MetricConfig, base=MetricConfig.paper() if args.paper_metric else rec).validate()
    diff = metric_differences(cfg, rec)
    if diff:
        warn(f"metric settings differ from those {frame.source} records: {', '.join(diff)}")
    return cfg


def _terrain_scene(scene, robot, frame: RecordedFrame | None, n_sigma: float):
    """A ground robot of a plan: the collision scene without the terrain the plan removed (the same
    floor height and band), so check sees what plan saw."""
    if frame is None or frame.terrain is None or not robot.walks_on_terrain:
        return scene
    from ..scenes.terrain import TerrainConfig, remove_terrain

    rec = dict(frame.terrain.get("config") or {})
    names = {f.name for f in dataclasses.fields(TerrainConfig)}
    cfg = TerrainConfig(**{k: v for k, v in rec.items() if k in names})
    if frame.terrain.get("floor_z") is not None:  # the floor the plan found, not a new fit
        cfg.floor_z = float(frame.terrain["floor_z"])
    out, rep = remove_terrain(scene, cfg, n_sigma=n_sigma)
    note(rep.summary())
    return out


def cmd_check(args) -> int:
    from ..metric import CollisionChecker

    plan_q, frame = _from_plan(args) if args.plan is not None else (None, None)
    if args.robot is None:
        raise SplatplanError("--robot is required (or --plan PATH.json, whose recorded robot is used)")
    try:
        name = parse_robot_name(args.robot)  # fails fast on a malformed sphere:R / ellipsoid:A,B,C
    except SplatplanError as exc:
        raise SplatplanError(f"--robot: {exc}") from None
    link = name.is_point
    axes = np.asarray(name.semi_axes, dtype=np.float64) if link else None  # (3,)
    if plan_q is None and (args.poses is None) == (args.configs is None):
        raise SplatplanError("give exactly one of --poses POSES.npy (link poses), --configs Q.npy (joint configurations) or --plan PATH.json")
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
    cfg = _metric_config(args, frame)
    # validate the query input before the (slow) scene load
    if args.poses is not None:
        centers, quats = load_poses(args.poses)
    else:
        robot, q = _load_configs(args, plan_q)
    check_scene(args.scene, frame)
    scene = _load(args.scene)
    if plan_q is not None:  # (a plan takes no --poses)
        scene = _terrain_scene(scene, robot, frame, cfg.n_sigma)
    checker = CollisionChecker(scene, device=args.device, config=cfg)
    res: dict[str, Any]
    if args.poses is not None:
        assert axes is not None  # (--poses: a single link, checked above)
        res = _check_link(axes, centers, quats, checker, scene, args.chunk)
    else:
        res = _check_robot(robot, q, checker, scene, args.chunk)
    if args.out:
        with atomic_path(args.out) as tmp:
            with open(tmp, "wb") as f:
                with signals_deferred():  # a half-written archive is removed by atomic_path anyway
                    np.savez(f, **res)  # type: ignore[arg-type]  # numpy's stub: **arrays could fill its allow_pickle (numpy >= 2.1)
        print(f"wrote {args.out}")
    return 0


def register(sub, eval_sub) -> None:
    s = add_command(sub, "check", cmd_check, "CollisionSplatting metric for a batch of link poses or robot configurations",
                    "CollisionSplatting metric for link poses (--robot sphere:R|ellipsoid:A,B,C --poses) or robot configurations "
                    "(--robot panda|go2|URDF --configs).")  # fmt: skip
    s.add_argument("scene", metavar="SCENE")
    s.add_argument("--robot", default=None, help=f"{ROBOT_NAME_HELP}; a point robot (sphere, ellipsoid) takes --poses or --configs, the others --configs "
                   "(required unless --plan records it)")
    s.add_argument("--poses", help="POSES.npy: (B,3) centres or (B,7) centre + wxyz quaternion, scene frame (single-link robots)")
    add_base_pose_arg(s, help=f"--configs robots: {BASE_POSE_HELP}")
    s.add_argument("--configs", help="Q.npy: (B, dof) joint configurations of --robot (rad or m; panda: 7 arm joints, go2: x, y, yaw)")
    s.add_argument("--plan", default=None, help="PATH.json of 'splatplan plan': check its vertices as --configs, with the robot, base pose, "
                   "metric settings and terrain it records unless flags give others")  # fmt: skip
    s.add_argument("--out", help="OUT.npz with min_s2, n_colliding, in_collision, softmin, cost, clearance_m (metres, the estimate "
                   "(sqrt(min s2~) - 1) x smallest semi-axis): (B,) per pose, or (B, E) per ellipsoid plus collision (B,), config_clearance_m (B,), "
                   "link_in_collision (B, L), link_min_s2 (B, L), link_names (L,) for --configs / --plan")  # fmt: skip
    s.add_argument("--chunk", type=POSITIVE_INT, default=DEFAULT_CHUNK, help=f"link poses per kernel call; Ctrl-C is honoured between calls (default {DEFAULT_CHUNK})")
    add_device_arg(s)
    add_metric_args(s)
