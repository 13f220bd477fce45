"""`go2vlm record [-a | TOPIC ...] [-o DIR] [--duration S]`: record topics into a rosbag2 bag (MCAP)."""

from __future__ import annotations

import argparse
import sys
import time
from typing import TYPE_CHECKING

from go2vlm.bus import ParamError, ShutdownRequested
from go2vlm.cli.args import add_dds_args

if TYPE_CHECKING:
    from go2vlm.apps.bag.recorder_node import TopicStats


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "record",
        help="record topics into a rosbag2 bag (MCAP), like `ros2 bag record`",
        description=(
            "Record topics into a rosbag2 bag: a folder with metadata.yaml and an MCAP file, readable by "
            "`ros2 bag info/play`, Foxglove and rosbags. The serialized samples are stored exactly as they "
            "came off the wire. Ctrl-C, SIGTERM or --duration stop it with a complete bag."
        ),
    )
    p.add_argument("topics", nargs="*", metavar="TOPIC", help="topics to record")
    p.add_argument("-a", "--all", action="store_true", help="record every topic whose type go2vlm knows")
    p.add_argument("-o", "--output", default=None, help="bag folder to create (default rosbag2_<date>-<time>)")
    p.add_argument("-x", "--exclude", action="append", default=[], metavar="TOPIC", help="do not record TOPIC")
    p.add_argument("--duration", type=float, default=None, help="stop after S seconds")
    p.add_argument("--compression", choices=("none", "zstd", "lz4"), default="none", help="MCAP chunk compression")
    p.add_argument("--queue-depth", type=int, default=500, help="reader queue per topic (default 500)")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no live per-topic table")
    add_dds_args(p)
    p.set_defaults(func=run)


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB"):
        if n < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} GB"


class Progress:
    """Messages and bytes per topic: a table redrawn in place on a terminal, a line now and then
    otherwise."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled
        self.tty = sys.stderr.isatty()
        self.lines = 0
        self.last: dict[str, tuple[int, float]] = {}
        self.t0 = time.monotonic()
        self.next_line = self.t0 + 5.0

    def show(self, stats: list[TopicStats], force: bool = False) -> None:
        if not self.enabled:
            return
        now = time.monotonic()
        if not self.tty and not force and now < self.next_line:
            return
        self.next_line = now + 5.0
        rows = []
        total_n = total_b = 0
        for s in sorted(stats, key=lambda s: s.topic):
            n0, t0 = self.last.get(s.topic, (0, self.t0))
            rate = (s.messages - n0) / max(1e-3, now - t0)
            self.last[s.topic] = (s.messages, now)
            total_n += s.messages
            total_b += s.bytes
            rows.append(f"  {s.topic:<32} {s.messages:>8} msgs {_size(s.bytes):>10} {rate:7.1f} Hz  {s.type}")
        head = f"recording: {now - self.t0:6.1f} s, {total_n} messages, {_size(total_b)}"
        if not self.tty:
            print(head, file=sys.stderr, flush=True)
            return
        out = []
        if self.lines:
            out.append(f"\x1b[{self.lines}F\x1b[J")
        out.append("\n".join([head, *rows]) + "\n")
        sys.stderr.write("".join(out))
        sys.stderr.flush()
        self.lines = 1 + len(rows)


def run(args: argparse.Namespace) -> int:
    from go2vlm.apps.bag.bagfile import BagError
    from go2vlm.apps.bag.recorder import BagRecorder

    if args.all and args.topics:
        print("go2vlm record: give topics or -a/--all, not both", file=sys.stderr)
        return 2
    if not args.all and not args.topics:
        print("go2vlm record: give topics to record, or -a/--all for every topic", file=sys.stderr)
        return 2
    if args.duration is not None and not args.duration > 0:
        print("go2vlm record: --duration must be positive", file=sys.stderr)
        return 2
    topics = [t if t.startswith("/") else "/" + t for t in args.topics]
    stop = ShutdownRequested()
    stop.install()
    try:
        rec = BagRecorder(
            args.output or "",
            topics,
            all_topics=args.all,
            exclude=[t if t.startswith("/") else "/" + t for t in args.exclude],
            domain_id=args.domain,
            interface=args.interface,
            compression=args.compression,
            queue_depth=args.queue_depth,
        )
    except (BagError, ParamError) as exc:
        print(f"go2vlm record: {exc}", file=sys.stderr)
        return 2
    print(f"go2vlm record: writing {rec.out}/ (Ctrl-C stops)", file=sys.stderr, flush=True)
    progress = Progress(args.progress)
    rec.start()
    t0 = time.monotonic()
    period = 1.0 if progress.tty else 0.2
    try:
        while True:
            left = None if args.duration is None else args.duration - (time.monotonic() - t0)
            if (left is not None and left <= 0) or stop.event.wait(period if left is None else min(period, left)):
                break
            progress.show(rec.stats())
    finally:
        result = rec.stop()
    progress.show(result.topics, force=True)
    print(
        f"go2vlm record: {result.messages} messages on {len(result.topics)} topics in {result.out}/",
        file=sys.stderr,
    )
    return 0
