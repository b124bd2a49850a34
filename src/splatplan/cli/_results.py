"""Result files that carry their frame: what ``plan`` and ``mpc`` record about the robot, its base
pose, the metric settings and the scene, and how ``view``, ``check`` and ``mpc`` read it back.

A result's ``"frame"`` object (absent in files written before it existed; they load as before)::

    "frame": {
      "robot": "panda",                          # the --robot spec as given (a name, sphere:R, a URDF path)
      "base_pose": [x, y, z, qw, qx, qy, qz],    # world <- base as --base-pose takes it (metres, wxyz); null = the origin
      "scene": {"path": "house.ply", "sha256": "..."},   # or {"builtin": "tabletop"}
      "metric": {"n_sigma": 1.0, ...},           # every MetricConfig field the answer was computed with
      "terrain": {...} | null                    # ground robots: the TerrainConfig used and the floor found
    }

A reader fills what the user did not pass from the frame (one ``note:`` line on stderr) and warns in
one ``warning:`` line where what was passed differs from what the result records.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from ._common import parse_base_pose

#: the key of the frame object in a result file
FRAME_KEY = "frame"
#: two base poses closer than this (metres, and rotation-matrix entries) are the same pose
POSE_TOL = 1e-6


def note(msg: str) -> None:
    """One ``note:`` line on stderr."""
    print(f"note: {msg}", file=sys.stderr)


def warn(msg: str) -> None:
    """One ``warning:`` line on stderr."""
    print(f"warning: {msg}", file=sys.stderr)


def sha256_file(path: str | Path, chunk: int = 1 << 22) -> str:
    """Hex sha256 of a file's bytes (read in ``chunk``-byte pieces)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        while True:
            b = f.read(chunk)
            if not b:
                return h.hexdigest()
            h.update(b)


def scene_record(scene: str) -> dict:
    """``{"path", "sha256"}`` of a scene file, ``{"builtin": name}`` of a built-in scene name."""
    p = Path(scene)
    if p.is_file():
        return {"path": str(scene), "sha256": sha256_file(p)}
    return {"builtin": str(scene)}


def pose_record(pose: np.ndarray | None) -> list[float] | None:
    """(4, 4) world <- base -> [x, y, z, qw, qx, qy, qz] as ``--base-pose`` takes it (None stays None)."""
    if pose is None:
        return None
    from ..scenes.splats import rotmat_to_quat

    pose = np.asarray(pose, dtype=np.float64)
    q = np.asarray(rotmat_to_quat(pose[:3, :3][None]), dtype=np.float64).reshape(4)
    q = q if q[0] >= 0 else -q  # one sign for one rotation
    return [round(float(v), 9) for v in (*pose[:3, 3], *q)]


def pose_text(v: list[float] | None) -> str | None:
    """[x, y, z, qw, qx, qy, qz] -> the ``--base-pose`` text (the identity rotation left out)."""
    if v is None:
        return None
    nums = list(v[:3]) if np.allclose(v[3:], [1, 0, 0, 0], atol=1e-12) else list(v)
    return ",".join(f"{float(x):.9g}" for x in nums)


def frame_record(robot: str, base_pose: np.ndarray | None, scene: str, metric, terrain: dict | None = None) -> dict:
    """The ``"frame"`` object of a result (see the module docstring); ``metric`` a MetricConfig."""
    return {
        "robot": str(robot),
        "base_pose": pose_record(base_pose),
        "scene": scene_record(scene),
        "metric": dataclasses.asdict(metric),
        "terrain": terrain,
    }


@dataclass
class RecordedFrame:
    """A result file's frame, as read back (:func:`read_frame`).

    Attributes:
        source: what it came from, for messages ("--plan house_arm.json").
        robot: the robot spec the result was made with (None: not recorded).
        base_pose: [x, y, z, qw, qx, qy, qz] or None (the origin).
        scene: ``{"path", "sha256"}`` or ``{"builtin"}``, or None.
        metric: the MetricConfig fields, or None.
        terrain: the ground robot's terrain record, or None.
    """

    source: str
    robot: str | None
    base_pose: list[float] | None
    scene: dict | None
    metric: dict | None
    terrain: dict | None

    @property
    def base_pose_text(self) -> str | None:
        """The recorded base pose as ``--base-pose`` text (None: the origin)."""
        return pose_text(self.base_pose)


def read_frame(obj: dict, source: str) -> RecordedFrame | None:
    """The frame of a loaded result (None for a file without one: written before frames existed)."""
    fr = obj.get(FRAME_KEY) if isinstance(obj, dict) else None
    if not isinstance(fr, dict):
        return None
    pose = fr.get("base_pose")
    if pose is not None:
        try:
            pose = [float(x) for x in pose]
        except (TypeError, ValueError):
            raise SplatplanError(f"{source}: \"frame\".\"base_pose\" must be 7 numbers x,y,z,qw,qx,qy,qz or null") from None
        if len(pose) != 7 or not np.all(np.isfinite(pose)):
            raise SplatplanError(f"{source}: \"frame\".\"base_pose\" must be 7 finite numbers x,y,z,qw,qx,qy,qz or null")
    robot = fr.get("robot")
    return RecordedFrame(source, str(robot) if robot else None, pose, _dict_or_none(fr.get("scene")), _dict_or_none(fr.get("metric")),
                         _dict_or_none(fr.get("terrain")))  # fmt: skip


def _dict_or_none(v) -> dict | None:
    return v if isinstance(v, dict) else None


def load_result(path: str | Path, what: str) -> dict:
    """A result file's JSON object (one line naming ``what`` when it is missing or not JSON)."""
    p = Path(path)
    if not p.is_file():
        raise SplatplanError(f"{what} {path}: no such file")
    try:
        obj = json.loads(p.read_text())
    except (ValueError, UnicodeDecodeError) as exc:
        raise SplatplanError(f"{what} {path}: not a JSON result file ({exc.__class__.__name__})") from None
    if not isinstance(obj, dict):
        raise SplatplanError(f"{what} {path}: expected a JSON object")
    return obj


def same_pose(a_text: str | None, b: list[float] | None) -> bool:
    """Whether ``--base-pose`` text ``a_text`` (None: the origin) places the base where ``b`` does."""
    pa = parse_base_pose(a_text)
    pb = parse_base_pose(pose_text(b))
    pa = np.eye(4) if pa is None else pa
    pb = np.eye(4) if pb is None else pb
    return bool(np.allclose(pa, pb, atol=POSE_TOL))


def fill_robot(args, frame: RecordedFrame | None, robot_attr: str = "robot") -> None:
    """Fill ``args.robot`` and ``args.base_pose`` from the frame where the user left them unset (one
    note saying so); warn where the user's differ from the frame's."""
    if frame is None:
        return
    used = []
    given = getattr(args, robot_attr)
    if frame.robot is not None:
        if given is None:
            setattr(args, robot_attr, frame.robot)
            used.append(f"robot {frame.robot}")
        elif given.strip() != frame.robot.strip():
            warn(f"--robot {given} differs from the robot {frame.source} records ({frame.robot}); using {given}")
    if args.base_pose is None:
        if frame.base_pose is not None:
            args.base_pose = frame.base_pose_text
            used.append(f"base pose {args.base_pose}")
    elif not same_pose(args.base_pose, frame.base_pose):
        rec = frame.base_pose_text or "the origin"
        warn(f"--base-pose {args.base_pose} differs from the base pose {frame.source} records ({rec}); using {args.base_pose}")
    if used:
        note(f"{' and '.join(used)} from {frame.source}")


def check_scene(scene: str, frame: RecordedFrame | None) -> None:
    """Warn (one line) when ``scene`` is not the scene the result was made in (another file hash, or
    a file where the result names a built-in scene and the other way round)."""
    if frame is None or frame.scene is None:
        return
    rec = frame.scene
    p = Path(scene)
    if "sha256" in rec:
        if not p.is_file():
            warn(f"{frame.source} was made in the scene file {rec.get('path')}, not {scene}")
            return
        h = sha256_file(p)
        if h != rec["sha256"]:
            warn(f"scene {scene} (sha256 {h[:12]}) is not the scene {frame.source} was made in ({rec.get('path')}, sha256 {str(rec['sha256'])[:12]})")
    elif "builtin" in rec and str(rec["builtin"]) != str(scene):
        warn(f"{frame.source} was made in the built-in scene {rec['builtin']}, not {scene}")


def recorded_metric(frame: RecordedFrame | None):
    """The MetricConfig a result records (None when it records none); unknown fields are ignored."""
    if frame is None or frame.metric is None:
        return None
    from ..metric import MetricConfig

    names = {f.name for f in dataclasses.fields(MetricConfig)}
    try:
        return MetricConfig(**{k: v for k, v in frame.metric.items() if k in names}).validate()
    except (TypeError, SplatplanError) as exc:
        raise SplatplanError(f"{frame.source}: \"frame\".\"metric\" is not a valid MetricConfig ({exc})") from None


def metric_differences(cfg, recorded) -> list[str]:
    """'n_sigma 0.5 (recorded 1)' for every MetricConfig field where ``cfg`` and ``recorded`` differ."""
    if recorded is None:
        return []
    out = []
    for f in dataclasses.fields(cfg):
        a, b = getattr(cfg, f.name), getattr(recorded, f.name)
        if a != b:
            out.append(f"{f.name} {a:g} (recorded {b:g})" if isinstance(a, float) and isinstance(b, float) else f"{f.name} {a} (recorded {b})")
    return out


def read_plan(path: str, what: str = "--plan") -> tuple[np.ndarray, RecordedFrame | None]:
    """The path (P, dof) of a ``splatplan plan`` result and its recorded frame (None in files without one)."""
    obj = load_result(path, what)
    arr = finite_rows(obj, "path", f"{what} {path}", "the JSON of 'splatplan plan' with a \"path\" list", "list of finite configurations")
    return arr, read_frame(obj, f"{what} {path}")


def finite_rows(obj: dict, key: str, where: str, expected: str, rows: str) -> np.ndarray:
    """``obj[key]`` as a non-empty (N, D) float64 array of finite numbers; otherwise one-line
    errors: "WHERE: expected EXPECTED" (missing or not numeric) or "WHERE: "KEY" must be a
    non-empty ROWS" (wrong shape, empty, NaN/Inf)."""
    try:
        arr = np.asarray(obj[key], dtype=np.float64)
    except (ValueError, KeyError, TypeError) as exc:
        raise SplatplanError(f"{where}: expected {expected} ({exc.__class__.__name__})") from None
    if arr.ndim != 2 or len(arr) == 0 or not np.all(np.isfinite(arr)):
        raise SplatplanError(f"{where}: \"{key}\" must be a non-empty {rows}, got shape {arr.shape}")
    return arr
