"""OMPL's planners on splatplan's checker: a point robot through a wall gap and the Panda on the
built-in tabletop, each path re-checked densely and independently; the time limit; the missing
extra's message (the module hidden); the plan() / CLI dispatch."""

from __future__ import annotations

import sys

import numpy as np
import pytest

pytest.importorskip("ompl")

from splatplan.errors import SplatplanError
from splatplan.planners import RRTConfig, plan
from splatplan.planners.ompl_bridge import available_planners, plan_ompl
from splatplan.robots import load_robot

from .scenes import make_checker, make_scene, wall_scene

R = 0.015
SPHERE = load_robot(f"sphere:{R}")
START, GOAL = (-0.15, 0.0, 0.06), (0.15, 0.0, 0.06)
PLANE = RRTConfig(box_lo=(-0.3, -0.3, 0.06), box_hi=(0.3, 0.3, 0.06))


@pytest.fixture(scope="module")
def wall_checker():
    return make_checker(wall_scene(), n_sigma=1.0)


def dense_free(checker, path: np.ndarray, axes, step: float) -> bool:
    """Every point of the polyline at spacing <= step, checked as one batch (independent of the bridge)."""
    pts = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step)))
        pts.append(a + (np.arange(1, n + 1) / n)[:, None] * (b - a))
    pts = np.concatenate(pts)
    return not bool(checker.collides(pts, None, axes).any())


@pytest.mark.parametrize("name", ["RRTConnect", "RRTstar", "BITstar", "PRM", "KPIECE1"])
def test_point_robot_through_the_gap(wall_checker, name):
    res = plan_ompl(wall_checker, START, GOAL, name=name, time_limit_s=0.6, robot=SPHERE, rrt_config=PLANE)
    assert res.success, res.message
    p = res.path
    np.testing.assert_array_equal(p[0], START)
    np.testing.assert_array_equal(p[-1], GOAL)
    assert np.all(p[:, 2] == 0.06)  # the frozen coordinate stays at the plane
    assert np.all(p[:, :2] >= -0.3 - 1e-12) and np.all(p[:, :2] <= 0.3 + 1e-12)
    # around one of the wall's ends (y 0.12, or y -0.25 where a 5 cm gap to the box's side is left), never through it
    assert p[:, 1].max() > 0.12 or p[:, 1].min() < -0.25
    assert dense_free(wall_checker, p, (R, R, R), R / 20)
    assert res.info["planner"] == f"ompl:{name}" and res.info["n_motion_checks"] > 0 and res.n_nodes >= 2
    assert res.length == pytest.approx(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
    assert res.info["edge_resolution"] == pytest.approx(R / 4)


def test_time_limit_holds_when_there_is_no_path():
    # the goal sits inside a closed box: no planner can reach it
    box = make_scene([((0.1, -0.08, 0.0), (0.26, 0.08, 0.14))], spacing=0.01)
    ch = make_checker(box, n_sigma=1.0)
    res = plan_ompl(ch, (-0.15, 0.0, 0.06), (0.18, 0.0, 0.06), name="RRTConnect", time_limit_s=0.5, robot=SPHERE, rrt_config=PLANE)
    assert not res.success and res.path.shape == (0, 3) and res.length == np.inf
    assert res.info["time_limit_hit"] and "no exact solution within 0.5 s" in res.message
    assert res.info["solve_s"] < 0.5 + 5.0  # generous: a contended machine; the point is that it returns


def test_panda_on_the_tabletop():
    from splatplan.planners.robot_links import LinkGeometry
    from splatplan.planners.rrt import edge_samples
    from splatplan.tasks._common import load_task_scene

    ch = load_task_scene("tabletop", n_sigma=1.0, n_splats=20_000).checker  # floaters filtered
    robot = load_robot("panda")
    q1, q2 = robot.q_default.copy(), robot.q_default.copy()
    q1[0], q2[0] = 0.9, -0.9
    res = plan_ompl(ch, q1, q2, robot=robot, name="RRTConnect", time_limit_s=5.0)
    assert res.success, res.message
    p = res.path
    np.testing.assert_array_equal(p[0], q1)
    np.testing.assert_array_equal(p[-1], q2)
    lim = robot.joint_limits
    assert np.all(p >= lim[:, 0] - 1e-9) and np.all(p <= lim[:, 1] + 1e-9)
    # independent dense re-check: 4x finer than the bridge's edge resolution, every ellipsoid
    geom = LinkGeometry(robot)
    pts, _, _ = edge_samples(p[:-1], p[1:], geom.motion(np.diff(p, axis=0)), res.info["edge_resolution"] / 4)
    c, quat, ax = robot.ellipsoids(pts)
    assert not ch.collides(c, quat, ax).any()


def test_unknown_planner_lists_the_available_ones(wall_checker):
    with pytest.raises(SplatplanError, match="available: .*BITstar.*RRTConnect"):
        plan_ompl(wall_checker, START, GOAL, name="RRTsharp", robot=SPHERE, rrt_config=PLANE)
    assert {"RRTConnect", "RRTstar", "BITstar", "PRM", "PRMstar", "KPIECE1"} <= set(available_planners())


def test_plan_dispatch(wall_checker):
    res = plan(wall_checker, START, GOAL, robot=SPHERE, rrt_config=PLANE, planner="ompl:RRTConnect")
    assert res.success and res.info["planner"] == "ompl:RRTConnect"
    with pytest.raises(SplatplanError, match="unknown planner"):
        plan(wall_checker, START, GOAL, robot=SPHERE, rrt_config=PLANE, planner="rrtx")


def test_missing_extra_says_how_to_install(monkeypatch, tmp_path, capsys):
    for mod in ("ompl", "ompl.base", "ompl.geometric", "ompl.util"):
        monkeypatch.setitem(sys.modules, mod, None)  # import -> ImportError, as without the extra
    with pytest.raises(SplatplanError, match=r"pip install 'splatplan\[ompl\]'"):
        plan_ompl(None, START, GOAL, robot=SPHERE)
    from splatplan.cli import main

    rc = main(["plan", "stonehenge.ply", "--start", "0,0,0.06", "--goal", "0.1,0,0.06", "--planner", "ompl:RRTConnect", "--out", str(tmp_path / "p.json")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "pip install 'splatplan[ompl]'" in err[0]


def test_cli_plan_with_ompl_keeps_nanobind_off_stderr(tmp_path):
    """`splatplan plan --planner ompl:NAME` in a fresh interpreter: a path, and no leak report at exit."""
    import os
    import subprocess
    from pathlib import Path

    from splatplan.scenes.load import save_scene

    save_scene(wall_scene(), tmp_path / "wall.ply")
    out = tmp_path / "p.json"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2] / "src")}
    cmd = [sys.executable, "-m", "splatplan.cli", "plan", str(tmp_path / "wall.ply"), "--start=-0.15,0,0.06", "--goal", "0.15,0,0.06",
           "--box", "-0.3,-0.3,0.06", "0.3,0.3,0.06", "--planner", "ompl:RRTConnect", "--time-limit", "2", "--device", "cpu", "--out", str(out)]  # fmt: skip
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr
    assert "nanobind" not in p.stderr and "leaked" not in p.stderr, p.stderr
    import json

    doc = json.loads(out.read_text())
    assert doc["success"] and len(doc["path"]) >= 2


def test_ctrl_c_stops_the_search():
    """SIGINT while OMPL's solve() runs (GIL held, C++ frames on the stack): the search stops at the
    next callback and KeyboardInterrupt is raised after solve() returns, long before the limit."""
    import os
    import signal
    import threading
    import time

    box = make_scene([((0.1, -0.08, 0.0), (0.26, 0.08, 0.14))], spacing=0.01)
    ch = make_checker(box, n_sigma=1.0)
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            plan_ompl(ch, (-0.15, 0.0, 0.06), (0.18, 0.0, 0.06), name="RRTConnect", time_limit_s=60.0, robot=SPHERE, rrt_config=PLANE)
    finally:
        timer.cancel()
    assert time.perf_counter() - t0 < 30.0
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # the handler is restored
