"""Launch files: the packaged ones resolve by name, and entries parse or fail with a LaunchError."""

from __future__ import annotations

import pytest

from go2vlm.launch.launcher import LaunchError, available, parse_entries, resolve


def test_launch_files_parse_and_resolve() -> None:
    assert "follow_test_pattern" in available()
    assert resolve("follow_test_pattern").name == "follow_test_pattern.yaml"
    entries = parse_entries(
        [{"node": "follower", "params": {"kp_angular": 0.5}, "remap": {"detected_target": "/ball"}}, {"node": "safety"}]
    )
    assert [e.name for e in entries] == ["follower", "safety"]
    assert entries[0].remap == {"/detected_target": "/ball"}
    assert parse_entries({"nodes": [{"node": "safety"}]})[0].kind == "safety"
    for bad in (
        [],
        [{"node": "nope"}],
        [{"node": "safety", "extra": 1}],
        [{"node": "safety"}, {"node": "safety"}],
        [{"node": "safety", "params": [1]}],
        [{"node": "safety", "name": "a b"}],
    ):
        with pytest.raises(LaunchError):
            parse_entries(bad)
    with pytest.raises(LaunchError, match="not found"):
        resolve("no_such_launch_file")
