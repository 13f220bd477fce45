"""follower: turns towards the detected target and walks up to it (the follow article's
follower.py, section 5.3).

The follow article's standalone demo node: it runs in the article's graphs (follow_sim,
follow_test_pattern, follow_go2*: color_detector -> /detected_target -> follower), never in a goal
graph. A language goal "follow the red ball" is the commander's (behavior/commander_node.py), with
its own law and gains (behavior/control.py approach_command, kp_angular 1.5); this node's law and
gains (kp_angular 0.8, the article's) are for the article's demo only.

Topics
  subscribes  /detected_target     geometry_msgs/PointStamped: x = horizontal offset -1..1, z = size
  publishes   /follower/cmd_vel    geometry_msgs/Twist at rate_hz (20 Hz); the safety gate turns it
                                   into /cmd_vel

Control law, per target (behavior/control.py follow_command; the article's numbers are the defaults):
  angular.z = clamp(-kp_angular * x - kd_angular * dx/dt, +-max_angular)
  linear.x  = clamp(kp_linear * (1 - z), 0, max_linear) while |x| < align_threshold, else 0
              (forward only: it turns first, then walks)
The command drops to zero once no target has arrived for lost_timeout_s (1.0 s); that zero goes out
at once, not at the next 20 Hz tick. Zeros keep going out for idle_after_lost_s more, then the
follower falls silent until a target returns: a zero is a live command to the safety gate's mux, and
a follower that streams zeros forever would block lower-priority inputs (/behavior/cmd_vel from the
commander's search or approach). The gate's own watchdog keeps /cmd_vel at zero meanwhile.
Optional, off by default (the article's troubleshooting table, section 7, against oscillation): a D term on x
(kd_angular) and a first-order low-pass on the output (filter_alpha: weight of the new command per
tick, 1.0 = no filtering).
A target with NaN/inf or absurd values is dropped with a rate-limited error and counted in
`bad_targets`; it does not refresh the target, so the robot stops on the timeout as if none came.
Parameters at runtime (`go2vlm param set follower kp_angular 0.4`): all but rate_hz (read-only:
its timer starts with the node); a new gain applies from the next target.
Time: rate_hz, lost_timeout_s and idle_after_lost_s are in the node's clock: sim time with
use_sim_time (the lost watchdog then runs every 10 ms of sim time).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from go2vlm.behavior.control import follow_command
from go2vlm.bus import Node, param
from go2vlm.bus.topics import DETECTED_TARGET, FOLLOWER_CMD_VEL
from go2vlm.msgs.geometry_msgs import PointStamped, Twist, Vector3

__all__ = ["FollowerConfig", "FollowerNode"]

# Beyond these a "normalised" target is garbage, not a far-off-centre target.
MAX_ABS_XY = 2.0
MAX_SIZE = 10.0


@dataclass
class FollowerConfig:
    kp_angular: float = param(0.8, help="P gain from horizontal offset x to angular.z", min=0.0, max=20.0, live=True)
    kp_linear: float = param(0.3, help="P gain from (1 - size) to linear.x", min=0.0, max=20.0, live=True)
    max_linear: float = param(
        0.5, help="linear.x ceiling (m/s); the safety gate limits again", min=0.0, max=3.8, live=True, bound="max"
    )
    max_angular: float = param(1.0, help="|angular.z| ceiling (rad/s)", min=0.0, max=4.0, live=True, bound="max")
    align_threshold: float = param(0.2, help="walk only while |x| is below this", min=0.0, max=1.0, live=True)
    lost_timeout_s: float = param(1.0, help="stop when no target came for this long", min=0.01, max=60.0, live=True)
    rate_hz: float = param(20.0, help="command publishing rate", min=1.0, max=200.0)
    kd_angular: float = param(0.0, help="D gain on dx/dt (s); 0 = off", min=0.0, max=10.0, live=True)
    filter_alpha: float = param(
        1.0, help="low-pass weight of the new command per tick; 1 = off", min=0.01, max=1.0, live=True
    )
    idle_after_lost_s: float = param(
        0.5, help="after losing the target, send zeros this long, then stay silent", min=0.0, max=3600.0, live=True
    )


class FollowerNode(Node):
    name = "follower"
    Config = FollowerConfig

    def __init__(self, config: FollowerConfig | None = None, **kwargs: object) -> None:
        super().__init__(config, **kwargs)  # type: ignore[arg-type]
        self.cmd_pub = FOLLOWER_CMD_VEL.publisher(self)
        DETECTED_TARGET.subscription(self, self.on_target)
        self._last_target: float | None = None  # receive time (clock.monotonic())
        self._last_x: float | None = None
        self._goal = (0.0, 0.0)  # linear.x, angular.z from the latest target
        self._cmd = (0.0, 0.0)  # what goes out (after the optional low-pass)
        self._lost = True
        self._lost_at: float | None = None  # clock time the target was lost; None: never had one
        self.create_timer(1.0 / self.config.rate_hz, self.tick)
        self.create_timer(0.01, self._watchdog)

    def on_target(self, msg: PointStamped) -> None:
        p = msg.point
        x, y, z = p.x, p.y, p.z
        if not all(math.isfinite(v) for v in (x, y, z)) or abs(x) > MAX_ABS_XY or abs(y) > MAX_ABS_XY:
            self._reject(f"x={x}, y={y}, z={z}")
            return
        if not 0.0 <= z <= MAX_SIZE:
            self._reject(f"size z={z} is outside 0..{MAX_SIZE}")
            return
        now = self.clock.monotonic()
        dx_dt = 0.0
        if self.config.kd_angular > 0 and self._last_x is not None and self._last_target is not None:
            dx_dt = (x - self._last_x) / max(now - self._last_target, 1e-3)
        self._goal = follow_command(x, z, self.config, dx_dt)
        self._last_target, self._last_x = now, x
        if self._lost:
            self.log.info(f"target acquired at x={x:+.3f}, size={z:.3f}")
        self._lost = False

    def _reject(self, what: str) -> None:
        n = self.count("bad_targets")
        self.log.throttled("error", 2.0, f"dropping an invalid /detected_target ({n} so far): {what}", key="bad")

    def _check_lost(self) -> bool:
        """True when the target just became lost; the command is then zero."""
        if self._lost:
            return False
        now = self.clock.monotonic()
        if self._last_target is None or now - self._last_target >= self.config.lost_timeout_s:
            self._lost = True
            self._lost_at = now
            self._goal = self._cmd = (0.0, 0.0)
            self._last_x = None
            self.log.throttled("info", 2.0, "target lost, stopping", key="lost")
            return True
        return False

    def _watchdog(self) -> None:
        if self._check_lost():
            self._publish()

    def tick(self) -> None:
        self._check_lost()
        if not self._lost:
            a = self.config.filter_alpha
            self._cmd = (
                a * self._goal[0] + (1 - a) * self._cmd[0],
                a * self._goal[1] + (1 - a) * self._cmd[1],
            )
        elif self._lost_at is None or self.clock.monotonic() - self._lost_at > self.config.idle_after_lost_s:
            return
        self._publish()

    def _publish(self) -> None:
        self.cmd_pub.publish(Twist(linear=Vector3(x=self._cmd[0]), angular=Vector3(z=self._cmd[1])))
