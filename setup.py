"""Builds akd_ros: the Python package, the Rust crate in native/ as akd_ros._native, and the
package's ROS 2 messages, services and actions (msg/, srv/, action/), and control_msgs'
FollowJointTrajectory where control_msgs is not installed (generated and compiled by rosidl_build.py).

The same file serves `pip install -e .` (the virtual environment made by scripts/setup.sh) and
`colcon build` in a ROS 2 workspace (ament_python), where setuptools-rust and cargo come from apt
or rustup.
"""

import sys
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup
from setuptools_rust import Binding, RustExtension

PACKAGE = "akd_ros"
# The real source directory: `colcon build --symlink-install` runs a symlink of this file from
# its build directory, where neither native/ nor README.md is linked.
HERE = Path(__file__).resolve().parent
# rosidl_build sits beside this file, which is not on sys.path when run through that symlink.
sys.path.insert(0, str(HERE))
import rosidl_build  # noqa: E402


class LiteralReprRustExtension(RustExtension):
    """A RustExtension whose repr is a Python literal.

    colcon learns about a package by running setup.py with --dry-run and literal-evaluating the
    repr of the distribution's attributes; it skips `ext_modules` but not `rust_extensions`, and
    the default repr of a RustExtension is no literal, so `colcon build` would stop with a
    SyntaxError before building anything.
    """

    def __repr__(self) -> str:
        return repr(f"RustExtension {self.name} from {self.path}")


setup(
    name=PACKAGE,
    version="0.1.0",
    description="Kollmorgen AKD servo drives on EtherCAT in ROS 2, over a Rust EtherCAT master",
    long_description=(HERE / "README.md").read_text(encoding="utf-8"),
    long_description_content_type="text/markdown",
    license="Apache-2.0",
    maintainer="akd_ros maintainers",
    maintainer_email="akd_ros@users.noreply.github.com",
    python_requires=">=3.10",
    # The message modules are generated during the build, so they may not exist yet to be found; without the
    # generators they are not built, and modules another build left in the tree are not packaged.
    packages=sorted(
        {
            *find_packages(include=[PACKAGE, f"{PACKAGE}.*"], exclude=rosidl_build.INTERFACE_PACKAGES),
            # control_msgs where this build generates it (where it is not installed).
            *rosidl_build.interface_packages(),
        }
    ),
    ext_modules=rosidl_build.extensions(),
    cmdclass=rosidl_build.COMMANDS,
    distclass=rosidl_build.InterfaceDistribution,
    rust_extensions=[
        LiteralReprRustExtension(
            f"{PACKAGE}._native",
            path=str(HERE / "native" / "Cargo.toml"),
            binding=Binding.PyO3,
            features=["extension-module"],
            # Release build always: the cyclic path must be fast even in a developer's venv
            # (Cargo.toml keeps line-level debug info in release).
            debug=False,
        )
    ],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", sorted(glob("launch/*.py"))),
        (f"share/{PACKAGE}/config", sorted(glob("config/*.yaml"))),
        *rosidl_build.data_files(),
    ],
    install_requires=["setuptools", "eclipse-zenoh>=1.5,<2", "rosbags", "mcap", "xxhash", "PyYAML", "rich", "textual"],
    zip_safe=False,
    entry_points={
        "console_scripts": [
            "akd-sim = akd_ros.cli.sim:main",
            "akd-scan = akd_ros.cli.scan:main",
            "akd-sdo = akd_ros.cli.sdo:main",
            "akd-plot = akd_ros.cli.plot:main",
            "akd-top = akd_ros.cli.top:main",
            "akd-eoe = akd_ros.cli.eoe:main",
            "akd-foe = akd_ros.cli.foe:main",
            "akd-zenohd = akd_ros.cli.zenohd:main",
            "akd-access = akd_ros.cli.access:main",
            "akd_node = akd_ros.node.command_line:main",
        ]
    },
)
