"""nav_msgs/msg: Odometry, MapMetaData, OccupancyGrid, Path.

OccupancyGrid.data is ROS's `int8[]`: row-major, row 0 at the origin's y, -1 unknown, 0..100 the
probability of occupied (in percent). cyclonedds packs a sequence of primitives with one struct call,
so a 1200 x 1200 grid (the map's cap) costs one pack, not 1.4 M Python calls.
"""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register
from go2vlm.msgs.builtin_interfaces import Time
from go2vlm.msgs.geometry_msgs import Pose, PoseStamped, PoseWithCovariance, TwistWithCovariance
from go2vlm.msgs.std_msgs import Header


@register
@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = default(Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = default(PoseWithCovariance)
    twist: TwistWithCovariance = default(TwistWithCovariance)


@register
@dataclass
class MapMetaData(IdlStruct, typename="nav_msgs::msg::dds_::MapMetaData_"):
    map_load_time: Time = default(Time)
    resolution: types.float32 = 0.0  # m per cell
    width: types.uint32 = 0  # cells along x (columns)
    height: types.uint32 = 0  # cells along y (rows)
    origin: Pose = default(Pose)  # the world pose of cell (0, 0)'s outer corner


@register
@dataclass
class OccupancyGrid(IdlStruct, typename="nav_msgs::msg::dds_::OccupancyGrid_"):
    header: Header = default(Header)
    info: MapMetaData = default(MapMetaData)
    data: types.sequence[types.int8] = default(list)


@register
@dataclass
class Path(IdlStruct, typename="nav_msgs::msg::dds_::Path_"):
    header: Header = default(Header)
    poses: types.sequence[PoseStamped] = default(list)  # the waypoints, in the header's frame
