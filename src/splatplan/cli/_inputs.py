"""What a command reads: the path check of file arguments, scene files, ``.npy`` arrays, robots.

Nothing here imports a heavy library at module level.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._files import existing_file
from ..errors import SplatplanError

if TYPE_CHECKING:
    from ..robots.robot import Robot

__all__ = ["OUTPUT_FILE_DESTS", "PATH_DESTS", "check_paths", "load_npy", "load_poses", "load_scene_file", "robot_at"]

#: the destinations of flags and positionals that name files or folders (inputs and outputs)
PATH_DESTS = frozenset({"out", "depth", "scene", "input", "poses", "configs", "images", "encoder_weights", "target_image", "urdf",
                        "spec", "tree", "plan", "mpc", "viewmat", "ellipsoids", "meshes_from", "K"})
#: the output-file flags (written through :func:`atomic_path`); ``--out`` of a command whose help
#: says "folder" is an output folder instead
OUTPUT_FILE_DESTS = frozenset({"out", "depth"})


def _path_values(v) -> list[str]:
    vals = v if isinstance(v, (list, tuple)) else [v]
    return [x for x in vals if isinstance(x, str) and x]


def check_paths(args: argparse.Namespace, parser: argparse.ArgumentParser | None = None) -> None:
    """The one cheap path check, before any work: every file or folder argument (``PATH_DESTS``)
    has components the file system can hold (a 300-character name is one line naming the flag,
    not an ``OSError`` after the planner ran), and every output file (``--out PATH.json``,
    ``--depth``) has a place to go (:func:`splatplan._files.output_target`: its folder exists, it
    is not a folder). Output folders are checked when they are made (:func:`out_dir`)."""
    from .._files import output_target

    actions = {a.dest: a for a in (parser._actions if parser is not None else [])}  # noqa: SLF001
    helps = {d: (a.help or "") for d, a in actions.items()}
    for dest, v in vars(args).items():
        if dest not in PATH_DESTS:
            continue
        a = actions.get(dest)
        flag = a.option_strings[-1] if a is not None and a.option_strings else dest.upper()
        for text in _path_values(v):
            for part in Path(text).parts:
                n = len(os.fsencode(part))
                if n > 255:
                    raise SplatplanError(f"{flag} {text}: file name too long ({n} bytes in one name, the limit is 255)")
            if len(os.fsencode(text)) > 4095:
                raise SplatplanError(f"{flag}: path too long ({len(os.fsencode(text))} bytes, the limit is 4095)")
            if dest in OUTPUT_FILE_DESTS and "folder" not in helps.get(dest, "folder"):
                if not os.path.isdir(text):  # a folder given for a file: the command names what it expects
                    output_target(text)
            elif dest not in OUTPUT_FILE_DESTS:
                _input_not_special(flag, text)
    robot = getattr(args, "robot", None)
    if isinstance(robot, str) and robot:
        _input_not_special("--robot", robot)


def _input_not_special(flag: str, text: str) -> None:
    """An input that names a device node, a FIFO or a socket is refused before it is opened
    (reading ``/dev/zero`` never ends; a FIFO blocks until a writer comes): one line naming it."""
    import stat as _stat

    from .._files import file_kind

    try:
        st = os.stat(text)
    except (OSError, ValueError):  # missing, or a name the file system refuses: the reader says so
        return
    if not (_stat.S_ISREG(st.st_mode) or _stat.S_ISDIR(st.st_mode)):
        raise SplatplanError(f"{flag} {text} is {file_kind(st.st_mode)}, not a regular file")


def load_scene_file(path: str, filter_floaters: bool = True, usable: bool = True):
    """The scene file ``path``; ``usable``: refuse (one line) splats whose values the metric and the
    renderer cannot compute with (:func:`splatplan.scenes.sanity.unusable_splats`); ``info`` passes
    False and warns instead."""
    from ..scenes.load import load_scene
    from ..scenes.sanity import unusable_splats

    scene = load_scene(path, filter_floaters=filter_floaters)
    problem = unusable_splats(scene) if usable else None
    if problem:
        raise SplatplanError(f"scene {path}: {problem}")
    return scene


def robot_at(spec: str, base_pose: np.ndarray | None, robot: Robot | None = None) -> Robot:
    """The robot named ``spec`` (or the given ``robot`` of that name, e.g. the Go2 of the tasks) with
    its base placed by ``--base-pose`` (None: unchanged). A robot that walks on terrain keeps its own
    standing offset: the pose places its floor frame, ``pose @ default base pose``."""
    from ..robots import load_robot

    robot = load_robot(spec) if robot is None else robot
    if base_pose is None:
        return robot
    if robot.walks_on_terrain:
        pose = base_pose @ robot.base_pose
        out = load_robot(spec, base_pose=pose)
        out.info.update({k: v for k, v in robot.info.items() if k not in out.info})
        out.info["standing_height_m"] = float(pose[2, 3])
        return out
    return load_robot(spec, base_pose=base_pose)


def load_npy(path: str, what: str) -> np.ndarray:
    """A real numeric ``.npy`` array as float64, or a one-line error naming ``what`` and the problem."""
    p = existing_file(path, what, "a .npy file")
    try:
        arr = np.load(p, allow_pickle=False)
    except Exception as exc:  # numpy raises several types for broken files
        raise SplatplanError(f"{what} {path} is not a readable .npy array ({exc.__class__.__name__}: {exc})") from None
    if isinstance(arr, np.lib.npyio.NpzFile):
        names = ", ".join(arr.files) or "none"
        arr.close()
        raise SplatplanError(f"{what} {path} is an .npz archive (arrays: {names}); save the one array with np.save(PATH.npy, array)")
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise SplatplanError(f"{what} {path}: expected a real numeric array, got dtype {arr.dtype}")
    return arr.astype(np.float64)


def load_poses(path: str) -> tuple[np.ndarray, np.ndarray | None]:
    """POSES.npy of shape (B, 3) centres or (B, 7) centre + wxyz quaternion."""
    arr = load_npy(path, "poses file")
    if arr.ndim != 2 or arr.shape[1] not in (3, 7):
        raise SplatplanError(f"poses file {path}: expected shape (B, 3) centres or (B, 7) centre + wxyz quaternion, got {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise SplatplanError(f"poses file {path}: {int(bad.sum())} row(s) contain NaN or Inf (first: row {int(np.argmax(bad))})")
    if arr.shape[1] == 7:
        q = arr[:, 3:]
        if np.any(np.linalg.norm(q, axis=1) < 1e-8):
            raise SplatplanError(f"poses file {path}: zero quaternion in row {int(np.argmax(np.linalg.norm(q, axis=1) < 1e-8))}")
        return arr[:, :3], q
    return arr, None
