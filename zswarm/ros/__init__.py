"""ROS 2 robots over Zenoh: the wire a ROS 2 robot speaks (rmw_zenoh or zenoh-bridge-ros2dds), the
robots file that maps agents to robots, and stand-in robots to rehearse a deployment with."""
