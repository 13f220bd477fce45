"""Run one episode: its launch graph in this process, every node on sim time, one recorder, then the
metrics and the run folder.

    from go2vlm.apps.episodes import Episode, RunOptions, run_episode
    result = run_episode(Episode(world="vision_test", goal="go to the blue cylinder"), RunOptions(fast=True))
    result.metrics["success"], result.metrics["spl"]

The graph is a packaged launch YAML (launch/follow_sim.yaml, episode_<perception>.yaml, ...; see
`graph_name`) read through the launcher, with the episode's world, spawn, goal and the caller's
parameters as overrides and `use_sim_time: true` on every node. Every node runs on its own thread
(the sim on three: executor, physics, render), over DDS, as `go2vlm launch` would run it.

Time: the episode's timeout, settle time and duration are sim seconds (the nodes' time). The
runner's own deadlines (start-up, a stalled sim, a model loading) and wall_s are wall time: they are
about the host. A vlm node starts first and the rest of the graph only once its model is loaded, so
that loading weights costs no sim time (the VLM article's start order, its section 6.3).

Run folder (`RunOptions.out`), every file written atomically (temporary name, then rename):
objects.json (what the object memory remembers at the end, a memory file: `go2vlm objects --file`),
metrics.json first, then series.json (the time series behind the plot), map.npz and map.png (the
newest /map, when the graph has a map node: apps/episodes/navmap.py), plot.png, video.mp4 (after
the run, from the recording; metrics.json is then rewritten with video_frames); with `bag`, bag/ (a
rosbag2 MCAP bag of every topic, for `go2vlm play` and Foxglove). A first SIGINT or
SIGTERM ends the episode early (`interrupted`); further signals wait until metrics.json is written,
and then only skip the plot and the video.
"""

from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from go2vlm.apps.episodes.episode import Episode, graph_name, node_overrides
from go2vlm.apps.episodes.latch import refuse_if_latched
from go2vlm.apps.episodes.metrics import END_STATES, Context, compute_metrics
from go2vlm.apps.episodes.outputs import atomic, write_json
from go2vlm.apps.episodes.recorder import EpisodeRecorder, Recording
from go2vlm.bus import Node, ShutdownRequested
from go2vlm.bus.topics import MAP_ODOM

__all__ = ["EpisodeResult", "RunOptions", "cpu_by_thread", "run_episode"]

POLL_S = 0.05  # wall seconds between looks at the sim clock
STALL_S = 15.0  # wall seconds of a sim clock that stands still: the sim is stuck
NO_FRAME_S = 5.0  # sim seconds without a head-camera frame: the camera is not working


@dataclass
class RunOptions:
    """How to run an episode (none of this changes its outcome, up to the nodes' processing delays)."""

    rtf: float = 1.0  # target real-time factor
    fast: bool = False  # as fast as the host allows
    out: Path | None = None  # the run folder; None: nothing written
    video: bool = True
    plot: bool = True
    interface: str | None = None
    domain_id: int | None = None
    startup_timeout_s: float = 60.0  # wall seconds until the first /clock
    model_timeout_s: float = 900.0  # wall seconds a vlm node may take to load its model before the sim starts
    cpu: bool = False  # CPU seconds per thread (Linux /proc), for the demo's figures
    bag: bool = False  # record every topic into out/bag (needs `out`)
    foxglove: dict[str, Any] | None = None  # the Foxglove view node's parameters (port, host): live view
    refuse_latched: bool = False  # RobotLatched (exit 2) before anything starts if the robot is latched


@dataclass
class EpisodeResult:
    episode: Episode
    metrics: dict[str, Any]
    series: dict[str, Any]
    out_dir: Path | None = None
    files: dict[str, str] = field(default_factory=dict)
    recording: Recording | None = None

    @property
    def interrupted(self) -> bool:
        return bool(self.metrics.get("interrupted"))


def cpu_by_thread() -> dict[str, float]:
    """CPU seconds per live thread of this process, by thread name (Linux /proc; {} elsewhere)."""
    names = {t.native_id: t.name for t in threading.enumerate() if t.native_id is not None}
    tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
    out: dict[str, float] = {}
    try:
        tids = os.listdir("/proc/self/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/self/task/{tid}/stat") as f:
                stat = f.read()
            with open(f"/proc/self/task/{tid}/comm") as f:
                comm = f.read().strip()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        name = names.get(int(tid), f"native:{comm}")
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return out


# With odometry drift (the sim's odom_drift): the map node matches scans against its map and
# publishes the corrected pose (/map/odom, frame map); the object memory and the commander read it.
_CORRECTED: dict[str, dict[str, str | bool]] = {
    "map": {"scan_matching": True},
    "object_memory": {"odom_topic": MAP_ODOM.name, "world_frame": "map"},
    "commander": {"odom_topic": MAP_ODOM.name},
}


def episode_entries(ep: Episode, opts: RunOptions) -> list[Any]:
    """The launch entries of the episode's graph, with the episode's parameters, on sim time."""
    from go2vlm.launch.launcher import LaunchEntry, load_launch, with_overrides

    _, entries = load_launch(graph_name(ep))
    if opts.foxglove is not None:
        entries.append(LaunchEntry("view", "foxglove_view", dict(opts.foxglove)))
    overrides = node_overrides(ep, opts.rtf, opts.fast)
    drifts = any(e.kind == "sim" and overrides.get(e.name, {}).get("odom_drift", 0.0) for e in entries)
    corrected = drifts and any(e.kind == "map" for e in entries)
    for e in entries:
        extra: dict[str, str | bool] = {}
        if e.kind in ("object_memory", "map"):  # of the episode's world (their files say so)
            extra["world"] = ep.world
        if corrected:  # odometry drifts: the map corrects it, the world is read in the map's frame
            extra.update(_CORRECTED.get(e.kind, {}))
        if extra:
            overrides[e.name] = {**extra, **overrides.get(e.name, {})}
    return with_overrides(entries, overrides, every={"use_sim_time": True})


def build_graph(ep: Episode, opts: RunOptions) -> tuple[list[Node], Any]:
    """The episode's nodes (not started) and the sim node among them."""
    from go2vlm.launch.launcher import make_nodes

    entries = episode_entries(ep, opts)
    nodes = make_nodes(entries, interface=opts.interface, domain_id=opts.domain_id)
    sim = next(n for n, e in zip(nodes, entries, strict=True) if e.kind == "sim")
    return nodes, sim


def _save_memories(nodes: list[Node], out: Path, files: dict[str, str]) -> None:
    """What each object memory of the graph remembers at the end, as a memory file in the run folder
    (`go2vlm objects --file out/objects.json`)."""
    if "go2vlm.world.object_memory_node" not in sys.modules:
        return  # no object memory in this graph
    from go2vlm.world.object_memory_node import ObjectMemoryNode

    for n in nodes:
        if isinstance(n, ObjectMemoryNode):
            name = "objects.json" if n.node_name == n.name else f"objects-{n.node_name}.json"
            try:
                n.save(out / name, overwrite=True)  # the run folder is the runner's own
            except OSError as exc:
                print(f"go2vlm: {name} not written: {exc}", file=sys.stderr)
            else:
                files["objects"] = str(out / name)


def _start_models_first(nodes: list[Node], stop: ShutdownRequested, timeout_s: float) -> list[Node]:
    """Start the graph's vlm nodes and wait (wall time) until each has loaded its model, so that the
    episode's sim time starts with a model that can answer (the VLM article's start order, section
    6.3: the model first); the other nodes, to be started next. RuntimeError when a model fails to
    load or takes longer than `timeout_s`."""
    if "go2vlm.perception.vlm.vlm_node" not in sys.modules:
        return nodes  # no vlm node in this graph (the module is imported only to build one)
    from go2vlm.perception.vlm.vlm_node import VlmNode

    models = [n for n in nodes if isinstance(n, VlmNode)]
    for n in models:
        n.start()
    deadline = time.monotonic() + timeout_s
    while any(n.state == "loading" for n in models) and not stop.event.is_set():
        if time.monotonic() > deadline:
            raise RuntimeError(f"the vlm node has not loaded its model in {timeout_s:g} s")
        stop.event.wait(POLL_S)
    failed = [n for n in models if n.state == "error"]
    if failed:
        raise RuntimeError(f"the vlm node cannot run: {failed[0].last_error}")
    return [n for n in nodes if n not in models]


def _sim_clock(stop: ShutdownRequested, rec: EpisodeRecorder, wall0: float, timeout_s: float) -> Iterator[float]:
    """The newest sim time every POLL_S (once the sim is up) until `stop`; RuntimeError when no
    /clock came within `timeout_s` (wall) or sim time stood still for STALL_S (wall)."""
    last, changed = -1.0, time.monotonic()
    while not stop.event.wait(POLL_S):
        t = rec.sim_time
        if t < 0:
            if time.monotonic() - wall0 > timeout_s:
                raise RuntimeError(f"the sim published no /clock within {timeout_s:g} s")
            continue
        if t != last:
            last, changed = t, time.monotonic()
        elif time.monotonic() - changed > STALL_S:
            raise RuntimeError(f"sim time stopped at {t:.1f} s (see the sim's log above)")
        yield t


def run_episode(
    ep: Episode,
    opts: RunOptions,
    stop: ShutdownRequested | None = None,
    on_tick: Callable[[float, EpisodeRecorder, Any], None] | None = None,
) -> EpisodeResult:
    """Run `ep` until its goal ends (+ settle_s), its duration or timeout passes (sim seconds), or
    `stop`; measure it; write the run folder. `on_tick(elapsed sim s, recorder, sim node)` is called
    every POLL_S (progress). RuntimeError when the loop cannot run (no /clock, no camera frame);
    with `opts.refuse_latched`, RobotLatched before anything starts when the robot is latched."""
    from go2vlm.behavior.commander_config import CommanderConfig
    from go2vlm.sim.worlds import world_footprints

    if opts.refuse_latched:
        refuse_if_latched(episode_entries(ep, opts), opts.domain_id, opts.interface)
    stop = stop or ShutdownRequested()
    out = Path(opts.out) if opts.out else None
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
    if opts.bag and out is None:
        raise ValueError("recording a bag needs a run folder (RunOptions.out)")
    recorder = EpisodeRecorder(video=opts.video, interface=opts.interface, domain_id=opts.domain_id)
    bag = None
    try:
        nodes, sim = build_graph(ep, opts)
        if opts.bag and out is not None:
            from go2vlm.apps.bag.recorder import BagRecorder

            bag = BagRecorder(out / "bag", all_topics=True, domain_id=opts.domain_id, interface=opts.interface)
    except BaseException:
        recorder.shutdown()
        raise
    shapes = world_footprints(sim.sim.model)
    kind = ep.kind
    stop_distance = float(ep.params.get("commander", {}).get("stop_distance_m", CommanderConfig.stop_distance_m))
    result = EpisodeResult(ep, {}, {}, out)
    with stop.hold("the metrics"):  # from the first signal until metrics.json is written
        wall0 = time.monotonic()  # wall time: the runner's deadlines and wall_s
        cpu0, threads0 = os.times(), cpu_by_thread() if opts.cpu else {}
        recorder.start()
        if bag is not None:
            bag.start()
        try:
            rest = _start_models_first(nodes, stop, opts.model_timeout_s)
        except BaseException:
            for n in reversed(nodes):
                n.shutdown()
            recorder.shutdown()
            if bag is not None:
                bag.stop()
            raise
        for n in rest:
            n.start()
        t0: float | None = None
        t_done: float | None = None
        interrupted = True
        try:
            for t in _sim_clock(stop, recorder, wall0, opts.startup_timeout_s):
                t0 = t if t0 is None else t0
                if on_tick is not None:
                    on_tick(t - t0, recorder, sim)
                if t - t0 >= ep.duration_s:
                    interrupted = False
                    break
                if kind not in ("follow",) and t_done is None and recorder.latest_state() in END_STATES:
                    t_done = t
                if t_done is not None and t - t_done >= ep.settle_s:
                    interrupted = False
                    break
                if t - t0 > NO_FRAME_S and recorder.frame_count() == 0 and ep.robot == "sim":
                    err = recorder.last_status().get("render_error")
                    raise RuntimeError(f"no camera frame after {t:.0f} s of sim time: {err or 'is the camera on?'}")
        finally:
            wall_s = time.monotonic() - wall0
            cpu = {k: v - threads0.get(k, 0.0) for k, v in cpu_by_thread().items()} if opts.cpu else {}
            if out is not None:
                _save_memories(nodes, out, result.files)
            for n in reversed(nodes):  # the sim (first) goes last; the recorders hear everything
                n.shutdown()
            recorder.shutdown()
            bagged = bag.stop() if bag is not None else None
        cpu1 = os.times()
        rec = recorder.snapshot()
        ctx = Context(ep, shapes, t0 or 0.0, wall_s, opts.rtf, opts.fast, stop_distance)
        metrics, series = compute_metrics(rec, ctx)
        metrics["interrupted"] = interrupted
        metrics["video_frames"] = 0
        if opts.cpu:
            busy = sorted(cpu.items(), key=lambda kv: -kv[1])
            metrics["cpu_s_by_thread"] = {k: round(v, 2) for k, v in busy if v >= 0.01}
            metrics["cpu_s_process"] = round(cpu1.user + cpu1.system - cpu0.user - cpu0.system, 2)
            metrics["cpu_s_children"] = round(
                cpu1.children_user + cpu1.children_system - cpu0.children_user - cpu0.children_system, 2
            )
            metrics["cpu_cores"] = os.cpu_count()
        metrics["options"] = {
            "episode": ep.to_dict(),
            "graph": graph_name(ep),
            "rtf": opts.rtf,
            "fast": opts.fast,
            "video": opts.video,
            "bag": opts.bag,
        }
        if bagged is not None:
            metrics["bag"] = {"path": str(bagged.out), "messages": bagged.messages, "topics": len(bagged.topics)}
        result = EpisodeResult(ep, metrics, series, out, result.files, rec)
        if bagged is not None:
            result.files["bag"] = str(bagged.out)
        if out is not None:
            write_json(out / "metrics.json", metrics)
            result.files["metrics"] = str(out / "metrics.json")
            write_json(out / "series.json", series)
            if rec.grid is not None:
                from go2vlm.apps.episodes.navmap import write_map_files

                result.files.update(write_map_files(rec.grid, out))
    if out is None or stop.abort.is_set():
        return result
    if opts.plot:
        from go2vlm.apps.episodes.plot import write_plot

        with stop.hold("the plot"), atomic(out / "plot.png") as tmp:
            write_plot(metrics, series, shapes, tmp)
        result.files["plot"] = str(out / "plot.png")
    if opts.video and not stop.abort.is_set():
        from go2vlm.apps.episodes.video import render_video

        try:
            metrics["video_frames"] = render_video(rec, ep, metrics, out / "video.mp4", stop.abort.is_set)
        except Exception as exc:  # no GL, ffmpeg failed, a second signal: the rest of the run stands
            print(f"go2vlm: video not written: {exc}", file=sys.stderr)
        else:
            if metrics["video_frames"]:
                result.files["video"] = str(out / "video.mp4")
            with stop.hold("the metrics"):
                write_json(out / "metrics.json", metrics)
    return result
