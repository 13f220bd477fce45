"""The navigator (navigator.py): route, controller, progress checker and recoveries, handed a place."""

from go2vlm.behavior.navigate.navigator import Navigator, NavStep, in_view, line_of_sight
from go2vlm.behavior.navigate.params import NavParams

__all__ = ["NavParams", "NavStep", "Navigator", "in_view", "line_of_sight"]
