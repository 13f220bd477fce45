"""commander: language goals -> what the robot does, over the target_tracker's confirmed target.

"follow the red ball", "go to the blue cylinder", "look for the green box", "stop", "sit", "stand",
"turn left 20 degrees" (and Chinese: 跟着红球, 走到蓝色圆柱, 找一下绿色盒子, 停下, 坐下, 站起来; see behavior/goals.py).
A thin node over the pure Mission core (behavior/mission.py has the rules, behavior/strategies/ the
ways to the goal); it does not look at images: the target_tracker grounds, tracks and ranges, the
vlm node answers decisions. It drives every goal itself, follow included, with one control law
(behavior/control.py); the follower node is the follow article's standalone demo, not this graph's.

Topics (QoS: reliable, volatile, keep-last 10 unless noted)
  subscribes  /goal               std_msgs/String       a goal as text (also the `goal` parameter), or
                                  JSON {"goal": text, "lease": {"key", "s"}}: a goal with a lease; the
                                  running goal sent again as plain text keeps its lease
              /goal/lease         std_msgs/String       JSON {"proof", "next", "s"}: renews the running
                                  goal's lease, if proof hashes to its key (only the goal's sender
                                  knows it; behavior/lease.py); unrenewed for its s (wall time), the
                                  goal stops; any other renewal is counted (lease_not_ours)
              /target/tracked     go2vlm_msgs/TrackedTarget  the target_tracker's target, one per camera
                                  frame; only `tracking` reports for the goal's object count; their
                                  bearing_rad and hfov_rad (from the real CameraInfo) place it
              /vlm/decision       std_msgs/String       raw VLM scene decisions (the vlm node in
                                  mode=decide), mapped onto the whitelist of behavior/decisions.py
              /scan               sensor_msgs/LaserScan  best-effort, keep-last 5 (`scan_topic`, frame
                                  base_link): obstacles for the local planner (avoid_obstacles)
              /odom               nav_msgs/Odometry     (`odom_topic`): keeps the target's last confirmed
                                  place while a detour takes it out of view; where the robot is, for
                                  the remembered objects
              /objects            vision_msgs/Detection3DArray, latched (`objects_topic`): the object
                                  memory (world/object_memory_node.py): remembered objects in the odom
                                  frame, and (header.stamp) the newest answer it has taken in
              /map/costmap        nav_msgs/OccupancyGrid, latched (`costmap_topic`): the map node's
                                  inflated costmap (world/map_node.py), frame odom: the global planner
                                  and the frontiers (explore); one over the bus's size caps (30000 x
                                  30000 cells, no cells, a resolution not finite > 0: msgs/sizes.py)
                                  is dropped before it is decoded or allocated, the last good one stays
              /vlm/way            std_msgs/String       frontier_choice vlm: answers about camera frames
                                  (perception/way.py); a whitelisted word's score goes on the value
                                  map from the pose at the frame's stamp (world/value_map.py),
                                  anything else counted (way_rejected_*) and ignored
  publishes   /explore/way_query  std_msgs/String, latched: frontier_choice vlm: the goal's object while
                                  it searches or explores, else '': which way is likeliest to lead to it
              /target/query       std_msgs/String, latched (transient-local, keep-last 1): the goal's
                                  object while a motion goal runs ("blue cylinder"), else ''; the
                                  target_tracker tracks it and the vlm node (mode=detect) grounds it
              /behavior/cmd_vel   geometry_msgs/Twist   follow / go to / look for / search at
                                  control_rate_hz; zeros for 0.5 s after a goal ends, then quiet;
                                  lowest priority in the safety gate (/teleop > /follower > /behavior)
              /go2/command        std_msgs/String       "sit" / "stand" (the Go2 driver / sim acts)
              /plan               nav_msgs/Path, latched: the navigator's route (to a frontier, or a
                                  remembered place), frame odom, on every replan; empty when it ends
              /commander/status   std_msgs/String       latched JSON: goal, kind, target, state, reason,
                                  seen, x, distance_m, range_method, tracker, cmd, decision, counters,
                                  basis (tracker | memory | ''), remembered (the goal's remembered object:
                                  id, x, y, confidence, distance_m), memory (objects, answer latency),
                                  explore (exploring, phase, frontier, frontiers_left, visited,
                                  given_up, retried_given_up, views_scored), plan (length_m, waypoints,
                                  reason), navigate (goal, route_m, recovering, recoveries, plans, failures), lease
                                  (left_s, renewals; never its key; null when none), refused_inputs
                                  (topic -> refused, last: inputs dropped for their size,
                                  msgs/sizes.py); on change and each status_period_s

Goals and states
  follow    waiting -> tracking (keeps follow_distance_m) | lost | searching   never ends by itself
  go to     searching -> approaching -> reached (stops at stop_distance_m, base -> object surface);
            detouring while the local planner (behavior/planner/local.py) steers round an obstacle on /scan
  look for  searching -> aligning -> found (target centred), or not_found after search_timeout_s
            (with explore: searching -> exploring -> ... -> not_found when no frontier is left)
  turn      turning (in place at decision_turn_rate, |angle| <= 30 deg) -> done
  stop      stopped (zero velocity); sit / stand -> done; text it cannot parse -> rejected: reason on
            /commander/status, zero velocity, nothing else moves; an object the target_tracker cannot
            ground (free text with its colour grounder) -> rejected.
  The target counts only while the tracker confirms it (tracking, younger than lost_timeout_s):
  otherwise zero at once (`lost`), then go to / look for search if search_on_loss.

The world (use_memory, with an object_memory running): go to / look for use the most confident
remembered object of the goal's label while the tracker does not confirm it; go to walks there once
the memory is sure of it (memory_confirm_confidence) and stops only when an answer about a frame
taken at the stop placed it within reach; look for ends found when an answer about a frame taken
facing it saw it. With slow answers the search stops and looks (search_view_per_answer). The memory
never commands a velocity (behavior/mission.py, behavior/strategies/remembered.py).

Exploring (explore, behavior/strategies/explore.py): once turn-and-look has found nothing, walk to a
frontier of /map/costmap (`frontier_choice` nearest by path cost, or vlm: the best-scored way on
/vlm/way first), look all round there, and repeat, until the target is seen or remembered, no
reachable frontier is left or explore_timeout_s has passed (not_found, with the reason).

Places (a frontier, a remembered object, a tracked go to's target) are walked to by the navigator
(behavior/navigate/: route, regulated pure pursuit checked on the footprint, one progress checker,
bounded recoveries; nav_*). A followed target, or a go to's without a map, is approached by the approach law, steering
round what a fresh /scan shows at the clearance of its speed (planner_margin_m at a creep, more at
speed: geometry/footprint.py Clearance, the guard's rule too); a detour that hides it carries on
towards its last confirmed place for up to detour_memory_s. The guard has the last word.

Decisions (/vlm/decision): stop | continue | turn (|angle| <= max_turn_deg <= 30) | sit; anything
else is counted (decisions_rejected) and ignored. The text never becomes a velocity.

Bounds (behavior/lease.py): a leased goal stops when its owner stops renewing it (wall time); every goal
stops after max_goal_s; a go to whose seen object lies beyond max_go_to_m is rejected, a remembered
one only given up (remembered_too_far).

Time: every period and timeout here is in the node's clock: sim time with use_sim_time.
Parameters (behavior/commander_config.py; the cores' declared once, on their fields). Live: the gains,
speeds, distances, timeouts, search, decision, memory and nav_* settings, avoid_obstacles,
planner_margin_m, detour_memory_s; the ceilings (max_goal_s, max_go_to_m, max_linear, max_angular,
max_turn_deg, explore_timeout_s) only go down (bound="max"); the rest are read-only.
"""

from __future__ import annotations

import dataclasses
import json
import time
from typing import Any

from go2vlm.behavior.commander_config import CommanderConfig
from go2vlm.behavior.commander_msgs import commander_status, route_path, way_answer, way_query
from go2vlm.behavior.lease import Lease, LeaseError, goal_end, parse_goal, parse_renewal
from go2vlm.behavior.mission import Intent, Mission
from go2vlm.behavior.planner.global_path import Costmap
from go2vlm.behavior.planner.route import Route
from go2vlm.behavior.sighting import sighting_of
from go2vlm.behavior.strategies.base import SearchStrategy
from go2vlm.behavior.strategies.explore_search import Explore
from go2vlm.behavior.strategies.search import TurnAndLook
from go2vlm.behavior.view_scores import ViewAnswerRejected
from go2vlm.bus import Node
from go2vlm.bus.topics import (
    BEHAVIOR_CMD_VEL,
    COMMANDER_STATUS,
    EXPLORE_WAY_QUERY,
    GO2_COMMAND,
    GOAL,
    GOAL_LEASE,
    MAP_COSTMAP,
    OBJECTS,
    ODOM,
    PLAN,
    SCAN,
    TARGET_QUERY,
    TARGET_TRACKED,
    VLM_DECISION,
    VLM_WAY,
)
from go2vlm.geometry.rotations import quat_yaw
from go2vlm.geometry.scan import frame_scan_points
from go2vlm.msgs.geometry_msgs import Twist, Vector3
from go2vlm.msgs.go2vlm_msgs import TrackedTarget
from go2vlm.msgs.nav_msgs import OccupancyGrid, Odometry
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import String
from go2vlm.msgs.vision_msgs import Detection3DArray
from go2vlm.perception.way import WayMessageRejected
from go2vlm.robot_profile import go2 as spec
from go2vlm.world.map_msg import grid_of
from go2vlm.world.objects_msg import remembered
from go2vlm.world.poses import PoseHistory, PoseUnavailable

__all__ = ["CommanderConfig", "CommanderNode"]


class CommanderNode(Node):
    """The ``commander`` node; its contract (topics, goals, parameters) is the module docstring."""

    name = "commander"
    Config = CommanderConfig

    def __init__(self, config: CommanderConfig | None = None, **kwargs: Any) -> None:
        super().__init__(config, **kwargs)
        cfg: CommanderConfig = self.config
        self.explore = Explore(cfg.explore_params())
        self.mission = Mission(cfg.mission_params(), searches=self._searches())
        self.pub_plan = PLAN.publisher(self)
        self._route: Route | None = None  # the route last published on /plan
        self.pub_query = TARGET_QUERY.publisher(self)
        self.pub_cmd = BEHAVIOR_CMD_VEL.publisher(self)
        self.pub_go2 = GO2_COMMAND.publisher(self)
        self.pub_status = COMMANDER_STATUS.publisher(self)
        GOAL.subscription(self, self.on_goal)
        GOAL_LEASE.subscription(self, self.on_lease)
        self._lease: Lease | None = None  # the running goal's, on wall time
        self._goal_t0 = 0.0
        TARGET_TRACKED.subscription(self, self.on_tracked)
        VLM_DECISION.subscription(self, self.on_decision)
        SCAN.subscription(self, self.on_scan, name=cfg.scan_topic)
        ODOM.subscription(self, self.on_odom, name=cfg.odom_topic)
        OBJECTS.subscription(self, self.on_objects, name=cfg.objects_topic)
        MAP_COSTMAP.subscription(self, self.on_costmap, name=cfg.costmap_topic)
        self._odom_frame = ""
        self._poses = PoseHistory()  # vlm: the heading at each answer's frame, on this node's clock
        self._way_query = ""
        self.pub_way = EXPLORE_WAY_QUERY.publisher(self)
        VLM_WAY.subscription(self, self.on_way)
        self._query: str | None = None
        self._last_key: tuple[str, str] | None = None
        self.create_timer(1.0 / cfg.control_rate_hz, self.tick)
        self.create_timer(cfg.status_period_s, self.publish_status)
        if cfg.goal.strip():
            self.set_goal(cfg.goal)
        else:
            self.tick()

    # -- inputs ------------------------------------------------------------------------------
    def on_params_changed(self, old: CommanderConfig, changed: frozenset[str]) -> None:
        # The mission reads its gains, speeds and timeouts from params on every step.
        self.mission.params = self.config.mission_params()
        self.explore.explorer.params = self.config.explore_params()
        self.mission.searches[:] = self._searches()

    def _searches(self) -> tuple[SearchStrategy, ...]:
        """The search chain: turn and look where it stands, then (explore) walk to frontiers."""
        old = getattr(self, "mission", None)
        look = (next((s for s in old.searches if isinstance(s, TurnAndLook)), None) if old else None) or TurnAndLook()
        look.more_after = self.config.explore  # one whole turn, then the frontier search
        return (look, self.explore) if self.config.explore else (look,)

    def on_goal(self, msg: String) -> None:
        try:
            g = parse_goal(msg.data)
        except LeaseError as exc:
            self.set_goal("")  # rejected, and nothing moves
            self.mission.reason = f"a bad goal message: {exc}"
            return self.publish_status()
        self.set_goal(g.text, None if g.lease_key is None else Lease.grant(g.lease_key, g.lease_s, time.monotonic()))

    def on_lease(self, msg: String) -> None:
        try:
            ok = self._lease is not None and self._lease.renew(parse_renewal(msg.data), time.monotonic())
        except LeaseError as exc:
            ok = False
            self.log.throttled("error", 5.0, f"ignoring a bad {GOAL_LEASE.name}: {exc}", key="lease")
        if not ok:
            n = self.count("lease_not_ours")
            self.log.throttled("warning", 5.0, f"refused a renewal that does not prove it comes from the goal's "
                               f"sender ({n} so far)", key="lease_not_ours")  # fmt: skip

    def set_goal(self, text: str, lease: Lease | None = None) -> None:
        before = self.mission.goal
        self.mission.set_goal(text, self.clock.monotonic())
        m = self.mission
        if m.goal is not before:
            self._goal_t0 = self.clock.monotonic()
            self._lease = lease
        elif lease is not None:  # the running goal again, with a lease of its own: its sender's order now
            self._lease = lease
        # else: a plain re-send of the running goal (a UI repeating it) keeps its lease: it never weakens it
        if m.state == "rejected":
            self.log.throttled("warning", 1.0, f"goal rejected: {m.reason}", key="goal")
        elif m.goal is not None:
            self.log.info(f"goal: {m.goal.describe()} ({text!r}): {m.state}")
        self.tick()

    def on_tracked(self, msg: TrackedTarget) -> None:
        sighting, bad = sighting_of(msg, self.clock.monotonic())
        if bad is not None:
            n = self.count("bad_tracked")
            self.log.throttled("error", 5.0, f"ignoring a bad /target/tracked ({n} so far): {bad}", key="tracked")
        was_active = self.mission.active
        self.mission.observe(sighting)
        if was_active and not self.mission.active:
            self.tick()  # rejected: stop now

    def on_scan(self, msg: LaserScan) -> None:
        now = self.clock.monotonic()
        try:
            pts = frame_scan_points(spec.BASE_FRAME, msg.header.frame_id, msg.ranges, msg.angle_min,
                                    msg.angle_increment, msg.range_min, msg.range_max)  # fmt: skip
        except (ValueError, TypeError, OverflowError) as exc:
            n = self.count("bad_scan")
            self.log.throttled("error", 5.0, f"ignoring a bad {self.config.scan_topic} ({n} so far): {exc}", key="scan")
            self.mission.observe_scan(None, now)
            return
        self.mission.observe_scan(pts, now)

    def on_odom(self, msg: Odometry) -> None:
        self._odom_frame = msg.header.frame_id
        pose = msg.pose.pose
        q = pose.orientation
        yaw, now = quat_yaw(q.w, q.x, q.y, q.z), self.clock.monotonic()
        self.mission.observe_pose(pose.position.x, pose.position.y, yaw, now)
        stamp = msg.header.stamp.to_sec()
        self._poses.add(stamp + now - self.clock.now() if stamp > 0 else now, pose.position.x, pose.position.y, yaw)

    def on_way(self, msg: String) -> None:
        """An answer about one frame (perception/way.py): its whitelisted score over what that frame saw."""
        try:
            stamp, score = way_answer(msg.data, self._way_query)
            now = self.clock.monotonic()
            at = self._poses.at(stamp + now - self.clock.now())
        except (WayMessageRejected, ViewAnswerRejected, PoseUnavailable) as exc:
            n = self.count(f"way_rejected_{getattr(exc, 'reason', 'bad')}")
            self.log.throttled("warning", 5.0, f"ignoring a /vlm/way answer ({n} so far): {exc}", key="way")
            return
        self.explore.scored(at.x, at.y, at.yaw, score, self.mission.ctx.view)
        self.count("way_answers")

    def _in_odom_frame(self, frame: str, topic: str, key: str) -> bool:
        """A memory or map message in /odom's frame (or before any /odom); one in another is counted and ignored."""
        if not self._odom_frame or frame == self._odom_frame:
            return True
        n = self.count(f"{key}_wrong_frame")
        self.log.throttled("error", 5.0, f"ignoring {topic} in frame {frame!r} ({n} so far): /odom is in "
                           f"{self._odom_frame!r}", key=key)  # fmt: skip
        return False

    def on_objects(self, msg: Detection3DArray) -> None:
        if not self._in_odom_frame(msg.header.frame_id, self.config.objects_topic, "objects"):
            return
        shift = self.clock.monotonic() - self.clock.now()  # stamps -> this node's clock (0 on sim time)
        objs = [dataclasses.replace(r, last_seen=r.last_seen + shift)
                for r in map(remembered, msg.detections) if r is not None]  # fmt: skip
        stamp = msg.header.stamp.to_sec()
        self.mission.observe_memory(objs, stamp + shift if stamp > 0 else None, self.clock.monotonic())

    def on_costmap(self, msg: OccupancyGrid) -> None:
        """A new costmap for the global planner; a bad one (or one in another frame than /odom) is
        counted and ignored: the last good one stays."""
        try:
            g = grid_of(msg)
        except ValueError as exc:
            n = self.count("bad_costmap")
            self.log.throttled("error", 5.0, f"ignoring a bad {self.config.costmap_topic} ({n} so far): {exc}",
                               key="costmap")  # fmt: skip
            return
        if not self._in_odom_frame(g.frame_id, self.config.costmap_topic, "costmap"):
            return
        self.mission.observe_map(Costmap(g.cells, g.resolution, g.origin, stamp=self.clock.monotonic()))

    def on_decision(self, msg: String) -> None:
        m = self.mission
        before = m.counters["decisions_rejected"]
        m.decide(msg.data, self.clock.monotonic())
        if (n := m.counters["decisions_rejected"]) > before:
            self.log.throttled("warning", 5.0, f"ignored a VLM decision outside the schema ({n} so far): "
                               f"{m.last_decision}")  # fmt: skip
        self.tick()

    # -- control -------------------------------------------------------------------------------
    def tick(self) -> None:
        self._bound()
        intent = self.mission.step(self.clock.monotonic())
        if intent.query != self._query:
            self._query = intent.query
            self.pub_query.publish(String(data=intent.query))
        cfg = self.config
        if (way := way_query(intent.query, self.mission.state, cfg.explore, cfg.frontier_choice)) != self._way_query:
            self._way_query = way
            self.pub_way.publish(String(data=way))
        for posture in intent.postures:
            self.pub_go2.publish(String(data=posture))
        if intent.publish_cmd:
            self.pub_cmd.publish(Twist(linear=Vector3(x=float(intent.vx)), angular=Vector3(z=float(intent.wz))))
        route = self.mission.ctx.route if self.mission.active else None
        if route is not self._route:
            self._route = route
            self.publish_plan(route)
        if (intent.state, intent.reason) != self._last_key:
            self._last_state_log(intent)
            self.publish_status()

    def _bound(self) -> None:
        """Stop the goal when its lease ran out or it ran too long; refuse a go to beyond its cap."""
        m, now, cfg = self.mission, self.clock.monotonic(), self.config
        if not m.active or m.goal is None:
            return
        if (far := m.base_distance(now, cfg.max_go_to_m)) is None and (why := m.drop_far_memory(now, cfg.max_go_to_m)):
            self.log.warning(why)
        lease_why = self._lease.expired(time.monotonic()) if self._lease is not None else None
        end = goal_end(lease_why, self._goal_t0, now, cfg.max_goal_s, m.goal.kind, far, cfg.max_go_to_m)
        if end is not None:
            self.set_goal("stop")
            m.state, m.reason = end
            self.log.warning(f"goal ended: {m.reason}")

    def _last_state_log(self, intent: Intent) -> None:
        if self._last_key is not None and intent.state != self._last_key[0]:
            self.log.info(f"{self._last_key[0]} -> {intent.state}: {intent.reason}")

    # -- status --------------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        lease = None if self._lease is None else self._lease.status(time.monotonic())
        explore = self.explore.status() if self.config.explore else None
        out = commander_status(self.mission, self.clock.monotonic(), counters=self.counters, lease=lease,
                               explore=explore, route=self._route)  # fmt: skip
        if refused := self.input_refusals():  # inputs dropped for their size (msgs/sizes.py), with the reason
            out["refused_inputs"] = refused
        return out

    def publish_plan(self, route: Route | None) -> None:
        self.pub_plan.publish(route_path(route, self.clock.now(), self._odom_frame or "odom"))

    def publish_status(self) -> None:
        self._last_key = (self.mission.state, self.mission.reason)
        self.pub_status.publish(String(data=json.dumps(self.status(), ensure_ascii=False)))

    def close(self) -> None:
        # Leave the robot still: the gate also times the input out, this is just faster.
        try:
            self.pub_cmd.publish(Twist())
        except Exception:  # noqa: BLE001 - the writer may already be gone
            pass
