"""Import hygiene: ``import splatplan`` and the scene stage pull in neither torch nor warp, the core
(scenes, metric, planners, CLI) works with torch absent, and the torch-only parts say which extra
to install. Each check runs in a fresh interpreter (sys.modules of the test process is shared)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BANANA = REPO / "tests" / "data" / "equinor_banana_splat.ply"
BIKER = REPO / "tests" / "data" / "playcanvas_biker.spz"

#: Prepended to a snippet: make ``import torch`` fail as if torch were not installed.
NO_TORCH = "import sys; sys.modules['torch'] = None\n"


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=300, cwd=REPO)


def test_root_and_scenes_import_neither_torch_nor_warp():
    res = _run(
        """
        import sys

        def heavy():
            return sorted(m for m in ("torch", "warp") if m in sys.modules)

        import splatplan
        assert heavy() == [], ("import splatplan", heavy())
        splatplan.load_scene, splatplan.save_scene, splatplan.Splats, splatplan.SplatplanError, splatplan.__version__
        assert heavy() == [], ("splatplan.load_scene etc.", heavy())
        import splatplan.scenes
        from splatplan.scenes import filter_floaters, transforms
        assert heavy() == [], ("import splatplan.scenes", heavy())
        s = splatplan.load_scene(%r)
        assert heavy() == [], ("load_scene(.ply)", heavy())
        splatplan.load_scene(%r)
        assert heavy() == [], ("load_scene(.spz v4)", heavy())
        print("ok", len(s))
        """
        % (str(BANANA), str(BIKER))
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith("ok")


def test_the_command_line_starts_without_the_heavy_modules():
    """Building the CLI (every subcommand's flags and help) loads none of torch, warp, matplotlib or
    scipy.spatial: ``splatplan --help`` and a bad flag answer in well under a second."""
    res = _run(
        """
        import sys
        from splatplan.cli import build_parser

        build_parser()
        print(sorted(m for m in ("torch", "warp", "matplotlib", "scipy.spatial") if m in sys.modules))
        """
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]", res.stdout


def test_core_works_without_torch():
    res = _run(
        NO_TORCH
        + """
import splatplan.metric, splatplan.planners, splatplan.scenes
from splatplan.cli import build_parser
build_parser()
from splatplan.cli import main
rc = main(["info", %r])
assert rc == 0, rc
assert sys.modules.get("torch") is None
print("ok")
"""
        % str(BANANA)
    )
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip().endswith("ok")


def test_baselines_without_torch_name_the_extra():
    res = _run(
        NO_TORCH
        + """
from splatplan.errors import SplatplanError
try:
    import splatplan.baselines
except SplatplanError as e:
    print(e)
else:
    raise SystemExit("imported without torch")
"""
    )
    assert res.returncode == 0, res.stderr
    msg = res.stdout.strip()
    assert "\\n" not in msg and "pip install 'splatplan[baselines]'" in msg


def test_cli_checkpoint_without_torch_is_one_line(tmp_path):
    (tmp_path / "c.pt").write_bytes(b"PK\x03\x04 not really a checkpoint")
    res = _run(NO_TORCH + "from splatplan.cli import main\nsys.exit(main(['info', %r]))\n" % str(tmp_path / "c.pt"))
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "pip install 'splatplan[baselines]'" in lines[0], res.stderr
