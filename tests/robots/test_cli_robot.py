"""`splatplan robot info|fit`."""

from __future__ import annotations

import json

import numpy as np

from splatplan.cli import main

from .conftest import write_tree


def test_info_builtin_json(capsys):
    assert main(["robot", "info", "panda", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["dof"] == 7 and d["n_ellipsoids"] == 43 and len(d["joints"]) == 7  # plain panda: the tight model
    assert all(1.0 <= v["volume_ratio"] < 5.0 for v in d["fit"].values())
    for argv in (["panda", "--model", "coarse"], ["panda:coarse"]):  # the coarse model stays available by name
        assert main(["robot", "info", *argv, "--json", "--no-measure"]) == 0
        d = json.loads(capsys.readouterr().out)
        assert d["dof"] == 7 and d["n_ellipsoids"] == 11 and len(d["joints"]) == 7
        assert all(1.0 <= v["volume_ratio"] < 5.0 for v in d["fit"].values())
    assert main(["robot", "info", "go2"]) == 0
    out = capsys.readouterr().out
    assert "go2: 3 dof" in out and "ratio" in out and "yaw" in out
    assert main(["robot", "info", "sphere:0.02"]) == 0


def test_fit_writes_yaml_and_png(tmp_path, capsys):
    from splatplan.robots import load_robot
    from splatplan.robots.fit import link_points, mahalanobis
    from splatplan.robots.urdf import read_urdf

    urdf = write_tree(tmp_path)
    out = tmp_path / "fit.yaml"
    assert main(["robot", "fit", str(urdf), "--out", str(out), "--per-link", "2"]) == 0
    cap = capsys.readouterr()
    assert "l6" in cap.err and "without collision geometry" in cap.err
    assert out.is_file() and out.with_suffix(".png").stat().st_size > 10_000
    robot = load_robot(urdf, ellipsoids=out)
    model = read_urdf(urdf)
    for link in ("base", "l4"):  # polytopes split into 2 ellipsoids; every vertex inside their union
        idx = [e for e, l in enumerate(robot.ellipsoid_link) if robot.link_names[l] == link]
        assert len(idx) == 2
        pts = link_points(model.collisions[link], link)
        loc = robot.ellipsoid_local
        inside = np.zeros(len(pts), dtype=bool)
        for e in idx:
            inside |= mahalanobis(pts, loc[e, :3, 3], loc[e, :3, :3], robot.semi_axes[e]) <= 1.0
        assert inside.all()
    assert main(["robot", "info", str(urdf), "--ellipsoids", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["n_ellipsoids"] == robot.n_ellipsoids


def test_cli_errors(tmp_path, capsys):
    broken = tmp_path / "b.urdf"
    broken.write_text("<robot name='x'><link name='a'>")
    nomesh = write_tree(tmp_path / "nomesh" if (tmp_path / "nomesh").mkdir() is None else tmp_path, with_mesh=False)
    cases = [
        (["robot", "info", "ur5"], "unknown robot 'ur5'"),
        (["robot", "info", str(broken)], "does not parse"),
        (["robot", "fit", str(nomesh), "--out", str(tmp_path / "o.yaml")], "not found"),
        (["robot", "fit", str(tmp_path / "none.urdf"), "--out", str(tmp_path / "o.yaml")], "does not exist"),
        (["robot", "fit", "panda", "--out", str(tmp_path / "o.txt")], "expected a .yaml"),
        (["robot", "fit", "panda", "--out", str(tmp_path / "o.yaml"), "--per-link", "0"], "--per-link"),
    ]
    for argv, msg in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) == 1, err
