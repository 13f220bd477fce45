"""The ROS 2 QoS profiles, spelled out for cyclonedds.

Cyclone's own defaults are not ROS's (its readers default to best-effort, its writers to keep-last
1), so every entity we create gets one of these profiles explicitly. XCDR1 is forced because that
is what rmw_cyclonedds_cpp and rmw_fastrtps_cpp put on the wire.
"""

from __future__ import annotations

from dataclasses import dataclass

from cyclonedds.core import Policy, Qos
from cyclonedds.util import duration


@dataclass(frozen=True)
class QosProfile:
    reliable: bool = True
    transient_local: bool = False
    depth: int = 10

    def to_dds(self, user_data: str | None = None) -> Qos:
        """`user_data`: the USER_DATA QoS text (a service's endpoints carry `serviceid=...;`, bus/service.py)."""
        reliability = (
            Policy.Reliability.Reliable(duration(milliseconds=100)) if self.reliable else Policy.Reliability.BestEffort
        )
        durability = Policy.Durability.TransientLocal if self.transient_local else Policy.Durability.Volatile
        qos = Qos(
            reliability,
            durability,
            Policy.History.KeepLast(self.depth),
            Policy.DataRepresentation(use_cdrv0_representation=True),
        )
        return qos + Qos(Policy.Userdata(data=user_data.encode())) if user_data else qos

    def describe(self) -> str:
        rel = "reliable" if self.reliable else "best-effort"
        dur = "transient-local" if self.transient_local else "volatile"
        return f"{rel}, {dur}, keep-last {self.depth}"


# rclpy's qos_profile_default / qos_profile_sensor_data / a latched (transient-local) profile.
QOS_DEFAULT = QosProfile(reliable=True, transient_local=False, depth=10)
QOS_SENSOR = QosProfile(reliable=False, transient_local=False, depth=5)
QOS_LATCHED = QosProfile(reliable=True, transient_local=True, depth=1)

PROFILES = {"default": QOS_DEFAULT, "sensor": QOS_SENSOR, "latched": QOS_LATCHED}

# A best-effort reader matches every publisher, reliable or not: for inputs that must be heard
# whatever QoS their sender picked (the safety gate's inputs, the e-stop).
QOS_ANY = QosProfile(reliable=False, transient_local=False, depth=10)
# /clock as rclcpp reads it (ClockQoS): best-effort matches any publisher, and keep-last 1 because
# only the newest time matters.
QOS_CLOCK = QosProfile(reliable=False, transient_local=False, depth=1)
# /safety/heartbeat's readers: heartbeats are latched (a late robot end hears every live gate's);
# each gate's arrive in one keyless instance, so the reader keeps a deep history to hear every gate's.
QOS_HEARTBEAT_READER = QosProfile(reliable=True, transient_local=True, depth=32)
# Camera images: reliable, so both reliable and best-effort (sensor-QoS) readers match; depth 2
# keeps a slow reader from holding more than two frames.
QOS_IMAGE = QosProfile(reliable=True, transient_local=False, depth=2)
# unitree_sdk2 creates every reader and writer with Cyclone's default QoS (qos=None): writers
# reliable, readers best-effort, volatile, keep-last. Reliable writers and best-effort readers
# match any peer, so we use exactly that split; depth is local and does not affect matching.
QOS_UNITREE_WRITER = QosProfile(reliable=True, transient_local=False, depth=10)
QOS_UNITREE_READER = QosProfile(reliable=False, transient_local=False, depth=32)
# Services (bus/service.py), as rmw's profiles: rmw_qos_profile_services_default (reliable, volatile,
# keep-last 10) and rmw_qos_profile_parameters (the same with keep-last 1000), which rclcpp also
# uses for /parameter_events. Reliable + volatile is what decides matching; depth is local.
QOS_SERVICES = QosProfile(reliable=True, transient_local=False, depth=10)
QOS_PARAMETERS = QosProfile(reliable=True, transient_local=False, depth=1000)
# The sim's sport server reads requests with a deep history, so that a burst of Moves from a client
# does not push a Damp out of the reader's cache before the executor takes it.
QOS_UNITREE_SERVER = QosProfile(reliable=False, transient_local=False, depth=8192)
