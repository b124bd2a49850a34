"""`splatplan sweep`: serial and 2 local Dask workers give the same cells; resume; bad input is one
line and exit 2."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("distributed")
pytest.importorskip("yaml")

from splatplan.cli import main
from splatplan.scenes.load import save_scene

from ..planners.scenes import make_scene

SPEC = """
scenes: ["scenes/*.ply"]
job: plan
robot: sphere:0.015
n_sigma: [0.0, 1.0]
seeds: [0, 1]
planners: [rrt]
time_limit: 30
max_iters: 200
pairs: 2
"""


@pytest.fixture(scope="module")
def spec_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("sweep")
    (d / "scenes").mkdir()
    floor = ((-0.25, -0.25, -0.01), (0.25, 0.25, 0.0))
    save_scene(make_scene([floor, ((-0.01, -0.25, 0.0), (0.01, 0.12, 0.12))], spacing=0.02, seed=0), d / "scenes" / "wall.ply")
    save_scene(make_scene([floor, ((0.05, -0.05, 0.0), (0.1, 0.05, 0.1))], spacing=0.02, seed=1), d / "scenes" / "post.ply")
    (d / "spec.yaml").write_text(SPEC)
    return d


def rows(out) -> dict:
    recs = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert len({r["key"] for r in recs}) == len(recs)
    return {r["key"]: {k: v for k, v in r["row"].items() if k != "time_s"} for r in recs}


def test_sweep_serial_equals_two_workers_and_resumes(spec_dir, capsys):
    a, b = spec_dir / "serial", spec_dir / "dask"
    assert main(["sweep", str(spec_dir / "spec.yaml"), "--out", str(a)]) == 0
    assert main(["sweep", str(spec_dir / "spec.yaml"), "--out", str(b), "--workers", "2"]) == 0
    ra, rb = rows(a), rows(b)
    assert len(ra) == 2 * 2 * 2 * 2 and ra == rb  # scenes x n_sigma x seeds x pairs, identical per cell
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert sa["engine"] == {"kind": "serial"}
    assert sb["engine"]["kind"] == "dask" and sb["engine"]["workers"] == 2 and sb["engine"]["scheduler"].startswith("tcp://127.0.0.1:")
    untimed = [[{k: v for k, v in g.items() if k != "median_time_s"} for g in s["groups"]] for s in (sa, sb)]
    assert untimed[0] == untimed[1] and sa["n_failed"] == 0
    assert (a / "summary.md").read_text().startswith("# sweep: plan jobs")
    capsys.readouterr()
    assert main(["sweep", str(spec_dir / "spec.yaml"), "--out", str(a)]) == 0  # resume: nothing left to run
    assert json.loads((a / "summary.json").read_text())["n_run"] == 0 and rows(a) == ra


@pytest.mark.parametrize(
    "text, extra, msg",
    [
        ("scenes: [a\njob: plan", [], "not valid YAML"),
        (SPEC + "colour: red\n", [], "unknown key(s) colour"),
        (SPEC, ["--workers", "0"], "--workers must be an integer >= 1"),
        (SPEC, ["--scheduler", "tcp://127.0.0.1:9"], "cannot reach the Dask scheduler"),
        (SPEC.replace("scenes/*.ply", "nothing/*.ply"), [], "matches no file"),
        (SPEC.replace("[rrt]", "[ompl:RRTsharp]"), [], "unknown OMPL planner"),
    ],
)
def test_bad_input_is_one_line_exit_2(spec_dir, tmp_path, capsys, text, extra, msg):
    spec = spec_dir / "bad.yaml"
    spec.write_text(text)
    rc = main(["sweep", str(spec), "--out", str(tmp_path / "o"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and msg in err[0], err


@pytest.mark.parametrize("study, extra, msg", [("pr", ["--workers", "0"], ">= 1"), ("conservatism", ["--scheduler", "nowhere"], "tcp://HOST:PORT")])
def test_eval_engine_flags_bad_input(tmp_path, capsys, study, extra, msg):
    rc = main(["eval", study, "--quick", "--out", str(tmp_path / "o"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and msg in err[0], err
    assert not (tmp_path / "o").exists()  # rejected before any work or output


def test_check_job(spec_dir):
    spec = spec_dir / "check.yaml"
    spec.write_text('scenes: ["scenes/wall.ply"]\njob: check\nn_sigma: [0, 2]\nseeds: 3\nn_configs: 2000\n')
    out = spec_dir / "check_out"
    assert main(["sweep", str(spec), "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    frac = {g["n_sigma"]: g["colliding_fraction"] for g in s["groups"]}
    assert 0 < frac[0.0] <= frac[2.0] < 1  # more conservative: more configurations in collision
    assert "| wall.ply | 2 | 1 |" in (out / "summary.md").read_text()
