"""Local refinement kernels of the recursion (measure.refine, registration._refine)."""

from __future__ import annotations

import math

import numpy as np

from brokenness.grid import OccupancyMap
from brokenness.masking import ReferenceIndex, cell_points, sample_at
from brokenness.measure.refine import (
    _planes,
    _trig,
    _turn_about,
    _turned,
    fit_rigid,
    polish_transform,
    refine_transform,
    soft_agreement,
    soft_agreements,
    sweep_rotation,
)
from brokenness.registration import _refine
from brokenness.transform import RigidTransform


def _rooms() -> np.ndarray:
    """An asymmetric floor plan with one-cell walls (occupied 1, free 0)."""
    s = np.zeros((160, 220), np.int8)
    occ = np.zeros(s.shape, bool)
    occ[10, 10:210] = occ[150, 10:210] = occ[10:151, 10] = occ[10:151, 210] = True
    occ[10:90, 70] = occ[60, 70:160] = occ[100:151, 130] = occ[30:60, 180] = True
    s[occ] = 1
    return s


def _index() -> tuple[ReferenceIndex, np.ndarray]:
    states = _rooms()
    return ReferenceIndex.build(OccupancyMap(states)), cell_points(states == 1)


def test_fit_rigid_recovers_a_known_motion():
    rng = np.random.default_rng(0)
    src = rng.random((500, 2)) * 3000  # far from the origin: the sums must stay exact
    true = RigidTransform(math.radians(7.5), -12.25, 40.5)
    got = fit_rigid(src, true.apply(src))
    assert abs(got.rotation - true.rotation) < 1e-9
    assert abs(got.tx - true.tx) < 1e-6 and abs(got.ty - true.ty) < 1e-6


def test_batched_scores_equal_one_by_one_scores():
    index, pts = _index()
    fan = [RigidTransform(math.radians(a), 0.3 * a, -0.2 * a) for a in (-2, -1, 0, 1, 2)]
    batch = soft_agreements(index.occupied_distance, fan, pts, 2.0)
    single = [soft_agreement(index.occupied_distance, t.apply(pts), 2.0) for t in fan]
    assert np.allclose(batch, single, rtol=1e-6)
    assert int(np.argmax(batch)) == 2  # the identity aligns the reference with itself


def test_sample_at_handles_long_and_empty_inputs():
    field = np.arange(100, dtype=np.float32).reshape(10, 10)
    pts = np.tile([[3.0, 2.0]], (70_000, 1))  # more than one remap row can hold
    pts[-1] = [50.0, 50.0]  # off the grid
    out = sample_at(field, pts, -1.0)
    assert out.shape == (70_000,) and np.all(out[:-1] == 23.0) and out[-1] == -1.0
    assert sample_at(field, np.zeros((0, 2)), 0.0).shape == (0,)


def test_a_symmetric_fan_is_turned_in_pairs_bit_for_bit():
    # the turns by -a from the products of the turns by a: the same float32 points as
    # turning every row on its own, and a fan that is not symmetric is turned row by row
    rng = np.random.default_rng(4)
    moved = rng.uniform(-300, 900, (777, 2))
    pivot = np.array([211.3, -17.9])
    half = 12
    deltas = [float(d) for d in np.radians(0.25 * np.arange(-half, half + 1)) if d != 0.0]
    pairs = (slice(half, None), slice(half - 1, None, -1))
    for angles in (deltas, deltas[:-1] + [0.05]):
        alone, paired = _planes(len(angles), 777), _planes(len(angles), 777)
        _turned(moved, pivot, _trig(angles), alone)
        _turned(moved, pivot, _trig(angles), paired, pairs)
        assert alone[0].tobytes() == paired[0].tobytes()
        assert alone[1].tobytes() == paired[1].tobytes()


def test_sweep_finds_the_turn_about_the_agreeing_cells():
    index, pts = _index()
    centre = pts.mean(axis=0)
    for deg in (2.0, -2.5, 1.0):
        start = _turn_about(centre, math.radians(deg))  # turned about the centroid
        pivot = start.apply(pts).mean(axis=0)
        swept = sweep_rotation(start, pts, index.occupied_distance, 2.0, pivot)
        assert abs(math.degrees(swept.rotation)) < 0.01
        assert np.mean(RigidTransform().displacement(swept, pts)) < 0.05


def test_icp_and_polish_undo_a_small_error():
    index, pts = _index()
    start = _turn_about(pts.mean(axis=0), math.radians(0.3), 1.6, -1.2)
    fitted = refine_transform(start, pts, index.correspondences, gate=3.0)
    polished = polish_transform(fitted, pts, index.occupied_distance, 2.0)
    assert np.mean(RigidTransform().displacement(polished, pts)) < 0.05
    before = soft_agreement(index.occupied_distance, start.apply(pts), 2.0)
    after = soft_agreement(index.occupied_distance, polished.apply(pts), 2.0)
    assert after > before


def test_gauss_newton_refinement_converges_on_the_distance_map():
    states = _rooms()
    field = _refine.distance_field(_refine.edges(states == 1))
    pts = cell_points(states == 1)
    true = RigidTransform()
    start = RigidTransform(math.radians(1.5), 2.0, -1.0)
    out = _refine.refine_rigid(
        field, pts, start.matrix, start_radius=6.0, end_radius=1.5, iterations=8
    )
    got = RigidTransform.from_matrix(out)
    # one-cell walls give a V-shaped distance with a flat gradient at the wall: the fit
    # brings a 1.5-degree, 2-cell error to within a cell (the recursion's polish does the rest)
    before = np.mean(true.displacement(start, pts))
    after = np.mean(true.displacement(got, pts))
    assert after < 1.0 and after < before / 3
    # a transform far from any wall has no inliers: it comes back unchanged
    far = RigidTransform(0.0, 1000.0, 1000.0)
    assert np.array_equal(
        _refine.refine_rigid(
            field, pts, far.matrix, start_radius=4.0, end_radius=1.5, iterations=4
        ),
        far.matrix,
    )


def test_batched_gauss_newton_equals_one_at_a_time():
    """The registration refines its promising hypotheses together; each comes out as it would
    alone (a far one, with no inlier, unchanged)."""
    states = _rooms()
    field = _refine.distance_field(_refine.edges(states == 1))
    pts = cell_points(states == 1)
    starts = [
        RigidTransform(math.radians(1.5), 2.0, -1.0).matrix,
        RigidTransform(math.radians(-2.0), -1.0, 2.5).matrix,
        RigidTransform(0.0, 1000.0, 1000.0).matrix,
        RigidTransform(math.radians(0.3), 0.4, 0.2).matrix,
    ]
    kwargs = {"start_radius": 6.0, "end_radius": 1.5, "iterations": 8}
    together = _refine.refine_rigid_many(field, pts, starts, **kwargs)
    for start, got in zip(starts, together, strict=True):
        np.testing.assert_allclose(
            got, _refine.refine_rigid(field, pts, start, **kwargs), atol=1e-9
        )
    assert np.array_equal(together[2], starts[2])
    assert _refine.refine_rigid_many(field, pts, [], **kwargs) == []


def test_edge_points_are_the_outline_cells_in_row_order():
    # found from the cells' neighbours: the cells of edges(), in the same (row-major) order
    rng = np.random.default_rng(5)
    for shape, share in [((1300, 40), 0.4), ((1, 9), 0.7), ((7, 1), 0.7), ((60, 70), 0.9)]:
        occupied = rng.random(shape) < share
        rows, cols = np.nonzero(_refine.edges(occupied))
        points = _refine.edge_points(occupied)
        assert points.dtype == np.int32
        np.testing.assert_array_equal(points, np.column_stack([cols, rows]))
    wall = np.zeros((9, 9), bool)
    wall[2:7, 1:8] = True  # a thick wall: its inside is no outline
    assert not (_refine.edge_points(wall)[:, None] == [[4, 4]]).all(axis=2).any()
    assert _refine.edge_points(np.zeros((3, 3), bool)).shape == (0, 2)


def test_outline_distance_field_is_the_edge_distance_field() -> None:
    # walls, a thick block and cells on the grid's border: the outline marked at the cells
    # gives the field of the eroded grid, bit for bit
    rng = np.random.default_rng(2)
    occ = rng.random((90, 120)) < 0.01
    occ[20, 10:100] = occ[30:80, 60] = True
    occ[40:55, 15:40] = True
    occ[0, :30] = occ[:, -1] = True
    outline = _refine.edge_points(occ)
    got = _refine.outline_distance_field(outline, occ.shape)
    expected = _refine.edge_distance_field(occ)
    assert got.dtype == np.float32
    np.testing.assert_array_equal(got.view(np.uint32), expected.view(np.uint32))
