"""The topic table: every topic between the stages, declared once with its type and QoS.

Nodes, the CLI and the launch code take a topic's name, type and QoS from here, so that no two
call sites can disagree (docs/architecture.md lists the same table; a test keeps the two equal):

    CAMERA_IMAGE.publisher(node)                      # Image on /camera/image_raw, image QoS
    CAMERA_IMAGE.subscription(node, cb, name=cfg.image_topic)   # a remappable input, sensor QoS

`qos` is what writers use; `reader_qos` (default: `qos`) is what readers use. A reader may be
looser than the writers (best-effort hears both reliable and best-effort writers; volatile hears
latched ones), never stricter. Two kinds of call site pass their own QoS on purpose: the safety
gate and the e-stop listeners, which must hear every sender whatever QoS it picked (`QOS_ANY`,
and `safety/estop.py` listens with each profile), and `go2vlm estop`, which holds the e-stop
latched. A topic a node takes as a parameter (`image_topic`, `answers_topic`, ...) keeps the
parameter, with the table's name as its default.

Not here: Unitree's own `rt/...` DDS topics (`robots/go2/protocol.py`), the bus's ROS plumbing
(`/parameter_events`, `ros_discovery_info`), and Foxglove-only channels (`go2vlm view`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

from go2vlm.bus import qos
from go2vlm.bus.qos import QosProfile
from go2vlm.msgs.geometry_msgs import PointStamped, Twist
from go2vlm.msgs.go2vlm_msgs import TrackedTarget
from go2vlm.msgs.nav_msgs import OccupancyGrid, Odometry, Path
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import CameraInfo, CompressedImage, Image, Imu, JointState, LaserScan, PointCloud2
from go2vlm.msgs.std_msgs import Bool, String
from go2vlm.msgs.tf2_msgs import TFMessage
from go2vlm.msgs.unitree import LowState
from go2vlm.msgs.vision_msgs import Detection2DArray, Detection3DArray
from go2vlm.msgs.visualization_msgs import MarkerArray
from go2vlm.robot_profile import go2

if TYPE_CHECKING:
    from go2vlm.bus.endpoints import Publisher, Subscription

M = TypeVar("M")
T = TypeVar("T")


class EndpointHost(Protocol):
    """What a topic needs of a node (bus.Node is one; node.py imports this table, so not the class)."""

    def create_publisher(self, msg_type: type[T], topic: str, qos: QosProfile = ...) -> Publisher[T]: ...

    def create_subscription(
        self,
        msg_type: type[T],
        topic: str,
        callback: Callable[..., object],
        qos: QosProfile = ...,
        *,
        with_sender: bool = False,
    ) -> Subscription[T]: ...


@dataclass(frozen=True)
class Topic(Generic[M]):
    """One topic: its ROS name, its message type, and the QoS of its writers and of its readers."""

    name: str
    type: type[M]
    qos: QosProfile
    reader: QosProfile | None = field(default=None, repr=False)

    @property
    def reader_qos(self) -> QosProfile:
        return self.reader or self.qos

    def publisher(self, node: EndpointHost, *, name: str = "", qos: QosProfile | None = None) -> Publisher[M]:
        """A writer on `name` (default: the table's name; a remappable parameter passes its value)."""
        return node.create_publisher(self.type, name or self.name, qos or self.qos)

    def subscription(
        self,
        node: EndpointHost,
        callback: Callable[..., object],
        *,
        name: str = "",
        qos: QosProfile | None = None,
        with_sender: bool = False,
    ) -> Subscription[M]:
        """A reader on `name` (default: the table's name) with the table's reader QoS."""
        return node.create_subscription(
            self.type, name or self.name, callback, qos or self.reader_qos, with_sender=with_sender
        )


def _status(name: str) -> Topic[String]:
    """A node's status: latched JSON, so a late listener hears the last word at once."""
    return Topic(name, String, qos.QOS_LATCHED)


# Cameras. Writers are reliable with a short queue (QOS_IMAGE), readers best-effort (sensor data),
# so a reader also hears a best-effort camera driver and a slow reader holds at most two frames.
CAMERA_IMAGE = Topic("/camera/image_raw", Image, qos.QOS_IMAGE, qos.QOS_SENSOR)
CAMERA_IMAGE_COMPRESSED = Topic("/camera/image_raw/compressed", CompressedImage, qos.QOS_IMAGE, qos.QOS_SENSOR)
# Latched for tools; readers are volatile best-effort, because a camera sends one with every frame
# and a ROS camera driver may publish it volatile.
CAMERA_INFO = Topic("/camera/camera_info", CameraInfo, qos.QOS_LATCHED, qos.QOS_SENSOR)
WORLD_CAMERA_IMAGE = Topic("/world_camera/image_raw", Image, qos.QOS_IMAGE, qos.QOS_SENSOR)
WORLD_CAMERA_INFO = Topic("/world_camera/camera_info", CameraInfo, qos.QOS_LATCHED, qos.QOS_SENSOR)
COLOR_DEBUG_IMAGE = Topic("/color_detector/debug_image", Image, qos.QOS_SENSOR)

# Perception and the world.
TARGET_QUERY = Topic("/target/query", String, qos.QOS_LATCHED)
VLM_DETECTIONS = Topic("/vlm/detections", Detection2DArray, qos.QOS_DEFAULT)
VLM_TEXT = Topic("/vlm/detection", String, qos.QOS_DEFAULT)
VLM_DECISION = Topic("/vlm/decision", String, qos.QOS_DEFAULT)
# Which way is likeliest to lead to the object (perception/way.py): the commander's standing question
# while it searches with frontier_choice vlm, and the answers about single camera frames.
EXPLORE_WAY_QUERY = Topic("/explore/way_query", String, qos.QOS_LATCHED)
VLM_WAY = Topic("/vlm/way", String, qos.QOS_DEFAULT)
TRACKER_DETECTIONS = Topic("/target_tracker/detections", Detection2DArray, qos.QOS_DEFAULT)
TARGET_TRACKED = Topic("/target/tracked", TrackedTarget, qos.QOS_DEFAULT)
DETECTED_TARGET = Topic("/detected_target", PointStamped, qos.QOS_DEFAULT)
SIM_DETECTIONS = Topic("/sim/detections", Detection2DArray, qos.QOS_DEFAULT)
OBJECTS = Topic("/objects", Detection3DArray, qos.QOS_LATCHED)
OBJECT_MARKERS = Topic("/objects/markers", MarkerArray, qos.QOS_LATCHED)
# The occupancy map (world/map_node.py) and its costmap, inflated by the footprint: latched, at most 1 Hz.
MAP = Topic("/map", OccupancyGrid, qos.QOS_LATCHED)
MAP_COSTMAP = Topic("/map/costmap", OccupancyGrid, qos.QOS_LATCHED)
# The robot's pose corrected by scan matching against the map (the map node's scan_matching), frame map.
MAP_ODOM = Topic("/map/odom", Odometry, qos.QOS_DEFAULT)

# Behaviour.
GOAL = Topic("/goal", String, qos.QOS_DEFAULT)
GOAL_LEASE = Topic("/goal/lease", String, qos.QOS_DEFAULT)
# The commander's global route (behavior/planner/global_path.py): latched, so a late viewer sees it.
PLAN = Topic("/plan", Path, qos.QOS_LATCHED)
MCP_PENDING = Topic("/mcp/pending", String, qos.QOS_LATCHED)
MCP_CONFIRM = Topic("/mcp/confirm", String, qos.QOS_DEFAULT)

# Velocity: the gate's inputs, and its one output.
TELEOP_CMD_VEL = Topic("/teleop/cmd_vel", Twist, qos.QOS_DEFAULT)
FOLLOWER_CMD_VEL = Topic("/follower/cmd_vel", Twist, qos.QOS_DEFAULT)
BEHAVIOR_CMD_VEL = Topic("/behavior/cmd_vel", Twist, qos.QOS_DEFAULT)
CMD_VEL = Topic("/cmd_vel", Twist, qos.QOS_DEFAULT)

# Safety. Volatile by default: a latched true would outlive its release (`go2vlm estop` holds it
# latched on purpose). Readers hear every sender.
EMERGENCY_STOP = Topic("/emergency_stop", Bool, qos.QOS_DEFAULT, qos.QOS_ANY)
ESTOP_RELEASE = Topic("/emergency_stop/release", String, qos.QOS_DEFAULT, qos.QOS_ANY)
SAFETY_HEARTBEAT = Topic("/safety/heartbeat", String, qos.QOS_LATCHED, qos.QOS_HEARTBEAT_READER)

# The robot ends.
GO2_COMMAND = Topic("/go2/command", String, qos.QOS_DEFAULT)
# The Go2's rt/lowstate in ROS form, as the robot and the sim publish it; the go2 driver relays it
# as /go2/lowstate (each robot profile's `health_topic` names the one its gate reads). The names are
# the robot's facts (robot_profile/go2.py); their types and QoS are this table's.
LOWSTATE = Topic(go2.LOWSTATE_TOPIC, LowState, qos.QOS_UNITREE_WRITER, qos.QOS_UNITREE_READER)
GO2_LOWSTATE = Topic(go2.DRIVER_LOWSTATE_TOPIC, LowState, qos.QOS_UNITREE_WRITER, qos.QOS_UNITREE_READER)
LIDAR_CLOUD = Topic(go2.LIDAR_TOPIC, PointCloud2, qos.QOS_SENSOR)
SCAN = Topic("/scan", LaserScan, qos.QOS_SENSOR)
ODOM = Topic("/odom", Odometry, qos.QOS_DEFAULT)
IMU = Topic("/imu", Imu, qos.QOS_DEFAULT)
TF = Topic("/tf", TFMessage, qos.QOS_DEFAULT)
TF_STATIC = Topic("/tf_static", TFMessage, qos.QOS_LATCHED)
JOINT_STATES = Topic("/joint_states", JointState, qos.QOS_DEFAULT)
# rclcpp's ClockQoS on the reading side: best-effort, only the newest time matters.
CLOCK = Topic("/clock", Clock, qos.QOS_DEFAULT, qos.QOS_CLOCK)
SIM_GROUND_TRUTH = Topic("/sim/ground_truth", TFMessage, qos.QOS_DEFAULT)
SIM_PUSH = Topic("/sim/push", Twist, qos.QOS_DEFAULT)

# Statuses (std_msgs/String JSON).
SAFETY_STATUS = _status("/safety/status")
COMMANDER_STATUS = _status("/commander/status")
TRACKER_STATUS = _status("/target_tracker/status")
OBJECT_MEMORY_STATUS = _status("/object_memory/status")
MAP_STATUS = _status("/map/status")
VLM_STATUS = _status("/vlm/status")
ANSWER_DELAY_STATUS = _status("/answer_delay/status")
GO2_STATUS = _status("/go2/status")
SIM_STATUS = _status("/sim/status")

# The object memory's services (bus/service.py; the srv type carries request and reply).
WHERE_IS_SERVICE = "/object_memory/where_is"
MEMORY_FILE_SERVICE = "/object_memory/memory_file"
# The map node's: its map file beside a memory file (the same srv type: save | load | check).
MAP_FILE_SERVICE = "/map/map_file"

# Every topic above, by name.
TOPICS: dict[str, Topic[Any]] = {t.name: t for t in list(globals().values()) if isinstance(t, Topic)}
