"""The CLI's shared helpers in one import (each name is defined in one of these modules):

* :mod:`._values`: command-line text -> numbers, vectors, poses;
* :mod:`._flags`: the parser, typed flags and the flags several commands share;
* :mod:`._config_flags`: config dataclasses -> flags and back;
* :mod:`._inputs`: path checks, scene files, ``.npy`` arrays, robots;
* :mod:`._outputs`: atomic output files and folders, JSON, clean-up of a failed run;
* :mod:`._process`: signals and the plot backend.

Nothing here imports a heavy library at module level.
"""

from __future__ import annotations

from .._files import atomic_path, existing_file, publish
from ._config_flags import Unset, add_config_args, config_from_args, field_docs
from ._flags import (
    BASE_POSE_HELP,
    DEVICE_HELP,
    MAX_WORKERS,
    PORT,
    POSITIVE_INT,
    SEED,
    Parser,
    UsageError,
    add_base_pose_arg,
    add_command,
    add_device_arg,
    add_engine_args,
    add_metric_args,
    add_seed_arg,
    add_terrain_args,
    allow_negative_values,
    check_device,
    engine_from_args,
    float_arg,
    ground_robot_scene,
    int_arg,
    metric_config_from_args,
    reject_nan_flags,
)
from ._inputs import OUTPUT_FILE_DESTS, PATH_DESTS, check_paths, load_npy, load_poses, load_scene_file, robot_at
from ._outputs import (
    CREATED_DIRS,
    OUT_BEFORE,
    atomic_dir,
    dumps_json,
    json_safe,
    move_into,
    out_dir,
    remove_created_empty_dirs,
    remove_new_outputs,
    write_json,
)
from ._process import Terminated, cli_signal_handlers, headless_matplotlib, signals_deferred
from ._values import MAX_COORD, NUMBER_LIST, parse_base_pose, parse_numbers, parse_vec3, strict_float, strict_int, unit_quaternion

#: the private spellings of three helpers, which some command modules import from here
_Unset = Unset
_load = load_scene_file
_out_dir = out_dir

__all__ = [
    "BASE_POSE_HELP", "CREATED_DIRS", "DEVICE_HELP", "MAX_COORD", "MAX_WORKERS", "NUMBER_LIST", "OUTPUT_FILE_DESTS", "OUT_BEFORE", "PATH_DESTS",
    "PORT", "POSITIVE_INT", "SEED", "Parser", "Terminated", "Unset", "UsageError", "add_base_pose_arg", "add_command", "add_config_args",
    "add_device_arg", "add_engine_args", "add_metric_args", "add_seed_arg", "add_terrain_args", "allow_negative_values", "atomic_dir",
    "atomic_path", "check_device", "check_paths", "cli_signal_handlers", "config_from_args", "dumps_json", "engine_from_args", "existing_file",
    "field_docs", "float_arg", "ground_robot_scene", "headless_matplotlib", "int_arg", "json_safe", "load_npy", "load_poses", "load_scene_file",
    "metric_config_from_args", "move_into", "out_dir", "parse_base_pose", "parse_numbers", "parse_vec3", "publish", "reject_nan_flags",
    "remove_created_empty_dirs", "remove_new_outputs", "robot_at", "signals_deferred", "strict_float", "strict_int", "unit_quaternion",
    "write_json",
]  # fmt: skip
