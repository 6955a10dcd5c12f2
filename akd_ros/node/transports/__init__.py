"""The middlewares the node's parts run on, each behind the same interface (`transport`: `Transport`, `Qos`,
`ActionCallbacks`): `ros_transport` over rclpy, `zenoh_transport` over Zenoh in rmw_zenoh's wire format without ROS,
`both_transport` over both at once; `worker` the callback group as a thread of its own that they run timers and
callbacks on. The parts ask their transport and never import a middleware; this package imports none itself, so a
node on Zenoh alone never imports rclpy."""
