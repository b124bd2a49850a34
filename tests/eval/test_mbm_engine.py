"""`eval mbm` on the job engine: serial and 2 local Dask workers give the same rows for our
(seeded) planner, a rerun resumes, a grown run reuses finished tasks, OMPL's planners get their
rows and table block, and bad ``--planners`` values are one line and exit 2. Skipped without the
shared MBM data (and the OMPL parts without the ``ompl`` extra)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from splatplan.cli import main
from splatplan.eval.mbm import MBMConfig, comparable

REPO = Path(__file__).resolve().parents[2]
MBM = REPO / ".." / "shared" / "data" / "mbm"
needs_mbm = pytest.mark.skipif(not (MBM / "problems").is_dir(), reason=f"{MBM} not present")

#: the first problem of two families (both free at margin 0 with 10k splats; ours solves them in
#: 2 and ~250 nodes), our searches to an iteration budget (--max-iters: no wall-clock limit, so
#: every row, node counts included, is the same on any machine and any worker)
QUICK = ["eval", "mbm", "--quick", "--families", "table_pick,bookshelf_small", "--n-splats", "10000", "--time-limit", "10",
         "--margin-m", "0", "--check-margin", "false", "--max-iters", "400"]  # fmt: skip


def _has_ompl() -> bool:
    from splatplan.planners.ompl_bridge import ompl_available

    return ompl_available()


def _run(capsys, out: Path, *extra: str) -> dict:
    rc = main([*QUICK, *extra, "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    capsys.readouterr()
    return json.loads((out / "mbm.json").read_text())


@needs_mbm
def test_mbm_serial_vs_workers_resume_and_ompl_rows(tmp_path, capsys):
    planners = "auto,ompl:RRTConnect" if _has_ompl() else "auto"
    # a run of our planner alone, then the same run grown by an OMPL planner: the first task is reused
    first = _run(capsys, tmp_path / "serial", "--families", "table_pick")
    assert first["engine"] == {"kind": "serial"} and first["setup"]["tasks"] == {"total": 1, "run": 1, "resumed": 0, "failed": 0}
    serial = _run(capsys, tmp_path / "serial", "--planners", planners)
    n = 2 * len(planners.split(","))
    assert serial["setup"]["tasks"] == {"total": n, "run": n - 1, "resumed": 1, "failed": 0}
    assert [(r["family"], r["planner"]) for r in serial["rows"]] == [(f, p) for f in ("table_pick", "bookshelf_small") for p in planners.split(",")]
    assert serial["rows"][0] == first["rows"][0]  # the resumed row, as it was written
    lines = (tmp_path / "serial" / "mbm.results.jsonl").read_text().splitlines()
    assert len(lines) == n and all(json.loads(x)["ok"] for x in lines)
    # a rerun into the same folder runs nothing and gives the same rows
    again = _run(capsys, tmp_path / "serial", "--planners", planners)
    assert again["setup"]["tasks"]["run"] == 0 and again["rows"] == serial["rows"]
    # 2 local workers: identical rows for our seeded planner (timings aside); OMPL's are not seeded
    dist = _run(capsys, tmp_path / "dask", "--planners", planners, "--workers", "2")
    assert dist["engine"]["kind"] == "dask" and dist["engine"]["workers"] == 2 and dist["engine"]["scheduler"].startswith("tcp://127.0.0.1:")
    assert [comparable(r) for r in dist["rows"]] == [comparable(r) for r in serial["rows"]]
    assert not any(r["timed_out"] for r in dist["rows"] if r["seeded"])  # n_nodes compared too
    ours = [r for r in dist["rows"] if r["planner"] == "auto"]
    assert ours and all(comparable(r) is not None and r["seeded"] for r in ours)
    md = (tmp_path / "dask" / "mbm.md").read_text()
    assert "| auto | overall |" in md and "VAMP" in md
    if _has_ompl():
        om = [r for r in dist["rows"] if r["planner"] == "ompl:RRTConnect"]
        assert len(om) == 2 and not any(r["seeded"] for r in om) and comparable(om[0]) is None
        assert "| ompl:RRTConnect | overall |" in md and "ompl:RRTConnect" in dist["summary_by_planner"]
        assert all(r["solved"] == (r["path"] is not None) for r in om)


@pytest.mark.parametrize(
    ("planners", "needle"),
    [("foo", "unknown planner 'foo'"), ("auto,auto", "listed twice"), ("ompl:NoSuchPlanner", "unknown OMPL planner")],
)
def test_mbm_bad_planners(tmp_path, capsys, planners, needle):
    if planners.startswith("ompl:") and not _has_ompl():
        pytest.skip("the ompl extra is not installed")
    rc = main(["eval", "mbm", "--planners", planners, "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and needle in err and err.count("\n") == 1 and err.startswith("splatplan: error:")
    assert not (tmp_path / "o").exists()


def test_mbm_planners_without_ompl_extra(tmp_path, capsys, monkeypatch):
    from splatplan.planners.ompl_bridge import INSTALL_HINT

    for m in ("ompl", "ompl.base", "ompl.geometric", "ompl.util"):
        monkeypatch.setitem(sys.modules, m, None)  # `import ompl.base` -> ImportError
    rc = main(["eval", "mbm", "--planners", "auto,ompl:RRTConnect", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and INSTALL_HINT in err and err.count("\n") == 1
    assert MBMConfig().planners == ("auto",)  # the default needs no extra
