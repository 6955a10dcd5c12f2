"""akd_ros's interfaces as C++ programs and ROS's own tools find them: the C++ headers and type supports, the .idl
files and the ament index entries that setup.py (rosidl_build.py) installs.

A C++ program, compiled here with g++ against the installed headers and linked to the C++ type-support dispatch
library only, fills one message of each type with the values rclpy's samples hold, serialises it with
rmw_fastrtps_cpp's rmw_serialize (the C++ type support found through
rosidl_typesupport_cpp::get_message_type_support_handle<T>(), as rclcpp and rosbag2 find it) and prints the bytes;
it also reads rclpy's bytes back with rmw_deserialize, serialises what it read again, and lists the members the C++
introspection type support describes. The test compares all three with rclpy's serialize_message and field list.
No DDS participant is made: serialisation needs none. Fast CDR skips CDR's alignment padding without writing it (the
bytes keep whatever the buffer held, in rclpy's serialisation as in the C++ one), so the comparison leaves out the
padding bytes, whose offsets it computes from the message's type; every other byte and the length must be equal.

The interfaces are looked up as `ros2 interface list/show` and rosidl_runtime_py look them up (neither has a PyPI
wheel): the ament index's rosidl_interfaces resource names the package's files, the package's share directory holds
them, and rosidl_parser reads the installed .idl.
"""

from __future__ import annotations

import importlib
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_prefix, get_package_share_directory
from ament_index_python.resources import get_resource, get_resources, has_resource
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from rosidl_parser.definition import IdlLocator, Message
from rosidl_parser.parser import parse_idl_file
from std_msgs.msg import Header

import akd_ros
from akd_ros.msg import TrajectoryStatus
from test_messages import answer, requests, samples

REPO = Path(__file__).resolve().parents[1]
# The installed package's prefix: the virtual environment for `pip install -e .` (scripts/setup.sh), as
# AMENT_PREFIX_PATH names a sourced ROS install or colcon workspace.
PREFIX = Path(sys.prefix)
PACKAGE_DIR = Path(akd_ros.__file__).resolve().parent
COMPILE_TIMEOUT_S = 300
RUN_TIMEOUT_S = 60


@pytest.fixture(autouse=True)
def ament_prefix_path(monkeypatch):
    """AMENT_PREFIX_PATH as a ROS install's setup.bash sets it, the venv after any prefix already there."""
    entries = [entry for entry in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if entry]
    monkeypatch.setenv("AMENT_PREFIX_PATH", os.pathsep.join(dict.fromkeys([*entries, str(PREFIX)])))


def cases() -> dict[str, object]:
    """Every message and service request and response type, each with its fields away from their defaults."""
    messages = samples()
    messages["TrajectoryStatus"] = TrajectoryStatus(
        header=Header(stamp=Time(sec=-5, nanosec=1), frame_id="world"),
        id=4_000_000_000,
        state="aborted",
        joints=["axis_1", "axis_2", "", "ünïcode"],
        point=2,
        points=3,
        elapsed=math.inf,
        duration=-0.0,
        replaced_by=7,
        message="axis_2: fault (F125)",
    )
    for name, request in requests().items():
        messages[f"{name}_Request"] = request
        messages[f"{name}_Response"] = answer(name, request)
    return messages


def cpp_literal(value) -> str:
    """value as a C++ expression that assigns exactly that value to a member of its ROS type."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        # Through unsigned long long or long long, so that 2**64-1 and -2**63 are no overflowing literals.
        return f"{value}ULL" if value >= 0 else f"(-{-value - 1}LL - 1)"
    if isinstance(value, float):
        if math.isnan(value):
            return "std::numeric_limits<double>::quiet_NaN()"
        if math.isinf(value):
            return f"{'-' if value < 0 else ''}std::numeric_limits<double>::infinity()"
        return repr(value)  # the shortest text that reads back as the same double
    if isinstance(value, str):
        return '"' + "".join(f"\\{byte:03o}" for byte in value.encode("utf-8")) + '"'
    raise TypeError(f"no C++ literal for {value!r}")


def cpp_assignments(message, path: str = "m") -> list[str]:
    """C++ statements that set every field of the C++ object at path to message's values."""
    statements = []
    for field in type(message).get_fields_and_field_types():
        value, target = getattr(message, field), f"{path}.{field}"
        if hasattr(type(value), "get_fields_and_field_types"):
            statements += cpp_assignments(value, target)
        elif isinstance(value, (str, int, float)):
            statements.append(f"{target} = static_cast<decltype({target})>({cpp_literal(value)});")
        else:  # a sequence or array: rclpy's list, array.array or numpy array
            items = (element.item() if hasattr(element, "item") else element for element in value)
            elements = ", ".join(cpp_literal(item) for item in items)
            statements.append(f"{target} = {{{elements}}};")
    return statements


def cpp_type(message) -> tuple[str, str]:
    """The C++ class of message's type and its header (akd_ros::msg::LatchEvent, akd_ros/msg/latch_event.hpp)."""
    package, kind, module = type(message).__module__.split(".")
    return f"{package}::{kind}::{type(message).__name__}", f"{package}/{kind}/{module.lstrip('_')}.hpp"


# Size (and CDR alignment) of each primitive type, by its rosidl name.
PRIMITIVE_SIZES = {
    **dict.fromkeys(("boolean", "octet", "char", "uint8", "int8"), 1),
    **dict.fromkeys(("uint16", "int16", "wchar"), 2),
    **dict.fromkeys(("uint32", "int32", "float"), 4),
    **dict.fromkeys(("uint64", "int64", "double"), 8),
}
CDR_HEADER = 4  # the encapsulation kind and options before the data, which alignment counts from


def padding_offsets(message) -> tuple[set[int], int]:
    """The offsets of the alignment padding in message's CDR serialisation, and the serialisation's length."""
    padding: set[int] = set()
    position = 0

    def align(size: int) -> None:
        nonlocal position
        while position % size:
            padding.add(CDR_HEADER + position)
            position += 1

    def value(type_name: str, item) -> None:
        nonlocal position
        array = re.fullmatch(r"(.+)\[(\d+)\]", type_name)
        if type_name.startswith("sequence<") or array:
            if not array:
                align(4)  # the element count
                position += 4
            element_type = array.group(1) if array else type_name[len("sequence<") : -1].split(",")[0]
            for element in item:
                value(element_type, element)
        elif type_name.startswith(("string", "wstring")):
            align(4)
            position += 4 + len(item.encode("utf-8")) + 1
        elif type_name in PRIMITIVE_SIZES:
            align(PRIMITIVE_SIZES[type_name])
            position += PRIMITIVE_SIZES[type_name]
        else:
            fields(item)

    def fields(nested) -> None:
        for field, type_name in type(nested).get_fields_and_field_types().items():
            value(type_name, getattr(nested, field))

    fields(message)
    return padding, CDR_HEADER + position


def without_padding(serialized_hex: str, padding: set[int], length: int) -> str:
    """The serialisation's bytes (hex) with the padding bytes, and any after length, replaced by '..'."""
    return "".join(
        ".." if i in padding or i >= length else serialized_hex[2 * i : 2 * i + 2]
        for i in range(len(serialized_hex) // 2)
    )


PROGRAM_HEAD = r"""
#include <cstdio>
#include <iostream>
#include <limits>
#include <map>
#include <string>

#include "rcutils/allocator.h"
#include "rmw/rmw.h"
#include "rmw/serialized_message.h"
#include "rosidl_runtime_c/message_type_support_struct.h"
#include "rosidl_typesupport_cpp/message_type_support.hpp"
#include "rosidl_typesupport_introspection_cpp/identifier.hpp"
#include "rosidl_typesupport_introspection_cpp/message_introspection.hpp"
"""

PROGRAM_BODY = r"""
static std::string hex(const rmw_serialized_message_t & bytes) {
  static const char digits[] = "0123456789abcdef";
  std::string text;
  for (size_t i = 0; i < bytes.buffer_length; ++i) {
    text += digits[bytes.buffer[i] >> 4];
    text += digits[bytes.buffer[i] & 0xF];
  }
  return text;
}

static void fail(const std::string & name, const char * what) {
  std::cerr << name << ": " << what << ": " << rcutils_get_error_string().str << std::endl;
  std::exit(1);
}

// Prints NAME cpp|roundtrip|members ...: the bytes rmw_serialize makes of message, the bytes of rclpy's
// serialisation read back with rmw_deserialize and serialised again, and the members introspection lists.
template<typename T>
static void report(const std::string & name, const T & message, const std::map<std::string, std::string> & python) {
  const rosidl_message_type_support_t * type_support = rosidl_typesupport_cpp::get_message_type_support_handle<T>();
  rcutils_allocator_t allocator = rcutils_get_default_allocator();
  rmw_serialized_message_t bytes = rmw_get_zero_initialized_serialized_message();
  if (rmw_serialized_message_init(&bytes, 0, &allocator) != RMW_RET_OK) fail(name, "init");
  if (rmw_serialize(&message, type_support, &bytes) != RMW_RET_OK) fail(name, "rmw_serialize");
  std::cout << name << " cpp " << hex(bytes) << std::endl;

  const std::string & theirs = python.at(name);
  rmw_serialized_message_t input = rmw_get_zero_initialized_serialized_message();
  if (rmw_serialized_message_init(&input, theirs.size() / 2, &allocator) != RMW_RET_OK) fail(name, "init");
  for (size_t i = 0; i < theirs.size() / 2; ++i) {
    input.buffer[i] = static_cast<uint8_t>(std::stoul(theirs.substr(2 * i, 2), nullptr, 16));
  }
  input.buffer_length = theirs.size() / 2;
  T read;
  if (rmw_deserialize(&input, type_support, &read) != RMW_RET_OK) fail(name, "rmw_deserialize");
  if (rmw_serialize(&read, type_support, &bytes) != RMW_RET_OK) fail(name, "rmw_serialize");
  std::cout << name << " roundtrip " << hex(bytes) << std::endl;

  const rosidl_message_type_support_t * introspection =
    get_message_typesupport_handle(type_support, rosidl_typesupport_introspection_cpp::typesupport_identifier);
  if (introspection == nullptr) fail(name, "no introspection type support");
  auto members = static_cast<const rosidl_typesupport_introspection_cpp::MessageMembers *>(introspection->data);
  std::cout << name << " members";
  for (uint32_t i = 0; i < members->member_count_; ++i) std::cout << " " << members->members_[i].name_;
  std::cout << std::endl;
  if (rmw_serialized_message_fini(&input) != RMW_RET_OK) fail(name, "fini");
  if (rmw_serialized_message_fini(&bytes) != RMW_RET_OK) fail(name, "fini");
}

int main() {
  std::map<std::string, std::string> python;  // NAME HEX lines on stdin: rclpy's serialisation
  std::string name, bytes;
  while (std::cin >> name >> bytes) python[name] = bytes;
"""


def program(messages: dict[str, object]) -> str:
    """The C++ program's source: one block per message, filling it and reporting it."""
    headers = sorted({cpp_type(message)[1] for message in messages.values()})
    blocks = []
    for name, message in messages.items():
        statements = "\n    ".join(cpp_assignments(message))
        blocks.append(f'  {{\n    {cpp_type(message)[0]} m;\n    {statements}\n    report("{name}", m, python);\n  }}')
    includes = "".join(f'#include "{header}"\n' for header in headers)
    return PROGRAM_HEAD + includes + PROGRAM_BODY + "\n".join(blocks) + "\n  return 0;\n}\n"


@pytest.fixture(scope="module")
def cpp_reports(tmp_path_factory) -> dict[tuple[str, str], str]:
    """The C++ program's output for cases(), keyed by (message name, report kind)."""
    messages = cases()
    build = tmp_path_factory.mktemp("cpp")
    source = build / "serialize.cpp"
    source.write_text(program(messages), encoding="utf-8")
    include = PREFIX / "include"
    lib = PREFIX / "lib"
    compile_command = [
        "g++",
        "-std=c++17",
        "-Wall",
        "-Werror",
        str(source),
        "-o",
        str(build / "serialize"),
        *(f"-I{directory}" for directory in sorted(include.iterdir()) if directory.is_dir()),
        f"-L{PACKAGE_DIR}",
        f"-L{lib}",
        "-lakd_ros__rosidl_typesupport_cpp",
        "-lrmw_fastrtps_cpp",
        "-lrmw",
        "-lrosidl_typesupport_introspection_cpp",
        "-lrosidl_runtime_c",
        "-lrcutils",
        f"-Wl,-rpath,{PACKAGE_DIR}:{lib}",
    ]
    compiled = subprocess.run(compile_command, capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S, check=False)
    assert compiled.returncode == 0, f"g++ {source}:\n{compiled.stderr[-6000:]}"
    python_bytes = "".join(f"{name} {serialize_message(message).hex()}\n" for name, message in messages.items())
    ran = subprocess.run(
        [str(build / "serialize")],
        input=python_bytes,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
        check=False,
    )
    assert ran.returncode == 0, ran.stderr
    reports = {}
    for line in ran.stdout.splitlines():
        name, kind, value = [*line.split(" ", 2), ""][:3]
        reports[name, kind] = value
    return reports


@pytest.mark.parametrize("name", sorted(cases()))
def test_cpp_type_support_serializes_as_rclpy_does(cpp_reports, name):
    message = cases()[name]
    padding, length = padding_offsets(message)
    ours = serialize_message(message).hex()
    # A fixed-size type's serialisation is padded at the end to a whole 4 bytes.
    assert length <= len(ours) // 2 <= -(-length // 4) * 4, f"{name}: the padding walk does not match rclpy's bytes"
    assert without_padding(cpp_reports[name, "cpp"], padding, length) == without_padding(ours, padding, length), (
        f"{name}: rmw_serialize of the C++ message differs from rclpy's serialize_message"
    )
    assert without_padding(cpp_reports[name, "roundtrip"], padding, length) == without_padding(ours, padding, length), (
        f"{name}: rclpy's bytes, read by the C++ type support and written again, differ"
    )
    fields = list(type(message).get_fields_and_field_types())
    assert cpp_reports[name, "members"].split() == fields


def test_ament_index_lists_the_interfaces_as_rosidl_generate_interfaces_does():
    assert has_resource("packages", "akd_ros")
    assert "akd_ros" in get_resources("rosidl_interfaces")
    content, prefix = get_resource("rosidl_interfaces", "akd_ros")
    assert Path(prefix) == Path(get_package_prefix("akd_ros"))
    definitions = sorted(
        str(path.relative_to(REPO)) for kind in ("msg", "srv", "action") for path in (REPO / kind).glob("*.*")
    )
    expected = sorted([*definitions, *(str(Path(d).with_suffix(".idl")) for d in definitions)])
    assert content.splitlines() == expected


def test_interfaces_are_found_and_read_like_ros2_interface_show():
    """`ros2 interface list` lists the index's .msg/.srv entries; `show` prints the installed file; rosidl_parser
    reads the installed .idl into the members rclpy's class has."""
    content, _ = get_resource("rosidl_interfaces", "akd_ros")
    share = Path(get_package_share_directory("akd_ros"))
    listed = [entry for entry in content.splitlines() if entry.endswith((".msg", ".srv"))]
    assert len(listed) == len(list((REPO / "msg").glob("*.msg"))) + len(list((REPO / "srv").glob("*.srv")))
    for entry in listed:
        assert (share / entry).read_text(encoding="utf-8") == (REPO / entry).read_text(encoding="utf-8"), entry
        description = share / Path(entry).with_suffix(".json")
        assert description.stat().st_size > 0, f"{description}: the type description is missing"
    for entry in (e for e in listed if e.startswith("msg/")):
        idl = parse_idl_file(IdlLocator(share, Path(entry).with_suffix(".idl")))
        message = next(element for element in idl.content.elements if isinstance(element, Message))
        python_class = getattr(importlib.import_module("akd_ros.msg"), message.structure.namespaced_type.name)
        assert [member.name for member in message.structure.members] == list(
            python_class.get_fields_and_field_types()
        ), entry


def test_cpp_headers_are_installed_where_ros_puts_them():
    """include/akd_ros/akd_ros/<kind>/<name>.hpp|.h beside each other, as rosidl_generate_interfaces installs them."""
    root = PREFIX / "include" / "akd_ros" / "akd_ros"
    for message in cases().values():
        header = root / cpp_type(message)[1].split("/", 1)[1]
        assert header.is_file(), header
        assert header.with_suffix(".h").is_file(), header.with_suffix(".h")
