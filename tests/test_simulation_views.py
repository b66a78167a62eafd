"""simulation.views: a run mapped in its own frame (cropped, labelled), its truth, a plan map."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from brokenness import OCCUPIED, load_map, save_map, simulate_broken_map
from brokenness.errors import ParameterError
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.simulation import frame_truth, map_in_frame, plan_map
from brokenness.simulation.bumps import rigid_matrix
from brokenness.simulation.carmen import broken_log_map, log_run, read_carmen

OREBRO = Path(__file__).parent / "data" / "carmen" / "orebro-corrected.log.gz"


@pytest.fixture(scope="module")
def sim():  # noqa: ANN201
    return simulate_broken_map(seed=3, degree=2)


def _agreement(m, ref, labels, truths) -> list[float]:  # noqa: ANN001
    index = ReferenceIndex.build(ref)
    return [
        float(index.occupied_agreement(t.apply(cell_points(labels == j)), 2.0).mean())
        for j, t in enumerate(truths)
    ]


@pytest.mark.parametrize("resolution", [0.05, 0.1])
def test_own_frame_map_and_truth_put_every_partition_on_the_reference(
    sim, resolution: float, tmp_path: Path
) -> None:  # noqa: ANN001
    run = sim.run
    segment = np.zeros(len(run.true_poses), np.int64)
    for p in sim.partitions:
        segment[p.first_scan : p.end_scan] = p.index
    frame = rigid_matrix(math.radians(137.0), 12.3, -40.0)
    m, labels = map_in_frame(
        sim.estimated_poses,
        run.ranges,
        run.angles,
        max_range=run.laser.max_range,
        resolution=resolution,
        frame=frame,
        segment=segment,
    )
    assert m.resolution == resolution
    assert set(np.unique(labels)) == {-1, 0, 1, 2}
    assert np.array_equal(labels >= 0, m.states == OCCUPIED)
    # cropped: occupied cells reach close to every border
    rows, cols = np.nonzero(m.occupied)
    margin = math.ceil(0.5 / resolution) + 1
    assert rows.min() <= margin and cols.min() <= margin
    assert rows.max() >= m.shape[0] - 1 - margin and cols.max() >= m.shape[1] - 1 - margin
    # through the files, as a user has them
    save_map(m, tmp_path / "m.yaml")
    loaded = load_map(tmp_path / "m.yaml")
    truths = [frame_truth(loaded, sim.reference, e, frame) for e in _errors(sim)]
    assert all(abs(t.scale - resolution / 0.05) < 1e-9 for t in truths)
    assert min(_agreement(loaded, sim.reference, labels, truths)) > 0.9
    # the world part undoes the frame and the bump
    assert truths[0].world is not None
    assert abs(truths[0].world.rotation_deg + 137.0) < 1e-6


def _errors(sim) -> list[np.ndarray]:  # noqa: ANN001
    # the world error of each segment, from its true transform's world part (E_j^-1)
    return [np.linalg.inv(p.transform.world.matrix) for p in sim.partitions]


def test_identity_frame_matches_the_simulator(sim) -> None:  # noqa: ANN001
    run = sim.run
    m, labels = map_in_frame(
        sim.estimated_poses, run.ranges, run.angles, max_range=run.laser.max_range, resolution=0.05
    )
    assert set(np.unique(labels)) == {-1, 0}
    truth = frame_truth(m, sim.map, np.eye(3))  # same world: a pure shift of whole cells
    assert abs(truth.rotation) < 1e-12
    assert np.allclose([truth.tx, truth.ty], np.round([truth.tx, truth.ty]), atol=1e-6)
    moved = np.rint(truth.apply(cell_points(m.occupied))).astype(int)
    assert sim.map.states[moved[:, 1], moved[:, 0]].tolist().count(OCCUPIED) == len(moved)


def test_map_in_frame_checks_shapes() -> None:
    with pytest.raises(ParameterError):
        map_in_frame(np.zeros((2, 3)), np.ones((3, 4)), np.zeros(4), max_range=5, resolution=0.1)


def test_plan_map_shares_the_reference_grid_and_holds_its_walls(sim) -> None:  # noqa: ANN001
    plan = plan_map(sim.building, 0.05)
    assert plan.shape == sim.reference.shape and plan.origin == sim.reference.origin
    assert plan.n_occupied > 0.5 * sim.reference.n_occupied  # walls never seen are there too
    near = ReferenceIndex.build(plan).occupied_agreement(
        cell_points(sim.reference.occupied).astype(float), 2.0
    )
    assert near.mean() > 0.95  # what the robot saw lies on the plan's walls
    assert plan.states[0, 0] == -1  # the margin is unknown
    coarse = plan_map(sim.building, 0.1)
    assert coarse.resolution == 0.1 and coarse.n_occupied < plan.n_occupied
    with pytest.raises(ParameterError):
        plan_map(sim.building, 0.0)


def test_log_run_is_the_run_broken_log_map_breaks() -> None:
    log = read_carmen(OREBRO)
    run, extent = log_run(log, max_range=10.0)
    assert run.ranges.shape == log.ranges.shape and run.laser.max_range == 10.0
    assert (run.ranges >= log.hit_range).sum() == 0  # no returns ignored
    x0, y0, x1, y1 = extent
    assert (log.poses[:, 0] >= x0).all() and (log.poses[:, 1] <= y1).all()
    sim = broken_log_map(log, degree=0, resolution=0.1, max_range=10.0)
    m, _ = map_in_frame(
        run.true_poses, run.ranges, run.angles, max_range=10.0, resolution=0.1, margin=0.5
    )
    assert abs(m.n_occupied - sim.reference.n_occupied) <= 0.02 * sim.reference.n_occupied
