"""The navigator (navigator.py): route, controller, progress checker and recoveries, handed a place."""

from go2vlm.behavior.navigate.navigator import Navigator, NavStep
from go2vlm.behavior.navigate.params import NavParams

__all__ = ["NavParams", "NavStep", "Navigator"]
