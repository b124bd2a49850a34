"""Viewer benchmark: time for a 200k-splat scene to appear in headless Chromium, and the server-side
time to update the robot's collision state after a pose change (sphere and Panda).

    python benchmarks/viewer.py [--out benchmarks/results/viewer.json] [--no-browser]

Prints a markdown table and writes JSON. Targets (issue 11): scene open < 5 s, pose update < 100 ms.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _wait(path: Path, event: str, timeout: float) -> dict | None:
    t0 = time.time()
    while time.time() - t0 < timeout:
        if path.exists():
            for line in path.read_text().splitlines():
                r = json.loads(line)
                if r["event"] == event:
                    return r
        time.sleep(0.05)
    return None


def browser_open_time(scene_path: Path, port: int, max_splats: int | None = None) -> dict:
    """Seconds from the page request to the first screenshot whose scene area shows splats."""
    import shutil

    from PIL import Image
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-gl=angle", "--use-angle=swiftshader",
              "--window-size=1000,700", "--disable-dev-shm-usage"):  # fmt: skip
        opts.add_argument(a)
    status = Path(tempfile.mkdtemp()) / "status.jsonl"
    proc = subprocess.Popen([sys.executable, "-m", "splatplan.cli", "view", str(scene_path), "--port", str(port), "--device", "cpu",
                             "--status-file", str(status)] + ([] if max_splats is None else ["--max-splats", str(max_splats)]),
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver") or "/usr/bin/chromedriver"), options=opts)
    try:
        t_srv0 = time.time()
        ready = _wait(status, "ready", 120)
        t_server = time.time() - t_srv0
        driver.get("about:blank")
        shot = Path(tempfile.mkdtemp()) / "s.png"
        t0 = time.time()
        driver.get(f"http://127.0.0.1:{port}")
        client = _wait(status, "client", 60)
        t_client = time.time() - t0
        t_visible = None
        from selenium.common.exceptions import TimeoutException

        while time.time() - t0 < 120:
            try:
                driver.save_screenshot(str(shot))
            except TimeoutException:  # software WebGL still drawing the first frames
                continue
            img = np.asarray(Image.open(shot).convert("RGB"), dtype=np.float64)
            h, w = img.shape[:2]
            centre = img[int(0.3 * h) : int(0.7 * h), int(0.25 * w) : int(0.6 * w)]
            if centre.std() > 12.0:
                t_visible = time.time() - t0
                break
            time.sleep(0.1)
        return {"max_splats": max_splats, "server_start_s": t_server, "client_connected_s": t_client, "splats_visible_s": t_visible,
                "n_splats": ready["n_splats"] if ready else None, "client_event": client is not None}  # fmt: skip
    finally:
        driver.quit()
        proc.terminate()
        proc.wait(timeout=20)


def pose_update_times(scene, robot_name: str, n: int = 40) -> dict:
    """Server-side time of one robot pose update (metric + colouring + GUI messages), ms."""
    from splatplan.robots import load_robot
    from splatplan.viewer import SplatViewer, ViewerConfig, free_port

    robot = load_robot(robot_name)
    v = SplatViewer(scene, robot=robot, config=ViewerConfig(port=free_port(), device="cpu"))
    v.start()
    try:
        rng = np.random.default_rng(0)
        lo, hi = v.lo, v.hi
        for _ in range(3):  # warm-up: grids and kernels
            v.set_q(v.state.q)
        v.state.timings["pose_update_ms"].clear()
        for _ in range(n):
            q = v.state.q.copy()
            if v.kind == "point":
                q[:3] = rng.uniform(lo, hi)
            elif v.kind == "planar":
                q[:2] = rng.uniform(lo[:2], hi[:2])
                q[2] = rng.uniform(-np.pi, np.pi)
            else:
                lim = np.asarray(robot.joint_limits)
                q = rng.uniform(lim[:, 0], lim[:, 1])
            v.set_q(q)
        ms = np.asarray(v.state.timings["pose_update_ms"])
        return {"robot": robot_name, "n_ellipsoids": int(robot.n_ellipsoids), "median_ms": float(np.median(ms)), "p90_ms": float(np.quantile(ms, 0.9)), "n": int(len(ms))}
    finally:
        v.stop()


def screenshot(path: Path, max_splats: int = 60_000) -> dict:
    """docs/viewer.png: the Panda in the built-in tabletop with an RRT path planned in joint space."""
    import shutil

    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    from splatplan.metric import CollisionChecker
    from splatplan.planners import plan
    from splatplan.robots import load_robot
    from splatplan.scenes.builtin import build_builtin
    from splatplan.scenes.filters import filter_floaters
    from splatplan.viewer import SplatViewer, ViewerConfig, free_port

    scene, _ = build_builtin("tabletop")
    scene, _ = filter_floaters(scene)
    robot = load_robot("panda")
    checker = CollisionChecker(scene, n_sigma=1.0, device="cpu")
    rng = np.random.default_rng(3)
    lim = np.asarray(robot.joint_limits)
    res = None
    for _ in range(30):  # a goal a good way from home that RRT connects
        goal = np.clip(robot.q_default + rng.normal(0, 0.8, robot.dof), lim[:, 0], lim[:, 1])
        try:
            res = plan(checker, robot.q_default, goal, robot=robot)
        except Exception:  # goal in collision: draw another
            continue
        if res.success and res.length > 1.0:
            break
    v = SplatViewer(scene, robot=robot, plan=np.asarray(res.path), config=ViewerConfig(port=free_port(), device="cpu", max_splats=max_splats))
    v.start()
    v.set_q(np.asarray(res.path)[len(res.path) // 2])
    opts = webdriver.ChromeOptions()
    opts.binary_location = shutil.which("chromium") or "/usr/bin/chromium"
    for a in ("--headless=new", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-gl=angle", "--use-angle=swiftshader",
              "--window-size=1280,800", "--disable-dev-shm-usage"):  # fmt: skip
        opts.add_argument(a)
    driver = webdriver.Chrome(service=Service(shutil.which("chromedriver") or "/usr/bin/chromedriver"), options=opts)
    try:
        driver.get(v.url)
        time.sleep(20)
        for c in v.server.get_clients().values():
            c.camera.position = (1.35, -1.25, 1.05)
            c.camera.look_at = (0.3, 0.0, 0.15)
            c.camera.up_direction = (0.0, 0.0, 1.0)
        time.sleep(8)
        driver.save_screenshot(str(path))
    finally:
        driver.quit()
        v.stop()
    return {"screenshot": str(path), "plan_length_rad": float(res.length), "plan_points": int(len(res.path))}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "viewer.json"))
    ap.add_argument("--no-browser", action="store_true")
    ap.add_argument("--screenshot", help="also write the README screenshot (Panda in tabletop with a plan) here, e.g. docs/viewer.png")
    args = ap.parse_args()
    from splatplan.scenes.load import save_scene
    from splatplan.scenes.builtin.stonehenge import build_stonehenge
    from splatplan.viewer import free_port

    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    scene, _ = build_stonehenge()
    tmp = Path(tempfile.mkdtemp()) / "stonehenge.ply"
    save_scene(scene, tmp)
    res: dict = {"machine": f"{platform.machine()}, {os.cpu_count()} cores, no GPU (Chromium with SwiftShader software WebGL)", "n_splats": len(scene)}
    if not args.no_browser:
        res["browser"] = [browser_open_time(tmp, free_port()), browser_open_time(tmp, free_port(), max_splats=60_000)]
    res["pose_update"] = [pose_update_times(scene, "sphere:0.015") | {"scene": f"stonehenge ({len(scene):,} splats)"}]
    try:
        from splatplan.scenes.builtin import build_builtin
        from splatplan.scenes.filters import filter_floaters

        table, _ = build_builtin("tabletop")
        table, _ = filter_floaters(table)
        res["pose_update"].append(pose_update_times(table, "panda") | {"scene": f"tabletop ({len(table):,} splats)"})
    except Exception as exc:  # the Panda needs the robots extra
        res["pose_update_error"] = f"panda: {exc}"
    if args.screenshot:
        res["screenshot"] = screenshot(Path(args.screenshot))
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(res, indent=2) + "\n")
    print(f"Viewer on {res['machine']}; Stonehenge {len(scene):,} splats.\n")
    print("| measure | value | target |\n|---|---|---|")
    for b in res.get("browser", []):
        shown = f"{b['n_splats']:,} splats shown" if b.get("n_splats") else "?"
        vis = "not within 120 s (no frame)" if b["splats_visible_s"] is None else f"{b['splats_visible_s']:.2f} s"
        print(f"| page request -> client connected ({shown}) | {b['client_connected_s']:.2f} s | |")
        print(f"| page request -> splats visible ({shown}) | {vis} | < 5 s |")
    for p in res["pose_update"]:
        print(f"| pose update, {p['robot']} ({p['n_ellipsoids']} ellipsoids) in {p['scene']}, median / p90 | {p['median_ms']:.1f} / {p['p90_ms']:.1f} ms | < 100 ms |")
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
