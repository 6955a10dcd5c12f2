"""An interpreter without ROS: with this directory on PYTHONPATH, Python imports this module at start-up (site's
sitecustomize), and from then on importing a ROS package raises ImportError, as it would where no ROS wheel is
installed.

Blocked: rclpy and the rest of rcl (rcl_*), rosidl* and rmw*, the interface packages (*_msgs, *_srvs,
*_interfaces: builtin_interfaces, std_msgs, sensor_msgs, rcl_interfaces...), ament_index_python and launch_ros, and
this package's generated interfaces akd_ros.msg and akd_ros.srv. rosbags, a reader of ROS data that needs no ROS, is
not blocked. `BLOCKED` tells a test that the blocker is in place.
"""

from __future__ import annotations

import sys
from importlib.abc import MetaPathFinder

BLOCKED = True
_PREFIXES = ("rclpy", "rcl_", "rosidl", "rmw", "ament_index", "launch_ros")
_SUFFIXES = ("_msgs", "_srvs", "_interfaces")
_MODULES = ("rcl", "akd_ros.msg", "akd_ros.srv")


def is_ros(name: str) -> bool:
    """Whether importing the module `name` is refused: a ROS package or one of the package's generated
    interfaces."""
    top = name.partition(".")[0]
    return (
        top.startswith(_PREFIXES)
        or top.endswith(_SUFFIXES)
        or any(name == module or name.startswith(f"{module}.") for module in _MODULES)
    )


class NoRos(MetaPathFinder):
    """Refuses every ROS module (`is_ros`) before any other finder looks for it."""

    def find_spec(self, fullname: str, path: object, target: object = None) -> None:
        """Raises ImportError for a ROS module; None (not found here) for the rest."""
        if is_ros(fullname):
            raise ImportError(f"No module named {fullname!r} (ROS is blocked: tests/support/no_ros)", name=fullname)


sys.meta_path.insert(0, NoRos())
