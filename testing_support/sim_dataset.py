"""Head-camera frames of our MuJoCo worlds with ground-truth boxes, for grounding models and tests.

What a grounder learns is a :class:`GroundingSpec`: its labels, the world bodies each label names,
the worlds it sees and where the robot may stand in them. Two are defined (:data:`SPECS`):

- ``primitives`` (:data:`PRIMITIVES`, the default): the coloured primitives of vision_test,
  follow_ball and obstacles. ``red_sphere`` and ``red_ball`` are both "red ball"; ``green_box``
  "green box"; ``blue_cylinder`` "blue cylinder" (tests/data/tiny_grounder).
- ``household`` (:data:`HOUSEHOLD`): the household world's objects by category ("teddy bear",
  "mug": both mugs, "box": all four boxes, ...) and the referring suite's phrases, each labelling its
  referent's box alone ("second box from the left" is box_3, "ball under the table" the red ball):
  what a box-per-phrase dataset can say of a relation (tests/data/tiny_grounder_household). Its
  lighting is drawn per frame as the sim draws it per episode (the world's ``light_jitter``).

A :class:`FrameRenderer` poses the kinematic Go2 anywhere in a world (position, yaw, a little
pitch/roll as when walking), renders the head camera exactly as the sim node does (640x480,
``SimConfig.camera_fovy_deg``) and derives boxes from ``render_head_segmentation``: the pixels of
each named body's geoms, so partly occluded or border-cut objects get the box of what is seen.

:func:`sample_frames` draws seeded poses that put an object in view most of the time (near, so
boxes are large and cut by the border; far, so they are small), plus free poses that often see
nothing. Boxes whose visible part is under :data:`MIN_BOX_SIDE_PX` on
a side are *ambiguous*: neither target nor negative (a model may or may not report them).

Also here, so training, evaluation and tests agree: the answer text a grounding model should
give (Qwen2.5-VL's JSON in resized-image pixels), the two ways a frame reaches the model (the
transformers processor's resize; the openai backend's resize + JPEG) and box IoU.
"""

from __future__ import annotations

import copy
import io
import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "ALL_LABELS",
    "CAMERA_HW",
    "HOUSEHOLD",
    "LABEL_BODIES",
    "MIN_BOX_SIDE_PX",
    "PRIMITIVES",
    "SPECS",
    "WORLDS",
    "Frame",
    "FrameRenderer",
    "GroundingSpec",
    "answer_text",
    "box_iou",
    "match_boxes",
    "openai_view",
    "processor_view",
    "sample_frames",
    "to_resized",
]

CAMERA_HW = (480, 640)  # the sim node's default head camera
# Under this (camera pixels) a visible part is a few resized pixels: too small to demand a box for.
MIN_BOX_SIDE_PX = 12

Area = tuple[float, float, float, float]  # x_min, x_max, y_min, y_max


@dataclass(frozen=True)
class GroundingSpec:
    """What a grounder is trained on: labels and the bodies each names, worlds, where the robot stands."""

    name: str
    labels: tuple[str, ...]
    label_bodies: Mapping[str, tuple[str, ...]]  # label -> the bodies it names (each its own box)
    worlds: tuple[str, ...]
    world_weights: tuple[float, ...]  # how often each world is drawn
    areas: Mapping[str, tuple[Area, ...]]  # per world, the rooms the robot may stand in (one or more)
    # primitives: some prompts (and the held-out evaluation) ask for every label at once; with dozens
    # of labels a prompt asks for one, or a few
    all_labels_prompts: bool = False
    vocab_size: int = 640  # the tokenizer's, trained on the spec's prompts and answers

    def bodies(self) -> tuple[str, ...]:
        return tuple(sorted({b for bodies in self.label_bodies.values() for b in bodies}))


PRIMITIVES = GroundingSpec(
    name="primitives",
    labels=("red ball", "green box", "blue cylinder"),
    label_bodies={
        "red ball": ("red_sphere", "red_ball"),
        "green box": ("green_box",),
        "blue cylinder": ("blue_cylinder",),
    },
    worlds=("vision_test", "follow_ball", "obstacles"),
    world_weights=(0.35, 0.25, 0.40),
    # inside the obstacles walls, around the objects elsewhere
    areas={
        "vision_test": ((-6.0, 6.0, -6.0, 6.0),),
        "follow_ball": ((-3.5, 6.5, -3.0, 7.0),),
        "obstacles": ((-4.6, 4.6, -4.6, 4.6),),
    },
    all_labels_prompts=True,
)

# The household world's objects by category, as people name them (sim/worlds/household.xml) ...
_HOUSEHOLD_CATEGORIES: dict[str, tuple[str, ...]] = {
    "teddy bear": ("teddy_bear",),
    "duck": ("duck",),
    "soccer ball": ("soccer_ball",),
    "red ball": ("red_ball",),
    "mug": ("red_mug", "blue_mug"),
    "red mug": ("red_mug",),
    "lego brick": ("red_lego_brick", "yellow_lego_brick"),
    "red lego brick": ("red_lego_brick",),
    "yellow lego brick": ("yellow_lego_brick",),
    "box": ("box_1", "box_2", "box_3", "box_4"),
    "toy chest": ("toy_chest",),
    "cone": ("cone",),
    "tray": ("tray",),
    "sofa": ("sofa",),
    "dining table": ("dining_table",),
    "coffee table": ("coffee_table",),
    "shelf": ("shelf",),
    "counter": ("counter",),
    "door": ("door",),
}
# ... and the referring suite's phrases (apps/episodes/suites/referring.yaml), each naming its referent
# alone, as the suite's `target` does. Left and right are the viewer's facing the row of boxes from the
# room (they stand against the south wall); nearest and farthest are from the doorway.
_HOUSEHOLD_PHRASES: dict[str, tuple[str, ...]] = {
    "ball under the table": ("red_ball",),
    "red object nearest the door": ("red_lego_brick",),
    "red object farthest from the door": ("red_mug",),
    "second box from the left": ("box_3",),
    "second box from the right": ("box_2",),
    "yellow object in the kitchen": ("yellow_lego_brick",),
    "blue mug": ("blue_mug",),
    "mug next to the dining table": ("blue_mug",),
    "toy next to the sofa": ("teddy_bear",),
    "ball nearest the door": ("soccer_ball",),
    "red object in the living room": ("red_ball",),
}
HOUSEHOLD = GroundingSpec(
    name="household",
    labels=(*_HOUSEHOLD_CATEGORIES, *_HOUSEHOLD_PHRASES),
    label_bodies={**_HOUSEHOLD_CATEGORIES, **_HOUSEHOLD_PHRASES},
    worlds=("household",),
    world_weights=(1.0,),
    areas={"household": ((-5.75, -0.3, -3.2, 3.2), (0.3, 5.75, -3.2, 3.2))},  # the living room, the kitchen
    vocab_size=960,
)
SPECS: dict[str, GroundingSpec] = {spec.name: spec for spec in (PRIMITIVES, HOUSEHOLD)}

# The primitives' names, as before the specs (tests and the shipped tiny_grounder use them).
ALL_LABELS: tuple[str, ...] = PRIMITIVES.labels
LABEL_BODIES: Mapping[str, tuple[str, ...]] = PRIMITIVES.label_bodies
WORLDS: tuple[str, ...] = PRIMITIVES.worlds

Box4 = tuple[float, float, float, float]


@dataclass
class Frame:
    """One head-camera frame and its ground truth (boxes in camera pixels, x2/y2 exclusive)."""

    world: str
    pose: tuple[float, float, float]  # robot base x, y, yaw
    rgb: np.ndarray  # (480, 640, 3) uint8
    boxes: dict[str, list[Box4]] = field(default_factory=dict)  # label -> boxes the model must find
    ambiguous: set[str] = field(default_factory=set)  # labels seen only as tiny specks
    camera_hw: tuple[int, int] = CAMERA_HW  # the boxes' image size (rgb may be dropped to save memory)

    def visible(self, label: str) -> bool:
        return bool(self.boxes.get(label))

    def negative(self, label: str) -> bool:
        """True when the label is neither visible nor a speck: any box of it is a false positive."""
        return not self.boxes.get(label) and label not in self.ambiguous


def box_iou(a: Sequence[float], b: Sequence[float]) -> float:
    ix = max(0.0, min(a[2], b[2]) - max(a[0], b[0]))
    iy = max(0.0, min(a[3], b[3]) - max(a[1], b[1]))
    inter = ix * iy
    union = (a[2] - a[0]) * (a[3] - a[1]) + (b[2] - b[0]) * (b[3] - b[1]) - inter
    return inter / union if union > 0 else 0.0


def match_boxes(truth: Sequence[Sequence[float]], pred: Sequence[Sequence[float]]) -> list[float]:
    """Greedy one-to-one matching by IoU: the IoU each true box got (0.0 when unmatched)."""
    pairs = sorted(
        ((box_iou(t, p), i, j) for i, t in enumerate(truth) for j, p in enumerate(pred)),
        reverse=True,
    )
    got = [0.0] * len(truth)
    used_t: set[int] = set()
    used_p: set[int] = set()
    for iou, i, j in pairs:
        if iou <= 0.0 or i in used_t or j in used_p:
            continue
        got[i] = iou
        used_t.add(i)
        used_p.add(j)
    return got


def to_resized(box: Sequence[float], camera_hw: tuple[int, int], resized_hw: tuple[int, int]) -> list[int]:
    """Camera-pixel box -> integer pixels of the resized image the model sees (Qwen2.5-VL's convention)."""
    sy, sx = resized_hw[0] / camera_hw[0], resized_hw[1] / camera_hw[1]
    x1, y1, x2, y2 = box
    out = [round(x1 * sx), round(y1 * sy), round(x2 * sx), round(y2 * sy)]
    out[2] = max(out[2], out[0] + 1)  # keep a speck a box after rounding
    out[3] = max(out[3], out[1] + 1)
    return [min(max(v, 0), lim) for v, lim in zip(out, (resized_hw[1], resized_hw[0]) * 2, strict=True)]


def answer_text(frame: Frame, labels: Sequence[str], resized_hw: tuple[int, int]) -> str:
    """The grounding answer for a prompt asking for ``labels``: Qwen2.5-VL's JSON, ``[]`` if none is seen.

    Boxes in the order the labels were asked, left to right within a label."""
    items = []
    for label in labels:
        for box in sorted(frame.boxes.get(label, []), key=lambda b: (b[0], b[1])):
            items.append({"bbox_2d": to_resized(box, frame.camera_hw, resized_hw), "label": label})
    return json.dumps(items, ensure_ascii=False)


def processor_view(rgb: np.ndarray, resized_hw: tuple[int, int]) -> np.ndarray:
    """The frame as the transformers backend's processor resizes it (torchvision bicubic, antialiased)."""
    import torch
    from torchvision.transforms.v2 import InterpolationMode
    from torchvision.transforms.v2 import functional as tvf

    chw = torch.from_numpy(np.ascontiguousarray(rgb)).permute(2, 0, 1)
    out = tvf.resize(chw, list(resized_hw), interpolation=InterpolationMode.BICUBIC, antialias=True)
    return out.permute(1, 2, 0).contiguous().numpy()


def openai_view(rgb: np.ndarray, resized_hw: tuple[int, int], quality: int = 90) -> np.ndarray:
    """The frame as the openai backend sends it (PIL bicubic resize, JPEG), decoded again."""
    import base64

    from PIL import Image

    from go2vlm.perception.vlm.openai_backend import encode_jpeg_data_url

    url = encode_jpeg_data_url(rgb, resized_hw, quality)
    data = base64.b64decode(url.split(",", 1)[1])
    return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))


class FrameRenderer:
    """One kinematic ``Go2Sim`` per world of ``spec``, posed by hand for each frame. Not thread-safe."""

    def __init__(
        self,
        worlds: Sequence[str] | None = None,
        camera_hw: tuple[int, int] = CAMERA_HW,
        spec: GroundingSpec = PRIMITIVES,
    ) -> None:
        import go2vlm.sim  # noqa: F401 - selects the headless GL backend before mujoco loads
        from go2vlm.sim import Go2Sim, SimConfig

        self.spec = spec
        self.camera_hw = camera_hw
        self.sims: dict[str, Any] = {}
        self._target_geoms: dict[str, dict[str, list[np.ndarray]]] = {}
        self._obstacles: dict[str, list[int]] = {}
        self._lights: dict[str, tuple[ET.Element, float]] = {}
        for world in spec.worlds if worlds is None else worlds:
            sim = Go2Sim(
                SimConfig(world=world, mode="kinematic", camera_width=camera_hw[1], camera_height=camera_hw[0])
            )
            self.sims[world] = sim
            m = sim.model
            robot = set(sim.robot_geom_ids().tolist())
            names = _body_names(m)
            # each target body's geoms: one box per body (two red balls in obstacles are two boxes)
            self._target_geoms[world] = {
                label: [np.flatnonzero(m.geom_bodyid == m.body(b).id) for b in bodies if b in names]
                for label, bodies in spec.label_bodies.items()
            }
            self._obstacles[world] = [g for g in range(m.ngeom) if g not in robot and m.geom_bodyid[g] != 0]
            lights = _jitter_template(world)
            if lights is not None:
                self._lights[world] = lights
        self.stand_z = {w: float(s.data.qpos[2]) for w, s in self.sims.items()}

    def jitters_light(self, world: str) -> bool:
        return world in self._lights

    def light(self, world: str, seed: int) -> None:
        """Light ``world`` as the sim does for an episode of this seed (worlds with ``light_jitter`` only)."""
        if world not in self._lights:
            return
        from go2vlm.sim.worlds import _jitter_lights

        template, amount = self._lights[world]
        root = copy.deepcopy(template)
        _jitter_lights(root, amount, seed)
        m = self.sims[world].model
        for light in root.iter("light"):
            m.light_diffuse[m.light(light.get("name")).id] = [float(v) for v in light.get("diffuse", "").split()]
        head = root.find("visual/headlight")
        if head is not None:
            m.vis.headlight.ambient = [float(v) for v in head.get("ambient", "").split()]
            m.vis.headlight.diffuse = [float(v) for v in head.get("diffuse", "").split()]

    def close(self) -> None:
        for sim in self.sims.values():
            sim.close()

    def __enter__(self) -> FrameRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def object_positions(self, world: str) -> dict[str, np.ndarray]:
        """World positions of the spec's bodies present in ``world``."""
        poses = self.sims[world].object_poses()
        return {b: poses[b].position for b in self.spec.bodies() if b in poses}

    def place_ball(self, world: str, xy: tuple[float, float]) -> None:
        """Move the mocap red ball (follow_ball, obstacles) to ``xy`` on the floor."""
        import mujoco

        sim = self.sims[world]
        if sim.ball is None:
            return
        mocap = int(sim.model.body("red_ball").mocapid[0])
        sim.data.mocap_pos[mocap] = (xy[0], xy[1], sim.ball.z)
        mujoco.mj_kinematics(sim.model, sim.data)  # object_poses() reads the body pose

    def clearance(self, world: str, point: np.ndarray) -> float:
        """Distance from ``point`` to the nearest solid non-robot geom (boxes, spheres, cylinders)."""
        import mujoco

        sim = self.sims[world]
        m, d = sim.model, sim.data
        best = math.inf
        for g in self._obstacles[world]:
            rot = d.geom_xmat[g].reshape(3, 3)
            p = rot.T @ (point - d.geom_xpos[g])
            size = m.geom_size[g]
            kind = m.geom_type[g]
            if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
                dist = float(np.linalg.norm(p)) - size[0]
            elif kind == mujoco.mjtGeom.mjGEOM_CYLINDER:
                radial = max(0.0, float(np.hypot(p[0], p[1])) - size[0])
                axial = max(0.0, abs(float(p[2])) - size[1])
                dist = float(np.hypot(radial, axial))
            else:  # boxes, and a bounding box for anything else
                dist = float(np.linalg.norm(np.maximum(np.abs(p) - size[:3], 0.0)))
            best = min(best, dist)
        return best

    def pose(self, world: str, x: float, y: float, yaw: float, pitch: float = 0.0, roll: float = 0.0) -> None:
        """Put the standing robot at (x, y, yaw) with a small body pitch/roll; cameras follow."""
        import mujoco

        sim = self.sims[world]
        m, d = sim.model, sim.data
        d.qpos[0:3] = (x, y, self.stand_z[world])
        cr, sr = math.cos(roll / 2), math.sin(roll / 2)
        cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
        cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
        d.qpos[3:7] = (
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        )
        mujoco.mj_kinematics(m, d)
        mujoco.mj_camlight(m, d)

    def render(self, world: str) -> Frame:
        """Render the current pose: RGB and boxes from segmentation."""
        sim = self.sims[world]
        h, w = self.camera_hw
        rgb = sim.render_head(w, h)
        seg = sim.render_head_segmentation(w, h)
        frame = Frame(world=world, pose=(0.0, 0.0, 0.0), rgb=rgb, camera_hw=(h, w))
        for label in self.spec.labels:
            for geoms in self._target_geoms[world].get(label, []):
                mask = np.isin(seg, geoms)
                if not mask.any():
                    continue
                ys = np.flatnonzero(mask.any(axis=1))
                xs = np.flatnonzero(mask.any(axis=0))
                box = (float(xs[0]), float(ys[0]), float(xs[-1] + 1), float(ys[-1] + 1))
                if min(box[2] - box[0], box[3] - box[1]) < MIN_BOX_SIDE_PX:
                    frame.ambiguous.add(label)
                else:
                    frame.boxes.setdefault(label, []).append(box)
        return frame


def _body_names(model: Any) -> set[str]:
    return {model.body(b).name for b in range(model.nbody)}


def _jitter_template(world: str) -> tuple[ET.Element, float] | None:
    """The world file's own lights (and headlight) and its ``light_jitter``; None for a world without."""
    from go2vlm.sim.worlds import world_path

    root = ET.parse(world_path(world)).getroot()
    amount = next((float(el.get("data", "0")) for el in root.iter("numeric") if el.get("name") == "light_jitter"), 0.0)
    if amount <= 0:
        return None
    template = ET.Element("mujoco")
    visual = ET.SubElement(template, "visual")
    head = root.find("visual/headlight")
    if head is not None:
        visual.append(copy.deepcopy(head))
    for light in root.iter("light"):
        template.append(copy.deepcopy(light))
    return template, amount


def _hfov(camera_hw: tuple[int, int], fovy_deg: float) -> float:
    return 2.0 * math.atan(math.tan(math.radians(fovy_deg) / 2.0) * camera_hw[1] / camera_hw[0])


def _room(areas: Sequence[Area], x: float, y: float) -> Area | None:
    return next((a for a in areas if a[0] <= x <= a[1] and a[2] <= y <= a[3]), None)


def sample_frames(renderer: FrameRenderer, n: int, seed: int) -> Iterator[Frame]:
    """``n`` frames from seeded random poses over the renderer's worlds.

    70 %: aimed at a random body of the spec from 0.7-8 m (log-uniform), the object anywhere from
    the image centre to just outside the border, the robot in the object's room (where a world has
    rooms); 30 %: anywhere, any heading (often nothing in view). The mocap red ball is moved too (on
    its path or anywhere in the area). A small body pitch/roll stands in for the trot's rocking.
    Worlds with ``light_jitter`` get each frame's lighting drawn as an episode's.
    """
    spec = renderer.spec
    rng = np.random.default_rng(seed)
    worlds = list(renderer.sims)
    weights = np.array([spec.world_weights[spec.worlds.index(w)] if w in spec.worlds else 1.0 for w in worlds])
    weights /= weights.sum()
    made = 0
    while made < n:
        world = worlds[int(rng.choice(len(worlds), p=weights))]
        sim = renderer.sims[world]
        hfov = _hfov(renderer.camera_hw, sim.config.camera_fovy_deg)
        areas = spec.areas.get(world, ((-5.0, 5.0, -5.0, 5.0),))
        # a world of several rooms: one by its floor area (no draw for one room: the primitives' stream)
        if len(areas) == 1:
            x0, x1, y0, y1 = areas[0]
        else:
            sizes = np.array([(a[1] - a[0]) * (a[3] - a[2]) for a in areas])
            x0, x1, y0, y1 = areas[int(rng.choice(len(areas), p=sizes / sizes.sum()))]
        if sim.ball is not None:
            # on its path half the time (where the follow demo sees it), else anywhere in the area
            on_path = sim.ball.at(rng.uniform(0.0, sim.ball.length))
            anywhere = (rng.uniform(x0, x1), rng.uniform(y0, y1))
            ball = (float(on_path[0]), float(on_path[1])) if rng.random() < 0.5 else anywhere
            renderer.place_ball(world, ball)
        targets = renderer.object_positions(world)
        if rng.random() < 0.7 and targets:
            body = sorted(targets)[int(rng.integers(len(targets)))]
            obj = targets[body]
            dist = math.exp(rng.uniform(math.log(0.7), math.log(8.0)))
            approach = rng.uniform(0, 2 * math.pi)
            x = float(obj[0] - dist * math.cos(approach))
            y = float(obj[1] - dist * math.sin(approach))
            yaw = approach + rng.uniform(-0.65, 0.65) * hfov
            if len(areas) > 1:  # stand in the object's room (else: any room)
                x0, x1, y0, y1 = _room(areas, float(obj[0]), float(obj[1])) or _room(areas, x, y) or (x0, x1, y0, y1)
        else:
            x, y, yaw = float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)), rng.uniform(-math.pi, math.pi)
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            continue
        pitch, roll = float(rng.normal(0.0, 0.035)), float(rng.normal(0.0, 0.025))
        renderer.pose(world, x, y, float(yaw), pitch, roll)
        base = np.array([x, y, renderer.stand_z[world]])
        nose = base + 0.33 * np.array([math.cos(yaw), math.sin(yaw), 0.0])
        tail = base - 0.3 * np.array([math.cos(yaw), math.sin(yaw), 0.0])
        if min(renderer.clearance(world, p) for p in (base, nose, tail)) < 0.15:
            continue  # the robot would stand inside an object
        if renderer.jitters_light(world):
            renderer.light(world, int(rng.integers(2**31)))
        frame = renderer.render(world)
        frame.pose = (x, y, float(yaw))
        made += 1
        yield frame
