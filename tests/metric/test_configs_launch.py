"""The recorded-launch CPU path of ``collides_configs`` (:mod:`splatplan.metric.configs_launch`, taken
for numpy batches on a CPU checker: in the workspace given, else the calling thread's): the same hits and
slack as the general path (:func:`general`) and the
numpy reference, on random and near-surface configurations, every n_sigma regime, across a
capacity growth, a change of robot, batch shapes, and the split over threads; invalid input still
gets the general path's errors."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.metric import CollisionChecker, MetricConfig
from splatplan.metric.wp_metric import TierConfig

from .conftest import random_scene


def general(call, *args, **kwargs):
    """``call`` through the general path (the lean one off: no batch fits its launchers)."""
    from splatplan.metric import configs_launch

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(configs_launch, "MAX_BATCH", 0)
        return call(*args, **kwargs)


def _setup(n_sigma: float, seed: int = 0):
    from splatplan.robots import load_robot

    rng = np.random.default_rng(seed)
    scene = random_scene(rng, 4000, scale=0.005 / (1.0 + n_sigma))
    scene.means[:] = rng.uniform(-1.0, 1.0, (4000, 3)) * np.array([0.03, 0.5, 0.4]) + np.array([0.55, 0.0, 0.4])
    ch = CollisionChecker(scene, config=MetricConfig(n_sigma=n_sigma), device="cpu", tiers=TierConfig(distance_grid_voxels=2**15))
    robot = load_robot("panda").inflated(0.01)
    lim = robot.joint_limits
    q = lim[:, 0] + rng.random((300, robot.dof)) * (lim[:, 1] - lim[:, 0])
    hit = np.asarray(general(ch.collides_configs, robot, q))
    near = q[hit][rng.integers(0, int(hit.sum()), 300)] + rng.normal(scale=0.03, size=(300, robot.dof))
    return ch, robot, np.concatenate([q, near]), scene


@pytest.mark.parametrize("n_sigma", [0.0, 1.0, 3.0])
def test_same_hits_and_slack_as_the_general_path(n_sigma):
    ch, robot, q, scene = _setup(n_sigma, seed=int(n_sigma))
    want = np.asarray(general(ch.collides_configs, robot, q))  # the general path
    want_h, want_s = (np.asarray(a) for a in general(ch.collides_configs_slack, robot, q))
    assert 0.1 < want.mean() < 0.9 and (want_s > 0).any()
    ws = ch.workspace()
    # small batches (one thread, recorded launches) in growing sizes: the buffers grow on the way
    for lo, hi in [(0, 1), (1, 9), (9, 70), (70, 200), (200, 600)]:
        got = np.asarray(ch.collides_configs(robot, q[lo:hi], out=ws)).copy()
        np.testing.assert_array_equal(got, want[lo:hi])
        h, s = ch.collides_configs_slack(robot, q[lo:hi], out=ws)
        np.testing.assert_array_equal(np.asarray(h), want_h[lo:hi])
        np.testing.assert_array_equal(np.asarray(s), want_s[lo:hi])
    assert "configs_launcher" in ws._cache
    # the RIGID SLACK (per-ellipsoid targets: the launcher's slack buffer is their input) as the general path's
    target = np.random.default_rng(1).uniform(0.0, 0.04, (len(q), robot.n_ellipsoids))
    want_rh, want_rs = (np.asarray(a) for a in general(ch.collides_configs_slack, robot, q, rigid_target=target))
    np.testing.assert_array_equal(want_rh, want_h)
    assert (want_rs > want_s).any()
    for lo, hi in [(0, 9), (9, 300), (300, 600)]:
        h, s = ch.collides_configs_slack(robot, q[lo:hi], out=ws, rigid_target=target[lo:hi])
        np.testing.assert_array_equal(np.asarray(h), want_h[lo:hi])
        np.testing.assert_array_equal(np.asarray(s), want_rs[lo:hi])
    ref = CollisionChecker(scene, config=MetricConfig(n_sigma=n_sigma), backend="reference")
    np.testing.assert_array_equal(np.asarray(ref.collides_configs(robot, q[::12])), want[::12])


def test_batch_shapes_robot_change_and_threads(monkeypatch):
    ch, robot, q, _ = _setup(0.0, seed=5)
    ws = ch.workspace()
    want = np.asarray(general(ch.collides_configs, robot, q))
    got = np.asarray(ch.collides_configs(robot, q[:60].reshape(3, 20, -1), out=ws))
    np.testing.assert_array_equal(got, want[:60].reshape(3, 20))
    h, s = ch.collides_configs_slack(robot, q[:60].reshape(3, 20, -1), out=ws)
    assert np.asarray(h).shape == (3, 20) and np.asarray(s).shape == (3, 20, robot.n_ellipsoids)
    # float32 input, and a single configuration (..., dof) -> ()
    np.testing.assert_array_equal(np.asarray(ch.collides_configs(robot, q[:50].astype(np.float32), out=ws)), want[:50])
    assert np.asarray(ch.collides_configs(robot, q[3], out=ws)).shape == ()
    # another robot object (a larger inflation) on the same workspace: a new launcher
    big = robot.inflated(0.02)
    np.testing.assert_array_equal(np.asarray(ch.collides_configs(big, q, out=ws)).copy(), np.asarray(general(ch.collides_configs, big, q)))
    np.testing.assert_array_equal(np.asarray(ch.collides_configs(robot, q, out=ws)), want)
    # the workspace keeps a launcher per robot: alternating robots builds none
    built = ws.reallocations
    for _ in range(3):
        np.testing.assert_array_equal(np.asarray(ch.collides_configs(big, q[:40], out=ws)), np.asarray(general(ch.collides_configs, big, q[:40])))
        np.testing.assert_array_equal(np.asarray(ch.collides_configs(robot, q[:40], out=ws)), want[:40])
    assert ws.reallocations == built
    # a new robot object with the same model and semi-axes (another inflated copy) reuses its launcher
    again = robot.inflated(0.02)
    np.testing.assert_array_equal(np.asarray(ch.collides_configs(again, q[:40], out=ws)), np.asarray(general(ch.collides_configs, big, q[:40])))
    assert ws.reallocations == built
    # a batch split over several threads: recorded chunk launches, as many as the batch needs (more on a larger batch)
    from splatplan.metric import wp_metric

    monkeypatch.setattr(wp_metric, "CONFIG_MIN_SPLIT", 16)
    monkeypatch.setattr(wp_metric, "CONFIG_MIN_STEP", 8)
    monkeypatch.setenv("SPLATPLAN_CPU_THREADS", "2")
    ws2 = ch.workspace()
    want_h, want_s = (np.asarray(a) for a in general(ch.collides_configs_slack, robot, q))
    for n in (20, len(q), 100):
        np.testing.assert_array_equal(np.asarray(ch.collides_configs(robot, q[:n], out=ws2)), want[:n])
        h, s = ch.collides_configs_slack(robot, q[:n], out=ws2)
        np.testing.assert_array_equal(np.asarray(h), want_h[:n])
        np.testing.assert_array_equal(np.asarray(s), want_s[:n])


def test_invalid_input_gets_the_general_errors():
    ch, robot, q, _ = _setup(0.0, seed=2)
    ws = ch.workspace()
    bad = q[:5].copy()
    bad[2, 3] = np.nan
    with pytest.raises(SplatplanError, match="NaN"):
        ch.collides_configs(robot, bad, out=ws)
    with pytest.raises(SplatplanError, match="configurations need 7 values"):
        ch.collides_configs(robot, q[:5, :6], out=ws)
    assert np.asarray(ch.collides_configs(robot, q[:0], out=ws)).shape == (0,)


def test_thread_workspace_is_kept_per_checker_and_thread_and_shared_by_searches():
    import threading

    from splatplan.planners.robot_links import LinkGeometry

    ch, robot, q, _ = _setup(0.0, seed=3)
    ws = ch.thread_workspace()
    assert ch.thread_workspace() is ws
    other = []
    t = threading.Thread(target=lambda: other.append(ch.thread_workspace()))
    t.start()
    t.join()
    assert other[0] is not ws
    assert ch.with_config(n_sigma=1.0).thread_workspace() is not ws  # (another config: its own buffers)
    # two searches' geometries (new objects, new inflated copies) on one checker: one launcher
    want = np.asarray(general(ch.collides_configs, robot, q[:50]))
    LinkGeometry(robot).collides(ch, q[:50])
    built = ws.reallocations
    for _ in range(2):
        same = robot.inflated(0.0)  # a new robot object, same model and semi-axes
        np.testing.assert_array_equal(LinkGeometry(same).collides(ch, q[:50]), want)
    assert ws.reallocations == built


def test_without_a_workspace_the_thread_workspace_and_copies():
    """A numpy batch without ``out`` takes the lean path in the calling thread's workspace and gets
    copies: the next call does not overwrite them; the answers are the general path's."""
    ch, robot, q, _ = _setup(1.0, seed=4)
    want = np.asarray(general(ch.collides_configs, robot, q))
    want_h, want_s = (np.asarray(a) for a in general(ch.collides_configs_slack, robot, q))
    first = ch.collides_configs(robot, q[:30])
    h, s = ch.collides_configs_slack(robot, q[:30])
    assert "configs_launcher" in ch.thread_workspace()._cache
    ch.collides_configs(robot, q[300:330])  # (same launcher buffers)
    ch.collides_configs_slack(robot, q[300:330])
    np.testing.assert_array_equal(first, want[:30])
    np.testing.assert_array_equal(h, want_h[:30])
    np.testing.assert_array_equal(s, want_s[:30])
    np.testing.assert_array_equal(np.asarray(ch.collides_configs(robot, q)), want)
