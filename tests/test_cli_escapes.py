"""Issue #21: the 38 escapes a careful tester found (tracebacks, an OOM, a hang, absurd values that
ran, a flag that did nothing, a temp-file name in an error, usage blocks, BrokenPipe, view's exit
code on Ctrl-C), one row each. Every row must now end as a one-line usage error (exit 2) or,
where stated, quietly.
"""

from __future__ import annotations

import importlib.util
import os
import signal
import stat
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


# ---------------------------------------------------------------------------- issue 31: second round
LONG = "L" * 300
RENDER = ["render", BANANA, "--eye", "0,-1,0", "--look-at", "0,0,0", "--width", "8", "--height", "8"]
CHECK = ["check", BANANA, "--robot", "sphere:0.01", "--poses", "{d}/poses.npy"]

#: (kind and the issue's wording, argv); each must be ONE line and exit 2, fast, leaving nothing
ESCAPES_31 = [
    ("E1 info long name", ["info", "{d}/" + LONG + ".ply"]),
    ("E1 check --poses long name", CHECK[:-1] + ["{d}/" + LONG + ".npy"]),
    ("E1 plan --out long name (before planning)", PLAN + ["--out", "{d}/" + LONG + ".json"]),
    ("E1 mpc --out long name (no folder left)", PANDA + ["--out", "{d}/new/" + LONG]),
    ("E1 render --out in a long folder", RENDER + ["--out", "{d}/" + LONG + "/v.png"]),
    ("E2 --out a FIFO without a reader", RENDER + ["--out", "{d}/fifo.png"]),
    ("E5 render --fov 1e-300", RENDER + ["--out", "{d}/v.png", "--fov", "1e-300"]),
    ("E5 render --depth-scale 1e300", RENDER + ["--out", "{d}/v.png", "--depth", "{d}/dv.png", "--depth-scale", "1e300"]),
    ("E5 render --eye 1e308", ["render", BANANA, "--eye", "1e308,0,0", "--look-at", "0,0,0", "--out", "{d}/v.png"]),
    ("E6 check --softmin-t 1e-300", CHECK + ["--softmin-t", "1e-300"]),
    ("E6 plan --goal-pose 1e300 position", ["plan", BANANA, "--robot", "panda", "--start", "0,0,0,-1.5,0,1.5,0.8", "--goal-pose",
                                            "1e300,0.2,0.3,1,0,0,0", "--out", "{d}/p.json", "--time-limit", "1"]),  # fmt: skip
    ("E6 plan --base-pose 1e300", PLAN + ["--out", "{d}/p.json", "--base-pose", "1e300,0,0"]),
    ("E7 plan --rrt-batch-size 1e23", PLAN + ["--out", "{d}/p.json", "--rrt-batch-size", "99999999999999999999999"]),
    ("E7 scene align --translate 1e39", ["scene", "align", BANANA, "--out", "{d}/a.ply", "--translate", "1e39,0,0"]),
    ("E7 scene align --floor 1e300", ["scene", "align", BANANA, "--out", "{d}/a.ply", "--floor", "1e300", "--up", "+z"]),
    ("E7 scene align --scale 1e300", ["scene", "align", BANANA, "--out", "{d}/a.ply", "--scale", "1e300"]),
    ("E9 plan --refine-n-samples 1e9", PLAN + ["--out", "{d}/p.json", "--refine", "--refine-n-samples", "1000000000"]),
    ("E9 plan --refine-n-knots 1e8", PLAN + ["--out", "{d}/p.json", "--refine", "--refine-n-knots", "100000000"]),
    ("E9 plan --refine-check-resolution 1e-12", PLAN + ["--out", "{d}/p.json", "--refine", "--refine-check-resolution", "1e-12"]),
    ("E9 --workers 1e20", ["eval", "pr", "--quick", "--out", "{d}/pr", "--workers", "99999999999999999999"]),
    ("E12 view --tree parent out of range", ["view", BANANA, "--tree", "{d}/tree.npz", "--port", "1"]),
    ("E13 plan --height without --planar", PLAN + ["--out", "{d}/p.json", "--height", "0.1"]),
    ("E13 plan --ee-link without --goal-pose", PLAN + ["--out", "{d}/p.json", "--ee-link", "panda_hand"]),
    ("E13 mpc panda --route", PANDA + ["--out", "{d}/m", "--route"]),
    ("E13 mpc panda --no-route", PANDA + ["--out", "{d}/m", "--no-route"]),
    ("E13 mpc panda --route-time", PANDA + ["--out", "{d}/m", "--route-time", "5"]),
    ("E13 mpc go2 --goal-pose", GO2 + ["--out", "{d}/m", "--goal-pose", "0.5,0,0.3,1,0,0,0"]),
    ("minor: FIFO as input", CHECK[:-1] + ["{d}/fifo.npy"]),
    ("minor: --width 1_0", RENDER[:-4] + ["--width", "1_0", "--height", "8", "--out", "{d}/v.png"]),
    ("minor: --width +3", RENDER[:-4] + ["--width", "+3", "--height", "8", "--out", "{d}/v.png"]),
    ("minor: --fov with an Arabic-Indic digit", RENDER + ["--out", "{d}/v.png", "--fov", "\u0666\u0660"]),
]


@pytest.fixture()
def files31(tmp_path):
    d = tmp_path
    np.save(d / "poses.npy", np.zeros((4, 3)))
    os.mkfifo(d / "fifo.png")
    os.mkfifo(d / "fifo.npy")
    np.savez(d / "tree.npz", nodes=np.zeros((3, 3)), parents=np.array([-1, 0, 7]))
    return d


def _warnings_as_errors():
    import warnings

    ctx = warnings.catch_warnings()
    ctx.__enter__()
    warnings.simplefilter("error")
    for cat in (ResourceWarning, DeprecationWarning, PendingDeprecationWarning):
        warnings.simplefilter("ignore", cat)
    return ctx


@pytest.mark.parametrize("what,argv", ESCAPES_31, ids=[e[0] for e in ESCAPES_31])
def test_escape_31_is_one_line_error(what, argv, files31, capsys):
    if "view" in argv:
        pytest.importorskip("viser")
    argv = [a.replace("{d}", str(files31)) for a in argv]
    before = set(files31.rglob("*"))
    ctx = _warnings_as_errors()  # no warning lines either
    try:
        t0 = time.perf_counter()
        rc, out, err = run_main(argv, capsys)
    finally:
        ctx.__exit__(None, None, None)
    assert_one_line_error(rc, err, argv)
    assert time.perf_counter() - t0 < 60, what
    assert set(files31.rglob("*")) == before, f"{what}: left files behind"
    assert stat.S_ISFIFO(os.lstat(files31 / "fifo.png").st_mode)


def test_kinds_name_their_problem(files31, capsys):
    """The messages name what is wrong (the flag, the path, the limit)."""
    d = str(files31)
    cases = [
        (["info", f"{d}/{LONG}.ply"], "name too long"),
        (PLAN + ["--out", f"{d}/{LONG}.json"], "too long"),
        (RENDER + ["--out", f"{d}/fifo.png"], "FIFO"),
        (CHECK[:-1] + [f"{d}/fifo.npy"], "FIFO"),
        (PLAN + ["--out", f"{d}/p.json", "--refine", "--refine-n-samples", "1000000000"], "--refine-n-samples"),
        (["view", BANANA, "--tree", f"{d}/tree.npz", "--port", "1"], "parents[2] = 7"),
        (["eval", "pr", "--quick", "--out", f"{d}/pr", "--workers", "99999999999999999999"], "--workers"),
    ]
    for argv, needle in cases:
        if "view" in argv and importlib.util.find_spec("viser") is None:
            continue
        rc, _, err = run_main(argv, capsys)
        assert rc == 2 and needle in err, (argv[-2:], err)


def test_huge_quaternions_are_normalised():
    """E6: a quaternion of 1e300-sized parts is a rotation (normalised without overflow), not NaN."""
    from splatplan.cli._common import parse_base_pose
    from splatplan.cli.plan import parse_goal_pose
    from splatplan.robots import load_robot

    v = parse_goal_pose("0.5,0.2,0.3,1e300,1e300,0,0", load_robot("panda"), "panda_hand_tcp")
    assert np.all(np.isfinite(v)) and np.isclose(np.linalg.norm(v[3:]), 1.0)
    pose = parse_base_pose("0,0,0,1e-300,0,0,1e-300")
    assert np.all(np.isfinite(pose)) and np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3))


def _mknod_or_skip(path: Path, minor: int) -> None:
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, minor))
    except (PermissionError, OSError, AttributeError) as exc:
        pytest.skip(f"cannot make a device node here ({exc})")


def test_out_device_nodes_are_written_not_replaced(tmp_path, capsys):
    """E2: an existing non-regular --out (a copy of /dev/null) is written directly: exit 0 and it is
    still the device; a copy of /dev/full gives exit 2 'no space'; neither leaves a temp file."""
    null, full = tmp_path / "null.png", tmp_path / "full.png"
    _mknod_or_skip(null, 3)
    _mknod_or_skip(full, 7)
    rc, _, err = run_main(RENDER + ["--out", str(null)], capsys)
    assert rc == 0, err
    assert stat.S_ISCHR(os.lstat(null).st_mode)
    rc, _, err = run_main(RENDER + ["--out", str(full)], capsys)
    assert_one_line_error(rc, err, "render --out full")
    assert "no space" in err and stat.S_ISCHR(os.lstat(full).st_mode)
    njson = tmp_path / "null.json"
    _mknod_or_skip(njson, 3)
    rc, _, err = run_main(PLAN + ["--out", str(njson), "--time-limit", "2"], capsys)
    assert rc in (0, 1), err
    assert stat.S_ISCHR(os.lstat(njson).st_mode)
    nply = tmp_path / "null.ply"
    _mknod_or_skip(nply, 3)
    rc, _, err = run_main(["scene", "stonehenge", "--out", str(nply)], capsys)
    assert rc == 0, err
    assert stat.S_ISCHR(os.lstat(nply).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full.png", "null.gt.json", "null.json", "null.ply", "null.png"]


def test_out_symlink_is_followed(tmp_path, capsys):
    """E2: a symlinked --out stays a link; its target is replaced atomically (also when the target
    does not exist yet, and for the two files of `scene`)."""
    (tmp_path / "real").mkdir()
    (tmp_path / "real" / "v.png").write_bytes(b"old")
    (tmp_path / "v.png").symlink_to(tmp_path / "real" / "v.png")
    rc, _, err = run_main(RENDER + ["--out", str(tmp_path / "v.png")], capsys)
    assert rc == 0, err
    assert (tmp_path / "v.png").is_symlink() and (tmp_path / "real" / "v.png").read_bytes()[:4] == b"\x89PNG"
    (tmp_path / "s.ply").symlink_to(tmp_path / "real" / "new.ply")  # dangling: the target is created
    rc, _, err = run_main(["scene", "stonehenge", "--out", str(tmp_path / "s.ply")], capsys)
    assert rc == 0, err
    assert (tmp_path / "s.ply").is_symlink() and (tmp_path / "real" / "new.ply").stat().st_size > 1000
    assert not [p for p in tmp_path.rglob(".*")], "temp files left"


URDF = """<robot name="r">
  <link name="a"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="b"><collision><geometry>{geom}</geometry></collision></link>
  <joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="{lower}" upper="1" velocity="{vel}" effort="1"/></joint>
</robot>
"""
BOX = '<box size="0.1 0.1 0.1"/>'
#: E3 / E6 / E14: (what, URDF fields, a word the message must hold)
BAD_URDFS = [
    ("mesh is /dev/zero", dict(geom='<mesh filename="/dev/zero"/>'), "character device"),
    ("mesh is a FIFO", dict(geom='<mesh filename="fifo.stl"/>'), "FIFO"),
    ("mesh scale 0 0 0", dict(geom='<mesh filename="m.stl" scale="0 0 0"/>'), "scale"),
    ("mesh scale NaN", dict(geom='<mesh filename="m.stl" scale="nan 1 1"/>'), 'scale="nan'),
    ("NaN joint origin", dict(xyz="nan 0 0.1"), "joint 'j' <origin"),
    ("huge joint origin", dict(xyz="1e300 0 0.1"), "joint 'j' <origin"),
    ("NaN joint limit", dict(lower="nan"), "lower"),
    ("NaN velocity", dict(vel="nan"), "velocity"),
    ("NaN box size", dict(geom='<box size="nan 0.1 0.1"/>'), "size"),
    ("all-coincident mesh vertices", dict(geom='<mesh filename="coin.stl"/>'), "no extent"),
    ("NaN mesh vertices", dict(geom='<mesh filename="nanv.stl"/>'), "no volume"),
    ("duplicate link", dict(dup="link"), "'a'"),
    ("duplicate joint", dict(dup="joint"), "'j'"),
]


def _stl(*verts) -> str:
    return "solid s\nfacet normal 0 0 1\nouter loop\n" + "".join(f"vertex {v}\n" for v in verts) + "endloop\nendfacet\nendsolid s\n"


@pytest.mark.parametrize("what,fields,needle", BAD_URDFS, ids=[b[0] for b in BAD_URDFS])
def test_invalid_urdf_refused_naming_the_element(what, fields, needle, tmp_path, capsys):
    os.mkfifo(tmp_path / "fifo.stl")
    (tmp_path / "coin.stl").write_text(_stl("1 1 1", "1 1 1", "1 1 1"))
    (tmp_path / "nanv.stl").write_text(_stl("nan 0 0", "1 0 0", "0 1 0"))
    fields = dict(fields)
    dup = fields.pop("dup", None)
    text = URDF.format(**{"geom": BOX, "xyz": "0 0 0.1", "lower": "-1", "vel": "1", **fields})
    if dup == "link":
        text = text.replace('<link name="b">', '<link name="a"/><link name="b">')
    elif dup == "joint":
        text = text.replace("</robot>", '<link name="c"/><joint name="j" type="fixed"><parent link="b"/><child link="c"/></joint></robot>')
    path = tmp_path / "r.urdf"
    path.write_text(text)
    t0 = time.perf_counter()
    rc, _, err = run_main(["robot", "info", str(path)], capsys)
    assert_one_line_error(rc, err, what)
    assert needle in err, err
    assert time.perf_counter() - t0 < 30, what  # refused before any fit or read of the mesh


def test_yaml_structure_extremes(tmp_path, capsys):
    """E8: a 400-digit integer, a 5,000-character integer and 5,000-deep nesting in a MoveIt scene:
    one line naming the file, nothing written."""
    cases = {
        "big.yaml": "world:\n  collision_objects:\n  - id: a\n    primitives: [{type: box, dimensions: [" + "9" * 400 + ", 1, 1]}]\n    primitive_poses: [{}]\n",
        "digits.yaml": "a: " + "9" * 5000 + "\n",
        "deep.yaml": "a: " + "[" * 5000 + "]" * 5000 + "\n",
    }
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
        rc, _, err = run_main(["scene", "from-moveit", str(tmp_path / name), "--out", str(tmp_path / "o.ply")], capsys)
        assert_one_line_error(rc, err, name)
        assert name in err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(cases)


def test_sweep_and_ply_sizes_are_guarded(tmp_path, capsys):
    """E8 / E9 / E11: sweep specs whose sizes or numbers are absurd, and an unreachable scheduler,
    are one line naming the key and leave nothing (no results.jsonl, no folder); an ASCII PLY that
    declares 1e12 vertices is one line, not an allocation."""
    specs = {
        "pairs.yaml": ("scenes: [builtin:stonehenge]\njob: plan\npairs: 1000000000\n", "pairs"),
        "configs.yaml": ("scenes: [builtin:stonehenge]\njob: check\nn_configs: 100000000000\n", "n_configs"),
        "digits.yaml": ("scenes: [builtin:stonehenge]\njob: check\nn_configs: " + "9" * 400 + "\n", "n_configs"),
        "deep.yaml": ("scenes: " + "[" * 5000 + "]" * 5000 + "\n", "nested"),
        "time.yaml": ("scenes: [builtin:stonehenge]\njob: plan\ntime_limit: 1e300\n", "time_limit"),
    }
    for name, (text, needle) in specs.items():
        (tmp_path / name).write_text(text)
        rc, _, err = run_main(["sweep", str(tmp_path / name), "--out", str(tmp_path / "o")], capsys)
        assert_one_line_error(rc, err, name)
        assert needle in err, err
    (tmp_path / "ok.yaml").write_text("scenes: [builtin:stonehenge]\njob: check\nn_configs: 100\n")
    pytest.importorskip("distributed")
    rc, _, err = run_main(["sweep", str(tmp_path / "ok.yaml"), "--out", str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:1"], capsys)
    assert_one_line_error(rc, err, "sweep --scheduler tcp://127.0.0.1:1")
    assert not (tmp_path / "o").exists(), list((tmp_path / "o").iterdir())


def test_ascii_ply_count_beyond_its_size(tmp_path, capsys):
    p = tmp_path / "big.ply"
    p.write_text("ply\nformat ascii 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n")
    t0 = time.perf_counter()
    rc, _, err = run_main(["info", str(p)], capsys)
    assert_one_line_error(rc, err, "info big.ply")
    assert "1,000,000,000,000" in err and time.perf_counter() - t0 < 10


def test_note_lines_do_not_precede_an_error(capsys):
    """Minor (issue 31): a command that prints a note and is then rejected prints one line only;
    a command that succeeds keeps its notes, before its output."""
    import io

    from splatplan.cli import _HeldNotes

    # go2 prints a note on the terrain it removed, then the start is outside the box: one line
    argv = ["plan", BANANA, "--robot", "go2", "--start", "0,0,0", "--goal", "0.1,0,0", "--box", "1,1,0", "2,2,1",
            "--out", str(Path(__import__("tempfile").gettempdir()) / "splatplan-31-never.json"), "--time-limit", "1"]  # fmt: skip
    rc, _, err = run_main(argv, capsys)
    assert_one_line_error(rc, err, argv)

    buf = io.StringIO()
    h = _HeldNotes(buf)
    h.write("note: a\n")
    h.write("splatplan: error: b\n")
    h.finish(keep=False)
    assert buf.getvalue() == "splatplan: error: b\n"
    buf = io.StringIO()
    h = _HeldNotes(buf)
    h.write("note: a\n")
    h.write("\r 50%|#####")  # a progress bar: written at once, after the note
    h.finish(keep=True)
    assert buf.getvalue() == "note: a\n\r 50%|#####"


def test_work_guards_before_work(tmp_path, capsys):
    """E10: an iteration count or a robot whose work is absurd is refused before the run starts."""
    t0 = time.perf_counter()
    rc, _, err = run_main(PANDA + ["--out", str(tmp_path / "m"), "--arm-mppi-n-iters", "100000000"], capsys)
    assert_one_line_error(rc, err, "mpc --arm-mppi-n-iters 1e8")
    assert "lower --arm-mppi-n-iters, --arm-mppi-n-samples" in err and not (tmp_path / "m").exists()  # the flags, not the config fields
    links = "".join(f'<link name="l{i}"><collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>' for i in range(1100))
    joints = "".join(f'<joint name="j{i}" type="fixed"><parent link="l{i}"/><child link="l{i + 1}"/></joint>' for i in range(1099))
    (tmp_path / "many.urdf").write_text(f'<robot name="m">{links}{joints}</robot>')
    rc, _, err = run_main(["robot", "info", str(tmp_path / "many.urdf")], capsys)
    assert_one_line_error(rc, err, "robot info of 1,100 links")
    assert "--per-link" in err
    assert time.perf_counter() - t0 < 60


def test_robot_info_json_is_valid_with_unlimited_joints(tmp_path, capsys):
    """E6: a continuous joint's limits are +-inf: --json prints null, never a bare Infinity/NaN."""
    import json

    text = URDF.format(geom=BOX, xyz="0 0 0.1", lower="-1", vel="1").replace('type="revolute"', 'type="continuous"')
    (tmp_path / "c.urdf").write_text(text)
    # the links' ellipsoids given (a sphere around each 10 cm box): no fit, which is not what this tests (minutes on 2 cores)
    ells = "ellipsoids:\n" + "".join(f"- link: {n}\n  center: [0, 0, 0]\n  quat: [1, 0, 0, 0]\n  semi_axes: [0.0867, 0.0867, 0.0867]\n" for n in "ab")
    (tmp_path / "c.yaml").write_text(ells)
    rc, out, err = run_main(["robot", "info", str(tmp_path / "c.urdf"), "--json", "--ellipsoids", str(tmp_path / "c.yaml")], capsys)
    if rc != 0:
        pytest.skip(f"robot info did not run here: {err}")

    def bad(x):
        raise ValueError(x)

    doc = json.loads(out, parse_constant=bad)
    assert doc["joints"][0]["lower"] is None


def test_mbm_other_robot_is_refused_before_its_fit(tmp_path, capsys):
    """E10: `eval mbm --robot other.urdf` names the joints the problems need before any fit."""
    from splatplan.eval.mbm import DEFAULT_MBM

    if not (DEFAULT_MBM / "problems").is_dir():
        pytest.skip("the shared MBM problems are absent")
    (tmp_path / "r.urdf").write_text(URDF.format(geom=BOX, xyz="0 0 0.1", lower="-1", vel="1"))
    t0 = time.perf_counter()
    rc, _, err = run_main(["eval", "mbm", "--quick", "--out", str(tmp_path / "o"), "--robot", str(tmp_path / "r.urdf")], capsys)
    assert_one_line_error(rc, err, "eval mbm --robot r.urdf")
    assert "panda_joint1" in err and time.perf_counter() - t0 < 30
    assert not (tmp_path / "o").exists()
