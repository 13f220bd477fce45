"""One DDS participant per process, configured like a ROS 2 process.

- Domain: `ROS_DOMAIN_ID` (default 0), or an explicit id.
- Memory: large frames are allocated and freed at camera rate; glibc would hand each one back to the
  kernel and fault in fresh zeroed pages for the next (2 ms of CPU per 640x480 frame on the
  receiving side). `tune_malloc` keeps them in the heap instead; `GO2VLM_MALLOC_TUNE=0` opts out.
- A domain of one's own: `claim_free_domain` finds a domain that no other go2vlm process has
  claimed and no participant on this host speaks on, and holds it while the process lives (test
  sessions and `go2vlm eval` workers use it so that parallel runs never hear each other).
- Network interface: `GO2VLM_IFACE` or the `interface` argument (`lo` for a local sim, the robot's
  interface such as `eth0` or `enp3s0` for a real Go2).
- Socket receive buffer: a camera frame is hundreds of UDP datagrams sent in one burst (1280x720 rgb8
  is 2.8 MB); when the kernel's socket buffer overflows before Cyclone's receive thread drains it, a
  best-effort reader loses the whole frame and a reliable one waits for repairs. Every participant
  asks for `RCVBUF_REQUEST` (Cyclone's default is 1 MiB); the kernel grants at most
  `net.core.rmem_max` (`go2vlm doctor` compares the two and prints the sysctl). Reliable writers may
  also hold a whole frame unacknowledged (`WhcHigh`) instead of blocking on Cyclone's 500 kB default.
- Configuration (Cyclone merges the parts; a later one wins): our defaults above, then either the
  interface binding, when an interface is given, or else the user's `CYCLONEDDS_URI`, so the VLM
  article's setup (its CYCLONEDDS_URI with `lo`) keeps working and any setting in it wins over ours.
"""

from __future__ import annotations

import os
import random
import re
import socket
import tempfile
import threading
import time
from collections.abc import Collection
from pathlib import Path
from typing import Any

from cyclonedds.core import DDSException
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.topic import Topic

from go2vlm.bus.params import ParamError

_lock = threading.Lock()
_participants: dict[int, tuple[DomainParticipant, Domain | None]] = {}
_topics: dict[tuple[int, str, str], Topic[Any]] = {}

_IFACE_RE = re.compile(r"^[A-Za-z0-9_.:\-]{1,32}$")


def domain_id_from_env() -> int:
    raw = os.environ.get("ROS_DOMAIN_ID", "0").strip() or "0"
    try:
        value = int(raw)
    except ValueError:
        raise ParamError(f"ROS_DOMAIN_ID={raw!r} is not an integer (0..232)") from None
    if not 0 <= value <= 232:
        raise ParamError(f"ROS_DOMAIN_ID={value} is outside 0..232")
    return value


# What every participant asks the kernel for (see the module docstring and docs/bus.md for the
# figures): enough for a 1920x1080 rgb8 frame in one burst. The kernel caps it at net.core.rmem_max.
RCVBUF_REQUEST = 16 << 20
# Unacknowledged bytes a reliable writer keeps before it blocks: more than one 1920x1080 rgb8 frame.
WHC_HIGH = 16 << 20


def cyclone_config(interface: str) -> str:
    """Cyclone XML that binds to one interface, as the VLM article's CYCLONEDDS_URI does with `lo`."""
    if not _IFACE_RE.match(interface):
        raise ParamError(f"network interface {interface!r} is not a valid interface name")
    return (
        '<CycloneDDS><Domain id="any"><General><Interfaces>'
        f'<NetworkInterface name="{interface}" priority="default" multicast="default"/>'
        "</Interfaces></General></Domain></CycloneDDS>"
    )


def buffer_config() -> str:
    """Cyclone XML with our socket receive buffer and writer watermark (asks; accepts what it gets)."""
    return (
        '<CycloneDDS><Domain id="any"><Internal>'
        f'<SocketReceiveBufferSize min="default" max="{RCVBUF_REQUEST}B"/>'
        f"<Watermarks><WhcHigh>{WHC_HIGH}B</WhcHigh></Watermarks>"
        "</Internal></Domain></CycloneDDS>"
    )


def domain_config(interface: str | None) -> str:
    """Our defaults, then an explicit interface or else the user's CYCLONEDDS_URI (a later part wins)."""
    user = os.environ.get("CYCLONEDDS_URI", "").strip()
    extra = cyclone_config(interface) if interface else user
    return ",".join(p for p in (buffer_config(), extra) if p)


def kernel_rmem_max() -> int | None:
    """net.core.rmem_max: the most a socket receive buffer may be (None where it cannot be read)."""
    try:
        return int(open("/proc/sys/net/core/rmem_max").read().split()[0])
    except (OSError, ValueError, IndexError):
        return None


_MALLOC_TUNED = False


def tune_malloc() -> bool:
    """Reuse freed image-sized buffers instead of mmap/munmap per frame (glibc only, once per process)."""
    global _MALLOC_TUNED
    if _MALLOC_TUNED:
        return True
    if os.environ.get("GO2VLM_MALLOC_TUNE", "1").strip().lower() in ("0", "false", "no", "off"):
        return False
    if any(k in os.environ for k in ("MALLOC_MMAP_THRESHOLD_", "MALLOC_TRIM_THRESHOLD_", "GLIBC_TUNABLES")):
        return False  # the user tuned malloc already
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3
        ok = libc.mallopt(m_mmap_threshold, 32 << 20) == 1 and libc.mallopt(m_trim_threshold, 64 << 20) == 1
    except (OSError, AttributeError):  # not glibc (musl, macOS): nothing to do
        return False
    _MALLOC_TUNED = ok
    return ok


def participant(domain_id: int | None = None, interface: str | None = None) -> DomainParticipant:
    """The process-wide participant for a domain (created on first use)."""
    did = domain_id_from_env() if domain_id is None else domain_id
    iface = interface or os.environ.get("GO2VLM_IFACE") or None
    with _lock:
        if did in _participants:
            return _participants[did][0]
        if not 0 <= did <= 232:
            raise ParamError(f"DDS domain {did} is outside 0..232")
        dom = _domain(did, iface)
        dp = DomainParticipant(did)
        tune_malloc()
        _participants[did] = (dp, dom)
        return dp


def _interfaces() -> list[str]:
    try:
        return [name for _, name in socket.if_nameindex()]
    except OSError:
        return []


def _domain(did: int, iface: str | None) -> Domain:
    """Cyclone with our configuration (bound to `iface` if given); a missing interface or a broken
    CYCLONEDDS_URI is a clear ParamError (a ValueError), not a bare DDS_RETCODE_ERROR."""
    config = domain_config(iface)
    known = _interfaces()
    hint = f"; this machine has: {', '.join(known)}" if known else ""
    if iface and known and iface not in known and not re.match(r"^\d+\.\d+\.\d+\.\d+$", iface):
        raise ParamError(f"network interface {iface!r} does not exist (GO2VLM_IFACE / --interface){hint}")
    try:
        return Domain(did, config)
    except DDSException as exc:
        if iface:
            raise ParamError(f"cannot start DDS on network interface {iface!r}: {exc}{hint}") from None
        raise ParamError(f"cannot start DDS (check CYCLONEDDS_URI): {exc}") from None


def topic(dp: DomainParticipant, name: str, msg_type: type) -> Topic[Any]:
    """A cached Topic, so that many nodes in one process share one DDS topic entity."""
    key = (id(dp), name, msg_type.__idl_typename__)  # type: ignore[attr-defined]  # an IdlStruct class
    with _lock:
        t = _topics.get(key)
        if t is None:
            t = Topic(dp, name, msg_type)
            _topics[key] = t
        return t


def dds_topic_name(ros_topic: str) -> str:
    """`/camera/image_raw` -> `rt/camera/image_raw` (ROS 2's DDS topic prefix)."""
    name = ros_topic.strip()
    if not name or name == "/":
        raise ValueError(f"topic name {ros_topic!r} is empty")
    if not name.startswith("/"):
        name = "/" + name
    if "//" in name or name.endswith("/") or not re.match(r"^[/A-Za-z0-9_~{}]+$", name):
        raise ValueError(f"topic name {ros_topic!r} is not a valid ROS 2 topic name")
    return "rt" + name


def ros_topic_name(dds_name: str) -> str | None:
    return dds_name[2:] if dds_name.startswith("rt/") else None


# -- a domain of one's own -----------------------------------------------------------------------
_claims: list[int] = []  # lock file descriptors held for the life of the process


def domain_in_use(domain_id: int, interface: str = "lo", wait_s: float = 0.6) -> bool:
    """True if any participant answers discovery on `domain_id` (on `interface`) within `wait_s`
    (wall seconds: a DDS discovery wait)."""
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsParticipant

    dom = Domain(domain_id, cyclone_config(interface))
    dp = DomainParticipant(domain_id)
    reader = BuiltinDataReader(dp, BuiltinTopicDcpsParticipant)
    try:
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline:
            if any(getattr(s, "key", None) != dp.guid for s in reader.take(N=64) if hasattr(s, "key")):
                return True
            time.sleep(0.05)
        return False
    finally:
        for entity in (reader, dp, dom):
            entity.__del__()  # delete now: a lingering participant would make the domain look busy


def _bindable(domain_id: int, interface: str) -> bool:
    """Can Cyclone start `domain_id` here? A domain's ports are fixed (7400 + 250 x id and up), and
    from domain 102 on they lie in the ephemeral range, where any process's UDP socket may hold one:
    Cyclone then cannot start it at all (a Ray eval task failed so, DDS_RETCODE_ERROR)."""
    try:
        Domain(domain_id, cyclone_config(interface)).__del__()
    except DDSException:
        return False
    return True


def domain_lock_dir() -> Path:
    """Where domain claims live: one lock file per domain, shared by every go2vlm process of this host."""
    return Path(os.environ.get("TMPDIR", tempfile.gettempdir())) / "go2vlm-domains"


def claim_free_domain(
    lo: int, hi: int, interface: str = "lo", seed: int | None = None, exclude: Collection[int] = ()
) -> int:
    """A DDS domain in lo..hi, not in `exclude`, that no other process holds (an flock on a file per
    domain), that Cyclone can start here (its ports free) and that no participant on this host uses;
    the claim lasts as long as this process. ParamError if none is free."""
    import fcntl

    if not 0 <= lo <= hi <= 232:
        raise ParamError(f"domain range {lo}..{hi} is outside 0..232")
    lock_dir = domain_lock_dir()
    lock_dir.mkdir(parents=True, exist_ok=True)
    candidates = [d for d in range(lo, hi + 1) if d not in exclude]
    random.Random(os.getpid() if seed is None else seed).shuffle(candidates)
    for domain_id in candidates:
        fd = os.open(lock_dir / f"{domain_id}.lock", os.O_CREAT | os.O_RDWR, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        if not _bindable(domain_id, interface) or domain_in_use(domain_id, interface):
            os.close(fd)
            continue
        _claims.append(fd)
        return domain_id
    raise ParamError(f"no free DDS domain in {lo}..{hi} on this host")
