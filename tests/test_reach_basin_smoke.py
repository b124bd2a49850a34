"""benchmarks/reach_basin.py: the --quick run on the committed E5 study's goals writes reach_basin.json
and reach_basin.md, and shows what the script reports: the image cost grows away from every goal
view (a basin), and a coarser pyramid has the wider basin. The committed full result is the same
kind of file with the same goals."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("torch")
pytest.importorskip("warp")

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))

import reach_basin  # noqa: E402

STUDY = REPO / "benchmarks" / "results" / "reach.json"


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("reach_basin")
    assert reach_basin.main(["--quick", "--out", str(out)]) == 0
    return json.loads((out / "reach_basin.json").read_text()), (out / "reach_basin.md").read_text()


def test_every_goal_and_run_is_reported(quick_run):
    data, md = quick_run
    study = json.loads(STUDY.read_text())
    assert data["quick"] is True and data["directions"] == 6
    assert [g["name"] for g in data["goals"]] == [g["name"] for g in study["goals"]]
    for g in data["goals"]:
        assert len(g["translation_median"]) == len(reach_basin.STEPS_M) and len(g["rotation_median"]) == len(reach_basin.STEPS_DEG)
        assert set(g["runs"]) == {"with_collision", "without_collision"}
        for r in g["runs"].values():
            assert r["final_cost"] >= 0
            assert r["guidance_radius_m"] in (0.0, *reach_basin.STEPS_M)
        assert f"| {g['name']} |" in md


def test_the_cost_grows_away_from_every_goal(quick_run):
    data, _ = quick_run
    for g in data["goals"]:
        t, r = g["translation_median"], g["rotation_median"]
        assert t[0] < 0.25 * t[-1], g["name"]  # 0.5 cm from the goal: a fraction of the cost 20 cm away
        assert r[0] < 0.25 * r[-1], g["name"]  # 1 deg against 30 deg


def test_a_coarser_pyramid_has_the_wider_basin(quick_run):
    data, _ = quick_run
    enc = data["encoders"]
    default, coarse, fine = (enc[label]["half_width_m"] for label, _, _ in reach_basin.ENCODERS)
    assert coarse > default > fine


def test_bad_input_is_a_clear_error(tmp_path, capsys):
    assert reach_basin.main(["--study", str(tmp_path / "nope.json"), "--out", str(tmp_path)]) == 2
    assert "no study results" in capsys.readouterr().err
    for text in ("{not json", '{"goals": []}', '{"goals": [{"name": "g", "q": [0, 1]}]}'):
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        assert reach_basin.main(["--study", str(bad), "--out", str(tmp_path)]) == 2
        assert "is not an E5 study result" in capsys.readouterr().err
    for n in ("0", "-1", str(10**18)):
        assert reach_basin.main(["--directions", n, "--out", str(tmp_path)]) == 2
        assert "--directions must be between 1 and" in capsys.readouterr().err
    assert not list(tmp_path.glob("reach_basin.*"))  # nothing written


def test_committed_result_matches_the_study():
    data = json.loads((REPO / "benchmarks" / "results" / "reach_basin.json").read_text())
    study = json.loads(STUDY.read_text())
    assert data["quick"] is False
    assert [g["name"] for g in data["goals"]] == [g["name"] for g in study["goals"]]
    for g, s in zip(data["goals"], study["goals"]):
        for name, r in g["runs"].items():
            assert r["translation_error_m"] == s["runs"][name]["translation_error_m"]
