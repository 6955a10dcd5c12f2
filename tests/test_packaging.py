"""The package as ROS users build it: `colcon build` of this repository in a workspace.

The issue asks that the same setup.py work in a colcon workspace; colcon (from PyPI here, the same
code as Jazzy's apt packages) introspects setup.py in ways pip does not, so it is built for real:
plainly and with --symlink-install, then the installed tool is run from the install space, and the install space
holds the interfaces as a CMake package's does: the ament index entries (found through ament_index_python), the .idl
files, the C++ headers and the C++ type-support libraries.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
COLCON = Path(sys.executable).with_name("colcon")


@pytest.mark.skipif(not COLCON.exists(), reason="colcon not installed (scripts/setup.sh installs it)")
@pytest.mark.parametrize("mode", [[], ["--symlink-install"]], ids=["install", "symlink_install"])
def test_colcon_build_installs_a_working_package(tmp_path, mode):
    workspace = tmp_path / "ws"
    (workspace / "src").mkdir(parents=True)
    (workspace / "src" / "akd_ros").symlink_to(REPO)
    build = subprocess.run(
        [str(COLCON), "build", "--packages-select", "akd_ros", *mode],
        cwd=workspace,
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    log = workspace / "log" / "latest_build" / "akd_ros" / "stderr.log"
    assert build.returncode == 0, build.stdout + (log.read_text() if log.exists() else "")
    prefix = workspace / "install" / "akd_ros"
    site = prefix / "lib" / f"python{sys.version_info.major}.{sys.version_info.minor}" / "site-packages"
    assert (prefix / "share" / "ament_index" / "resource_index" / "packages" / "akd_ros").exists()
    assert (prefix / "share" / "akd_ros" / "package.xml").exists()
    for definition in sorted((REPO / "msg").glob("*.msg")):
        assert (prefix / "share" / "akd_ros" / "msg" / definition.with_suffix(".idl").name).is_file(), definition
    assert (prefix / "include" / "akd_ros" / "akd_ros" / "msg" / "latch_event.hpp").is_file()
    env = {**os.environ, "PYTHONPATH": str(site), "AMENT_PREFIX_PATH": str(prefix)}
    # The install space's package is the one imported, not the development install in .venv
    # (with --symlink-install it links back to this repository, which is the point of it).

    def run(*command: str) -> subprocess.CompletedProcess:
        return subprocess.run(command, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=60, check=False)

    where = run(sys.executable, "-c", "import akd_ros; print(akd_ros.__file__)")
    assert where.returncode == 0, where.stderr
    expected = REPO if mode else site
    assert where.stdout.startswith(str(expected)), where.stdout
    package_dir = Path(where.stdout.strip()).parent
    for suffix in ("rosidl_typesupport_cpp", "rosidl_typesupport_fastrtps_cpp", "rosidl_typesupport_introspection_cpp"):
        assert (package_dir / f"libakd_ros__{suffix}.so").is_file(), suffix
    index = run(
        sys.executable,
        "-c",
        "from ament_index_python.resources import get_resource; "
        "content, prefix = get_resource('rosidl_interfaces', 'akd_ros'); print(prefix); print(content)",
    )
    assert index.returncode == 0, index.stderr
    found_prefix, *entries = index.stdout.split()
    assert Path(found_prefix) == prefix
    assert "msg/LatchEvent.idl" in entries
    assert "srv/SdoWrite.srv" in entries
    scan = run(str(prefix / "lib" / "akd_ros" / "akd-scan"), "sim")
    assert scan.returncode == 0, scan.stderr
    assert scan.stdout.startswith("0 vendor=0x0000006A product=0x00414B44")


def test_the_public_api_is_what_the_package_names():
    """`akd_ros` exports what its `__all__` names, each of it importable, and nothing of the extension besides: a new
    helper of the extension does not become the user's API unnoticed."""
    import types

    import akd_ros

    public = {
        name
        for name, value in vars(akd_ros).items()
        if not name.startswith("_") and not isinstance(value, types.ModuleType)
    }
    assert public == set(akd_ros.__all__)
    assert "check_mapping" not in public and "Master" in public
