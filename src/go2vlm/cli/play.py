"""`go2vlm play BAG [--rate R] [--loop] [--topics T ...] [--remap /a:=/b]`: publish a bag back."""

from __future__ import annotations

import argparse
import sys
import time

from go2vlm.bus import ParamError, ShutdownRequested
from go2vlm.cli.args import add_dds_args, non_negative, positive


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "play",
        help="play a rosbag2 bag (MCAP) back onto the bus, like `ros2 bag play`",
        description=(
            "Publish the messages of a rosbag2 bag (folder with metadata.yaml, or an .mcap file) with their "
            "original timing scaled by --rate, each topic with its recorded QoS, and the bag's time on /clock."
        ),
    )
    p.add_argument("bag", help="bag folder or .mcap file")
    p.add_argument("--rate", "-r", type=float, default=1.0, help="speed factor (default 1.0)")
    p.add_argument("--loop", "-l", action="store_true", help="start over at the end")
    p.add_argument("--topics", nargs="+", default=[], metavar="TOPIC", help="play only these topics")
    p.add_argument("--remap", "-m", action="append", default=[], metavar="FROM:=TO", help="rename a topic")
    p.add_argument("--no-clock", dest="clock", action="store_false", help="do not publish /clock")
    p.add_argument("--clock-hz", type=float, default=40.0, help="/clock rate (default 40)")
    p.add_argument(
        "--wait-for",
        nargs="+",
        default=[],
        metavar="TOPIC",
        help="wait (up to --wait-timeout) until these topics have a subscriber before playing",
    )
    p.add_argument("--wait-timeout", type=positive, default=10.0, help="seconds (default 10)")
    p.add_argument("--delay", type=non_negative, default=0.0, help="sleep S seconds before playing")
    add_dds_args(p)
    p.set_defaults(func=run)


def _slash(t: str) -> str:
    return t if t.startswith("/") else "/" + t


def run(args: argparse.Namespace) -> int:
    from go2vlm.apps.bag.bagfile import BagError
    from go2vlm.apps.bag.player_node import PlayerConfig, PlayerNode
    from go2vlm.bus import build_config
    from go2vlm.cli.run import parse_remaps

    remap = parse_remaps(args.remap)
    params = {
        "bag": args.bag,
        "rate": args.rate,
        "loop": args.loop,
        "topics": [_slash(t) for t in args.topics],
        "clock": args.clock,
        "clock_hz": args.clock_hz,
        "wait_for": [remap.get(_slash(t), _slash(t)) for t in args.wait_for],
        "wait_timeout_s": args.wait_timeout,
        "delay_s": args.delay,
    }
    # Before the node exists: its publishers are visible on the bus at once, and a Ctrl-C from then
    # on must stop it cleanly (exit 0), never as a bare KeyboardInterrupt (130).
    stop = ShutdownRequested()
    stop.install()
    try:
        config = build_config(PlayerConfig, params, node="player")
        # wait_for names the published (remapped) topics; the node knows them by their bag names
        inverse = {dst: src for src, dst in remap.items()}
        config.wait_for = [inverse.get(t, t) for t in config.wait_for]
        node = PlayerNode(config, remap=remap, domain_id=args.domain, interface=args.interface)
    except (BagError, ParamError) as exc:
        print(f"go2vlm play: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"go2vlm play: {exc}", file=sys.stderr)
        return 2
    r = node.reader
    span = (r.end_ns - r.start_ns) / 1e9
    print(
        f"go2vlm play: {args.bag}: {len(node.pubs)} topics, {span:.1f} s at rate {args.rate:g}"
        f"{' (looping)' if args.loop else ''}; Ctrl-C stops",
        file=sys.stderr,
        flush=True,
    )
    node.start()
    try:
        while not stop.event.wait(0.1):
            if node.finished.is_set():
                time.sleep(0.3)  # reliable readers (and latched late joiners) get the last samples
                break
    finally:
        node.shutdown()
    failed = node.counters.get("playback_errors", 0)
    print(f"go2vlm play: published {node.published} messages", file=sys.stderr)
    return 1 if failed else 0
