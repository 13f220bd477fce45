"""`go2vlm sim [--world NAME] [--duration S] [--rtf X | --fast] [--viewer] [--mode dynamic|kinematic]
[--unitree] [--webrtc [HOST:PORT]]`.

Time here is wall time (time.monotonic): a tool's deadlines, rates and waits are for the person at
the terminal and for DDS discovery, not a node's clock.
"""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING, cast

from go2vlm.bus import ShutdownRequested, exit_code, parse_overrides
from go2vlm.cli.args import add_dds_args, house_note
from go2vlm.cli.view import add_foxglove_args, foxglove_params, make_view
from go2vlm.errors import UsageError

if TYPE_CHECKING:
    from go2vlm.robots.go2_sim.sim_node import SimNode


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "sim",
        help="run the simulated Go2 (MuJoCo) on ROS 2 topics",
        description=(
            "Run the `sim` node: a MuJoCo Go2 publishing /camera/image_raw, /odom, /imu, /joint_states, /lowstate, "
            "/tf, /clock, /sim/ground_truth and /sim/status, driven by /cmd_vel. Headless by default (EGL, "
            "OSMesa fallback). `go2vlm run --help` lists every parameter of the sim node; set them with --param."
        ),
    )
    p.add_argument(
        "--world",
        default="follow_ball",
        help="vision_test, follow_ball, obstacles, household, apartment ..., house:SEED (a generated house) or an "
        ".xml path",
    )
    p.add_argument("--mode", default="dynamic", choices=("dynamic", "kinematic"), help="physics mode")
    speed = p.add_mutually_exclusive_group()
    speed.add_argument("--rtf", type=float, default=1.0, help="target real-time factor (default 1.0)")
    speed.add_argument("--fast", action="store_true", help="run as fast as possible")
    p.add_argument("--duration", type=float, default=None, help="stop after this many sim seconds")
    p.add_argument("--viewer", action="store_true", help="open MuJoCo's interactive viewer (needs a display)")
    p.add_argument("--unitree", action="store_true", help="also serve the Unitree DDS protocol")
    p.add_argument(
        "--webrtc",
        nargs="?",
        const="127.0.0.1:9991",
        default=None,
        metavar="HOST:PORT",
        help="also serve the Go2's WebRTC route (the Unitree app's; implies --unitree) on HOST:PORT (127.0.0.1:9991)",
    )
    p.add_argument("--param", "-p", action="append", default=[], metavar="NAME=VALUE", help="any sim parameter")
    add_dds_args(p)
    add_foxglove_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import os

    if args.duration is not None and not args.duration > 0:
        raise UsageError("--duration must be positive")

    if args.viewer:
        if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
            print(
                "go2vlm sim: --viewer needs a display (DISPLAY or WAYLAND_DISPLAY is not set); running headless.",
                file=sys.stderr,
            )
            args.viewer = False
        else:
            # The interactive viewer uses GLFW; offscreen cameras then share that backend.
            os.environ.setdefault("MUJOCO_GL", "glfw")
    from go2vlm.launch.registry import make_node

    house_note(args.world, "sim")
    params = {"world": args.world, "mode": args.mode, "rtf": args.rtf, "fast": args.fast, "viewer": args.viewer}
    if args.unitree:
        params["unitree"] = True
    if args.webrtc is not None:
        host, _, port = args.webrtc.rpartition(":")
        if not host or not port.isdigit():
            raise UsageError(f"--webrtc takes HOST:PORT, e.g. 127.0.0.1:9991, not {args.webrtc!r}")
        params.update(webrtc=True, webrtc_host=host, webrtc_port=int(port))
    params.update(parse_overrides(args.param))
    node = cast("SimNode", make_node("sim", params=params, domain_id=args.domain, interface=args.interface))
    view_params = foxglove_params(args)
    view = make_view(view_params, domain_id=args.domain, interface=args.interface) if view_params else None
    stop = ShutdownRequested()
    stop.install()
    node.start()
    if view is not None:
        view.start()
    target = "as fast as possible" if node.config.fast else f"target real-time factor {node.config.rtf:g}"
    print(
        f"go2vlm sim: world {node.config.world!r}, {node.config.mode} physics, {target}. Ctrl-C stops.", file=sys.stderr
    )
    next_print = time.monotonic() + 2.0
    try:
        while not stop.event.wait(0.1):
            if args.duration is not None and node.sim_time >= args.duration:
                break
            if time.monotonic() >= next_print:
                next_print += 5.0
                print(f"go2vlm sim: sim time {node.sim_time:7.1f} s  real-time factor {node.rtf:.2f}", file=sys.stderr)
    finally:
        if view is not None:
            view.shutdown()
        node.shutdown()
    fell = getattr(node, "fell_reported", False)
    print(
        f"go2vlm sim: stopped at sim time {node.sim_time:.1f} s{' (the robot fell)' if fell else ''}", file=sys.stderr
    )
    return exit_code(stop.signal)
