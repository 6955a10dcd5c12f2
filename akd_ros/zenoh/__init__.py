"""akd_node on Zenoh in rmw_zenoh's wire format, needing no ROS install: eclipse-zenoh, rosbags and xxhash only.

`wire` holds the format (key expressions, attachments, liveliness tokens, GIDs, QoS), pure; `types` the ROS types
(RIHS01 hashes, CDR, default messages) from rosbags' typestore; `session` the session as rmw_zenoh configures it;
`entities` a node's publishers, subscriptions and services on that session.
"""
