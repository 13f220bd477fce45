"""World files (``worlds/<name>.xml``) and insertion of the Go2 into them.

A world is a plain MJCF file.  Optional ``<custom>`` entries carry metadata:
``go2_spawn`` (x y yaw), ``rooms`` (text, "name x0 y0 x1 y1; ...": each room's floor inside its
walls, what suites and their tests call a room), ``spawn_<room>`` (x y yaw: a clear pose in that
room, `go2vlm demo --spawn ROOM`), ``ball_path_type`` (text, "ellipse" or
"figure8"), ``ball_path`` (cx cy rx ry start_angle), ``ball_radius`` and
``light_jitter`` (a fraction: every light's intensity and tint, and the headlight's,
vary by up to it, drawn from the sim's seed, so that each episode sees other lighting), ``doors``
(text, "room_a room_b x y width axis; ...": each doorway's centre, clear width and the axis its wall
runs along) and ``house`` (text, "seed N hash H": a generated house's).

A world name ``house:SEED`` (or ``house:SEED:rooms=N``) is a generated house (sim/houses): its file is
written to the cache folder and read like any other.
Angles in world files are radians (the loader forces ``<compiler angle="radian"/>``).
Mesh and texture folders (``<compiler meshdir texturedir assetdir>``) are relative to
the world file, as MuJoCo reads them from a file.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from go2vlm.geometry.footprint import Footprint
from go2vlm.sim import go2_model
from go2vlm.sim.houses import house_file, is_house
from go2vlm.sim.houses.plan import Door
from go2vlm.sim.render import labelled_bodies

WORLDS_DIR = Path(__file__).with_name("worlds")


@dataclass(frozen=True)
class Room:
    """A room's floor inside its walls: a rectangle of the world frame."""

    name: str
    x0: float
    y0: float
    x1: float
    y1: float

    def contains(self, x: float, y: float) -> bool:
        return self.x0 <= x <= self.x1 and self.y0 <= y <= self.y1


@dataclass(frozen=True)
class WorldInfo:
    name: str
    spawn: tuple[float, float, float]  # x, y, yaw
    ball_path_type: str | None
    ball_path: tuple[float, ...] | None
    ball_radius: float
    rooms: tuple[Room, ...] = ()
    room_spawns: tuple[tuple[str, tuple[float, float, float]], ...] = ()  # (room, (x, y, yaw))
    doors: tuple[Door, ...] = ()
    house: str = ""  # a generated house's "seed N hash H"

    def room_of(self, x: float, y: float) -> str | None:
        """The room this floor point is in (None: in none of them: a wall, a doorway, outside)."""
        return next((r.name for r in self.rooms if r.contains(x, y)), None)

    def room_spawn(self, room: str) -> tuple[float, float, float]:
        """The world's spawn pose in `room`; ValueError naming the rooms that have one."""
        spawns = dict(self.room_spawns)
        if room not in spawns:
            have = ", ".join(spawns) or "none"
            raise ValueError(f"world {self.name!r} has no spawn in a room {room!r} (rooms with one: {have})")
        return spawns[room]


def available_worlds() -> list[str]:
    return sorted(p.stem for p in WORLDS_DIR.glob("*.xml"))


def world_path(name: str) -> Path:
    """The file of a world: a packaged name, an .xml path, or a house (``house:SEED``, generated into the
    cache). ValueError (HouseError for a house) naming what is wrong."""
    if is_house(name):
        return house_file(name)[0]
    path = Path(name)
    if path.suffix == ".xml" and path.exists():
        return path
    path = WORLDS_DIR / f"{name}.xml"
    if not path.exists():
        raise ValueError(f"unknown world {name!r}; available: {available_worlds()}")
    return path


def _child(parent: ET.Element, tag: str) -> ET.Element:
    el = parent.find(tag)
    if el is None:
        el = ET.SubElement(parent, tag)
    return el


def _custom(root: ET.Element) -> dict[str, str]:
    out: dict[str, str] = {}
    for custom in root.findall("custom"):
        for el in custom:
            if "name" in el.attrib and "data" in el.attrib:
                out[el.attrib["name"]] = el.attrib["data"]
    return out


def _jitter_lights(root: ET.Element, amount: float, seed: int) -> None:
    """Scale each light's diffuse (and the headlight's ambient and diffuse) by 1 +- amount, with a
    small tint, drawn from `seed`: the same seed gives the same lighting."""
    rng = np.random.default_rng([seed, 7919])

    def vary(el: ET.Element, attr: str, default: str) -> None:
        rgb = np.array([float(v) for v in el.get(attr, default).split()])
        gain = 1.0 + rng.uniform(-amount, amount)
        tint = 1.0 + rng.uniform(-amount / 4, amount / 4, size=3)
        el.set(attr, " ".join(f"{v:.4f}" for v in np.clip(rgb * gain * tint, 0.0, 1.0)))

    for light in root.iter("light"):
        vary(light, "diffuse", "0.7 0.7 0.7")
    head = root.find("visual/headlight")
    if head is not None:
        vary(head, "ambient", "0.1 0.1 0.1")
        vary(head, "diffuse", "0.4 0.4 0.4")


def _rooms(meta: dict[str, str], file: Path) -> tuple[Room, ...]:
    out = []
    for part in filter(None, (p.strip() for p in meta.get("rooms", "").split(";"))):
        words = part.split()
        try:
            name, x0, y0, x1, y1 = words[0], *(float(v) for v in words[1:])
        except ValueError:
            raise ValueError(f"{file}: a room is 'name x0 y0 x1 y1', got {part!r}") from None
        if not (x0 < x1 and y0 < y1):
            raise ValueError(f"{file}: room {name!r} is empty ({x0} {y0} {x1} {y1})")
        out.append(Room(name, x0, y0, x1, y1))
    return tuple(out)


def _doors(meta: dict[str, str], file: Path) -> tuple[Door, ...]:
    out = []
    for part in filter(None, (p.strip() for p in meta.get("doors", "").split(";"))):
        words = part.split()
        try:
            a, b, x, y, w, axis = words[0], words[1], *(float(v) for v in words[2:5]), words[5]
        except (ValueError, IndexError):
            raise ValueError(f"{file}: a door is 'room_a room_b x y width x|y', got {part!r}") from None
        out.append(Door(a, b, x, y, w, axis == "x"))
    return tuple(out)


def _room_spawns(meta: dict[str, str]) -> tuple[tuple[str, tuple[float, float, float]], ...]:
    out = []
    for key, data in meta.items():
        if key.startswith("spawn_"):
            x, y, yaw = (float(v) for v in data.split())
            out.append((key.removeprefix("spawn_"), (x, y, yaw)))
    return tuple(out)


def world_info(name: str) -> WorldInfo:
    """A world's metadata (its spawn, rooms, room spawns, ball path) without building its model."""
    return build_world_xml(name)[1]


def build_world_xml(
    name: str,
    spawn: tuple[float, float, float] | None = None,
    offscreen: tuple[int, int] = (1920, 1080),
    seed: int | None = None,
) -> tuple[str, WorldInfo]:
    """Return the MJCF of world ``name`` with the Go2 inserted, and its metadata. `seed` draws the
    lighting of worlds with ``light_jitter`` (None: the file's own)."""
    file = world_path(name)
    root = ET.parse(file).getroot()
    meta = _custom(root)
    compiler = root.find("compiler")
    if compiler is not None:  # the XML is compiled from a string: make its asset folders absolute
        for attr in ("meshdir", "texturedir", "assetdir"):
            if attr in compiler.attrib and not Path(compiler.attrib[attr]).is_absolute():
                compiler.set(attr, str((file.parent / compiler.attrib[attr]).resolve()))
    if seed is not None and float(meta.get("light_jitter", "0")) > 0:
        _jitter_lights(root, float(meta["light_jitter"]), seed)
    if spawn is None:
        vals = [float(v) for v in meta.get("go2_spawn", "0 0 0").split()]
        spawn = (vals[0], vals[1], vals[2])
    path = tuple(float(v) for v in meta["ball_path"].split()) if "ball_path" in meta else None
    info = WorldInfo(
        name=name if is_house(name) else Path(name).stem,
        spawn=spawn,
        ball_path_type=meta.get("ball_path_type"),
        ball_path=path,
        ball_radius=float(meta.get("ball_radius", "0.2")),
        rooms=_rooms(meta, file),
        room_spawns=_room_spawns(meta),
        doors=_doors(meta, file),
        house=meta.get("house", ""),
    )

    # Everything here (robot ranges, world eulers) is in radians. Files a world names (textures)
    # are next to it: the MJCF is compiled from a string, which has no folder of its own.
    compiler = _child(root, "compiler")
    compiler.set("angle", "radian")
    compiler.attrib.setdefault("assetdir", str(world_path(name).parent.resolve()))
    option = _child(root, "option")
    option.attrib.setdefault("timestep", "0.002")
    option.attrib.setdefault("integrator", "implicitfast")
    visual = _child(root, "visual")
    # No MSAA: 6-10x faster software rendering, and the offscreen buffer must fit the cameras.
    _child(visual, "quality").set("offsamples", "0")
    glob = _child(visual, "global")
    glob.set("offwidth", str(max(offscreen[0], int(glob.get("offwidth", "0")))))
    glob.set("offheight", str(max(offscreen[1], int(glob.get("offheight", "0")))))
    for light in root.iter("light"):
        light.set("castshadow", "false")

    default = _child(root, "default")
    default.extend(ET.fromstring(f"<d>{go2_model.robot_defaults_xml()}</d>"))
    worldbody = _child(root, "worldbody")
    x, y, yaw = spawn
    body = go2_model.robot_body_xml((x, y, go2_model.STAND_HEIGHT), yaw)
    worldbody.append(ET.fromstring(body))
    _child(root, "actuator").extend(ET.fromstring(f"<a>{go2_model.robot_actuators_xml()}</a>"))
    _child(root, "sensor").extend(ET.fromstring(f"<s>{go2_model.robot_sensors_xml()}</s>"))
    return ET.tostring(root, encoding="unicode"), info


def gazebo_rpy_to_xyaxes(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """MuJoCo camera ``xyaxes`` for a Gazebo camera pose with this rpy (for world authors porting a
    Gazebo world, as vision_test.xml ports the article's).

    Gazebo (R = Rz(yaw) Ry(pitch) Rx(roll)) cameras look along +x with +z up;
    MuJoCo cameras look along -z with +y up, so x_mj = -y_gz and y_mj = z_gz.
    """
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    r = rz @ ry @ rx
    return np.concatenate([-r[:, 1], r[:, 2]])


def world_footprints(model: mujoco.MjModel) -> dict[str, Footprint]:
    """Floor footprints of the named world bodies at their initial poses (spheres, cylinders and
    capsules as circles, boxes as oriented rectangles, meshes as the convex hull of their vertices,
    which is what MuJoCo collides: a teddy bear's bounding box, a third larger, had the robot
    "collide" with air; the first geom of a body counts). A moving body (the mocap ball) takes its
    pose from ground truth at run time (`Footprint.moved`)."""
    circles = (mujoco.mjtGeom.mjGEOM_SPHERE, mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE)
    bodies = labelled_bodies(model)
    out: dict[str, Footprint] = {}
    for g in range(model.ngeom):
        b = int(model.geom_bodyid[g])
        name = bodies.get(b)
        if name is None or name in out:
            continue
        t, size = int(model.geom_type[g]), model.geom_size[g]
        pos, q = model.body_pos[b], model.body_quat[b]
        yaw = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
        if t in circles:
            out[name] = Footprint("circle", float(pos[0]), float(pos[1]), r=float(size[0]))
        elif t == mujoco.mjtGeom.mjGEOM_BOX:
            out[name] = Footprint("rect", float(pos[0]), float(pos[1]), yaw, hx=float(size[0]), hy=float(size[1]))
        elif t == mujoco.mjtGeom.mjGEOM_MESH:  # the hull of its vertices in the body frame, turned by the body's yaw
            from scipy.spatial import ConvexHull

            xy = _mesh_xy(model, g)
            lo, hi = xy.min(axis=0), xy.max(axis=0)
            (mx, my), (hx, hy) = (lo + hi) / 2, (hi - lo) / 2  # its bounding box: x, y its middle
            c, s = math.cos(yaw), math.sin(yaw)
            cx, cy = pos[0] + c * mx - s * my, pos[1] + s * mx + c * my
            pts = tuple((float(a - mx), float(b - my)) for a, b in xy[ConvexHull(xy).vertices])  # counter-clockwise
            out[name] = Footprint("hull", float(cx), float(cy), yaw, hx=float(hx), hy=float(hy), pts=pts)
    return out


def _mesh_xy(model: mujoco.MjModel, g: int) -> np.ndarray:
    """x, y of a mesh geom's vertices in its body's frame (MuJoCo re-centres meshes on their
    inertial frame, so the geom's pose is applied)."""
    mesh = int(model.geom_dataid[g])
    adr, n = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, model.geom_quat[g])
    pts = model.mesh_vert[adr : adr + n] @ rot.reshape(3, 3).T + model.geom_pos[g]
    return np.asarray(pts[:, :2], dtype=float)


def world_model(name: str, spawn: tuple[float, float, float] | None = None) -> tuple[mujoco.MjModel, WorldInfo]:
    """The compiled MuJoCo model of a world with the Go2 in it (for geometry; nothing is stepped)."""
    xml, info = build_world_xml(name, spawn)
    return mujoco.MjModel.from_xml_string(xml), info
