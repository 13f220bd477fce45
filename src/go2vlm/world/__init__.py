"""The world stage: what the VLM saw stays where it is in the world.

poses.py (the pose history: where was the robot at stamp t), placement.py (a grounded box at the pose
of its frame -> a world position), memory.py (the object memory: placed answers fused into objects),
memory_file.py (the memory on disk), labels.py (the one way labels are compared), and the
object_memory node over them (object_memory_node.py).
"""
