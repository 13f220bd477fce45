"""way_oracle: the oracle graphs' answer to "which way is likeliest to lead to the object", from the sim's ground truth.

Topics
  subscribes  /explore/way_query   std_msgs/String, latched: the object the commander asks about ('' = no question)
              /sim/ground_truth    tf2_msgs/TFMessage: world -> gt/go2 (the robot) and gt/<target_body>
              /sim/detections      vision_msgs/Detection2DArray: one per head frame, used for its stamp only
  publishes   /vlm/way             std_msgs/String: JSON {"stamp", "object", "answer"} (perception/way.py)
                                   about one frame every period_s at most, while a question stands

Parameters
  target_body    ''     the world body the goal refers to (the episode runner sets it); '' = no answers
  half_view_deg  36.0   `likely` when the body's bearing is within this of the robot's heading, else
                        `unlikely`; the episode runner sets half the head camera's view at the episode's
                        image size (robot_profile: 36.5 at 640x480)
  period_s       0.5    at most one answer per this many seconds of frame stamps

The answer is perfect and at once (perception/way.py `oracle_way`: walls notwithstanding), so an eval with
--perception oracle measures the commander's `frontier_choice: vlm` at its upper bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from go2vlm.bus import Node, param
from go2vlm.bus.topics import EXPLORE_WAY_QUERY, SIM_DETECTIONS, SIM_GROUND_TRUTH, VLM_WAY
from go2vlm.geometry.rotations import quat_yaw
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.msgs.vision_msgs import Detection2DArray
from go2vlm.perception.way import oracle_way, way_message

__all__ = ["WayOracleConfig", "WayOracleNode"]


@dataclass
class WayOracleConfig:
    target_body: str = param("", help="the world body the goal refers to ('' = no answers)")
    half_view_deg: float = param(36.0, help="likely within this of the heading (deg)", min=1.0, max=180.0)
    period_s: float = param(0.5, help="at most one answer per this many seconds of frame stamps", min=0.0, max=10.0)


class WayOracleNode(Node):
    name = "way_oracle"
    Config = WayOracleConfig

    def __init__(self, config: WayOracleConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        self.query = ""
        self.robot: tuple[float, float, float] | None = None  # world x, y, yaw
        self.target: tuple[float, float] | None = None
        self._last = -math.inf
        self.pub = VLM_WAY.publisher(self)
        EXPLORE_WAY_QUERY.subscription(self, self.on_query)
        SIM_GROUND_TRUTH.subscription(self, self.on_truth)
        SIM_DETECTIONS.subscription(self, self.on_frame)

    def on_query(self, msg: String) -> None:
        self.query = msg.data.strip()

    def on_truth(self, msg: TFMessage) -> None:
        body = "gt/" + self.config.target_body
        for tf in msg.transforms:
            p, q = tf.transform.translation, tf.transform.rotation
            if tf.child_frame_id == "gt/go2":
                self.robot = (p.x, p.y, quat_yaw(q.w, q.x, q.y, q.z))
            elif tf.child_frame_id == body:
                self.target = (p.x, p.y)

    def on_frame(self, msg: Detection2DArray) -> None:
        cfg: WayOracleConfig = self.config
        stamp = msg.header.stamp.to_sec()
        if not self.query or self.robot is None or self.target is None or stamp - self._last < cfg.period_s:
            return
        self._last = stamp
        word = oracle_way(*self.robot, *self.target, math.radians(cfg.half_view_deg))
        self.pub.publish(String(data=way_message(stamp, self.query, word)))
        self.count(f"answered_{word}")
