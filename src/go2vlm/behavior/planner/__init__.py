"""The commander's planners: the local one (local.py: steer round what /scan shows on the way to a
goal) and the global one (global_path.py: the shortest safe path on the map's inflated costmap, in
waypoints; route.py: a plan being followed, and when to replan; sight.py: what a stand sees of a
place).
`from go2vlm.behavior.planner import steer` keeps naming the local planner."""

from go2vlm.behavior.planner.local import PlannerParams, Steer, corridor_free, steer

__all__ = ["PlannerParams", "Steer", "corridor_free", "steer"]
