"""simulation.plan_run: a tour planned through a map or floor plan, scanned, broken, measured."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from brokenness import FREE, OCCUPIED, UNKNOWN, OccupancyMap, compute_brokenness, load_map
from brokenness.errors import MapError, ParameterError
from brokenness.io import MapWarning
from brokenness.masking import ReferenceIndex
from brokenness.simulation import Bump, plan_route, simulate_plan_run
from brokenness.simulation.ground_truth import broken_map_from_run, reference_map
from brokenness.simulation.plan_run import ROUTE_CELL

DEPOT = Path(__file__).parent / "data" / "depot.yaml"


def _two_rooms(resolution: float = 0.05) -> OccupancyMap:
    """Two 6 x 6 m rooms side by side, a 1 m door between them, unknown outside."""
    cells = round(1.0 / resolution)
    states = np.full((8 * cells, 15 * cells), UNKNOWN, dtype=np.int8)
    states[cells : 7 * cells, cells : 14 * cells] = OCCUPIED
    states[cells + 2 : 7 * cells - 2, cells + 2 : 14 * cells - 2] = FREE
    wall = slice(7 * cells - 1, 8 * cells + 1)  # the wall between them, 0.1 m thick
    states[cells : 7 * cells, wall] = OCCUPIED
    states[int(3.5 * cells) : int(4.5 * cells), wall] = FREE  # the door
    return OccupancyMap(states, resolution, (0.0, 0.0, 0.0), "two rooms")


def _clearance_at(plan: OccupancyMap, xy: np.ndarray) -> np.ndarray:
    """Metres from each world point to the nearest cell of the plan that is not free."""
    res = plan.resolution
    assert res is not None
    free = np.asarray(plan.states == FREE, dtype=np.uint8)
    room = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE) * res
    cols = (xy[:, 0] / res).astype(int)
    rows = (plan.shape[0] - xy[:, 1] / res).astype(int)
    return room[rows, cols]


def test_the_route_keeps_clear_of_the_walls_and_goes_through_the_door() -> None:
    plan = _two_rooms()
    route = plan_route(plan, clearance=0.4, rng=np.random.default_rng(3))
    # every point of every segment, sampled every 2 cm, keeps the promised clearance
    steps = [
        a + (b - a) * t[:, None]
        for a, b in zip(route[:-1], route[1:], strict=True)
        for t in [np.linspace(0.0, 1.0, max(2, int(np.hypot(*(b - a)) / 0.02)))]
    ]
    along = np.concatenate(steps)
    assert _clearance_at(plan, along).min() >= 0.4 - ROUTE_CELL
    # both rooms are visited (the wall between them is at x = 7-8 m)
    assert (route[:, 0] < 6.0).any() and (route[:, 0] > 9.0).any()


def test_the_same_generator_state_gives_the_same_run() -> None:
    plan = _two_rooms()
    a, extent = simulate_plan_run(plan, rng=np.random.default_rng(5))
    b, _ = simulate_plan_run(plan, rng=np.random.default_rng(5))
    np.testing.assert_array_equal(a.true_poses, b.true_poses)
    np.testing.assert_array_equal(a.ranges, b.ranges)
    assert extent == (0.0, 0.0, 15.0, 8.0)
    # the tour starts at another waypoint for another state
    c, _ = simulate_plan_run(plan, rng=np.random.default_rng(6))
    assert not np.array_equal(a.true_poses[:1], c.true_poses[:1])


def test_scans_hit_the_walls_of_the_plan() -> None:
    plan = _two_rooms()
    run, _ = simulate_plan_run(plan, rng=np.random.default_rng(1))
    hit = run.ranges < run.laser.max_range
    assert hit.mean() > 0.9  # rooms of 6 m, a laser of 8 m: nearly every beam hits a wall
    ends = np.stack(
        [
            run.true_poses[:, :1] + run.ranges * np.cos(run.true_poses[:, 2:] + run.angles),
            run.true_poses[:, 1:2] + run.ranges * np.sin(run.true_poses[:, 2:] + run.angles),
        ],
        axis=-1,
    )[hit]
    # the end points lie on the walls: within 5 cm (range noise 1 cm, half a cell) of one
    assert np.percentile(_clearance_at(plan, ends), 99) <= 0.05


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"clearance": 0.0}, "clearance must be a positive number, got 0.0"),
        ({"clearance": math.nan}, "clearance must be a positive number"),
        ({"waypoint_spacing": -1.0}, "waypoint_spacing must be a positive number"),
    ],
)
def test_bad_options_are_refused(kwargs: dict[str, float], message: str) -> None:
    with pytest.raises(ParameterError, match=message):
        plan_route(_two_rooms(), **kwargs)


def test_a_plan_with_no_room_for_the_robot_is_refused() -> None:
    states = np.full((40, 40), OCCUPIED, dtype=np.int8)
    states[10:30, 19:21] = FREE  # a corridor 0.1 m wide
    plan = OccupancyMap(states, 0.05, (0.0, 0.0, 0.0), "narrow")
    with pytest.raises(MapError, match="no free cell of the plan is 0.4 m from every wall"):
        plan_route(plan)
    with pytest.raises(MapError, match="no resolution"):
        plan_route(OccupancyMap(states, None, None, "no resolution"))


def test_a_broken_map_of_a_toured_plan_is_measured_with_its_degree() -> None:
    """The Nav2 depot, toured and scanned, one bump turning the second half of the run by
    40 degrees: degree 1, both halves where the bump says."""
    with pytest.warns(MapWarning, match="read as FREE"):  # the YAML's thresholds, as Nav2 has it
        plan = load_map(DEPOT)
    run, extent = simulate_plan_run(plan, rng=np.random.default_rng(2))
    reference = reference_map(run, extent, 0.05)
    bump = Bump(scan=len(run.true_poses) // 2, theta=math.radians(40.0), d=0.6, direction=1.0)
    broken, expected, parts, *_ = broken_map_from_run(
        run, reference, [bump], extent=extent, index=ReferenceIndex.build(reference)
    )
    assert expected == 1
    result = compute_brokenness(broken, reference)
    assert result.degree == 1
    turns = sorted(abs(p.transform.rotation_deg) for p in result.partitions)
    truth = sorted(abs(p.transform.rotation_deg) for p in parts)
    np.testing.assert_allclose(turns, truth, atol=1.0)


def test_waypoints_too_close_for_the_memory_bound_are_spread(monkeypatch) -> None:
    """Waypoints a micrometre apart would make every route cell one, and the tour's distances
    (waypoints x route cells) grow with the square of the plan: the blocks are doubled until
    they fit ``MAX_TOUR_ENTRIES``, and the tour still goes through both rooms."""
    import brokenness.simulation.plan_run as plan_run

    plan = _two_rooms()
    seen: list[int] = []
    tour = plan_run._tour

    def counted(inside, nodes, rows, cols, waypoints, start):  # noqa: ANN001, ANN202
        seen.append(waypoints.size * rows.size)
        return tour(inside, nodes, rows, cols, waypoints, start)

    monkeypatch.setattr(plan_run, "_tour", counted)
    monkeypatch.setattr(plan_run, "MAX_TOUR_ENTRIES", 20_000)
    route = plan_route(plan, waypoint_spacing=1e-6, rng=np.random.default_rng(3))
    assert 0 < seen[0] <= 20_000
    assert (route[:, 0] < 6.0).any() and (route[:, 0] > 9.0).any()


def test_a_plan_finer_than_the_route_grid_by_far_is_refused_quickly() -> None:
    # a micrometre a cell: the whole plan is less than one route cell (no block grid as large
    # as a route cell is made), and no cell is 0.4 m from a wall
    plan = OccupancyMap(_two_rooms().states, 1e-6, (0.0, 0.0, 0.0), "tiny")
    with pytest.raises(MapError, match="no free cell of the plan is 0.4 m from every wall"):
        plan_route(plan)
