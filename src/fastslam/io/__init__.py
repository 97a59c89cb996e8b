"""ROS-free file I/O: bags (rosbags, lazy), CARMEN logs, map_server maps, PNG, trajectories."""
