"""`go2vlm mcp`: give an LLM agent (Claude, a local LLM, an IDE) typed, bounded skills over the robot
through the Model Context Protocol, behind the safety gate (apps/mcp/, docs/mcp.md).

    go2vlm mcp                          # stdio: an agent starts it; it joins the running robot on the bus
    go2vlm mcp --sim                    # ... and starts a sim with perception, commander and gate
    go2vlm mcp --http 8765              # streamable HTTP on http://127.0.0.1:8765/mcp
    GO2VLM_MCP_TOKEN=... go2vlm mcp --http 0.0.0.0:8765     # off loopback: a token is required
    go2vlm mcp --http 192.168.1.5:8765 --token-file ~/.config/go2vlm/mcp-token

The token comes from the environment ($GO2VLM_MCP_TOKEN) or a file (--token-file), never from the
command line, where `ps` shows it. No token: only exactly 127.0.0.1, ::1 or localhost may be bound.
Every bind checks the Host header against the hosts it names (the bound address; on a wildcard bind
the loopback names, this machine's name and --allow-host), against DNS rebinding.

Time here is wall time: the server's waits are for the agent, a person and DDS discovery.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
from typing import Any

from go2vlm.cli.args import add_dds_args, add_node_params, node_params, positive
from go2vlm.errors import ConfigError, UsageError
from go2vlm.secret import MIN_TOKEN_CHARS

TOKEN_ENV = "GO2VLM_MCP_TOKEN"


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "mcp",
        help="a Model Context Protocol server: an LLM agent gives the robot goals, through the safety gate",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--http", metavar="[HOST:]PORT", default=None,
        help="serve streamable HTTP (path /mcp) instead of stdio; HOST defaults to 127.0.0.1, PORT 0 = any free",
    )  # fmt: skip
    p.add_argument("--token", default=None, help=argparse.SUPPRESS)  # refused: `ps` shows it
    p.add_argument(
        "--token-file", metavar="FILE", default=None,
        help=f"a file holding the bearer token every HTTP request must carry (or env {TOKEN_ENV}); required "
        "off loopback",
    )  # fmt: skip
    p.add_argument(
        "--allow-host", metavar="NAME", action="append", default=[],
        help="a wildcard bind (0.0.0.0, ::) also accepts this Host header (repeatable)",
    )  # fmt: skip
    p.add_argument(
        "--sim", nargs="?", const="vision_test", default=None, metavar="WORLD",
        help="also start a sim (default world vision_test) with the colour grounder, commander and gate",
    )  # fmt: skip
    p.add_argument("--mode", default="dynamic", choices=("dynamic", "kinematic"), help="--sim: physics mode")
    p.add_argument("--rtf", type=positive, default=1.0, help="--sim: target real-time factor (default 1)")
    p.add_argument("--vlm-base-url", default=None, help="--sim: a vlm node (describe) on this OpenAI-compatible server")
    p.add_argument("--vlm-model", default=None, help="--sim: the served model's name for --vlm-base-url")
    p.add_argument("--confirm", action="store_true", help="each motion goal waits for a person's yes")
    p.add_argument("--deadman", type=positive, default=10.0,
                   help="stop a goal after S s without status() (10; at most 600)")  # fmt: skip
    add_node_params(p, "--sim: a node's parameter, e.g. -p sim.rtf=2 or -p commander.max_linear=0.3 (repeatable)")
    add_dds_args(p)
    p.set_defaults(func=run)


def read_token(args: argparse.Namespace) -> str | None:
    """The bearer token: --token-file's first line, else $GO2VLM_MCP_TOKEN, else None; never --token."""
    if args.token is not None:
        raise UsageError(f"--token shows the secret in `ps`: put it in ${TOKEN_ENV} or a file (--token-file)")
    from go2vlm.secret import read_secret

    try:
        return read_secret(TOKEN_ENV, args.token_file, "--token-file") or None
    except ConfigError as exc:
        raise UsageError(str(exc)) from None


def parse_bind(text: str) -> tuple[str, int]:
    """`8765`, `127.0.0.1:8765`, `[::1]:8765` -> (host, port); UsageError otherwise."""
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = "127.0.0.1", text
    host = host.strip("[]") or "127.0.0.1"
    try:
        number = int(port)
    except ValueError:
        raise UsageError(
            f"--http {text!r}: the port must be a number, e.g. --http 8765 or --http 0.0.0.0:8765"
        ) from None
    if not 0 <= number <= 65535:
        raise UsageError(f"--http {text!r}: the port must be within 0..65535")
    return host, number


def sim_entries(args: argparse.Namespace) -> list[Any]:
    from go2vlm.launch.launcher import LaunchEntry, load_launch, with_overrides

    _, entries = load_launch("mcp_sim")
    if args.vlm_base_url:
        if not args.vlm_model:
            raise UsageError("--vlm-base-url needs --vlm-model (the served model's name)")
        vlm = {"use_sim_time": True, "backend": "openai", "base_url": args.vlm_base_url, "model": args.vlm_model}
        entries.append(LaunchEntry("vlm", "vlm", {**vlm, "mode": "describe", "period_s": 1.0}))
    own = {"sim": {"world": args.sim, "mode": args.mode, "rtf": args.rtf}}
    extra = node_params(args.param)
    merged = {name: {**own.get(name, {}), **extra.get(name, {})} for name in {*own, *extra}}
    return with_overrides(entries, merged)


def run(args: argparse.Namespace) -> int:
    try:
        import mcp  # noqa: F401
    except ImportError as exc:
        raise ConfigError(f"go2vlm mcp needs the `mcp` extra (pip install 'go2vlm[mcp]'): {exc}") from None
    from go2vlm.apps.mcp.bridge_node import McpBridgeNode
    from go2vlm.apps.mcp.server import Session, build_server, http_security, make_lifespan, serve_http, serve_stdio
    from go2vlm.bus import build_node_config, exit_code, interrupt_on_signals, signal_of
    from go2vlm.bus.runtime import Interrupted
    from go2vlm.launch.launcher import check_entries, make_nodes
    from go2vlm.launch.registry import node_class

    if args.param and args.sim is None:
        raise UsageError("--param sets the nodes of --sim; without --sim there are none here")
    from go2vlm.apps.mcp.bridge_node import MAX_DEADMAN_S

    if not 1.0 <= args.deadman <= MAX_DEADMAN_S:
        raise UsageError(f"--deadman {args.deadman:g}: within 1..{MAX_DEADMAN_S:g} s")
    token = read_token(args)
    host, port = parse_bind(args.http) if args.http is not None else ("", 0)
    if token is not None and len(token) < MIN_TOKEN_CHARS:
        raise UsageError(f"the token is too short: at least {MIN_TOKEN_CHARS} characters (e.g. `openssl rand -hex 16`)")
    security = auth = verifier = None
    if args.http is not None:
        try:
            security, auth, verifier = http_security(host, token, tuple(args.allow_host))
        except ValueError:
            raise UsageError(
                f"--http {args.http}: binding to {host} (not 127.0.0.1, ::1 or localhost) needs a token: "
                f"${TOKEN_ENV} or --token-file"
            ) from None
    elif token is not None:
        print("go2vlm mcp: a token is for --http; stdio has no network to guard", file=sys.stderr)
    entries = sim_entries(args) if args.sim is not None else []
    if entries:
        check_entries(entries)  # a typo in -p fails here, before anything starts
        node_class("sim")  # the sim extra, or a clear error now
    session = Session()
    lock = threading.Lock()

    def start() -> None:
        with lock:
            if args.interface:
                os.environ["GO2VLM_IFACE"] = args.interface
            if args.domain is not None:
                os.environ["ROS_DOMAIN_ID"] = str(args.domain)
            session.nodes = make_nodes(entries) if entries else []
            for node in session.nodes:
                node.start()
            config, _ = build_node_config(McpBridgeNode.Config, {"deadman_s": args.deadman, "confirm": args.confirm})
            bridge = McpBridgeNode(config)
            bridge.on_question = ask_at_terminal
            bridge.start()
            session.node = bridge
            session.nodes.append(bridge)
            if args.confirm:
                start_terminal_answers(bridge, stdio=args.http is None)
            what = f"with the sim ({args.sim}, {args.mode})" if entries else "on the bus"
            print(f"go2vlm mcp: up {what}, domain {bridge.domain_id}; deadman {args.deadman:g} s", file=sys.stderr)

    def stop() -> None:
        with lock:
            nodes, session.nodes, session.node = session.nodes, [], None
        for node in reversed(nodes):
            node.shutdown()

    app = build_server(
        session, deadman_s=args.deadman, lifespan=make_lifespan(start, stop), auth=auth, token_verifier=verifier
    )
    interrupt_on_signals()
    try:
        if args.http is None:
            print("go2vlm mcp: serving MCP on stdio", file=sys.stderr, flush=True)
            serve_stdio(app)
        else:
            shown = f"[{host}]" if ":" in host else host
            hosts = " ".join(h for h in getattr(security, "allowed_hosts", []) if not h.endswith(":*"))

            def ready(bound: int) -> None:
                guard = "bearer token required" if token else "loopback only, no token"
                guard += f"; Host: {hosts}"
                print(f"go2vlm mcp: serving MCP on http://{shown}:{bound}/mcp ({guard})", file=sys.stderr, flush=True)

            serve_http(app, host, port, security, ready)
    except (KeyboardInterrupt, Interrupted) as exc:
        stop()
        return exit_code(signal_of(exc))
    finally:
        stop()
    return 0


def ask_at_terminal(qid: int, text: str) -> None:
    print(
        f"go2vlm mcp: the agent asks for {text!r} (#{qid}). Allow it? Type yes or no (or publish 'yes {qid}' on "
        "/mcp/confirm).",
        file=sys.stderr,
        flush=True,
    )


def start_terminal_answers(bridge: Any, *, stdio: bool) -> None:
    """Read a person's answers at this terminal: stdin over HTTP; over stdio (where stdin is the agent's
    wire) the controlling terminal, if there is one."""
    source: Any = None
    if stdio:
        try:
            source = open("/dev/tty", encoding="utf-8", errors="replace")  # noqa: SIM115 - read by the thread
        except OSError:
            print("go2vlm mcp: no terminal to confirm at; answer on /mcp/confirm (the Foxglove view)", file=sys.stderr)
            return
    else:
        source = sys.stdin

    def read() -> None:
        for line in source:
            print(f"go2vlm mcp: {bridge.answer(line, need_id=False)}", file=sys.stderr, flush=True)

    threading.Thread(target=read, name="mcp-confirm", daemon=True).start()
