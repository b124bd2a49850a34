"""Image-goal navigation: floor removal, view retrieval on a tiny hand-made tree, weak matches, a
short drive, and the CLI's bad-input handling."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.errors import SplatplanError
from splatplan.render import SplatRenderer

robots = pytest.importorskip("splatplan.robots")

NODES = np.array([[-0.8, 0.3, 0.0], [-1.0, 1.6, 0.0], [-2.5, -1.9, 0.0], [1.5, 1.0, 0.0], [2.5, -0.8, 0.0], [0.8, -1.9, 0.0]])


@pytest.fixture(scope="module")
def nav_setup():
    from splatplan.encoders import load_encoder
    from splatplan.tasks.navigate import NavigateConfig, load_nav_scene, nav_robot

    cfg = NavigateConfig(image_size=32, n_headings=6, max_steps=8)
    robot = nav_robot()
    nav = load_nav_scene("apartment", cfg)
    with SplatRenderer(nav.render_splats, "cpu") as rend:
        yield robot, nav, cfg, rend, load_encoder("thumbnail")


def test_floor_removed_for_the_metric(nav_setup):
    from splatplan.tasks.navigate import floor_mask

    robot, nav, cfg, rend, enc = nav_setup
    assert "floor" not in nav.task.analytic.labels
    assert len(nav.task.splats) < len(nav.render_splats)
    assert not floor_mask(nav.task.splats).any()
    assert not np.asarray(nav.task.checker.collides_robot(robot, np.asarray(cfg.start)[None])).any()


def test_retrieval_on_a_tiny_tree(nav_setup):
    from splatplan.encoders.view_index import retrieve
    from splatplan.tasks.navigate import build_view_index, head_camera

    robot, nav, cfg, rend, enc = nav_setup
    index = build_view_index(robot, nav, NODES, enc, rend, cfg)
    assert index.poses.shape == (len(NODES) * cfg.n_headings, 3) and np.asarray(index.embeddings).shape[0] == len(index.poses)
    cam = head_camera(robot, cfg)
    # every node and heading, seen from a held-out pose near it (not on it): mostly the right node
    poses = index.poses.copy()
    poses[:, :2] += (0.08, -0.05)
    poses[:, 2] += 0.1
    imgs = np.asarray(cam.render(rend, robot, poses, background=(cfg.background,) * 3).rgb)
    hits = 0
    for img, node in zip(imgs, index.node):
        m = retrieve(index, img, cfg.weak_ratio)
        assert m.cost == pytest.approx(float(np.min(m.costs)))
        hits += int(m.node == node)
    assert hits >= 0.75 * len(imgs), f"{hits} of {len(imgs)} views retrieved their node"
    # any image size: the encoder resizes it
    big = np.asarray(cam.render(rend, robot, NODES[3][None]).rgb[0]).repeat(3, axis=0).repeat(2, axis=1)
    assert retrieve(index, big).costs.shape == (len(index.poses),)
    # noise matches nothing well: reported as weak with its score
    noise = np.random.default_rng(0).random((32, 32, 3)).astype(np.float32)
    w = retrieve(index, noise, cfg.weak_ratio)
    assert w.weak and w.ratio > cfg.weak_ratio and w.to_json()["weak"] is True
    with pytest.raises(SplatplanError, match="RGB"):
        retrieve(index, np.zeros((8, 8)))


def test_short_drive_and_branch(nav_setup):
    from splatplan.planners.route import tree_branch
    from splatplan.tasks.navigate import drive_to

    robot, nav, cfg, rend, enc = nav_setup
    parents = np.array([-1, 0, 1])
    br = tree_branch(NODES[:3], parents, 2)
    np.testing.assert_allclose(br, NODES[:3])
    d = drive_to(robot, nav, (-0.8, 0.9), cfg)
    assert d.states.shape[1] == 3 and 1 <= d.steps <= cfg.max_steps
    assert d.clearance_source == "analytic" and d.min_clearance_m > 0
    assert np.linalg.norm(d.states[-1, :2] - (-0.8, 0.9)) < np.linalg.norm(np.asarray(cfg.start[:2]) - (-0.8, 0.9))


def test_cli_bad_target_images(tmp_path, capsys):
    from splatplan.cli import main

    out = str(tmp_path / "o")
    assert main(["navigate", "--target-image", str(tmp_path / "missing.png"), "--out", out]) == 2
    assert "does not exist" in capsys.readouterr().err
    bad = tmp_path / "bad.png"
    bad.write_bytes(b"not an image at all")
    assert main(["navigate", "--target-image", str(bad), "--out", out]) == 2
    err = capsys.readouterr().err
    assert "not a readable image" in err and "Traceback" not in err
    assert main(["navigate", "--target-image", str(bad), "--out", out, "--weak-ratio", "0"]) == 2
    assert main(["eval", "reach", "--n-goals", "0", "--out", out]) == 2
