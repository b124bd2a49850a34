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


def browser_open_time(scene_path: Path, port: int) -> dict:
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
                             "--status-file", str(status)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
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
        while time.time() - t0 < 60:
            driver.save_screenshot(str(shot))
            img = np.asarray(Image.open(shot).convert("RGB"), dtype=np.float64)
            h, w = img.shape[:2]
            centre = img[int(0.3 * h) : int(0.7 * h), int(0.25 * w) : int(0.6 * w)]
            if centre.std() > 12.0:
                t_visible = time.time() - t0
                break
            time.sleep(0.1)
        return {"server_start_s": t_server, "client_connected_s": t_client, "splats_visible_s": t_visible,
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "viewer.json"))
    ap.add_argument("--no-browser", action="store_true")
    args = ap.parse_args()
    from splatplan.scenes.load import save_scene
    from splatplan.scenes.stonehenge import build_stonehenge
    from splatplan.viewer import free_port

    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    scene, _ = build_stonehenge()
    tmp = Path(tempfile.mkdtemp()) / "stonehenge.ply"
    save_scene(tmp, scene)
    res: dict = {"machine": f"{platform.machine()}, {os.cpu_count()} cores, no GPU (Chromium with SwiftShader software WebGL)", "n_splats": len(scene)}
    if not args.no_browser:
        res["browser"] = browser_open_time(tmp, free_port())
    res["pose_update"] = [pose_update_times(scene, "sphere:0.015")]
    try:
        res["pose_update"].append(pose_update_times(scene, "panda"))
    except Exception as exc:  # the Panda needs the robots extra
        res["pose_update_error"] = f"panda: {exc}"
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(res, indent=2) + "\n")
    print(f"Viewer on {res['machine']}; Stonehenge {len(scene):,} splats.\n")
    print("| measure | value | target |\n|---|---|---|")
    if "browser" in res:
        b = res["browser"]
        vis = "n/a" if b["splats_visible_s"] is None else f"{b['splats_visible_s']:.2f} s"
        print(f"| page request -> client connected | {b['client_connected_s']:.2f} s | |")
        print(f"| page request -> splats visible | {vis} | < 5 s |")
    for p in res["pose_update"]:
        print(f"| pose update, {p['robot']} ({p['n_ellipsoids']} ellipsoids), median / p90 | {p['median_ms']:.1f} / {p['p90_ms']:.1f} ms | < 100 ms |")
    print(f"\nwrote {args.out}")


if __name__ == "__main__":
    main()
