"""MoveIt planning scenes and motion-plan requests (YAML) -> analytic scenes and joint configurations.

Planning scene (``moveit_msgs/PlanningScene`` as YAML, e.g. MotionBenchMaker's ``sceneNNNN.yaml``):
``world.collision_objects`` is a list of objects, each with ``id``, ``primitives`` (``type`` and
``dimensions``) and one ``primitive_poses`` entry per primitive, plus an optional object-level
``pose`` (newer MoveIt: primitive poses are relative to it, so world <- primitive = pose @
primitive_pose; absent = identity). Supported primitive types (names or the message's numbers):

* ``box`` (1): ``dimensions`` = full sizes [x, y, z];
* ``sphere`` (2): ``[radius]``;
* ``cylinder`` (3): ``[height, radius]``, axis along the primitive's own z.

Poses are ``position`` [x, y, z] (metres) and ``orientation`` **[x, y, z, w]** (MoveIt / ROS order;
converted to this package's wxyz), either as lists or as ``{x:, y:, z:, w:}`` mappings. The world
frame is the planning frame (the robot's base frame for MBM), z up. Meshes, planes, cones and
unknown types are refused with an error naming the object.

Motion-plan request (``moveit_msgs/MotionPlanRequest`` as YAML, e.g. ``requestNNNN.yaml``):
``start_state.joint_state`` (``name`` + ``position``) and ``goal_constraints[0].joint_constraints``
(one ``{joint_name, position}`` per joint, any order). Joints are matched **by name** onto the
robot's degrees of freedom (:attr:`Robot.joint_names`):

* a name the robot's kinematic tree does not have at all is an error naming it (start or goal);
* a joint the robot has but holds fixed (not a dof; e.g. MBM's Panda fingers, fixed joints in its
  URDF, or the built-in Panda's fingers baked at load) is **ignored**: the robot model decides its
  value, the request's value is not used;
* every dof must get a value in the start state and in the goal (else an error naming the missing
  ones); start and goal must lie inside the joint limits (an error names the joint and by how much).

Every error is a :class:`~splatplan.errors.SceneFormatError` (the file) or
:class:`~splatplan.errors.PlanningError` (the request does not fit the robot), so the CLI prints one
line and exits 2.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import PlanningError, SceneFormatError
from .builtin.analytic_scene import AnalyticScene
from .builtin.primitive_sdf import make_box, make_cylinder, make_sphere
from .splats import quat_multiply, quat_to_rotmat

__all__ = ["build_moveit", "load_moveit_request", "load_moveit_scene", "moveit_request_from_dict", "moveit_scene_from_dict", "read_yaml", "write_moveit"]

#: shape_msgs/SolidPrimitive type numbers -> names
PRIMITIVE_TYPES = {1: "box", 2: "sphere", 3: "cylinder", 4: "cone"}
#: number of ``dimensions`` per supported type
N_DIMS = {"box": 3, "sphere": 1, "cylinder": 2}
#: joint values may exceed the limits by this much (rad or m) before the request is refused (rounding)
LIMIT_TOL = 1e-6


def read_yaml(path: str | Path) -> dict:
    """Parse a MoveIt YAML file into a dict; a missing file or a syntax error is a one-line SceneFormatError."""
    from .._files import read_yaml as _read

    path = Path(path)
    d = _read(path, "MoveIt YAML", SceneFormatError)
    if not isinstance(d, dict):
        raise SceneFormatError(f"{path}: expected a YAML mapping at the top level, got {type(d).__name__}")
    return d


#: the largest position or size (m) a planning scene may hold (the declared range of every field)
MAX_MOVEIT_M = 1e6


def _vec(x, keys: str, what: str, max_abs: float | None = MAX_MOVEIT_M) -> np.ndarray:
    """A list [a, b, ...] or a mapping {k: v} over ``keys`` -> float64 array in ``keys`` order."""
    if isinstance(x, dict):
        try:
            x = [x[k] for k in keys]
        except KeyError as exc:
            raise SceneFormatError(f"{what}: missing {exc.args[0]!r}") from None
    try:
        v = np.asarray(x, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError, OverflowError):
        raise SceneFormatError(f"{what}: expected {len(keys)} numbers ({', '.join(keys)}), got {x!r}") from None
    if v.shape != (len(keys),) or not np.all(np.isfinite(v)):
        raise SceneFormatError(f"{what}: expected {len(keys)} finite numbers ({', '.join(keys)}), got {x!r}")
    if max_abs is not None and np.any(np.abs(v) > max_abs):
        raise SceneFormatError(f"{what}: values must be within +-{max_abs:g} m, got {x!r}")
    return v


def _pose(p, what: str) -> tuple[np.ndarray, np.ndarray]:
    """A geometry_msgs/Pose mapping -> (position (3,), wxyz unit quaternion (4,))."""
    if p is None:
        return np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
    if not isinstance(p, dict):
        raise SceneFormatError(f"{what}: expected a pose mapping with 'position' and 'orientation'")
    pos = _vec(p.get("position", [0.0, 0.0, 0.0]), "xyz", f"{what} position")
    xyzw = _vec(p.get("orientation", [0.0, 0.0, 0.0, 1.0]), "xyzw", f"{what} orientation (x, y, z, w)", None)
    xyzw = xyzw / max(float(np.max(np.abs(xyzw))), 1e-300)  # scaled first: the norm of 1e300-sized parts overflows
    n = np.linalg.norm(xyzw)
    if n < 1e-9:
        raise SceneFormatError(f"{what}: zero orientation quaternion")
    return pos, np.array([xyzw[3], xyzw[0], xyzw[1], xyzw[2]]) / n  # xyzw -> wxyz


def moveit_scene_from_dict(d: dict, source: str = "<dict>") -> AnalyticScene:
    """A parsed planning-scene mapping -> :class:`AnalyticScene` (see the module docstring).

    Labels are the object ids (``id#k`` for the k-th primitive of an object with several).
    """
    world = d.get("world") if isinstance(d.get("world"), dict) else None
    objs = world.get("collision_objects") if world is not None else d.get("collision_objects")
    if objs is None:
        raise SceneFormatError(f"{source}: no 'world.collision_objects' list: not a MoveIt planning scene")
    if not isinstance(objs, list):
        raise SceneFormatError(f"{source}: 'world.collision_objects' must be a list")
    boxes, cyls, sphs = [], [], []
    for k, obj in enumerate(objs):
        if not isinstance(obj, dict):
            raise SceneFormatError(f"{source}: collision object {k} is not a mapping")
        oid = str(obj.get("id", f"#{k}"))
        if obj.get("meshes"):
            raise SceneFormatError(f"{source}: object {oid!r} is a mesh; only box, cylinder and sphere primitives are supported")
        if obj.get("planes"):
            raise SceneFormatError(f"{source}: object {oid!r} has planes; only box, cylinder and sphere primitives are supported")
        prims = obj.get("primitives") or []
        poses = obj.get("primitive_poses") or []
        if not isinstance(prims, list) or not isinstance(poses, list):
            raise SceneFormatError(f"{source}: object {oid!r}: 'primitives' and 'primitive_poses' must be lists")
        if len(prims) != len(poses):
            raise SceneFormatError(f"{source}: object {oid!r} has {len(prims)} primitives but {len(poses)} primitive_poses")
        o_pos, o_q = _pose(obj.get("pose"), f"{source}: object {oid!r} pose")
        o_rot = quat_to_rotmat(o_q)
        for i, (prim, pose) in enumerate(zip(prims, poses)):
            label = oid if len(prims) == 1 else f"{oid}#{i}"
            if not isinstance(prim, dict):
                raise SceneFormatError(f"{source}: object {oid!r} primitive {i} is not a mapping")
            kind = prim.get("type")
            kind = PRIMITIVE_TYPES.get(kind, kind) if isinstance(kind, int) else str(kind).lower()
            if kind not in N_DIMS:
                raise SceneFormatError(f"{source}: object {oid!r}: unknown primitive type {prim.get('type')!r} (supported: box, cylinder, sphere)")
            try:
                dims = np.asarray(prim.get("dimensions"), dtype=np.float64).reshape(-1)
            except (TypeError, ValueError, OverflowError):
                dims = np.zeros(0)
            if dims.shape != (N_DIMS[kind],) or not np.all(np.isfinite(dims)) or np.any(dims <= 0) or np.any(dims > MAX_MOVEIT_M):
                raise SceneFormatError(
                    f"{source}: object {oid!r}: a {kind} needs {N_DIMS[kind]} positive dimensions up to {MAX_MOVEIT_M:g} m "
                    f"({ {'box': 'x, y, z sizes', 'sphere': 'radius', 'cylinder': 'height, radius'}[kind]}), got {prim.get('dimensions')!r}"
                )
            p_pos, p_q = _pose(pose, f"{source}: object {oid!r} primitive pose {i}")
            pos = o_rot @ p_pos + o_pos  # world <- primitive = object pose @ primitive pose
            q = quat_multiply(o_q, p_q)
            if kind == "box":
                boxes.append((make_box(pos, dims / 2.0, q), label))
            elif kind == "cylinder":
                cyls.append((make_cylinder(pos, dims[1], dims[0] / 2.0, q), label))
            else:
                sphs.append((make_sphere(pos, dims[0]), label))
    if not boxes and not cyls and not sphs:
        raise SceneFormatError(f"{source}: the planning scene has no collision objects")
    return AnalyticScene(
        np.array([b for b, _ in boxes]).reshape(-1, 10),
        [lab for _, lab in boxes + cyls + sphs],
        {"source": str(source), "units": "m", "frame": "MoveIt planning frame (z up)", "generator": "splatplan.scenes.moveit"},
        np.array([c for c, _ in cyls]).reshape(-1, 9),
        np.array([s for s, _ in sphs]).reshape(-1, 4),
    )


def load_moveit_scene(path: str | Path) -> AnalyticScene:
    """Read a MoveIt planning-scene YAML into an :class:`AnalyticScene` (exact boxes, cylinders, spheres).

    Raises:
        SceneFormatError: unparsable YAML, no objects, a mesh / plane object or an unknown
            primitive type (named), malformed dimensions or poses.
    """
    return moveit_scene_from_dict(read_yaml(path), source=str(path))


def _joint_values(names, values, what: str, source: str) -> dict[str, float]:
    if not isinstance(names, list) or not isinstance(values, list) or len(names) != len(values):
        raise SceneFormatError(f"{source}: {what} needs 'name' and 'position' lists of equal length")
    out = {}
    for n, v in zip(names, values):
        try:
            out[str(n)] = float(v)
        except (TypeError, ValueError):
            raise SceneFormatError(f"{source}: {what}: joint {n!r} has a non-numeric position {v!r}") from None
    return out


def _to_q(values: dict[str, float], robot, what: str, source: str) -> np.ndarray:
    """Joint name -> value mapping -> (dof,) configuration of ``robot`` (see the module docstring)."""
    known = set(robot.kin.joint_names) | set(robot.joint_names)
    unknown = [n for n in values if n not in known]
    if unknown:
        raise PlanningError(f"{source}: the {what} names joint(s) {', '.join(map(repr, unknown))} that robot {robot.name} does not have "
                            f"(its joints: {', '.join(robot.joint_names)})")  # fmt: skip
    missing = [n for n in robot.joint_names if n not in values]
    if missing:
        raise PlanningError(f"{source}: the {what} gives no value for joint(s) {', '.join(missing)} of robot {robot.name}")
    q = np.array([values[n] for n in robot.joint_names], dtype=np.float64)
    if not np.all(np.isfinite(q)):
        raise SceneFormatError(f"{source}: the {what} has NaN or Inf joint values")
    lo, hi = robot.joint_limits[:, 0], robot.joint_limits[:, 1]
    for j, n in enumerate(robot.joint_names):
        if q[j] < lo[j] - LIMIT_TOL:
            raise PlanningError(f"{source}: the {what} has {n} = {q[j]:.6g}, {lo[j] - q[j]:.4g} below its lower limit {lo[j]:.6g}")
        if q[j] > hi[j] + LIMIT_TOL:
            raise PlanningError(f"{source}: the {what} has {n} = {q[j]:.6g}, {q[j] - hi[j]:.4g} above its upper limit {hi[j]:.6g}")
    return np.clip(q, lo, hi)


def moveit_request_from_dict(d: dict, robot, source: str = "<dict>") -> tuple[np.ndarray, np.ndarray]:
    """A parsed motion-plan request mapping -> (q_start (dof,), q_goal (dof,)) for ``robot``."""
    js = (d.get("start_state") or {}).get("joint_state") if isinstance(d.get("start_state"), dict) else None
    if not isinstance(js, dict):
        raise SceneFormatError(f"{source}: no 'start_state.joint_state': not a MoveIt motion plan request")
    start = _joint_values(js.get("name"), js.get("position"), "start_state.joint_state", source)
    goals = d.get("goal_constraints")
    if not isinstance(goals, list) or not goals or not isinstance(goals[0], dict):
        raise SceneFormatError(f"{source}: no 'goal_constraints' list")
    jc = goals[0].get("joint_constraints")
    if not isinstance(jc, list) or not jc:
        raise SceneFormatError(f"{source}: goal_constraints[0] has no joint_constraints (only joint-space goals are supported)")
    goal = {}
    for k, c in enumerate(jc):
        if not isinstance(c, dict) or "joint_name" not in c or "position" not in c:
            raise SceneFormatError(f"{source}: joint_constraints[{k}] needs 'joint_name' and 'position'")
        try:
            goal[str(c["joint_name"])] = float(c["position"])
        except (TypeError, ValueError):
            raise SceneFormatError(f"{source}: joint_constraints[{k}]: non-numeric position {c['position']!r}") from None
    dofs = set(robot.joint_names)
    start = {n: v for n, v in start.items() if n in dofs or n not in set(robot.kin.joint_names)}  # fixed joints: ignored
    goal = {n: v for n, v in goal.items() if n in dofs or n not in set(robot.kin.joint_names)}
    return _to_q(start, robot, "start state", source), _to_q(goal, robot, "goal", source)


def load_moveit_request(path: str | Path, robot) -> tuple[np.ndarray, np.ndarray]:
    """Read a MoveIt motion-plan request YAML into (q_start (dof,), q_goal (dof,)) for ``robot``.

    Joints are matched by name onto ``robot.joint_names``; joints the robot holds fixed are ignored
    (see the module docstring).

    Raises:
        SceneFormatError: unparsable YAML or a missing field.
        PlanningError: a joint the robot does not have, a dof without a value, a value outside the
            joint limits (names the joint and by how much).
    """
    return moveit_request_from_dict(read_yaml(path), robot, source=str(path))


#: Default splat count of a MoveIt scene (a metre-scale workcell: ~7 mm spacing on a 2 x 1.2 m table).
DEFAULT_N_SPLATS = 100_000


def build_moveit(path: str | Path | AnalyticScene, n_splats: int = DEFAULT_N_SPLATS, seed: int = 0):
    """Splats (the built-in real-capture look, :func:`~.builtin.surface_splats.splats_from_scene`) and
    the exact ground truth of a MoveIt planning scene (a YAML path, or the scene already parsed by
    :func:`load_moveit_scene`: the same splats for the same seed).

    Colours: one base colour per object, drawn from ``seed``. Returns (Splats, AnalyticScene).
    """
    from .builtin.surface_splats import splats_from_scene

    scene = path if isinstance(path, AnalyticScene) else load_moveit_scene(path)
    rng = np.random.default_rng([int(seed), 19])
    colors = 0.25 + 0.6 * rng.random((len(scene), 3))
    splats = splats_from_scene(scene, int(n_splats), colors=colors, seed=rng)
    return splats, scene


def write_moveit(path: str | Path | AnalyticScene, out_ply: str | Path, n_splats: int = DEFAULT_N_SPLATS, seed: int = 0) -> tuple[Path, Path]:
    """Write a MoveIt scene as an INRIA 3DGS .ply plus its exact ground truth ``<stem>.gt.json``.

    Returns:
        (ply path, ground-truth JSON path).
    """
    from .builtin.stonehenge import ground_truth_path, save_ply

    out_ply = Path(out_ply)
    splats, scene = build_moveit(path, n_splats, seed)
    save_ply(out_ply, splats)
    gt = ground_truth_path(out_ply)
    scene.meta.update(n_splats=len(splats), n_floaters=int(splats.info["n_floaters"]), ply=out_ply.name, seed=int(seed),
                      base_spacing=float(splats.info["base_spacing"]))  # fmt: skip
    scene.save(gt)
    return out_ply, gt
