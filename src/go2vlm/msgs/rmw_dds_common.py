"""rmw_dds_common/msg (ROS 2 Jazzy): Gid, NodeEntitiesInfo, ParticipantEntitiesInfo.

ROS 2 announces which nodes live in a DDS participant, and which readers and writers belong to each
node, on the bare DDS topic `ros_discovery_info`; `ros2 node list` and rqt_graph read it. Since Iron a
Gid is 16 bytes (`char[16] data`, the DDS GUID), no longer 24.
"""

from dataclasses import dataclass

from cyclonedds.idl import types

from go2vlm.msgs._base import IdlStruct, default, register


@register
@dataclass
class Gid(IdlStruct, typename="rmw_dds_common::msg::dds_::Gid_"):
    data: types.array[types.byte, 16] = bytes(16)  # cyclonedds reads octet arrays back as bytes

    @classmethod
    def from_bytes(cls, raw: bytes) -> "Gid":
        if len(raw) != 16:
            raise ValueError(f"a Gid is 16 bytes, got {len(raw)}")
        return cls(data=bytes(raw))

    def to_bytes(self) -> bytes:
        return bytes(self.data)


@register
@dataclass
class NodeEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::NodeEntitiesInfo_"):
    node_namespace: types.bounded_str[256] = "/"
    node_name: types.bounded_str[256] = ""
    reader_gid_seq: types.sequence[Gid] = default(list)
    writer_gid_seq: types.sequence[Gid] = default(list)


@register
@dataclass
class ParticipantEntitiesInfo(IdlStruct, typename="rmw_dds_common::msg::dds_::ParticipantEntitiesInfo_"):
    gid: Gid = default(Gid)
    node_entities_info_seq: types.sequence[NodeEntitiesInfo] = default(list)
