"""How far from a goal view the visual-reaching image cost still points the way: the cost landscape
around each goal of the last full E5 study, against the cost of the views where its runs ended.

    python benchmarks/reach_basin.py                      # the goals of benchmarks/results/reach.json
    python benchmarks/reach_basin.py --quick --out /tmp   # smoke: fewer probe directions

For every goal of the study (its configuration and its runs' final configurations are read from the
study's JSON), the target image is rendered as the study renders it, and the raw image cost that the
reach controller minimises (:meth:`~splatplan.planners.ImageCost.raw_cost_of_images`: the encoder's
distance plus the empty-view term, before the log transform and the weight) is evaluated on
**probe views**: the goal camera moved by 0.5..20 cm along random directions (world frame,
orientation kept) and turned by 1..30 degrees about random axes through its centre (position kept),
``--directions`` probes per step, in one batched render per step. Nothing moves the arm: a probe is a
camera pose (the cost of a view depends on the camera pose only).

Reported per goal and run: the raw cost of the run's final view and its pose error (from the study);
per probe step the median and the 10th percentile of the probe costs; the **guidance radius** (the
largest translation step whose median probe cost is still below the run's final cost) and the
**guidance angle** (the same for turns). A run that ended at a look-alike view whose cost lies below
the median probe cost a few centimetres from the goal ended in a minimum deeper than most of the
goal basin's rim: a local controller started outside that radius is not drawn to the goal by the
image alone. Also per encoder (the study's and two other thumbnail pyramids): the basin half-width,
the translation step at which the median probe cost, averaged over the goals, reaches half of its
value at the largest step.

Writes ``reach_basin.json`` and ``reach_basin.md`` into ``--out``. Units: metres, degrees; the cost
is dimensionless (the encoder's normalised distance lies in [0, 4], plus the empty-view term).
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

from splatplan.robots.kinematics import axis_angle_matrix

#: translation probe steps (m)
STEPS_M = (0.005, 0.01, 0.02, 0.03, 0.05, 0.08, 0.12, 0.20)
#: rotation probe steps (degrees)
STEPS_DEG = (1.0, 2.0, 4.0, 8.0, 15.0, 30.0)
#: most probe directions per step (each step renders this many views per goal)
MAX_DIRECTIONS = 4096
#: encoders compared for the basin half-width: (label, thumbnail size, pyramid levels); the first is the study's default
ENCODERS = (("bands 4/8 px (default)", 8, 2), ("bands 2/4 px", 4, 2), ("bands 4/8/16 px", 16, 3))


def unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) random unit vectors (uniform on the sphere)."""
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def probe_poses(t_goal: np.ndarray, dirs: np.ndarray, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World <- camera probe poses around ``t_goal`` (4, 4): translations (len(STEPS_M), n, 4, 4)
    (camera moved by step * dir, world frame) and turns (len(STEPS_DEG), n, 4, 4) (camera rotated
    about axes given in its own frame, centre kept)."""
    tr = np.broadcast_to(t_goal, (len(STEPS_M), len(dirs), 4, 4)).copy()
    tr[..., :3, 3] += np.asarray(STEPS_M)[:, None, None] * dirs[None]
    rot = np.broadcast_to(t_goal, (len(STEPS_DEG), len(axes), 4, 4)).copy()
    for j, ax in enumerate(axes):
        rot[:, j, :3, :3] = t_goal[:3, :3] @ axis_angle_matrix(ax, np.radians(STEPS_DEG))  # (steps, 3, 3)
    return tr, rot


def study_goals(study: dict) -> list[dict]:
    """The goals of an E5 study result: name, q (7,) and per run its final_q (7,) and final errors
    (KeyError / TypeError / ValueError where the file is not one)."""
    out = []
    for g in study["goals"]:
        runs = {k: {"final_q": np.asarray(r["final_q"], np.float64).reshape(7), "translation_error_m": float(r["translation_error_m"]),
                    "rotation_error_deg": float(r["rotation_error_deg"])} for k, r in g["runs"].items()}  # fmt: skip
        out.append({"name": str(g["name"]), "q": np.asarray(g["q"], np.float64).reshape(7), "runs": runs})
    if not out:
        raise ValueError("no goals")
    return out


def guidance(steps, medians: list[float], level: float) -> float:
    """The largest step whose median probe cost is below ``level`` (0 when the first is not)."""
    out = 0.0
    for s, m in zip(steps, medians):
        if m < level:
            out = float(s)
        else:
            break
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--study", type=Path, default=Path(__file__).parent / "results" / "reach.json", help="the E5 study's JSON (goals and final configurations)")
    ap.add_argument("--directions", type=int, default=24, help="probe directions (and turn axes) per step")
    ap.add_argument("--quick", action="store_true", help="6 directions per step (smoke run)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=Path(__file__).parent / "results")
    a = ap.parse_args(argv)

    from splatplan.encoders.thumbnail import ThumbnailEncoder
    from splatplan.eval._study import write_outputs
    from splatplan.render import SplatRenderer
    from splatplan.render.cameras import invert_rigid, wrist_camera
    from splatplan.robots import load_robot
    from splatplan.tasks._common import load_task_scene
    from splatplan.tasks.reach import ReachConfig

    if not a.study.is_file():
        print(f"reach_basin: no study results at {a.study}: run `splatplan eval reach --out {a.study.parent}` first", file=sys.stderr)
        return 2
    if not a.out.is_dir():
        print(f"reach_basin: --out {a.out} is not a folder", file=sys.stderr)
        return 2
    n_dirs = 6 if a.quick else int(a.directions)
    if not 1 <= n_dirs <= MAX_DIRECTIONS:
        print(f"reach_basin: --directions must be between 1 and {MAX_DIRECTIONS}, got {n_dirs}", file=sys.stderr)
        return 2
    try:
        study = json.loads(a.study.read_text())
        goals_in = study_goals(study)
    except (ValueError, KeyError, TypeError) as e:
        print(f"reach_basin: {a.study} is not an E5 study result (goals with q and runs with final_q): {type(e).__name__}: {e}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    cfg = ReachConfig()
    size = int(study.get("config", {}).get("image_size", cfg.image_size))
    robot = load_robot("panda", model=study.get("robot_model") or "tight")
    ts = load_task_scene("tabletop", n_sigma=cfg.n_sigma, device="cpu", n_splats=int(study.get("config", {}).get("n_splats", cfg.n_splats)))
    cam = wrist_camera(robot, size, cfg.fov_deg, cfg.camera_link)
    bg = (cfg.background,) * 3
    rng = np.random.default_rng(a.seed)
    dirs, axes = unit_vectors(rng, n_dirs), unit_vectors(rng, n_dirs)
    encoders = [(label, ThumbnailEncoder(size=s, levels=lv, device="cpu")) for label, s, lv in ENCODERS]
    goals, profiles = [], {label: [] for label, _, _ in ENCODERS}
    with SplatRenderer(ts.splats, "cpu") as rend:

        def views(poses: np.ndarray):
            v = invert_rigid(poses.reshape(-1, 4, 4))
            res = rend.render(v, cam.Ks((len(v),)), cam.width, cam.height, background=bg)
            return np.asarray(res.rgb), np.asarray(res.alpha)

        for g in goals_in:
            q_goal = g["q"]
            t_goal = cam.cam_to_world(robot, q_goal)
            target = np.asarray(cam.render(rend, robot, q_goal[None], background=bg).rgb[0])
            tr, rot = probe_poses(t_goal, dirs, axes)
            tr_img, rot_img = [views(p) for p in tr], [views(p) for p in rot]
            row = {"name": g["name"], "runs": {}}
            for k, (label, enc) in enumerate(encoders):
                cost = cfg.image_cost(rend, cam, robot, enc, target)
                med_t = [float(np.median(cost.raw_cost_of_images(*im))) for im in tr_img]
                profiles[label].append(med_t)
                if k:
                    continue
                p10_t = [float(np.percentile(cost.raw_cost_of_images(*im), 10)) for im in tr_img]
                rot_c = [cost.raw_cost_of_images(*im) for im in rot_img]
                med_r, p10_r = [float(np.median(c)) for c in rot_c], [float(np.percentile(c, 10)) for c in rot_c]
                row.update({"translation_median": med_t, "translation_p10": p10_t, "rotation_median": med_r, "rotation_p10": p10_r})
                for run_name, run in g["runs"].items():
                    q_end = run["final_q"]
                    res = cam.render(rend, robot, q_end[None], background=bg)
                    c_end = float(cost.raw_cost_of_images(np.asarray(res.rgb), np.asarray(res.alpha))[0])
                    row["runs"][run_name] = {"final_cost": c_end, "translation_error_m": run["translation_error_m"], "rotation_error_deg": run["rotation_error_deg"],
                                             "guidance_radius_m": guidance(STEPS_M, med_t, c_end), "guidance_angle_deg": guidance(STEPS_DEG, med_r, c_end)}  # fmt: skip
            goals.append(row)
    half = {}
    for label, prof in profiles.items():
        m = np.mean(np.asarray(prof), axis=0)  # (steps,) median probe cost averaged over the goals
        half[label] = {"mean_median_cost": m.round(4).tolist(), "half_width_m": next((float(s) for s, v in zip(STEPS_M, m) if v >= 0.5 * m[-1]), float(STEPS_M[-1]))}
    data = {
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}",
        "study": str(a.study.name), "study_encoder": study.get("encoder"), "image_size": size, "directions": n_dirs, "seed": a.seed, "quick": bool(a.quick),
        "steps_m": list(STEPS_M), "steps_deg": list(STEPS_DEG), "goals": goals, "encoders": half, "time_s": round(time.perf_counter() - t0, 1),
    }  # fmt: skip
    md = markdown(data)
    print(md)
    write_outputs(a.out, "reach_basin", data, md)
    return 0


def markdown(d: dict) -> str:
    """The tables of a result (see the module docstring)."""
    cm = lambda s: f"{100 * s:g} cm"  # noqa: E731
    lines = [
        f"Image cost around the E5 goals ({d['study_encoder']}, {d['image_size']} px views, {d['directions']} probe directions per step; "
        "raw cost: the encoder's distance plus the empty-view term). Median probe cost per step away from the goal view:",
        "",
        "| goal | " + " | ".join(cm(s) for s in d["steps_m"]) + " | " + " | ".join(f"{s:g} deg" for s in d["steps_deg"]) + " |",
        "|---|" + "---|" * (len(d["steps_m"]) + len(d["steps_deg"])),
    ]
    for g in d["goals"]:
        lines.append(f"| {g['name']} | " + " | ".join(f"{v:.3f}" for v in g["translation_median"] + g["rotation_median"]) + " |")
    lines += ["", "Where the study's runs ended: the raw cost of the final view, and the farthest step (translation, turn) whose median probe cost is still lower "
              "(beyond it a typical view scores worse than the view the run settled on):", "",
              "| goal | run | final error | final cost | guidance radius | guidance angle |", "|---|---|---|---|---|---|"]  # fmt: skip
    for g in d["goals"]:
        for name, r in g["runs"].items():
            err = f"{100 * r['translation_error_m']:.1f} cm, {r['rotation_error_deg']:.1f} deg"
            lines.append(f"| {g['name']} | {name.replace('_', ' ')} | {err} | {r['final_cost']:.3f} | {cm(r['guidance_radius_m']) if r['guidance_radius_m'] else '< ' + cm(d['steps_m'][0])} | "
                         f"{str(r['guidance_angle_deg']) + ' deg' if r['guidance_angle_deg'] else '< ' + str(d['steps_deg'][0]) + ' deg'} |")  # fmt: skip
    lines += ["", "Basin half-width per encoder (the step at which the median probe cost, averaged over the goals, reaches half of its value at "
              f"{cm(d['steps_m'][-1])}):", "", "| encoder | " + " | ".join(cm(s) for s in d["steps_m"]) + " | half-width |", "|---|" + "---|" * (len(d["steps_m"]) + 1)]  # fmt: skip
    for label, e in d["encoders"].items():
        lines.append(f"| {label} | " + " | ".join(f"{v:.3f}" for v in e["mean_median_cost"]) + f" | {cm(e['half_width_m'])} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
