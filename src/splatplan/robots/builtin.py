"""``load_robot``: built-in robots (offline, from example-robot-data) and any URDF.

Built-ins:

* ``panda``: Franka Panda arm, 7 dofs (panda_joint1..7), base at the world origin. The fingers
  are fixed joints: ``finger_opening`` (m, each finger's distance from the hand's centre line,
  the value of ``panda_finger_joint1``, in [0, 0.04]; default the SRDF "default" state, 0.001 m)
  sets them (``fixed={"panda_finger_joint1": x}`` does the same); the finger ellipsoids move with
  the fingers. Collision models (``model=``): ``"tight"`` (``data/panda_tight.yaml``: a few
  optimised ellipsoids per link, certified to contain the meshes, ``splatplan robot fit panda
  --method opt``, see :mod:`splatplan.robots.fit_opt`), ``"coarse"`` (``data/panda.yaml``: one
  enclosing ellipsoid per link, ``--method split``) and ``"cover"`` (``data/panda_cover.yaml``:
  the greedy union of :mod:`splatplan.robots.fit_cover`). ``DEFAULT_MODEL`` (``"tight"``) says
  which one plain ``"panda"`` loads; the name ``"panda:coarse"`` (or ``panda:cover``,
  ``panda:tight``) picks one wherever a robot name is taken (``--robot panda:coarse``).
* ``go2``: Unitree Go2 as a planar base, dofs (x [m], y [m], yaw [rad]), that walks on terrain
  (``robot.walks_on_terrain``); the 12 leg joints are fixed at the SRDF "standing" state; the body
  is raised so that the lowest point of any ellipsoid (the feet's) is at z = 0. Ellipsoids:
  ``data/go2.yaml``.
* ``sphere:R`` / ``ellipsoid:A,B,C``: one link ("body"), dofs (x, y, z) translation, axis-aligned;
  with ``base="planar"`` the same body as a planar base, dofs (x, y, yaw), at the height of
  ``base_pose`` (e.g. a ground robot's body for MPPI over SE(2)).

A path to a ``.urdf`` loads that robot: every movable non-mimic joint is a dof (or ``active=``),
the base is fixed (or ``base="planar"`` / ``"translation"``), ellipsoids come from ``ellipsoids=``
(YAML), else a sidecar ``<urdf stem>.ellipsoids.yaml``, else they are fitted at load time
(``fit_method``: ``"opt"``, default, the tight and safe fit of :mod:`splatplan.robots.fit_opt`,
about a CPU-minute per link; ``"cover"``; or ``"split"``, milliseconds, enclosing ellipsoids).
``opt`` and ``cover`` fits are cached by :mod:`splatplan.robots.fit_cache` (keyed by the mesh
files' content, the method, its version and parameters), and the MotionBenchMaker Panda's ``opt``
fit ships with the package, so loading it never fits.

What kind of robot a name gives (:attr:`Robot.base`, :attr:`Robot.walks_on_terrain`,
:attr:`Robot.is_point`): ``panda`` a fixed base; ``go2`` a planar base that walks on terrain;
``sphere:R`` / ``ellipsoid:A,B,C`` a point (a translation base), or a planar body with
``base="planar"``; a URDF a fixed base unless ``base=`` says otherwise. **A ground robot from a
URDF**: ``load_robot(path, walks_on_terrain=True)`` (a planar base, ``base="planar"`` implied) or
the name ``PATH.urdf:walking`` (``--robot PATH.urdf:walking`` on the command line;
``PATH.urdf:planar`` is a planar base that does not walk): like ``go2`` it stands on the floor
(raised so that its lowest ellipsoid point is at z = 0 unless ``base_pose`` is given) and the
command line removes the floor's splats (terrain) from its collision scene.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from .fit import METHODS, EllipsoidSet, fit_model, load_yaml
from .kinematics import FIXED, PLANAR, TRANSLATION, Kinematics, bake_fixed
from .robot import Robot
from .urdf import UrdfModel, read_srdf, read_urdf, share_dir

DATA = Path(__file__).parent / "data"
KNOWN = ("panda", "go2", "sphere:R", "ellipsoid:A,B,C")
#: What a robot name may be: the one help text of :func:`load_robot` and of every ``--robot`` flag.
ROBOT_NAME_HELP = (
    "panda (7 joint angles, rad; the tight collision model, panda:coarse = one ellipsoid per link, panda:cover) | "
    "go2 (planar base: x, y, yaw) | sphere:R | ellipsoid:A,B,C "
    "(a point robot: one axis-aligned link with these semi-axes, scene units; dofs x, y, z) | PATH.urdf "
    "(fixed base; PATH.urdf:planar = a planar base x, y, yaw; PATH.urdf:walking = a planar base that walks on terrain, as go2)"
)
#: URDF name suffixes (``PATH.urdf:SUFFIX``) -> (base, walks_on_terrain): see the module docstring.
URDF_SUFFIXES = {"planar": ("planar", False), "walking": ("planar", True)}
#: The point robot of the studies, the demo and ``splatplan plan``: a sphere of radius 0.015 scene
#: units (Stonehenge's gates are sized for it). Give it to a planner as ``load_robot(DEFAULT_POINT_ROBOT)``.
DEFAULT_POINT_ROBOT = "sphere:0.015"
#: Collision models of the built-in Panda: name -> YAML in ``data/``.
PANDA_MODELS = {"coarse": "panda.yaml", "cover": "panda_cover.yaml", "tight": "panda_tight.yaml"}
#: The model plain ``load_robot("panda")`` (and ``--robot panda``) uses: the tight, certified one;
#: ``model="coarse"`` keeps the one-ellipsoid-per-link model.
DEFAULT_MODEL = "tight"
#: The built-in robots whose URDF comes with the package -> the SRDF group state their fixed joints
#: take ("panda": the fingers; "go2": the 12 leg joints).
BUILTIN_STATE = {"panda": "default", "go2": "standing"}
#: Range of the built-in Panda's finger opening (m per finger, panda_finger_joint1).
FINGER_RANGE = (0.0, 0.04)
#: Default base speeds for planar / translation bases (m/s, rad/s); documented, not from a datasheet.
BASE_SPEED = {"x": 1.0, "y": 1.0, "z": 1.0, "yaw": 2.0}


def _known_msg() -> str:
    return f"use one of {', '.join(KNOWN)} or a path to a .urdf file"


@dataclass(frozen=True)
class RobotName:
    """A parsed robot name (see :func:`parse_robot_name`)."""

    #: "panda", "go2", "sphere", "ellipsoid" (point robots) or "path" (a URDF file, checked on load)
    kind: str
    #: the name as given, stripped
    text: str
    #: point robots: the link's semi-axes (a, b, c) along x, y, z (scene units); None otherwise
    semi_axes: tuple[float, float, float] | None = None
    #: "panda:MODEL": the built-in Panda's collision model (:data:`PANDA_MODELS`); None = not named
    model: str | None = None
    #: paths: the file, without a ``:planar`` / ``:walking`` suffix (:data:`URDF_SUFFIXES`); None otherwise
    path: str | None = None
    #: "PATH.urdf:SUFFIX": the base the suffix names ("planar"); None = not named
    base: str | None = None
    #: "PATH.urdf:walking": a ground robot that walks on terrain; None = not named
    walks_on_terrain: bool | None = None

    @property
    def is_point(self) -> bool:
        """A sphere or ellipsoid point robot (one link, dofs x, y, z)."""
        return self.semi_axes is not None


def parse_robot_name(spec: str | Path) -> RobotName:
    """The one parser of robot names (:data:`ROBOT_NAME_HELP`): "panda", "panda:MODEL" (a
    collision model of :data:`PANDA_MODELS`, e.g. "panda:coarse"), "go2", "sphere:R",
    "ellipsoid:A,B,C" or a path, optionally with a base suffix ``PATH.urdf:planar`` /
    ``PATH.urdf:walking`` (:data:`URDF_SUFFIXES`; a file whose name itself ends so is read as that
    file). Point-robot sizes and Panda model names are checked here (finite, > 0); whether a path is
    a URDF file is left to :func:`load_robot`.

    Raises:
        SplatplanError: a malformed "sphere:..." / "ellipsoid:..." or an unknown "panda:MODEL"
            (one line naming the form).
    """
    text = str(spec).strip()
    kind, sep, rest = text.partition(":")
    if text in ("panda", "go2"):
        return RobotName(text, text)
    if sep and kind == "panda" and not Path(text).is_file():
        if rest not in PANDA_MODELS:
            raise SplatplanError(f"robot {text!r}: unknown Panda model {rest!r}: use panda:{' | panda:'.join(PANDA_MODELS)} (plain panda = {DEFAULT_MODEL})")
        return RobotName("panda", text, model=rest)
    if not (sep and kind in ("sphere", "ellipsoid")):
        head, sep, suffix = text.rpartition(":")
        if sep and head and suffix in URDF_SUFFIXES and not Path(text).is_file():
            base, walks = URDF_SUFFIXES[suffix]
            return RobotName("path", text, path=head, base=base, walks_on_terrain=walks)
        return RobotName("path", text, path=text)
    try:
        vals = [float(v) for v in rest.split(",")] if rest else []
    except ValueError:
        raise SplatplanError(f"robot {text!r}: numbers expected after ':' ('sphere:R' or 'ellipsoid:A,B,C', scene units)") from None
    if not ((kind == "sphere" and len(vals) == 1) or (kind == "ellipsoid" and len(vals) == 3)):
        raise SplatplanError(f"robot {text!r} not understood: 'sphere:R' or 'ellipsoid:A,B,C' (semi-axes, scene units)")
    abc = vals * 3 if kind == "sphere" else vals
    axes = (abc[0], abc[1], abc[2])
    if not all(math.isfinite(v) and v > 0 for v in axes):
        raise SplatplanError(f"robot {text!r}: sizes must be finite and > 0")
    return RobotName(kind, text, axes)


def robot_data_dir(sub: str) -> Path:
    share = share_dir()
    if share is None:
        raise SplatplanError("the built-in robots need the 'example-robot-data' package (pip install example-robot-data)")
    return share / "example-robot-data" / "robots" / sub


def builtin_urdf(name: str) -> tuple[Path, Path | None]:
    if name == "panda":
        d = robot_data_dir("panda_description")
        return d / "urdf" / "panda.urdf", d / "srdf" / "panda.srdf"
    if name == "go2":
        d = robot_data_dir("go2_description")
        return d / "urdf" / "go2.urdf", d / "srdf" / "go2.srdf"
    raise SplatplanError(f"unknown built-in robot {name!r}: {_known_msg()}")


def point_radius(name: str = DEFAULT_POINT_ROBOT) -> float:
    """The radius (scene units) of a sphere robot's name: ``"sphere:R"`` -> R (default: the studies'
    sphere :data:`DEFAULT_POINT_ROBOT`), for a study's ``radius`` knob or a plot label.

    Raises:
        SplatplanError: ``name`` is not a sphere.
    """
    parsed = parse_robot_name(name)
    if parsed.kind != "sphere" or parsed.semi_axes is None:  # (a sphere has its semi-axes)
        raise SplatplanError(f"robot {parsed.text!r} is not a sphere 'sphere:R'")
    return parsed.semi_axes[0]


def load_robot(
    spec: "str | Path | Robot",
    *,
    active: list[str] | None = None,
    fixed: dict[str, float] | None = None,
    base: str | None = None,
    base_pose: np.ndarray | None = None,
    ellipsoids: str | Path | None = None,
    per_link: int = 1,
    from_visual: bool = False,
    srdf: str | Path | None = None,
    model: str | None = None,
    finger_opening: float | None = None,
    fit_method: str | None = None,
    walks_on_terrain: bool | None = None,
) -> Robot:
    """A :class:`Robot` from a built-in name or a URDF path (see the module docstring).

    Every call returns a new Robot (its own thread pool and device caches; changing it changes no
    other caller's robot); only the parsed built-in models are cached.

    Args:
        spec: a name (:data:`ROBOT_NAME_HELP`, parsed by :func:`parse_robot_name`), or a Robot
            (returned as is).
        active: joints that are dofs (URDF order kept); others are fixed at ``fixed`` / SRDF / 0.
        fixed: joint values for joints that are not dofs.
        base: "fixed" (default for URDFs), "planar" (x, y, yaw) or "translation" (x, y, z); a
            ``PATH.urdf:planar`` / ``:walking`` name says "planar" already.
        base_pose: (4, 4) world <- robot base (default: identity; a robot that walks on terrain,
            e.g. go2: raised to its standing height, its lowest ellipsoid point at z = 0).
        ellipsoids: YAML with the collision ellipsoids (skips fitting).
        per_link: ellipsoids per link when fitting at load time.
        from_visual: fit links without collision geometry to their visual meshes.
        srdf: SRDF with disabled collision pairs / group states (default: ``<urdf stem>.srdf`` beside it).
        model: built-in Panda only: "tight", "coarse" or "cover" (default: the name's
            ``panda:MODEL``, else ``DEFAULT_MODEL``, "tight").
        finger_opening: built-in Panda only: each finger's distance from the centre line (m, [0, 0.04]).
        fit_method: None = "opt" (default: tight and safe, :mod:`splatplan.robots.fit_opt`, cached),
            "cover" (:mod:`splatplan.robots.fit_cover`, cached) or "split" (enclosing
            ellipsoids, ``per_link`` each) when a URDF is fitted at load time.
        walks_on_terrain: a ground robot (:attr:`Robot.walks_on_terrain`; a planar base: ``base``
            defaults to "planar" and may not be another): it stands on the floor and the floor's
            splats are terrain, not obstacles. None = the name's (``go2``, ``PATH.urdf:walking``:
            True; else False).
    """
    if isinstance(spec, Robot):
        return spec
    parsed = parse_robot_name(spec)
    text = parsed.text
    if parsed.base is not None:  # "PATH.urdf:planar" / ":walking"
        if base is not None and base != parsed.base:
            raise SplatplanError(f"robot {text!r} names base {parsed.base!r} but base={base!r} was given: give one of them")
        if walks_on_terrain is not None and walks_on_terrain != parsed.walks_on_terrain:
            raise SplatplanError(f"robot {text!r} says walks_on_terrain={parsed.walks_on_terrain} but walks_on_terrain={walks_on_terrain} was given: give one of them")
        base, walks_on_terrain = parsed.base, parsed.walks_on_terrain
    if walks_on_terrain:
        base = base or "planar"
        if base != "planar":
            raise SplatplanError(f"robot {text!r}: a robot that walks on terrain has a planar base (x, y, yaw), not base={base!r}")
    if parsed.model is not None:  # "panda:MODEL"
        if model is not None and model != parsed.model:
            raise SplatplanError(f"robot {text!r} names model {parsed.model!r} but model={model!r} was given: give one of them")
        text, model = "panda", parsed.model
    if parsed.is_point:
        urdf_only = [k for k, v in (("active", active), ("fixed", fixed), ("ellipsoids", ellipsoids), ("per_link", per_link != 1), ("from_visual", from_visual),
                                    ("srdf", srdf), ("model", model), ("finger_opening", finger_opening), ("fit_method", fit_method is not None)) if v]  # fmt: skip
        if urdf_only:
            raise SplatplanError(f"robot {text!r}: {', '.join(urdf_only)} apply to URDF robots, not to a point robot (give base= and base_pose= only)")
        return _standing(lambda pose: _point_robot(parsed, base, pose, bool(walks_on_terrain)), base_pose)
    fit_method = "opt" if fit_method is None else fit_method
    if fit_method not in METHODS:
        raise SplatplanError(f"unknown fit method {fit_method!r}: use one of {', '.join(METHODS)}")
    if (model is not None or finger_opening is not None) and text != "panda":
        raise SplatplanError(f"robot {text!r}: model= and finger_opening= apply to the built-in 'panda' only")
    if text in ("panda", "go2"):
        if text == "panda":
            model = model or DEFAULT_MODEL
            if model not in PANDA_MODELS:
                raise SplatplanError(f"unknown Panda model {model!r}: use one of {', '.join(PANDA_MODELS)}")
            if finger_opening is not None:
                fo = float(finger_opening)
                if not (FINGER_RANGE[0] <= fo <= FINGER_RANGE[1]):
                    raise SplatplanError(f"finger_opening {finger_opening} m is outside [{FINGER_RANGE[0]}, {FINGER_RANGE[1]}] (each finger's distance from the centre line)")
                fixed = {**(fixed or {}), "panda_finger_joint1": fo}
            ellipsoids = ellipsoids or DATA / PANDA_MODELS[model]
        if not (active or fixed or base or base_pose is not None or srdf or walks_on_terrain is not None) and (
            ellipsoids is None or text == "panda" and model is not None and Path(ellipsoids) == DATA / PANDA_MODELS[model]
        ):
            return copy.deepcopy(_cached_builtin(text, str(ellipsoids) if ellipsoids else None))  # fresh: never the cached one
        return _builtin(text, active, fixed, base, base_pose, ellipsoids, walks_on_terrain)
    p = Path(parsed.path or text).expanduser()
    if p.suffix.lower() in (".urdf", ".xml") or p.is_file():
        if not p.is_file():
            raise SplatplanError(f"URDF {p} does not exist")
        srdf_path = Path(srdf) if srdf else (p.with_suffix(".srdf") if p.with_suffix(".srdf").is_file() else None)
        ell = ellipsoids or (p.with_name(p.stem + ".ellipsoids.yaml") if p.with_name(p.stem + ".ellipsoids.yaml").is_file() else None)
        model_ = read_urdf(p)
        return _standing(lambda pose: build_robot(model_, srdf_path, active, fixed, base or "fixed", pose, ell, per_link, from_visual,
                                                  fit_method="split" if per_link > 1 else fit_method, walks_on_terrain=bool(walks_on_terrain)),
                         base_pose)  # fmt: skip
    raise SplatplanError(f"unknown robot {text!r}: {_known_msg()}")


def standing_height(robot: Robot) -> float:
    """How far to raise ``robot`` (at its ``q_default``) so that its lowest ellipsoid point is at
    z = 0 of its base frame: minus the lowest point's z (metres / scene units)."""
    c, r = robot.ellipsoid_frames(robot.q_default)
    return -float(np.min(c[:, 2] - np.linalg.norm(r[:, 2, :] * robot.semi_axes, axis=-1)))


def _standing(build: Callable[[np.ndarray | None], Robot], base_pose: np.ndarray | None) -> Robot:
    """``build(base_pose)``; a robot that walks on terrain, given no ``base_pose``, is built again
    standing on the floor: raised by :func:`standing_height` (recorded as
    ``info["standing_height_m"]``)."""
    robot = build(base_pose)
    if base_pose is not None or not robot.walks_on_terrain:
        return robot
    h = standing_height(robot)
    pose = np.eye(4)
    pose[2, 3] = h
    robot = build(pose)
    robot.info["standing_height_m"] = h
    return robot


def _point_robot(name: RobotName, base: str | None, base_pose, walks_on_terrain: bool = False) -> Robot:
    """One axis-aligned ellipsoid on one link: a translation base (x, y, z; default) or a planar
    base (x, y, yaw) in the frame of ``base_pose`` (world <- base, default identity)."""
    text, kind = name.text, name.kind
    base = base or "translation"
    if base not in ("translation", "planar"):
        raise SplatplanError(f"robot {text!r}: base {base!r}: a point robot's base is 'translation' (x, y, z) or 'planar' (x, y, yaw)")
    axes = np.asarray(name.semi_axes, dtype=np.float64)  # (3,)
    origin = np.eye(4)[None].copy()
    if base_pose is not None:
        origin[0] = _check_pose(base_pose)
    jtype, names = (TRANSLATION, ["x", "y", "z"]) if base == "translation" else (PLANAR, ["x", "y", "yaw"])
    kin = Kinematics(["body"], ["xyz" if base == "translation" else "planar"], np.array([-1]), np.array([jtype]), np.array([[1.0, 0, 0]]), origin,
                     np.array([0]), np.ones(1), np.zeros(1))  # fmt: skip
    v = float(4.0 / 3.0 * math.pi * np.prod(axes))
    ells = EllipsoidSet(["body"], np.zeros((1, 3)), np.eye(3)[None], axes[None].astype(np.float64),
                        {"body": {"source": "analytic", "geometry": [kind], "n": 1, "geometry_volume": v, "ellipsoid_volume": v, "volume_ratio": 1.0}})
    lim = np.array([[-np.inf, np.inf]] * 2 + [[-np.inf, np.inf] if base == "translation" else [-math.pi, math.pi]])
    cont = np.array([False, False, base == "planar"])
    return Robot(text, kin, names, lim, np.array([BASE_SPEED[k] for k in names]), np.zeros(3), ells, continuous=cont, walks_on_terrain=walks_on_terrain)


def _check_pose(t) -> np.ndarray:
    t = np.asarray(t, dtype=np.float64)
    if t.shape != (4, 4) or not np.all(np.isfinite(t)) or not np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-6) or np.linalg.det(t[:3, :3]) < 0:
        raise SplatplanError("base_pose must be a finite (4, 4) rigid transform (rotation + translation)")
    return t


@lru_cache(maxsize=4)
def _cached_builtin(name: str, ellipsoids: str | None) -> Robot:
    """The parsed built-in (URDF, SRDF, ellipsoids, FK tables): private, never handed out (only
    deep copies of it are, see :func:`load_robot`), so it stays as built."""
    return _builtin(name, None, None, None, None, ellipsoids, None)


def _builtin(name, active, fixed, base, base_pose, ellipsoids, walks_on_terrain: bool | None) -> Robot:
    urdf, srdf = builtin_urdf(name)
    model = read_urdf(urdf)
    ell = ellipsoids or (DATA / f"{name}.yaml" if (DATA / f"{name}.yaml").is_file() else None)
    if name == "panda":
        active = active or [f"panda_joint{i}" for i in range(1, 8)]
        return build_robot(model, srdf, active, fixed, base or "fixed", base_pose, ell, 1, False, state=BUILTIN_STATE["panda"], name="panda",
                           walks_on_terrain=bool(walks_on_terrain))  # fmt: skip
    # go2: a planar base that walks on terrain (unless told otherwise), standing on the floor
    base = base or "planar"
    walks = base == "planar" if walks_on_terrain is None else bool(walks_on_terrain)
    return _standing(lambda pose: build_robot(model, srdf, active or [], fixed, base, pose, ell, 1, False, state=BUILTIN_STATE["go2"], name="go2", walks_on_terrain=walks),
                     base_pose)  # fmt: skip


def build_robot(
    model: UrdfModel,
    srdf: Path | None,
    active: list[str] | None,
    fixed: dict[str, float] | None,
    base: str,
    base_pose: np.ndarray | None,
    ellipsoids: str | Path | None,
    per_link: int,
    from_visual: bool,
    state: str | None = None,
    name: str | None = None,
    fit_method: str = "split",
    walks_on_terrain: bool = False,
) -> Robot:
    """Assemble a Robot from a parsed URDF: choose dofs, bake the others, attach ellipsoids
    (``walks_on_terrain``: :attr:`Robot.walks_on_terrain`, a planar base only)."""
    sr = read_srdf(srdf) if srdf is not None and Path(srdf).is_file() else None
    kin = model.kin
    dof_joints = model.dof_joints
    active = list(dof_joints) if active is None else list(active)
    unknown = [a for a in active if a not in dof_joints]
    if unknown:
        raise SplatplanError(f"robot {model.name}: unknown or non-movable joints {unknown}; movable joints: {', '.join(dof_joints)}")
    # Values of every URDF dof: SRDF state, then explicit ``fixed``, clipped to limits (0 by default).
    vals = np.zeros(len(dof_joints))
    if sr is not None and state and state in sr.group_states:
        for k, jn in enumerate(dof_joints):
            sv = sr.group_states[state].get(jn)
            if sv and len(sv) == 1:
                vals[k] = sv[0]
    for jn, v in (fixed or {}).items():
        if jn not in dof_joints:
            raise SplatplanError(f"robot {model.name}: cannot fix unknown joint {jn!r}; movable joints: {', '.join(dof_joints)}")
        vals[dof_joints.index(jn)] = float(v)
    vals = np.clip(vals, model.lower, model.upper)
    keep_dof = np.array([jn in active for jn in dof_joints], dtype=bool)
    # Per-link joint value for baking; which links keep their joint.
    keep = np.zeros(kin.n_links, dtype=bool)
    lv = np.zeros(kin.n_links)
    for l in range(kin.n_links):
        if kin.jtype[l] == FIXED:
            continue
        qi = int(kin.qidx[l])
        keep[l] = keep_dof[qi]
        lv[l] = vals[qi] * kin.mult[l] + kin.offset[l]
    kin = bake_fixed(kin, keep, lv)
    new_index = -np.ones(len(dof_joints), dtype=np.int64)
    new_index[keep_dof] = np.arange(int(keep_dof.sum()))
    shift = {"fixed": 0, "planar": 3, "translation": 3}.get(base)
    if shift is None:
        raise SplatplanError(f"base {base!r}: use 'fixed', 'planar' or 'translation'")
    if len(new_index):
        kin.qidx = np.where(kin.qidx >= 0, new_index[np.maximum(kin.qidx, 0)] + shift, -1)
    names = [jn for jn in dof_joints if jn in active]
    lim = np.stack([model.lower[keep_dof], model.upper[keep_dof]], axis=1)
    vel = model.velocity[keep_dof]
    cont = model.continuous[keep_dof]
    qdef = np.clip(vals[keep_dof], lim[:, 0], lim[:, 1])
    qdef = np.where(np.isfinite(qdef), qdef, 0.0)
    if base_pose is not None:
        kin.origin[0] = _check_pose(base_pose)
    if base != "fixed":
        if kin.jtype[0] != FIXED:  # pragma: no cover - URDF roots never have joints
            raise SplatplanError("the root link already moves")
        kin.jtype[0], kin.qidx[0] = (PLANAR if base == "planar" else TRANSLATION), 0
        bnames = ["x", "y", "yaw"] if base == "planar" else ["x", "y", "z"]
        blim = np.array([[-np.inf, np.inf], [-np.inf, np.inf], [-math.pi, math.pi] if base == "planar" else [-np.inf, np.inf]])
        names = bnames + names
        lim = np.concatenate([blim, lim])
        vel = np.concatenate([[BASE_SPEED[n] for n in bnames], vel])
        cont = np.concatenate([[False, False, base == "planar"], cont])
        qdef = np.concatenate([np.zeros(3), qdef])
    if ellipsoids is not None:
        ells = load_yaml(ellipsoids, kin.link_names)
    elif fit_method == "cover":
        from .fit_cache import cached_fit

        ells, cache_file = cached_fit(model, "cover", per_link, from_visual)
    elif fit_method == "opt":
        from .fit_cache import cached_fit

        ells, cache_file = cached_fit(model, "opt", per_link, from_visual)
    else:
        ells = fit_model(model, per_link=per_link, from_visual=from_visual)
    return Robot(
        name or model.name,
        kin,
        names,
        lim,
        vel,
        qdef,
        ells,
        continuous=cont,
        disabled_pairs=sr.disabled_pairs if sr else set(),
        info={"urdf": str(model.path), **({"srdf": str(srdf)} if sr else {})},
        walks_on_terrain=walks_on_terrain,
    )
