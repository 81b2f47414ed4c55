"""Map quality: wall precision / recall, free coverage and wall distance against a truth grid."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from pppbot_common.maps import FREE, OCCUPIED, UNKNOWN, OccupancyGrid
from pppbot_eval.map_quality import MapQualityError, compare_maps

RES = 0.1


def box_room() -> OccupancyGrid:
    """30×30 cells, free everywhere but a 3-cell-thick square wall ring at indices 5..7 and 22..24.

    Interior: rows/cols 8..21 (14×14 cells). Inner wall faces: the ring at indices 7 and 22
    (16 cells a side: 60 cells); outer faces: the ring at 5 and 24 (20 a side: 76 cells).
    """
    data = np.full((30, 30), FREE, dtype=np.int8)
    data[5:25, 5:25] = OCCUPIED
    data[8:22, 8:22] = FREE
    return OccupancyGrid(data, RES)


def thick_wall() -> OccupancyGrid:
    """20×40 cells, free but a 6-cell-thick wall across all rows at cols 17..22."""
    data = np.full((20, 40), FREE, dtype=np.int8)
    data[:, 17:23] = OCCUPIED
    return OccupancyGrid(data, RES)


INSIDE = (1.5, 1.5)  # world point in the box room's interior


def shifted(grid: OccupancyGrid, cells: int) -> OccupancyGrid:
    """The same data with the origin moved ``cells`` cells along +x."""
    return OccupancyGrid(grid.data.copy(), grid.resolution, (cells * grid.resolution, 0.0, 0.0))


def test_identical_maps_score_perfectly():
    quality = compare_maps(box_room(), box_room(), reachable_from=INSIDE)
    assert (quality.precision, quality.recall, quality.f1, quality.free_coverage) == (1.0, 1.0, 1.0, 1.0)
    assert (quality.mean_wall_distance_m, quality.wall_distance_p95_m) == (0.0, 0.0)
    assert quality.estimated_occupied_cells == 20 * 20 - 14 * 14
    assert not quality.false_walls.any()


def test_reachable_from_counts_only_inner_wall_faces():
    assert compare_maps(box_room(), box_room()).reference_wall_cells == 60 + 76
    quality = compare_maps(box_room(), box_room(), reachable_from=INSIDE)
    assert (quality.reference_wall_cells, quality.reference_free_cells) == (60, 14 * 14)
    expected = np.zeros((30, 30), dtype=bool)
    expected[7:23, 7:23] = True
    expected[8:22, 8:22] = False
    assert np.array_equal(quality.true_walls, expected)


@pytest.mark.parametrize("point", [(0.6, 0.6), (-1.0, 1.0)])  # in the wall; outside the grid
def test_reachable_from_must_be_in_free_space(point):
    with pytest.raises(ValueError, match=f"reachable_from \\({point[0]}, {point[1]}\\)"):
        compare_maps(box_room(), box_room(), reachable_from=point)


def test_one_cell_shift_is_within_tolerance_one_only():
    truth = box_room()
    tolerant = compare_maps(shifted(truth, 1), truth, reachable_from=INSIDE, tolerance_cells=1)
    assert (tolerant.precision, tolerant.recall) == (1.0, 1.0)
    assert tolerant.mean_wall_distance_m is not None and tolerant.mean_wall_distance_m > 0
    strict = compare_maps(shifted(truth, 1), truth, reachable_from=INSIDE, tolerance_cells=0)
    assert strict.precision < 1.0 and strict.recall < 1.0


def test_three_cell_shift_scores_the_overlap():
    """Estimated wall at truth cols 20..25: 20..23 are within one cell of truth cols 17..22, 24..25 aren't;
    the truth's faces are cols 17 (not reached: nearest estimate col 20) and 22 (reached)."""
    truth = thick_wall()
    quality = compare_maps(shifted(truth, 3), truth, tolerance_cells=1)
    assert quality.precision == pytest.approx(4 / 6)
    assert quality.recall == pytest.approx(0.5)
    assert quality.f1 == pytest.approx(4 / 7)
    assert quality.reference_wall_cells == 40
    assert np.array_equal(np.flatnonzero(quality.false_walls.any(axis=0)), [24, 25])
    assert np.array_equal(np.flatnonzero(quality.matched_walls.any(axis=0)), [20, 21, 22, 23])
    # distances from truth cols 20..25 to the wall (col 22): 0, 0, 0, 1, 2, 3 cells
    assert quality.mean_wall_distance_m == pytest.approx(RES * 6 / 6)


def test_ghost_wall_lowers_precision_and_is_a_false_wall():
    truth = box_room()
    estimate = box_room()
    estimate.data[14, 12:18] = OCCUPIED  # 6 cells in the middle of the room
    quality = compare_maps(estimate, truth, reachable_from=INSIDE)
    walls = 20 * 20 - 14 * 14
    assert quality.precision == pytest.approx(walls / (walls + 6))
    assert quality.recall == 1.0
    ghost = np.zeros((30, 30), dtype=bool)
    ghost[14, 12:18] = True
    assert np.array_equal(quality.false_walls, ghost)


def test_half_mapped_room():
    """Columns 15.. unknown: the inner faces keep 8 + 8 + 14 of 60 cells; 7 of 14 free columns remain."""
    estimate = box_room()
    estimate.data[:, 15:] = UNKNOWN
    quality = compare_maps(estimate, box_room(), reachable_from=INSIDE, tolerance_cells=0)
    assert quality.recall == pytest.approx(30 / 60)
    assert quality.free_coverage == pytest.approx(0.5)
    assert quality.precision == 1.0


def test_estimate_in_a_rotated_frame_scores_perfectly():
    """map frame = world rotated 90° and moved to (W·res, 0): est[r, c] = truth[c, W-1-r]."""
    truth = box_room()
    data = truth.data.copy()
    data[20:22, 0:3] = OCCUPIED  # break the symmetry so a wrong rotation would show
    truth = OccupancyGrid(data, RES)
    estimate = OccupancyGrid(truth.data[:, ::-1].T.copy(), RES)
    map_to_world = (truth.width * RES, 0.0, math.pi / 2)
    quality = compare_maps(estimate, truth, map_to_world=map_to_world, reachable_from=INSIDE, tolerance_cells=0)
    assert (quality.precision, quality.recall, quality.free_coverage) == (1.0, 1.0, 1.0)
    assert compare_maps(estimate, truth, reachable_from=INSIDE, tolerance_cells=0).precision < 1.0


def test_estimate_origin_and_resolution_may_differ():
    """A half-resolution estimate with its own origin, sampled from the truth, still matches."""
    truth = box_room()
    fine = np.repeat(np.repeat(truth.data, 2, axis=0), 2, axis=1)[4:, 6:]
    estimate = OccupancyGrid(fine, RES / 2, (6 * RES / 2, 4 * RES / 2, 0.0))
    quality = compare_maps(estimate, truth, reachable_from=INSIDE, tolerance_cells=0)
    assert (quality.precision, quality.recall, quality.free_coverage) == (1.0, 1.0, 1.0)


def test_occupied_cells_outside_the_truth_are_false_walls():
    truth = box_room()
    estimate = OccupancyGrid(np.pad(truth.data, ((0, 0), (0, 2)), constant_values=FREE), RES)
    estimate.data[10, 31] = OCCUPIED
    quality = compare_maps(estimate, truth, reachable_from=INSIDE)
    walls = 20 * 20 - 14 * 14
    assert quality.precision == pytest.approx(walls / (walls + 1))
    assert quality.outside_occupied_cells == 1
    assert quality.mean_wall_distance_m == 0.0  # the outside cell is left out of the distance


def test_empty_estimate_scores_zero_and_stays_json_safe():
    estimate = OccupancyGrid(np.full((30, 30), UNKNOWN, dtype=np.int8), RES)
    quality = compare_maps(estimate, box_room(), reachable_from=INSIDE)
    assert (quality.precision, quality.recall, quality.f1, quality.free_coverage) == (0.0, 0.0, 0.0, 0.0)
    summary = quality.as_dict()
    assert summary["map_mean_wall_distance_m"] is None
    assert set(summary) == {"map_precision", "map_recall", "map_f1", "map_free_coverage", "map_mean_wall_distance_m",
                            "map_wall_distance_p95_m", "map_occupied_cells", "map_reference_wall_cells"}
    json.dumps(summary, allow_nan=False)


def test_intermediate_values_use_nav2_thresholds():
    truth = box_room()
    estimate = box_room()
    estimate.data[estimate.data == OCCUPIED] = 65
    estimate.data[estimate.data == FREE] = 24
    assert compare_maps(estimate, truth, reachable_from=INSIDE).f1 == 1.0
    estimate.data[estimate.data == 65] = 64
    assert compare_maps(estimate, truth, reachable_from=INSIDE).estimated_occupied_cells == 0


@pytest.mark.parametrize("tolerance", [-1, 1.5, True])
def test_bad_tolerance_is_refused(tolerance):
    with pytest.raises(MapQualityError, match="tolerance_cells"):
        compare_maps(box_room(), box_room(), tolerance_cells=tolerance)


def test_truth_without_walls_is_refused():
    empty = OccupancyGrid(np.zeros((5, 5), dtype=np.int8), RES)
    with pytest.raises(MapQualityError, match="no occupied cell"):
        compare_maps(empty, empty)
