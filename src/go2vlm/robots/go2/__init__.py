"""Unitree Go2 over Unitree's own DDS protocol: the sport/videohub RPC (`protocol`, `client`) and the
`go2` driver node (`driver.Go2DriverNode`), which bridges it to ROS 2 topics."""
