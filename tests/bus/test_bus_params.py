"""Typed node parameters: defaults, coercion, ROS 2 params files, --param overrides, clear errors."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from bus_probe_node import ProbeConfig

from go2vlm.bus import ParamError, build_config, describe_params, load_params_file, param, parse_overrides

HERE = Path(__file__).parent


@dataclass
class Cfg:
    gain: float = param(0.5, min=0.0, max=2.0)
    count: int = param(3, min=1)
    name: str = param("ball")
    enabled: bool = param(True)
    color: str = param("red", choices=("red", "green", "blue"))
    hsv_low: list[int] = param([0, 100, 100])
    topics: list[str] = param(list)
    extra: dict = param(dict)
    limit: float | None = param(None)


def test_defaults() -> None:
    cfg = build_config(Cfg, {})
    assert (cfg.gain, cfg.count, cfg.name, cfg.enabled, cfg.color) == (0.5, 3, "ball", True, "red")
    assert cfg.hsv_low == [0, 100, 100] and cfg.topics == [] and cfg.extra == {} and cfg.limit is None
    # mutable defaults are fresh per instance
    cfg.hsv_low.append(1)
    assert build_config(Cfg, {}).hsv_low == [0, 100, 100]


@pytest.mark.parametrize(
    ("values", "expect"),
    [
        ({"gain": "1.5"}, {"gain": 1.5}),
        ({"gain": 1}, {"gain": 1.0}),
        ({"count": "7"}, {"count": 7}),
        ({"count": 4.0}, {"count": 4}),
        ({"enabled": "false"}, {"enabled": False}),
        ({"enabled": "on"}, {"enabled": True}),
        ({"enabled": 0}, {"enabled": False}),
        ({"name": 12}, {"name": "12"}),
        ({"hsv_low": "[1, 2, 3]"}, {"hsv_low": [1, 2, 3]}),
        ({"hsv_low": "4,5,6"}, {"hsv_low": [4, 5, 6]}),
        ({"topics": ["/a", "/b"]}, {"topics": ["/a", "/b"]}),
        ({"extra": "{k: 1}"}, {"extra": {"k": 1}}),
        ({"limit": "0.25"}, {"limit": 0.25}),
        ({"limit": None}, {"limit": None}),
    ],
)
def test_coercion(values: dict, expect: dict) -> None:
    cfg = build_config(Cfg, values)
    for k, v in expect.items():
        got = getattr(cfg, k)
        assert got == v and type(got) is type(v), (k, got)


@pytest.mark.parametrize(
    ("values", "words"),
    [
        ({"gain": "fast"}, ["'gain'", "'fast'", "not a number"]),
        ({"gain": True}, ["'gain'", "not a number"]),
        ({"gain": "nan"}, ["'gain'", "not a number"]),
        ({"gain": ".inf"}, ["'gain'", "finite"]),
        ({"gain": float("nan")}, ["'gain'", "finite"]),
        ({"gain": 2.5}, ["'gain'", "2.5", "maximum 2.0"]),
        ({"gain": -1}, ["'gain'", "minimum 0.0"]),
        ({"count": 1.5}, ["'count'", "not an int"]),
        ({"count": "three"}, ["'count'", "not an int"]),
        ({"count": True}, ["'count'", "not an int"]),
        ({"count": 0}, ["'count'", "minimum 1"]),
        ({"enabled": "maybe"}, ["'enabled'", "not a bool"]),
        ({"enabled": 2}, ["'enabled'", "not a bool"]),
        ({"color": "purple"}, ["'color'", "'purple'", "not one of", "red"]),
        ({"hsv_low": "[1, x]"}, ["'hsv_low'[1]", "'x'", "not an int"]),
        ({"hsv_low": 5}, ["'hsv_low'", "not a list"]),
        ({"name": [1]}, ["'name'", "not a string"]),
        ({"extra": "[1]"}, ["'extra'", "mapping"]),
        ({"count": None}, ["'count'", "null"]),
        ({"gian": 1.0}, ["unknown parameter", "gian", "gain"]),
    ],
)
def test_bad_values_are_clear_param_errors(values: dict, words: list[str]) -> None:
    with pytest.raises(ParamError) as info:
        build_config(Cfg, values, node="follower")
    text = str(info.value)
    assert "'follower'" in text
    for w in words:
        assert w in text, f"{w!r} not in {text!r}"


def test_validate_hook() -> None:
    @dataclass
    class Range:
        lo: float = param(0.0)
        hi: float = param(1.0)

        def validate(self) -> None:
            if self.lo >= self.hi:
                raise ValueError(f"lo ({self.lo}) must be below hi ({self.hi})")

    assert build_config(Range, {"lo": 0.5}).lo == 0.5
    with pytest.raises(ParamError, match=r"node 'n': lo \(2.0\) must be below hi \(1.0\)"):
        build_config(Range, {"lo": 2}, node="n")


def test_params_file_ros2_layout(tmp_path: Path) -> None:
    f = tmp_path / "params.yaml"
    f.write_text(
        "/**:\n  ros__parameters:\n    gain: 1.0\n    count: 2\n"
        "follower:\n  ros__parameters:\n    gain: 1.25\n    color: green\n"
        "/other:\n  ros__parameters:\n    gain: 0.1\n"
    )
    values = load_params_file(f, "follower")
    assert values == {"gain": 1.25, "count": 2, "color": "green"}  # node section beats /**
    values.update(parse_overrides(["count=5", "topics=[/a, /b]"]))  # --param beats the file
    cfg = build_config(Cfg, values, node="follower")
    assert (cfg.gain, cfg.count, cfg.color, cfg.topics) == (1.25, 5, "green", ["/a", "/b"])
    assert load_params_file(f, "other") == {"gain": 0.1, "count": 2}
    assert load_params_file(f, "nobody") == {"gain": 1.0, "count": 2}


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("follower: [1, 2]\n", ["section 'follower'", "ros__parameters"]),
        ("follower:\n  ros__parameters: 3\n", ["ros__parameters"]),
        ("- a\n- b\n", ["top level"]),
        ("follower: {ros__parameters: {gain: [}\n", ["not valid YAML"]),
    ],
)
def test_bad_params_files(tmp_path: Path, text: str, words: list[str]) -> None:
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    with pytest.raises(ParamError) as info:
        load_params_file(f, "follower")
    for w in words:
        assert w in str(info.value)
    with pytest.raises(ParamError, match="does not exist"):
        load_params_file(tmp_path / "missing.yaml", "follower")


def test_parse_overrides() -> None:
    assert parse_overrides(["a=1", "b=0.5", "c=true", "d=hello world", "e=[1, 2]", "f=", "g=a=b"]) == {
        "a": 1,
        "b": 0.5,
        "c": True,
        "d": "hello world",
        "e": [1, 2],
        "f": "",
        "g": "a=b",
    }
    with pytest.raises(ParamError, match="expected name=value"):
        parse_overrides(["gain"])
    with pytest.raises(ParamError, match="not a parameter name"):
        parse_overrides(["my-gain=1"])


def test_describe_params() -> None:
    rows = {r[0]: r for r in describe_params(ProbeConfig)}
    assert rows["rate"][1:3] == ("float", "5.0")
    assert "[echo|count]" in rows["mode"][3]
    assert rows["labels"][2] == "[]"


def probe_cli(*args: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]))
    return subprocess.run(
        [sys.executable, "-m", "bus_probe_node", *args], capture_output=True, text=True, timeout=timeout, env=env
    )


def test_cli_bad_value_exits_nonzero_with_clear_message(tmp_path: Path) -> None:
    out = probe_cli("run", "probe", "--param", "rate=fast", "--param", "mode=echo")
    assert out.returncode == 2
    assert "parameter error" in out.stderr and "'rate'" in out.stderr and "'fast'" in out.stderr
    assert "Traceback" not in out.stderr
    out = probe_cli("run", "probe", "--param", "mode=shout")
    assert out.returncode == 2 and "not one of ['echo', 'count']" in out.stderr
    f = tmp_path / "p.yaml"
    f.write_text("/**:\n  ros__parameters:\n    rate: 5000.0\n")
    out = probe_cli("run", "probe", "--params-file", str(f))
    assert out.returncode == 2 and "above the maximum 1000.0" in out.stderr and "Traceback" not in out.stderr
    out = probe_cli("run", "probe", "--param", "bogus=1")
    assert out.returncode == 2 and "unknown parameter(s) bogus" in out.stderr


def test_cli_good_params_run_and_stop(tmp_path: Path) -> None:
    f = tmp_path / "p.yaml"
    f.write_text("probe:\n  ros__parameters:\n    rate: 20.0\n    prefix: 'from file '\n")
    out = probe_cli("run", "probe", "--params-file", str(f), "--param", "repeat=2", "--duration", "0.3")
    assert out.returncode == 0, out.stderr
    assert "'rate': 20.0" in out.stderr and "'prefix': 'from file '" in out.stderr and "'repeat': 2" in out.stderr


def test_go2vlm_run_unknown_node() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "go2vlm", "run", "no_such_node"], capture_output=True, text=True, timeout=30
    )
    assert out.returncode != 0
    assert "unknown node 'no_such_node'" in out.stderr and "available:" in out.stderr
    assert "Traceback" not in out.stderr
