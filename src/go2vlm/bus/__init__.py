"""The bus: ROS 2 topics over cyclonedds without a ROS install, and the node runtime on top.

from go2vlm.bus import Node, param, QOS_SENSOR
"""

from go2vlm.bus.clock import Clock
from go2vlm.bus.domain import cyclone_config, dds_topic_name, domain_id_from_env, participant
from go2vlm.bus.endpoints import Endpoint, Publisher, RawSample, RawSubscription, Subscription
from go2vlm.bus.log import Logger
from go2vlm.bus.node import Node, NoParams, Timer
from go2vlm.bus.params import (
    BASE_PARAMS,
    NodeParams,
    ParamError,
    build_config,
    build_node_config,
    core_params,
    core_values,
    describe_params,
    from_core,
    load_params_file,
    param,
    parse_overrides,
)
from go2vlm.bus.qos import (
    PROFILES,
    QOS_ANY,
    QOS_CLOCK,
    QOS_DEFAULT,
    QOS_HEARTBEAT_READER,
    QOS_IMAGE,
    QOS_LATCHED,
    QOS_SENSOR,
    QOS_UNITREE_READER,
    QOS_UNITREE_SERVER,
    QOS_UNITREE_WRITER,
    QosProfile,
)
from go2vlm.bus.runtime import (
    Interrupted,
    ShutdownRequested,
    exit_code,
    interrupt_on_signals,
    running,
    signal_of,
    spin,
)

__all__ = [
    "BASE_PARAMS",
    "PROFILES",
    "QOS_ANY",
    "QOS_CLOCK",
    "QOS_DEFAULT",
    "QOS_HEARTBEAT_READER",
    "QOS_IMAGE",
    "QOS_LATCHED",
    "QOS_SENSOR",
    "QOS_UNITREE_READER",
    "QOS_UNITREE_SERVER",
    "QOS_UNITREE_WRITER",
    "Clock",
    "Endpoint",
    "Interrupted",
    "Logger",
    "Node",
    "NoParams",
    "NodeParams",
    "ParamError",
    "Publisher",
    "QosProfile",
    "RawSample",
    "RawSubscription",
    "ShutdownRequested",
    "Subscription",
    "Timer",
    "build_config",
    "build_node_config",
    "core_params",
    "core_values",
    "cyclone_config",
    "dds_topic_name",
    "describe_params",
    "from_core",
    "domain_id_from_env",
    "exit_code",
    "interrupt_on_signals",
    "load_params_file",
    "param",
    "parse_overrides",
    "participant",
    "running",
    "signal_of",
    "spin",
]
