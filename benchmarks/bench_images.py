"""Large images between two processes: how many rgb8 frames at 10 Hz arrive, best-effort and reliable.

    python benchmarks/bench_images.py                                   # 640x480, 1280x720, 1920x1080
    python benchmarks/bench_images.py --sizes 1280x720 --frames 50
    python benchmarks/bench_images.py --cyclone-defaults                # Cyclone's own buffers, for comparison
    python benchmarks/bench_images.py --request 212992                  # as if net.core.rmem_max were 208 KiB

This process reads `/bench/images` with a best-effort reader (QOS_SENSOR, what perception uses),
then in a second run with a reliable one (QOS_DEFAULT); each time a child process publishes
numbered frames with QOS_IMAGE (the camera nodes' profile; reliable, so both readers match) at
`--rate`. A frame counts when its number arrives. `--cyclone-defaults` puts Cyclone's own defaults
(a 1 MiB socket receive buffer request, WhcHigh 500 kB) in CYCLONEDDS_URI, which wins over
go2vlm's (bus/domain.py). The kernel's net.core.rmem_max caps what any request gets; it is printed
with the results. Without GO2VLM_IFACE Cyclone picks the machine's default interface (multicast,
IP fragments past the MTU), where losses show first; with GO2VLM_IFACE=lo the frames stay on loopback.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

from go2vlm.bus import QOS_DEFAULT, QOS_SENSOR, Node
from go2vlm.bus.domain import kernel_rmem_max
from go2vlm.msgs.sensor_msgs import Image

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root: testing_support/ (dev-only)
from testing_support.image_frames import send_frames  # noqa: E402

TOPIC = "/bench/images"
CYCLONE_DEFAULTS = (
    '<CycloneDDS><Domain id="any"><Internal><SocketReceiveBufferSize min="default" max="default"/>'
    "<Watermarks><WhcHigh>500kB</WhcHigh></Watermarks></Internal></Domain></CycloneDDS>"
)


READERS = {"best_effort": QOS_SENSOR, "reliable": QOS_DEFAULT}


def arrived(width: int, height: int, frames: int, rate: float, reader: str) -> int:
    """Frames that reach one reader of kind `reader` (alone in its process: a reliable reader beside
    it would have its repairs delivered to the best-effort one too)."""
    got: set[int] = set()
    node = Node(node_name=f"bench_images_{reader}")
    node.create_subscription(Image, TOPIC, lambda m: got.add(int(m.header.frame_id)), READERS[reader])
    node.start()
    cmd = [sys.executable, __file__, "--publish", f"{width}x{height}", "--frames", str(frames), "--rate", str(rate)]
    subprocess.run(cmd, check=True, env=os.environ)
    time.sleep(0.5)
    node.shutdown()
    return len(got)


def measure(width: int, height: int, frames: int, rate: float) -> dict[str, object]:
    row: dict[str, object] = {"size": f"{width}x{height}", "frame_mb": round(width * height * 3 / 1e6, 2)}
    row["frames"] = frames
    for reader in READERS:
        row[reader] = arrived(width, height, frames, rate, reader)
    return row


def parse_size(text: str) -> tuple[int, int]:
    w, _, h = text.partition("x")
    return int(w), int(h)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="640x480,1280x720,1920x1080")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--rate", type=float, default=10.0)
    ap.add_argument("--cyclone-defaults", action="store_true", help="Cyclone's own buffer sizes instead of ours")
    ap.add_argument(
        "--request", type=int, default=None, help="ask for this socket receive buffer (bytes): a lower kernel limit"
    )
    ap.add_argument("--json", default=None, help="also write the results here")
    ap.add_argument("--publish", default=None, help=argparse.SUPPRESS)  # the child process
    args = ap.parse_args()
    if args.publish:
        send_frames(TOPIC, *parse_size(args.publish), args.frames, args.rate, 10.0, "bench_images_pub")
        return
    config = "go2vlm"
    if args.cyclone_defaults:
        os.environ["CYCLONEDDS_URI"] = CYCLONE_DEFAULTS
        config = "Cyclone defaults"
    elif args.request:
        # Linux grants min(request, rmem_max) (and doubles it for bookkeeping): asking for less than
        # the limit behaves as a machine whose limit is that low.
        os.environ["CYCLONEDDS_URI"] = (
            '<CycloneDDS><Domain id="any"><Internal>'
            f'<SocketReceiveBufferSize min="default" max="{args.request}B"/></Internal></Domain></CycloneDDS>'
        )
        config = f"go2vlm, buffer request {args.request} B"
    rows = [measure(*parse_size(s), args.frames, args.rate) for s in args.sizes.split(",")]
    rmem = kernel_rmem_max()
    iface = os.environ.get("GO2VLM_IFACE") or "default interface"
    print(f"net.core.rmem_max = {rmem} bytes; config: {config}; interface: {iface}")
    print("| size | MB/frame | frames sent | best-effort arrived | reliable arrived |")
    print("|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['size']} | {r['frame_mb']} | {r['frames']} | {r['best_effort']} | {r['reliable']} |")
    if args.json:
        Path(args.json).write_text(json.dumps({"rmem_max": rmem, "rows": rows}, indent=2))


if __name__ == "__main__":
    main()
