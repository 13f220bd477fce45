"""answer_delay: grounding answers delivered as a slow VLM would deliver them, for latency experiments.

Topics
  subscribes  <input_topic>    vision_msgs/Detection2DArray (reliable; default /sim/detections): a perfect
                               answer about every frame (the sim's ground-truth boxes), stamped with it
  publishes   <output_topic>   vision_msgs/Detection2DArray (reliable; default /vlm/detections): one frame
                               at a time, the newest when free, re-published `latency_s` after its frame's
                               stamp with that stamp (perception/answer_delay.py); the others are dropped
              /answer_delay/status  std_msgs/String, latched JSON every 1 s: latency_s, counters

Parameters
  latency_s          2.5   seconds from a frame's stamp to its answer (sim seconds with use_sim_time)
  input_topic        /sim/detections
  output_topic       /vlm/detections
  target_body        ''    only this body's boxes pass ('' = every box as it came): the answer of a perfect
                           model asked about one object, e.g. the referent of "the ball under the table"
  target_label       ''    with target_body: the label its boxes get (what the commander asked for)
  release_period_s   0     > 0: also release due answers on a timer of this period (node clock), for
                           inputs that arrive seldom (a real model's answers, held back); 0: a due answer
                           leaves with the next input

It isolates latency from accuracy: the answers are right, only late, and they reach the target_tracker
exactly where the vlm node's would (benchmarks/bench_vlm_latency.py). Time is the frames' stamps only.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from go2vlm.bus import Node, param
from go2vlm.bus.topics import ANSWER_DELAY_STATUS, SIM_DETECTIONS, VLM_DETECTIONS
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.vision_msgs import Detection2DArray, best_hypothesis
from go2vlm.perception.answer_delay import AnswerDelay

__all__ = ["AnswerDelayConfig", "AnswerDelayNode"]


@dataclass
class AnswerDelayConfig:
    latency_s: float = param(2.5, help="seconds from a frame's stamp to its answer", min=0.0, max=60.0)
    input_topic: str = param(SIM_DETECTIONS.name, help="perfect answers, one per frame (vision_msgs/Detection2DArray)")
    output_topic: str = param(VLM_DETECTIONS.name, help="where the delayed answers go")
    target_body: str = param("", help="only this body's boxes pass ('' = all, unchanged)")
    target_label: str = param("", help="with target_body: the label its boxes get")
    release_period_s: float = param(0.0, help="> 0: release due answers on a timer too", min=0.0, max=10.0)


class AnswerDelayNode(Node):
    name = "answer_delay"
    Config = AnswerDelayConfig

    def __init__(self, config: AnswerDelayConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: AnswerDelayConfig = self.config
        self.delay: AnswerDelay[Detection2DArray] = AnswerDelay(cfg.latency_s)
        self.pub = VLM_DETECTIONS.publisher(self, name=cfg.output_topic)
        self.pub_status = ANSWER_DELAY_STATUS.publisher(self)
        SIM_DETECTIONS.subscription(self, self.on_answer, name=cfg.input_topic)
        self.create_timer(1.0, self.publish_status)
        if cfg.release_period_s > 0:
            self.create_timer(cfg.release_period_s, self.release)
        self.log.info(f"{cfg.input_topic} -> {cfg.output_topic}, {cfg.latency_s:g} s after each frame")

    def on_answer(self, msg: Detection2DArray) -> None:
        cfg: AnswerDelayConfig = self.config
        if cfg.target_body:
            kept = []
            for d in msg.detections:
                h = best_hypothesis(d.results)
                if h is not None and h.class_id == cfg.target_body:
                    h.class_id = cfg.target_label or cfg.target_body
                    kept.append(d)
            msg.detections = kept
        for _, held in self.delay.offer(msg.header.stamp.to_sec(), msg):
            self.pub.publish(held)

    def release(self) -> None:
        for _, held in self.delay.due(self.clock.now()):
            self.pub.publish(held)

    def publish_status(self) -> None:
        st = {"latency_s": self.delay.latency_s, "counters": dict(self.delay.counters)}
        self.pub_status.publish(String(data=json.dumps(st)))
