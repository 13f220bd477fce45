"""`go2vlm node list [-v]`: the nodes on the bus, ours and ROS 2's, as `ros2 node list` shows them;
`-v` adds each node's topics and services (our nodes serve the parameter services).

Read from `ros_discovery_info`, which every ROS 2 process (and every go2vlm process) publishes.

Time here is wall time (time.monotonic): a tool's deadlines, rates and waits are for the person at
the terminal and for DDS discovery, not a node's clock.
"""

from __future__ import annotations

import argparse
import time

from go2vlm.cli.args import non_negative


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser("node", help="list nodes (like `ros2 node list`)")
    verbs = p.add_subparsers(dest="verb", metavar="VERB", required=True)
    ls = verbs.add_parser("list", help="nodes seen on the bus")
    ls.add_argument("--wait", type=non_negative, default=1.5, help="discovery time in seconds")
    ls.add_argument("-v", "--verbose", action="store_true", help="also show each node's topics")
    ls.set_defaults(func=cmd_list)


def cmd_list(args: argparse.Namespace) -> int:
    from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription

    from go2vlm.bus import discovery_info, domain

    dp = domain.participant()
    directory = discovery_info.directory(dp)
    pubs = BuiltinDataReader(dp, BuiltinTopicDcpsPublication)
    subs = BuiltinDataReader(dp, BuiltinTopicDcpsSubscription)
    topics: dict[bytes, str] = {}
    deadline = time.monotonic() + args.wait
    while True:
        directory.announcements()
        for r in (pubs, subs):
            for ep in r.take(N=256):
                if isinstance(getattr(ep, "topic_name", None), str):
                    topics[ep.key.bytes] = ep.topic_name
        if time.monotonic() >= deadline:
            break
        time.sleep(0.05)
    rows = []
    for info in directory.announcements():
        for n in info.node_entities_info_seq:
            full = discovery_info.full_name(n.node_namespace, n.node_name)
            rows.append(
                (
                    full,
                    [topics.get(g.to_bytes(), "?") for g in n.reader_gid_seq],
                    [topics.get(g.to_bytes(), "?") for g in n.writer_gid_seq],
                )
            )
    for full, readers, writers in sorted(rows):
        print(full)
        if args.verbose:
            # As `ros2 node info` sorts them: a service is its request reader (rq/<name>Request, with
            # a reply writer beside it), a client its reply reader (rr/<name>Reply).
            servers = [n[2 : -len("Request")] for n in readers if n.startswith("rq/") and n.endswith("Request")]
            clients = [n[2 : -len("Reply")] for n in readers if n.startswith("rr/") and n.endswith("Reply")]
            sections = [
                ("Subscribers", [n for n in readers if not n.startswith(("rq/", "rr/"))]),
                ("Publishers", [n for n in writers if not n.startswith(("rq/", "rr/"))]),
                ("Service Servers", servers),
                ("Service Clients", clients),
            ]
            for title, names in sections:
                if names or title in ("Subscribers", "Publishers"):
                    print(f"  {title}:")
                for name in sorted(names):
                    print(f"    {name[2:] if name.startswith('rt/') else name}")
    return 0
