"""URDF (via ``yourdfpy``) and SRDF reading into flat kinematics and per-link geometry lists.

``package://PKG/...`` mesh paths are resolved against the ``example-robot-data`` share directory
(the cmeel prefix in site-packages) and, failing that, against the URDF's own folder and its
parents (``package://PKG/x`` -> ``<ancestor>/PKG/x`` or ``<ancestor>/x``).
"""

from __future__ import annotations

import math
import os
import stat
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import SplatplanError
from .kinematics import PRISMATIC, REVOLUTE, Kinematics


def share_dir() -> Path | None:
    """The cmeel ``share`` folder that holds ``example-robot-data`` (None when not installed)."""
    for base in [Path(p) for p in sys.path if p] + [Path(sys.prefix) / "lib"]:
        cand = base / "cmeel.prefix" / "share"
        if (cand / "example-robot-data").is_dir():
            return cand
    return None


def resolve_mesh_path(filename: str, urdf_dir: Path) -> Path:
    """Absolute path of a URDF mesh reference (``package://``, ``file://``, relative or absolute)."""
    if filename.startswith("file://"):
        filename = filename[len("file://") :]
    if filename.startswith("package://"):
        rel = filename[len("package://") :]
        cands = []
        share = share_dir()
        if share is not None:
            cands.append(share / rel)
        pkg, _, rest = rel.partition("/")
        for anc in [urdf_dir, *urdf_dir.parents]:
            cands += [anc / rel, anc / rest]
            if anc.name == pkg:
                cands.append(anc / rest)
        for c in cands:
            if c.is_file():
                return c
        return cands[0]
    p = Path(filename)
    return p if p.is_absolute() else urdf_dir / p


@dataclass
class Geom:
    """One collision or visual element of a link."""

    kind: str  # "mesh", "box", "sphere", "cylinder", "capsule"
    origin: np.ndarray  # (4, 4) link <- geometry frame
    size: np.ndarray  # box: (3,) full sizes; sphere: (r,); cylinder/capsule: (r, length) along z; mesh: (3,) scale
    mesh: Path | None = None  # resolved mesh file
    ref: str = ""  # the mesh filename as written in the URDF


@dataclass
class UrdfModel:
    """Everything read from a URDF: the full tree (every movable, non-mimic joint a dof)."""

    name: str
    path: Path
    kin: Kinematics
    dof_joints: list[str]  # (n,) movable non-mimic joints in URDF order
    lower: np.ndarray  # (n,)
    upper: np.ndarray  # (n,)
    velocity: np.ndarray  # (n,)
    continuous: np.ndarray  # (n,) bool
    collisions: dict[str, list[Geom]] = field(default_factory=dict)
    visuals: dict[str, list[Geom]] = field(default_factory=dict)


def _rpy_xyz(el) -> np.ndarray:
    t = np.eye(4)
    if el is None:
        return t
    xyz = [float(v) for v in el.get("xyz", "0 0 0").split()]
    r, p, y = [float(v) for v in el.get("rpy", "0 0 0").split()]
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    t[:3, :3] = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    t[:3, 3] = xyz
    return t


def _capsules(path: Path) -> dict[tuple[str | None, str, int], Geom]:
    """<capsule> elements (not in the URDF standard, ignored by yourdfpy): (link, tag, index) -> Geom."""
    out: dict[tuple[str | None, str, int], Geom] = {}
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError:
        return out
    for link in root.iter("link"):
        for tag in ("collision", "visual"):
            for i, el in enumerate(link.findall(tag)):
                cap = el.find("geometry/capsule")
                if cap is not None:
                    r, ln = float(cap.get("radius", "nan")), float(cap.get("length", "nan"))
                    out[(link.get("name"), tag, i)] = Geom("capsule", _rpy_xyz(el.find("origin")), np.array([r, ln]))
    return out


def _geoms(link, tag: str, urdf_dir: Path, caps: dict) -> list[Geom]:
    out = []
    for i, el in enumerate(link.collisions if tag == "collision" else link.visuals):
        g = el.geometry
        origin = np.eye(4) if el.origin is None else np.asarray(el.origin, dtype=np.float64)
        if (link.name, tag, i) in caps:
            out.append(caps[(link.name, tag, i)])
            continue
        if g is None or (g.box is None and g.sphere is None and g.cylinder is None and g.mesh is None):
            continue
        if g.box is not None:
            out.append(Geom("box", origin, np.asarray(g.box.size, dtype=np.float64)))
        elif g.sphere is not None:
            out.append(Geom("sphere", origin, np.array([float(g.sphere.radius)])))
        elif g.cylinder is not None:
            out.append(Geom("cylinder", origin, np.array([float(g.cylinder.radius), float(g.cylinder.length)])))
        else:
            scale = g.mesh.scale
            scale = np.ones(3) if scale is None else np.broadcast_to(np.asarray(scale, dtype=np.float64), (3,)).copy()
            out.append(Geom("mesh", origin, scale, resolve_mesh_path(g.mesh.filename, urdf_dir), g.mesh.filename))
    return out


def read_urdf(path: str | Path) -> UrdfModel:
    """Parse a URDF file into a :class:`UrdfModel` (no meshes are loaded here)."""
    import yourdfpy

    from .._files import MAX_TEXT_BYTES, existing_file

    path = existing_file(path, "URDF", "a URDF file", max_bytes=MAX_TEXT_BYTES)  # a FIFO or a device is never opened
    try:
        root = ET.parse(path).getroot()  # strict XML check first (yourdfpy silently recovers from broken XML)
    except ET.ParseError as exc:
        raise SplatplanError(f"URDF {path} does not parse (XML error: {exc})") from None
    if root.tag != "robot":
        raise SplatplanError(f"URDF {path} does not parse: the root element is <{root.tag}>, expected <robot name=...>")
    _check_attributes(path, root)  # before yourdfpy computes with them (sin(inf) warned)
    caps = _capsules(path)
    source: object = str(path)
    if caps:  # yourdfpy rejects <capsule>: parse it as a sphere placeholder, replaced below
        import io

        tree = ET.parse(path)
        for el in tree.getroot().iter("capsule"):
            el.tag = "sphere"
            el.attrib.pop("length", None)
        buf = io.BytesIO()
        tree.write(buf)
        source = io.BytesIO(buf.getvalue())
    import logging

    ylog = logging.getLogger("yourdfpy")
    level = ylog.level
    ylog.setLevel(logging.CRITICAL)  # our own one-line errors instead of its log lines
    try:
        u = yourdfpy.URDF.load(
            source,
            load_meshes=False,
            load_collision_meshes=False,
            build_scene_graph=False,
            build_collision_scene_graph=False,
        )
        robot = u.robot
    except Exception as exc:  # lxml / yourdfpy raise many types for broken files
        raise SplatplanError(f"URDF {path} does not parse ({exc.__class__.__name__}: {str(exc).splitlines()[0] if str(exc) else ''})") from None
    finally:
        ylog.setLevel(level)
    if not robot.links:
        raise SplatplanError(f"URDF {path} has no links")
    links = {l.name: l for l in robot.links}
    child_joint = {}
    kids: dict[str, list] = {n: [] for n in links}
    for j in robot.joints:
        if j.parent not in links or j.child not in links:
            raise SplatplanError(f"URDF {path}: joint {j.name!r} refers to a missing link ({j.parent!r} -> {j.child!r})")
        if j.child in child_joint:
            raise SplatplanError(f"URDF {path}: link {j.child!r} has two parent joints")
        child_joint[j.child] = j
        kids[j.parent].append(j)
    roots = [n for n in links if n not in child_joint]
    if len(roots) != 1:
        raise SplatplanError(f"URDF {path}: expected one root link, found {len(roots)} ({', '.join(roots[:5])})")
    # Topological order (depth first, children in file order).
    order, stack = [], [roots[0]]
    while stack:
        n = stack.pop()
        order.append(n)
        stack.extend(j.child for j in reversed(kids[n]))
    if len(order) != len(links):  # pragma: no cover - cycles are rejected above
        raise SplatplanError(f"URDF {path}: the joints do not form a tree")
    index = {n: i for i, n in enumerate(order)}

    movable = [j for j in robot.joints if j.type in ("revolute", "continuous", "prismatic")]
    for j in robot.joints:
        if j.type not in ("revolute", "continuous", "prismatic", "fixed"):
            raise SplatplanError(f"URDF {path}: joint {j.name!r} has unsupported type {j.type!r} (revolute, continuous, prismatic, fixed)")
    dof_joints = [j.name for j in movable if j.mimic is None]
    dof_index = {n: i for i, n in enumerate(dof_joints)}
    jmap = {j.name: j for j in robot.joints}
    L = len(order)
    parent = np.full(L, -1, dtype=np.int64)
    jtype = np.zeros(L, dtype=np.int64)
    axis = np.tile(np.array([1.0, 0.0, 0.0]), (L, 1))
    origin = np.tile(np.eye(4), (L, 1, 1))
    qidx = np.full(L, -1, dtype=np.int64)
    mult, offset = np.ones(L), np.zeros(L)
    jnames = [""] * L
    for n, i in index.items():
        j = child_joint.get(n)
        if j is None:
            continue
        parent[i] = index[j.parent]
        jnames[i] = j.name
        origin[i] = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=np.float64)
        if j.type == "fixed":
            continue
        a = np.asarray(j.axis if j.axis is not None else [1.0, 0.0, 0.0], dtype=np.float64)
        if not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-12:
            raise SplatplanError(f"URDF {path}: joint {j.name!r} has a zero or invalid axis")
        axis[i] = a / np.linalg.norm(a)
        jtype[i] = PRISMATIC if j.type == "prismatic" else REVOLUTE
        if j.mimic is not None:
            src = jmap.get(j.mimic.joint)
            if src is None or src.name not in dof_index:
                raise SplatplanError(f"URDF {path}: joint {j.name!r} mimics {j.mimic.joint!r}, which is not a movable joint")
            qidx[i] = dof_index[src.name]
            mult[i] = 1.0 if j.mimic.multiplier is None else float(j.mimic.multiplier)
            offset[i] = 0.0 if j.mimic.offset is None else float(j.mimic.offset)
        else:
            qidx[i] = dof_index[j.name]
    n = len(dof_joints)
    lower, upper, vel = np.full(n, -np.inf), np.full(n, np.inf), np.full(n, np.inf)
    cont = np.zeros(n, dtype=bool)
    for k, name in enumerate(dof_joints):
        j = jmap[name]
        cont[k] = j.type == "continuous"
        if j.limit is not None:
            if not cont[k] and j.limit.lower is not None and j.limit.upper is not None:
                lower[k], upper[k] = float(j.limit.lower), float(j.limit.upper)
            if j.limit.velocity is not None and float(j.limit.velocity) > 0:
                vel[k] = float(j.limit.velocity)
        if lower[k] > upper[k]:
            raise SplatplanError(f"URDF {path}: joint {name!r} has lower limit {lower[k]} > upper limit {upper[k]}")
    _check_numbers(path, robot, root, jnames, origin, mult, offset)
    kin = Kinematics(order, jnames, parent, jtype, axis, origin, qidx, mult, offset)
    coll = {n: _geoms(links[n], "collision", path.parent, caps) for n in order}
    vis = {n: _geoms(links[n], "visual", path.parent, caps) for n in order}
    for kind, geoms in (("collision", coll), ("visual", vis)):
        for n, gs in geoms.items():
            for g in gs:
                _check_geom(path, n, kind, g)
    return UrdfModel(robot.name or path.stem, path, kin, dof_joints, lower, upper, vel, cont, coll, vis)


#: the largest distance (m) a URDF places anything at, and the largest mesh file it may name
MAX_URDF_COORD = 1e6
MAX_MESH_BYTES = 512 * 1024**2


#: numeric URDF attributes and their declared range (metres, radians, scale factors, limits)
_NUMERIC_ATTRS = ("xyz", "rpy", "size", "radius", "length", "scale", "lower", "upper", "velocity", "effort", "multiplier", "offset")


def _check_attributes(path: Path, root) -> None:
    """Every numeric attribute of the URDF (``xyz``, ``rpy``, ``size``, ``radius``, ``scale``,
    limits, ...) holds finite numbers within +-:data:`MAX_URDF_COORD`; else one line naming the
    element (its tag and the name of the link or joint it belongs to) and the attribute."""
    def owner(el_path: list) -> str:
        named = [e for e in el_path if e.get("name") is not None and e.tag in ("link", "joint")]
        return f"{named[-1].tag} {named[-1].get('name')!r} " if named else ""

    stack = [(root, [root])]
    while stack:
        el, chain = stack.pop()
        for attr in _NUMERIC_ATTRS:
            text = el.get(attr)
            if text is None or el.tag == "axis" and attr != "xyz":
                continue
            try:
                vals = [float(x) for x in text.split()]
            except ValueError:
                raise SplatplanError(f"URDF {path}: {owner(chain)}<{el.tag} {attr}=\"{text}\">: expected numbers") from None
            if not all(math.isfinite(v) and abs(v) <= MAX_URDF_COORD for v in vals):
                raise SplatplanError(f"URDF {path}: {owner(chain)}<{el.tag} {attr}=\"{text}\">: expected finite numbers within +-{MAX_URDF_COORD:g}")
        stack.extend((c, chain + [c]) for c in el)


def _check_numbers(path: Path, robot, root, jnames, origin, mult, offset) -> None:
    """The URDF's own declared ranges, each refusal naming the element: unique link and joint
    names, finite joint origins within :data:`MAX_URDF_COORD`, finite limits and mimic factors."""
    for tag in ("link", "joint"):
        seen: set[str] = set()
        for el in root.findall(tag):
            name = el.get("name")
            if name in seen:
                raise SplatplanError(f"URDF {path}: two <{tag}> elements are named {name!r}")
            seen.add(name)
    for i, name in enumerate(jnames):
        if name and not (np.all(np.isfinite(origin[i])) and np.all(np.abs(origin[i][:3, 3]) <= MAX_URDF_COORD)):
            raise SplatplanError(f"URDF {path}: joint {name!r} has a NaN, infinite or absurd <origin> (positions within +-{MAX_URDF_COORD:g} m)")
        if name and not (np.isfinite(mult[i]) and np.isfinite(offset[i]) and abs(mult[i]) <= 1e6 and abs(offset[i]) <= 1e6):
            raise SplatplanError(f"URDF {path}: joint {name!r} has a NaN or absurd <mimic> multiplier or offset")
    for j in robot.joints:
        lim = j.limit
        if lim is None:
            continue
        for what in ("lower", "upper", "velocity", "effort"):
            v = getattr(lim, what, None)
            if v is not None and not (math.isfinite(float(v)) and abs(float(v)) <= 1e9):
                raise SplatplanError(f"URDF {path}: joint {j.name!r} has <limit {what}=\"{v}\">; expected a finite number")


def _check_geom(path: Path, link: str, kind: str, g: "Geom") -> None:
    """One geometry of a link: finite origin and sizes, a mesh scale with no zero or NaN factor, a
    mesh file that is a regular file of at most :data:`MAX_MESH_BYTES` (a device or a FIFO would be
    read without end when it is hashed for the fit cache)."""
    where = f"URDF {path}: link {link!r} {kind} {g.kind}"
    if not (np.all(np.isfinite(g.origin)) and np.all(np.abs(g.origin[:3, 3]) <= MAX_URDF_COORD)):
        raise SplatplanError(f"{where} has a NaN, infinite or absurd <origin>")
    size = np.asarray(g.size, dtype=np.float64)
    if not (np.all(np.isfinite(size)) and np.all(np.abs(size) <= MAX_URDF_COORD)):
        raise SplatplanError(f"{where} has a NaN, infinite or absurd size {size.tolist()}")
    if g.kind == "mesh":
        if np.any(size == 0):
            raise SplatplanError(f"{where} {g.ref!r} has scale {size.tolist()}: a zero factor flattens the mesh")
        if g.mesh is not None:
            from .._files import file_kind

            try:
                st = os.stat(g.mesh)
            except OSError:
                return  # missing: said where the mesh is loaded
            if not stat.S_ISREG(st.st_mode):
                raise SplatplanError(f"{where} {g.ref!r} is {file_kind(st.st_mode)}, not a regular mesh file")
            if st.st_size > MAX_MESH_BYTES:
                raise SplatplanError(f"{where} {g.ref!r} is {st.st_size:,} bytes, over the {MAX_MESH_BYTES:,}-byte limit of a mesh")


@dataclass
class Srdf:
    """The parts of an SRDF this package uses."""

    disabled_pairs: set[frozenset[str | None]]  # (None: a link attribute missing from the file)
    group_states: dict[str | None, dict[str | None, list[float]]]  # state name -> joint -> values


def read_srdf(path: str | Path) -> Srdf:
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise SplatplanError(f"SRDF {path} does not parse ({exc})") from None
    pairs = {frozenset((d.get("link1"), d.get("link2"))) for d in root.iter("disable_collisions")}
    states: dict[str | None, dict[str | None, list[float]]] = {}
    for s in root.iter("group_state"):
        states[s.get("name")] = {j.get("name"): [float(v) for v in j.get("value", "").split()] for j in s.iter("joint")}
    return Srdf(pairs, states)
