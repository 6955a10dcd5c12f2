"""`akd_node`: the AKD axes of one EtherCAT line in ROS 2, a lifecycle (managed) node over `akd_ros.Bus`.

One joint (no `joints` parameter: its topics and services under ~/) or a robot of several (`joints`, each with its
block joints.<name>.* and its topics and services under ~/<joint>/). Topics: /joint_states (sensor_msgs/JointState,
SI, every joint of one cycle), /diagnostics (a status per joint and one of the bus), per joint status (DriveStatus),
latch (LatchEvent) and fault (DriveFault) and the commands position_command, velocity_command and torque_command
(std_msgs/Float64, SI); ~/joint_commands (sensor_msgs/JointState by name), ~/joint_trajectory
(trajectory_msgs/JointTrajectory, interpolated by the cycle thread) and ~/trajectory_status (TrajectoryStatus).
Services: ~/enable, ~/disable, ~/reset_fault, ~/quick_stop (std_srvs/Trigger, every joint at once), and per joint the
same four, set_mode, arm_latch, sdo_read and sdo_write (the package's own).

One module per job, each a part that the node's `Core` is made of:

- `command_line`: `main`, akd_node's entry point: its help, its parameters, the runner its transport needs (`ros_node`
  over rclpy, `zenoh_node` on Zenoh alone);
- `core`: `Core`, the parts over a transport and the transitions (configure opens the Bus, close closes it);
- `lifecycle`: `AkdNode`, the rclpy LifecycleNode that runs a Core on rclpy (`transports.ros_transport`);
- `transports`: what the parts need of a middleware (`transport`: `Transport`, `Qos`) and the middlewares: rclpy
  (`ros_transport`), Zenoh (`zenoh_transport`), both (`both_transport`);
- `doors`: the transport the parts declare their doors on: those of the roles `doors` opens, each request recorded on
  ~/access;
- `publishing`: /joint_states, each joint's status (made by the crate) and its events (latch, fault);
- `diagnostics`: /diagnostics;
- `commands`: the command topics, their refusal and time-out, the automatic fault reset, the drive requests;
- `trajectories`: ~/joint_trajectory and ~/trajectory_status;
- `services`: the services over those requests;
- `recording`: the bag of everything published and received, and of every cycle of every joint (`record.*`);
- `live_view`: everything published, served to Foxglove over its WebSocket protocol, view only (`live_view.*`);
  `foxglove_layout` the Foxglove layout of a node's joints, for it and for the bags;
- `clock`: stamps, the cycle thread's monotonic times moved onto the ROS clock;
- `threads`: the node's Python threads, named in the operating system as the crate's are, giving the GIL up quickly;
- `node_state`: what the parts share (the settings, the clock; from configure to cleanup the Bus, the Recorder, the
  lock).

Threads. The cycle thread and, beside it, the crate's feed (/joint_states and the statuses made from the cycle's
snapshot) and the bag's writer (every cycle's records and what is published, written to the bag) never need Python.
In Python: the publishing thread (`publishing`) hands the feed's messages to the middleware and takes the cycle's
events when the feed says there are some; three callback groups: the periodic group (/diagnostics, the trajectories'
status), the command group (the command subscriptions, queued 100 deep so a stall of the Python side delays commands
rather than drops them) and the request group (services, the supervisor that handles automatic fault resets), which
may wait up to the axes' time-outs. Over rclpy a SingleThreadedExecutor takes every message and runs the command
callbacks itself, while services run on the request group's thread (`transports.worker`) and timers on their group's,
so nothing that waits or takes long is ever in front of a command; over Zenoh each group is such a thread. Every
Python thread gives the GIL up within `threads.GIL_SWITCH_INTERVAL_S` when another wants it. The node state's lock
guards the axes' Python-side state (position unwrapping, event queues, the last command) between them.
"""

# akd_node's entry point where a console script installed before `command_line` held it names it akd_ros.node:main
# (setup.py now names akd_ros.node.command_line:main).
from akd_ros.node.command_line import main

__all__ = ["main"]
