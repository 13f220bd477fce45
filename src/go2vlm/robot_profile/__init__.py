"""Each robot's facts, once (ground floor: pure data over geometry/). `profile(name)` is the profile of
the robot end `name` ("sim", "go2"); `CEILING_BOUND` is the largest ceiling of any of them (the static
bound of a speed-limit parameter; the gate then holds each robot to its own)."""

from __future__ import annotations

from go2vlm.robot_profile.go2 import GO2, SIM
from go2vlm.robot_profile.profile import Battery, Frames, HeadCamera, LidarMount, RobotProfile, SpeedCeilings

__all__ = [
    "CEILING_BOUND",
    "DEFAULT_ROBOT",
    "PROFILES",
    "Battery",
    "Frames",
    "HeadCamera",
    "LidarMount",
    "RobotProfile",
    "SpeedCeilings",
    "profile",
]

PROFILES: dict[str, RobotProfile] = {p.name: p for p in (SIM, GO2)}
DEFAULT_ROBOT = SIM.name  # what a node that is not told otherwise commands: the sim, as before profiles

CEILING_BOUND = SpeedCeilings(
    *(max(getattr(p.ceilings, f) for p in PROFILES.values()) for f in ("vx_forward", "vx_backward", "vy", "vyaw"))
)


def profile(name: str) -> RobotProfile:
    """The profile of robot `name`; ValueError naming the known ones."""
    try:
        return PROFILES[name]
    except KeyError:
        raise ValueError(f"unknown robot {name!r}; known: {', '.join(sorted(PROFILES))}") from None
