"""Attack: the WebRTC route (docs/safety.md, the attack table; docs/real_robot.md).

- The voxel bomb: a lidar message that declares 64 MiB decompressed (the real map is 77,824 bytes) is
  refused before anything is decompressed: the peak memory of the refusal stays under 1 MiB.
- A forged discovery answer (another host's IP, a broadcast or loopback address, another serial) is
  not taken: only the sender's own address, for our serial.
- The sim's signalling server: a DNS-rebinding Host header gets 421, `Content-Length: -1` gets 400 at
  once (it used to read until EOF), a huge one 413, and the server goes on serving.
- The AES key is no parameter: neither the driver nor the sim has one that holds the key.
"""

from __future__ import annotations

import json
import socket
import time
import tracemalloc
from dataclasses import fields

import pytest
from busutil import wait_for

from go2vlm.robots.go2.webrtc import codec
from go2vlm.robots.go2.webrtc.link import discovery_answer

pytest.importorskip("lz4")


def test_the_voxel_bomb_is_refused_before_decompressing() -> None:
    import lz4.block

    bomb = lz4.block.compress(b"\x00" * (64 << 20), store_size=False)  # a few hundred kB on the wire
    header = {"src_size": 64 << 20, "resolution": 0.05, "origin": [0, 0, 0], "width": [128, 128, 4096]}
    tracemalloc.start()
    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="declares 67108864 bytes; the map is 77824"):
        codec.voxel_points(header, bomb)
    spent = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    print(f"voxel bomb ({len(bomb)} bytes declaring 64 MiB): refused in {spent * 1000:.2f} ms, peak {peak} bytes")
    assert peak < 1 << 20
    # The real size with a payload that expands past it, or a lying width: refused too.
    with pytest.raises(ValueError):
        codec.voxel_points({**header, "src_size": codec.VOXEL_BYTES, "width": [128, 128, 38]}, bomb)
    with pytest.raises(ValueError, match="width"):
        codec.voxel_points({**header, "src_size": codec.VOXEL_BYTES}, b"\x00")


@pytest.mark.parametrize(
    ("answer", "sender", "taken"),
    [
        ({"sn": "B42", "ip": "192.168.12.1"}, "192.168.12.1", "192.168.12.1"),
        ({"sn": "B42"}, "192.168.12.1", "192.168.12.1"),
        ({"sn": "B42", "ip": "10.0.0.66"}, "192.168.12.1", None),  # sends us to a third host
        ({"sn": "B42", "ip": "127.0.0.1"}, "127.0.0.1", None),
        ({"sn": "B42", "ip": "224.0.0.1"}, "224.0.0.1", None),
        ({"sn": "B42", "ip": "192.168.12.255"}, "192.168.12.255", None),
        ({"sn": "OTHER", "ip": "192.168.12.1"}, "192.168.12.1", None),
        (["B42"], "192.168.12.1", None),
        ("[" * 5000, "192.168.12.1", None),
    ],
)
def test_a_forged_discovery_answer_is_not_taken(answer: object, sender: str, taken: str | None) -> None:
    data = answer.encode() if isinstance(answer, str) else json.dumps(answer).encode()
    assert discovery_answer(data, sender, "B42") == taken


def test_the_aes_key_is_no_parameter() -> None:
    from go2vlm.robots.go2.driver_node import Go2DriverConfig
    from go2vlm.robots.go2_sim.sim_node import SimNodeConfig

    for cfg in (Go2DriverConfig, SimNodeConfig):
        names = {f.name for f in fields(cfg)}
        assert not {n for n in names if "aes_key" in n and not n.endswith("_file")}, names
    from go2vlm.robots.go2.webrtc.link import LinkSettings

    assert "00112233" not in repr(LinkSettings(aes_key="00112233445566778899aabbccddeeff"))


def _raw(port: int, request: bytes, timeout: float = 10.0) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
        s.sendall(request)
        chunks = []
        while chunk := s.recv(65536):
            chunks.append(chunk)
        return b"".join(chunks)


def test_the_sims_signalling_checks_host_and_bounds_content_length() -> None:
    from go2vlm.launch.registry import make_node

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = int(sock.getsockname()[1])
    params = {"mode": "kinematic", "world": "vision_test", "world_camera": False, "camera_width": 160,
              "camera_height": 120, "webrtc": True, "webrtc_port": port}  # fmt: skip
    sim = make_node("sim", params=params)
    sim.start()
    try:
        ok = (f"POST /con_notify HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nContent-Length: 0\r\n"
              "Connection: close\r\n\r\n").encode()  # fmt: skip
        assert wait_for(lambda: _raw(port, ok).startswith(b"HTTP/1.0 200"), 30)
        rebinding = ok.replace(f"127.0.0.1:{port}".encode(), f"evil.example:{port}".encode())
        assert _raw(port, rebinding).split(b"\r\n")[0].endswith(b"421 Misdirected Request")
        t0 = time.monotonic()
        minus = ok.replace(b"Content-Length: 0", b"Content-Length: -1")  # and the connection stays open
        with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
            s.sendall(minus)
            first = s.recv(4096)
        answered = time.monotonic() - t0
        assert first.split(b"\r\n")[0].endswith(b"400 Bad Request"), first
        huge = ok.replace(b"Content-Length: 0", b"Content-Length: 99999999999")
        assert _raw(port, huge).split(b"\r\n")[0].endswith(b"413 Request Entity Too Large")
        assert _raw(port, ok).startswith(b"HTTP/1.0 200")  # still serving
        print(f"sim signalling: Content-Length -1 answered 400 in {answered:.3f} s (wall) with the socket left open")
        assert sim.webrtc.counters.get("bad_signals", 0) >= 3
    finally:
        sim.shutdown()
