"""ROS 2 parameter files checked as rcl reads them: one message with the file, line, column and key."""
from __future__ import annotations

from pathlib import Path

import pytest

from pppbot_common.errors import ParameterFileError
from pppbot_common.param_files import check_parameter_file, parameter_file_arguments

REPO = Path(__file__).resolve().parents[2]


def write(tmp_path: Path, text: str | bytes) -> Path:
    path = tmp_path / "params.yaml"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


@pytest.mark.parametrize("name", sorted(p.name for p in (REPO / "config").glob("*.yaml")))
def test_the_shipped_parameter_files_pass(name):
    assert check_parameter_file(REPO / "config" / name)


def test_parameters_come_back_by_node_name(tmp_path):
    path = write(tmp_path, "/**:\n  ros__parameters:\n    use_sim_time: true\n"
                           "amcl:\n  ros__parameters:\n    alpha1: 0.2\n    laser:\n      max_beams: 60\n"
                           "/ns/node:\n  ros__parameters: {}\n"
                           "ns:\n  map_server:\n    ros__parameters:\n      names: [a, b]\n")
    assert check_parameter_file(path) == {
        "/**": {"use_sim_time": True},
        "amcl": {"alpha1": 0.2, "laser": {"max_beams": 60}},
        "/ns/node": {},
        "ns/map_server": {"names": ["a", "b"]},
    }


def test_an_empty_file_has_no_parameters(tmp_path):
    assert check_parameter_file(write(tmp_path, "# nothing yet\n")) == {}


def test_documents_are_merged_in_order(tmp_path):
    path = write(tmp_path, "n:\n  ros__parameters:\n    a: 1\n    b: 1\n---\nn:\n  ros__parameters:\n    b: 2\n")
    assert check_parameter_file(path) == {"n": {"a": 1, "b": 2}}


def test_malformed_yaml_names_file_line_and_column(tmp_path):
    path = write(tmp_path, "map_server:\n  ros__parameters:\n    yaml_filename: [unclosed\n    x: 1\n")
    with pytest.raises(ParameterFileError) as info:
        check_parameter_file(path)
    assert str(info.value).startswith(f"{path}: line 4, column 6: not valid YAML")
    assert "line 3, column 20" in str(info.value)  # where the unclosed list starts
    assert (info.value.line, info.value.column) == (4, 6)


def test_bad_indentation_is_a_yaml_error_with_its_line(tmp_path):
    path = write(tmp_path, "amcl:\n  ros__parameters:\n    a: 1\n   b: 2\n")
    with pytest.raises(ParameterFileError, match=r"params\.yaml: line 4, column 4: not valid YAML"):
        check_parameter_file(path)


def test_a_binary_file_is_not_text(tmp_path):
    path = write(tmp_path, b"n:\n  \xff\xfe\x00")
    with pytest.raises(ParameterFileError, match=r"line 2, column 3: not a text file: byte 0xff"):
        check_parameter_file(path)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(ParameterFileError, match=r"nope\.yaml: cannot read the file \(No such file"):
        check_parameter_file(tmp_path / "nope.yaml")


@pytest.mark.parametrize("text, where, message", [
    ("- a\n- b\n", "line 1, column 1", "a parameter file is a mapping of node names"),
    ("hello\n", "line 1, column 1", "not the value 'hello'"),
    ("amcl:\n  alpha1: 0.2\n", "line 2, column 11", "key 'amcl/alpha1' must hold 'ros__parameters:'"),
    ("amcl: 5\n", "line 1, column 7", "key 'amcl' must hold 'ros__parameters:'"),
    ("amcl:\n", "line 1, column 6", "key 'amcl' must hold 'ros__parameters:'"),
    ("amcl:\n  ros__parameters:\n    a: 1\n  extra: 2\n", "line 4, column 3",
     "key 'amcl/extra': a node name holds only"),
    ("amcl:\n  ros__parameters: [1]\n", "line 2, column 20", "key 'amcl/ros__parameters' must be a mapping"),
    ("ros__parameters:\n  a: 1\n", "line 1, column 1", "goes under a node name"),
    ("my-node:\n  ros__parameters: {}\n", "line 1, column 1", "key 'my-node': a node name"),
    ("/ns//node:\n  ros__parameters: {}\n", "line 1, column 1", "key '/ns//node': a node name"),
    ("1node:\n  ros__parameters: {}\n", "line 1, column 1", "key '1node': a node name"),
    ("n:\n  ros__parameters:\n    a:\n", "line 3, column 7", "parameter 'a' of 'n' has no value"),
    ("n:\n  ros__parameters:\n    a: [1, x]\n", "line 3, column 12",
     "parameter 'a' of 'n': a list's items must be of one type"),
    ("n:\n  ros__parameters:\n    a: [1, 2.5]\n", "line 3, column 12", "write integers as 1.0"),
    ("n:\n  ros__parameters:\n    g:\n      a: [[1]]\n", "line 4, column 11",
     "parameter 'g.a' of 'n': a list parameter holds scalars"),
])
def test_the_wrong_shape_names_the_key(tmp_path, text, where, message):
    path = write(tmp_path, text)
    with pytest.raises(ParameterFileError) as info:
        check_parameter_file(path)
    assert str(info.value).startswith(f"{path}: {where}: ")
    assert message in str(info.value)


def test_a_namespace_holding_itself_is_refused(tmp_path):
    path = write(tmp_path, "ns: &a\n  inner: *a\n")
    with pytest.raises(ParameterFileError, match="key 'ns/inner' holds itself"):
        check_parameter_file(path)


def test_params_files_are_found_in_the_ros_args_parts_of_a_command_line():
    args = ["node", "--params-file", "not_ros.yaml", "--ros-args", "-r", "a:=b", "--params-file", "one.yaml",
            "--", "--params-file", "app.yaml", "--ros-args", "--params-file", "two.yaml"]
    assert parameter_file_arguments(args) == [Path("one.yaml"), Path("two.yaml")]
