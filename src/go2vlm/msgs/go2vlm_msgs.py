"""go2vlm_msgs/msg: go2vlm's own message types, with ROS 2 naming so ROS tools see them.

TrackedTarget: the target_tracker's one tracked target per camera frame (perception/tracker_node.py);
every behaviour reads it. The ROS definition is `msgs/ros/go2vlm_msgs/msg/TrackedTarget.msg` (shipped
with the package; copy `msgs/ros/go2vlm_msgs` into a colcon workspace to use it from ROS 2), and
tests/msgs checks these bytes against rosbags with that very file registered.

Services of the object memory (world/object_memory_node.py), defined in `msgs/ros/go2vlm_msgs/srv/`:
WhereIs ("where is X?": a label in, the remembered objects that fit out) and MemoryFile (save the
memory to a file, or load one). As with rcl_interfaces' services, the request and response structs
are not registered as topic types: they travel inside rmw_cyclonedds' request wrapper (bus/service.py).
"""

from dataclasses import dataclass
from pathlib import Path

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.std_msgs import Header
from go2vlm.msgs.vision_msgs import BoundingBox2D, Detection3D

__all__ = ["MSG_DIR", "SRV_DIR", "STATE_NAMES", "MemoryFile", "TrackedTarget", "WhereIs"]

# The .msg files of the go2vlm_msgs ROS package.
MSG_DIR = Path(__file__).resolve().parent / "ros" / "go2vlm_msgs" / "msg"
SRV_DIR = MSG_DIR.parent / "srv"

# TrackedTarget.state (the .msg's constants)
IDLE, SEARCHING, TRACKING, LOST, UNGROUNDABLE = 0, 1, 2, 3, 4
STATE_NAMES = {IDLE: "idle", SEARCHING: "searching", TRACKING: "tracking", LOST: "lost", UNGROUNDABLE: "ungroundable"}


@register
@dataclass
class TrackedTarget(IdlStruct, typename="go2vlm_msgs::msg::dds_::TrackedTarget_"):
    header: Header = default(Header)
    label: str = ""
    state: types.byte = IDLE
    bbox: BoundingBox2D = default(BoundingBox2D)
    image_width: types.uint32 = 0
    image_height: types.uint32 = 0
    confidence: float = 0.0
    bearing_rad: float = 0.0
    hfov_rad: float = 0.0
    distance_m: float = 0.0
    range_method: str = ""
    grounding_age_s: float = 0.0


# The .msg text lists the state constants (msgs/msgdef.py reads `__ros_constants__`).
TrackedTarget.__ros_constants__ = tuple(  # type: ignore[attr-defined]
    ("uint8", name.upper(), value) for value, name in STATE_NAMES.items()
)


@dataclass
class WhereIs_Request(IdlStruct, typename="go2vlm_msgs::srv::dds_::WhereIs_Request_"):
    label: str = ""


@dataclass
class WhereIs_Response(IdlStruct, typename="go2vlm_msgs::srv::dds_::WhereIs_Response_"):
    found: bool = False
    message: str = ""
    objects: types.sequence[Detection3D] = default(list)


class WhereIs:
    NAME = "go2vlm_msgs/srv/WhereIs"
    Request = WhereIs_Request
    Response = WhereIs_Response


@dataclass
class MemoryFile_Request(IdlStruct, typename="go2vlm_msgs::srv::dds_::MemoryFile_Request_"):
    command: str = ""  # save | load
    path: str = ""  # a name, or a path under go2vlm's state directory (statefiles.py)
    overwrite: bool = False  # save: replace an existing file


@dataclass
class MemoryFile_Response(IdlStruct, typename="go2vlm_msgs::srv::dds_::MemoryFile_Response_"):
    success: bool = False
    message: str = ""
    objects: types.uint32 = 0


class MemoryFile:
    NAME = "go2vlm_msgs/srv/MemoryFile"
    Request = MemoryFile_Request
    Response = MemoryFile_Response
