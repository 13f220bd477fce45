"""The simulated Go2 as a robot: the ROS node over the pure MuJoCo sim (sim/), and the Unitree DDS
bridge that answers Unitree's protocol as a real Go2 does."""

# go2vlm.sim picks the headless GL backend (MUJOCO_GL) and must run before sim_node imports mujoco:
# `go2vlm launch` imports the sim node first, and MuJoCo reads MUJOCO_GL only once.
import go2vlm.sim  # noqa: E402, F401
