"""Parameter services benchmark: get/set round trips to a follower node in another process, and what
serving them costs each node at start-up.

    python benchmarks/bench_params.py                    # 500 round trips each
    python benchmarks/bench_params.py --calls 2000

The follower runs as `go2vlm run follower` on a private loopback domain; the client is
go2vlm.bus.param_services.ParameterClient (what `go2vlm param` uses), one request at a time.
"""

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import time

from go2vlm.bus import domain
from go2vlm.bus.param_services import ParameterClient, python_to_value


def percentile(xs: list[float], q: float) -> float:
    xs = sorted(xs)
    return xs[min(len(xs) - 1, int(q * len(xs)))]


def round_trips(calls: int, out: dict[str, object]) -> None:
    env = dict(os.environ, GO2VLM_IFACE="lo")
    node = subprocess.Popen([sys.executable, "-m", "go2vlm", "run", "follower"], env=env, stderr=subprocess.DEVNULL)
    try:
        with ParameterClient("follower", timeout_s=30) as client:
            client.list()  # discovery, once
            for what in ("get", "set"):
                times = []
                for i in range(calls):
                    t = time.perf_counter()
                    if what == "get":
                        client.get(["kp_angular"])
                    else:
                        (r,) = client.set({"kp_angular": python_to_value(0.5 + 0.1 * (i % 2))})
                        assert r.successful, r.reason
                    times.append((time.perf_counter() - t) * 1000)
                out[what] = {"calls": calls, "median_ms": statistics.median(times), "p99_ms": percentile(times, 0.99)}
                print(
                    f"{what}: {calls} calls, median {statistics.median(times):.2f} ms, "
                    f"p99 {percentile(times, 0.99):.2f} ms"
                )
    finally:
        node.terminate()
        node.wait(10)


def start_cost(n: int, out: dict[str, object]) -> None:
    from go2vlm.behavior.follower_node import FollowerNode

    per_node: dict[bool, float] = {}
    for k, services in enumerate((False, True) * 2):  # the first pass warms up imports and DDS
        cpu = time.process_time()
        nodes = [FollowerNode(node_name=f"bench_{k}_{i}", parameter_services=services) for i in range(n)]
        per_node[services] = (time.process_time() - cpu) / n * 1000
        for node in nodes:
            node.shutdown()
    without, with_ = per_node[False], per_node[True]
    out["startup_cpu_ms"] = {"without_services": without, "with_services": with_}
    print(f"start-up CPU per node: {without:.1f} ms without, {with_:.1f} ms with the parameter services")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--calls", type=int, default=500)
    ap.add_argument("--nodes", type=int, default=10, help="nodes per start-up cost pass")
    ap.add_argument("--json", default=None, help="also write the results here")
    args = ap.parse_args()
    out: dict[str, object] = {}
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(150, 200)))
    os.environ["GO2VLM_IFACE"] = "lo"
    domain.participant()
    round_trips(args.calls, out)
    start_cost(args.nodes, out)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
