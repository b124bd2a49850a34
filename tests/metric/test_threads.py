"""A CPU checker splits large launches over its worker threads (``SPLATPLAN_CPU_THREADS``, default
one per core; :func:`splatplan._warp.launch_split`): every output is the single-thread one. (``make
test`` runs each worker process single-threaded, so the split is exercised here on purpose.)"""

from __future__ import annotations

import numpy as np

from splatplan.metric import CollisionChecker, MetricConfig

from .conftest import random_quats, random_scene


def _checker(monkeypatch, threads: int, scene, n_sigma: float) -> CollisionChecker:
    monkeypatch.setenv("SPLATPLAN_CPU_THREADS", str(threads))  # (read when the checker starts its pool)
    return CollisionChecker(scene, config=MetricConfig(n_sigma=n_sigma), device="cpu")


def test_split_launches_give_the_single_thread_outputs(monkeypatch):
    from splatplan.robots import load_robot

    rng = np.random.default_rng(3)
    scene = random_scene(rng, 3000)
    scene.means[:] = rng.uniform(-0.3, 0.3, (len(scene), 3)) + np.array([0.5, 0.0, 0.4])
    b = 3000  # queries: well above the split threshold (256)
    c = rng.uniform(-0.35, 0.35, (b, 3)) + np.array([0.5, 0.0, 0.4])
    quat = random_quats(rng, b)
    axes = rng.uniform(0.005, 0.04, (b, 3))
    robot = load_robot("panda").inflated(0.01)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((600, robot.dof)) * (lim[:, 1] - lim[:, 0])
    for n_sigma in (0.0, 1.0):
        one = _checker(monkeypatch, 1, scene, n_sigma)
        two = _checker(monkeypatch, 2, scene, n_sigma)
        r1, r2 = one.query(c, quat, axes), two.query(c, quat, axes)
        for f in ("min_s2", "n_colliding", "in_collision"):
            np.testing.assert_array_equal(np.asarray(getattr(r2, f)), np.asarray(getattr(r1, f)), err_msg=f)
        np.testing.assert_allclose(np.asarray(r2.softmin), np.asarray(r1.softmin), rtol=1e-6, atol=0)
        hit = np.asarray(one.collides(c, quat, axes))
        assert 0.05 < hit.mean() < 0.95  # both answers occur
        np.testing.assert_array_equal(np.asarray(two.collides(c, quat, axes)), hit)
        want = np.asarray(one.collides_configs(robot, q))
        assert 0.05 < want.mean() < 0.95
        np.testing.assert_array_equal(np.asarray(two.collides_configs(robot, q)), want)
        np.testing.assert_array_equal(np.asarray(two.collides_robot(robot, q)), np.asarray(one.collides_robot(robot, q)))
        one.close()
        two.close()
