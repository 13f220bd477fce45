"""`go2vlm demo`: the simulated Go2 follows a red ball; metrics, a plot and a video at the end."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="the closed loop in one command: sim + color_detector + follower + safety gate",
        description=(
            "Bring up the simulated Go2 in the follow_ball world (a red ball at 0.3 m/s on a closed path), the "
            "colour detector, the follower and the safety gate in one process; the Go2 follows the ball. At the "
            "end it prints a summary and writes metrics.json, plot.png and video.mp4 to --out. Exit code 1 if "
            "the robot fell."
        ),
    )
    p.add_argument("--duration", type=float, default=60.0, help="sim seconds to run (default 60)")
    speed = p.add_mutually_exclusive_group()
    speed.add_argument("--rtf", type=float, default=1.0, help="target real-time factor (default 1.0)")
    speed.add_argument("--fast", action="store_true", help="run the sim as fast as possible")
    p.add_argument("--mode", default="dynamic", choices=("dynamic", "kinematic"), help="physics mode")
    p.add_argument("--out", type=Path, default=None, help="output folder (default runs/demo-<timestamp>)")
    p.add_argument(
        "--robot",
        default="sim",
        choices=("sim", "go2"),
        help="sim: /cmd_vel straight into the sim; go2: through the Go2 driver and the Unitree protocol",
    )
    p.add_argument("--no-video", dest="video", action="store_false", help="skip the MP4")
    p.add_argument("--world", default=None, help="world (default follow_ball; with --goal, picked from the goal)")
    p.add_argument(
        "--goal",
        default=None,
        help="run a language goal instead, e.g. 'go to the blue cylinder', 'look for the green box', '跟着红球'",
    )
    p.add_argument("--ball-speed", type=float, default=0.3, help="ball speed, m/s (default 0.3)")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    p.add_argument(
        "--param",
        "-p",
        action="append",
        default=[],
        metavar="NODE.NAME=VALUE",
        help="a node parameter, e.g. follower.kp_angular=1.0 or sim.camera_rate_hz=15",
    )
    p.add_argument("--interface", default=None, help="network interface, e.g. lo (env GO2VLM_IFACE)")
    p.add_argument("--domain", type=int, default=None, help="DDS domain (default: ROS_DOMAIN_ID or 0)")
    p.set_defaults(func=run)


def node_params(items: list[str]) -> dict[str, dict]:
    from go2vlm.bus import ParamError, parse_overrides

    out: dict[str, dict] = {}
    for item in items:
        name, sep, value = item.partition("=")
        node, dot, pname = name.partition(".")
        if not sep or not dot or not node or not pname:
            raise ParamError(f"--param {item!r}: expected NODE.NAME=VALUE, e.g. follower.kp_angular=1.0")
        out.setdefault(node.strip(), {}).update(parse_overrides([f"{pname}={value}"]))
    return out


def run(args: argparse.Namespace) -> int:
    if args.goal:
        return run_goal_cli(args)
    args.world = args.world or "follow_ball"
    from go2vlm.apps.follow_demo import DemoOptions, run_demo, summary

    if args.duration <= 0:
        print("go2vlm demo: --duration must be positive", file=sys.stderr)
        return 2
    if not args.fast and args.rtf <= 0:
        print("go2vlm demo: --rtf must be positive", file=sys.stderr)
        return 2
    opts = DemoOptions(
        duration=args.duration,
        rtf=args.rtf,
        fast=args.fast,
        mode=args.mode,
        out=args.out,
        robot=args.robot,
        video=args.video,
        world=args.world,
        ball_speed=args.ball_speed,
        progress=args.progress,
        interface=args.interface,
        domain_id=args.domain,
        params=node_params(args.param),
    )
    try:
        result = run_demo(opts)
    except RuntimeError as exc:
        print(f"go2vlm demo: {exc}", file=sys.stderr)
        return 3
    print(summary(result))
    if result.fell:
        print("go2vlm demo: FAILED: the robot fell", file=sys.stderr)
        return 1
    return 130 if result.metrics.get("interrupted") else 0


def run_goal_cli(args: argparse.Namespace) -> int:
    """`go2vlm demo --goal TEXT`: uses the demo parser's --duration, --rtf/--fast, --mode, --world,
    --out, --ball-speed, --param, --interface, --domain (a --world of None picks the world from the goal)."""
    from go2vlm.apps.goal_demo import GoalDemoOptions, goal_summary, run_goal_demo
    from go2vlm.behavior.goals import GoalParseError, parse_goal

    try:
        parse_goal(args.goal)
    except GoalParseError as exc:
        print(f"go2vlm demo: {exc}", file=sys.stderr)
        return 2
    opts = GoalDemoOptions(
        goal=args.goal,
        world=getattr(args, "world", None),
        mode=getattr(args, "mode", "kinematic"),
        rtf=getattr(args, "rtf", 1.0),
        fast=getattr(args, "fast", False),
        timeout_s=getattr(args, "duration", None) or 60.0,
        follow_duration_s=getattr(args, "duration", None) or 30.0,
        ball_speed=getattr(args, "ball_speed", 0.3),
        params=node_params(getattr(args, "param", []) or []),
        out=getattr(args, "out", None),
        interface=getattr(args, "interface", None),
        domain_id=getattr(args, "domain", None),
        progress=getattr(args, "progress", True),
    )
    try:
        result = run_goal_demo(opts)
    except RuntimeError as exc:
        print(f"go2vlm demo: {exc}", file=sys.stderr)
        return 3
    print(goal_summary(result))
    return 0 if result.metrics["goal_reached"] else 1
