"""video.mp4 of one episode, rendered after the run from what the recorder kept: a chase camera
behind the Go2 (640x480, the robot walking, re-posed from /sim/ground_truth and /joint_states), the
head camera as an inset with the detections drawn on it, and the goal, the state and the speed.

One video frame per head-camera frame (10 fps at the default 10 Hz camera = real speed in sim time).
Rendering after the run costs nothing while the loop runs in real time; it costs about 30 ms of one
core per frame on the 2-core reference machine (llvmpipe), so a 60 s demo takes ~20 s more at the end.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from go2vlm.apps.episodes.episode import Episode, goal_target, label_matches
from go2vlm.apps.episodes.outputs import atomic
from go2vlm.apps.episodes.recorder import Recording

__all__ = ["VIDEO_SIZE", "goal_caption", "render_video"]

VIDEO_SIZE = (640, 480)
INSET_WIDTH = 224
YELLOW = (255, 220, 0)
WHITE = (255, 255, 255)


def goal_caption(goal: str | None) -> str:
    """The goal as the video can write it (Hershey fonts have no CJK glyphs: a Chinese goal is shown
    in its parsed English form)."""
    if goal is None:
        return "follow the red ball (colour detector + follower)"
    if goal.isascii():
        return goal
    from go2vlm.behavior.goals import GoalParseError, parse_goal

    try:
        g = parse_goal(goal)
    except GoalParseError:
        return "(a goal it could not parse)"
    return f"{g.kind.replace('_', ' ')} {g.target.label if g.target else ''}".strip()


def _nearest(times: list[float], t: float) -> int:
    i = bisect.bisect_left(times, t)
    if i == 0:
        return 0
    if i >= len(times):
        return len(times) - 1
    return i if times[i] - t < t - times[i - 1] else i - 1


def _latest(items: list[tuple[float, Any]], times: list[float], t: float) -> Any:
    i = bisect.bisect_right(times, t) - 1
    return items[i][1] if i >= 0 else None


def _text(
    img: np.ndarray, s: str, org: tuple[int, int], scale: float = 0.5, colour: tuple[int, int, int] = WHITE
) -> None:
    import cv2

    # A 1-pixel shadow, not a thick outline: OpenCV 5 widens the glyphs of thicker text.
    cv2.putText(img, s, (org[0] + 1, org[1] + 1), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    cv2.putText(img, s, org, cv2.FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv2.LINE_AA)


def render_video(
    rec: Recording,
    ep: Episode,
    metrics: dict[str, Any],
    path: Path,
    abort: Callable[[], bool] = lambda: False,
) -> int:
    """Write `path` (atomically); returns the number of frames. Raises RuntimeError when `abort()`
    turns true (nothing is left behind) and RenderingUnavailable without GL."""
    import imageio_ffmpeg

    from go2vlm.sim.replay import ChaseCamera

    track = [(t, p["go2"]) for t, p in rec.poses if "go2" in p]
    if not track:
        return 0
    track_t = [t for t, _ in track]
    joint_t = [t for t, _ in rec.joints]
    status_t = [t for t, _ in rec.commander]
    cmd_t = [c[0] for c in rec.cmds]
    cmd_items = [(c[0], c) for c in rec.cmds]
    pose_t = [p[0] for p in rec.poses]
    targets = {t: (x, y, z) for t, x, y, z in rec.targets}
    answers = {stamp: boxes for _, stamp, boxes in rec.answers}
    want = goal_target(ep.goal)
    frames = sorted(set(rec.frames)) or list(np.arange(track_t[0], track_t[-1], 1.0 / ep.camera_rate_hz))
    frames = [t for t in frames if track_t[0] - 0.1 <= t <= track_t[-1] + 0.1]
    caption = goal_caption(ep.goal)
    w, h = VIDEO_SIZE
    n = 0
    with ChaseCamera(ep.world, ep.spawn, w, h) as cam, atomic(path) as tmp:
        gen = imageio_ffmpeg.write_frames(
            str(tmp),
            (w, h),
            fps=ep.camera_rate_hz,
            codec="libx264",
            quality=None,
            output_params=["-preset", "ultrafast", "-crf", "26", "-movflags", "+faststart"],
            macro_block_size=2,
            ffmpeg_log_level="error",
        )
        gen.send(None)
        try:
            for t in frames:
                if abort():
                    raise RuntimeError("video stopped by a second signal")
                i = _nearest(track_t, t)
                x, y, z, *q = track[i][1]
                joints = rec.joints[_nearest(joint_t, t)][1] if rec.joints else None
                moving = {k: v[:3] for k, v in rec.poses[_nearest(pose_t, t)][1].items() if k != "go2"}
                img = np.ascontiguousarray(cam.render(t, (x, y, z), q, joints, moving))
                # Speed over the ground from ground truth, over ~0.2 s.
                j = max(0, i - 4)
                dt = track_t[i] - track_t[j]
                speed = math.hypot(x - track[j][1][0], y - track[j][1][1]) / dt if dt > 0 else 0.0
                cmd = _latest(cmd_items, cmd_t, t)
                st = _latest(rec.commander, status_t, t) or {}
                state = st.get("state") or ("tracking" if t in targets else "searching")
                _overlay(img, caption, state, t - frames[0], cmd, speed)
                _inset(img, rec.thumbs.get(t), t, targets, answers, rec.truth, st, want, ep)
                gen.send(img.tobytes())
                n += 1
        finally:
            gen.close()
    return n


def _overlay(img: np.ndarray, caption: str, state: str, t: float, cmd: Any, speed: float) -> None:
    import cv2

    band = img[0:64, 0 : img.shape[1] - INSET_WIDTH - 16]
    band[:] = (band * 0.55).astype(np.uint8)
    _text(img, caption[:48], (8, 20), 0.55, YELLOW)
    _text(img, f"state: {state}    t = {t:5.1f} s", (8, 40))
    vx, wz = (cmd[1], cmd[3]) if cmd is not None else (0.0, 0.0)
    _text(img, f"cmd vx {vx:+.2f} m/s  wz {wz:+.2f} rad/s   speed {speed:.2f} m/s", (8, 58), 0.45)
    cv2.rectangle(img, (0, 0), (img.shape[1] - 1, img.shape[0] - 1), (40, 40, 40), 1)


def _inset(
    img: np.ndarray,
    jpg: bytes | None,
    t: float,
    targets: dict[float, tuple[float, float, float]],
    answers: dict[float, list[Any]],
    truth: dict[float, list[Any]],
    status: dict[str, Any],
    want: Any,
    ep: Episode,
) -> None:
    import cv2

    if jpg is None:
        return
    head = cv2.imdecode(np.frombuffer(jpg, np.uint8), cv2.IMREAD_COLOR)
    if head is None:
        return
    head = cv2.cvtColor(head, cv2.COLOR_BGR2RGB)
    ih = round(head.shape[0] * INSET_WIDTH / head.shape[1])
    head = cv2.resize(head, (INSET_WIDTH, ih), interpolation=cv2.INTER_AREA)
    s = INSET_WIDTH / ep.camera_width
    # The boxes the grounding gave (the vlm's answers; the oracle's are the ground truth itself).
    boxes = answers.get(t) if ep.perception == "vlm" else truth.get(t) if ep.perception == "oracle" else None
    for label, (x1, y1, x2, y2), _ in boxes or []:
        mine = want is not None and label_matches(want, label)
        cv2.rectangle(head, (int(x1 * s), int(y1 * s)), (int(x2 * s), int(y2 * s)), YELLOW if mine else WHITE, 1)
    target = targets.get(t)
    if target is not None:  # /detected_target: the follow article's convention (x, y in -1..1, z = size)
        x, y, z = target
        cx, cy, r = (x + 1) * INSET_WIDTH / 2, (y + 1) * ih / 2, z * INSET_WIDTH / 2
        cv2.circle(head, (int(cx), int(cy)), max(2, int(r)), YELLOW, 1)
    elif status.get("seen") and isinstance(status.get("x"), (int, float)):  # the commander's offset
        cx = int((status["x"] + 1) * INSET_WIDTH / 2)
        cv2.line(head, (cx, ih - 14), (cx, ih - 2), YELLOW, 2)
    _text(head, "head camera", (4, 12), 0.35)
    x0 = img.shape[1] - INSET_WIDTH - 8
    img[8 : 8 + ih, x0 : x0 + INSET_WIDTH] = head
    cv2.rectangle(img, (x0 - 1, 7), (x0 + INSET_WIDTH, 8 + ih), WHITE, 1)
