"""`go2vlm view` shows the map: a real map node's latched /map and /map/costmap reach a Foxglove client
as nav_msgs/OccupancyGrid (CDR, the ROS schema Foxglove's 3D panel draws), also to a client that
connects after they were published."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import websockets
from busutil import Procs, wait_for
from test_view import SUBPROTOCOL, Client, server_port

from go2vlm.bus import Node, running
from go2vlm.bus.topics import MAP, MAP_COSTMAP, MAP_STATUS, ODOM, SCAN
from go2vlm.launch.registry import make_node
from go2vlm.msgs.nav_msgs import OccupancyGrid, Odometry
from go2vlm.msgs.sensor_msgs import LaserScan
from go2vlm.msgs.std_msgs import Header, String
from go2vlm.world.map_msg import grid_of
from go2vlm.world.occupancy import INSCRIBED


def test_the_view_serves_the_map_and_its_costmap(procs: Procs) -> None:
    mapper = make_node("map", params={"publish_period_s": 0.2})
    robot = Node(node_name="fake_robot")
    odom, scan = ODOM.publisher(robot), SCAN.publisher(robot)
    statuses: list[String] = []
    MAP_STATUS.subscription(robot, lambda m: statuses.append(m))

    def tick() -> None:  # standing still at the origin, a wall 2.01 m ahead and behind
        t = robot.now()
        odom.publish(Odometry(header=Header(stamp=robot.stamp(t), frame_id="odom"), child_frame_id="base_link"))
        ranges = [2.01 / abs(math.cos(a)) if abs(math.cos(a)) > 0.5 else math.inf
                  for a in -math.pi + 2 * math.pi / 180 * np.arange(180)]  # fmt: skip
        scan.publish(LaserScan(header=Header(stamp=robot.stamp(t - 0.02), frame_id="base_link"),
                                   angle_min=-math.pi, angle_increment=2 * math.pi / 180, range_min=0.05,
                                   range_max=10.0, ranges=ranges))  # fmt: skip

    robot.create_timer(0.05, tick)
    with running(robot, mapper):
        assert wait_for(lambda: bool(statuses) and '"published": 0' not in statuses[-1].data, 20)
        view = procs.start("view", "--port", "0")  # after the map was published: latched, it still comes
        port = server_port(view)

        async def session() -> Client:
            async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], max_size=None) as ws:
                c = Client(ws)
                wanted = (MAP.name, MAP_COSTMAP.name)
                assert await c.pump(lambda: all(t in c.channels for t in wanted), 60), sorted(c.channels)
                missing = list(wanted)
                for _ in range(4):
                    await c.subscribe(*missing)
                    await c.pump(lambda: all(c.received.get(t) for t in wanted), 15)
                    missing = [t for t in wanted if not c.received.get(t)]
                    if not missing:
                        break
                assert not missing, (missing, c.statuses)
                return c

        c = asyncio.run(session())
    for topic in (MAP.name, MAP_COSTMAP.name):
        assert c.channels[topic]["schemaName"] == "nav_msgs/msg/OccupancyGrid"
        assert c.channels[topic]["encoding"] == "cdr" and c.channels[topic]["schemaEncoding"] == "ros2msg"
    grid = grid_of(OccupancyGrid.deserialize(c.received[MAP.name][-1]))
    assert (
        grid.frame_id == "odom"
        and grid.cells[grid.cell_of(2.02, 0.0)] == 100
        and grid.cells[grid.cell_of(1.0, 0.0)] == 0
    )
    cost = grid_of(OccupancyGrid.deserialize(c.received[MAP_COSTMAP.name][-1]))
    assert cost.cells[cost.cell_of(1.9, 0.0)] >= INSCRIBED  # 0.12 m from the wall: never entered
