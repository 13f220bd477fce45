"""`go2vlm doctor`: check the known traps, one line each with a verdict and the fix.

    go2vlm doctor [--interface enp3s0] [--model 3b|7b] [--quantization none|nf4|int8]
    go2vlm doctor --robot 192.168.8.181 [--aes-key-file F]  # a Go2 over WebRTC (Wi-Fi, every model)

Checks: the network interface (exists, up, an address; a Go2 needs 192.168.123.x), the DDS domain
(ROS_DOMAIN_ID sane; who else speaks on it), the socket receive buffer against the kernel's limit
(large camera frames), headless rendering for the sim (MUJOCO_GL: EGL or OSMesa), torch and CUDA
for a local Qwen2.5-VL (GPU memory against the model's need, estimates), and a second /cmd_vel
writer on the domain (only the safety gate may write it). With --robot IP, the Go2's WebRTC route
(robots/go2/webrtc/probe.py): the robot answers, its signalling port and protocol, the Unitree app
(or another client) holding the connection, and the firmware version. Exit 0 when nothing fails (warnings
included), 1 when something fails, 2 for bad arguments. It reads system settings, never changes
them: where a fix needs root it prints the command to run.

Time here is wall time (time.monotonic): a tool's waits are for DDS discovery, not a node's clock.
"""

from __future__ import annotations

import argparse
import functools
import os
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

from go2vlm.cli.args import add_dds_args

OK, WARN, FAIL = "ok", "warn", "FAIL"

# Socket receive buffers (net.core.rmem_max), measured in docs/benchmarks.md ("Large images", rgb8
# at 10 Hz between two processes on a network interface): from 4 MiB every 1920x1080 frame arrived;
# from 2 MiB every 1280x720 frame (1920x1080: 22 of 30); at 1 MiB 19 of 30 1280x720 frames, and at
# 208 KiB (a common distribution default) 3 of 30 even at 640x480.
RMEM_GOOD = 4 << 20
RMEM_LOW = 2 << 20

# GPU memory a Qwen2.5-VL needs, GB: ESTIMATES, parameters x bytes per weight (fp16/bf16 2, int8 1,
# nf4 ~0.55 with double quantisation) + ~1 GB of activations and vision tokens at 640x480.
# Parameters: 3.75 B (3B) and 8.29 B (7B), the model cards' counts. The VLM article (section 7)
# measured the 3B at ~6.7 GB fp16 and ~2.0 GB nf4 on an RTX 5060, inside these.
VLM_NEED_GB = {
    ("3b", "none"): 8.5,
    ("3b", "int8"): 4.8,
    ("3b", "nf4"): 3.1,
    ("7b", "none"): 17.6,
    ("7b", "int8"): 9.3,
    ("7b", "nf4"): 5.6,
}
GO2_NET = "192.168.123."


@dataclass
class Verdict:
    check: str
    level: str
    text: str
    fix: str = ""

    def line(self) -> str:
        fix = f"  -> fix: {self.fix}" if self.fix and self.level != OK else ""
        return f"[{self.level:>4}] {self.check}: {self.text}{fix}"


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "doctor",
        help="check the known traps (network, DDS, buffers, rendering, GPU, /cmd_vel writers)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_dds_args(p, interface_help="the interface to check (default: GO2VLM_IFACE)")
    p.add_argument("--wait", type=float, default=2.0, help="seconds of DDS discovery")
    p.add_argument("--model", choices=("3b", "7b"), default="3b", help="the Qwen2.5-VL size to check GPU memory for")
    p.add_argument("--quantization", choices=("none", "nf4", "int8"), default="none", help="as the vlm node's")
    p.add_argument("--robot", default=None, metavar="IP", help="also check a Go2 over WebRTC at this address")
    p.add_argument("--robot-port", type=int, default=9991, help="its signalling port (9991; the sim's --webrtc port)")
    p.add_argument("--aes-key-file", default="", metavar="FILE",
                   help="a file holding the robot's AES-128 key (32 hex chars; else env GO2VLM_AES_KEY), "
                   "firmware >= 1.1.15")  # fmt: skip
    p.add_argument("--skip", action="append", default=[], metavar="CHECK", help="skip a check (e.g. render, torch)")
    p.set_defaults(func=run)


# -- network -------------------------------------------------------------------------------------
def ipv4_of(iface: str) -> str | None:
    """The interface's IPv4 address (SIOCGIFADDR), or None."""
    import fcntl

    siocgifaddr = 0x8915
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            raw = fcntl.ioctl(s.fileno(), siocgifaddr, struct.pack("256s", iface.encode()[:15]))
        except OSError:
            return None
    return socket.inet_ntoa(raw[20:24])


def is_up(iface: str) -> bool:
    try:
        with open(f"/sys/class/net/{iface}/flags") as f:
            flags = int(f.read().strip(), 16)
    except (OSError, ValueError):
        return False
    return bool(flags & 0x1)  # IFF_UP


def interfaces() -> list[str]:
    try:
        return [name for _, name in socket.if_nameindex()]
    except OSError:
        return []


def check_interface(iface: str | None) -> Verdict:
    known = interfaces()
    go2 = [f"{n} {a}" for n in known if (a := ipv4_of(n)) and a.startswith(GO2_NET)]
    on_go2 = f"; Go2 network on {', '.join(go2)}" if go2 else ""
    if not iface:
        return Verdict(
            "interface",
            WARN,
            f"none set: Cyclone picks the machine's default interface{on_go2}",
            "set GO2VLM_IFACE=lo (or --interface lo) for a local sim, the wired interface (e.g. enp3s0) for a Go2",
        )
    if known and iface not in known:
        return Verdict(
            "interface", FAIL, f"{iface!r} does not exist; this machine has {', '.join(known)}", "pick one of those"
        )
    if not is_up(iface):
        return Verdict("interface", FAIL, f"{iface} is down", f"sudo ip link set {iface} up")
    addr = ipv4_of(iface)
    if addr is None:
        return Verdict("interface", FAIL, f"{iface} is up but has no IPv4 address", f"sudo ip addr add ... dev {iface}")
    if iface == "lo":
        return Verdict("interface", OK, f"lo is up ({addr}): a local sim only, never a real Go2{on_go2}")
    if not addr.startswith(GO2_NET):
        return Verdict(
            "interface",
            WARN,
            f"{iface} is up with {addr}, not on the Go2's 192.168.123.x network",
            f"for a Go2: sudo ip addr add 192.168.123.99/24 dev {iface}, then ping 192.168.123.161",
        )
    return Verdict("interface", OK, f"{iface} is up with {addr}, on the Go2's network")


# -- DDS -----------------------------------------------------------------------------------------
def check_domain(domain_id: int | None) -> tuple[Verdict, int | None]:
    from go2vlm.bus import ParamError, domain_id_from_env

    try:
        did = domain_id_from_env() if domain_id is None else domain_id
    except ParamError as exc:
        return Verdict("domain", FAIL, str(exc), "export ROS_DOMAIN_ID=0 (a Go2 speaks on 0)"), None
    if not 0 <= did <= 232:
        return Verdict("domain", FAIL, f"{did} is outside 0..232", "use 0..101"), None
    if did > 101:
        return Verdict(
            "domain", WARN, f"{did}: above 101 its ports may collide with the kernel's ephemeral ports", "use 0..101"
        ), did
    note = " (the Go2's)" if did == 0 else "; a Go2 speaks on 0 only"
    return Verdict("domain", OK, f"ROS_DOMAIN_ID {did}{note}"), did


def check_peers(wait_s: float) -> tuple[Verdict, Verdict]:
    """Other participants on the domain, and the writers of /cmd_vel."""
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsParticipant, BuiltinTopicDcpsPublication

    from go2vlm.bus import discovery_info, domain
    from go2vlm.bus.topics import CMD_VEL

    cmd_vel = domain.dds_topic_name(CMD_VEL.name)
    dp = domain.participant()
    names = discovery_info.directory(dp)
    parts = BuiltinDataReader(dp, BuiltinTopicDcpsParticipant)
    pubs = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
    others: set[str] = set()
    writers: dict[str, str] = {}  # /cmd_vel writer GUID -> participant GUID
    deadline = time.monotonic() + wait_s
    while True:
        for s in parts.take(N=256):
            if hasattr(s, "key") and s.key != dp.guid:
                others.add(str(s.key))
        for ep in pubs.take(N=256):
            if getattr(ep, "topic_name", None) == cmd_vel and ep.participant_key != dp.guid:
                writers[str(ep.key)] = str(ep.participant_key)
        if time.monotonic() >= deadline:
            break
        time.sleep(0.05)
    nodes = sorted({n for p in others for n in names.nodes_in(p)})
    shown = ", ".join(nodes[:12]) + (" ..." if len(nodes) > 12 else "")
    peers = Verdict(
        "peers",
        OK,
        f"{len(others)} other participant(s) on the domain" + (f": {shown}" if nodes else ""),
    )
    described = [f"{names.node_of(g) or 'an unnamed node'} (participant {p}, writer {g})" for g, p in writers.items()]
    if len(writers) > 1:
        cmd = Verdict(
            "cmd_vel",
            FAIL,
            f"{len(writers)} writers on /cmd_vel: {'; '.join(sorted(described))}",
            "only the safety gate may write /cmd_vel: stop the others (the robot refuses to drive meanwhile)",
        )
    elif writers:
        cmd = Verdict("cmd_vel", OK, f"one writer on /cmd_vel: {described[0]}")
    else:
        cmd = Verdict("cmd_vel", OK, "no writer on /cmd_vel")
    return peers, cmd


def check_rcvbuf() -> Verdict:
    from go2vlm.bus.domain import RCVBUF_REQUEST, kernel_rmem_max

    rmem = kernel_rmem_max()
    fix = f"sudo sysctl -w net.core.rmem_max={RCVBUF_REQUEST} (and in /etc/sysctl.d/ to keep it)"
    if rmem is None:
        return Verdict("rcvbuf", WARN, "cannot read net.core.rmem_max (not Linux?)", fix)
    have = f"net.core.rmem_max is {rmem / 2**20:.2f} MiB (go2vlm asks for {RCVBUF_REQUEST >> 20} MiB)"
    if rmem >= RCVBUF_REQUEST:
        return Verdict("rcvbuf", OK, have)
    if rmem >= RMEM_GOOD:
        return Verdict("rcvbuf", WARN, f"{have}: enough for 1920x1080 rgb8 at 10 Hz, not for larger frames", fix)
    if rmem >= RMEM_LOW:
        return Verdict("rcvbuf", WARN, f"{have}: 1280x720 frames arrive, 1920x1080 ones are partly lost", fix)
    return Verdict("rcvbuf", FAIL, f"{have}: camera frames are lost between processes (even 640x480 at 208 KiB)", fix)


# -- rendering and the GPU -------------------------------------------------------------------------
_RENDER_PROBE = """
import go2vlm.sim  # picks MUJOCO_GL before mujoco is imported
import mujoco, os
m = mujoco.MjModel.from_xml_string("<mujoco><worldbody><light pos='0 0 1'/><geom size='.1'/></worldbody></mujoco>")
r = mujoco.Renderer(m, 32, 32)
r.update_scene(mujoco.MjData(m))
r.render()
print(os.environ.get("MUJOCO_GL", "?"))
"""


def check_render() -> Verdict:
    try:
        import mujoco  # noqa: F401
    except ImportError:
        return Verdict("render", WARN, "MuJoCo is not installed: no sim", "pip install 'go2vlm[sim]'")
    from go2vlm.sim.gl import APT_HINT

    try:
        out = subprocess.run(
            [sys.executable, "-c", _RENDER_PROBE], capture_output=True, text=True, timeout=120, env=os.environ
        )
    except subprocess.TimeoutExpired:
        return Verdict("render", FAIL, "a 32x32 MuJoCo render did not finish in 120 s", APT_HINT)
    if out.returncode != 0:
        last = (out.stderr.strip().splitlines() or ["?"])[-1][:200]
        return Verdict("render", FAIL, f"MuJoCo cannot render headless: {last}", APT_HINT)
    return Verdict("render", OK, f"headless rendering works (MUJOCO_GL={out.stdout.strip()})")


def check_torch(model: str, quantization: str) -> Verdict:
    need = VLM_NEED_GB[(model, quantization)]
    what = f"Qwen2.5-VL-{model.upper()} {quantization if quantization != 'none' else 'bf16/fp16'}"
    try:
        import torch
    except ImportError:
        return Verdict(
            "torch",
            WARN,
            "torch is not installed: no local VLM",
            "pip install 'go2vlm[vlm]', or run the vlm node with backend=openai against a server",
        )
    if not torch.cuda.is_available():
        return Verdict(
            "torch",
            WARN,
            f"torch {torch.__version__}, no CUDA GPU: a local {what} runs on the CPU (seconds to minutes per frame)",
            "use a GPU machine, or backend=openai with a server that has one",
        )
    free, total = torch.cuda.mem_get_info()
    name = torch.cuda.get_device_name()
    have = f"{name}: {free / 1e9:.1f} of {total / 1e9:.1f} GB free; {what} needs ~{need:g} GB (estimate)"
    if free / 1e9 >= need:
        return Verdict("torch", OK, have)
    smaller = [f"{m.upper()} {q}" for (m, q), gb in VLM_NEED_GB.items() if gb <= free / 1e9]
    fix = f"fits: {', '.join(smaller)}" if smaller else "free GPU memory, or backend=openai with a bigger GPU"
    return Verdict("torch", FAIL, f"{have}: it will run out of memory", fix)


def run(args: argparse.Namespace) -> int:
    if not args.wait >= 0:
        print("go2vlm doctor: --wait must not be negative", file=sys.stderr)
        return 2
    iface = args.interface or os.environ.get("GO2VLM_IFACE") or None
    if args.interface:
        os.environ["GO2VLM_IFACE"] = args.interface
    if args.domain is not None:
        os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    verdicts: list[Verdict] = []

    def add(check: str, fn: Callable[[], Verdict]) -> None:
        if check in args.skip:
            return
        v = fn()
        verdicts.append(v)
        print(v.line(), flush=True)

    add("interface", lambda: check_interface(iface))
    dom, did = check_domain(None)
    if "domain" not in args.skip:
        verdicts.append(dom)
        print(dom.line(), flush=True)
    add("rcvbuf", check_rcvbuf)
    dds_ok = did is not None and not any(v.check == "interface" and v.level == FAIL for v in verdicts)
    if dds_ok and not {"peers", "cmd_vel"} <= set(args.skip):
        peers, cmd = check_peers(args.wait)
        for v in (peers, cmd):
            if v.check not in args.skip:
                verdicts.append(v)
                print(v.line(), flush=True)
    add("render", check_render)
    add("torch", lambda: check_torch(args.model, args.quantization))
    if args.robot:
        from go2vlm.robots.go2.protocol import AES_KEY_ENV
        from go2vlm.robots.go2.webrtc.probe import probe
        from go2vlm.secret import read_secret

        key = read_secret(AES_KEY_ENV, args.aes_key_file, "--aes-key-file")
        for check, level, text, fix in probe(args.robot, args.robot_port, key):
            add(f"webrtc.{check}", functools.partial(Verdict, f"webrtc.{check}", level, text, fix))
    failed = [v.check for v in verdicts if v.level == FAIL]
    warned = [v.check for v in verdicts if v.level == WARN]
    if failed:
        print(f"go2vlm doctor: {len(failed)} check(s) failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    print(f"go2vlm doctor: all checks pass{f' ({len(warned)} warning(s))' if warned else ''}")
    return 0
