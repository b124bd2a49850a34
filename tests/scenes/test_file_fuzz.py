"""File fuzzing (issue #21): real scene files of every format, with random bytes overwritten and
truncated at random points (seeded). Every outcome is a load or ONE typed error
(:class:`SceneFormatError` in the library; one ``splatplan: error:`` line and exit 2 from
``splatplan info``); a load whose values are absurd is flagged by ``info`` ("absurd splats").

Sources: the fixtures in tests/data and the shared captures in ``<repo>/../shared/data/real``
when present (skipped otherwise), plus a gsplat checkpoint written here. ``SPLATPLAN_FUZZ_FULL=1``
runs 10x more mutations.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
from pathlib import Path

import numpy as np
import pytest

from splatplan.cli import main
from splatplan.errors import SceneFormatError, SplatplanError
from splatplan.scenes import load_scene
from splatplan.scenes.sanity import absurd_splats

REPO = Path(__file__).resolve().parents[2]
FIXTURES = [REPO / "tests" / "data" / "equinor_banana_splat.ply", REPO / "tests" / "data" / "playcanvas_biker.spz"]
SHARED_REAL = REPO / ".." / "shared" / "data" / "real"
SHARED = [SHARED_REAL / "uav4geo_truck.splat", SHARED_REAL / "ARVR_Apartments_Toilet.compressed.ply"]
FULL = os.environ.get("SPLATPLAN_FUZZ_FULL", "") not in ("", "0")
N_MUTANTS = 40 if FULL else 3


def _sources() -> list[Path]:
    return FIXTURES + [p for p in SHARED if p.exists()]


def mutate(data: bytes, rng: np.random.Generator) -> tuple[str, bytes]:
    """One seeded mutation: overwrite 1..16 random bytes (half of the time in the first 4 KiB,
    where headers live), or truncate at a random point."""
    kind = rng.integers(3)
    if kind == 0:
        cut = int(rng.integers(0, len(data)))
        return f"truncated at {cut}", data[:cut]
    buf = bytearray(data)
    span = min(len(buf), 4096) if kind == 1 else len(buf)
    k = int(rng.integers(1, 17))
    pos = rng.integers(0, span, size=k)
    for p in pos:
        buf[p] = int(rng.integers(0, 256))
    return f"{k} byte(s) overwritten at {sorted(int(x) for x in pos)[:4]}...", bytes(buf)


def _info(path: Path) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(["info", str(path), "--json"])
        except SystemExit as exc:
            rc = int(exc.code or 0)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    """A gsplat checkpoint (.pt) of the banana's splats, for the checkpoint reader."""
    torch = pytest.importorskip("torch")
    s = load_scene(FIXTURES[0], filter_floaters=False)
    from splatplan.scenes.io_common import color_to_sh_dc, logit

    splats = {
        "means": torch.from_numpy(s.means),
        "quats": torch.from_numpy(s.quats),
        "scales": torch.from_numpy(np.log(s.scales)),
        "opacities": torch.from_numpy(logit(s.opacities)),
        "sh0": torch.from_numpy(color_to_sh_dc(s.colors)[:, None, :].astype(np.float32)),
        "shN": torch.zeros((len(s), 0, 3)),
    }
    path = tmp_path_factory.mktemp("ckpt") / "banana.pt"
    torch.save({"step": 1, "splats": splats}, path)
    load_scene(path)  # the writer above matches the reader
    return path


def _check_file(src: Path, tmp_path: Path, seed: int) -> list[str]:
    data = src.read_bytes()
    rng = np.random.default_rng(seed)
    problems = []
    for i in range(N_MUTANTS):
        what, mutant = mutate(data, rng)
        path = tmp_path / f"m{i}{src.suffix if not src.name.endswith('.compressed.ply') else '.compressed.ply'}"
        path.write_bytes(mutant)
        try:
            s = load_scene(path, filter_floaters=False)
        except SceneFormatError as exc:
            msg = str(exc)
            if "\n" in msg or str(path) not in msg:
                problems.append(f"{src.name} {what}: message not one line naming the file: {msg!r}")
            loaded = None
        except SplatplanError as exc:
            problems.append(f"{src.name} {what}: untyped SplatplanError (not SceneFormatError): {exc}")
            loaded = None
        except Exception as exc:  # noqa: BLE001 - the escape this test looks for
            problems.append(f"{src.name} {what}: {type(exc).__name__}: {exc}")
            loaded = None
        else:
            loaded = s
        rc, out, err = _info(path)
        if rc == 0:
            info = json.loads(out)
            if loaded is not None and info["absurd"] != absurd_splats(loaded):
                problems.append(f"{src.name} {what}: info's absurd list differs from absurd_splats()")
        elif rc == 2:
            lines = [ln for ln in err.splitlines() if ln.strip()]
            if len(lines) != 1 or not lines[0].startswith("splatplan: error: "):
                problems.append(f"{src.name} {what}: info exit 2 without one error line: {err[-800:]!r}")
        else:
            problems.append(f"{src.name} {what}: info exit {rc}: {err[-800:]!r}")
        if "Traceback" in err:
            problems.append(f"{src.name} {what}: traceback from info")
        path.unlink()
    return problems


@pytest.mark.parametrize("name", [p.name for p in FIXTURES + SHARED])
def test_mutated_real_files(name, tmp_path):
    src = next(p for p in FIXTURES + SHARED if p.name == name)
    if not src.exists():
        pytest.skip(f"{src} not present")
    problems = _check_file(src, tmp_path, seed=sum(map(ord, name)))
    assert not problems, "\n".join(problems[:10])


def test_mutated_checkpoint(checkpoint, tmp_path):
    problems = _check_file(checkpoint, tmp_path, seed=21)
    assert not problems, "\n".join(problems[:10])


def test_absurd_splats_flagged_by_info(tmp_path, capsys):
    """A load that 'succeeds' with absurd values (a far mean, a giant std) is flagged by info."""
    s = load_scene(FIXTURES[0], filter_floaters=False)
    assert absurd_splats(s) == []
    s.means[0] = (1e8, 0.0, 0.0)
    s.scales[1] = (1e5, 1e5, 1e5)
    from splatplan.scenes import save_scene

    path = tmp_path / "absurd.ply"
    save_scene(s, path)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.count("warning: absurd splats:") == 3  # far mean, coordinate beyond 1e7, huge std
    assert main(["info", str(path), "--json"]) == 0
    assert len(json.loads(capsys.readouterr().out)["absurd"]) == 3
