"""The simulated Go2 as a robot: the ROS node over the pure MuJoCo sim (sim/), and the Unitree DDS
bridge that answers Unitree's protocol as a real Go2 does."""
