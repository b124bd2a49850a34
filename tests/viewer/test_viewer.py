"""Viewer: geometry helpers against the metric reference, the app without a browser, CLI errors,
and one end-to-end run in headless Chromium (skipped when no browser is installed)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from splatplan.metric.reference import conservative_s2_ref, link_matrices
from splatplan.scenes.splats import Splats
from splatplan.viewer.geometry import ellipsoid_mesh, polyline_segments, splat_s2_tilde, tree_segments

BANANA = Path(__file__).resolve().parents[1] / "data" / "equinor_banana_splat.ply"


def _rand_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def test_ellipsoid_mesh_lies_on_the_surface():
    rng = np.random.default_rng(0)
    c, q, ax = rng.normal(size=3), _rand_quats(rng, 1)[0], np.array([0.3, 0.1, 0.05])
    v, f = ellipsoid_mesh(c, q, ax)
    a = link_matrices(q[None], ax, 1)[0]
    d = v.astype(np.float64) - c
    np.testing.assert_allclose(np.einsum("ni,ij,nj->n", d, a, d), 1.0, atol=1e-5)
    assert f.max() < len(v)


@pytest.mark.parametrize("n_sigma", [0.0, 1.0, 2.5])
def test_splat_s2_tilde_matches_the_metric_reference(n_sigma):
    rng = np.random.default_rng(1)
    n, e = 300, 3
    means = rng.uniform(-0.3, 0.3, (n, 3))
    quats = _rand_quats(rng, n)
    scales = np.exp(rng.normal(np.log(0.01), 0.5, (n, 3)))
    centers, lq, ax = rng.uniform(-0.2, 0.2, (e, 3)), _rand_quats(rng, e), rng.uniform(0.03, 0.1, (e, 3))
    got = splat_s2_tilde(means, quats, scales, centers, lq, ax, n_sigma)
    _, ref = conservative_s2_ref(means, quats, scales, centers, link_matrices(lq, ax, e), n_sigma)  # (E, N)
    np.testing.assert_allclose(got, ref.min(0), rtol=1e-9, atol=1e-12)


def test_tree_and_polyline_segments():
    nodes = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 1.0]])
    seg = tree_segments(nodes, np.array([-1, 0, 1, 0]))
    assert seg.shape == (3, 2, 3)
    np.testing.assert_allclose(seg[1], [[1, 1, 0], [1, 0, 0]])
    assert polyline_segments(nodes).shape == (3, 2, 3)
    assert tree_segments(nodes[:, :2], np.array([-1, 0, 1, 0])).shape == (3, 2, 3)  # planar tree: z = 0


def _small_scene() -> Splats:
    rng = np.random.default_rng(2)
    n = 2000
    return Splats(means=rng.uniform(-0.5, 0.5, (n, 3)), quats=_rand_quats(rng, n), scales=np.full((n, 3), 0.005),
                  opacities=np.full(n, 0.9), colors=rng.uniform(0, 1, (n, 3)))  # fmt: skip


def test_app_state_without_a_browser(capsys):
    from splatplan.robots import load_robot
    from splatplan.viewer import SplatViewer, ViewerConfig

    scene = _small_scene()
    robot = load_robot("sphere:0.05")
    far_plan = np.array([[0.0, 0.0, 0.0], [5.0, 5.0, 5.0]])
    v = SplatViewer(scene, robot=robot, plan=far_plan, config=ViewerConfig(device="cpu"))
    assert any("outside the scene bounds" in w for w in v.warnings)
    assert "outside the scene bounds" in capsys.readouterr().out
    # the per-splat colouring agrees with the checker's count at the same pose
    q = scene.means[0].astype(np.float64)
    st = v.collision_state(q)
    d = v.splat_distances(q)
    assert st["per_link"][robot.link_names[0]] == int(np.sum(d < 1.0)) > 0
    assert st["collides"]


def _cli(*args, timeout=60):
    return subprocess.run([sys.executable, "-m", "splatplan.cli", *args], capture_output=True, text=True, timeout=timeout)


def test_cli_view_bad_inputs(tmp_path):
    import socket

    bad = tmp_path / "plan.json"
    bad.write_text("{not json")
    r = _cli("view", str(BANANA), "--plan", str(bad), "--device", "cpu")
    assert r.returncode == 2 and "--plan" in r.stderr and "Traceback" not in r.stderr
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen(1)
        port = s.getsockname()[1]
        r = _cli("view", str(BANANA), "--port", str(port), "--device", "cpu")
    assert r.returncode == 2 and f"port {port}" in r.stderr and "try --port" in r.stderr, r.stderr
    r = _cli("view", str(tmp_path / "missing.ply"))
    assert r.returncode == 2 and "Traceback" not in r.stderr


def _browser():
    chromium = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    driver = shutil.which("chromedriver")
    if not chromium or not driver:
        pytest.skip("no headless browser: apt-get install chromium chromium-driver (make test does this as root)")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        pytest.skip("selenium is not installed (test extra)")
    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    for a in ("--headless=new", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-gl=angle", "--use-angle=swiftshader",
              "--window-size=1000,700", "--disable-dev-shm-usage"):  # fmt: skip
        opts.add_argument(a)
    return webdriver.Chrome(service=Service(driver), options=opts)


def _wait_event(path: Path, event: str, timeout: float, pred=lambda r: True) -> dict:
    t0 = time.time()
    while time.time() - t0 < timeout:
        if path.exists():
            for line in path.read_text().splitlines():
                r = json.loads(line)
                if r["event"] == event and pred(r):
                    return r
        time.sleep(0.2)
    raise AssertionError(f"no {event!r} event in {path} within {timeout} s")


def test_viewer_in_headless_chromium(tmp_path):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    from splatplan.viewer import free_port

    driver = _browser()
    port = free_port()
    status = tmp_path / "status.jsonl"
    plan = tmp_path / "plan.json"
    plan.write_text(json.dumps({"path": [[0.0, 0.0, 0.0], [0.05, 0.05, 0.0], [0.1, 0.05, 0.05]]}))
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "splatplan.cli", "view", str(BANANA), "--robot", "sphere:0.01", "--plan", str(plan),
                             "--port", str(port), "--device", "cpu", "--status-file", str(status)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)  # fmt: skip
    try:
        ready = _wait_event(status, "ready", 60)
        assert {"/splats", "/robot/ellipsoids/0", "/plans/plan", "/metric/field"} <= set(ready["nodes"])
        driver.get(f"http://127.0.0.1:{port}")
        _wait_event(status, "client", 30)
        time.sleep(3.0)  # let the client receive and draw the splats
        png = tmp_path / "shot.png"
        driver.save_screenshot(str(png))
        from PIL import Image

        img = np.asarray(Image.open(png).convert("RGB"), dtype=np.float64)
        assert img.std() > 10.0, "the screenshot is blank"
        assert len(np.unique(img.reshape(-1, 3)[::97], axis=0)) > 50, "the screenshot has too few colours to show a scene"
        thumbs = driver.find_elements(By.CSS_SELECTOR, "[role=slider]")
        assert thumbs, "no sliders on the page"
        driver.execute_script("arguments[0].focus()", thumbs[0])  # the first slider is n_sigma
        thumbs[0].send_keys(Keys.ARROW_RIGHT)
        ev = _wait_event(status, "n_sigma", 20, lambda r: abs(r["value"] - 1.0) > 1e-9)
        assert ev["value"] == pytest.approx(1.25)
        _wait_event(status, "pose", 20, lambda r: r["n_sigma"] == pytest.approx(1.25))
    finally:
        driver.quit()
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
    assert proc.returncode in (0, 130), err
    assert "Traceback" not in err
    assert f"http://127.0.0.1:{port}" in out
