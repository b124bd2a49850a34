"""The picture of a path (`plan --png`): exact ellipsoid outlines against sampled surfaces, frames
along the path, the figure, and the CLI flag (written atomically, refused in one line before work)."""

from __future__ import annotations

import numpy as np
import pytest

from splatplan.render.robot_overlay import ellipsoid_outlines, path_figure, path_frames
from splatplan.scenes import Splats, rotmat_to_quat


def _random_rotations(n: int, rng) -> np.ndarray:
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


@pytest.mark.parametrize("dims", [(0, 1), (0, 2), (1, 2)])
def test_outline_is_the_shadow_of_the_ellipsoid(dims):
    """Reference: dense surface samples projected on the plane; their convex hull is the shadow."""
    from scipy.spatial import ConvexHull, Delaunay

    from splatplan.scenes.splats import quat_to_rotmat

    rng = np.random.default_rng(0)
    c, q, a = rng.normal(size=(5, 3)), _random_rotations(5, rng), rng.uniform(0.01, 0.3, (5, 3))  # anisotropic, rotated
    out = ellipsoid_outlines(c, q, a, dims, n=400)
    u = rng.normal(size=(20000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    for k in range(5):
        pts = (c[k] + (u * a[k]) @ quat_to_rotmat(q[k]).T)[:, list(dims)]
        hull = ConvexHull(pts)
        # every outline point lies on the hull's boundary (within the sampling's resolution) ...
        tri = Delaunay(pts[hull.vertices])
        scale = float(a[k].max())
        shrunk = c[k][list(dims)] + 0.97 * (out[k] - c[k][list(dims)])
        grown = c[k][list(dims)] + 1.03 * (out[k] - c[k][list(dims)])
        assert np.all(tri.find_simplex(shrunk) >= 0) and np.all(tri.find_simplex(grown) < 0), scale
        # ... and the areas agree
        x, y = out[k][:, 0], out[k][:, 1]
        area = 0.5 * abs(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1)))
        assert area == pytest.approx(hull.volume, rel=0.02)


def test_path_frames_span_the_path_evenly():
    path = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 3.0]])
    f = path_frames(path, 5)
    np.testing.assert_allclose(f[0], path[0])
    np.testing.assert_allclose(f[-1], path[-1])
    np.testing.assert_allclose(np.linalg.norm(np.diff(f, axis=0), axis=1), 1.0, atol=1e-12)  # length 4, 4 steps
    np.testing.assert_allclose(path_frames(path[:1], 3), np.repeat(path[:1], 3, axis=0))


def test_path_figure_has_two_views_in_metres():
    from splatplan.robots import load_robot

    rng = np.random.default_rng(0)
    n = 3000
    m = np.c_[rng.uniform(-1, 1, (n, 2)), rng.uniform(0, 0.5, n)]
    s = Splats(m, np.tile(rotmat_to_quat(np.eye(3)), (n, 1)), np.full((n, 3), 0.01), np.full(n, 0.9), np.full((n, 3), 0.5))
    robot = load_robot("sphere:0.05")
    fig = path_figure(s, robot, np.array([[-0.5, 0.0, 0.3], [0.5, 0.2, 0.3]]), n_frames=4)
    views = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in views] == ["top (x-y)", "side (x-z)"]
    for ax in views:
        assert ax.get_xlabel() == "x (m)" and ax.get_aspect() == 1.0
        lo, hi = ax.get_xlim()
        assert lo < -0.55 and hi > 0.55  # the drawn robot fits the view
    assert len(views[0].lines) >= 4 + 3  # 4 outlines, the trace, start and goal


def test_cli_plan_png(tmp_path, capsys):
    from splatplan.cli import main

    ply = tmp_path / "stonehenge.ply"
    assert main(["scene", "stonehenge", "--out", str(ply)]) == 0
    out, png = tmp_path / "p.json", tmp_path / "p.png"
    argv = ["plan", str(ply), "--start", "-0.05,0,0.06", "--goal", "0.45,0.1,0.06", "--time-limit", "5", "--device", "cpu", "--out", str(out)]
    rc = main(argv + ["--png", str(png)])
    text = capsys.readouterr().out
    assert rc == 0, text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"picture of the path (top and side views): {png}" in text
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp file left
    for bad, why in ((tmp_path / "p.jpg", "expected a PATH.png"), (tmp_path / "no" / "p.png", "")):
        out2 = tmp_path / "q.json"
        assert main(argv[:-1] + [str(out2), "--png", str(bad)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("splatplan: error:") and why in err[0]
        assert not out2.exists() and not bad.exists()
