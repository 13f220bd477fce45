"""The topic table (bus/topics.py) against docs/architecture.md, the launch files and the code.

The doc's rule: a row whose first cell names a ROS topic in backticks (`/...`) is a topic of the
table; rows that name only Unitree's `rt/...` topics or the WebRTC data channel are not.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from go2vlm.bus import qos as q
from go2vlm.bus.topics import GO2_LOWSTATE, LIDAR_CLOUD, LOWSTATE, TOPICS, Topic
from go2vlm.launch.launcher import available, load_launch
from go2vlm.msgs import ros_name

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "architecture.md"
SRC = ROOT / "src" / "go2vlm"

# The QoS words of the doc table.
QOS_WORDS = {
    "default": q.QOS_DEFAULT,
    "latched": q.QOS_LATCHED,
    "sensor": q.QOS_SENSOR,
    "image": q.QOS_IMAGE,
    "clock": q.QOS_CLOCK,
    "any": q.QOS_ANY,
    "unitree": q.QOS_UNITREE_READER,
    "heartbeat": q.QOS_HEARTBEAT_READER,
}
TICKS = re.compile(r"`([^`]+)`")


def _type_name(cls: type) -> str:
    """`sensor_msgs/msg/Image` -> `sensor_msgs/Image`, as the doc writes types."""
    pkg, _, name = ros_name(cls).split("/")
    return f"{pkg}/{name}"


def doc_rows() -> dict[str, tuple[str, tuple[str, ...]]]:
    """topic -> (type, QoS words) from the doc's topic table."""
    text = DOC.read_text()
    section = text[text.index("## Topics between the stages") :]
    section = section[: section.index("\n## ", 4)]
    rows: dict[str, tuple[str, tuple[str, ...]]] = {}
    for line in section.splitlines():
        if not line.startswith("| `") and not line.startswith("| WebRTC"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        topics = [t for t in TICKS.findall(cells[0]) if t.startswith("/")]
        if not topics:
            continue  # rt/... and the WebRTC data channel: Unitree's, not the table's
        types = [t for t in TICKS.findall(cells[1]) if re.fullmatch(r"\w+/(msg/)?[A-Z]\w*", t)]
        assert len(types) in (1, len(topics)), f"{line}: one type, or one per topic"
        words = tuple(w for w in TICKS.findall(cells[2]) if w in QOS_WORDS)
        assert words, f"{line}: no QoS word ({', '.join(QOS_WORDS)}) in the QoS column"
        for i, topic in enumerate(topics):
            assert topic not in rows, f"{topic} is in the doc table twice"
            rows[topic] = (types[0] if len(types) == 1 else types[i], words)
    return rows


def test_every_topic_in_the_table_is_in_the_doc_with_its_type_and_qos() -> None:
    rows = doc_rows()
    missing = sorted(set(TOPICS) - set(rows))
    assert not missing, f"in bus/topics.py but not in docs/architecture.md's topic table: {missing}"
    for name, topic in TOPICS.items():
        doc_type, words = rows[name]
        assert doc_type.replace("/msg/", "/") == _type_name(topic.type), f"{name}: doc says {doc_type}"
        assert QOS_WORDS[words[0]] == topic.qos, f"{name}: doc says writers use {words[0]!r}, code {topic.qos}"
        reader = QOS_WORDS[words[1]] if len(words) > 1 else QOS_WORDS[words[0]]
        assert reader == topic.reader_qos, f"{name}: doc says readers use {words[1:]}, code {topic.reader_qos}"


def test_every_ros_topic_in_the_doc_is_in_the_table() -> None:
    extra = sorted(set(doc_rows()) - set(TOPICS))
    assert not extra, f"in docs/architecture.md's topic table but not in bus/topics.py: {extra}"


def test_topics_are_declared_once() -> None:
    """Only bus/topics.py spells a topic of the table in code: nodes, the CLI and the launch code take
    the name from it (docstrings, help texts and log lines may name them); the robot's own topics
    only robot_profile/go2.py spells, and the table takes them from there."""
    spelled: list[str] = []
    for path in sorted(SRC.rglob("*.py")):
        if path.name == "topics.py" and path.parent.name == "bus":
            continue
        tree = ast.parse(path.read_text())
        docs = {
            id(n.body[0].value)
            for n in ast.walk(tree)
            if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
            and n.body
            and isinstance(n.body[0], ast.Expr)
        }
        in_text = {  # strings inside f-strings and help=... texts are words to people, not names
            id(c)
            for n in ast.walk(tree)
            for c in ast.walk(n)
            if isinstance(n, ast.JoinedStr) or (isinstance(n, ast.keyword) and n.arg == "help")
        }
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Constant)
                and isinstance(node.value, str)
                and node.value in TOPICS
                and id(node) not in docs
                and id(node) not in in_text
            ):
                spelled.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value}")
    allowed = {"src/go2vlm/apps/episodes/plot.py"}  # an axis label
    # The robot's own topics are robot facts: its profile names them, the table takes them from there.
    robot_own = {("src/go2vlm/robot_profile/go2.py", t.name) for t in (LOWSTATE, GO2_LOWSTATE, LIDAR_CLOUD)}
    spelled = [
        s for s in spelled if s.split(":")[0] not in allowed and (s.split(":")[0], s.split(": ")[1]) not in robot_own
    ]
    assert not spelled, "topics spelled by hand (use go2vlm.bus.topics):\n" + "\n".join(spelled)


@pytest.mark.parametrize("name", available())
def test_launch_files_name_table_topics(name: str) -> None:
    """A launch file remaps table topics, and its `*_topic` parameters name table topics or the
    targets of its own remaps (a renamed table topic, e.g. `/vlm/answers`)."""
    _, entries = load_launch(name)
    renamed = {dst for e in entries for dst in e.remap.values()}
    for e in entries:
        for src in e.remap:
            assert src in TOPICS, f"{name}: {e.name} remaps {src}, which is not in bus/topics.py"
        for key, value in e.params.items():
            if key.endswith("_topic") and value:
                assert value in TOPICS or value in renamed, f"{name}: {e.name}.{key} = {value} is no known topic"


def test_the_table_is_sound() -> None:
    """Names are valid ROS names and unique; a reader is never stricter than the writers (else it
    would not match them): best-effort or volatile readers hear reliable or latched writers."""
    from go2vlm.bus.domain import dds_topic_name

    for name, topic in TOPICS.items():
        assert isinstance(topic, Topic) and topic.name == name
        dds_topic_name(name)
        r = topic.reader_qos
        assert not (r.reliable and not topic.qos.reliable), name
        assert not (r.transient_local and not topic.qos.transient_local), name


@pytest.mark.parametrize("name", available())
def test_a_gate_reads_the_health_topic_of_the_robot_it_commands(name: str) -> None:
    """With a go2 driver in the graph the gate's robot is the go2 (health on /go2/lowstate, the
    driver's relay); without one, its robot's own health topic; both from the table."""
    from go2vlm.robot_profile import DEFAULT_ROBOT, profile

    _, entries = load_launch(name)
    driver = any(e.kind == "go2" for e in entries)
    for e in entries:
        if e.kind != "safety":
            continue
        health = e.params.get("health_topic") or profile(e.params.get("robot", DEFAULT_ROBOT)).health_topic
        assert health in TOPICS, f"{name}: the gate reads health on {health}, not a table topic"
        if driver:
            assert health == GO2_LOWSTATE.name, (
                f"{name}: the driver relays {GO2_LOWSTATE.name}, the gate reads {health}"
            )


def test_the_robots_own_topics_are_its_profiles_and_the_profile_floor_imports_only_geometry() -> None:
    """robot_profile/ imports nothing above geometry/ (a fresh interpreter: what importing it loads);
    the table takes the robot's own topic names from it."""
    import subprocess
    import sys

    from go2vlm.robot_profile import GO2, SIM

    code = "import sys, go2vlm.robot_profile; print(' '.join(m for m in sys.modules if m.startswith('go2vlm.')))"
    loaded = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    # declare.py imports nothing of the project: any floor may declare its parameters with it
    floor = ("go2vlm.robot_profile", "go2vlm.geometry", "go2vlm.declare")
    assert loaded and all(m.startswith(floor) for m in loaded), loaded
    assert (GO2.health_topic, SIM.health_topic, GO2.lidar.topic) == (GO2_LOWSTATE.name, LOWSTATE.name, LIDAR_CLOUD.name)
