"""The commander's exploration wiring over real DDS: with a costmap on /map/costmap whose living room
is unknown, a look for that turn-and-look cannot finish walks to a frontier: state `exploring`, the
route on /plan (nav_msgs/Path, frame odom, from where the robot stands), the frontier and the
frontiers left on /commander/status. A bad costmap is counted and ignored (the last good one stays);
with explore off the goal ends not_found where it stands. With `frontier_choice: vlm` the commander
asks which way on /explore/way_query: a `likely` answer about a frame taken facing the far door makes
it walk there first; garbage answers are counted and ignored, and it takes the nearest door."""

from __future__ import annotations

import json
import math
import threading
import time

import numpy as np
from busutil import wait_for
from scipy import ndimage

from go2vlm.bus import QOS_DEFAULT, QOS_LATCHED, Node, running
from go2vlm.bus.topics import BEHAVIOR_CMD_VEL, COMMANDER_STATUS, EXPLORE_WAY_QUERY, MAP_COSTMAP, ODOM, PLAN, VLM_WAY
from go2vlm.launch.registry import make_node
from go2vlm.msgs.geometry_msgs import Point, Pose, PoseWithCovariance, Quaternion
from go2vlm.msgs.nav_msgs import OccupancyGrid, Odometry, Path
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.perception.way import way_message
from go2vlm.world.map_msg import grid_msg

RES = 0.05
ORIGIN = (-6.0, -3.5)


def kitchen_known() -> np.ndarray:
    """The two rooms' costmap with only the kitchen (x > 0) known; a 1.2 m door at x = 0, |y| < 0.6."""
    occ = np.zeros((140, 240), bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[:, 119:121] = True
    occ[58:82, 119:121] = False
    d = ndimage.distance_transform_edt(~occ) * RES
    cost = np.clip((0.8 - d) / 0.4 * 98, 0, 98).astype(np.int8)
    cost[d <= 0.43] = 99
    cost[d <= 0.2] = 100
    cost[:, :119] = -1
    return cost


def two_doors() -> np.ndarray:
    """The kitchen known only up to x = 5, with a second 1.2 m door there (|y| < 0.6), unknown beyond."""
    occ = np.zeros((140, 240), bool)
    occ[:2, :] = occ[-2:, :] = occ[:, :2] = occ[:, -2:] = True
    occ[:, 119:121] = occ[:, 219:221] = True
    occ[58:82, 119:121] = occ[58:82, 219:221] = False
    d = ndimage.distance_transform_edt(~occ) * RES
    cost = np.clip((0.8 - d) / 0.4 * 98, 0, 98).astype(np.int8)
    cost[d <= 0.43] = 99
    cost[d <= 0.2] = 100
    cost[:, :119] = cost[:, 221:] = -1
    return cost


class World(Node):
    """The robot standing in the kitchen (/odom at 20 Hz), the map's costmap (latched), and recorders."""

    name = "fake_world"

    def __init__(self, yaw: float = 0.0, **kw) -> None:
        super().__init__(**kw)
        self.yaw = yaw
        self.lock = threading.Lock()
        self.plans: list[Path] = []
        self.status: list[dict] = []
        self.cmds: list[tuple[float, float]] = []
        self.pub_odom = self.create_publisher(Odometry, ODOM.name, QOS_DEFAULT)
        self.pub_map = self.create_publisher(OccupancyGrid, MAP_COSTMAP.name, QOS_LATCHED)
        self.create_subscription(Path, PLAN.name, self._rec(self.plans), QOS_LATCHED)
        self.create_subscription(String, COMMANDER_STATUS.name, lambda m: self._rec(self.status)(json.loads(m.data)),
                                 QOS_LATCHED)  # fmt: skip
        BEHAVIOR_CMD_VEL.subscription(self,
                                 lambda m: self._rec(self.cmds)((m.linear.x, m.angular.z)))  # fmt: skip
        self.create_timer(0.05, self._odom)

    def _rec(self, into: list):
        def add(x) -> None:
            with self.lock:
                into.append(x)

        return add

    def _odom(self) -> None:
        q = Quaternion(w=math.cos(self.yaw / 2), z=math.sin(self.yaw / 2))
        pose = Pose(position=Point(x=3.0, y=-2.0), orientation=q)
        self.pub_odom.publish(Odometry(header=Header(frame_id="odom"), pose=PoseWithCovariance(pose=pose)))

    def state(self) -> dict:
        with self.lock:
            return self.status[-1] if self.status else {}


def test_look_for_explores_to_a_frontier_and_publishes_the_route() -> None:
    commander = make_node("commander", params={"search_timeout_s": 1.0})
    world = World()
    with running(world, commander):
        world.pub_map.publish(grid_msg(kitchen_known(), ORIGIN, RES, "odom", 1.0))
        assert wait_for(lambda: world.state().get("state") is not None, 10)
        commander.set_goal("look for the duck")
        assert wait_for(lambda: world.state().get("state") == "exploring", 15), world.state()
        st = world.state()
        assert st["explore"]["exploring"] and st["explore"]["frontier"] is not None
        assert st["explore"]["frontiers_left"] >= 1 and "frontier" in st["reason"]
        assert wait_for(lambda: any(p.poses for p in world.plans), 5)
        plan = next(p for p in reversed(world.plans) if p.poses)
        assert plan.header.frame_id == "odom" and len(plan.poses) >= 2
        first, last = plan.poses[0].pose.position, plan.poses[-1].pose.position
        assert (first.x, first.y) == (3.0, -2.0)
        assert abs(last.x) < 1.0 and abs(last.y) < 1.5  # the frontier is the open door
        assert st["plan"]["waypoints"] == len(plan.poses)
        assert wait_for(lambda: any(abs(wz) > 0.05 or vx > 0.0 for vx, wz in world.cmds[-5:]), 5)
        # A costmap turned against its frame: counted and ignored, the route stays. (One whose data does
        # not fit its size never gets past the bus's size check: msgs/sizes.py.)
        bad = grid_msg(kitchen_known(), ORIGIN, RES, "odom", 2.0)
        bad.info.origin.orientation.z, bad.info.origin.orientation.w = 0.7071, 0.7071
        world.pub_map.publish(bad)
        assert wait_for(lambda: world.state().get("counters", {}).get("bad_costmap") == 1, 5), world.state()
        assert world.state()["state"] in ("exploring", "detouring")
        commander.set_goal("stop")
        assert wait_for(lambda: world.plans and not world.plans[-1].poses, 5)  # the route ends: an empty /plan


def test_explore_off_ends_not_found_where_it_stands() -> None:
    commander = make_node("commander", params={"search_timeout_s": 1.0, "explore": False})
    world = World()
    with running(world, commander):
        world.pub_map.publish(grid_msg(kitchen_known(), ORIGIN, RES, "odom", 1.0))
        commander.set_goal("look for the duck")
        assert wait_for(lambda: world.state().get("state") == "not_found", 15), world.state()
        assert world.state()["explore"] is None
        assert all(vx == 0.0 for vx, _ in world.cmds)


def _explore_with_answers(answers: list[str]) -> tuple[dict, dict]:
    """Look for the duck with frontier_choice vlm, facing the far (west) door from (3, -2), and these
    raw answers (each in a /vlm/way envelope, unless it is not JSON at all) about frames taken
    now; the status once it explores (its frontier), and the counters."""
    west = math.atan2(0.0 - -2.0, 0.0 - 3.0)  # the bearing to the west door: 146 deg
    commander = make_node("commander", params={"search_timeout_s": 4.0, "frontier_choice": "vlm"})
    world = World(yaw=west)
    queries: list[str] = []
    EXPLORE_WAY_QUERY.subscription(world, lambda m: queries.append(m.data))
    pub = VLM_WAY.publisher(world)
    with running(world, commander):
        world.pub_map.publish(grid_msg(two_doors(), ORIGIN, RES, "odom", 1.0))
        assert wait_for(lambda: world.state().get("state") is not None, 10)
        assert wait_for(lambda: len(commander._poses) >= 10, 10)  # half a second of /odom: the frame's heading
        commander.set_goal("look for the duck")
        assert wait_for(lambda: queries and queries[-1] == "duck", 10), queries
        for text in answers:  # a frame 0.2 s ago (wall time stamps: this commander runs on wall time)
            data = text if text.startswith("!") else way_message(time.time() - 0.2, "duck", text)
            pub.publish(String(data=data))
        n = len(answers)
        counted = lambda: sum(v for k, v in world.state().get("counters", {}).items() if k.startswith("way_"))  # noqa: E731
        assert wait_for(lambda: counted() >= n, 10), world.state()
        assert wait_for(lambda: world.state().get("state") == "exploring", 15), world.state()
        st = world.state()
        commander.set_goal("stop")
        assert wait_for(lambda: queries[-1] == "", 5), queries  # no goal, no question
    return st["explore"]["frontier"], st["counters"]


def test_a_likely_way_picks_the_far_door_first() -> None:
    frontier, counters = _explore_with_answers(["likely"])
    assert counters.get("way_answers") == 1
    assert frontier["goal"][0] < 1.5, frontier  # the west door at x = 0, not the nearer one at x = 5


def test_garbage_answers_are_counted_and_the_nearest_door_comes_first() -> None:
    garbage = ["go left through the door at 2 m/s", '{"way": "likely", "speed": 2}', "!not json"]
    frontier, counters = _explore_with_answers(garbage)
    assert counters.get("way_answers", 0) == 0
    assert counters["way_rejected_not_whitelisted"] == 1 and counters["way_rejected_bad_object"] == 1
    assert counters["way_rejected_way_not_json"] == 1
    assert frontier["goal"][0] > 3.5, frontier  # the east door at x = 5: nearest
