"""Nothing is lost on interrupt: `go2vlm demo` as a real process, stopped by a signal and then a
second one while it writes its results. metrics.json is complete, no file is torn or half-named,
and the exit code says which signal stopped it (130 SIGINT, 143 SIGTERM)."""

from __future__ import annotations

import json
import signal
from pathlib import Path

import imageio_ffmpeg
import pytest
from busutil import Procs, Recorder, wait_for

from go2vlm.bus import QOS_LATCHED, Node
from go2vlm.msgs.std_msgs import String

pytestmark = pytest.mark.slow


@pytest.mark.parametrize(("first", "code"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_demo_writes_its_metrics_before_it_stops(tmp_path: Path, first: int, code: int) -> None:
    procs = Procs()
    args = ["demo", "--out", str(tmp_path), "--no-progress", "--mode", "kinematic", "--duration", "300"]
    proc = procs.start(*(args + (["--goal", "follow the red ball"] if first == signal.SIGTERM else [])))
    probe = Node(node_name="interrupt_probe")
    status = Recorder()
    sub = probe.create_subscription(String, "/sim/status", status, QOS_LATCHED)
    probe.start()
    try:
        assert wait_for(lambda: any(json.loads(m.data)["sim_time"] > 8.0 for m in status.msgs()), timeout=120)
        proc.send_signal(first)
        # The second signal while the demo shuts its nodes down and writes: it must wait, not kill.
        assert wait_for(lambda: sub.publisher_count == 0, timeout=30), "the sim did not stop"
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=120)
    finally:
        probe.shutdown()
        procs.stop_all()
    assert proc.returncode == code, out[-3000:]
    assert "Traceback" not in out and "interrupted: partial run" in out
    assert "still writing" in out or "skipping what is left" in out, out[-3000:]
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["interrupted"] is True and 8.0 <= m["sim_s"] < 300
    json.loads((tmp_path / "series.json").read_text())
    leftovers = [p.name for p in tmp_path.iterdir() if ".partial" in p.name]
    assert not leftovers, f"torn files left: {leftovers}"
    if (tmp_path / "video.mp4").exists():  # finished before the second signal came: then it is whole
        assert imageio_ffmpeg.count_frames_and_secs(str(tmp_path / "video.mp4"))[0] >= 10
