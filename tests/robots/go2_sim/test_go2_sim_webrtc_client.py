"""The community's own WebRTC client, unmodified, against `go2vlm sim --webrtc`, as the official
Unitree SDK is against the sim's DDS: `unitree-webrtc-connect` from the registry, in a venv of its
own, connects to the sim on a loopback address, receives video frames, sport-mode states and the
lidar's voxel map, and the Moves it sends walk the simulated robot (its ground truth says so).

The client always signals on port 9991 (it cannot be told another), so the sim listens on a loopback
address of its own (127.x.y.z) where 9991 is free: tests side by side do not meet.

The venv (about 150 MB) is built once and kept under the user's cache folder. Only the packages the
client imports are installed (`--no-deps` for the client itself): its pins also want pyaudio, which
needs a C compiler and PortAudio's headers, and opencv-python, flask-socketio and pydub, which only
its examples use. `sounddevice`, which it imports, needs the PortAudio library (libportaudio2, which
`scripts/setup.sh all` installs). The test skips only when that library is missing or the package
registry cannot be reached; any other failure to build the venv fails it.
"""

from __future__ import annotations

import ctypes.util
import json
import os
import random
import socket
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from busutil import GO2VLM, Output, Procs, env

pytestmark = pytest.mark.slow

CLIENT = "unitree-webrtc-connect==2.2.0"
# What the client imports (its own pins, less pyaudio, opencv-python, flask-socketio and pydub).
CLIENT_DEPS = ["aiortc>=1.9", "pycryptodome", "requests", "curl_cffi", "wasmtime", "lz4", "numpy", "packaging"]
CLIENT_DEPS.append("sounddevice")

SCRIPT = textwrap.dedent(
    """
    import asyncio, json, sys
    from unitree_webrtc_connect import RTC_TOPIC, SPORT_CMD, UnitreeWebRTCConnection, WebRTCConnectionMethod

    async def main(ip):
        conn = UnitreeWebRTCConnection(WebRTCConnectionMethod.LocalSTA, ip=ip)
        await conn.connect()
        got = {"states": 0, "frames": 0, "voxels": 0, "points": 0, "codes": []}

        def on_state(message):
            got["states"] += 1
            got["position"] = message["data"]["position"]

        def on_voxels(message):
            got["voxels"] += 1
            got["points"] = len(message["data"]["data"]["points"])

        async def on_track(track):
            while True:
                frame = await track.recv()
                got["frames"] += 1
                got["shape"] = list(frame.to_ndarray(format="bgr24").shape)

        conn.datachannel.pub_sub.subscribe(RTC_TOPIC["LF_SPORT_MOD_STATE"], on_state)
        conn.video.add_track_callback(on_track)
        conn.video.switchVideoChannel(True)
        conn.datachannel.set_decoder(decoder_type="native")
        await conn.datachannel.disableTrafficSaving(True)
        conn.datachannel.pub_sub.publish_without_callback("rt/utlidar/switch", "on")
        conn.datachannel.pub_sub.subscribe("rt/utlidar/voxel_map_compressed", on_voxels)
        for _ in range(100):
            if got["frames"] >= 5 and got["states"] >= 10 and got["voxels"] >= 2:
                break
            await asyncio.sleep(0.1)
        print("BEFORE " + json.dumps(got), flush=True)
        sport = RTC_TOPIC["SPORT_MOD"]
        r = await conn.datachannel.pub_sub.publish_request_new(sport, {"api_id": SPORT_CMD["BalanceStand"]})
        got["codes"].append(r["data"]["header"]["status"]["code"])
        for _ in range(40):
            move = {"api_id": SPORT_CMD["Move"], "parameter": {"x": 0.4, "y": 0, "z": 0}}
            r = await conn.datachannel.pub_sub.publish_request_new(sport, move)
            got["codes"].append(r["data"]["header"]["status"]["code"])
            await asyncio.sleep(0.1)
        await asyncio.sleep(0.5)
        print("RESULT " + json.dumps(got), flush=True)
        await conn.disconnect()

    asyncio.run(main(sys.argv[1]))
    """
)


def _cache() -> Path:
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "go2vlm-tests" / CLIENT.replace("==", "-")


@pytest.fixture(scope="session")
def client_python() -> Path:
    if ctypes.util.find_library("portaudio") is None:
        pytest.skip("libportaudio2 is missing (the client imports sounddevice): bash scripts/setup.sh all installs it")
    venv = _cache()
    py = venv / "bin" / "python"
    check = [str(py), "-c", "import unitree_webrtc_connect"]
    if py.exists() and subprocess.run(check, capture_output=True, timeout=120).returncode == 0:
        return py
    subprocess.run([sys.executable, "-m", "venv", "--clear", str(venv)], check=True, timeout=300)
    for args in (["--no-deps", CLIENT], CLIENT_DEPS):
        out = subprocess.run(
            [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check", *args],
            capture_output=True,
            text=True,
            timeout=1200,
        )
        if out.returncode != 0:
            unreachable = ("Could not find a version", "No matching distribution", "connection", "Network")
            if any(s.lower() in out.stderr.lower() for s in unreachable):
                pytest.skip(f"the package registry cannot be reached: {out.stderr.strip().splitlines()[-1]}")
            pytest.fail(f"pip install {' '.join(args)} failed:\n{out.stderr[-2000:]}")
    assert subprocess.run(check, capture_output=True, timeout=120).returncode == 0
    return py


def _free_loopback() -> str:
    """A 127.x.y.z address where the client's fixed signalling port 9991 is free."""
    for _ in range(50):
        ip = f"127.{random.randint(1, 254)}.{random.randint(0, 254)}.{random.randint(2, 254)}"
        with socket.socket() as sock:
            try:
                sock.bind((ip, 9991))
            except OSError:
                continue
        return ip
    pytest.skip("no loopback address with port 9991 free")


def test_unmodified_client_drives_the_sim(client_python: Path, procs: Procs, tmp_path: Path) -> None:
    ip = _free_loopback()
    sim = procs.start(
        "sim",
        "--webrtc",
        f"{ip}:9991",
        "--mode",
        "kinematic",
        "--world",
        "vision_test",
        "--param",
        "world_camera=false",
        "--param",
        "camera_width=320",
        "--param",
        "camera_height=240",
    )
    sim_out = Output(sim)
    assert sim_out.wait_line("WebRTC signalling on", 60), "".join(sim_out.lines)
    gt = subprocess.Popen(
        [*GO2VLM, "topic", "echo", "/sim/ground_truth", "--json", "--count", "400", "--timeout", "120"],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
        env=env(),
    )
    gt_out = Output(gt)
    script = tmp_path / "client.py"
    script.write_text(SCRIPT)
    client = subprocess.run([str(client_python), str(script), ip], capture_output=True, text=True, timeout=180)
    gt.terminate()
    gt_out.finish(10)
    result = [line for line in client.stdout.splitlines() if line.startswith("RESULT ")]
    assert client.returncode == 0 and result, client.stdout[-3000:] + client.stderr[-3000:]
    got = json.loads(result[0][len("RESULT ") :])
    assert got["frames"] >= 5 and got["shape"] == [240, 320, 3], got
    assert got["states"] >= 10 and got["voxels"] >= 2 and got["points"] > 0, got
    assert set(got["codes"]) == {0}, got  # BalanceStand and every Move answered "applied"
    xs = []
    for line in gt_out.lines:
        if not line.startswith("{"):
            continue
        for tf in json.loads(line).get("transforms", []):
            if tf["child_frame_id"] == "gt/go2":
                xs.append(tf["transform"]["translation"]["x"])
    assert xs and max(xs) - xs[0] > 0.5, f"the sim's ground truth did not move: {xs[:1]} .. {max(xs, default=None)}"
