"""The real-time cases' measuring helpers (crawler_motion.tools.live_cases), on made-up maps
and paths, without ROS."""

from __future__ import annotations

import numpy as np
import pytest

from crawler_motion.navigation.mission import parse_mission
from crawler_motion.tools.live_cases import (
    BOXES,
    box_distance,
    boxes_in,
    map_figures,
    mission_figures,
)
from crawler_motion.tools.live_nav import LiveResult, MapSnapshot

QUAY, BOX = BOXES["harbour"]


def harbour_map(known_boxes: tuple[tuple[float, float, float, float], ...]) -> MapSnapshot:
    """A 5 cm map of x, y in [-1, 3) x [-2, 1): free, with every cell touching one of
    ``known_boxes`` an obstacle."""
    grid = MapSnapshot(np.zeros((60, 80), dtype=np.int16), (-1.0, -2.0), 0.05)
    x, y = grid.cell_centres()
    for x0, x1, y0, y1 in known_boxes:
        grid.data[(x + 0.025 > x0) & (x - 0.025 < x1) & (y + 0.025 > y0)
                  & (y - 0.025 < y1)] = 100
    return grid


@pytest.mark.parametrize(("area", "inside"), [
    ((0.9, -1.6, 1.4, -0.9), (BOX,)),  # a corner of the box
    ((0.4, -2.6, 2.4, -0.6), (BOX,)),  # the whole box (the shipped mission)
    ((0.8, -1.3, 1.4, -0.85), ()),  # beside it
    ((0.9, -1.45, 1.25, -0.9), ()),  # edges touching the box's: no overlap
    ((0.0, -2.0, 2.0, 0.5), (QUAY, BOX)),
])
def test_boxes_in_an_area(area, inside):
    x0, y0, x1, y1 = area
    assert boxes_in("harbour", [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]) == inside


def test_box_distance_is_zero_inside_and_euclidean_outside():
    xy = np.array([[1.4, -1.6], [1.0, -1.6], [1.0, -1.2]])
    assert box_distance("harbour", xy) == pytest.approx([0.0, 0.25, np.hypot(0.25, 0.25)])


def test_map_figures_count_the_cells_of_the_boxes_asked():
    grid = harbour_map((QUAY,))
    every = map_figures("harbour", grid)
    only_box = map_figures("harbour", grid, (BOX,))
    assert every["wall_cells_obstacle"] > 0 and every["stray_obstacle_cells"] == 0
    assert only_box["wall_cells_known"] == 6 * 6  # a 0.30 m square on the 5 cm cells
    assert only_box["wall_cells_obstacle"] == 0 and only_box["wall_cells_free"] == 36


def test_a_cover_task_reports_its_box_hidden_at_the_start_and_found_at_the_end():
    mission = parse_mission("tasks:\n  - goto: {x: 0.5, y: 0.0}\n"
                            "  - cover: {area: [0.9, -1.6, 1.4, -0.9], spacing: 0.15}\n")
    res = LiveResult(state="DONE", path=np.array([[0.0, 0.0, 0.0], [1.0, 0.5, 0.0]]),
                     map=harbour_map((QUAY, BOX)), task_maps={2: harbour_map((QUAY,))},
                     mission=[{"task_kind": "cover", "covered": 0.95, "distance": 3.0}])
    fig = mission_figures("harbour", res, (0.0, 0.0), list(mission.tasks))
    assert fig["cover_box_cells_at_start"] == 0
    assert fig["cover_box_cells_at_end"] == 36
    assert fig["covered"] == 0.95 and fig["home_error_m"] == pytest.approx(0.5)
    res.task_maps = {}  # no map as the task began: no figure rather than a wrong one
    assert "cover_box_cells_at_start" not in mission_figures("harbour", res, (0.0, 0.0),
                                                             list(mission.tasks))


def test_the_follow_clearance_is_measured_on_the_map_as_the_follow_ended():
    mission = parse_mission("tasks:\n  - follow: {side: left, length: 1.0}\n  - home: {}\n")
    t = np.arange(20.0)
    path = np.column_stack([t, 0.05 * t, np.zeros_like(t)])  # along the quay, 0.475 m off
    res = LiveResult(state="DONE", path=path, disc_radius=0.3,
                     map=harbour_map(()),  # the final window has forgotten the quay
                     task_maps={2: harbour_map((QUAY,))},
                     mission=[{"task_index": 1, "received": 0.0},
                              {"task_index": 2, "received": 19.5}])
    fig = mission_figures("harbour", res, (0.0, 0.0), list(mission.tasks))
    assert fig["follow_clearance_m"] == pytest.approx(0.475 - 0.3, abs=0.03)
