"""`go2vlm demo [--goal TEXT]`: one episode of the episode runner (apps/episodes), with a progress
bar and a summary; metrics.json, series.json, plot.png and video.mp4 in the run folder."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from go2vlm.cli.args import add_dds_args, add_node_params, house_note, node_params
from go2vlm.cli.view import add_foxglove_args, foxglove_params


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "demo",
        help="the closed loop in one command: sim + color_detector + follower + safety gate",
        description=(
            "Bring up the simulated Go2 in the follow_ball world (a red ball at 0.3 m/s on a closed path), the "
            "colour detector, the follower and the safety gate in one process; the Go2 follows the ball. At the "
            "end it prints a summary and writes metrics.json, plot.png and video.mp4 to --out. Exit code 1 if "
            "the robot fell or the e-stop stopped it; exit code 2, before anything starts, if the robot is latched."
        ),
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help="sim seconds to run; with --goal, the timeout (default 60; a goal in a generated house: the houses "
        "suite's, 240, time to search several rooms)",
    )
    speed = p.add_mutually_exclusive_group()
    speed.add_argument("--rtf", type=float, default=1.0, help="target real-time factor (default 1.0)")
    speed.add_argument("--fast", action="store_true", help="run the sim as fast as possible")
    p.add_argument("--mode", default="dynamic", choices=("dynamic", "kinematic"), help="physics mode")
    p.add_argument(
        "--out", type=Path, default=None, help="output folder (default runs/demo-<timestamp>, runs/goal-<timestamp>)"
    )
    p.add_argument(
        "--robot",
        default="sim",
        choices=("sim", "go2"),
        help="sim: /cmd_vel straight into the sim; go2: through the Go2 driver and the Unitree protocol",
    )
    p.add_argument(
        "--transport",
        default="dds",
        choices=("dds", "webrtc"),
        help="with --robot go2: dds (Unitree DDS, the EDU's Ethernet) or webrtc (the Unitree app's route, every Go2)",
    )
    p.add_argument("--no-video", dest="video", action="store_false", help="skip the MP4")
    p.add_argument("--bag", action="store_true", help="also record every topic into OUT/bag (rosbag2 MCAP)")
    add_foxglove_args(p)
    p.add_argument(
        "--world",
        default=None,
        help="world (default follow_ball; with --goal, picked from the goal); house:SEED is a generated house",
    )
    p.add_argument(
        "--spawn",
        default=None,
        metavar="ROOM|X,Y,YAW",
        help="where the robot starts: a room of the world (e.g. kitchen: household, apartment; the world's "
        "spawn_<room> pose) or a pose x,y,yaw in metres and radians (default: the world's own spawn)",
    )
    p.add_argument(
        "--goal",
        default=None,
        help="run a language goal instead, e.g. 'go to the blue cylinder', 'look for the green box', '跟着红球'",
    )
    p.add_argument(
        "--perception",
        choices=("color", "oracle", "vlm"),
        default="color",
        help=(
            "what grounds the target: color (default, no weights), oracle (the sim's ground-truth boxes) or vlm "
            "(Qwen2.5-VL: --model, and --base-url for a server); oracle and vlm run the ball follow demo as the "
            "goal 'follow the red ball' through the target_tracker"
        ),
    )
    p.add_argument(
        "--model", default=None, help="vlm: a checkpoint dir or hub id; with --base-url, the served model's name"
    )
    p.add_argument(
        "--base-url",
        default=None,
        help="vlm: an OpenAI-compatible server (vLLM, transformers serve), e.g. http://gpu-box:8000/v1",
    )
    p.add_argument("--ball-speed", type=float, default=0.3, help="ball speed, m/s (default 0.3)")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    add_node_params(p, "a node parameter, e.g. follower.kp_angular=1.0 or sim.camera_rate_hz=15")
    add_dds_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from go2vlm.apps.episodes import Episode, RunOptions
    from go2vlm.apps.episodes.demo import (
        default_out_dir,
        demo_duration,
        demo_spawn,
        demo_world,
        goal_summary,
        run_with_progress,
        summary,
    )
    from go2vlm.apps.episodes.episode import FOLLOW_BALL_GOAL, vlm_node_params
    from go2vlm.apps.episodes.latch import stopped_line
    from go2vlm.behavior.goals import GoalParseError, parse_goal
    from go2vlm.bus import ShutdownRequested
    from go2vlm.launch.launcher import LaunchError

    if args.duration is not None and args.duration <= 0:
        print("go2vlm demo: --duration must be positive", file=sys.stderr)
        return 2
    if not args.fast and args.rtf <= 0:
        print("go2vlm demo: --rtf must be positive", file=sys.stderr)
        return 2
    goal = args.goal
    if goal is None and args.perception != "color":
        goal = FOLLOW_BALL_GOAL  # the ball follow demo through the tracker: the article's detector has no VLM
    if goal is not None:
        try:
            parse_goal(goal)
        except GoalParseError as exc:
            print(f"go2vlm demo: {exc}", file=sys.stderr)
            return 2
    world = args.world or demo_world(goal)
    duration = args.duration if args.duration is not None else demo_duration(world, goal)
    try:
        house_note(world, "demo")
        spawn = None if args.spawn is None else demo_spawn(world, args.spawn)
    except ValueError as exc:
        print(f"go2vlm demo: {exc}", file=sys.stderr)
        return 2
    try:
        ep = Episode(
            world=world,
            spawn=spawn,
            goal=goal,
            perception=args.perception,
            mode=args.mode,
            ball_speed=args.ball_speed,
            duration_s=duration,
            robot=args.robot,
            transport=args.transport,
            params=vlm_node_params(args.perception, args.model, args.base_url, node_params(args.param)),
        )
    except ValueError as exc:
        print(f"go2vlm demo: {exc}", file=sys.stderr)
        return 2
    opts = RunOptions(
        rtf=args.rtf,
        fast=args.fast,
        out=args.out or default_out_dir(goal),
        video=args.video,
        interface=args.interface,
        domain_id=args.domain,
        cpu=goal is None,
        bag=args.bag,
        foxglove=foxglove_params(args),
        refuse_latched=True,  # a latched robot: one line and exit 2, before anything starts
    )
    stop = ShutdownRequested()
    stop.install()
    try:
        result = run_with_progress(ep, opts, stop, progress=args.progress)
    except LaunchError as exc:
        print(f"go2vlm demo: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:
        print(f"go2vlm demo: {exc}", file=sys.stderr)
        return 1
    if goal is None:
        print(summary(result), flush=True)
        if result.metrics["fell"]:
            print("go2vlm demo: FAILED: the robot fell", file=sys.stderr)
            return 1
    else:
        print(goal_summary(result), flush=True)
    if result.interrupted:
        return stop.exit_code or 130
    stopped = stopped_line(result.metrics.get("estop"))
    if stopped is not None:
        print(f"go2vlm demo: {stopped}", file=sys.stderr)
        return 1
    return 0 if goal is None or result.metrics["goal_reached"] else 1
