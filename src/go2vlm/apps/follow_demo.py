"""`go2vlm demo`: the closed loop in one process, measured.

    sim (follow_ball) -> /camera/image_raw -> color_detector -> /detected_target -> follower
      -> /follower/cmd_vel -> safety gate -> /cmd_vel -> sim

Every node runs on its own thread (the sim on three: executor, physics, render). A recorder node
listens like any other node (/detected_target, /cmd_vel, /sim/ground_truth, /odom, /sim/status,
/camera/camera_info and, for the video, /camera/image_raw) and turns what it heard into
metrics.json, a plot and a video of the head camera with the detection drawn on it.

Every node here, the recorder included, runs with use_sim_time: stamps and timers are sim time, so
a run at --fast behaves as one at --rtf 1 (up to how late the nodes answer in sim time). The demo's
own deadlines (start-up, a stalled sim) and wall_s are wall time: they are about the host.
"""

from __future__ import annotations

import json
import math
import os
import queue
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, QOS_SENSOR, Node, ShutdownRequested
from go2vlm.geometry.camera import fovy_to_hfov
from go2vlm.geometry.rotations import quat_yaw
from go2vlm.msgs.geometry_msgs import PointStamped, Twist
from go2vlm.msgs.image import image_to_numpy
from go2vlm.msgs.nav_msgs import Odometry
from go2vlm.msgs.rosgraph_msgs import Clock
from go2vlm.msgs.sensor_msgs import CameraInfo, Image
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.tf2_msgs import TFMessage

VIDEO_WIDTH = 320  # frames are downscaled before encoding: a quarter of the pixels of 640x480


@dataclass
class DemoOptions:
    duration: float = 60.0  # sim seconds
    rtf: float = 1.0
    fast: bool = False
    mode: str = "dynamic"
    out: Path | None = None
    robot: str = "sim"  # sim | go2 (the sim driven through the Unitree protocol by the go2 driver)
    video: bool = True
    world: str = "follow_ball"
    ball_speed: float = 0.3
    camera_width: int = 640
    camera_height: int = 480
    camera_rate_hz: float = 10.0
    progress: bool = True
    interface: str | None = None
    domain_id: int | None = None
    params: dict[str, dict[str, Any]] = field(default_factory=dict)  # node kind -> extra parameters
    extra_nodes: list[str] = field(default_factory=list)  # more node kinds to run (e.g. commander)
    startup_timeout_s: float = 60.0


@dataclass
class DemoResult:
    metrics: dict[str, Any]
    out_dir: Path
    files: dict[str, str]

    @property
    def fell(self) -> bool:
        return bool(self.metrics.get("fell"))


class DemoRecorder(Node):
    """Listens to the loop like any other node and keeps what the metrics need."""

    name = "demo_recorder"

    def __init__(self, config: Any = None, *, video: bool = True, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        # Latched topics may still hold a previous run's last sample (another demo in this process).
        self.t_start = self.now()  # stamps before this are not ours (0.0 on sim time: none are)
        self.wall_start = time.time()  # wall time: /sim/status carries the wall time it was sent at
        self.lock = threading.Lock()
        self.targets: list[tuple[float, float, float, float]] = []  # stamp, x, y, z
        self.cmds: list[tuple[float, float, float, float]] = []  # receive time (recorder's clock), vx, vy, wz
        self.gt: list[tuple[float, float, float, float, float, float]] = []  # stamp, robot xy yaw, ball xy
        self.odom: list[tuple[float, float, float]] = []  # stamp, x, y
        self.frames: list[float] = []  # camera_info stamps: one per head-camera frame
        self.status: list[dict[str, Any]] = []
        self.sim_time = -1.0
        self.fell = False
        self.video_frames: queue.Queue[np.ndarray | None] = queue.Queue(maxsize=64)
        self.video_dropped = 0
        self._pending: dict[float, np.ndarray] = {}  # frame stamp -> downscaled RGB, waiting for its detection
        self.create_subscription(PointStamped, "/detected_target", self._on_target, QOS_DEFAULT)
        self.create_subscription(Twist, "/cmd_vel", self._on_cmd, QOS_DEFAULT)
        self.create_subscription(TFMessage, "/sim/ground_truth", self._on_gt, QOS_DEFAULT)
        self.create_subscription(Odometry, "/odom", self._on_odom, QOS_DEFAULT)
        self.create_subscription(String, "/sim/status", self._on_status, QOS_LATCHED)
        self.create_subscription(Clock, "/clock", self._on_clock, QOS_DEFAULT)
        self.create_subscription(CameraInfo, "/camera/camera_info", self._on_info, QOS_DEFAULT)
        if video:
            self.create_subscription(Image, "/camera/image_raw", self._on_image, QOS_SENSOR)

    # -- callbacks (the recorder's own thread) -------------------------------------------------
    def _on_target(self, msg: PointStamped) -> None:
        p = msg.point
        if not all(math.isfinite(v) for v in (p.x, p.y, p.z)):
            self.count("bad_targets")
            return
        t = msg.header.stamp.to_sec()
        if t < self.t_start:
            return
        with self.lock:
            self.targets.append((t, p.x, p.y, p.z))
        frame = self._pending.pop(t, None)
        if frame is not None:
            self._emit(frame, (p.x, p.y, p.z))

    def _on_cmd(self, msg: Twist) -> None:
        with self.lock:
            self.cmds.append((self.now(), msg.linear.x, msg.linear.y, msg.angular.z))

    def _on_gt(self, msg: TFMessage) -> None:
        robot = ball = None
        for tf in msg.transforms:
            if tf.child_frame_id == "gt/go2":
                robot = tf.transform
            elif tf.child_frame_id == "gt/red_ball":
                ball = tf.transform
        if robot is None or ball is None:
            return
        q = robot.rotation
        yaw = quat_yaw(q.w, q.x, q.y, q.z)
        with self.lock:
            self.gt.append(
                (
                    msg.transforms[0].header.stamp.to_sec(),
                    robot.translation.x,
                    robot.translation.y,
                    yaw,
                    ball.translation.x,
                    ball.translation.y,
                )
            )

    def _on_odom(self, msg: Odometry) -> None:
        p = msg.pose.pose.position
        with self.lock:
            self.odom.append((msg.header.stamp.to_sec(), p.x, p.y))

    def _on_status(self, msg: String) -> None:
        try:
            st = json.loads(msg.data)
        except ValueError:
            self.count("bad_status")
            return
        if float(st.get("wall_time", 0.0)) < self.wall_start:
            return
        with self.lock:
            self.status.append(st)
            self.fell = self.fell or bool(st.get("fell"))

    def _on_clock(self, msg: Clock) -> None:
        self.sim_time = msg.clock.to_sec()

    def _on_info(self, msg: CameraInfo) -> None:
        t = msg.header.stamp.to_sec()
        if t < self.t_start:
            return
        with self.lock:
            self.frames.append(t)

    def _on_image(self, msg: Image) -> None:
        import cv2

        try:
            arr = image_to_numpy(msg)
        except ValueError as exc:
            self.count("bad_images")
            self.log.throttled("error", 2.0, f"video: {exc}")
            return
        h, w = arr.shape[:2]
        small = cv2.resize(arr, (VIDEO_WIDTH, max(2, round(h * VIDEO_WIDTH / w / 2) * 2)), interpolation=cv2.INTER_AREA)
        if msg.encoding in ("bgr8", "8UC3"):
            small = cv2.cvtColor(small, cv2.COLOR_BGR2RGB)
        elif small.ndim == 2:
            small = cv2.cvtColor(small, cv2.COLOR_GRAY2RGB)
        elif small.shape[2] == 4:
            small = np.ascontiguousarray(small[:, :, :3])
        # A frame waits for its detection (same stamp) until newer frames push it out.
        self._pending[msg.header.stamp.to_sec()] = small
        while len(self._pending) > 3:
            oldest = min(self._pending)
            self._emit(self._pending.pop(oldest), None)

    def flush_video(self) -> None:
        for t in sorted(self._pending):
            self._emit(self._pending.pop(t), None)

    def _emit(self, rgb: np.ndarray, target: tuple[float, float, float] | None) -> None:
        import cv2

        h, w = rgb.shape[:2]
        if target is not None:
            x, y, z = target
            cx, cy, r = (x + 1) * w / 2, (y + 1) * h / 2, z * w / 2
            cv2.circle(rgb, (int(cx), int(cy)), max(2, int(r)), (255, 255, 0), 2)
            cv2.drawMarker(rgb, (int(cx), int(cy)), (255, 255, 0), cv2.MARKER_CROSS, 10, 2)
            label = f"x={x:+.2f}"
        else:
            label = "no target"
        cv2.putText(rgb, label, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
        try:
            self.video_frames.put_nowait(rgb)
        except queue.Full:
            self.video_dropped += 1


class VideoWriter:
    """Encodes frames with ffmpeg (imageio-ffmpeg) on a background thread, as they come."""

    def __init__(self, path: Path, frames: queue.Queue[np.ndarray | None], fps: float) -> None:
        self.path = path
        self.frames = frames
        self.fps = fps
        self.count = 0
        self.error: str | None = None
        self._thread = threading.Thread(target=self._run, name="demo:video", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        gen = None
        try:
            import imageio_ffmpeg

            while True:
                frame = self.frames.get()
                if frame is None:
                    break
                if gen is None:
                    h, w = frame.shape[:2]
                    gen = imageio_ffmpeg.write_frames(
                        str(self.path),
                        (w, h),
                        fps=self.fps,
                        codec="libx264",
                        quality=None,
                        output_params=["-preset", "ultrafast", "-crf", "26", "-movflags", "+faststart"],
                        macro_block_size=2,
                        ffmpeg_log_level="error",
                    )
                    gen.send(None)
                gen.send(np.ascontiguousarray(frame).tobytes())
                self.count += 1
        except Exception as exc:
            self.error = f"{type(exc).__name__}: {exc}"
            while True:  # keep draining so that the recorder never blocks
                try:
                    if self.frames.get(timeout=0.5) is None:
                        break
                except queue.Empty:
                    break
        finally:
            if gen is not None:
                try:
                    gen.close()
                except Exception as exc:
                    self.error = self.error or f"{type(exc).__name__}: {exc}"

    def finish(self, timeout_s: float = 60.0) -> None:
        self.frames.put(None)
        self._thread.join(timeout_s)


# -- metrics -----------------------------------------------------------------------------------


def _wall_to_sim(status: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray]:
    pairs = sorted({(float(s["wall_time"]), float(s["sim_time"])) for s in status if "wall_time" in s})
    if not pairs:
        return np.array([0.0, 1.0]), np.array([0.0, 1.0])
    if len(pairs) == 1:
        w, s = pairs[0]
        return np.array([w, w + 1.0]), np.array([s, s + 1.0])
    arr = np.array(pairs)
    return arr[:, 0], arr[:, 1]


def _to_sim(wall: np.ndarray, ref: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Wall stamps -> sim time, interpolated from the (wall, sim) pairs in /sim/status."""
    ws, ss = ref
    slope = (ss[-1] - ss[0]) / max(1e-9, ws[-1] - ws[0])
    out = np.interp(wall, ws, ss)
    out = np.where(wall < ws[0], ss[0] + (wall - ws[0]) * slope, out)
    return np.where(wall > ws[-1], ss[-1] + (wall - ws[-1]) * slope, out)


def compute_metrics(rec: DemoRecorder, wall_s: float, opts: DemoOptions) -> dict[str, Any]:
    with rec.lock:
        targets = np.array(rec.targets, dtype=float).reshape(-1, 4)
        cmds = np.array(rec.cmds, dtype=float).reshape(-1, 4)
        gt = np.array(rec.gt, dtype=float).reshape(-1, 6)
        frames = np.array(sorted(set(rec.frames)), dtype=float)
        status = list(rec.status)
    ref = _wall_to_sim(status)
    if rec.use_sim_time:  # stamps are sim time already
        ref = (np.array([0.0, 1.0]), np.array([0.0, 1.0]))
    sim_times = [float(s["sim_time"]) for s in status]
    walls = [float(s["wall_time"]) for s in status]

    def rate(i0: int) -> float:
        dw = walls[-1] - walls[i0] if len(walls) > i0 + 1 else 0.0
        return (sim_times[-1] - sim_times[i0]) / dw if dw > 0 else 0.0

    # Steady state: from the first status after 2 s of sim time (start-up: imports, GL context, first frames).
    warm = next((i for i, t in enumerate(sim_times) if t >= 2.0), 0)
    rtf = rate(warm) if rate(warm) > 0 else rate(0)
    rtf_overall = rate(0)
    seen = set(targets[:, 0].tolist())
    visible = sum(1 for t in frames if t in seen) / len(frames) if len(frames) else 0.0
    dist = np.hypot(gt[:, 4] - gt[:, 1], gt[:, 5] - gt[:, 2]) if len(gt) else np.zeros(0)
    cmd_span = cmds[-1, 0] - cmds[0, 0] if len(cmds) >= 2 else 0.0
    travelled = float(np.sum(np.hypot(np.diff(gt[:, 1]), np.diff(gt[:, 2])))) if len(gt) >= 2 else 0.0
    last = status[-1] if status else {}
    return {
        "duration_s": round(max([rec.sim_time, *sim_times]), 3),
        "wall_s": round(wall_s, 3),
        "real_time_factor": round(rtf, 3),
        "real_time_factor_with_startup": round(rtf_overall, 3),
        "target_visible_fraction": round(visible, 4),
        "frames": len(frames),
        "frames_with_target": int(sum(1 for t in frames if t in seen)),
        "mean_abs_x_error": round(float(np.mean(np.abs(targets[:, 1]))), 4) if len(targets) else None,
        "fell": bool(rec.fell),
        "min_distance_to_ball_m": round(float(dist.min()), 3) if len(dist) else None,
        "mean_distance_to_ball_m": round(float(dist.mean()), 3) if len(dist) else None,
        "max_distance_to_ball_m": round(float(dist.max()), 3) if len(dist) else None,
        "final_distance_to_ball_m": round(float(dist[-1]), 3) if len(dist) else None,
        "robot_distance_travelled_m": round(travelled, 3),
        "cmd_rate_hz": round((len(cmds) - 1) / cmd_span, 2) if cmd_span > 0 else 0.0,
        "mean_cmd_vx": round(float(np.mean(cmds[:, 1])), 4) if len(cmds) else None,
        "frames_dropped_by_renderer": last.get("frames_dropped"),
        "mode": opts.mode,
        "world": opts.world,
        "robot": opts.robot,
        "rtf_target": None if opts.fast else opts.rtf,
        "fast": opts.fast,
        "camera": f"{opts.camera_width}x{opts.camera_height}@{opts.camera_rate_hz:g}Hz",
        "ball_speed_mps": opts.ball_speed,
        "_series": {
            "target_sim_t": _to_sim(targets[:, 0], ref).tolist() if len(targets) else [],
            "target_x": targets[:, 1].tolist(),
            "gt_sim_t": _to_sim(gt[:, 0], ref).tolist() if len(gt) else [],
            "robot_xy": gt[:, 1:3].tolist(),
            "ball_xy": gt[:, 4:6].tolist(),
            "distance": dist.tolist(),
        },
    }


def write_plot(metrics: dict[str, Any], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = metrics["_series"]
    fig = plt.figure(figsize=(12, 5.5))
    ax1 = fig.add_subplot(2, 2, 1)
    ax1.plot(s["target_sim_t"], s["target_x"], ".", ms=2, color="tab:red")
    ax1.axhline(0, color="0.5", lw=0.8)
    ax1.set_ylim(-1.05, 1.05)
    ax1.set_ylabel("x error (normalised)")
    ax1.set_title(
        f"tracking: ball visible {100 * metrics['target_visible_fraction']:.1f} % of frames, "
        f"mean |x| {metrics['mean_abs_x_error'] or 0:.3f}",
        fontsize=9,
    )
    ax2 = fig.add_subplot(2, 2, 3, sharex=ax1)
    ax2.plot(s["gt_sim_t"], s["distance"], color="tab:blue")
    ax2.set_xlabel("sim time (s)")
    ax2.set_ylabel("distance to ball (m)")
    ax3 = fig.add_subplot(1, 2, 2)
    robot, ball = np.array(s["robot_xy"]).reshape(-1, 2), np.array(s["ball_xy"]).reshape(-1, 2)
    if len(ball):
        ax3.plot(ball[:, 0], ball[:, 1], color="tab:red", lw=1, label="ball")
        ax3.plot(*ball[0], "o", color="tab:red", ms=5)
    if len(robot):
        ax3.plot(robot[:, 0], robot[:, 1], color="tab:blue", lw=1.5, label="Go2")
        ax3.plot(*robot[0], "s", color="tab:blue", ms=5)
    ax3.set_aspect("equal", adjustable="datalim")
    ax3.set_xlabel("x (m)")
    ax3.set_ylabel("y (m)")
    ax3.grid(alpha=0.3)
    if len(ball) or len(robot):
        ax3.legend(loc="best", fontsize=8)
    ax3.set_title(
        f"top view ({metrics['mode']}, {metrics['duration_s']:.0f} s, rtf {metrics['real_time_factor']:.2f}"
        f"{', FELL' if metrics['fell'] else ''})",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


# -- CPU accounting (Linux) ----------------------------------------------------------------------


def cpu_by_thread() -> dict[str, float]:
    """CPU seconds per live thread of this process, by thread name (from /proc)."""
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
        cpu = (int(fields[11]) + int(fields[12])) / tick
        name = names.get(int(tid), f"native:{comm}")
        out[name] = out.get(name, 0.0) + cpu
    return out


# -- orchestration (shared with go2vlm.apps.goal_demo) ---------------------------------------


def sim_node_params(opts: Any, world: str) -> dict[str, Any]:
    """The sim node's parameters from a demo's options (DemoOptions or GoalDemoOptions)."""
    return {
        "world": world,
        "mode": opts.mode,
        "rtf": opts.rtf,
        "fast": opts.fast,
        "ball_speed": opts.ball_speed,
        "camera_width": opts.camera_width,
        "camera_height": opts.camera_height,
        "camera_rate_hz": opts.camera_rate_hz,
        "world_camera": False,  # nobody looks at it in the demo: save the render time
    }


def shutdown_request(shutdown: ShutdownRequested | None) -> ShutdownRequested:
    """The caller's shutdown request, else a new one that Ctrl-C / SIGTERM set."""
    stop = shutdown or ShutdownRequested()
    if shutdown is None:
        stop.install()
    return stop


def start_nodes(recorder: Node, nodes: list[Node]) -> None:
    recorder.start()
    for n in nodes:
        n.start()


def shutdown_nodes(recorder: Node, nodes: list[Node]) -> None:
    """In reverse order of starting: the sim (first) goes last, the recorder hears everything."""
    for n in reversed(nodes):
        n.shutdown()
    recorder.shutdown()


def sim_clock(
    stop: ShutdownRequested, recorder: Any, started: float, timeout_s: float, period_s: float
) -> Iterator[float]:
    """The sim time the recorder last heard on /clock, every `period_s` (once the sim is up), until
    `stop` is requested; RuntimeError when no /clock came within `timeout_s` of `started` (monotonic).
    Wall time: these are the demo's own deadlines on the host, not the nodes' time."""
    while not stop.event.wait(period_s):
        t = recorder.sim_time
        if t < 0:
            if time.monotonic() - started > timeout_s:
                raise RuntimeError(f"the sim published no /clock within {timeout_s:g} s")
            continue
        yield t


def sim_time(params: dict[str, Any]) -> dict[str, Any]:
    """A demo node's parameters with use_sim_time on (unless the caller's own params say otherwise)."""
    return {"use_sim_time": True, **params}


def build_nodes(opts: DemoOptions) -> list[Node]:
    from go2vlm.launch.registry import make_node

    common: dict[str, Any] = {"interface": opts.interface, "domain_id": opts.domain_id}
    sim_params: dict[str, Any] = sim_node_params(opts, opts.world)
    nodes: list[Node] = []
    sim_remap: dict[str, str] = {}
    if opts.robot == "go2":
        try:
            from go2vlm.launch.registry import node_class

            node_class("go2")
        except (ImportError, AttributeError) as exc:
            raise RuntimeError(
                "--robot go2 needs the Go2 driver node (go2vlm.robots.go2.driver_node:Go2DriverNode), "
                f"which is not available: {exc}"
            ) from None
        # The sim is reached only through the Unitree protocol (sport API, videohub camera,
        # rt/sportmodestate), as a real Go2 would be; the driver owns /cmd_vel, /odom, /imu, /tf
        # and the camera topics, so the sim's own ROS outputs move out of the way.
        sim_params["unitree"] = True
        sim_params["camera"] = False
        sim_remap = {t: "/sim" + t for t in ("/cmd_vel", "/odom", "/imu", "/tf")}
    sim_params.update(opts.params.get("sim", {}))
    nodes.append(make_node("sim", params=sim_time(sim_params), remap=sim_remap, **common))
    if opts.robot == "go2":
        fovy = float(sim_params.get("camera_fovy_deg", 58.0))
        hfov = math.degrees(fovy_to_hfov(fovy, opts.camera_width, opts.camera_height))
        go2_params: dict[str, Any] = {"camera_rate_hz": opts.camera_rate_hz, "camera_hfov_deg": round(hfov, 3)}
        go2_params.update(opts.params.get("go2", {}))
        nodes.append(make_node("go2", params=sim_time(go2_params), **common))
    for kind in ("color_detector", "follower", "safety", *opts.extra_nodes):
        nodes.append(make_node(kind, params=sim_time(opts.params.get(kind, {})), **common))
    return nodes


def default_out_dir() -> Path:
    return Path("runs") / time.strftime("demo-%Y%m%d-%H%M%S")


def run_demo(opts: DemoOptions, shutdown: ShutdownRequested | None = None) -> DemoResult:
    """Run the loop for `opts.duration` sim seconds; write metrics.json, plot.png, video.mp4."""
    out = Path(opts.out) if opts.out else default_out_dir()
    out.mkdir(parents=True, exist_ok=True)
    stop = shutdown_request(shutdown)
    recorder = DemoRecorder(video=opts.video, interface=opts.interface, domain_id=opts.domain_id, use_sim_time=True)
    nodes = build_nodes(opts)
    sim = nodes[0]
    writer = VideoWriter(out / "video.mp4", recorder.video_frames, opts.camera_rate_hz) if opts.video else None
    bar = None
    if opts.progress:
        from tqdm import tqdm

        bar = tqdm(
            total=opts.duration,
            unit="sim s",
            desc="demo",
            file=sys.stderr,
            bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.0f} sim s [{elapsed}<{remaining}{postfix}]",
            disable=None,  # no bar when stderr is not a terminal: a line every 10 s instead
        )
    wall0 = time.monotonic()  # wall time: the demo's deadlines on the host and wall_s
    cpu0, threads0 = os.times(), cpu_by_thread()
    start_nodes(recorder, nodes)
    interrupted = False
    try:
        next_line = time.monotonic() + 10.0
        last_t, last_change = -1.0, time.monotonic()
        for t in sim_clock(stop, recorder, wall0, opts.startup_timeout_s, 0.1):
            rtf = getattr(sim, "rtf", 0.0)
            if bar is not None and not bar.disable:
                bar.n = min(t, opts.duration)
                bar.set_postfix_str(f"rtf {rtf:.2f}{' FELL' if recorder.fell else ''}")
            elif opts.progress and time.monotonic() >= next_line:
                next_line += 10.0
                print(f"demo: sim time {t:.1f}/{opts.duration:g} s, real-time factor {rtf:.2f}", file=sys.stderr)
            if t >= opts.duration:
                break
            if t != last_t:
                last_t, last_change = t, time.monotonic()
            elif time.monotonic() - last_change > 15.0:
                raise RuntimeError(f"sim time stopped at {t:.1f} s (see the sim's log above)")
            if t > 5.0 and not recorder.frames:
                err = recorder.status[-1].get("render_error") if recorder.status else None
                raise RuntimeError(f"no camera frame after {t:.0f} s of sim time: {err or 'is the camera on?'}")
        else:
            interrupted = True
    finally:
        wall_s = time.monotonic() - wall0
        cpu = {k: v - threads0.get(k, 0.0) for k, v in cpu_by_thread().items()}
        shutdown_nodes(recorder, nodes)
        if bar is not None:
            bar.close()
    cpu_total = os.times()
    recorder.flush_video()
    files: dict[str, str] = {}
    if writer is not None:
        writer.finish()
        if writer.count and writer.error is None:
            files["video"] = str(writer.path)
        elif writer.error:
            print(f"go2vlm demo: video not written: {writer.error}", file=sys.stderr)
    metrics = compute_metrics(recorder, wall_s, opts)
    metrics["interrupted"] = interrupted
    metrics["video_frames"] = writer.count if writer is not None else 0
    metrics["cpu_s_by_thread"] = {k: round(v, 2) for k, v in sorted(cpu.items(), key=lambda kv: -kv[1]) if v >= 0.01}
    metrics["cpu_s_process"] = round(cpu_total.user + cpu_total.system - cpu0.user - cpu0.system, 2)
    metrics["cpu_s_children"] = round(
        cpu_total.children_user + cpu_total.children_system - cpu0.children_user - cpu0.children_system, 2
    )
    metrics["cpu_cores"] = os.cpu_count()
    metrics["options"] = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(opts).items()}
    write_plot(metrics, out / "plot.png")
    files["plot"] = str(out / "plot.png")
    series = metrics.pop("_series")
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n")
    (out / "series.json").write_text(json.dumps(series) + "\n")
    files["metrics"] = str(out / "metrics.json")
    return DemoResult(metrics=metrics, out_dir=out, files=files)


def summary(result: DemoResult) -> str:
    m = result.metrics
    pct = 100 * m["target_visible_fraction"]

    def fmt(v: Any, unit: str = "") -> str:
        return "n/a" if v is None else f"{v:.2f}{unit}"

    lines = [
        f"go2vlm demo: {m['duration_s']:.1f} s of sim time in {m['wall_s']:.1f} s "
        f"(real-time factor {m['real_time_factor']:.2f}, {m['mode']} physics, robot={m['robot']})",
        f"  ball in view:      {pct:.1f} % of {m['frames']} camera frames",
        f"  mean |x| error:    {fmt(m['mean_abs_x_error'])} (normalised, 0 = centred)",
        f"  distance to ball:  mean {fmt(m['mean_distance_to_ball_m'], ' m')}, "
        f"min {fmt(m['min_distance_to_ball_m'], ' m')}, max {fmt(m['max_distance_to_ball_m'], ' m')}",
        f"  /cmd_vel rate:     {m['cmd_rate_hz']:.1f} Hz",
        f"  fell:              {'YES' if m['fell'] else 'no'}",
        f"  wrote:             {', '.join(result.files.values())}",
    ]
    if m.get("interrupted"):
        lines.insert(1, "  (interrupted: partial run)")
    return "\n".join(lines)
