"""Images of any size arrive: 1280x720 and 1920x1080 rgb8 frames at 10 Hz between two processes,
with a best-effort (sensor QoS) and a reliable reader, on loopback and on the machine's default
interface (multicast, where Cyclone's own 1 MiB socket buffer lost most 1280x720 frames). What
arrives is counted, not timed. Where the kernel's net.core.rmem_max is too low for a size, the test
skips with `go2vlm doctor`'s verdict and the sysctl that fixes it (docs/benchmarks.md has figures).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from busutil import env

from go2vlm.bus.domain import kernel_rmem_max
from go2vlm.cli.doctor import RMEM_GOOD, RMEM_LOW, check_rcvbuf, interfaces, ipv4_of, is_up

LINK = str(Path(__file__).resolve().parent / "image_link.py")
FRAMES = 30
# Arrived fractions with margin: every frame arrived in every measured run on the 2-core reference
# machine with a 4 MiB kernel limit (docs/benchmarks.md); a busy machine may drop a few (23 of 30 at
# 1280x720 with a demo, two busy loops and another suite beside it). Cyclone's defaults got 19.
MIN_FRACTION = 0.7

# Sizes and the kernel limit each needs (docs/benchmarks.md, "Large images").
NEEDS = {"1280x720": RMEM_LOW, "1920x1080": RMEM_GOOD}


def default_interface_up() -> bool:
    return any(n != "lo" and is_up(n) and ipv4_of(n) for n in interfaces())


def link(size: str, qos: str, iface: str | None) -> int:
    e = env()
    if iface:
        e["GO2VLM_IFACE"] = iface
    else:
        e.pop("GO2VLM_IFACE", None)
    recv = subprocess.Popen(
        [sys.executable, LINK, "recv", "--qos", qos, "--frames", str(FRAMES), "--timeout", "40"],
        stdout=subprocess.PIPE, text=True, env=e,
    )  # fmt: skip
    try:
        assert recv.stdout is not None and recv.stdout.readline().strip() == "ready"
        subprocess.run([sys.executable, LINK, "send", size, "--frames", str(FRAMES)], check=True, env=e, timeout=120)
        out, _ = recv.communicate(timeout=60)
    finally:
        if recv.poll() is None:
            recv.kill()
            recv.wait()
    return int(out.strip().split()[-1])


def cases() -> list[object]:
    """1280x720 on the default interface (where the loss was) is in the fast set; the rest is slow."""
    out = []
    for size in NEEDS:
        for iface, where in ((None, "default-interface"), ("lo", "loopback")):
            for qos, kind in (("sensor", "best-effort"), ("default", "reliable")):
                fast = size == "1280x720" and iface is None
                marks = () if fast else (pytest.mark.slow,)
                out.append(pytest.param(size, qos, iface, id=f"{size}-{kind}-{where}", marks=marks))
    return out


@pytest.mark.parametrize(("size", "qos", "iface"), cases())
def test_large_frames_arrive(size: str, qos: str, iface: str | None) -> None:
    if iface is None and not default_interface_up():
        pytest.skip("no network interface besides lo is up")
    rmem = kernel_rmem_max()
    if rmem is not None and rmem < NEEDS[size]:
        v = check_rcvbuf()
        pytest.skip(f"{size} needs net.core.rmem_max >= {NEEDS[size]} here; go2vlm doctor says: {v.text} -> {v.fix}")
    got = link(size, qos, iface)
    assert got >= MIN_FRACTION * FRAMES, f"{got} of {FRAMES} {size} frames arrived ({qos}, {iface or 'default'})"
