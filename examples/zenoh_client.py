"""A client of akd_node over Zenoh with no ROS at all (run it with .venv-noros/bin/python): it reads /joint_states,
enables every joint (~/enable), moves each by 0.1 rad through ~/joint_commands and disables them, on the wire
rmw_zenoh uses, through akd_ros.zenoh: a session configured as rmw_zenoh's (the router at tcp/localhost:7447), a node
whose liveliness tokens ROS graph tools list, and messages made and read from their definitions (rosbags). The node
runs with transport zenoh (or both) on the same ROS_DOMAIN_ID.

    .venv/bin/akd-zenohd                                                      # a Zenoh router
    .venv-noros/bin/akd_node --ros-args --params-file config/akd_sim_6axis.yaml -p transport:=zenoh
    .venv-noros/bin/python examples/zenoh_client.py

ZENOH_SESSION_CONFIG_URI names a Zenoh configuration file to use instead, as it does for rmw_zenoh: one of those
`akd-access init` writes, for a node that listens with mutual TLS (docs/howto/access.md).
"""

import os
import sys
import time

from akd_ros.zenoh.entities import ZenohNode
from akd_ros.zenoh.session import open_session, router_warning, session_config
from akd_ros.zenoh.types import Types

NODE = sys.argv[1] if len(sys.argv) > 1 else "/akd_node"
JOINT_STATE = "sensor_msgs/msg/JointState"
TRIGGER = "std_srvs/srv/Trigger"
TIMEOUT_S = 30.0

types = Types()
# rmw_zenoh's default, or the file ZENOH_SESSION_CONFIG_URI names (e.g. akd-access's, to the node or its router);
# session_config(connect=["tcp/HOST:7447"]) for another router.
config_file = os.environ.get("ZENOH_SESSION_CONFIG_URI")
config = session_config(config_file)
session = open_session(config)
if not config_file and (warning := router_warning(session, config)):
    sys.exit(warning)
# ROS_DOMAIN_ID picks the domain as it does for rmw_zenoh (0 when unset).
client = ZenohNode(session, types, "akd_zenoh_client", domain=int(os.environ.get("ROS_DOMAIN_ID", "0")))
latest = []
client.subscription("/joint_states", JOINT_STATE, latest.append, deserialize=lambda c: types.from_cdr(c, JOINT_STATE))
commands = client.publisher(f"{NODE}/joint_commands", JOINT_STATE)


def wait_until(done, what: str) -> None:
    deadline = time.monotonic() + TIMEOUT_S
    while not done():
        if time.monotonic() > deadline:
            sys.exit(f"no {what} within {TIMEOUT_S} s: is akd_node running with transport zenoh?")
        time.sleep(0.05)


def trigger(service: str) -> str:
    """Calls a std_srvs/Trigger service of the node; its message, or exits with it when refused."""
    request = types.to_cdr(types.message(f"{TRIGGER}_Request"), f"{TRIGGER}_Request")
    reply = client.client(f"{NODE}/{service}", TRIGGER).call(request, TIMEOUT_S)
    if reply is None:
        sys.exit(f"no answer of {NODE}/{service} within {TIMEOUT_S} s")
    response = types.from_cdr(reply, f"{TRIGGER}_Response")
    if not response.success:
        sys.exit(f"{NODE}/{service}: {response.message}")
    return response.message


def command(positions: list[float]) -> None:
    message = types.message(JOINT_STATE, name=list(start.name), position=positions)
    commands.publish(types.to_cdr(message, JOINT_STATE))


wait_until(lambda: latest, "/joint_states")
print("enable:", trigger("enable"))
try:
    start = latest[-1]
    targets = [p + 0.1 for p in start.position]
    # A ramp of 0.1 rad over a second in steps of 1 mrad: the drive takes each step within one 1 ms cycle, and a few
    # commands delivered at once add up to one step, which must stay within max_velocity (6 mrad a cycle).
    for step in range(1, 101):
        command([p + 0.1 * step / 100 for p in start.position])
        time.sleep(0.01)
    wait_until(lambda: all(abs(p - t) < 1e-3 for p, t in zip(latest[-1].position, targets, strict=True)), "arrival")
    for name, position in zip(latest[-1].name, latest[-1].position, strict=True):
        print(f"{name}: {position:+.4f} rad")
finally:
    print("disable:", trigger("disable"))
client.close()
session.close()
