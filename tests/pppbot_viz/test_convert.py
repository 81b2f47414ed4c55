"""ROS messages → rerun archetypes: each display shows its message's data, in its frame."""
from __future__ import annotations

import math
from pathlib import Path as FilePath
from typing import Any

import numpy as np
import pytest
import rerun as rr
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped, PoseWithCovarianceStamped, TransformStamped
from nav2_msgs.msg import Particle, ParticleCloud
from nav_msgs.msg import OccupancyGrid, Path
from pppbot_viz.ros import convert
from pppbot_viz.visuals import UNKNOWN_CELL
from sensor_msgs.msg import CompressedImage, Image, LaserScan
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from pppbot_common.maps import OccupancyGrid as OccupancyGridCore

ROOT = FilePath(__file__).resolve().parents[2]


def values(batch: Any) -> list[Any]:
    return batch.as_arrow_array().to_pylist()


def frame(archetypes: list[Any]) -> str:
    coordinate_frame = next(a for a in archetypes if isinstance(a, rr.CoordinateFrame))
    return values(coordinate_frame.frame)[0]


def test_scan_points_in_the_lidar_frame() -> None:
    msg = LaserScan(angle_min=0.0, angle_increment=math.pi / 2, range_min=0.1, range_max=10.0,
                    ranges=[1.0, math.inf, 2.0])
    msg.header.frame_id = "lidar_frame"
    archetypes = convert.scan(msg)
    assert frame(archetypes) == "lidar_frame"
    np.testing.assert_allclose(values(archetypes[1].positions), [[1, 0, 0], [-2, 0, 0]], atol=1e-6)


def test_grid_at_its_origin_with_unknown_cells_as_255() -> None:
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.info.width, msg.info.height, msg.info.resolution = 3, 2, 0.05
    msg.info.origin.position.x, msg.info.origin.position.y = -1.5, 2.0
    msg.info.origin.orientation.w = 1.0
    msg.data = [-1, 0, 100, 0, 0, 50]
    archetypes = convert.grid(msg, rr.components.Colormap.RvizMap, lift_m=0.01)
    grid = archetypes[1]
    assert frame(archetypes) == "map"
    # rerun draws the image as a picture (first row on top, lower-left corner at the origin): the
    # grid's row 0, at its origin, goes last
    assert list(values(grid.data)[0]) == [0, 0, 50, UNKNOWN_CELL, 0, 100]
    assert values(grid.cell_size) == [pytest.approx(0.05)]
    assert values(grid.translation) == [[-1.5, 2.0, pytest.approx(0.01)]]


def test_transform_is_a_tf_edge() -> None:
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id = "odom", "/base_link"
    msg.transform.translation.x = 1.0
    msg.transform.rotation.z, msg.transform.rotation.w = 0.0, 2.0  # not normalized
    t = convert.transform(msg)
    assert values(t.parent_frame) == ["odom"] and values(t.child_frame) == ["base_link"]
    assert values(t.quaternion) == [[0.0, 0.0, 0.0, 1.0]]
    assert values(t.translation) == [[1.0, 0.0, 0.0]]


def test_path_is_a_line_and_an_empty_path_clears_it() -> None:
    msg = Path()
    msg.header.frame_id = "map"
    for x in (0.0, 1.0, 2.0):
        pose = PoseStamped()
        pose.pose.position.x = x
        msg.poses.append(pose)
    line = convert.path(msg, convert.PLAN_COLOR)[1]
    assert [[p[0] for p in strip] for strip in values(line.strips)] == [[0.0, 1.0, 2.0]]
    assert values(convert.path(Path(), convert.PLAN_COLOR)[1].strips) == []


def test_particles_are_heading_arrows() -> None:
    msg = ParticleCloud()
    msg.header.frame_id = "map"
    for x, yaw in ((1.0, 0.0), (2.0, math.pi / 2)):
        particle = Particle(weight=0.5)
        particle.pose.position.x = x
        particle.pose.orientation.z, particle.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        msg.particles.append(particle)
    arrows = convert.particles(msg, arrow_m=0.1)[1]
    np.testing.assert_allclose(values(arrows.origins), [[1, 0, 0], [2, 0, 0]], atol=1e-6)
    np.testing.assert_allclose(values(arrows.vectors), [[0.1, 0, 0], [0, 0.1, 0]], atol=1e-6)


def test_pose_with_covariance_shows_its_ellipse() -> None:
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = "map"
    msg.pose.pose.position.x, msg.pose.pose.orientation.w = 3.0, 1.0
    covariance = [0.0] * 36
    covariance[0], covariance[7] = 0.04, 0.01
    msg.pose.covariance = covariance
    archetypes = convert.pose_with_covariance(msg, sigmas=2.0)
    ellipse, arrow = archetypes[1], archetypes[2]
    half = values(ellipse.half_sizes)[0]
    assert half[:2] == pytest.approx([0.4, 0.2])
    assert values(ellipse.centers) == [[3.0, 0.0, 0.0]]
    assert values(arrow.origins)[0][0] == pytest.approx(3.0)


def test_markers_draw_the_slam_graph_and_clear() -> None:
    nodes = Marker(type=Marker.SPHERE_LIST, action=Marker.ADD, id=0, ns="slam_toolbox")
    nodes.header.frame_id = "map"
    nodes.pose.orientation.w = 1.0
    nodes.scale.x = 0.1
    nodes.color = ColorRGBA(r=0.0, g=0.0, b=1.0, a=1.0)
    nodes.points = [Point(x=0.0), Point(x=1.0)]
    edges = Marker(type=Marker.LINE_LIST, action=Marker.ADD, id=1, ns="slam_toolbox")
    edges.header.frame_id = "map"
    edges.pose.position.y = 1.0  # a marker's pose moves its points
    edges.pose.orientation.w = 1.0
    edges.scale.x = 0.02
    edges.points = [Point(x=0.0), Point(x=1.0)]
    gone = Marker(action=Marker.DELETE, id=2, ns="slam_toolbox")
    out = convert.markers(MarkerArray(markers=[nodes, edges, gone]))
    assert set(out) == {"slam_toolbox/0", "slam_toolbox/1", "slam_toolbox/2"}
    assert out["slam_toolbox/2"] is None
    points = out["slam_toolbox/0"][1]  # type: ignore[index]
    assert values(points.positions) == [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    assert values(points.colors) == [0x0000FFFF]
    segments = values(out["slam_toolbox/1"][1].strips)  # type: ignore[index]
    assert segments == [[[0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]]
    assert convert.markers(MarkerArray(markers=[nodes, Marker(action=Marker.DELETEALL)])) == {"": None}


def shown(picture: rr.Image) -> np.ndarray:
    """An image as the view sent it: (height, width[, 3]) uint8."""
    fmt = values(picture.format)[0]
    pixels = np.frombuffer(bytes(values(picture.buffer)[0]), dtype=np.uint8)
    return pixels.reshape(fmt["height"], fmt["width"], -1).squeeze(axis=2) if pixels.size == fmt["height"] * \
        fmt["width"] else pixels.reshape(fmt["height"], fmt["width"], -1)


def test_the_slam_health_says_closures_accepted_rejected_and_why_and_the_largest_correction() -> None:
    health = {"keyframes": "412", "loop_closures": "85", "rejected_closures": "14", "rejected_disagrees": "10",
              "rejected_see_through": "3", "rejected_inconsistent": "1", "rejected_residual": "0",
              "undone_closures": "1",
              "largest_correction_m": "0.314", "largest_correction_rad": "0.0349"}
    other = DiagnosticStatus(name="amcl: localization", message="ok")
    status = DiagnosticStatus(name="slam_toolbox: mapping", message="1 loop closure(s) proved wrong and were undone",
                              values=[KeyValue(key=k, value=v) for k, v in health.items()])
    text = convert.slam_health(DiagnosticArray(status=[other, status]))
    assert text is not None
    assert text.splitlines() == [
        "- **1 loop closure(s) proved wrong and were undone**: 412 keyframes, 85 loop closures, largest "
        "correction 0.31 m, 2.0°",
        "- rejected 14: 10 disagree with the map, 3 see through walls, 1 disagree with other matches",
        "- undone 1"]
    assert convert.slam_health(DiagnosticArray(status=[other])) is None


def test_images_in_common_encodings_go_to_the_view_8_bit_and_at_most_320_px_wide() -> None:
    red_green = np.zeros((480, 640, 3), dtype=np.uint8)
    red_green[:, :320, 0] = 255
    red_green[:, 320:, 1] = 255
    rgb = shown(convert.image(Image(width=640, height=480, encoding="rgb8", step=1920, data=red_green.tobytes())))
    assert rgb.shape == (240, 320, 3)  # halved: the camera panel shows no more
    assert rgb[100, 10].tolist() == [255, 0, 0] and rgb[100, 300].tolist() == [0, 255, 0]
    bgr = shown(convert.image(Image(width=640, height=480, encoding="bgr8", step=1920, data=red_green.tobytes())))
    assert bgr[100, 10].tolist() == [0, 0, 255]  # blue where the bytes say B first
    rows = np.zeros((2, 4), dtype=np.uint8)  # one padding byte per 3-pixel row
    rows[0, :3], rows[1, :3] = 40, 200
    padded = shown(convert.image(Image(width=3, height=2, encoding="mono8", step=4, data=rows.tobytes())))
    assert padded.tolist() == [[40, 40, 40], [200, 200, 200]]  # padding dropped
    depth = np.array([[0.0, 2.0, 4.0, np.nan]], dtype=np.float32)
    grey = shown(convert.image(Image(width=4, height=1, encoding="32FC1", step=16, data=depth.tobytes())))
    assert grey.tolist() == [[0, 128, 255, 0]]  # 0 black, the farthest white, NaN black
    with pytest.raises(ValueError, match="encoding 'yuv422' is not shown"):
        convert.image(Image(width=1, height=1, encoding="yuv422", step=2, data=bytes(2)))
    with pytest.raises(ValueError, match="needs step >= 6"):
        convert.image(Image(width=2, height=1, encoding="rgb8", step=2, data=bytes(6)))
    jpeg = convert.compressed_image(CompressedImage(format="jpeg", data=b"\xff\xd8"))
    assert values(jpeg.media_type) == ["image/jpeg"]


URDF = """<robot name="r">
  <link name="base_link"/>
  <link name="chassis"><visual><origin xyz="0.15 0 0.075"/><geometry><box size="0.3 0.3 0.15"/></geometry>
    <material name="white"><color rgba="1 1 1 1"/></material></visual></link>
  <link name="wheel"><visual><origin rpy="1.5707963 0 0"/><geometry><cylinder radius="0.05" length="0.04"/></geometry>
    </visual></link>
  <link name="arm"><visual><geometry><mesh filename="package://nowhere/arm.dae"/></geometry></visual></link>
  <joint name="c" type="fixed"><parent link="base_link"/><child link="chassis"/></joint>
  <joint name="w" type="continuous"><parent link="base_link"/><child link="wheel"/></joint>
  <joint name="a" type="fixed"><parent link="base_link"/><child link="arm"/></joint>
</robot>"""


def test_robot_model_in_link_frames_and_missing_meshes_named() -> None:
    visuals, warnings = convert.robot_visuals(URDF, resolve_mesh=lambda name: None)
    by_path = {v.path: v.archetypes for v in visuals}
    assert set(by_path) == {"robot/chassis/visual_0", "robot/wheel/visual_0"}
    assert frame(by_path["robot/chassis/visual_0"]) == "chassis"
    box = by_path["robot/chassis/visual_0"][1]
    assert values(box.half_sizes) == [pytest.approx([0.15, 0.15, 0.075])]
    assert values(box.centers) == [pytest.approx([0.15, 0.0, 0.075])]
    cylinder = by_path["robot/wheel/visual_0"][1]
    assert values(cylinder.radii) == [pytest.approx(0.05)] and values(cylinder.lengths) == [pytest.approx(0.04)]
    assert warnings == ["link 'arm': mesh 'package://nowhere/arm.dae' not found; not drawn"]


def drawn_grid(archetypes: list[Any]) -> OccupancyGridCore:
    """What the viewer draws for a GridMap, read back as rerun documents it: the image as a
    picture, its lower-left corner at the translation, ``cell_size`` a pixel."""
    grid = archetypes[1]
    fmt = values(grid.format)[0]
    image = np.frombuffer(bytes(values(grid.data)[0]), dtype=np.uint8).reshape(fmt["height"], fmt["width"])
    x, y, _ = values(grid.translation)[0]
    picture = image[::-1]  # its bottom row, at the translation, first
    cells = np.where(picture == UNKNOWN_CELL, -1, picture).astype(np.int8)
    return OccupancyGridCore(cells, float(values(grid.cell_size)[0]), (x, y, 0.0))


@pytest.mark.parametrize("world", ["cones", "maze", "office", "room"])
def test_every_shipped_map_is_drawn_where_its_world_has_walls(world: str) -> None:
    """Each shipped map (origins inside the map, not at its corner) as the view draws it lies on
    its world's ground truth; drawn upside down, as it was, the cones (a world without mirror
    symmetry) miss theirs."""
    from pppbot_common.maps import load_map
    from pppbot_eval.map_quality import compare_maps
    from pppbot_sim.ground_truth import ground_truth_map
    from pppbot_sim.simulation import load_world
    from pppbot_sim.worlds import find_world, model_paths

    saved, _ = load_map(ROOT / "maps" / f"{world}.yaml")
    assert saved.origin[0] < 0 and saved.origin[1] < 0  # the map frame's origin lies inside the map
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.info.width, msg.info.height, msg.info.resolution = saved.width, saved.height, saved.resolution
    msg.info.origin.position.x, msg.info.origin.position.y = saved.origin[0], saved.origin[1]
    msg.info.origin.orientation.w = 1.0
    msg.data = saved.data.reshape(-1).tolist()
    drawn = drawn_grid(convert.grid(msg, rr.components.Colormap.RvizMap))
    np.testing.assert_array_equal(drawn.data, saved.data)
    world_file = find_world(world)
    spec, _ = load_world(world_file, model_paths(world_file))
    truth = ground_truth_map(spec.compile(), 0.05, 0.2)
    assert compare_maps(drawn, truth).precision > 0.9
    upside_down = OccupancyGridCore(drawn.data[::-1], drawn.resolution, drawn.origin)
    if world == "cones":
        assert compare_maps(upside_down, truth).precision < 0.2


def test_a_footprint_is_a_closed_line_just_above_the_costmaps() -> None:
    from geometry_msgs.msg import Point32, PolygonStamped

    msg = PolygonStamped()
    msg.header.frame_id = "odom"
    msg.polygon.points = [Point32(x=1.0, y=0.0), Point32(x=0.0, y=1.0), Point32(x=-1.0, y=0.0)]
    archetypes = convert.polygon(msg, convert.FOOTPRINT_COLOR)
    assert frame(archetypes) == "odom"
    (strip,) = values(archetypes[1].strips)
    np.testing.assert_allclose(strip, [[1, 0, 0.03], [0, 1, 0.03], [-1, 0, 0.03], [1, 0, 0.03]], atol=1e-6)
