"""tools/workspace.py: the CMake export fix, stamps, and a do-nothing second run."""
from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def load_workspace():
    spec = importlib.util.spec_from_file_location("pppbot_workspace", REPO / "tools" / "workspace.py")
    if spec is None or spec.loader is None:
        raise ImportError("cannot load tools/workspace.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


workspace = load_workspace()

WHEEL_EXPORT = (
    'INTERFACE_INCLUDE_DIRECTORIES "/opt/python/cp311-cp311/include/python3.11;'
    '/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include"'
)


@pytest.mark.parametrize("tag", ["cp310-cp310", "cp311-cp311", "cp313-cp313"])
def test_wheel_paths_are_recognised_for_each_python(tag):
    version = "3." + tag[3:5]
    text = WHEEL_EXPORT.replace("cp311-cp311", tag).replace("python3.11", f"python{version}")
    new = workspace._WHEEL_NUMPY_INCLUDE.sub("/NUMPY", text)
    new = workspace._WHEEL_PYTHON_INCLUDE.sub("/PY", new)
    assert new == 'INTERFACE_INCLUDE_DIRECTORIES "/PY;/NUMPY"'


def test_installed_exports_no_longer_point_at_the_wheel_builder():
    exports = list((REPO / ".venv" / "share").glob("*/cmake/*rosidl_generator_pyExport.cmake"))
    assert len(exports) >= 15  # one per message package from PyPI
    stale = [p.name for p in exports if "/opt/python/" in p.read_text()]
    assert stale == []


def test_venv_is_a_colcon_prefix_chained_by_install_setup():
    assert (REPO / ".venv" / "COLCON_IGNORE").exists()
    assert 'export VIRTUAL_ENV="' in (REPO / ".venv" / "local_setup.bash").read_text()
    assert f'COLCON_CURRENT_PREFIX="{REPO / ".venv"}"' in (REPO / "install" / "setup.bash").read_text()


def test_second_setup_does_nothing():
    result = subprocess.run([sys.executable, str(REPO / "tools" / "workspace.py"), "setup", "--quiet"],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stderr == "" and result.stdout == ""


def test_package_inputs_skip_module_sources_but_not_setup_files():
    pkg = REPO / "pppbot_common"
    inputs = {p.relative_to(pkg).as_posix() for p in workspace._package_inputs(pkg)}
    assert {"package.xml", "setup.py", "setup.cfg", "resource/pppbot_common"} <= inputs
    assert not any(name.startswith("pppbot_common/") and name.endswith(".py") for name in inputs)


def test_digest_depends_on_content_and_order_of_parts():
    assert workspace._digest([b"ab", b"c"]) != workspace._digest([b"a", b"bc"])
    assert workspace._digest([b"x"]) == workspace._digest([b"x"])


def test_an_interface_package_counts_as_provided_only_with_every_kind_it_defines():
    nav2 = REPO / "interfaces" / "nav2_msgs"
    assert workspace.interface_modules(nav2) == ["nav2_msgs.msg", "nav2_msgs.srv", "nav2_msgs.action"]
    assert workspace.interface_modules(REPO / "interfaces" / "tf2_msgs") == [
        "tf2_msgs.msg", "tf2_msgs.srv", "tf2_msgs.action"]


def test_built_nav2_msgs_has_the_map_services():
    """After setup, the environment imports nav2_msgs' services (SaveMap, LoadMap) too."""
    result = subprocess.run([sys.executable, "-c", "from nav2_msgs.srv import LoadMap, SaveMap; print('ok')"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout == "ok\n"
