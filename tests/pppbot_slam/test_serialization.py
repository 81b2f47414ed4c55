"""Pose-graph files: saved and loaded back unchanged, mapping continues from them, bad files are named."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from slam_synthetic import RING, drifting_odometry, feed, ring_path

from pppbot_common.se2 import se2_compose, se2_inverse
from pppbot_slam.mapper import Mapper, MapperError
from pppbot_slam.serialization import PoseGraphFileError, load_posegraph, posegraph_path, save_posegraph

TRUTH = ring_path(overlap_m=0.0)
FIRST_PART = 170  # scans of the first run: (0, −3) round to the far side of the block


@pytest.fixture(scope="module")
def first_run() -> Mapper:
    mapper = Mapper()
    feed(mapper, RING, TRUTH[:FIRST_PART], drifting_odometry(TRUTH[:FIRST_PART], yaw_per_m=0.01, scale=1.01))
    return mapper


def odometry_from_zero(truth: np.ndarray) -> np.ndarray:
    """Drifting odometry of a new run along ``truth``, in an odom frame of its own (zero at its start)."""
    odom = drifting_odometry(truth, yaw_per_m=-0.01, scale=0.99)
    return np.array([se2_compose(se2_inverse(odom[0]), o) for o in odom])


def errors_of(mapper: Mapper, indices: range) -> np.ndarray:
    """Map-pose position errors of keyframes ``indices`` (their scan k is TRUTH[k], stamped 0.1·k)."""
    rows = [round(mapper.keyframes[i].stamp_s / 0.1) for i in indices]
    poses = np.array([mapper.map_pose(i) for i in indices])
    return np.linalg.norm(poses[:, :2] - TRUTH[rows, :2], axis=1)


def test_round_trip_keeps_keyframes_scans_graph_and_map(first_run: Mapper, tmp_path: Path):
    written = save_posegraph(first_run, tmp_path / "ring")
    assert written == tmp_path / "ring.posegraph" and not list(tmp_path.glob("*.partial"))
    loaded = load_posegraph(written)
    assert len(loaded.keyframes) == len(first_run.keyframes)
    np.testing.assert_array_equal(np.array(loaded.graph.poses), np.array(first_run.graph.poses))
    for a, b in zip(loaded.keyframes, first_run.keyframes, strict=True):
        assert a.stamp_s == b.stamp_s and a.session == b.session
        np.testing.assert_array_equal(a.odom_pose, b.odom_pose)
        np.testing.assert_array_equal(a.rays.ranges_m, b.rays.ranges_m)
        np.testing.assert_array_equal(a.points, b.points)
    assert [(e.source, e.target, e.loop) for e in loaded.graph.edges] == \
        [(e.source, e.target, e.loop) for e in first_run.graph.edges]
    np.testing.assert_array_equal(loaded.grid().data, first_run.grid().data)


def test_mapping_continues_from_the_dock_with_a_new_odometry(first_run: Mapper, tmp_path: Path):
    mapper = load_posegraph(save_posegraph(first_run, tmp_path / "ring"))
    old = len(mapper.keyframes)
    mapper.start_session()  # at the first keyframe, where the first run started
    # A second run round the whole ring, its odometry starting at zero in a new odom frame.
    feed(mapper, RING, TRUTH, odometry_from_zero(TRUTH))
    new = range(old, len(mapper.keyframes))
    assert len(new) > 40 and all(mapper.keyframes[i].session == 1 for i in new)
    # The first new keyframe hangs off the graph at the dock; the run is placed in the old map.
    first_edge = next(e for e in mapper.graph.edges if e.target == old)
    assert first_edge.source < old
    errors = errors_of(mapper, new)
    assert np.sqrt(np.mean(errors ** 2)) < 0.05 and errors.max() < 0.1
    # Where it drives through the first run's part, it closes loops with it.
    assert any(c.target >= old > c.source for c in mapper.loop_closures)


def test_a_given_start_pose_is_corrected_by_matching(first_run: Mapper, tmp_path: Path):
    mapper = load_posegraph(save_posegraph(first_run, tmp_path / "ring"))
    old = len(mapper.keyframes)
    start = 100
    mapper.start_session(TRUTH[start] + [0.12, -0.08, 0.04])  # a rough start pose, as a user gives it
    feed(mapper, RING, TRUTH[:start + 30], odometry_from_zero(TRUTH[start:start + 30]), first=start)
    # Placed in the old map where it belongs: relative to the keyframe it is linked to, as in truth.
    edge = next(e for e in mapper.graph.edges if e.target == old)
    truth_rows = [round(mapper.keyframes[i].stamp_s / 0.1) for i in (edge.source, old)]
    truth_relative = se2_compose(se2_inverse(TRUTH[truth_rows[0]]), TRUTH[truth_rows[1]])
    assert np.hypot(*(mapper.graph.relative(edge.source, old)[:2] - truth_relative[:2])) < 0.03


def test_bad_start_pose_is_refused(first_run: Mapper):
    with pytest.raises(MapperError, match="start pose must be three finite numbers"):
        first_run.start_session([0.0, float("nan"), 0.0])


def test_bad_files_are_named(first_run: Mapper, tmp_path: Path):
    with pytest.raises(PoseGraphFileError, match="no such pose-graph file"):
        load_posegraph(tmp_path / "missing")
    garbage = tmp_path / "garbage.posegraph"
    garbage.write_bytes(b"not a zip at all")
    with pytest.raises(PoseGraphFileError, match="garbage.posegraph: not a pose-graph file"):
        load_posegraph(garbage)
    good = save_posegraph(first_run, tmp_path / "good")
    with np.load(good) as archive:
        fields = {k: archive[k] for k in archive.files}
    for change, message in [
        (lambda f: f.pop("poses"), "field 'poses' is missing"),
        (lambda f: f.update(version=np.array(7)), "version 7 is not supported"),
        (lambda f: f.update(odom_poses=f["odom_poses"][:, :2]), "field 'odom_poses' has shape"),
        (lambda f: f.update(ray_counts=f["ray_counts"] + 1), "field 'ray_counts' sums to"),
        (lambda f: f.update(edge_nodes=f["edge_nodes"] + 10_000), "edge source .* is not a node"),
    ]:
        broken = dict(fields)
        change(broken)
        path = tmp_path / "broken.posegraph"
        np.savez(path.with_suffix(""), **broken)
        path.with_suffix(".npz").replace(path)
        with pytest.raises(PoseGraphFileError, match=f"broken.posegraph: .*{message}"):
            load_posegraph(path)
    with pytest.raises(PoseGraphFileError, match="nothing to save"):
        save_posegraph(Mapper(), tmp_path / "empty")
    assert posegraph_path("maps/x") == Path("maps/x.posegraph")
