"""VAMP side of ``benchmarks/vamp_compare.py``: run by the python of VAMP's throw-away venv, never by
splatplan's (imports only vamp, numpy and the standard library; NOT splatplan).

    python _vamp_worker.py OUT.json < problems.json

Input (stdin, JSON): ``{"mode": "exact" | "capt", "point_radius": float, "seed": int,
"cylinders": "vamp" | "capsule" | "cuboid", "warmup": bool, "problems": [{"family", "index",
"objects": AnalyticScene.to_json(), "q_start": [7], "q_goal": [7], "points": [[x, y, z], ...]}]}``
(points already thinned by the caller; mode "capt" only).

Output: ``{"meta": {...}, "results": [...]}`` written to OUT.json (a file, not stdout: VAMP's own
prints, Python's or C's, are sent to stderr, so nothing can corrupt the results).

Conversions (splatplan's AnalyticScene -> VAMP):

* box row ``(c, h, q_wxyz)`` -> ``vamp.Cuboid(c, euler_xyz, h)``: VAMP takes **half** extents and
  Euler angles such that R = Rz(ez) @ Ry(ey) @ Rx(ex) (static x-y-z; checked against the cuboid's
  axes here, per box, to 1e-5);
* cylinder row ``(c, r, half_height, q_wxyz)``: VAMP has no true cylinder. ``cylinders="vamp"``
  (default) does what VAMP's own MBM evaluation does (``vamp.problem_dict_to_vamp``): a capsule
  (``Cylinder(center, euler_xyz, r, length)``: the segment between the two end-cap centres, radius
  r, so the cylinder plus a hemisphere of radius r on each end) except in family ``box``, where a cuboid of half extents
  (r, r, half_height) (the top-down grasp of the can would hit the capsule's cap); "capsule" /
  "cuboid" force one of them everywhere. Both contain the cylinder (over-approximations).
* sphere row ``(c, r)`` -> ``vamp.Sphere(c, r)``.

Planning: ``vamp.configure_robot_and_planner_with_kwargs("panda", "rrtc")`` (VAMP's default
settings), the Halton sampler reset and skipped ``seed`` draws per problem (VAMP's evaluate_mbm
seeding), then ``panda.simplify`` with VAMP's default SimplifySettings and the same sampler. A
problem whose start or goal VAMP calls invalid is not planned (as VAMP's evaluation skips them).
"""

import json
import os
import sys
import time

import numpy as np


def _euler_xyz(R):
    """Euler angles (ex, ey, ez) with R = Rz(ez) @ Ry(ey) @ Rx(ex) (VAMP's Cuboid convention)."""
    sy = float(np.hypot(R[0, 0], R[1, 0]))
    if sy > 1e-9:
        return [float(np.arctan2(R[2, 1], R[2, 2])), float(np.arctan2(-R[2, 0], sy)), float(np.arctan2(R[1, 0], R[0, 0]))]
    return [float(np.arctan2(-R[1, 2], R[1, 1])), float(np.arctan2(-R[2, 0], sy)), 0.0]  # gimbal lock: ez = 0


def _rotmat(q):
    """wxyz (4,) -> (3, 3) rotation (frame -> world)."""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip


def _cuboid(vamp, center, half, R):
    cub = vamp.Cuboid([float(v) for v in center], _euler_xyz(R), [float(v) for v in half])
    axes = np.array([[cub.axis_1_x, cub.axis_1_y, cub.axis_1_z], [cub.axis_2_x, cub.axis_2_y, cub.axis_2_z],
                     [cub.axis_3_x, cub.axis_3_y, cub.axis_3_z]]).T  # fmt: skip  # columns = the box's axes in the world
    err = float(np.abs(axes - R).max())
    if err > 1e-5:
        raise ValueError(f"cuboid orientation conversion off by {err:.3g} (VAMP's Euler convention changed?)")
    return cub


def _capsule(vamp, center, r, hh, R):
    # VAMP 0.6.4's Cylinder(endpoint, endpoint, radius) constructor segfaults: use (center, euler, r, length)
    cap = vamp.Cylinder([float(v) for v in center], _euler_xyz(R), float(r), 2.0 * float(hh))
    a = np.asarray(center, dtype=np.float64) + hh * R[:, 2]  # VAMP's first end: centre + R z * length / 2
    v = -2.0 * hh * R[:, 2]  # VAMP's axis vector: from the first end to the second
    err = max(float(np.abs(np.array([cap.x1, cap.y1, cap.z1]) - a).max()), float(np.abs(np.array([cap.xv, cap.yv, cap.zv]) - v).max()))
    if err > 1e-5:
        raise ValueError(f"capsule conversion off by {err:.3g} (VAMP's Cylinder convention changed?)")
    return cap


def build_exact_env(vamp, objects, family, cylinders="vamp"):
    """AnalyticScene.to_json() dict -> (vamp.Environment, counts dict)."""
    env = vamp.Environment()
    n = {"cuboids": 0, "capsules": 0, "spheres": 0}
    for row in objects.get("boxes", []):
        c, h, q = row[0:3], row[3:6], row[6:10]
        env.add_cuboid(_cuboid(vamp, c, h, _rotmat(q)))
        n["cuboids"] += 1
    as_box = cylinders == "cuboid" or (cylinders == "vamp" and family == "box")
    if cylinders not in ("vamp", "capsule", "cuboid"):
        raise ValueError(f"cylinders={cylinders!r}: use vamp, capsule or cuboid")
    for row in objects.get("cylinders", []):
        c, r, hh, q = np.asarray(row[0:3], dtype=np.float64), float(row[3]), float(row[4]), row[5:9]
        R = _rotmat(q)
        if as_box:
            env.add_cuboid(_cuboid(vamp, c, [r, r, hh], R))
            n["cuboids"] += 1
        else:
            env.add_capsule(_capsule(vamp, c, r, hh, R))
            n["capsules"] += 1
    for row in objects.get("spheres", []):
        env.add_sphere(vamp.Sphere([float(v) for v in row[0:3]], float(row[3])))
        n["spheres"] += 1
    return env, n


def solve_one(vamp, robot, planner, settings, simp_settings, p, mode, point_radius, seed, cylinders):
    q0 = np.asarray(p["q_start"], dtype=np.float32)
    q1 = np.asarray(p["q_goal"], dtype=np.float32)
    out = {"family": p.get("family"), "index": p.get("index"), "solved": False, "plan_s": None, "simplify_s": None, "path": None,
           "build_s": 0.0, "n_points": 0, "start_valid": None, "goal_valid": None, "iterations": None, "n_waypoints_raw": None,
           "path_interpolated": False, "error": ""}  # fmt: skip
    if q0.shape != (robot.dimension(),) or q1.shape != (robot.dimension(),):
        out["error"] = f"q_start / q_goal must have {robot.dimension()} values"
        return out
    if mode == "exact":
        env, counts = build_exact_env(vamp, p["objects"], p.get("family"), cylinders)
        out.update(counts)
    elif mode == "capt":
        pts = np.asarray(p.get("points") or [], dtype=np.float32).reshape(-1, 3)
        if not len(pts):
            out["error"] = "mode capt: no points given"
            return out
        r_min, r_max = robot.min_max_radii()
        env = vamp.Environment()
        build_ns = env.add_pointcloud(pts.tolist(), r_min, r_max, point_radius)
        out.update(build_s=build_ns / 1e9, n_points=int(len(pts)), r_min=float(r_min), r_max=float(r_max), point_radius=float(point_radius))
    else:
        raise ValueError(f"mode {mode!r}: use exact or capt")
    out["start_valid"] = bool(robot.validate(q0, env))
    out["goal_valid"] = bool(robot.validate(q1, env))
    if not (out["start_valid"] and out["goal_valid"]):
        out["error"] = "start invalid for VAMP" if not out["start_valid"] else "goal invalid for VAMP"
        return out
    rng = robot.halton()
    rng.reset()
    if seed:
        rng.skip(int(seed))
    res = planner(q0, q1, env, settings, rng)
    out["plan_s"] = res.nanoseconds / 1e9
    out["iterations"] = int(res.iterations)
    if not res.solved:
        out["error"] = "not solved"
        return out
    out["n_waypoints_raw"] = len(res.path)
    simple = robot.simplify(res.path, env, simp_settings, rng)
    out["simplify_s"] = simple.nanoseconds / 1e9
    path = np.asarray(simple.path.numpy(), dtype=np.float64)
    if not len(path):  # defensive: simplification returned nothing, keep the planner's path
        path = np.asarray(res.path.numpy(), dtype=np.float64)
    out["solved"] = True
    out["path_valid_vamp"] = bool(simple.path.validate(env))
    out["path"] = path.tolist()
    return out


def main(argv):
    if len(argv) != 2:
        print("usage: _vamp_worker.py OUT.json < problems.json", file=sys.stderr)
        return 2
    out_path = argv[1]
    job = json.load(sys.stdin)
    sys.stdout.flush()
    os.dup2(2, 1)  # anything VAMP prints (C or Python) goes to stderr; results go to OUT.json
    sys.stdout = sys.stderr

    t_import = time.perf_counter()
    import vamp

    t_import = time.perf_counter() - t_import
    mode = job.get("mode", "exact")
    point_radius = float(job.get("point_radius", 0.0025))
    seed = int(job.get("seed", 0))
    cylinders = job.get("cylinders", "vamp")
    robot, planner, settings, simp_settings = vamp.configure_robot_and_planner_with_kwargs("panda", "rrtc")
    problems = job.get("problems", [])
    if job.get("warmup", True) and problems:  # one untimed solve first (page faults, lazy init)
        try:
            solve_one(vamp, robot, planner, settings, simp_settings, problems[0], mode, point_radius, seed, cylinders)
        except Exception:
            pass
    results = []
    for p in problems:
        try:
            results.append(solve_one(vamp, robot, planner, settings, simp_settings, p, mode, point_radius, seed, cylinders))
        except Exception as e:  # one bad problem does not sink the run
            results.append({"family": p.get("family"), "index": p.get("index"), "solved": False, "plan_s": None, "simplify_s": None,
                            "path": None, "build_s": 0.0, "n_points": 0, "error": f"{type(e).__name__}: {e}"})  # fmt: skip
    r_min, r_max = robot.min_max_radii()
    meta = {
        "vamp_version": getattr(vamp, "__version__", None) or _dist_version(),
        "robot": "panda", "planner": "rrtc", "sampler": "halton", "seed": seed, "mode": mode, "cylinders": cylinders,
        "point_radius": point_radius, "r_min": float(r_min), "r_max": float(r_max), "n_spheres": int(robot.n_spheres()),
        "resolution": int(robot.resolution()),
        "rrtc": {k: getattr(settings, k) for k in ("range", "max_iterations", "max_samples", "dynamic_domain", "balance", "tree_ratio")},
        "simplify": {"operations": [str(o).split(".")[-1] for o in simp_settings.operations], "max_iterations": int(simp_settings.max_iterations)},
        "import_s": t_import,
    }  # fmt: skip
    with open(out_path, "w") as f:
        json.dump({"meta": meta, "results": results}, f)
    return 0


def _dist_version():
    try:
        from importlib.metadata import version

        return version("vamp-planner")
    except Exception:
        return None


if __name__ == "__main__":
    sys.exit(main(sys.argv))
