"""The one exit-code rule, end to end: every misuse of `go2vlm` is a real process that ends with one
line on stderr (or argparse's short usage block), never a traceback, and exit 2 for a usage or
configuration error, 1 for a runtime failure."""

from __future__ import annotations

import subprocess

import pytest
from busutil import GO2VLM, env

USAGE, RUNTIME = 2, 1

# (arguments, exit code, a fragment the one line must contain)
MISUSES = [
    (["topic", "pub", "/emergency_stop", '{"data": true}'], USAGE, "is not a message type"),
    (["topic", "pub", "/x", "nope/Bool"], USAGE, "unknown message type"),
    (["topic", "pub", "/x", "std_msgs/msg/Bool", '{"data": [}'], USAGE, "not valid YAML/JSON"),
    (["topic", "pub", "/x", "std_msgs/msg/Bool", '{"nope": 1}'], USAGE, "unknown field(s) nope"),
    (["topic", "pub", "/x", "std_msgs/msg/Bool", "--rate", "0", "-1"], USAGE, "--rate"),
    (["topic", "echo", "/x", "nope"], USAGE, "is not a message type"),
    (["topic", "echo", "/x", "std_msgs/msg/Bool", "--count", "-1"], USAGE, "--count must not be negative"),
    (["topic", "hz", "/x", "a/b/c/d"], USAGE, "is not a message type"),
    (["run", "nope"], USAGE, "unknown node 'nope'"),
    (["run", "safety", "--param", "nope=1", "--duration", "0.1"], USAGE, "unknown parameter(s) nope"),
    (["run", "safety", "--param", "garbage"], USAGE, "expected name=value"),
    (["run", "safety", "--param", "rate_hz=fast"], USAGE, "parameter error"),
    (["run", "safety", "--remap", "x"], USAGE, "expected /from:=/to"),
    (["run", "safety", "--param", "health_tilt_deg=[50, 40, 30, 20]"], USAGE, "must increase strictly"),
    (["run", "safety", "--params-file", "/nope.yaml"], USAGE, "does not exist"),
    (["run", "safety", "--domain", "999"], USAGE, "outside 0..232"),
    (["run", "safety", "--interface", "nope0"], USAGE, "does not exist"),
    (["run", "vlm", "--param", "model=/nope"], USAGE, "no such directory, and not a hub id"),
    (["run", "vlm"], USAGE, "'model' is required"),
    (["run", "vlm", "--param", "model={tmp}"], USAGE, "cannot load the model"),  # a directory, but no checkpoint
    (["launch", "/nope.yaml"], USAGE, "not found"),
    (["sim", "--duration", "-1"], USAGE, "--duration must be positive"),
    (["sim", "--param", "nope=1"], USAGE, "unknown parameter(s) nope"),
    (["record", "-a", "--duration", "-1"], USAGE, "--duration must be positive"),
    (["record"], USAGE, "give topics"),
    (["play", "/nope"], USAGE, "does not exist"),
    (["view", "--port", "99999"], USAGE, "above the maximum"),
    (["eval", "--suite", "nope", "--perception", "color", "--out", "{tmp}/ev"], USAGE, "suite 'nope' not found"),
    (
        ["eval", "--suite", "rooms", "--perception", "oracle", "--only", "48", "--out", "{tmp}/ev"],
        USAGE,
        "no episode 48 in rooms",
    ),
    (
        ["eval", "--suite", "rooms", "--perception", "oracle", "--only", "x", "--out", "{tmp}/ev"],
        USAGE,
        "--only takes episode indices",
    ),
    (["demo", "--duration", "-1"], USAGE, "--duration must be positive"),
    (["demo", "--goal", "fly to the moon"], USAGE, "cannot understand"),
    (["doctor", "--wait", "-1"], USAGE, "--wait must not be negative"),
    (["estop", "--timeout", "-1"], USAGE, "--timeout must be positive"),
    (["go2", "move", "nan", "0", "0"], USAGE, "must be finite"),
    (["teleop", "--topic", "/cmd_vel"], USAGE, "never /cmd_vel"),
    (["teleop"], USAGE, "not a TTY"),
    (["param", "set", "/nope", "a"], USAGE, "expected NAME VALUE pairs"),
    (["param", "get", "/nope", "x", "--timeout", "0.5"], RUNTIME, "is not available"),
    (["record", "/x", "--out", "/proc/nope/bag"], RUNTIME, "No such file or directory"),
]

# argparse's own errors: a short usage block and exit 2
ARGPARSE = [
    ["--log-level", "nope", "node", "list"],
    ["nope"],
    ["topic"],
    ["go2", "move", "1", "2"],
    ["sim", "--params-file", "x"],
    ["run", "safety", "--duration", "soon"],
    ["run", "safety", "--duration", "nan"],
    ["node", "list", "--wait", "nan"],
    ["topic", "hz", "/x", "std_msgs/msg/Bool", "--duration", "-1"],
    ["param", "get", "/x", "y", "--timeout", "0"],
    ["teleop", "--speed", "-1"],
    ["teleop", "--key-timeout", "inf"],
]


@pytest.mark.parametrize(
    ("args", "code", "fragment"), MISUSES, ids=lambda v: " ".join(v) if isinstance(v, list) else ""
)
def test_misuse_is_one_line(args: list[str], code: int, fragment: str, tmp_path) -> None:  # noqa: ANN001
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    out = subprocess.run(
        [*GO2VLM, *argv], capture_output=True, text=True, timeout=120, env=env(), stdin=subprocess.DEVNULL
    )
    assert "Traceback" not in out.stderr + out.stdout
    assert out.returncode == code, out.stderr
    errors = [line for line in out.stderr.splitlines() if line.startswith("go2vlm")]
    assert len(errors) == 1, out.stderr
    assert fragment in errors[0], out.stderr


@pytest.mark.parametrize("args", ARGPARSE, ids=" ".join)
def test_argparse_misuse_is_a_usage_block(args: list[str]) -> None:
    out = subprocess.run(
        [*GO2VLM, *args], capture_output=True, text=True, timeout=60, env=env(), stdin=subprocess.DEVNULL
    )
    assert "Traceback" not in out.stderr
    assert out.returncode == 2
    lines = out.stderr.splitlines()
    assert lines[0].startswith("usage: go2vlm") and "error:" in lines[-1] and len(lines) <= 8, out.stderr
