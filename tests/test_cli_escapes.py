"""Issue #21: the 38 escapes a careful tester found (tracebacks, an OOM, a hang, absurd values that
ran, a flag that did nothing, a temp-file name in an error, usage blocks, BrokenPipe, view's exit
code on Ctrl-C), one row each. Every row must now end as a one-line usage error (exit 2) or,
where stated, quietly.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import main

DATA = Path(__file__).parent / "data"
BANANA = str(DATA / "equinor_banana_splat.ply")
ENV = {**os.environ, "SPLATPLAN_NO_TQDM": "1"}


def run_main(argv: list[str], capsys) -> tuple[int, str, str]:
    """The CLI in-process: (exit code, stdout, stderr); argparse's SystemExit counts as its code."""
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = int(exc.code or 0)
    out, err = capsys.readouterr()
    return rc, out, err


def assert_one_line_error(rc: int, err: str, argv) -> None:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2, (argv, rc, err)
    assert "Traceback" not in err, (argv, err)
    assert len(lines) == 1 and lines[0].startswith("splatplan: error: "), (argv, err)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("escapes")
    np.save(d / "poses.npy", np.zeros((4, 3)))
    from PIL import Image

    Image.fromarray(np.full((16, 16, 3), 128, np.uint8)).save(d / "img.png")
    return d


PANDA = ["mpc", "--robot", "panda", "--goal-pose", "0.5,0,0.3,0,1,0,0"]
GO2 = ["mpc", "--robot", "go2", "--goal", "1,0"]
PLAN = ["plan", BANANA, "--start", "0,0,0", "--goal", "0.1,0,0"]
NAV = ["navigate", "--target-image", "{d}/img.png"]

#: (issue's wording, argv after the command's output flag is added where it needs one)
ESCAPES = [
    ("plan --seed -1", PLAN + ["--out", "{d}/p.json", "--seed", "-1"]),
    ("eval pr --seed -1", ["eval", "pr", "--quick", "--out", "{d}/pr", "--seed", "-1"]),
    ("mpc --seed -1", PANDA + ["--out", "{d}/m", "--seed", "-1"]),
    ("navigate --seed -1", NAV + ["--out", "{d}/n", "--seed", "-1"]),
    ("plan --refine --refine-n-samples 0", PLAN + ["--out", "{d}/p.json", "--refine", "--refine-n-samples", "0"]),
    ("plan --refine --refine-n-iters -1", PLAN + ["--out", "{d}/p.json", "--refine", "--refine-n-iters", "-1"]),
    ("navigate --render-batch 0", NAV + ["--out", "{d}/n", "--render-batch", "0"]),
    ("view --port 99999", ["view", BANANA, "--port", "99999"]),
    ("view --port -1", ["view", BANANA, "--port", "-1"]),
    ("view --max-splats -1", ["view", BANANA, "--max-splats", "-1"]),
    ("view --field-res 0", ["view", BANANA, "--field-res", "0"]),
    ("eval pr --quick --spacing 1e-9 (OOM)", ["eval", "pr", "--quick", "--out", "{d}/pr", "--spacing", "1e-9"]),
    ("robot fit --per-link 100000 (hang)", ["robot", "fit", "panda", "--out", "{d}/e.yaml", "--per-link", "100000"]),
    ("check --cost-gamma -1", ["check", BANANA, "--robot", "sphere:0.01", "--poses", "{d}/poses.npy", "--cost-gamma", "-1"]),
    ("plan --refine --refine-noise-sigma -1", PLAN + ["--out", "{d}/p.json", "--refine", "--refine-noise-sigma", "-1"]),
    ("render --background 2,0,0", ["render", BANANA, "--eye", "0,-1,0", "--look-at", "0,0,0", "--width", "8", "--height", "8",
                                   "--out", "{d}/r.png", "--background", "2,0,0"]),  # fmt: skip
    ("encode --encoder-image-size 0", ["encode", "{d}/img.png", "--encoder", "thumbnail", "--encoder-image-size", "0"]),
    ("view --max-splats 0", ["view", BANANA, "--max-splats", "0"]),
    ("mpc panda --arm-mppi-noise-sigma -1", PANDA + ["--out", "{d}/m", "--arm-mppi-noise-sigma", "-1"]),
    ("mpc panda --arm-mppi-n-knots 1000", PANDA + ["--out", "{d}/m", "--arm-mppi-n-knots", "1000"]),
    ("mpc panda --arm-max-steps 0", PANDA + ["--out", "{d}/m", "--arm-max-steps", "0"]),
    ("mpc panda --arm-velocity-scale 0", PANDA + ["--out", "{d}/m", "--arm-velocity-scale", "0"]),
    ("mpc panda --arm-velocity-scale -1", PANDA + ["--out", "{d}/m", "--arm-velocity-scale", "-1"]),
    ("mpc panda --arm-position-tol -1", PANDA + ["--out", "{d}/m", "--arm-position-tol", "-1"]),
    ("mpc go2 --base-mppi-n-samples 0", GO2 + ["--out", "{d}/m", "--base-mppi-n-samples", "0"]),
    ("mpc go2 --base-mppi-dt 0", GO2 + ["--out", "{d}/m", "--base-mppi-dt", "0"]),
    ("mpc go2 --base-goal-tol -1", GO2 + ["--out", "{d}/m", "--base-goal-tol", "-1"]),
    ("mpc go2 --base-sensor-radius-m -1", GO2 + ["--out", "{d}/m", "--base-sensor-radius-m", "-1"]),
    ("mpc go2 --base-memory-cell-m 0", GO2 + ["--out", "{d}/m", "--base-memory-cell-m", "0"]),
    ("mpc go2 --base-memory-yaws 0", GO2 + ["--out", "{d}/m", "--base-memory-yaws", "0"]),
    ("navigate --mppi-dt 0", NAV + ["--out", "{d}/n", "--mppi-dt", "0"]),
    ("navigate --mppi-n-samples 0", NAV + ["--out", "{d}/n", "--mppi-n-samples", "0"]),
    ("navigate --index-spacing-m 0", NAV + ["--out", "{d}/n", "--index-spacing-m", "0"]),
    ("--base-n-iters does nothing", GO2 + ["--out", "{d}/m", "--base-n-iters", "3"]),
    ("argparse usage block", ["plan"]),
]


@pytest.mark.parametrize("what,argv", ESCAPES, ids=[e[0] for e in ESCAPES])
def test_escape_is_one_line_error(what, argv, files, capsys):
    argv = [a.replace("{d}", str(files)) for a in argv]
    before = set(files.rglob("*"))
    t0 = time.perf_counter()
    rc, out, err = run_main(argv, capsys)
    assert_one_line_error(rc, err, argv)
    assert time.perf_counter() - t0 < 60, what
    assert set(files.rglob("*")) == before, f"{what}: left files behind"


def test_oom_and_hang_name_the_flag(files, capsys):
    rc, _, err = run_main(["eval", "pr", "--quick", "--out", str(files / "pr"), "--spacing", "1e-9"], capsys)
    assert rc == 2 and "--spacing" in err
    rc, _, err = run_main(["robot", "fit", "panda", "--out", str(files / "e.yaml"), "--per-link", "100000"], capsys)
    assert rc == 2 and "--per-link" in err
    # found beyond the list: sizes that grow memory without bound
    rc, _, err = run_main(PANDA + ["--out", str(files / "m"), "--arm-mppi-n-samples", "1000000000"], capsys)
    assert rc == 2 and "n_samples" in err and not (files / "m").exists()
    rc, _, err = run_main(["view", BANANA, "--field-res", "10000000", "--device", "cpu"], capsys)
    assert rc == 2 and "--field-res" in err
    rc, _, err = run_main(["view", BANANA, "--n-sigma", "1e30"], capsys)  # crashed the GUI slider (range 0..3)
    assert rc == 2 and "--n-sigma" in err
    # a goal 1e30 away: the edge checks of the path are guarded (was: numpy "array is too big")
    from splatplan.errors import SplatplanError
    from splatplan.planners.rrt import edge_samples

    with pytest.raises(SplatplanError, match="collision checks along 1 edge"):
        edge_samples(np.zeros((1, 3)), np.full((1, 3), 1e30), np.array([1e30]), 0.01)


def test_library_gets_the_same_message():
    from splatplan.errors import SplatplanError
    from splatplan.planners import MPPIConfig
    from splatplan.tasks.base import BaseConfig

    with pytest.raises(SplatplanError, match=r"MPPIConfig\.dt must be > 0, got 0"):
        BaseConfig(mppi=MPPIConfig(dt=0.0)).validate()
    assert not hasattr(BaseConfig(), "n_iters")  # removed: it was never read


def test_view_bad_host_is_one_line(capsys):
    pytest.importorskip("viser")
    rc, _, err = run_main(["view", BANANA, "--host", "8.8.8.8", "--port", "8123"], capsys)
    assert_one_line_error(rc, err, "view --host 8.8.8.8")
    assert "8.8.8.8" in err


def test_bad_out_names_the_given_path(capsys):
    """/proc refuses new files even for root: the error names the path given, not a temp file."""
    if not Path("/proc").is_dir():
        pytest.skip("no /proc")
    argv = ["render", BANANA, "--eye", "0,-1,0", "--look-at", "0,0,0", "--width", "8", "--height", "8", "--out", "/proc/splatplan-x.png"]
    rc, _, err = run_main(argv, capsys)
    assert_one_line_error(rc, err, argv)
    assert "/proc/splatplan-x.png" in err and ".splatplan-x.png." not in err


def _closed_stdout(argv: list[str]) -> subprocess.CompletedProcess:
    """Run the CLI with a stdout whose reader has already gone (``| head -0``)."""
    r, w = os.pipe()
    os.close(r)
    try:
        return subprocess.run([sys.executable, "-m", "splatplan.cli", *argv], stdout=w, stderr=subprocess.PIPE, text=True, timeout=300, env=ENV)
    finally:
        os.close(w)


CLOSED_STDOUT = {
    "robot-info": ["robot", "info", "panda"],
    "check": ["check", BANANA, "--robot", "sphere:0.01", "--poses", "{d}/poses.npy"],
    "plan": PLAN + ["--out", "{d}/piped.json", "--time-limit", "5"],
    "encode": ["encode", "{d}/img.png", "{d}/img.png", "--encoder", "thumbnail"],
}


@pytest.mark.parametrize("name", sorted(CLOSED_STDOUT))
def test_closed_stdout_ends_quietly(name, files):
    res = _closed_stdout([a.replace("{d}", str(files)) for a in CLOSED_STDOUT[name]])
    assert res.returncode in (0, 141), res.stderr  # 141 = 128 + SIGPIPE, as a shell reports it
    assert res.stderr.strip() == "", res.stderr


def test_view_ctrl_c_exits_130(tmp_path):
    pytest.importorskip("viser")
    from splatplan.viewer.app import free_port

    p = subprocess.Popen([sys.executable, "-m", "splatplan.cli", "view", BANANA, "--port", str(free_port()), "--device", "cpu"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)  # fmt: skip
    try:
        line = ""
        t0 = time.time()
        while "splatplan viewer:" not in line and time.time() - t0 < 120:
            line = p.stdout.readline()
            if not line and p.poll() is not None:
                break
        assert "splatplan viewer:" in line, p.stderr.read() if p.poll() is not None else "no viewer line"
        p.send_signal(signal.SIGINT)
        assert p.wait(timeout=60) == 130
        assert "Traceback" not in p.stderr.read()
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
