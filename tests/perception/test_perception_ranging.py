"""The range estimate (perception/ranging.py) on frames rendered by the MuJoCo sim."""

from __future__ import annotations

import math

import numpy as np
import pytest

from go2vlm.geometry.camera import PinholeCamera
from go2vlm.perception.grounding import ground
from go2vlm.perception.ranging import RangeEstimator


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


@pytest.mark.parametrize("d", [1.0, 3.0, 5.0])
def test_the_bodys_pitch_is_the_cameras_too(d: float) -> None:
    """A Go2 stands 0.8 degrees nose down: the floor under an object d m away is that much nearer the
    image's centre than a level camera would put it. Given the pitch the range is right; taken as
    level, an object 5 m away read 1.2 m farther (the object memory's phantoms behind the sofa)."""
    cam = PinholeCamera.from_hfov(640, 480, math.radians(75.0))
    pitch = math.radians(0.8)
    h = 0.36
    bottom = cam.cy + cam.fy * math.tan(math.atan(h / d) - pitch)
    box = (300.0, bottom - 20.0, 340.0, bottom)
    level = RangeEstimator("box", camera_height=h).estimate(box, cam)
    pitched = RangeEstimator("box", camera_height=h).estimate(box, cam, pitch)
    assert pitched.method == "bottom" and pitched.distance == pytest.approx(d, rel=1e-6)
    assert level.distance is not None and level.distance > d * (1.0 + 0.03 * d)  # farther, the more so far off
