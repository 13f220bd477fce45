"""`go2vlm` command line: one entry point, one subcommand module per verb.

The exit-code rule lives here and only here: 0 success; 2 for a usage or configuration error
(argparse's own errors, and any `go2vlm.errors.UsageError`/`ConfigError`, `ParamError` included);
1 for a failure at runtime (any other exception); 128 + N when stopped by signal N. Each error is one
line on stderr (`go2vlm VERB: message`), never a traceback; GO2VLM_TRACEBACK=1 shows the traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import traceback

from go2vlm.bus import Logger, ParamError, exit_code, signal_of
from go2vlm.bus.log import LEVELS
from go2vlm.errors import UsageError

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
    "teleop": "go2vlm.cli.teleop",
    "doctor": "go2vlm.cli.doctor",
    "mcp": "go2vlm.cli.mcp",
    "objects": "go2vlm.cli.objects",
    "houses": "go2vlm.cli.houses",
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="go2vlm",
        description="Make a Unitree Go2 see with a VLM and act on it. ROS 2 on the wire, no ROS install.",
    )
    parser.add_argument(
        "--log-level", default=None, type=str.lower, choices=sorted(LEVELS), help="log level (env GO2VLM_LOG_LEVEL)"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS.values():
        importlib.import_module(module).add_parser(sub)
    return parser


def one_line(exc: BaseException) -> str:
    """An exception as one line: its message with newlines folded, or its type when it has none."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def main(argv: list[str] | None = None) -> int:
    # A shell starts background jobs (`nohup go2vlm ... &`) with SIGINT ignored, and Python keeps an
    # inherited SIG_IGN: restore the default so that Ctrl-C stops every command.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    parser = build_parser()
    args = parser.parse_args(argv)
    prog = " ".join(["go2vlm", *filter(None, [getattr(args, "command", None)])])
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        if args.log_level:
            Logger.set_level(args.log_level)
        return int(args.func(args) or 0)
    except UsageError as exc:
        _report(prog, exc, ("parameter error: " if isinstance(exc, ParamError) else "") + one_line(exc))
        return 2
    except KeyboardInterrupt as exc:  # SIGINT (Ctrl-C), or SIGTERM in a tool: 128 + the signal
        return exit_code(signal_of(exc))
    except Exception as exc:  # noqa: BLE001 - the one place a runtime failure becomes exit 1
        _report(prog, exc, f"{type(exc).__name__}: {one_line(exc)}")
        return 1


def _report(prog: str, exc: BaseException, line: str) -> None:
    if os.environ.get("GO2VLM_TRACEBACK"):
        traceback.print_exception(exc)
    print(f"{prog}: {line}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
