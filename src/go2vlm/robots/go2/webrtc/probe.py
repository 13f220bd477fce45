"""What can be checked of a Go2's WebRTC route from the user's side (`go2vlm doctor --robot IP`): the
robot answers, its signalling port and protocol, whether another client (the Unitree app) holds the
connection, and its firmware version. Each check is (name, level, text, fix); level ok | warn | FAIL.

The last two checks connect for a moment, as the app does; a robot held by another client answers
"reject", and nothing is commanded.
"""

from __future__ import annotations

from typing import Any

from go2vlm.robots.go2 import protocol as p

Check = tuple[str, str, str, str]
OK, WARN, FAIL = "ok", "warn", "FAIL"


def probe(ip: str, port: int = p.SIGNAL_PORT, aes_key: str = "", timeout_s: float = 10.0) -> list[Check]:
    from go2vlm.robots.go2.webrtc import codec
    from go2vlm.robots.go2.webrtc.link import LinkError, LinkSettings, _post, port_open

    out: list[Check] = []
    new, legacy = port_open(ip, port), port_open(ip, p.LEGACY_SIGNAL_PORT)
    if not new and not legacy:
        fix = "check the IP (the Unitree app shows it), that the robot is on and on this network"
        return [("robot", FAIL, f"nothing answers at {ip} on ports {port} or {p.LEGACY_SIGNAL_PORT}", fix)]
    out.append(("robot", OK, f"{ip} answers on port {port if new else p.LEGACY_SIGNAL_PORT}", ""))
    if new:
        try:
            text = _post(f"http://{ip}:{port}/con_notify", b"", 5.0, "application/json")
            settings = LinkSettings(ip=ip, port=port, aes_key=aes_key)
            _, _, seal = codec.parse_con_notify(text, settings.device_key())
        except (LinkError, codec.SignalError) as exc:
            upgrade = "a newer go2vlm, or report the firmware version"
            key = "set GO2VLM_AES_KEY or pass --aes-key-file"
            return [*out, ("signalling", FAIL, str(exc), key if "aes" in str(exc).lower() else upgrade)]
        what = {1: "plain", 2: "the app's key (firmware 1.1.1-1.1.14)", 3: "the robot's own key (firmware >= 1.1.15)"}
        out.append(("signalling", OK, f"con_notify on {port}, key sealed with {what[seal]} (data2={seal})", ""))
    else:
        out.append(("signalling", WARN, f"only the legacy port {p.LEGACY_SIGNAL_PORT}: firmware older than 1.1.x", ""))
    try:
        import aiortc  # noqa: F401
    except ImportError:
        fix = "pip install 'go2vlm[webrtc]'"
        return [*out, ("connection", WARN, "aiortc is not installed: cannot try the connection", fix)]
    return out + _connect(ip, port, aes_key, timeout_s)


def _connect(ip: str, port: int, aes_key: str, timeout_s: float) -> list[Check]:
    import threading

    from go2vlm.robots.go2.webrtc.link import Go2Link, LinkError, LinkSettings, RobotBusy

    firmware: dict[str, Any] = {}
    got = threading.Event()

    def on_message(msg: dict[str, Any], _: bytes | None) -> None:
        if msg.get("type") == "firmware":
            firmware.update(version=msg.get("data"), code=msg.get("code"))
            got.set()

    link = Go2Link(
        LinkSettings(ip=ip, port=port, aes_key=aes_key, timeout_s=timeout_s),
        on_message=on_message,
        on_link=lambda up, reason: None,
    )
    try:
        link.connect_first()
    except RobotBusy:
        return [
            ("connection", FAIL, "another WebRTC client holds the robot", "close the Unitree app (or other client)")
        ]
    except LinkError as exc:
        return [("connection", FAIL, str(exc), "see docs/real_robot.md#troubleshooting")]
    try:
        got.wait(5.0)
    finally:
        link.stop()
    out: list[Check] = [("connection", OK, "WebRTC connected and validated; no other client held it", "")]
    version = firmware.get("version")
    if not version:
        return [*out, ("firmware", WARN, f"the robot did not say its version (code {firmware.get('code')})", "")]
    note = p.firmware_note(str(version))
    if note is None:
        tested = "the go2vlm simulator" if version == p.SIM_FIRMWARE else "tested"
        return [*out, ("firmware", OK, f"{version} ({tested})", "")]
    return [*out, ("firmware", WARN, note, "report how it went: docs/real_robot.md")]
