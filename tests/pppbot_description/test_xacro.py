"""ppp_bot's xacro expands, its arguments change the robot, and errors point at file and line."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from pppbot_description.errors import DescriptionError
from pppbot_description.urdf_model import parse_urdf
from pppbot_description.xacro_model import default_xacro_path, process_xacro


def model(**mappings: str):
    return parse_urdf(process_xacro(mappings=mappings))


def test_default_file_is_the_modular_xacro():
    folder = default_xacro_path().parent
    for name in ("robot.urdf.xacro", "robot_core.xacro", "lidar.xacro", "camera.xacro", "imu.xacro",
                 "inertial_macros.xacro", "materials.xacro"):
        assert (folder / name).is_file(), name


def test_defaults_give_the_full_robot():
    m = model()
    assert m.name == "ppp_bot"
    assert {s.type for s in m.sensors} == {"gpu_lidar", "camera", "imu"}
    assert "camera_link_optical" in m.links and "imu_link" in m.links


@pytest.mark.parametrize("flag, links", [
    ("use_camera", {"camera_link", "camera_link_optical"}),
    ("use_imu", {"imu_link"}),
])
def test_optional_sensors_can_be_left_out(flag, links):
    m = model(**{flag: "false"})
    assert not links & set(m.links)
    assert len(m.sensors) == 2


def test_prefix_renames_every_link_joint_and_sensor_frame():
    m = model(prefix="r1_")
    assert all(name.startswith("r1_") for name in m.links)
    assert all(name.startswith("r1_") for name in m.joints)
    assert set(m.control_joints) == {"r1_left_wheel_joint", "r1_right_wheel_joint"}
    (lidar,) = m.sensors_of_type("gpu_lidar")
    assert lidar.link == lidar.frame_id == "r1_lidar_frame"


def test_lidar_arguments_reach_the_sensor_tag():
    (lidar,) = model(samples="360", update_rate="5", noise_stddev="0.02").sensors_of_type("gpu_lidar")
    assert lidar.find_float("lidar/scan/horizontal/samples", 0) == 360
    assert lidar.update_rate_hz == 5
    assert lidar.find_float("lidar/noise/stddev", 0) == pytest.approx(0.02)


def test_unknown_argument_is_named():
    with pytest.raises(DescriptionError, match=r"unknown xacro argument\(s\) sample .*declared: .*samples"):
        process_xacro(mappings={"sample": "10"})


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(textwrap.dedent(text).lstrip())
    return path


def test_missing_include_names_the_including_file_and_line(tmp_path):
    top = write(tmp_path, "top.xacro", """
        <?xml version="1.0"?>
        <robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r">
          <link name="base_link"/>
          <xacro:include filename="gone.xacro"/>
        </robot>
    """)
    with pytest.raises(DescriptionError) as info:
        process_xacro(top)
    assert f"{top}:4: included file not found: {tmp_path / 'gone.xacro'}" == str(info.value)


def test_bad_xml_in_an_include_names_that_file_and_line(tmp_path):
    write(tmp_path, "part.xacro", """
        <?xml version="1.0"?>
        <robot xmlns:xacro="http://www.ros.org/wiki/xacro">
          <link name="a">
        </robot>
    """)
    top = write(tmp_path, "top.xacro", """
        <?xml version="1.0"?>
        <robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r">
          <xacro:include filename="part.xacro"/>
        </robot>
    """)
    with pytest.raises(DescriptionError, match=rf"^{tmp_path / 'part.xacro'}:4: malformed XML: mismatched tag$"):
        process_xacro(top)


def test_missing_top_file(tmp_path):
    with pytest.raises(DescriptionError, match="nothere.xacro: file not found"):
        process_xacro(tmp_path / "nothere.xacro")


def test_undefined_property_is_reported_with_the_file(tmp_path):
    top = write(tmp_path, "top.xacro", """
        <?xml version="1.0"?>
        <robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="r">
          <link name="${no_such_property}"/>
        </robot>
    """)
    with pytest.raises(DescriptionError, match=rf"^{top}:3: .*no_such_property"):
        process_xacro(top)
