"""Recovery of partitions the greedy recursion lost, and joining of partitions that are one.

The end-to-end case: building 31 (a real map) cut into 3 x 2 rectangles, five of them
turned and shifted by known amounts (the benchmark's degree-5 case). A small rectangle
(6 % of the cells) loses most of its cells to the four partitions found before it, under
whose transforms its walls land on reference walls by coincidence; without the recovery
the degree comes out 4.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from _breaking import SETTINGS, break_map, move_about

import brokenness.measure.recovery as recovery
import brokenness.measure.recursion as recursion
import brokenness.measure.settle as settle_module
from brokenness import OccupancyMap, RigidTransform, compute_brokenness, load_map
from brokenness.masking import ReferenceIndex, cell_points
from brokenness.measure.context import MapContext
from brokenness.measure.evidence import ClearFree
from brokenness.measure.partitions import Found, consolidate, reassign
from brokenness.measure.recovery import agreement_support
from brokenness.registration.base import Candidate

DATA = Path(__file__).parent / "data"


@pytest.fixture(scope="module")
def building() -> OccupancyMap:
    m = load_map(DATA / "building_31.yaml")
    states = np.full((520, 520), -1, np.int8)
    h, w = m.shape
    r0, c0 = max((h - 520) // 2, 0), max((w - 520) // 2, 0)
    crop = m.states[r0 : r0 + 520, c0 : c0 + 520]
    R0, C0 = (520 - crop.shape[0]) // 2, (520 - crop.shape[1]) // 2
    states[R0 : R0 + crop.shape[0], C0 : C0 + crop.shape[1]] = crop
    return OccupancyMap(states, m.resolution, (0.0, 0.0, 0.0))


def _three_by_two(ref: OccupancyMap, max_angle: float):
    h, w = ref.shape
    regions, motions = [], []
    for i in range(6):
        region = np.zeros(ref.shape, bool)
        r, c = divmod(i, 2)
        region[r * h // 3 : (r + 1) * h // 3, c * w // 2 : (c + 1) * w // 2] = True
        rows, cols = np.nonzero(region)
        angle = 0.0 if i == 0 else max_angle * (1 if i % 2 else -1) * (0.5 + i / 12)
        shift = (2.0 * i, -1.5 * i)
        motions.append(move_about((cols.mean(), rows.mean()), angle, shift) if i else None)
        regions.append(region)
    motions[0] = RigidTransform()
    broken, truths = break_map(ref, regions, motions, pad=40)
    return broken, truths


def _errors(result, truths) -> list[float]:
    """Per found partition, mean displacement (cells) from the nearest true transform."""
    out = []
    for p in result.partitions:
        pts = cell_points(result.labels == p.index)
        out.append(min(float(p.transform.displacement(t, pts).mean()) for t in truths))
    return out


@pytest.mark.parametrize("max_angle", [15.0, 20.0, 25.0])
def test_a_partition_lost_to_coincidences_is_recovered(building, max_angle, monkeypatch):
    """Degree 5 with six true partitions (at 10 degrees the degree is 5 too, but one part is
    placed by a wrong transform under which it agrees as well: see the README)."""
    broken, truths = _three_by_two(building, max_angle)
    result = compute_brokenness(broken, building)
    assert result.degree == 5
    assert max(_errors(result, truths)) < 3.0  # six true partitions, none twice
    assert result.unassigned_cells < 0.02 * result.occupied_cells
    # no suspect, no split of settle and no pass over the call's hypotheses (each finds the
    # lost part too): the recursion alone
    monkeypatch.setattr(recovery, "SUPPORT_SHARE", 0.0)
    monkeypatch.setattr(settle_module, "_best_split", lambda *args: None)
    monkeypatch.setattr(recursion, "pooled_partitions", lambda found, *args: found)
    assert compute_brokenness(broken, building).degree == 4


@pytest.mark.parametrize("max_angle", [20.0, 25.0])
def test_the_lost_partition_is_among_the_calls_hypotheses(building, max_angle, monkeypatch):
    """Without the recovery's suspects and settle's split, the pass over the call's
    hypotheses (``recovery.pooled_partitions``) finds the lost part: its true transform was
    a hypothesis of an earlier registration (without the pass, the degree is 4: above)."""
    broken, truths = _three_by_two(building, max_angle)
    monkeypatch.setattr(recovery, "SUPPORT_SHARE", 0.0)
    monkeypatch.setattr(settle_module, "_best_split", lambda *args: None)
    result = compute_brokenness(broken, building)
    assert result.degree == 5
    assert max(_errors(result, truths)) < 3.0


def test_recovery_adds_nothing_to_the_reference_against_itself(building, monkeypatch):
    calls = []
    real = recovery.best_hypothesis
    monkeypatch.setattr(
        recovery, "best_hypothesis", lambda *a, **k: calls.append(1) or real(*a, **k)
    )
    result = compute_brokenness(building, building)
    assert result.degree == 0
    assert result.unassigned_cells == 0
    assert not calls  # no cell is a suspect: nothing was registered again


def test_agreement_support_tells_scattered_cells_from_a_partition():
    # a reference of parallel walls every 6 cells; the map's left half is the same, its
    # right half is shifted by 3 cells (between the walls)
    ref = np.zeros((120, 120), bool)
    ref[10:110:6, 10:110] = True
    m = np.zeros_like(ref)
    m[10:110:6, 10:60] = True
    m[13:110:6, 60:110] = True
    index = ReferenceIndex.build(OccupancyMap.from_array(ref))
    points = cell_points(m)
    left = np.flatnonzero(points[:, 0] < 60)
    right = np.flatnonzero(points[:, 0] >= 60)
    # the identity partition also claims every fifth cell on the right (a coincidence)
    stolen = right[::5]
    found = [
        Found(RigidTransform(), np.concatenate([left, stolen]), 1.0, 0.0),
        Found(RigidTransform(0.0, 0.0, -3.0), np.setdiff1d(right, stolen), 1.0, 0.0),
    ]
    support = agreement_support(found, points, index, 2.0, ref.shape, radius=8)
    interior = left[points[left, 0] < 45]
    assert np.all(support[interior] == 1.0)
    assert np.all(support[stolen[points[stolen, 0] > 75]] < 0.3)  # scattered: suspects
    assert np.all(support[found[1].members] > 0.45)  # a partition's own (border included)


def test_consolidate_joins_one_rigid_piece_and_keeps_two_apart():
    ref = np.zeros((160, 160), bool)
    ref[20, 10:150] = ref[140, 10:150] = ref[20:141, 10] = ref[20:141, 150] = True
    ref[20:80, 60] = ref[90:141, 100] = ref[100, 100:150] = True
    index = ReferenceIndex.build(OccupancyMap.from_array(ref))
    points = cell_points(ref)
    top = np.flatnonzero(points[:, 1] < 80)
    bottom = np.flatnonzero(points[:, 1] >= 80)
    same = [
        Found(RigidTransform(), top, 1.0, 0.0),
        Found(RigidTransform(0.0, 0.4, -0.3), bottom, 1.0, 0.0),  # the same piece
    ]
    joined = consolidate(same, points, index, SETTINGS)
    assert len(joined) == 1 and joined[0].members.size == points.shape[0]
    # the bottom half turned by 20 degrees about its centre: a broken map of degree 1
    motion = move_about((80.0, 110.0), 20.0, (0.0, 0.0))
    moved = np.rint(motion.apply(points[bottom]))
    broken = np.concatenate([points[top], moved])
    apart = [
        Found(RigidTransform(), np.arange(top.size), 1.0, 0.0),
        Found(motion.inverse(), np.arange(top.size, broken.shape[0]), 1.0, 0.0),
    ]
    kept = consolidate(apart, broken, index, SETTINGS)
    assert len(kept) == 2
    assert sorted(f.members.size for f in kept) == sorted([top.size, bottom.size])


@pytest.mark.parametrize("shift", [(0.0, 12.0), (12.0, 0.0)])
def test_a_part_shifted_along_its_walls_takes_its_own_region(shift, corner, corner_index):
    """A pure-shift bump: the right part of building 31 (a fifth of its walls) shifted by
    12 cells. The partition of the left part's transform holds every cell that agrees
    under it, among them the right part's walls along the shift (a third to a half of
    them), so few of the right part's cells are suspects. The cells its true transform
    would *take* (coherent, and their neighbourhood agreeing more under it than under
    their partition's) are the right part's, nearly all of them, and hardly any of the
    left part's; the left part's own transform takes nothing, and a wrong one little."""
    index = corner_index
    points = cell_points(corner.occupied)
    right = points[:, 0] >= 360
    moved = points.copy()
    moved[right] += shift
    left_t, right_t = RigidTransform(), RigidTransform(0.0, -shift[0], -shift[1])
    agree = index.occupied_agreement(left_t.apply(moved), SETTINGS.threshold)
    assert 0.3 < np.count_nonzero(agree & right) / np.count_nonzero(right) < 0.6
    found = [Found(left_t, np.flatnonzero(agree), 1.0, 0.0)]
    owner = recovery.owners(found, moved.shape[0])
    counts = recovery._owner_counts(found, owner, moved, index, SETTINGS.threshold)
    around = recovery.occupied_around(moved, (540, 540))

    def taken(t: RigidTransform) -> np.ndarray:
        return recovery.taken_cells(t, owner, counts, moved, index, SETTINGS.threshold, around)

    by_truth = taken(right_t)
    assert np.count_nonzero(by_truth & right) > 0.9 * np.count_nonzero(right)
    assert np.count_nonzero(by_truth & ~right) < 0.01 * np.count_nonzero(~right)
    assert not taken(left_t).any()
    wrong = RigidTransform(np.radians(37.0), 40.0, -25.0)
    assert np.count_nonzero(taken(wrong)) < 0.1 * np.count_nonzero(by_truth)


@pytest.fixture(scope="module")
def shifted_right(corner, corner_index):
    """The corner with its right part shifted by 12 cells along x (a pure-shift bump), and
    a partition of the left part's transform holding the cells that agree under it:
    ``(context, found, (left_t, right_t))``."""
    index = corner_index
    right = np.zeros(corner.shape, bool)
    right[:, 360:] = True
    broken, truths = break_map(
        corner, [~right, right], [RigidTransform(), RigidTransform(0.0, 12.0, 0.0)], pad=20
    )
    points = cell_points(broken.occupied)
    agree = index.occupied_agreement(truths[0].apply(points), SETTINGS.threshold)
    found = [Found(truths[0], np.flatnonzero(agree), 1.0, 0.0)]
    around = recovery.occupied_around(points, broken.shape)
    context = MapContext(
        points, broken, index, SETTINGS, around, ClearFree(broken, SETTINGS.threshold)
    )
    return context, found, truths


def test_only_a_true_part_taken_over_the_map_clears_the_free_space(shifted_right):
    """The free-space check of a partition counted by the cells it takes: with the right
    part of building 31 shifted by 12 cells (walls and free space), the partition of its true
    transform, holding the cells it takes, makes the map's free space cross reference walls
    far less often than the left part's partition alone; a partition at a wrong place (turned
    by 90 degrees about the part) that holds the same cells does not."""
    context, found, (left_t, right_t) = shifted_right
    points, index, free = context.points, context.index, context.clear
    owner = recovery.owners(found, points.shape[0])
    counts = recovery._owner_counts(found, owner, points, index, SETTINGS.threshold)
    taken = recovery.taken_cells(
        right_t, owner, counts, points, index, SETTINGS.threshold, context.around
    )
    part = Found(right_t, np.flatnonzero(taken), 1.0, 0.0)
    grown = reassign([*found, part], points, index, SETTINGS.threshold, SETTINGS.min_cells)
    assert len(grown) == 2
    before = recovery.contradiction(found, points, free, index)
    clears, z = recovery._clears_free_space, SETTINGS.significance
    assert clears(before, recovery.contradiction(grown, points, free, index), z)
    centre = points[taken].mean(axis=0)
    turned = RigidTransform(np.pi / 2).compose(RigidTransform(0.0, *(-centre))).compose(right_t)
    wrong = [*found, Found(RigidTransform(0.0, *centre).compose(turned), part.members, 1.0, 0.0)]
    assert not clears(before, recovery.contradiction(wrong, points, free, index), z)


def test_suspect_regions_group_near_suspects_and_take_every_cell_around():
    reach = recovery.REGION_REACH
    rng = np.random.default_rng(3)

    def square(x0: int, y0: int, side: int, n: int = 400) -> np.ndarray:
        return np.column_stack([rng.integers(x0, x0 + side, n), rng.integers(y0, y0 + side, n)])

    big = np.vstack([square(0, 0, 40, 200), square(40 + reach, 0, 40, 200)])  # one group
    small = square(20 * reach, 0, 40, 300)  # its own group
    tiny = square(0, 20 * reach, 10, 20)  # too few suspects for a region
    beside = square(0, 40, reach // 2)  # not suspects, within reach of ``big``
    far = square(0, 40 + 3 * reach, 40)  # not suspects, far from every suspect
    points = np.vstack([big, small, tiny, beside, far]).astype(np.float64) + 7.0
    suspect = np.zeros(points.shape[0], bool)
    suspect[: 400 + 300 + 20] = True
    regions = recovery.suspect_regions(points, suspect, min_cells=100)
    assert len(regions) == 2  # the tiny group holds fewer than min_cells suspects
    first, second = regions
    assert first[:400].all() and not first[400:720].any()  # the larger group first
    assert first[720:1120].all()  # with the cells within reach of it
    assert not first[1120:].any() and not second[1120:].any()  # but not farther
    assert second[400:700].all() and not second[:400].any()
    assert recovery.suspect_regions(points, suspect, min_cells=800) == []


def test_regions_around_few_suspects_hold_every_cell_around_them():
    """The last search places the region around each group of dense suspects, however few
    (a small part's cells mostly taken by other partitions): a region must hold at least
    ``min_cells`` cells, suspects or not, and groups far apart are regions of their own."""
    reach = recovery.REGION_REACH
    rng = np.random.default_rng(5)

    def square(x0: int, y0: int, side: int, n: int) -> np.ndarray:
        return np.column_stack([rng.integers(x0, x0 + side, n), rng.integers(y0, y0 + side, n)])

    few = square(0, 0, 20, 30)  # 30 suspects ...
    around = square(0, 20, reach // 2, 300)  # ... with 300 cells within reach of them
    lone = square(20 * reach, 0, 20, 40)  # 40 suspects with nothing around them
    points = np.vstack([few, around, lone]).astype(np.float64) + 7.0
    cells = np.zeros(points.shape[0], bool)
    cells[:30] = True
    cells[330:] = True
    regions = recovery._regions_around(points, cells, min_cells=100)
    assert len(regions) == 1  # the lone group's region holds 40 cells only
    assert regions[0][:330].all() and not regions[0][330:].any()
    assert len(recovery._regions_around(points, cells, min_cells=30)) == 2
    assert recovery._regions_around(points, np.zeros_like(cells), min_cells=1) == []


def test_groups_leave_out_what_was_registered_already():
    """A group that holds nearly every suspect was registered as the suspects, and a region
    that holds nearly the whole map was registered by the recursion: neither again."""
    rng = np.random.default_rng(4)
    reach = recovery.REGION_REACH
    near = rng.integers(0, 40, (300, 2))  # suspects, one group, and cells within reach:
    around = np.column_stack([rng.integers(0, 40, 300), rng.integers(40, 40 + reach // 2, 300)])
    far = rng.integers(0, 40, (1000, 2)) + [0, 40 + 3 * reach]  # far from them
    points = np.vstack([near, around, far]).astype(np.float64)
    suspect = np.zeros(points.shape[0], bool)
    suspect[:300] = True
    groups = recovery._groups(points, suspect, min_cells=100)
    assert len(groups) == 1  # the region only: the group is every suspect
    assert groups[0][:600].all() and not groups[0][600:].any()
    # without the far cells the region is the whole map: nothing is left to register
    assert recovery._groups(points[:600], suspect[:600], min_cells=100) == []
    # a second group of suspects, far away: each group is a part of the suspects now
    suspect[600:900] = True
    groups = recovery._groups(points, suspect, min_cells=100)
    assert len(groups) == 4
    assert [int(g.sum()) for g in groups[::2]] == [300, 300]


def _found(transform: RigidTransform, members: list[int]) -> Found:
    return Found(transform, np.asarray(members, dtype=np.intp), 1.0, 0.0)


def test_a_new_partition_is_kept_when_it_adds_or_replaces_with_more_cells():
    """A new partition stays if the reassignment has one partition more, or if it survives
    and the partitions explain more cells than before (it replaced one it left too few
    cells); not if it was dropped, nor if it survives while fewer cells are explained."""
    a, b, twin, new = (RigidTransform(0.0, float(k), 0.0) for k in range(4))
    found = [_found(a, list(range(100))), _found(twin, list(range(100, 150)))]
    new_one = _found(new, list(range(150, 230)))
    added = [*found, new_one]
    assert recovery._kept(found, added, new_one)
    replaced = [found[0], _found(new, list(range(100, 230)))]  # the twin dropped
    assert recovery._kept(found, replaced, new_one)
    dropped = [found[0], found[1]]  # the new one kept too few cells
    assert not recovery._kept(found, dropped, new_one)
    poorer = [found[0], _found(new, list(range(100, 140)))]  # survives, fewer cells explained
    assert not recovery._kept(found, poorer, new_one)
    other = [_found(a, list(range(100))), _found(b, list(range(100, 250)))]  # not the new one
    assert not recovery._kept(found, other, new_one)


def test_a_recovery_round_is_not_repeated_when_the_tests_change_nothing(monkeypatch) -> None:
    """The recovery's search depends only on the partitions it starts from: once the tests
    after it (join, drop, settle) leave them as they were, a second round would search the
    same suspects again, and it is not run; the bundled broken example still has degree 2."""
    import brokenness.measure.recursion as recursion

    rounds: list[int] = []
    search = recursion.recover

    def counted(*args, **kwargs):  # noqa: ANN002, ANN003, ANN202
        rounds.append(len(args[0]))
        return search(*args, **kwargs)

    monkeypatch.setattr(recursion, "recover", counted)
    root = Path(__file__).parent.parent / "examples"
    reference = load_map(root / "building_31.yaml")
    result = compute_brokenness(load_map(root / "broken_building_31.yaml"), reference)
    assert result.degree == 2 and len(rounds) == 1
    rounds.clear()
    assert compute_brokenness(reference, reference).degree == 0 and len(rounds) == 1


def _junk(k: int) -> tuple[Candidate, ...]:
    """``k`` placements far off the reference's walls, as a registration's group."""
    rng = np.random.default_rng(k)
    return tuple(
        Candidate(RigidTransform(float(a), float(x), float(y)), 0.5)
        for a, x, y in zip(
            rng.uniform(0.3, 2.8, k),
            rng.uniform(-300, 300, k),
            rng.uniform(-300, 300, k),
            strict=True,
        )
    )


def test_a_part_whose_transform_is_among_the_hypotheses_is_added(shifted_right) -> None:
    """The pass over the call's hypotheses (``pooled_partitions``): the shifted part's true
    transform, one hypothesis of a registration among others, becomes a partition holding
    the part's cells; the left partition keeps its own."""
    context, found, (left_t, right_t) = shifted_right
    pool = [_junk(8), (*_junk(5), Candidate(right_t, 0.9)), (Candidate(left_t, 1.0),)]
    grown = recovery.pooled_partitions(found, context, pool)
    assert len(grown) == 2
    new = next(g for g in grown if g.transform is right_t)
    xs = context.points[new.members, 0]
    assert np.mean(xs >= 360 + 20 + 12) > 0.9  # the right part's cells (padded, shifted)
    kept = next(g for g in grown if g.transform is left_t)
    assert np.mean(context.points[kept.members, 0] < 360 + 20) > 0.9


def test_no_partition_is_added_from_hypotheses_that_hold_none(shifted_right) -> None:
    """Placements off the walls, and the left partition's own transform found again, add
    nothing; nor does a placement of the right part turned by 90 degrees (it takes cells by
    coincidence only)."""
    context, found, (left_t, right_t) = shifted_right
    turned = move_about(tuple(context.points.mean(axis=0)), 90.0, (0.0, 0.0)).compose(right_t)
    pool = [_junk(8), (*_junk(5), Candidate(turned, 0.9)), (Candidate(left_t, 1.0),)]
    assert recovery.pooled_partitions(found, context, pool) == found
    assert recovery.pooled_partitions(found, context, []) == found
