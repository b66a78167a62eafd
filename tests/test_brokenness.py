"""End-to-end: compute_brokenness on real maps broken on purpose by known rigid motions."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from _breaking import break_map, move_about, strips

from brokenness import (
    NOT_OCCUPIED,
    UNASSIGNED,
    MapError,
    OccupancyMap,
    ParameterError,
    RigidTransform,
    compute_brokenness,
    load_map,
    resample_to_resolution,
)
from brokenness.grid import FREE, OCCUPIED, UNKNOWN
from brokenness.io.resample import cell_scale_offset
from brokenness.limits import MAX_CELLS_ENV
from brokenness.masking import cell_points
from brokenness.measure.walls import wall_thickness

DATA = Path(__file__).parent / "data"
MAPS = ["depot.yaml", "tb3_sandbox.yaml", "building_31.yaml", "willow-2010-02-18-0.10.yaml"]


@pytest.fixture(scope="module")
def maps() -> dict[str, OccupancyMap]:
    with pytest.warns():  # depot.yaml: the Nav2 free_thresh warning
        depot = load_map(DATA / "depot.yaml")
    out = {name: load_map(DATA / name) for name in MAPS if name != "depot.yaml"}
    out["depot.yaml"] = depot
    return out


def _mean_error(found: RigidTransform, truth: RigidTransform, labels: np.ndarray, i: int) -> float:
    pts = cell_points(labels == i)
    return float(found.displacement(truth, pts).mean())


def _match(result, truths, labels=None):
    """Map each found partition to the truth transform it is closest to (mean displacement)."""
    labels = result.labels if labels is None else labels
    pairs = []
    for p in result.partitions:
        errors = [_mean_error(p.transform, t, labels, p.index) for t in truths]
        j = int(np.argmin(errors))
        pairs.append((j, errors[j]))
    return pairs


@pytest.mark.parametrize("name", MAPS)
def test_reference_against_itself_is_degree_zero(maps, name):
    ref = maps[name]
    result = compute_brokenness(ref, ref)
    assert result.degree == 0
    assert len(result.partitions) == 1
    p = result.partitions[0]
    assert abs(p.transform.rotation_deg) < 0.05
    assert np.hypot(*p.transform.translation) < 0.1
    assert result.unassigned_cells == 0 and p.fraction == 1.0
    assert p.transform.world is not None
    assert np.hypot(*p.transform.world.translation) < 0.01


@pytest.mark.parametrize("name", ["depot.yaml", "building_31.yaml", "tb3_sandbox.yaml"])
def test_one_large_rotated_region_is_degree_one(maps, name):
    ref = maps[name]
    h, w = ref.shape
    regions = strips(ref.shape, [0.6])
    motions = [RigidTransform(), move_about((0.8 * w, h / 2), 12.0, (5.0, -4.0))]
    broken, truths = break_map(ref, regions, motions, pad=w // 6)
    result = compute_brokenness(broken, ref)
    assert result.degree == 1
    pairs = _match(result, truths)
    assert sorted(j for j, _ in pairs) == [0, 1]
    assert all(err < 1.5 for _, err in pairs), pairs
    for p, (j, _) in zip(result.partitions, pairs, strict=True):
        assert abs(p.transform.rotation_deg - truths[j].rotation_deg) < 1.0
    # the rotated region is 12 degrees off the rest
    assert abs(abs(result.partitions[1].rotation_offset_deg) - 12.0) < 1.0
    assert result.partitions[1].displacement > 5.0
    assert result.partitions[0].cells >= result.partitions[1].cells
    assert result.unassigned_fraction < 0.05


def test_four_strips_of_a_building_is_degree_three(maps):
    ref = maps["building_31.yaml"]
    h, w = ref.shape
    regions = strips(ref.shape, [0.3, 0.55, 0.8])
    motions = [
        RigidTransform(),
        move_about((0.42 * w, h / 2), -20.0, (3.0, 6.0)),
        move_about((0.67 * w, h / 2), 35.0, (-4.0, 2.0)),
        move_about((0.9 * w, h / 2), 90.0, (0.0, 0.0)),
    ]
    broken, truths = break_map(ref, regions, motions, pad=max(h, w) // 4)
    result = compute_brokenness(broken, ref)
    pairs = _match(result, truths)
    assert result.degree == 3, (pairs, [p.fraction for p in result.partitions])
    assert sorted(j for j, _ in pairs) == [0, 1, 2, 3]
    assert all(err < 1.5 for _, err in pairs)
    sizes = [p.cells for p in result.partitions]
    assert sizes == sorted(sizes, reverse=True)
    assert result.unassigned_fraction < 0.05
    assert sum(sizes) + result.unassigned_cells == result.occupied_cells


def _salt_and_pepper(m: OccupancyMap, rate: float, seed: int) -> OccupancyMap:
    rng = np.random.default_rng(seed)
    states = m.states.copy()
    flip = (rng.random(m.shape) < rate) & m.free
    states[flip] = OCCUPIED
    return m.with_states(states)


def _thicken(m: OccupancyMap) -> OccupancyMap:
    occ = cv2.dilate(m.occupied.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    states = m.states.copy()
    states[occ] = OCCUPIED
    return m.with_states(states)


def _jitter(m: OccupancyMap, seed: int) -> OccupancyMap:
    """Move every occupied cell by -1, 0 or +1 in x and y."""
    rng = np.random.default_rng(seed)
    pts = cell_points(m.occupied).astype(int)
    pts += rng.integers(-1, 2, size=pts.shape)
    h, w = m.shape
    pts[:, 0] = pts[:, 0].clip(0, w - 1)
    pts[:, 1] = pts[:, 1].clip(0, h - 1)
    states = m.states.copy()
    states[m.occupied] = FREE
    states[pts[:, 1], pts[:, 0]] = OCCUPIED
    return m.with_states(states)


@pytest.mark.parametrize("name", ["building_31.yaml", "depot.yaml", "tb3_sandbox.yaml"])
@pytest.mark.parametrize("noise", ["salt-and-pepper", "thick walls", "jitter"])
def test_noise_alone_does_not_break_a_map(maps, name, noise):
    ref = maps[name]
    noisy = {
        "salt-and-pepper": lambda m: _salt_and_pepper(m, 0.01, 3),
        "thick walls": _thicken,
        "jitter": lambda m: _jitter(m, 5),
    }[noise](ref)
    result = compute_brokenness(noisy, ref)
    assert result.degree == 0
    p = result.partitions[0]
    assert abs(p.transform.rotation_deg) < 0.3 and np.hypot(*p.transform.translation) < 1.0


def test_deterministic_bit_for_bit(maps):
    ref = maps["building_31.yaml"]
    h, w = ref.shape
    broken, _ = break_map(
        ref, strips(ref.shape, [0.6]), [RigidTransform(), move_about((0.8 * w, h / 2), -25, (3, 3))]
    )
    a = compute_brokenness(broken, ref)
    b = compute_brokenness(broken, ref)
    assert a.degree == b.degree
    assert np.array_equal(a.labels, b.labels)
    assert [p.transform for p in a.partitions] == [p.transform for p in b.partitions]


def test_labels_account_for_every_occupied_cell(maps):
    ref = maps["tb3_sandbox.yaml"]
    result = compute_brokenness(_salt_and_pepper(ref, 0.02, 1), ref)
    labels = result.labels
    assert labels.shape == ref.shape and labels.dtype == np.int16
    noisy_occupied = np.count_nonzero(labels != NOT_OCCUPIED)
    assert noisy_occupied == result.occupied_cells
    assert np.count_nonzero(labels == UNASSIGNED) == result.unassigned_cells
    assert sum(p.cells for p in result.partitions) + result.unassigned_cells == noisy_occupied


def test_coarser_map_is_brought_to_the_reference_resolution(maps):
    ref = maps["building_31.yaml"]
    coarse = resample_to_resolution(ref, 0.1)
    result = compute_brokenness(coarse, ref)
    assert result.degree == 0
    t = result.partitions[0].transform
    assert t.scale == pytest.approx(2.0)
    assert abs(t.rotation_deg) < 0.3
    # coarse cell centres land on the reference cells they cover
    assert t.world is not None and np.hypot(*t.world.translation) < 0.06
    assert result.labels.shape == coarse.shape


@pytest.mark.parametrize("shift", [(8.0, 0.0), (0.0, 6.0)])
def test_finer_map_is_measured_at_its_own_resolution(maps, shift):
    # a part shifted by 0.3-0.4 m: 6-8 cells of the map, 3-4 of a reference at 0.1 m, where
    # the downsampled map's two parts were within the merge threshold of each other (degree 0)
    ref = maps["building_31.yaml"]
    coarse = resample_to_resolution(ref, 0.1)
    motions = [RigidTransform(), RigidTransform(0.0, *shift)]
    broken, truths = break_map(ref, strips(ref.shape, [0.5]), motions, pad=40)
    result = compute_brokenness(broken, coarse)
    assert result.degree == 1
    assert result.parameters["working_resolution"] == pytest.approx(0.05)
    assert result.labels.shape == broken.shape
    s, tx, ty = cell_scale_offset(ref, coarse)
    to_coarse = RigidTransform(0.0, tx, ty, s)
    for _, error in _match(result, [to_coarse.compose(t) for t in truths]):
        assert error < 1.0  # reference cells (0.1 m)
    assert {i for i, _ in _match(result, [to_coarse.compose(t) for t in truths])} == {0, 1}
    # displacements are reported in reference cells: the shift, halved
    assert result.partitions[1].displacement == pytest.approx(np.hypot(*shift) / 2, abs=0.5)
    assert result.partitions[1].displacement_m == pytest.approx(
        result.partitions[1].displacement * 0.1
    )


def test_map_four_times_coarser_than_the_reference(maps):
    # A map at 0.2 m against its reference at 0.05 m: upsampled, each map cell is 4 x 4
    # working cells and its walls 4 cells thick, so at c = 2 the two parts fell apart into
    # pieces (degree 4 here); the threshold is raised to the map cell's side.
    ref = maps["building_31.yaml"]
    h, w = ref.shape
    motions = [RigidTransform(), move_about((0.75 * w, h / 2), 12.0, (10.0, -8.0))]
    broken, truths = break_map(ref, strips(ref.shape, [0.5]), motions, pad=40)
    coarse = resample_to_resolution(broken, 0.2)
    result = compute_brokenness(coarse, ref)
    assert result.degree == 1
    assert result.parameters["threshold"] == 2.0  # as asked, for the record
    # downsampled, the map draws its walls two cells thick, the reference two working
    # cells: 4 + 4 (2 - 1) / 2 - (2 - 1) / 2 (session 42; 4 for walls of one cell)
    assert wall_thickness(cell_points(coarse.occupied)) == 2
    assert wall_thickness(cell_points(ref.occupied)) == 2
    assert result.parameters["working_threshold"] == pytest.approx(5.5)
    assert result.parameters["working_resolution"] == pytest.approx(0.05)
    s, tx, ty = cell_scale_offset(broken, coarse)
    from_coarse = RigidTransform(0.0, tx, ty, s).inverse()
    matched = _match(result, [t.compose(from_coarse) for t in truths])
    assert {i for i, _ in matched} == {0, 1}
    for _, error in matched:
        assert error < 2.0  # reference cells (0.05 m); a map cell is 4 of them
    # twice as coarse: a map cell's side is the threshold as asked, c = 2; walls of two
    # map cells reach 2 + 2 (2 - 1) / 2 - (2 - 1) / 2 working cells
    half_map = resample_to_resolution(broken, 0.1)
    half = compute_brokenness(half_map, ref)
    assert half.degree == 1
    assert wall_thickness(cell_points(half_map.occupied)) == 2
    assert half.parameters["working_threshold"] == pytest.approx(2.5)


def test_reference_too_large_upsampled_downsamples_the_map(maps, monkeypatch):
    ref = maps["building_31.yaml"]
    coarse = resample_to_resolution(ref, 0.1)
    # the reference at 5 cm (648 x 694 cells) exceeds the limit; the map at 10 cm fits it
    monkeypatch.setenv(MAX_CELLS_ENV, str(400_000))
    result = compute_brokenness(ref, coarse)
    assert result.parameters["working_resolution"] == pytest.approx(0.1)
    assert result.degree == 0
    assert result.partitions[0].transform.scale == pytest.approx(0.5)
    assert result.labels.shape == ref.shape


def test_world_transform_in_metres(maps):
    ref = maps["depot.yaml"]
    h, w = ref.shape
    motions = [RigidTransform(), move_about((0.8 * w, h / 2), 12.0, (5.0, -4.0))]
    broken, truths = break_map(ref, strips(ref.shape, [0.6]), motions, pad=40)
    result = compute_brokenness(broken, ref)
    for p in result.partitions:
        world = p.transform.world
        assert world is not None
        # a cell moved by the cell transform lands where the world transform puts it
        cell = np.array([[100.0, 50.0]])
        a = broken.cell_to_world_matrix() @ np.array([100.0, 50.0, 1.0])
        b = ref.cell_to_world_matrix() @ np.append(p.transform.apply(cell)[0], 1.0)
        np.testing.assert_allclose(world.apply(a[None, :2])[0], b[:2], atol=1e-9)
    # the unmoved part: the broken map's origin was shifted by the pad, so in metres it is identity
    assert np.hypot(*result.partitions[0].transform.world.translation) < 0.05
    assert result.partitions[1].displacement_m == pytest.approx(
        result.partitions[1].displacement * 0.05
    )


def test_empty_and_bad_inputs(maps):
    ref = maps["tb3_sandbox.yaml"]
    empty = OccupancyMap(np.zeros((20, 20), np.int8))
    with pytest.raises(MapError, match="no occupied"):
        compute_brokenness(empty, ref)
    with pytest.raises(MapError, match="no occupied"):
        compute_brokenness(ref, empty)
    with pytest.raises(ParameterError):
        compute_brokenness(ref, ref, threshold=0)
    # an absurd threshold is refused, and the message names the value given
    with pytest.raises(ParameterError, match=r"threshold 1000000\.0 implies a neighbourhood"):
        compute_brokenness(ref, ref, threshold=1e6)
    with pytest.raises(ParameterError) as huge:  # one short line, not a 300-digit number
        compute_brokenness(ref, ref, threshold=1e300)
    assert len(str(huge.value)) < 200 and "\n" not in str(huge.value)
    with pytest.raises(ParameterError):
        compute_brokenness(ref, ref, method="magic")
    with pytest.raises(MapError):
        compute_brokenness(np.array([[np.nan, 1.0]]), ref)
    all_unknown = OccupancyMap(np.full((5, 5), UNKNOWN, np.int8))
    with pytest.raises(MapError):
        compute_brokenness(all_unknown, ref)


def test_accepts_paths_and_arrays(maps):
    ref = maps["tb3_sandbox.yaml"]
    by_path = compute_brokenness(DATA / "tb3_sandbox.yaml", str(DATA / "tb3_sandbox.yaml"))
    by_array = compute_brokenness(ref.occupied, ref.occupied)
    assert by_path.degree == 0 and by_array.degree == 0
    assert math.isclose(by_path.partitions[0].fraction, 1.0)


@pytest.mark.parametrize("name", ["building_31.yaml", "depot.yaml"])
def test_broken_and_noisy_map_keeps_its_degree(maps, name):
    """Noise on top of a structural error neither hides it nor adds partitions.

    (Not on tb3_sandbox: its hexagonal arena is symmetric, and a 125-cell part of it under
    this much noise fits more than one place.)
    """
    ref = maps[name]
    h, w = ref.shape
    motions = [RigidTransform(), move_about((0.8 * w, h / 2), -15.0, (4.0, 3.0))]
    broken, truths = break_map(ref, strips(ref.shape, [0.6]), motions, pad=w // 6)
    noisy = _jitter(_salt_and_pepper(broken, 0.005, 11), 12)
    result = compute_brokenness(noisy, ref)
    assert result.degree == 1
    pairs = _match(result, truths)
    assert sorted(j for j, _ in pairs) == [0, 1]
    assert all(err < 2.0 for _, err in pairs), pairs


def test_nothing_found_is_said_not_hidden():
    """Scattered dots against a room: no partition, no degree (not measured), a warning."""
    from brokenness import NothingFoundWarning

    room = np.zeros((80, 80), bool)
    room[10, 10:70] = room[70, 10:70] = room[10:70, 10] = room[10:70, 70] = True
    room[10:40, 40] = True
    dots = np.zeros((80, 80), bool)
    dots[np.random.default_rng(0).random((80, 80)) < 0.01] = True
    with pytest.warns(NothingFoundWarning):
        result = compute_brokenness(dots, room)
    assert result.degree is None and result.partitions == ()
    assert not result.measured and "not the same place" in result.reason
    assert result.to_dict()["degree"] is None and result.to_dict()["measured"] is False
    assert result.unassigned_fraction == 1.0
