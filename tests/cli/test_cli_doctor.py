"""`go2vlm doctor` as a real process: one verdict line per known trap, exit 0 when nothing fails,
1 when something does (a second /cmd_vel writer on the domain, a missing interface), 2 for bad
arguments; it reads the kernel's limit and prints the sysctl, never changes it."""

from __future__ import annotations

import subprocess

from busutil import GO2VLM, env

from go2vlm.bus import QOS_DEFAULT, Node, running
from go2vlm.bus.domain import RCVBUF_REQUEST, kernel_rmem_max
from go2vlm.msgs.geometry_msgs import Twist


def doctor(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*GO2VLM, "doctor", *args], capture_output=True, text=True, timeout=240, env=env())


def lines_of(out: subprocess.CompletedProcess[str]) -> dict[str, str]:
    """check name -> its verdict line."""
    found = {}
    for line in out.stdout.splitlines():
        if line.startswith("[") and "]" in line:
            found[line.split("]", 1)[1].split(":", 1)[0].strip()] = line
    return found


def test_doctor_checks_every_trap() -> None:
    out = doctor("--wait", "1")
    found = lines_of(out)
    assert set(found) == {"interface", "domain", "rcvbuf", "peers", "cmd_vel", "render", "torch"}, out.stdout
    assert "lo is up (127.0.0.1)" in found["interface"]  # the tests run on GO2VLM_IFACE=lo
    assert "[  ok] render" in found["render"], found["render"]
    assert "FAIL" not in out.stdout and out.returncode == 0, out.stdout + out.stderr
    assert "all checks pass" in out.stdout and "Traceback" not in out.stderr
    rmem = kernel_rmem_max()
    if rmem is not None and rmem < RCVBUF_REQUEST:
        assert f"sudo sysctl -w net.core.rmem_max={RCVBUF_REQUEST}" in found["rcvbuf"]


def test_doctor_fails_on_a_second_cmd_vel_writer() -> None:
    a, b = Node(node_name="writer_a"), Node(node_name="writer_b")
    pa = a.create_publisher(Twist, "/cmd_vel", QOS_DEFAULT)
    pb = b.create_publisher(Twist, "/cmd_vel", QOS_DEFAULT)
    writer, participant = str(pa.guid), str(a.participant.guid)
    assert str(pb.guid) != writer
    with running(a, b):
        out = doctor("--wait", "2", "--skip", "render", "--skip", "torch")
    found = lines_of(out)
    assert out.returncode == 1, out.stdout
    line = found["cmd_vel"]
    assert line.startswith("[FAIL] cmd_vel: 2 writers on /cmd_vel") and "only the safety gate" in line
    assert "/writer_a" in line and "/writer_b" in line and writer in line and participant in line
    assert "cmd_vel" in out.stderr  # the summary names what failed


def test_doctor_fails_on_a_missing_interface_and_rejects_bad_arguments() -> None:
    out = doctor("--interface", "nosuch0", "--skip", "render", "--skip", "torch")
    assert out.returncode == 1 and "[FAIL] interface: 'nosuch0' does not exist" in out.stdout, out.stdout
    bad = doctor("--wait", "-1")
    assert bad.returncode == 2 and "--wait" in bad.stderr and "Traceback" not in bad.stderr
