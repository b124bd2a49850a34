"""MPC rates of the two arm tasks on one device (made for a lent GPU; runs on CPU too).

1. Panda MPPI with the collision cost over every link ellipsoid on the 200k-splat tabletop, T = 32,
   one iteration per MPC step, K from ``--samples`` (issue #8 target on a GPU: >= 100 steps/s at
   K = 1024), with the wall time per step spent in each cost object.
2. Visual reaching (E5 task, goal 0 of the study) with the collision cost and the image cost at
   ``--reach-size`` px (issue #10 target on a GPU: >= 5 MPC steps/s at 224 x 224), for each encoder
   of ``--reach-encoders`` (DINOv2 with random weights: no weights offline; same architecture and
   cost). The rate counts every executed step over the whole run, initial plan included.

Writes ``--out`` (JSON) and a markdown table beside it, and prints the table::

    python benchmarks/gpu_rates.py --device cuda [--quick] [--out benchmarks/results/gpu_rates.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))

from planners import bench_mppi_panda, near_configs, panda_setup, time_query_robot  # noqa: E402


def device_name(device: str) -> str:
    if device.startswith("cuda"):
        import torch

        return torch.cuda.get_device_name(0) if torch.cuda.is_available() else device
    return f"{platform.processor() or platform.machine()} CPU, {os.cpu_count()} cores"


def bench_reach(device: str, size: int, encoder: str, quick: bool, backend: str = "warp", horizon: int | None = None, plan_iters: int | None = None) -> dict:
    from splatplan.encoders import load_encoder
    from splatplan.eval.reach import quick_task_config
    from splatplan.render import SplatRenderer
    from splatplan.robots import load_robot
    from splatplan.tasks._common import load_task_scene
    from splatplan.planners.reach_goals import make_reach_goals, reach_start
    from splatplan.render.cameras import wrist_camera
    from splatplan.tasks.reach import ReachConfig, reach_encoder, run_reach

    from dataclasses import replace

    cfg = replace(quick_task_config(ReachConfig()) if quick else ReachConfig(), image_size=size)
    if horizon is not None:  # fewer executed MPC steps (a smoke run of the script; the rate is per step)
        cfg = replace(cfg, mppi=replace(cfg.mppi, horizon=int(horizon), n_knots=min(cfg.mppi.n_knots, int(horizon))))
    if plan_iters is not None:  # a shorter initial plan, one start, no goal search (a smoke run of the script)
        n = max(1, int(plan_iters))
        cfg = replace(cfg, plan_iters=n, plan_starts=1, plan_start_iters=min(cfg.plan_start_iters, n), plan_start_refine=0, refine_plan_iters=0, goal_search=False)
    robot = load_robot("panda")
    ts = load_task_scene("tabletop", n_sigma=cfg.n_sigma, device=device, n_splats=cfg.n_splats)
    random = encoder.startswith("dinov2")
    enc = load_encoder(encoder, device=device, random_init=True) if random else reach_encoder(encoder, None, device, cfg)
    cam = wrist_camera(robot, cfg.image_size, cfg.fov_deg, cfg.camera_link)
    q0 = reach_start(robot, cfg.camera_link)
    with SplatRenderer(ts.splats, device) as rend:
        g = make_reach_goals(robot, ts, rend, cam, n=1, q_start=q0, n_behind=1, seed=cfg.mppi.seed)[0]
        target = cam.render(rend, robot, g["q"][None], background=(cfg.background,) * 3).rgb[0]
        import numpy as np

        target = np.asarray(target.cpu() if hasattr(target, "cpu") else target)
        run_rend = rend
        if backend == "gsplat":
            from splatplan.render.gsplat_backend import GsplatRenderer

            run_rend = GsplatRenderer(ts.splats, device)
        cam.render(run_rend, robot, g["q"][None], background=(cfg.background,) * 3)  # warm-up: kernels built / loaded outside the timing
        enc.encode(target[None])
        r = run_reach(robot, ts, target, config=cfg, collision=True, q0=q0, encoder=enc, goal_camera_pose=g["camera_pose"], renderer=run_rend, device=device)
    return {
        "encoder": enc.name, "renderer": backend, "image_size": cfg.image_size, "K": cfg.mppi.n_samples, "T": cfg.mppi.horizon, "device": device,
        "mpc_steps": len(r.trajectory) - 1, "mppi_iterations": r.iterations, "time_s": r.time_s,
        "mpc_steps_per_s": r.steps_per_s, "mppi_iterations_per_s": r.iterations_per_s,
        "translation_error_m": r.translation_error_m, "rotation_error_deg": r.rotation_error_deg, "min_clearance_m": r.min_clearance_m,
        "note": "random DINOv2 weights: the rate is real, the errors are not meaningful" if random else "",
    }  # fmt: skip


def tune_panda(robot, scene, device: str, x, factors: list[float], lanes: list[int], n: int, seed: int = 0, repeats: int = 5,
               groups: tuple[bool, ...] = (False,)) -> list[dict]:  # fmt: skip
    """Panda collision query alone (moving ellipsoids, q on the device) on n configurations near
    ``x`` for each TierConfig (elongated_cell_factor, lanes, group_links): the GPU's best grid and
    thread layout."""
    import numpy as np

    from splatplan._warp import wp as _wp
    from splatplan.metric import CollisionChecker
    from splatplan.metric.wp_metric import TierConfig

    wp = _wp()
    q = near_configs(robot, x, n, seed)
    mv = np.flatnonzero(~robot.static_ellipsoids)
    rows = []
    for g in groups:
        for f in factors:
            for n_l in lanes:
                tc = TierConfig(elongated_cell_factor=f, lanes=n_l, group_links=g)
                ck = CollisionChecker(scene, n_sigma=1.0, device=device, tiers=tc).with_config(s2_cap=2.0)
                qw = wp.array(q.astype(np.float32), dtype=wp.float32, device=ck.device)
                sec = time_query_robot(ck, robot, qw, mv, repeats, out=ck.workspace(n * robot.n_ellipsoids))
                rows.append({"elongated_cell_factor": f, "lanes": n_l, "group_links": g, "seconds": sec, "configs": n})
                print(f"tune elongated_cell_factor={f} lanes={n_l} group_links={g}: {1e3 * rows[-1]['seconds']:.2f} ms", flush=True)
    return rows


def markdown(res: dict) -> str:
    lines = [f"Device: {res['device_name']} ({res['device']}). Panda: tabletop, {res['panda'][0]['scene'] if res['panda'] else '-'}, T = 32, 1 MPPI iteration per step.", "",
             "| task | K | MPC steps/s | collision cost ms/step (query alone, q on the device) | other costs ms/step | target |", "|---|---|---|---|---|---|"]  # fmt: skip
    for p in res["panda"]:
        c = p.get("cost_s_per_step", {})
        col = 1e3 * c.get("CollisionCost", float("nan"))
        other = 1e3 * sum(v for k, v in c.items() if k != "CollisionCost")
        tgt = ">= 100 (GPU)" if p["K"] == 1024 else "-"
        qo = 1e3 * p.get("query_only_s", {}).get("device_q_workspace", float("nan"))
        lines.append(f"| Panda MPPI, collision cost every step | {p['K']} | {p['steps_per_s']:.1f} | {col:.1f} ({qo:.1f}) | {other:.1f} | {tgt} |")
    for r in res["reach"]:
        lines.append(f"| visual reaching {r['image_size']}x{r['image_size']}, {r['encoder']}, {r['renderer']} renderer (T = {r['T']}) | {r['K']} | {r['mpc_steps_per_s']:.2f} "
                     f"({r['mppi_iterations_per_s']:.1f} MPPI iterations/s) | - | - | >= 5 at 224 (GPU) |")  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--device", default="cuda")
    ap.add_argument("--samples", default="256,1024", help="Panda MPPI sample counts K (comma list; empty: skip)")
    ap.add_argument("--steps", type=int, default=20, help="timed MPC steps per Panda row")
    ap.add_argument("--lanes-sweep", default="", help="also time the Panda query alone at these TierConfig.lanes (comma list)")
    ap.add_argument("--tune-factors", default="", help="time the Panda query at these TierConfig.elongated_cell_factor values (comma list) ...")
    ap.add_argument("--tune-lanes", default="4,8,16", help="... and these lanes")
    ap.add_argument("--tune-group-links", default="0,1", help="... and these TierConfig.group_links (0/1, comma list)")
    ap.add_argument("--prune-margin", type=float, default=None, help="MPPIConfig.prune_margin of the Panda rows (default: off)")
    ap.add_argument("--prune-chunks", type=int, default=4, help="MPPIConfig.prune_chunks with --prune-margin (fewer chunks: fewer, larger queries, less pruned)")
    ap.add_argument("--reach-size", type=int, default=224)
    ap.add_argument("--reach-horizon", type=int, default=None, help="MPC steps of the reach rows (the shrinking horizon; default: the study's)")
    ap.add_argument("--reach-plan-iters", type=int, default=None, help="initial-plan MPPI iterations of the reach rows, one start, no goal search (default: the study's schedule)")
    ap.add_argument("--reach-encoders", default="thumbnail,dinov2-vits14", help="comma list; empty: skip the reach rows")
    ap.add_argument("--reach-backends", default="warp", help="renderers of the reach rows: warp, gsplat (CUDA only), comma list")
    ap.add_argument("--quick", action="store_true", help="smoke test: 20k splats, 2 steps, the reach study's quick settings")
    ap.add_argument("--out", default=str(HERE / "results" / "gpu_rates.json"))
    args = ap.parse_args(argv)
    res = {"device": args.device, "device_name": device_name(args.device), "quick": args.quick, "panda": [], "reach": []}
    ks = [int(k) for k in args.samples.split(",") if k]
    if ks:
        setup = panda_setup(n_splats=20_000 if args.quick else 200_000, device=args.device)
        for k in ks:
            sweep = tuple(int(x) for x in args.lanes_sweep.split(",") if x)
            r = bench_mppi_panda(2 if args.quick else args.steps, setup, quick=args.quick, stonehenge=False, n_samples=k, profile=True, lanes_sweep=sweep,
                                 prune_margin=args.prune_margin, prune_chunks=args.prune_chunks)  # fmt: skip
            r.pop("_controls", None)
            res["panda"].append(r)
            if k == ks[-1] and args.tune_factors:
                res["tune"] = tune_panda(setup[0], setup[1], args.device, r.pop("_final_x"), [float(f) for f in args.tune_factors.split(",")],
                                         [int(v) for v in args.tune_lanes.split(",")], k * 32,
                                         groups=tuple(bool(int(v)) for v in args.tune_group_links.split(",") if v))  # fmt: skip
            r.pop("_final_x", None)
            print(f"panda K={k}: {r['steps_per_s']:.2f} steps/s, costs {r['cost_s_per_step']}, query alone {r['query_only_s']}", flush=True)
    for enc in [e for e in args.reach_encoders.split(",") if e]:
        for backend in [b for b in args.reach_backends.split(",") if b]:
            r = bench_reach(args.device, args.reach_size, enc, args.quick, backend, args.reach_horizon, args.reach_plan_iters)
            res["reach"].append(r)
            print(f"reach {enc} {backend}: {r['mpc_steps_per_s']:.2f} steps/s, {r['mppi_iterations_per_s']:.1f} it/s", flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=2) + "\n")
    md = markdown(res)
    out.with_suffix(".md").write_text(md + "\n")
    print(md)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
