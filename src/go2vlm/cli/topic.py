"""`go2vlm topic list | echo | hz | pub`, behaving like `ros2 topic` for our message types.

Time here is wall time (time.monotonic): a tool's deadlines, rates and waits are for the person at
the terminal and for DDS discovery, not a node's clock.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import threading
import time
from typing import Any

import yaml

from go2vlm.bus import PROFILES, QOS_DEFAULT, Node, QosProfile, exit_code, interrupt_on_signals, signal_of
from go2vlm.bus.graph import compatible_reader_qos, discover
from go2vlm.cli.args import non_negative, positive
from go2vlm.errors import UsageError
from go2vlm.msgs import get_type, ros_name
from go2vlm.msgs.convert import from_dict, to_dict, to_yaml_text


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("topic", help="list, echo, measure and publish topics (like `ros2 topic`)")
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)

    ls = verbs.add_parser("list", help="topics seen on the bus")
    ls.add_argument("-t", "--show-types", action="store_true")
    ls.add_argument("--wait", type=non_negative, default=1.5, help="discovery time in seconds")
    ls.set_defaults(func=cmd_list)

    ec = verbs.add_parser("echo", help="print messages")
    ec.add_argument("topic")
    ec.add_argument("type", nargs="?", default=None, help="message type, e.g. geometry_msgs/msg/Twist")
    ec.add_argument("--json", action="store_true", help="one JSON object per line")
    ec.add_argument("--count", "-n", type=int, default=0, help="exit after N messages")
    ec.add_argument("--timeout", type=positive, default=None, help="fail if the count is not reached in S seconds")
    ec.add_argument("--qos", choices=["auto", *PROFILES], default="auto")
    ec.add_argument("--bytes", choices=["summary", "base64", "list"], default="summary", dest="bytes_mode")
    ec.set_defaults(func=cmd_echo)

    hz = verbs.add_parser("hz", help="measure the publishing rate")
    hz.add_argument("topic")
    hz.add_argument("type", nargs="?", default=None)
    hz.add_argument("--window", type=int, default=100)
    hz.add_argument("--duration", type=positive, default=None, help="stop after S seconds")
    hz.add_argument("--qos", choices=["auto", *PROFILES], default="auto")
    hz.set_defaults(func=cmd_hz)

    pb = verbs.add_parser("pub", help="publish a message given as YAML or JSON")
    pb.add_argument("topic")
    pb.add_argument("type", help="message type, e.g. geometry_msgs/msg/Twist")
    pb.add_argument("values", nargs="?", default="{}", help='YAML/JSON, e.g. "{linear: {x: 0.2}}"')
    pb.add_argument("--rate", "-r", type=float, default=1.0, help="Hz")
    pb.add_argument("--count", "-t", type=int, default=0, help="publish N times then exit (0: forever)")
    pb.add_argument("--once", "-1", action="store_true", help="publish once then exit")
    pb.add_argument("--qos", choices=list(PROFILES), default="default")
    pb.add_argument("--wait", type=non_negative, default=2.0, help="wait up to S seconds for a subscriber first")
    pb.add_argument("--stamp", action="store_true", help="set header.stamp to now on every message")
    pb.set_defaults(func=cmd_pub)


def lookup_type(name: str) -> type[Any]:
    """The message class named on the command line; an unknown name is a usage error (exit 2)."""
    try:
        return get_type(name)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def _resolve(topic: str, type_name: str | None, qos: str, wait_s: float = 3.0) -> tuple[type, QosProfile]:
    """The message class and a compatible reader QoS, from the arguments or from discovery."""
    profile = PROFILES.get(qos, QOS_DEFAULT)
    name = topic if topic.startswith("/") else "/" + topic
    if type_name and qos != "auto":
        return lookup_type(type_name), profile
    deadline = time.monotonic() + wait_s
    info = None
    while time.monotonic() < deadline:
        info = discover(0.3).get(name)
        if info and info.publishers:
            break
    if type_name:
        cls = lookup_type(type_name)
    elif info and info.types:
        cls = lookup_type(sorted(info.types)[0])
    else:
        raise UsageError(f"topic {name} has no publisher yet; give its type to wait for it")
    if qos == "auto":
        profile = compatible_reader_qos(info.publishers if info else [], QOS_DEFAULT)
    return cls, profile


def cmd_list(args: argparse.Namespace) -> int:
    for name, info in sorted(discover(args.wait).items()):
        if args.show_types:
            types = ", ".join(sorted(ros_name(lookup_type(t)) if _known(t) else t for t in info.types))
            print(f"{name} [{types}]")
        else:
            print(name)
    return 0


def _known(dds_type: str) -> bool:
    try:
        get_type(dds_type)
        return True
    except ValueError:
        return False


class _Collector(Node):
    name = "_go2vlm_topic"


def cmd_echo(args: argparse.Namespace) -> int:
    if args.count < 0:
        raise UsageError("--count must not be negative")
    interrupt_on_signals()
    cls, profile = _resolve(args.topic, args.type, args.qos)
    done = threading.Event()
    seen = 0

    def on_msg(msg: Any) -> None:
        nonlocal seen
        if done.is_set():
            return
        if args.json:
            line = json.dumps(to_dict(msg, bytes_mode=args.bytes_mode), ensure_ascii=False)
        else:
            line = to_yaml_text(msg) + "\n---"
        sys.stdout.write(line + "\n")
        sys.stdout.flush()
        seen += 1
        if args.count and seen >= args.count:
            done.set()

    node = _Collector(node_name="go2vlm_topic_echo", parameter_services=False)
    node.create_subscription(cls, args.topic, on_msg, profile)
    node.start()
    stopped_by: int | None = None
    try:
        done.wait(args.timeout)
    except KeyboardInterrupt as exc:
        stopped_by = signal_of(exc)
    finally:
        node.shutdown()
    if stopped_by is not None:
        return exit_code(stopped_by)
    if args.count and seen < args.count:
        print(f"go2vlm: received {seen} of {args.count} messages on {args.topic} in time", file=sys.stderr)
        return 1
    return 0


def cmd_hz(args: argparse.Namespace) -> int:
    interrupt_on_signals()
    cls, profile = _resolve(args.topic, args.type, args.qos)
    stamps: list[float] = []
    lock = threading.Lock()

    def on_msg(_msg: Any) -> None:
        with lock:
            stamps.append(time.monotonic())
            del stamps[: -args.window - 1]

    node = _Collector(node_name="go2vlm_topic_hz", parameter_services=False)
    node.create_subscription(cls, args.topic, on_msg, profile)
    node.start()
    start = time.monotonic()
    stopped_by: int | None = None
    try:
        while args.duration is None or time.monotonic() - start < args.duration:
            time.sleep(1.0)
            with lock:
                gaps = [b - a for a, b in zip(stamps, stamps[1:], strict=False)]
            if not gaps:
                print("no new messages")
                continue
            mean = statistics.fmean(gaps)
            std = statistics.pstdev(gaps) if len(gaps) > 1 else 0.0
            print(
                f"average rate: {1.0 / mean:.3f}\n"
                f"\tmin: {min(gaps):.3f}s max: {max(gaps):.3f}s std dev: {std:.5f}s window: {len(gaps) + 1}"
            )
            sys.stdout.flush()
    except KeyboardInterrupt as exc:
        stopped_by = signal_of(exc)
    finally:
        node.shutdown()
    return exit_code(stopped_by)


def parse_message(cls: type, text: str) -> Any:
    try:
        data = yaml.safe_load(text) if text.strip() else {}
    except yaml.YAMLError as exc:
        raise UsageError(f"message is not valid YAML/JSON: {exc}") from None
    try:
        return from_dict(cls, data)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def cmd_pub(args: argparse.Namespace) -> int:
    interrupt_on_signals()
    cls = lookup_type(args.type)
    msg = parse_message(cls, args.values)
    if not args.rate > 0 or not math.isfinite(args.rate):
        raise UsageError("--rate must be a positive number")
    node = _Collector(node_name="go2vlm_topic_pub", parameter_services=False)
    pub = node.create_publisher(cls, args.topic, PROFILES[args.qos])
    deadline = time.monotonic() + args.wait
    waited = False
    while pub.matched == 0 and time.monotonic() < deadline:
        waited = True
        time.sleep(0.02)
    if waited and pub.matched:
        # We see the reader; give it a moment to see us, or it drops what we send first.
        time.sleep(0.25)
    count = 1 if args.once else args.count
    sent = 0
    stopped_by: int | None = None
    period = 1.0 / args.rate
    next_t = time.monotonic()
    try:
        while count == 0 or sent < count:
            if args.stamp and hasattr(msg, "header"):
                msg.header.stamp = node.stamp()
            pub.publish(msg)
            sent += 1
            print(f"publishing #{sent}: {json.dumps(to_dict(msg))}")
            sys.stdout.flush()
            if count and sent >= count:
                break
            next_t += period
            time.sleep(max(0.0, next_t - time.monotonic()))
        if PROFILES[args.qos].reliable:
            time.sleep(0.2)  # let reliable retransmits finish before the writer goes away
    except KeyboardInterrupt as exc:
        stopped_by = signal_of(exc)
    finally:
        node.shutdown()
    return exit_code(stopped_by)
