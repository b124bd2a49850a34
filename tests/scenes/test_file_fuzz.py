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


# ---------------------------------------------------------------------------- issue 31: content extremes
#: values every numeric file field gets (E4, E5, E6): huge finite, tiny, NaN, Inf, zero
FIELD_EXTREMES = (3e38, -3e38, 1e30, 1e-40, -1e-40, 0.0, float("nan"), float("inf"), float("-inf"))
#: the raw PLY fields of a splat: position, log-std, logit-opacity, quaternion, colour
PLY_FIELDS = ("x", "y", "scale_0", "scale_2", "opacity", "rot_0", "rot_3", "f_dc_0")
N_FIELD_SAMPLE = 60 if FULL else 6


def _run_cli(argv: list[str]) -> tuple[int, str, str]:
    """The CLI in-process with warnings as errors (no warning line may reach the user)."""
    import warnings

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), warnings.catch_warnings():
        warnings.simplefilter("error")
        for cat in (ResourceWarning, DeprecationWarning, PendingDeprecationWarning):
            warnings.simplefilter("ignore", cat)
        try:
            rc = main(argv)
        except SystemExit as exc:
            rc = int(exc.code or 0)
        except Exception as exc:  # noqa: BLE001 - an escape (a warning raised as an error included)
            import traceback

            err.write("Traceback (escaped main):\n" + "".join(traceback.format_exception(exc)))
            rc = -1
    return rc, out.getvalue(), err.getvalue()


def _outcome_problems(what: str, argv, rc: int, out: str, err: str, json_out: bool = False) -> list[str]:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if "Traceback" in err or "Warning" in err:
        return [f"{what}: {' '.join(argv[:2])}: traceback or warning: {err[-600:]!r}"]
    if rc == 2:
        return [] if len(lines) == 1 and lines[0].startswith("splatplan: error: ") else [f"{what}: exit 2 without one error line: {err!r}"]
    if rc not in (0, 1):
        return [f"{what}: {' '.join(argv[:2])}: exit {rc}: {err[-400:]!r}"]
    if json_out:
        def bad(x):
            raise ValueError(x)

        try:
            json.loads(out, parse_constant=bad)
        except ValueError:
            return [f"{what}: info --json printed invalid JSON (NaN/Inf): {out[:200]!r}"]
    if "nan" in out.lower().replace("nan_", "") and "=" in out:
        return [f"{what}: {' '.join(argv[:2])}: NaN in the output: {out[-300:]!r}"]
    return []


def _field_cases() -> list[tuple[str, float]]:
    return [(f, v) for f in PLY_FIELDS for v in FIELD_EXTREMES]


def test_scene_field_extremes(tmp_path):
    """Every raw field of a splat set to each extreme (a seeded sample; all with
    SPLATPLAN_FUZZ_FULL=1): `info --json` prints valid JSON (a warning for absurd splats) or one
    line; `check` (the metric) and `render` are one line or a sane result; no warning lines."""
    import random

    import plyfile

    src = plyfile.PlyData.read(str(FIXTURES[0]))
    cases = _field_cases()
    picked = cases if FULL else random.Random(31).sample(cases, N_FIELD_SAMPLE)
    picked += [("x", 3e38), ("scale_0", 1e-40)] if not FULL else []  # the two examples always
    np.save(tmp_path / "poses.npy", np.zeros((4, 3)))
    problems = []
    for field_name, value in picked:
        v = src["vertex"].data.copy()
        if field_name.startswith("scale") and np.isfinite(value) and value > 0:
            v[field_name][0] = np.float32(np.log(value)) if value > 1e-38 else np.float32(-92.0)  # the std itself is the extreme
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                v[field_name][0] = np.float32(value)
        path = tmp_path / "x.ply"
        plyfile.PlyData([plyfile.PlyElement.describe(v, "vertex")], text=False, byte_order="<").write(str(path))
        what = f"{field_name}={value:g}"
        argvs = [(["info", str(path), "--json"], True),
                 (["check", str(path), "--robot", "sphere:0.01", "--poses", str(tmp_path / "poses.npy"), "--device", "cpu"], False),
                 (["render", str(path), "--eye", "0,-1,0", "--look-at", "0,0,0", "--width", "8", "--height", "8",
                   "--out", str(tmp_path / "r.png"), "--device", "cpu"], False)]  # fmt: skip
        for argv, js in argvs:
            rc, out, err = _run_cli(argv)
            problems += _outcome_problems(what, argv, rc, out, err, js)
        (tmp_path / "r.png").unlink(missing_ok=True)
    assert not problems, "\n".join(problems[:10])


MOVEIT = """
world:
  collision_objects:
    - id: can
      primitives: [{type: cylinder, dimensions: [0.12, 0.03]}]
      primitive_poses: [{position: [0.5, 0.1, 0.3], orientation: [0, 0, 0.3826834, 0.9238795]}]
    - id: shelf
      pose: {position: {x: 1.0, y: 0.0, z: 0.0}, orientation: {x: 0, y: 0, z: 0.7071068, w: 0.7071068}}
      primitives: [{type: box, dimensions: [0.4, 0.2, 0.02]}]
      primitive_poses: [{position: [0.1, 0.0, 0.5], orientation: [0, 0, 0, 1]}]
"""
#: what each numeric YAML leaf gets (E7, E8): YAML spellings of extremes
YAML_EXTREMES = ("1e300", "-1e300", "3.0e38", "1.0e-300", ".nan", ".inf", "0", "9" * 400, "[[[[1]]]]")


def _numeric_leaves(node, path=()):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from _numeric_leaves(v, path + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _numeric_leaves(v, path + (i,))
    elif isinstance(node, (int, float)) and not isinstance(node, bool):
        yield path


def _set(doc, path, value):
    for k in path[:-1]:
        doc = doc[k]
    doc[path[-1]] = value


def test_moveit_field_extremes(tmp_path):
    """Every number of a MoveIt planning scene set to each extreme (seeded sample; all with
    SPLATPLAN_FUZZ_FULL=1), plus deep nesting: `scene from-moveit` gives one line (nothing written)
    or a scene; never a traceback or a warning."""
    import copy
    import random

    import yaml

    base = yaml.safe_load(MOVEIT)
    leaves = list(_numeric_leaves(base))
    cases = [(p, v) for p in leaves for v in YAML_EXTREMES]
    picked = cases if FULL else random.Random(8).sample(cases, 12)
    problems = []
    for path, value in picked:
        doc = copy.deepcopy(base)
        _set(doc, path, "@@")
        text = yaml.safe_dump(doc).replace("'@@'", value)
        f = tmp_path / "s.yaml"
        f.write_text(text)
        argv = ["scene", "from-moveit", str(f), "--out", str(tmp_path / "o.ply"), "--n-splats", "2000"]
        rc, out, err = _run_cli(argv)
        problems += _outcome_problems(f"{'.'.join(map(str, path))}={value[:20]}", argv, rc, out, err)
        if rc == 2 and any(p.name.startswith("o.") for p in tmp_path.iterdir()):
            problems.append(f"{path}={value[:20]}: exit 2 left output files")
        for p in tmp_path.glob("o.*"):
            p.unlink()
    (tmp_path / "deep.yaml").write_text("world: " + "[" * 5000 + "]" * 5000 + "\n")
    rc, out, err = _run_cli(["scene", "from-moveit", str(tmp_path / "deep.yaml"), "--out", str(tmp_path / "o.ply")])
    problems += _outcome_problems("deep nesting", ["scene", "from-moveit"], rc, out, err)
    assert rc == 2
    assert not problems, "\n".join(problems[:10])


URDF_BASE = """<robot name="r">
  <link name="a"><collision><origin xyz="0 0 0" rpy="0 0 0"/><geometry><box size="0.1 0.1 0.1"/></geometry></collision></link>
  <link name="b"><collision><origin xyz="0 0 0.05" rpy="0 0 0"/><geometry><cylinder radius="0.03" length="0.1"/></geometry></collision></link>
  <link name="c"><collision><geometry><sphere radius="0.02"/></geometry></collision></link>
  <link name="d"><collision><geometry><mesh filename="m.stl" scale="1 1 1"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" velocity="1" effort="1"/></joint>
  <joint name="j2" type="prismatic"><parent link="b"/><child link="c"/><origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="0.1" velocity="1" effort="1"/></joint>
  <joint name="j3" type="fixed"><parent link="c"/><child link="d"/><origin xyz="0 0 0.05" rpy="0 0 0"/></joint>
</robot>
"""
#: what each number of a URDF attribute gets (E6, E7, E14)
URDF_EXTREMES = ("nan", "inf", "-inf", "1e300", "-1e300", "0", "1e-300")
STL = "solid s\n" + "".join(
    f"facet normal 0 0 1\nouter loop\nvertex {a}\nvertex {b}\nvertex {c}\nendloop\nendfacet\n"
    for a, b, c in (("0 0 0", "0.05 0 0", "0 0.05 0"), ("0 0 0", "0 0.05 0", "0 0 0.05"), ("0 0 0", "0 0 0.05", "0.05 0 0"),
                    ("0.05 0 0", "0 0.05 0", "0 0 0.05"))
) + "endsolid s\n"


def _urdf_cases() -> list[tuple[int, int, str]]:
    """(attribute occurrence, number index in it, value) for every number of every attribute."""
    import re

    cases = []
    for i, m in enumerate(re.finditer(r'(xyz|rpy|size|radius|length|scale|lower|upper|velocity|effort)="([^"]*)"', URDF_BASE)):
        for k in range(len(m.group(2).split())):
            cases += [(i, k, v) for v in URDF_EXTREMES]
    return cases


def _mutate_urdf(i: int, k: int, value: str) -> str:
    import re

    ms = list(re.finditer(r'(xyz|rpy|size|radius|length|scale|lower|upper|velocity|effort)="([^"]*)"', URDF_BASE))
    m = ms[i]
    nums = m.group(2).split()
    nums[k] = value
    return URDF_BASE[: m.start(2)] + " ".join(nums) + URDF_BASE[m.end(2) :]


def test_urdf_attribute_extremes(tmp_path):
    """Every number of every URDF attribute set to each extreme (seeded sample; all with
    SPLATPLAN_FUZZ_FULL=1), plus duplicate names and a mesh that is a device or a FIFO: `robot
    fit --method split` gives one line naming the element, or a fit with finite numbers; never
    a traceback, a warning, or a read of a device."""
    import random

    (tmp_path / "m.stl").write_text(STL)
    cases = _urdf_cases()
    picked = cases if FULL else random.Random(14).sample(cases, 16)
    texts = [(f"attr{i}[{k}]={v}", _mutate_urdf(i, k, v)) for i, k, v in picked]
    texts += [("duplicate link", URDF_BASE.replace('<link name="c">', '<link name="a"/><link name="c">')),
              ("duplicate joint", URDF_BASE.replace('name="j2"', 'name="j1"')),
              ("mesh /dev/zero", URDF_BASE.replace('filename="m.stl"', 'filename="/dev/zero"'))]
    os.mkfifo(tmp_path / "f.stl")
    texts.append(("mesh FIFO", URDF_BASE.replace('filename="m.stl"', 'filename="f.stl"')))
    problems = []
    for what, text in texts:
        (tmp_path / "r.urdf").write_text(text)
        argv = ["robot", "fit", str(tmp_path / "r.urdf"), "--method", "split", "--out", str(tmp_path / "e.yaml"), "--no-png"]
        rc, out, err = _run_cli(argv)
        problems += _outcome_problems(what, argv, rc, out, err)
        if rc == 0 and "nan" in (tmp_path / "e.yaml").read_text().lower():
            problems.append(f"{what}: the fit holds NaN")
        if what.startswith(("duplicate", "mesh")) and rc != 2:
            problems.append(f"{what}: accepted (exit {rc})")
        (tmp_path / "e.yaml").unlink(missing_ok=True)
    assert not problems, "\n".join(problems[:10])
