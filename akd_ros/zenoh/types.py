"""The ROS types akd_node speaks over Zenoh, without rclpy: rosbags' typestore for Jazzy plus this package's own
msg/ and srv/ definitions, giving each type's RIHS01 hash, CDR bytes and messages with default values.

rmw_zenoh names every topic by its type's RIHS01 hash and carries plain CDR (with its 4-byte encapsulation
header), so a typestore that knows the definitions is all a node without ROS needs: rosbags hashes a definition
as rosidl does (`hash_rihs01`) and serialises it without ROS. Services are not messages to rosbags; this module
registers the types rosidl derives from a .srv (`<Name>_Request`, `<Name>_Response`, `<Name>_Event` and the
service's own description with its three members) so that rosbags hashes a service as rosidl does too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np
from rosbags.interfaces import Nodetype
from rosbags.serde import SerdeError
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

PACKAGE = "akd_ros"
# Standard services the node serves whose definitions rosbags' Jazzy store lacks (it holds messages only);
# field names and types are all a hash depends on.
STANDARD_SERVICES = {
    "std_srvs/srv/Trigger": "---\nbool success\nstring message\n",
}


def interface_dir() -> Path:
    """Where this package's msg/ and srv/ are: beside akd_ros/ in a source tree (an editable install), else in
    share/akd_ros of the installation prefix the package sits under (setup.py's data_files, colcon's install)."""
    package = Path(__file__).resolve().parents[1]
    candidates = [package.parent, *(prefix / "share" / PACKAGE for prefix in package.parents)]
    for candidate in candidates:
        if (candidate / "msg").is_dir() and (candidate / "srv").is_dir():
            return candidate
    raise FileNotFoundError(f"{PACKAGE}'s msg/ and srv/ are neither beside {package} nor in a share/{PACKAGE} above it")


class UnknownTypeError(ValueError):
    """A type name the typestore does not know, or a definition it cannot read."""


class PayloadError(ValueError):
    """Bytes that are not valid CDR of the type they were read as."""


class Types:
    """A typestore: rosbags' Jazzy types, the standard services above and the given package definitions."""

    def __init__(self, package_dirs: Mapping[str, Path] | None = None) -> None:
        """package_dirs maps a package name to its directory holding msg/ and srv/; by default this package's."""
        self.store: Typestore = get_typestore(Stores.ROS2_JAZZY)
        # rosidl reads a .msg `char` as uint8 (rosidl_adapter), rosbags keeps it a char, which hashes differently
        # (service_msgs/msg/ServiceEventInfo's client_gid, in every service's hash): read it as rosidl does.
        for typename, definition in list(self.store.fielddefs.items()):
            self.store.fielddefs[typename] = _char_as_uint8(definition)
        for name, text in STANDARD_SERVICES.items():
            self.register_service(name, text)
        for package, directory in (package_dirs or {PACKAGE: interface_dir()}).items():
            self.register_package(package, Path(directory))

    def register_package(self, package: str, directory: Path) -> None:
        """Registers every msg/*.msg and srv/*.srv of a package."""
        messages = sorted((directory / "msg").glob("*.msg"))
        for path in messages:
            self.register(get_types_from_msg(path.read_text(encoding="utf-8"), f"{package}/msg/{path.stem}"))
        for path in sorted((directory / "srv").glob("*.srv")):
            self.register_service(f"{package}/srv/{path.stem}", path.read_text(encoding="utf-8"))

    def register_service(self, name: str, text: str) -> None:
        """Registers a service from its .srv text, with the types rosidl derives from it."""
        lines = text.splitlines()
        separators = [index for index, line in enumerate(lines) if line.strip() == "---"]
        if len(separators) != 1:
            raise UnknownTypeError(f"service definition {name} has {len(separators)} '---' lines, expected 1")
        request = "\n".join(lines[: separators[0]])
        response = "\n".join(lines[separators[0] + 1 :])
        # rosbags reads definitions of messages only (pkg/msg/Name): parse under such names, then rename.
        package, _, service = name.split("/")
        parsed = {
            "Request": get_types_from_msg(request, f"{package}/msg/{service}_Request"),
            "Response": get_types_from_msg(response, f"{package}/msg/{service}_Response"),
            "Event": get_types_from_msg(
                f"service_msgs/msg/ServiceEventInfo info\n{package}/msg/{service}_Request[<=1] request\n"
                f"{package}/msg/{service}_Response[<=1] response\n",
                f"{package}/msg/{service}_Event",
            ),
            "": get_types_from_msg(
                f"{package}/msg/{service}_Request request_message\n{package}/msg/{service}_Response response_message\n"
                f"{package}/msg/{service}_Event event_message\n",
                f"{package}/msg/{service}",
            ),
        }
        renames = {
            f"{package}/msg/{service}{suffix}": f"{name}{suffix}" for suffix in ("", "_Request", "_Response", "_Event")
        }
        for typesdict in parsed.values():
            self.register(_renamed(typesdict, renames))

    def register(self, typesdict: Mapping[str, tuple]) -> None:
        """Registers types parsed from .msg text, `char` read as rosidl reads it."""
        self.store.register({typename: _char_as_uint8(definition) for typename, definition in typesdict.items()})

    def _known(self, typename: str) -> str:
        if typename not in self.store.fielddefs:
            raise UnknownTypeError(
                f"type {typename!r} is not known to the typestore (rosbags' Jazzy types and {PACKAGE}'s)"
            )
        return typename

    def rihs01(self, typename: str) -> str:
        """The type's RIHS01 hash as rosidl computes it (`RIHS01_<64 hex>`), for a message or a service."""
        return self.store.hash_rihs01(self._known(typename))

    def to_cdr(self, message: object, typename: str) -> bytes:
        """The message as little-endian CDR with its 4-byte encapsulation header; numeric sequences set as Python
        lists after it was made (a service's response filled in by its handler) are taken as the arrays rosbags
        serialises."""
        typename = self._known(typename)
        return bytes(self.store.serialize_cdr(self._normalized(message, typename), typename, little_endian=True))

    def _normalized(self, message: object, typename: str) -> object:
        _, definitions = self.store.fielddefs[typename]
        for name, desc in definitions:
            kind, argument = desc
            value = getattr(message, name)
            if kind == Nodetype.NAME:
                self._normalized(value, argument)
            elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                element_kind, element = argument[0]
                if element_kind == Nodetype.NAME:
                    for item in value:
                        self._normalized(item, element)
                else:
                    setattr(message, name, _given(value, desc))
        return message

    def from_cdr(self, data: bytes, typename: str) -> object:
        """The message from CDR bytes; PayloadError when they are not a valid `typename`."""
        typename = self._known(typename)
        try:
            return self.store.deserialize_cdr(bytes(data), typename)
        except SerdeError as error:
            raise PayloadError(f"payload is not valid CDR of {typename}: {error}") from None

    def message(self, typename: str, **fields: object) -> object:
        """A message of the type with the given fields and every other field at its default (zero, empty, or
        a nested message of defaults), since rosbags' message classes want every field. Numeric arrays and
        sequences may be given as any sequence of numbers (rosbags wants numpy arrays)."""
        _, definitions = self.store.fielddefs[self._known(typename)]
        names = {name for name, _ in definitions}
        if unknown := sorted(set(fields) - names):
            raise UnknownTypeError(
                f"{typename} has no field {', '.join(unknown)}; its fields: {', '.join(sorted(names))}"
            )
        values = {
            name: _given(fields[name], desc) if name in fields else self._default(desc) for name, desc in definitions
        }
        return self.store.types[typename](**values)

    def message_class(self, typename: str) -> Callable[..., object]:
        """A factory of `typename`'s messages (`message`'s keyword arguments), with the type's constants
        (DiagnosticStatus.OK, LatchEvent.EDGE_RISING) as its class has them: what a node's transport hands its parts."""
        cls = self.store.types[self._known(typename)]

        def make(**fields):
            return self.message(typename, **fields)

        for constant, _, value in self.store.fielddefs[typename][0]:
            setattr(make, constant, value)
        make.__name__ = cls.__name__
        return make

    def _default(self, desc: tuple) -> object:
        kind, argument = desc
        if kind == Nodetype.BASE:
            return _base_default(argument[0])
        if kind == Nodetype.NAME:
            return self.message(argument)
        element, length = argument
        if kind == Nodetype.ARRAY:
            return _array_default(self, element, length)
        return _sequence_default(element)


def _leaves_mapped(definition: tuple, leaf: Callable[[tuple], tuple]) -> tuple:
    """A rosbags type definition (constants, fields) with each field's element type (the field's own, or its
    array's or sequence's) passed through leaf."""

    def desc(value: tuple) -> tuple:
        kind, argument = value
        if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            return kind, (desc(argument[0]), argument[1])
        return leaf(value)

    constants, fields = definition
    return constants, [(field, desc(value)) for field, value in fields]


def _char_as_uint8(definition: tuple) -> tuple:
    """A definition with `char` fields as uint8."""
    return _leaves_mapped(
        definition,
        lambda value: (
            (value[0], ("uint8", value[1][1])) if value[0] == Nodetype.BASE and value[1][0] == "char" else value
        ),
    )


def _renamed(typesdict: Mapping[str, tuple], renames: Mapping[str, str]) -> dict:
    """A rosbags types dictionary with type names replaced, where defined and where referenced."""
    return {
        renames.get(typename, typename): _leaves_mapped(
            definition,
            lambda value: (value[0], renames.get(value[1], value[1])) if value[0] == Nodetype.NAME else value,
        )
        for typename, definition in typesdict.items()
    }


def _given(value: object, desc: tuple) -> object:
    kind, argument = desc
    if kind in (Nodetype.ARRAY, Nodetype.SEQUENCE) and not isinstance(value, np.ndarray):
        element_kind, element = argument[0]
        if element_kind == Nodetype.BASE and (dtype := _numpy_dtype(element[0])):
            return np.asarray(value, dtype=dtype)
    return value


def _base_default(base: str) -> object:
    if base == "string":
        return ""
    if base == "bool":
        return False
    if base in ("float32", "float64"):
        return 0.0
    return 0


def _numpy_dtype(base: str) -> str | None:
    return {
        "bool": "bool",
        "byte": "uint8",
        "char": "uint8",
        "octet": "uint8",
        "float32": "float32",
        "float64": "float64",
        "int8": "int8",
        "uint8": "uint8",
        "int16": "int16",
        "uint16": "uint16",
        "int32": "int32",
        "uint32": "uint32",
        "int64": "int64",
        "uint64": "uint64",
    }.get(base)


def _array_default(types: Types, element: tuple, length: int) -> object:
    kind, argument = element
    if kind == Nodetype.BASE and (dtype := _numpy_dtype(argument[0])):
        return np.zeros(length, dtype=dtype)
    return [types._default(element) for _ in range(length)]


def _sequence_default(element: tuple) -> object:
    kind, argument = element
    if kind == Nodetype.BASE and (dtype := _numpy_dtype(argument[0])):
        return np.zeros(0, dtype=dtype)
    return []
