"""The bus: ROS 2 topics over cyclonedds without a ROS install, and the node runtime on top.

from go2vlm.bus import Node, param, QOS_SENSOR
"""

from .domain import cyclone_config, dds_topic_name, domain_id_from_env, participant
from .log import Logger
from .node import Node, NoParams, Publisher, Subscription, Timer
from .params import ParamError, build_config, describe_params, load_params_file, param, parse_overrides
from .qos import PROFILES, QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, QosProfile
from .runtime import ShutdownRequested, running, spin

__all__ = [
    "PROFILES",
    "QOS_DEFAULT",
    "QOS_LATCHED",
    "QOS_SENSOR",
    "Logger",
    "Node",
    "NoParams",
    "ParamError",
    "Publisher",
    "QosProfile",
    "ShutdownRequested",
    "Subscription",
    "Timer",
    "build_config",
    "cyclone_config",
    "dds_topic_name",
    "describe_params",
    "domain_id_from_env",
    "load_params_file",
    "param",
    "parse_overrides",
    "participant",
    "running",
    "spin",
]
