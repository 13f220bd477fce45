"""Start a set of nodes from a YAML launch file, in one process (each node on its own executor
thread) or one `python -m go2vlm run ...` child process per node.

Launch file: a list of nodes (or a mapping with a `nodes:` list):

    - node: test_pattern          # a kind from `go2vlm run --help`
      params: {period_s: 0.2}
    - node: follower
      name: follower              # optional; default: the kind; names must be unique
      remap: {/detected_target: /ball}
      params: {use_sim_time: true}  # every node kind takes use_sim_time (bus/params.py NodeParams)

There is no start-up ordering and no readiness dependency: topics use late-joiner-safe QoS, so any
start order works. Children that die are reported, not restarted. A launcher that dies, even by
SIGKILL, takes its children with it: each stops cleanly (bus/runtime.py `stop_with_parent`).

In-process graphs for programs (the episode runner): `load_launch` -> `with_overrides` (parameters
per node name, e.g. the episode's world and goal) -> `make_nodes` -> start each node.

Exit codes (bus/runtime.py): stopped by signal N, the launcher exits 128 + N once every node is
down. A child that exits 0, or 128 + N after a SIGINT or SIGTERM (its clean shutdown), ended
cleanly; with --processes the launcher exits 1 only when every child has ended and one of them did
not end cleanly.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from go2vlm.bus import Node, ShutdownRequested, build_node_config, exit_code
from go2vlm.bus.runtime import PARENT_ENV, SHUTDOWN_GRACE_S
from go2vlm.errors import ConfigError
from go2vlm.launch.registry import NODES, make_node, node_class

__all__ = [
    "LaunchEntry",
    "LaunchError",
    "available",
    "load_launch",
    "make_nodes",
    "resolve",
    "run_in_process",
    "run_processes",
    "with_overrides",
]

LAUNCH_DIR = Path(__file__).resolve().parent


class LaunchError(ConfigError):
    """A launch file that cannot be found or read, or an entry in it that is wrong."""


@dataclass
class LaunchEntry:
    kind: str
    name: str
    params: dict[str, Any] = field(default_factory=dict)
    remap: dict[str, str] = field(default_factory=dict)


def available() -> list[str]:
    """Launch files shipped with the package (names usable without a path)."""
    return sorted(p.stem for p in LAUNCH_DIR.glob("*.yaml"))


def resolve(name: str) -> Path:
    """A path as given, else `launch/NAME` or `launch/NAME.yaml` from the package."""
    p = Path(name).expanduser()
    if p.is_file():
        return p
    for cand in (LAUNCH_DIR / name, LAUNCH_DIR / f"{name}.yaml"):
        if "/" not in name and cand.is_file():
            return cand
    raise LaunchError(f"launch file {name!r} not found (no such file; packaged: {', '.join(available()) or 'none'})")


def _topic(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value.strip():
        raise LaunchError(f"{where}: {value!r} is not a topic name")
    v = value.strip()
    return v if v.startswith("/") else "/" + v


def parse_entries(doc: Any, source: str = "launch file") -> list[LaunchEntry]:
    if isinstance(doc, dict) and set(doc) == {"nodes"}:
        doc = doc["nodes"]
    if not isinstance(doc, list) or not doc:
        raise LaunchError(f"{source}: expected a non-empty list of nodes (or a mapping with a `nodes:` list)")
    out: list[LaunchEntry] = []
    for i, item in enumerate(doc):
        where = f"{source}: entry #{i}"
        if not isinstance(item, dict):
            raise LaunchError(f"{where}: expected a mapping with `node:`, got {item!r}")
        unknown = set(item) - {"node", "name", "params", "remap"}
        if unknown:
            raise LaunchError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: node, name, params, remap")
        kind = item.get("node")
        if kind not in NODES:
            raise LaunchError(f"{where}: node {kind!r} is not one of {', '.join(NODES)}")
        name = item.get("name") or kind
        if not isinstance(name, str) or not name.replace("_", "a").isalnum():
            raise LaunchError(f"{where}: name {name!r} must be letters, digits and underscores")
        params = item.get("params") or {}
        if not isinstance(params, dict):
            raise LaunchError(f"{where}: params must be a mapping, got {params!r}")
        remap_raw = item.get("remap") or {}
        if not isinstance(remap_raw, dict):
            raise LaunchError(f"{where}: remap must be a mapping {{/from: /to}}, got {remap_raw!r}")
        remap = {_topic(k, where): _topic(v, where) for k, v in remap_raw.items()}
        out.append(LaunchEntry(kind, name, dict(params), remap))
    names = [e.name for e in out]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise LaunchError(f"{source}: node names must be unique; repeated: {', '.join(dupes)} (set `name:`)")
    return out


def load_launch(name: str) -> tuple[Path, list[LaunchEntry]]:
    path = resolve(name)
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as exc:
        raise LaunchError(f"{path}: not valid YAML: {exc}") from None
    return path, parse_entries(doc, str(path))


def with_overrides(
    entries: list[LaunchEntry], params: Mapping[str, Mapping[str, Any]], every: Mapping[str, Any] | None = None
) -> list[LaunchEntry]:
    """A copy of a graph with `params[name]` merged into the parameters of the node called `name`,
    then `every` into every node's. A name that is not in the graph is a LaunchError."""
    names = [e.name for e in entries]
    unknown = sorted(set(params) - set(names))
    if unknown:
        raise LaunchError(f"no node named {', '.join(map(repr, unknown))} in this graph (nodes: {', '.join(names)})")
    return [
        LaunchEntry(e.kind, e.name, {**e.params, **params.get(e.name, {}), **(every or {})}, dict(e.remap))
        for e in entries
    ]


def make_nodes(entries: list[LaunchEntry], **kwargs: Any) -> list[Node]:
    """The graph's nodes, built in this process in the file's order (not started); `kwargs` go to
    every node (domain_id, interface). A node that fails to build shuts down the ones built before it."""
    nodes: list[Node] = []
    try:
        for e in entries:
            nodes.append(make_node(e.kind, params=e.params, node_name=e.name, remap=e.remap, **kwargs))
    except BaseException:
        for node in reversed(nodes):
            node.shutdown()
        raise
    return nodes


def _say(msg: str) -> None:
    print(f"[launch] {msg}", flush=True)


def _wait(stop: ShutdownRequested, duration_s: float | None, alive: Callable[[], bool] = lambda: True) -> None:
    # Wall time: `--duration` is how long the launcher runs, whatever clock its nodes are on.
    start = time.monotonic()
    while not stop.event.is_set() and alive():
        if duration_s is not None and time.monotonic() - start >= duration_s:
            return
        stop.event.wait(0.1)


def run_in_process(entries: list[LaunchEntry], duration_s: float | None = None) -> int:
    """All nodes in this process, each on its own executor thread."""
    stop = ShutdownRequested()
    stop.install()
    nodes: list[Node] = []
    try:
        nodes = make_nodes(entries)
        for node, e in zip(nodes, entries, strict=False):
            node.start()
            _say(f"up: {e.name} ({e.kind})")
        _say(f"{len(nodes)} node(s) running in process {os.getpid()}; Ctrl-C stops")
        _wait(stop, duration_s, lambda: all(n.failure is None for n in nodes))
    finally:
        for node in reversed(nodes):
            node.shutdown()
    _say("all nodes stopped")
    failure = next((n.failure for n in nodes if n.failure is not None), None)
    if failure is not None and stop.signal is None:
        raise failure  # a node that cannot go on (cli/main.py: one line, exit 2 or 1)
    return exit_code(stop.signal)


def child_command(e: LaunchEntry, params_file: str, log_level: str | None = None) -> list[str]:
    cmd = [sys.executable, "-m", "go2vlm"]
    if log_level:
        cmd += ["--log-level", log_level]
    cmd += ["run", e.kind, "--name", e.name, "--params-file", params_file]
    for src, dst in e.remap.items():
        cmd += ["--remap", f"{src}:={dst}"]
    return cmd


def run_processes(entries: list[LaunchEntry], duration_s: float | None = None, log_level: str | None = None) -> int:
    """One `go2vlm run` child per node; deaths are reported, not restarted."""
    check_entries(entries)  # a parameter typo fails here, before anything starts
    stop = ShutdownRequested()
    stop.install()
    with tempfile.TemporaryDirectory(prefix="go2vlm-launch-") as tmp:
        params_file = os.path.join(tmp, "params.yaml")
        with open(params_file, "w") as f:
            yaml.safe_dump({e.name: {"ros__parameters": e.params} for e in entries}, f)
        children: list[tuple[LaunchEntry, subprocess.Popen[bytes]]] = []
        child_env = {**os.environ, PARENT_ENV: str(os.getpid())}  # each child stops when we die
        try:
            for e in entries:
                p = subprocess.Popen(child_command(e, params_file, log_level), env=child_env)
                children.append((e, p))
                _say(f"up: {e.name} ({e.kind}) pid {p.pid}")
            reported: set[int] = set()
            unclean: set[int] = set()
            lock = threading.Lock()

            def alive() -> bool:
                with lock:
                    for e, p in children:
                        if p.poll() is not None and p.pid not in reported:
                            reported.add(p.pid)
                            if not clean_exit(p.returncode):
                                unclean.add(p.pid)
                            _say(f"died: {e.name} ({e.kind}) pid {p.pid} {describe_exit(p.returncode)}")
                    return len(reported) < len(children)

            _wait(stop, duration_s, alive)
            all_dead = not alive()
        finally:
            _stop_children([p for _, p in children])
    _say("all nodes stopped")
    if stop.signal is not None:
        return exit_code(stop.signal)
    return 1 if all_dead and unclean else 0


CLEAN_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def clean_exit(code: int | None) -> bool:
    """0, or 128 + N after SIGINT/SIGTERM: a node that shut down cleanly (the signal convention)."""
    return code == 0 or code in {exit_code(s) for s in CLEAN_SIGNALS}


def describe_exit(code: int | None) -> str:
    for s in CLEAN_SIGNALS:
        if code == exit_code(s):
            return f"exit code {code} (stopped cleanly by {signal.Signals(s).name})"
    if code is not None and code < 0:
        return f"killed by {signal.Signals(-code).name}"
    return f"exit code {code}"


def _stop_children(procs: list[subprocess.Popen[bytes]], timeout_s: float = SHUTDOWN_GRACE_S + 1.0) -> None:
    # A child's own watchdog prints its stacks at SHUTDOWN_GRACE_S; kill only after that (wall time:
    # process management).
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    deadline = time.monotonic() + timeout_s
    for p in procs:
        try:
            p.wait(max(0.0, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def check_entries(entries: list[LaunchEntry]) -> None:
    """Raise ParamError for a node whose parameters would not build (imports the node classes)."""
    for e in entries:
        build_node_config(node_class(e.kind).Config, e.params, node=e.name)
