"""akd-top: a live terminal view of a bus's joints, over one data source (`source.Source`): a link run directly
(`direct.DirectSource`, no ROS) or a running akd_node attached over ROS (`ros_source.RosSource`)."""
