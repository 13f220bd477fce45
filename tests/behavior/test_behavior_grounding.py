"""The colour-shape grounder, the tracker and the range estimate, on drawn images and on frames
rendered by the MuJoCo sim."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from go2vlm.behavior.approach import ApproachParams, RangeEstimator, approach_command
from go2vlm.geometry.camera import PinholeCamera
from go2vlm.geometry.target import normalized_target
from go2vlm.perception.grounding import ground
from go2vlm.perception.tracker import HistTracker

BGR = {"red": (0, 0, 255), "green": (0, 200, 0), "blue": (255, 0, 0), "yellow": (0, 230, 255)}


def scene() -> np.ndarray:
    img = np.full((480, 640, 3), 40, np.uint8)
    cv2.circle(img, (450, 150), 70, BGR["red"], -1)  # red ball
    cv2.rectangle(img, (80, 220), (240, 380), BGR["green"], -1)  # green box
    cv2.rectangle(img, (300, 230), (360, 440), BGR["blue"], -1)  # blue cylinder (tall)
    cv2.rectangle(img, (500, 330), (600, 430), BGR["red"], -1)  # red box
    return img


@pytest.mark.parametrize(
    ("color", "shape", "center"),
    [
        ("red", "ball", (450, 150)),
        ("red", "box", (550, 380)),
        ("green", "box", (160, 300)),
        ("blue", "cylinder", (330, 335)),
        (None, "cylinder", (330, 335)),
    ],
)
def test_grounds_colour_and_shape(color: str | None, shape: str, center: tuple[int, int]) -> None:
    cands = ground(scene(), color, shape)
    assert cands, f"no {color} {shape}"
    x1, y1, x2, y2 = cands[0].xyxy
    assert abs((x1 + x2) / 2 - center[0]) < 6 and abs((y1 + y2) / 2 - center[1]) < 6
    assert cands[0].shape == shape


def test_wrong_shape_or_colour_finds_nothing() -> None:
    assert ground(scene(), "green", "ball") == []
    assert ground(scene(), "blue", "box") == []
    assert ground(scene(), "yellow", None) == []


def test_a_ball_cut_by_the_image_border_is_still_a_ball() -> None:
    img = np.full((480, 640, 3), 40, np.uint8)
    cv2.circle(img, (10, 200), 90, BGR["red"], -1)
    cands = ground(img, "red", "ball")
    assert cands and cands[0].shapes.clipped


def test_bad_arguments_are_clear_errors() -> None:
    with pytest.raises(ValueError, match="colour"):
        ground(scene(), "purple", None)
    with pytest.raises(ValueError, match="shape"):
        ground(scene(), "red", "pyramid")


def test_tracker_follows_a_moving_and_growing_blob_and_reports_loss() -> None:
    tracker = HistTracker()
    img = np.full((480, 640, 3), 40, np.uint8)
    cv2.circle(img, (100, 240), 30, BGR["blue"], -1)
    assert tracker.init(img, (70, 210, 60, 60))
    for i in range(1, 30):
        img = np.full((480, 640, 3), 40, np.uint8)
        cx, r = 100 + 12 * i, 30 + i
        cv2.circle(img, (cx, 240), r, BGR["blue"], -1)
        track = tracker.update(img)
        assert track is not None, f"lost at frame {i}"
        x1, y1, x2, y2 = track.xyxy
        assert abs((x1 + x2) / 2 - cx) < 4 and abs((x2 - x1) - 2 * r) < 6
    assert tracker.update(np.full((480, 640, 3), 40, np.uint8)) is None
    assert not tracker.active
    assert not tracker.init(np.full((480, 640, 3), 40, np.uint8), (0, 0, 50, 50))  # nothing coloured to track


def test_normalised_target_matches_the_colour_detector_convention() -> None:
    x, y, z = normalized_target((320 - 50, 240 - 50, 320 + 50, 240 + 50), 640, 480)
    assert (x, y) == (0.0, 0.0) and z == pytest.approx(50 / 320)
    x, _, _ = normalized_target((600, 0, 640, 40), 640, 480)
    assert x == pytest.approx((620 - 320) / 320)


def test_approach_command_turns_first_then_walks_and_stops_at_the_distance() -> None:
    p = ApproachParams(stop_distance=0.8, max_linear=0.4, max_angular=0.8)
    vx, wz, done = approach_command(0.8, 3.0, p)
    assert vx == 0.0 and wz < 0 and not done  # target on the right: turn right, do not walk yet
    vx, wz, done = approach_command(0.0, 3.0, p)
    assert vx == pytest.approx(0.4) and wz == 0.0 and not done
    assert approach_command(0.0, 0.84, p) == (0.0, 0.0, True)
    vx, _, _ = approach_command(0.0, None, p)
    assert vx == 0.0  # unknown distance: never walk blind


@pytest.fixture(scope="module")
def sim():
    pytest.importorskip("mujoco")
    from go2vlm.sim import Go2Sim, SimConfig

    s = Go2Sim(SimConfig(world="vision_test", mode="kinematic", camera_width=640, camera_height=480))
    yield s
    s.close()


def _view(sim, x: float, y: float, yaw: float) -> np.ndarray:
    import mujoco

    sim.data.qpos[0], sim.data.qpos[1] = x, y
    sim._kin_yaw = yaw  # pose the kinematic robot directly (test only)
    sim.step(1)
    mujoco.mj_camlight(sim.model, sim.data)
    return np.ascontiguousarray(sim.render_head()[:, :, ::-1])


@pytest.mark.parametrize(
    ("color", "shape", "center", "radius", "yaw"),
    [("blue", "cylinder", (-2.0, 0.0), 0.3, math.pi), ("red", "ball", (2.0, 0.0), 0.5, 0.0)],
)
def test_range_from_sim_frames(sim, color: str, shape: str, center: tuple[float, float], radius: float, yaw: float):
    """Camera -> surface distance within 10 cm from 3.5 m down to 0.4 m (size calibrated on the way in)."""
    hfov = 2 * math.atan(math.tan(math.radians(58.0) / 2) * 640 / 480)
    cam = PinholeCamera.from_hfov(640, 480, hfov)
    est = RangeEstimator(shape, default_sizes={"ball": 1.0, "box": 1.0, "cylinder": 1.0})  # wrong on purpose
    forward = 0.327  # head camera ahead of the base
    for d in (3.8, 3.0, 2.2, 1.6, 1.2, 0.9, 0.75):  # base -> surface
        img = _view(sim, center[0] - math.cos(yaw) * (d + radius), center[1] - math.sin(yaw) * (d + radius), yaw + 0.1)
        cands = ground(img, color, None)
        assert cands
        reading = est.estimate(cands[0].xyxy, cam)
        assert reading.distance is not None
        assert reading.distance == pytest.approx(d - forward, abs=0.1), (d, reading)
    assert est.calibrated and est.size == pytest.approx(radius, abs=0.03)
