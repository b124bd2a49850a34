"""The command line: outputs, and bad input -> clear message, exit code 2, no traceback, nothing half-written."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import main

DATA = Path(__file__).parent / "data"
BANANA = DATA / "equinor_banana_splat.ply"


def run_cli(*args: str) -> subprocess.CompletedProcess:
    """Run the installed console entry point in a fresh process (checks banners and tracebacks)."""
    return subprocess.run([sys.executable, "-m", "splatplan.cli", *args], capture_output=True, text=True, timeout=300)


def test_info_json(capsys):
    assert main(["info", str(BANANA), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["count"] == 11458
    assert info["format"] == "inria"
    assert len(info["bounds_min"]) == 3 and len(info["bounds_max"]) == 3
    assert all(a < b for a, b in zip(info["bounds_min"], info["bounds_max"]))


def test_check_writes_all_outputs(tmp_path, capsys):
    rng = np.random.default_rng(0)
    poses = np.concatenate([rng.uniform(-0.2, 0.2, (50, 3)), np.tile([1.0, 0, 0, 0], (50, 1))], axis=1)
    np.save(tmp_path / "poses.npy", poses)
    out = tmp_path / "res.npz"
    assert main(["check", str(BANANA), "--poses", str(tmp_path / "poses.npy"), "--robot", "ellipsoid:0.02,0.01,0.03",
                 "--n-sigma", "1.5", "--out", str(out)]) == 0  # fmt: skip
    res = np.load(out)
    for k in ("min_s2", "n_colliding", "in_collision", "softmin", "cost"):
        assert res[k].shape == (50,), k
    np.save(tmp_path / "p3.npy", poses[:, :3])
    assert main(["check", str(BANANA), "--poses", str(tmp_path / "p3.npy"), "--robot", "sphere:0.02"]) == 0


def test_subprocess_is_quiet_and_clean(tmp_path):
    np.save(tmp_path / "p.npy", np.zeros((4, 3)))
    r = run_cli("check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01")
    assert r.returncode == 0, r.stderr
    assert "Warp" not in r.stdout + r.stderr  # no banner, no CUDA-driver warning
    assert r.stdout.strip().startswith("4 poses checked")


BAD_POSES = {
    "nan": np.array([[0.0, np.nan, 0.0]]),
    "shape": np.zeros((5, 4)),
    "ndim": np.zeros(3),
    "zero_quat": np.zeros((2, 7)),
    "strings": np.array([["a", "b", "c"]]),
}


@pytest.mark.parametrize("case", sorted(BAD_POSES))
def test_bad_poses_exit_2(tmp_path, case):
    np.save(tmp_path / "p.npy", BAD_POSES[case])
    out = tmp_path / "o.npz"
    r = run_cli("check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--out", str(out))
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    assert r.stderr.startswith("splatplan: error:") and "poses" in r.stderr
    assert not out.exists()


def test_bad_inputs_exit_2(tmp_path):
    trunc = tmp_path / "trunc.ply"
    trunc.write_bytes(BANANA.read_bytes()[:5000])
    (tmp_path / "junk.npy").write_bytes(b"not an npy file")
    np.save(tmp_path / "p.npy", np.zeros((2, 3)))
    cases = [
        (["info", str(trunc)], "trunc.ply"),
        (["info", str(tmp_path / "missing.ply")], "missing.ply"),
        (["check", str(BANANA), "--poses", str(tmp_path / "junk.npy"), "--robot", "sphere:0.01"], "junk.npy"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "cube:1"], "--robot"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:-1"], "--robot"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--n-sigma", "-1"], "n_sigma"),
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--out", str(tmp_path / "nodir" / "o.npz")], "nodir"),
        (["scene", "stonehenge", "--out", str(tmp_path / "s.ply"), "--level", "9"], "--level"),
        (["scene", "atlantis", "--out", str(tmp_path / "s.ply")], "atlantis"),
    ]
    for argv, needle in cases:
        r = run_cli(*argv)
        assert r.returncode == 2, (argv, r.stderr)
        assert "Traceback" not in r.stderr, r.stderr
        assert needle in r.stderr, (needle, r.stderr)
    assert sorted(os.listdir(tmp_path)) == ["junk.npy", "p.npy", "trunc.ply"]  # nothing half-written


def test_existing_output_survives_a_failed_run(tmp_path):
    out = tmp_path / "o.npz"
    out.write_bytes(b"precious")
    np.save(tmp_path / "p.npy", np.array([[np.inf, 0, 0]]))
    assert main(["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--out", str(out)]) == 2
    assert out.read_bytes() == b"precious"


def test_scene_stonehenge_writes_ply_and_ground_truth(tmp_path, capsys):
    out = tmp_path / "sh.ply"
    assert main(["scene", "stonehenge", "--out", str(out), "--level", "5", "--seed", "1"]) == 0
    assert out.exists() and (tmp_path / "sh.gt.json").exists()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert info["count"] > 1000


def _write_ply(path: Path, fields: dict[str, np.ndarray]) -> None:
    from plyfile import PlyData, PlyElement

    n = len(next(iter(fields.values())))
    arr = np.zeros(n, dtype=[(k, "f4") for k in fields])
    for k, v in fields.items():
        arr[k] = v
    PlyData([PlyElement.describe(arr, "vertex")]).write(str(path))


def test_broken_scene_files_exit_2(tmp_path):
    n = 20
    good = {"x": np.zeros(n), "y": np.zeros(n), "z": np.zeros(n), "f_dc_0": np.zeros(n), "f_dc_1": np.zeros(n), "f_dc_2": np.zeros(n),
            "opacity": np.zeros(n), "scale_0": np.full(n, -4.0), "scale_1": np.full(n, -4.0), "scale_2": np.full(n, -4.0),
            "rot_0": np.ones(n), "rot_1": np.zeros(n), "rot_2": np.zeros(n), "rot_3": np.zeros(n)}  # fmt: skip
    missing = {k: v for k, v in good.items() if k != "opacity"}
    nan = dict(good, x=np.where(np.arange(n) == 3, np.nan, 0.0))
    zero_q = dict(good, rot_0=np.zeros(n))
    np.save(tmp_path / "p.npy", np.zeros((2, 3)))
    for name, fields, needle in (("missing", missing, "opacity"), ("nan", nan, "NaN"), ("zeroq", zero_q, "quaternion")):
        _write_ply(tmp_path / f"{name}.ply", fields)
        for argv in (["info", str(tmp_path / f"{name}.ply")],
                     ["check", str(tmp_path / f"{name}.ply"), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01"]):  # fmt: skip
            r = run_cli(*argv)
            assert r.returncode == 2, (name, r.stderr)
            assert "Traceback" not in r.stderr and needle in r.stderr, (name, r.stderr)
    _write_ply(tmp_path / "ok.ply", good)
    assert run_cli("info", str(tmp_path / "ok.ply")).returncode == 0


# ------------------------------------------------------------------ conventions shared by every command (issue #7)
def test_version(capsys):
    from splatplan import __version__

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"splatplan {__version__}"


@pytest.mark.parametrize("device, needle", [("gpu", "'gpu' not understood"), ("cuda:7", "cuda:7"), ("cuda:x", "not understood")])
def test_bad_device_is_one_line(tmp_path, capsys, device, needle):
    np.save(tmp_path / "p.npy", np.zeros((2, 3)))
    for argv in (["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--device", device],
                 ["eval", "pr", "--out", str(tmp_path / "pr"), "--device", device],
                 ["demo", "--out", str(tmp_path / "demo"), "--device", device]):  # fmt: skip
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("splatplan: error:") and needle in err and err.count("\n") == 1, err
    assert not (tmp_path / "pr").exists() and not (tmp_path / "demo").exists()


def test_device_auto_resolves_the_same_everywhere():
    from splatplan._warp import resolve_device
    from splatplan.cli._common import check_device

    assert check_device("auto") == resolve_device(None) in ("cpu", "cuda:0")
    assert check_device("cpu") == "cpu"


def test_bad_poses_paths_and_seed_exit_2(tmp_path, capsys):
    np.savez(tmp_path / "p.npz", poses=np.zeros((2, 3)))
    (tmp_path / "adir").mkdir()
    cases = [
        (["check", str(BANANA), "--poses", str(tmp_path / "p.npz"), "--robot", "sphere:0.01"], ".npz archive (arrays: poses)"),
        (["check", str(BANANA), "--poses", str(tmp_path / "adir"), "--robot", "sphere:0.01"], "is a directory"),
        (["check", str(BANANA), "--configs", str(tmp_path / "p.npz"), "--robot", "sphere:0.01"], ".npz archive"),
        (["check", str(BANANA), "--robot", "sphere:0.01"], "exactly one of --poses"),
        (["scene", "stonehenge", "--out", str(tmp_path / "s.ply"), "--seed=-1"], "--seed"),
        (["scene", "stonehenge", "--out", str(tmp_path / "adir")], ".ply"),
    ]
    for argv, needle in cases:
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("splatplan: error:") and needle in err and err.count("\n") == 1, (needle, err)
    assert sorted(os.listdir(tmp_path)) == ["adir", "p.npz"]


@pytest.mark.parametrize("umask", [0o022, 0o077])
def test_outputs_follow_the_umask(tmp_path, umask):
    np.save(tmp_path / "p.npy", np.zeros((3, 3)))
    old = os.umask(umask)
    try:
        assert main(["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.01", "--out", str(tmp_path / "o.npz")]) == 0
        assert main(["scene", "stonehenge", "--out", str(tmp_path / "s.ply"), "--level", "5"]) == 0
    finally:
        os.umask(old)
    for name in ("o.npz", "s.ply", "s.gt.json"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~umask, name
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]  # no temp files or folders left


def _loaded_warp(pid: int) -> bool:
    """True once process ``pid`` has mapped Warp's native library (Linux; True elsewhere after 2 s)."""
    try:
        return "warp" in Path(f"/proc/{pid}/maps").read_text()
    except FileNotFoundError:
        import time

        time.sleep(2.0)
        return True
    except OSError:
        return False


@pytest.mark.parametrize("sig, code", [("SIGINT", 130), ("SIGTERM", 143)])
def test_interrupt_during_the_kernel_exits_cleanly(tmp_path, sig, code):
    import signal
    import time

    np.save(tmp_path / "p.npy", np.zeros((4, 3)))
    assert main(["check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.02", "--device", "cpu"]) == 0  # kernels compiled and cached
    rng = np.random.default_rng(0)
    np.save(tmp_path / "p.npy", rng.uniform(-0.3, 0.3, (2_000_000, 3)))  # ~10-20 s of CPU kernel work on 2 cores
    out = tmp_path / "o.npz"
    proc = subprocess.Popen([sys.executable, "-m", "splatplan.cli", "check", str(BANANA), "--poses", str(tmp_path / "p.npy"), "--robot", "sphere:0.02",
                             "--chunk", "32768", "--device", "cpu", "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: [signal.signal(s, signal.SIG_DFL) for s in (signal.SIGINT, signal.SIGTERM)])  # fmt: skip
    t0 = time.monotonic()  # wait until main() runs (its handlers are installed before Warp loads), then ~1 s more
    while time.monotonic() - t0 < 60 and proc.poll() is None and not _loaded_warp(proc.pid):
        time.sleep(0.05)
    time.sleep(1.0)  # the signal lands in loading or in the chunked kernel phase
    if proc.poll() is not None:
        pytest.skip("check finished before it could be interrupted (fast machine)")
    proc.send_signal(getattr(signal, sig))
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == code, (proc.returncode, err)
    assert "Traceback" not in err and err.strip() in ("splatplan: interrupted", "splatplan: terminated"), err
    assert sorted(os.listdir(tmp_path)) == ["p.npy"]  # no output, no stray temp file


@pytest.mark.parametrize("sig, code, word", [("SIGINT", 130, "interrupted"), ("SIGTERM", 143, "terminated")])
def test_a_signal_that_native_code_turns_into_another_error_reads_as_the_interruption(monkeypatch, capsys, sig, code, word):
    """A Ctrl-C that lands in a C extension's import comes back as ``ImportError: initialization
    failed`` (pybind11 swallows the KeyboardInterrupt): the CLI reports the interruption (one line,
    its exit code), not a traceback; the same error with no signal received stays an error."""
    import argparse
    import signal

    import splatplan.cli as cli

    def interrupted_import(args):
        try:
            os.kill(os.getpid(), getattr(signal, sig))  # the CLI's handler raises on this thread
            time.sleep(5)  # (the handler runs at the next bytecode)
        except BaseException:
            raise ImportError("initialization failed") from None
        return 0

    def failing_import(args):
        raise ImportError("initialization failed")

    for func in (interrupted_import, failing_import):
        parser = argparse.ArgumentParser(prog="splatplan")
        parser.set_defaults(func=func)
        monkeypatch.setattr(cli, "build_parser", lambda p=parser: p)
        if func is failing_import:
            with pytest.raises(ImportError):
                cli.main([])
            continue
        assert cli.main([]) == code
        err = capsys.readouterr().err
        assert err.strip() == f"splatplan: {word}" and "Traceback" not in err


def test_check_robot_configurations(tmp_path, capsys):
    from splatplan.metric import CollisionChecker
    from splatplan.robots import load_robot
    from splatplan.scenes.load import load_scene

    robot = load_robot("panda")
    rng = np.random.default_rng(0)
    lim = np.asarray(robot.joint_limits)
    q = rng.uniform(lim[:, 0], lim[:, 1], (40, robot.dof))
    np.save(tmp_path / "q.npy", q)
    out = tmp_path / "o.npz"
    assert main(["check", str(BANANA), "--robot", "panda", "--configs", str(tmp_path / "q.npy"), "--chunk", "100", "--n-sigma", "0.5",
                 "--device", "cpu", "--out", str(out)]) == 0  # fmt: skip
    assert "40 configurations of panda" in capsys.readouterr().out
    res = np.load(out)
    e = robot.n_ellipsoids
    for k in ("min_s2", "n_colliding", "in_collision", "softmin", "cost"):
        assert res[k].shape == (40, e), k
    links = res["link_names"]
    assert res["collision"].shape == (40,) and res["link_in_collision"].shape == (40, len(links))
    # the same numbers as the API: the checker on the robot's ellipsoids
    checker = CollisionChecker(load_scene(BANANA), n_sigma=0.5, device="cpu")
    ref = checker.query(*robot.ellipsoids(q))
    np.testing.assert_allclose(res["min_s2"], ref.min_s2, rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(res["in_collision"], ref.in_collision)
    np.testing.assert_array_equal(res["collision"], ref.in_collision.any(axis=1))
    for j, name in enumerate(links):
        on_link = np.asarray(robot.ellipsoid_link) == robot.link_names.index(str(name))
        np.testing.assert_array_equal(res["link_in_collision"][:, j], ref.in_collision[:, on_link].any(axis=1))
    # wrong shapes and mixed inputs are one-line errors
    np.save(tmp_path / "bad.npy", q[:, :3])
    for argv, needle in ((["--robot", "panda", "--configs", str(tmp_path / "bad.npy")], "(B, 7)"),
                         (["--robot", "panda", "--poses", str(tmp_path / "q.npy")], "--configs")):  # fmt: skip
        assert main(["check", str(BANANA), *argv]) == 2
        assert needle in capsys.readouterr().err


def test_every_config_field_is_a_flag():
    import argparse
    import dataclasses

    from splatplan.cli import build_parser
    from splatplan.cli.eval import STUDIES, _study
    from splatplan.metric.config import MetricConfig

    parser = build_parser()

    def sub(p: argparse.ArgumentParser, *names: str) -> argparse.ArgumentParser:
        for n in names:
            p = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction)).choices[n]
        return p

    def dests(p):
        return {a.dest for a in p._actions}

    assert {f"cfg_{f.name}" for f in dataclasses.fields(MetricConfig)} <= dests(sub(parser, "check"))
    for name in STUDIES:
        cls = _study(name)[1]
        assert {f"cfg_{f.name}" for f in dataclasses.fields(cls)} <= dests(sub(parser, "eval", name)), name


def test_config_flags_parse_every_type():
    from splatplan.cli import build_parser
    from splatplan.cli._common import config_from_args
    from splatplan.eval.pr import PRConfig
    from splatplan.eval.throughput import ThroughputConfig

    p = build_parser()
    a = p.parse_args(["eval", "pr", "--out", "x", "--quick", "--n-sigmas", "0,1,1.5", "--n-splats", "none", "--variants", "default,log_mean_exp"])
    cfg = config_from_args(a, PRConfig, base=PRConfig.quick_config())
    assert cfg.n_sigmas == (0.0, 1.0, 1.5) and cfg.n_splats is None and cfg.variants == ("default", "log_mean_exp")
    assert cfg.spacing == PRConfig.quick_config().spacing and cfg.quick  # unset flags keep the --quick values
    from splatplan.errors import SplatplanError

    with pytest.raises(SplatplanError, match="include 1"):  # the cross-field rules run with the flags, before any work
        config_from_args(p.parse_args(["eval", "pr", "--out", "x", "--n-sigmas", "0,1.5"]), PRConfig)
    a = p.parse_args(["eval", "throughput", "--out", "x", "--rows", "splatnav:1,collisionsplatting:4096", "--timed-queries", "atlasnav=8",
                      "--baseline-threads", "none,1"])  # fmt: skip
    cfg = config_from_args(a, ThroughputConfig)
    assert cfg.rows == (("splatnav", 1), ("collisionsplatting", 4096)) and cfg.timed_queries == {"atlasnav": 8}
    assert cfg.baseline_threads == (None, 1)
    with pytest.raises(SystemExit):
        p.parse_args(["eval", "pr", "--out", "x", "--spacing", "abc"])


def test_eval_prints_its_table(tmp_path, capsys):
    argv = ["eval", "pr", "--quick", "--out", str(tmp_path), "--n-splats", "4000", "--spacing", "0.06", "--n-sigmas", "1", "--baselines", "splanning",
            "--variants", "default,opacity_filter,opacity_scaled_inflation", "--variant-baseline", "splanning", "--n-check", "1",
            "--n-check-clamped", "0", "--device", "cpu"]  # fmt: skip
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "| method |" in out and "| SPLANNING |" in out and "| Splat-Nav |" not in out
    assert "fidelity variants" in out and "opacity_scaled_inflation" in out and "Reference: SPLANNING" in out
    assert str(tmp_path / "pr.md") in out
    data = json.loads((tmp_path / "pr.json").read_text())
    assert data["config"]["n_splats"] == 4000 and data["config"]["spacing"] == 0.06 and data["device"] == "cpu"
