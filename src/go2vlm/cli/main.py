"""`go2vlm` command line: one entry point, one subcommand module per verb."""

from __future__ import annotations

import argparse
import importlib
import signal
import sys

from go2vlm.bus import Logger, ParamError, exit_code, signal_of

# verb -> module with `add_parser(subparsers)`; each sets `func` on its parser.
COMMANDS = {
    "run": "go2vlm.cli.run",
    "launch": "go2vlm.cli.launch",
    "topic": "go2vlm.cli.topic",
    "node": "go2vlm.cli.node",
    "param": "go2vlm.cli.param",
    "sim": "go2vlm.cli.sim",
    "demo": "go2vlm.cli.demo",
    "eval": "go2vlm.cli.eval",
    "go2": "go2vlm.cli.go2",
    "record": "go2vlm.cli.record",
    "play": "go2vlm.cli.play",
    "view": "go2vlm.cli.view",
    "estop": "go2vlm.cli.estop",
    "doctor": "go2vlm.cli.doctor",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="go2vlm",
        description="Make a Unitree Go2 see with a VLM and act on it. ROS 2 on the wire, no ROS install.",
    )
    parser.add_argument("--log-level", default=None, help="debug, info, warn or error (env GO2VLM_LOG_LEVEL)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS.values():
        importlib.import_module(module).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    # A shell starts background jobs (`nohup go2vlm ... &`) with SIGINT ignored, and Python keeps an
    # inherited SIG_IGN: restore the default so that Ctrl-C stops every command.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.log_level:
        Logger.set_level(args.log_level)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except ParamError as exc:
        print(f"go2vlm: parameter error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:  # SIGINT (Ctrl-C), or SIGTERM in a tool: 128 + the signal
        return exit_code(signal_of(exc))


if __name__ == "__main__":
    sys.exit(main())
