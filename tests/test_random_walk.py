"""The random-walk (BCMM) registration baseline: Delta, the walk, determinism, robustness."""

from __future__ import annotations

import math
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from brokenness import RigidTransform
from brokenness.errors import MapError, ParameterError
from brokenness.io import load_map
from brokenness.registration.base import Candidate
from brokenness.registration.methods import make_registrar
from brokenness.registration.random_walk import (
    DEFAULT_SEED,
    RandomWalkRegistrar,
    delta,
)

DATA = Path(__file__).parent / "data"


# --------------------------------------------------------------------------------------------
# Maps
# --------------------------------------------------------------------------------------------
def _downsample(states: np.ndarray, f: int) -> np.ndarray:
    """Blocks of f x f cells: occupied if any cell is, else free if any is, else unknown."""
    h, w = states.shape[0] // f * f, states.shape[1] // f * f
    b = states[:h, :w].reshape(h // f, f, w // f, f)
    out = np.full((h // f, w // f), -1, np.int8)
    out[(b == 0).any(axis=(1, 3))] = 0
    out[(b == 1).any(axis=(1, 3))] = 1
    return out


@pytest.fixture(scope="module")
def building() -> np.ndarray:
    """MIT building 31 (real SLAM map, tests/data), downsampled 5x to 129 x 138 cells."""
    return _downsample(load_map(DATA / "building_31.yaml").states, 5)


def _rooms(n: int = 120) -> np.ndarray:
    """A small synthetic floor plan drawn with OpenCV."""
    s = np.full((n, n), -1, np.int8)
    m = n // 10
    s[m : n - m, m : n - m] = 0
    occ = np.zeros((n, n), np.uint8)
    cv2.rectangle(occ, (m, m), (n - m - 1, n - m - 1), 1, 1)
    cv2.line(occ, (n // 2, m), (n // 2, int(n * 0.6)), 1, 1)
    cv2.line(occ, (m, int(n * 0.4)), (int(n * 0.35), int(n * 0.4)), 1, 1)
    cv2.rectangle(occ, (int(n * 0.65), int(n * 0.2)), (int(n * 0.75), int(n * 0.3)), 1, -1)
    cv2.circle(occ, (int(n * 0.3), int(n * 0.75)), n // 20, 1, -1)
    s[occ > 0] = 1
    return s


def _warp(reference: np.ndarray, true: RigidTransform, shape: tuple[int, int]) -> np.ndarray:
    """The map whose cell x shows reference cell true(x) (unknown off the reference)."""
    out = cv2.warpAffine(
        (reference + 1).astype(np.uint8),
        true.matrix[:2],
        (shape[1], shape[0]),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderValue=0,
    )
    return out.astype(np.int8) - 1


def _moved_copy(reference: np.ndarray, degrees: float, shift: tuple[float, float]):
    """A rotated and shifted copy of the whole reference on a canvas that holds all of it."""
    rows, cols = reference.shape
    side = int(math.ceil(math.hypot(rows, cols))) + 4
    theta = math.radians(degrees)
    centre_m = np.array([side / 2 + shift[0], side / 2 + shift[1]])
    centre_r = np.array([cols / 2, rows / 2])
    t = centre_r - RigidTransform(theta).apply(centre_m[None])[0]
    true = RigidTransform(theta, t[0], t[1])
    return _warp(reference, true, (side, side)), true


def _errors(found: RigidTransform, true: RigidTransform, moving: np.ndarray) -> tuple[float, float]:
    """(rotation error in degrees, mean displacement of the known moving cells in cells)."""
    rows, cols = np.nonzero(moving >= 0)
    pts = np.column_stack([cols, rows])
    rot = abs(math.degrees(math.remainder(found.rotation - true.rotation, 2 * math.pi)))
    return rot, float(found.displacement(true, pts).mean())


def _translation_error(found: RigidTransform, true: RigidTransform, moving: np.ndarray) -> float:
    """Displacement of the moving map's known-cell centroid (a translation error)."""
    rows, cols = np.nonzero(moving >= 0)
    centre = np.array([[cols.mean(), rows.mean()]])
    return float(found.displacement(true, centre)[0])


# --------------------------------------------------------------------------------------------
# Delta
# --------------------------------------------------------------------------------------------
def _delta_by_hand(ref: np.ndarray, mov: np.ndarray, t: RigidTransform, c_lock: float) -> float:
    """Delta with explicit per-cell loops: the definition, slowly (for tiny maps only)."""
    from brokenness.masking import manhattan_distance_map

    def land(pts: np.ndarray, tr: RigidTransform, shape: tuple[int, int]):
        p = np.rint(tr.apply(pts)).astype(int)
        out = []
        for x, y in p:
            inside = 0 <= x < shape[1] and 0 <= y < shape[0]
            out.append((int(y), int(x)) if inside else None)
        return out

    psi = 0.0
    agree = disagree = 0
    for kind in (1, 0):
        for src, dst, tr in ((mov, ref, t), (ref, mov, t.inverse())):
            dist = manhattan_distance_map(dst == kind)
            rows, cols = np.nonzero(src == kind)
            total, n = 0.0, 0
            for cell in land(np.column_stack([cols, rows]), tr, dst.shape):
                if cell is None or dst[cell] < 0:
                    continue
                total += float(dist[cell])
                n += 1
                if src is mov:
                    agree += int(dst[cell] == kind)
                    disagree += int(dst[cell] != kind)
            if rows.size:
                psi += total / n if n else float(sum(dst.shape))
    return psi + c_lock * (disagree - agree)


def test_delta_matches_the_definition_computed_cell_by_cell():
    rng = np.random.default_rng(3)
    ref = rng.choice(np.array([-1, 0, 1], np.int8), size=(24, 30), p=[0.2, 0.6, 0.2])
    mov = rng.choice(np.array([-1, 0, 1], np.int8), size=(20, 26), p=[0.3, 0.5, 0.2])
    for t in (RigidTransform(0.3, 2.0, -1.5), RigidTransform(-2.0, 25.0, 20.0)):
        got = delta(ref, mov, t, c_lock=0.01)
        assert got.value == pytest.approx(_delta_by_hand(ref, mov, t, 0.01), rel=1e-9, abs=1e-9)
        assert got.acceptance == pytest.approx(got.agree / (got.agree + got.disagree))


def test_delta_is_zero_picture_distance_and_full_acceptance_for_a_map_on_itself(building):
    d = delta(building, building, RigidTransform.identity())
    known = int(np.count_nonzero(building >= 0))
    assert d.psi == 0.0
    assert d.agree == known and d.disagree == 0 and d.acceptance == 1.0
    assert d.value == pytest.approx(-10.0)  # -lock_weight for a perfect full overlap


def test_delta_is_lowest_at_the_true_transform(building):
    moving, true = _moved_copy(building, 23.0, (4.0, -3.0))
    best = delta(building, moving, true).value
    for dth, dx, dy in [(2, 0, 0), (-2, 0, 0), (0, 2, 0), (0, 0, -2), (5, 3, 3), (0, 8, 0)]:
        worse = RigidTransform(true.rotation + math.radians(dth), true.tx + dx, true.ty + dy)
        assert delta(building, moving, worse).value > best


def test_delta_rejects_bad_maps():
    ref = np.zeros((10, 10), np.int8)
    with pytest.raises(MapError):
        delta(ref, np.full((5, 5), 2, np.int8), RigidTransform())
    with pytest.raises(MapError):
        delta(ref, np.full((5, 5), -1, np.int8), RigidTransform())
    with pytest.raises(MapError):
        delta(ref, np.zeros((5, 5), float), RigidTransform())


# --------------------------------------------------------------------------------------------
# Registration
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def moved(building):
    moving, true = _moved_copy(building, 37.0, (6.0, -4.0))
    reg = RandomWalkRegistrar(seed=11)
    cands = reg.candidates(reg.prepare_reference(building), moving, 5)
    return moving, true, cands


def test_recovers_a_known_rigid_transform(moved):
    moving, true, cands = moved
    assert 1 <= len(cands) <= 5
    assert all(isinstance(c, Candidate) and 0.0 <= c.confidence <= 1.0 for c in cands)
    rot, mean_disp = _errors(cands[0].transform, true, moving)
    assert rot < 2.0
    assert mean_disp < 2.0
    assert _translation_error(cands[0].transform, true, moving) < 2.0
    assert cands[0].confidence > 0.95


def test_candidates_are_distinct_and_the_first_explains_the_most(building, moved):
    from brokenness.masking import lookup_distance, manhattan_distance_map

    moving, _, cands = moved
    walls = manhattan_distance_map(building == 1)
    rows, cols = np.nonzero(moving == 1)
    occupied = np.column_stack([cols, rows]).astype(float)
    explained = [
        int(np.count_nonzero(lookup_distance(walls, c.transform.apply(occupied)) <= 2.0))
        for c in cands
    ]
    assert explained[0] == max(explained)
    box = np.array(
        [
            [cols.min(), rows.min()],
            [cols.max(), rows.min()],
            [cols.min(), rows.max()],
            [cols.max(), rows.max()],
        ],
        float,
    )
    for i, a in enumerate(cands):
        for b in cands[:i]:
            assert a.transform.displacement(b.transform, box).max() >= 8.0


def test_same_seed_gives_the_same_answer_bit_for_bit(building):
    moving, _ = _moved_copy(building, -70.0, (3.0, 2.0))
    options = {"rotations": 4, "walkers_per_angle": 1, "patience": 40}  # a short walk
    runs = []
    for _ in range(2):
        reg = make_registrar("random-walk", seed=7, **options)
        cands = reg.candidates(reg.prepare_reference(building), moving, 4)
        runs.append([(c.transform.matrix.tobytes(), c.confidence) for c in cands])
    assert runs[0] == runs[1]
    other = make_registrar("random-walk", seed=8, **options)
    cands = other.candidates(other.prepare_reference(building), moving, 4)
    assert [(c.transform.matrix.tobytes(), c.confidence) for c in cands] != runs[0]


def test_a_different_seed_still_finds_the_transform(building, moved):
    moving, true, first = moved
    reg = RandomWalkRegistrar(seed=12345)
    cands = reg.candidates(reg.prepare_reference(building), moving, 3)
    assert cands[0].transform != first[0].transform  # really another walk
    rot, mean_disp = _errors(cands[0].transform, true, moving)
    assert rot < 2.0 and mean_disp < 2.0


def test_registering_a_map_with_itself_gives_the_identity():
    ref = _rooms(120)
    reg = RandomWalkRegistrar()  # seed None -> DEFAULT_SEED
    assert reg.seed == DEFAULT_SEED
    best = reg.candidates(reg.prepare_reference(ref), ref, 1)[0]
    rot, mean_disp = _errors(best.transform, RigidTransform.identity(), ref)
    assert rot < 1.0 and mean_disp < 1.0
    assert best.confidence > 0.99


def test_a_moved_part_of_the_map_among_unknown_cells_is_found(building):
    """The recursion's case: only one region of the map is left, the rest set unknown."""
    rows, cols = building.shape
    part = np.full_like(building, -1)
    part[:, int(cols * 0.55) :] = building[:, int(cols * 0.55) :]
    # The region was knocked 12 degrees about its edge and shifted (a bump).
    bump = RigidTransform(math.radians(12.0))
    pivot = np.array([[cols * 0.55, rows / 2]])
    shift = pivot[0] - bump.apply(pivot)[0] + np.array([5.0, -7.0])
    motion = RigidTransform(bump.rotation, shift[0], shift[1])  # reference -> broken map
    true = motion.inverse()
    moving = _warp(part, true, (rows + 30, cols + 30))
    reg = RandomWalkRegistrar(seed=5)
    best = reg.candidates(reg.prepare_reference(building), moving, 3)[0]
    rot, mean_disp = _errors(best.transform, true, moving)
    assert rot < 2.0 and mean_disp < 2.0


# --------------------------------------------------------------------------------------------
# Options and bad input
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "options",
    [
        {"rotations": 0},
        {"patience": -1},
        {"max_iterations": 1.5},
        {"worse_acceptance": 1.0},
        {"worse_acceptance": -0.1},
        {"window": 1},
        {"rotation_step_deg": 0},
        {"translation_step": float("nan")},
        {"lock_weight": "a lot"},
        {"max_points": 3},
        {"seed": -1},
        {"seed": 1.5},
        {"start_grid": -1},
    ],
)
def test_invalid_options_raise_parameter_error(options):
    with pytest.raises(ParameterError):
        make_registrar("random-walk", **options)


def test_unknown_option_raises_parameter_error_not_a_silent_default():
    with pytest.raises(ParameterError, match="walkers"):
        make_registrar("random-walk", seed=1, walkers=3)


def test_bad_maps_and_arguments_raise_typed_errors():
    reg = RandomWalkRegistrar(rotations=2, max_iterations=5)
    with pytest.raises(MapError):
        reg.prepare_reference(np.zeros((10, 10), np.int8))  # no occupied cell
    with pytest.raises(MapError):
        reg.prepare_reference(np.ones((10,), np.int8))
    prepared = reg.prepare_reference(_rooms(60))
    with pytest.raises(MapError):
        reg.candidates(prepared, np.full((20, 20), -1, np.int8), 1)
    with pytest.raises(ParameterError):
        reg.candidates(prepared, _rooms(60), 0)
    with pytest.raises(ParameterError):
        reg.candidates(object(), _rooms(60), 1)


def test_the_walk_stops_within_max_iterations_and_returns_a_candidate():
    reg = RandomWalkRegistrar(rotations=2, max_iterations=3, start_grid=0)
    cands = reg.candidates(reg.prepare_reference(_rooms(60)), _rooms(60), 4)
    assert 1 <= len(cands) <= 4


# --------------------------------------------------------------------------------------------
# Distance maps: the two-pass transform against brute force
# --------------------------------------------------------------------------------------------
def _brute_manhattan(mask: np.ndarray) -> np.ndarray:
    """Manhattan distance to the nearest True cell, by comparing every pair of cells."""
    rows, cols = np.indices(mask.shape)
    tr, tc = np.nonzero(mask)
    d = np.abs(rows[..., None] - tr) + np.abs(cols[..., None] - tc)
    return d.min(axis=-1).astype(np.float64)


@pytest.mark.parametrize(
    "cells",
    [
        [(0, 0)],  # only the forward pass carries this one down and right
        [(16, 22)],  # the bottom-right corner: only the backward pass reaches the rest
        [(16, 0), (0, 22)],
        [(8, 11)],
    ],
)
def test_distance_map_equals_brute_force_for_single_seeds(cells):
    from brokenness.masking import manhattan_distance_map

    mask = np.zeros((17, 23), bool)
    for r, c in cells:
        mask[r, c] = True
    got = manhattan_distance_map(mask)
    assert got.dtype == np.float32
    assert np.array_equal(got.astype(np.float64), _brute_manhattan(mask))


def test_distance_map_equals_brute_force_on_random_maps():
    from brokenness.masking import manhattan_distance_map

    rng = np.random.default_rng(3)
    for shape, density in (((31, 19), 0.02), ((12, 40), 0.1), ((25, 25), 0.005)):
        mask = rng.random(shape) < density
        mask[rng.integers(shape[0]), rng.integers(shape[1])] = True
        assert np.array_equal(manhattan_distance_map(mask), _brute_manhattan(mask))


def test_lookup_tables_hold_exact_integer_distances_and_mark_unknown_cells():
    from brokenness.registration._rw_scoring import UNKNOWN_VALUE, build_tables

    rng = np.random.default_rng(5)
    states = rng.choice(np.array([-1, 0, 1], np.int8), size=(21, 27), p=[0.3, 0.6, 0.1])
    tables = build_tables(states, states.size)
    for k, kind in enumerate((1, 0)):
        expected = _brute_manhattan(states == kind)
        table = tables.tables[k]
        assert table.dtype == np.uint16
        known = states >= 0
        assert np.array_equal(table[known], expected[known].astype(np.uint16))
        assert np.all(table[~known] == UNKNOWN_VALUE)
    assert tables.counts == (int(np.sum(states == 1)), int(np.sum(states == 0)))


# --------------------------------------------------------------------------------------------
# Options, budgets, progress, repeatability
# --------------------------------------------------------------------------------------------
_QUICK = {"rotations": 4, "start_grid": 2, "max_iterations": 60, "patience": 20}


def test_walk_options_are_a_frozen_dataclass_and_keywords_override_them():
    import dataclasses

    from brokenness.registration.random_walk import WalkOptions

    opt = WalkOptions(rotations=8)
    with pytest.raises(dataclasses.FrozenInstanceError):
        opt.rotations = 3  # type: ignore[misc]
    reg = RandomWalkRegistrar(options=opt, patience=7)
    assert reg.options.rotations == 8 and reg.options.patience == 7
    with pytest.raises(ParameterError):
        WalkOptions(time_budget=0.0)
    with pytest.raises(ParameterError):
        RandomWalkRegistrar(options={"rotations": 3})  # type: ignore[arg-type]


def test_the_wider_walk_has_twice_the_start_poses_and_the_same_seed(building):
    reg = RandomWalkRegistrar(seed=11, walkers_per_angle=1, spectral_starts=3, **_QUICK)
    wide = reg.wider()
    assert wide.seed == 11
    assert wide.options.walkers_per_angle == 2 and wide.options.spectral_starts == 6
    assert wide.options.rotations == reg.options.rotations
    assert wide.options.max_iterations == reg.options.max_iterations
    assert RandomWalkRegistrar(spectral_starts=0).wider().options.spectral_starts == 0
    # it takes the same prepared reference, and repeats itself bit for bit
    moving, _ = _moved_copy(building, 25.0, (2.0, 1.0))
    prepared = reg.prepare_reference(building)
    a = wide.candidates(prepared, moving, 6)
    b = reg.wider().candidates(prepared, moving, 6)
    assert [c.transform for c in a] == [c.transform for c in b]


def test_a_search_shares_one_budget_in_units_of_the_plain_walk(building):
    from brokenness.registration.random_walk import WalkOptions, WalkProgress

    reports: list[WalkProgress] = []
    reg = RandomWalkRegistrar(seed=5, search_budget=4.0, progress=reports.append, **_QUICK)
    opt = reg.options
    unit = opt.nominal_evaluations
    walkers = opt.rotations * opt.walkers_per_angle + opt.spectral_starts
    starts = opt.rotations * (2 + opt.start_grid**2)
    assert unit == starts + (opt.max_iterations + 1) * walkers
    assert reg.budget_left is None and not reg.exhausted  # no search opened yet
    moving, _ = _moved_copy(building, 25.0, (2.0, 1.0))
    prepared = reg.prepare_reference(building)
    reg.candidates(prepared, moving, 4)  # before wider(): not counted
    wide = reg.wider()
    assert wide.options.search_budget == 4.0
    assert wide.budget_left == reg.budget_left == 4 * unit and not wide.exhausted
    reports.clear()
    reg.candidates(prepared, moving, 4)  # the plain walk is counted...
    plain = reports[-1]
    assert plain.done and plain.budget_left is None  # ...but not held to the budget
    assert wide.budget_left == 4 * unit - plain.evaluations
    calls = 0
    while not wide.exhausted:
        wide.candidates(prepared, moving, 4)  # still answers, also when the budget cuts it
        calls += 1
        assert calls < 10
    assert not reg.exhausted  # the plain registrar always walks
    done = [r for r in reports if r.done]
    spent = sum(r.evaluations for r in done)
    # the walk that spends it stops at its first step past the budget: it overshoots by at
    # most its start poses and one step of its walkers (twice the plain walk's)
    assert 4 * unit <= spent <= 4 * unit + starts + 2 * walkers
    assert done[-1].budget_left == wide.budget_left == reg.budget_left <= 0
    assert done[-1].step < opt.max_iterations
    assert RandomWalkRegistrar(search_budget=None).wider().budget_left is None
    with pytest.raises(ParameterError):
        WalkOptions(search_budget=-1.0)
    # the cut is counted in evaluations, not timed: the same calls give the same answers

    def run():
        again = RandomWalkRegistrar(seed=5, search_budget=4.0, **_QUICK)
        wider = again.wider()
        again.candidates(prepared, moving, 4)
        out = [[c.transform for c in wider.candidates(prepared, moving, 4)] for _ in range(calls)]
        return out, wider.budget_left

    assert run() == run()
    assert run()[1] == wide.budget_left


def test_same_seed_same_answer_alone_and_after_other_calls(building):
    moving, _ = _moved_copy(building, 25.0, (2.0, 1.0))
    other, _ = _moved_copy(building, -100.0, (0.0, 3.0))

    def key(cands):
        return [(c.transform.matrix.tobytes(), c.acceptance) for c in cands]

    alone = RandomWalkRegistrar(seed=3, **_QUICK)
    first = key(alone.candidates(alone.prepare_reference(building), moving, 4))
    batch = RandomWalkRegistrar(seed=3, **_QUICK)
    prepared = batch.prepare_reference(building)
    batch.candidates(prepared, other, 4)  # another pair first, as in a batch
    assert key(batch.candidates(prepared, moving, 4)) == first


def test_the_iteration_budget_bounds_the_walk_and_restarts_happen():
    from brokenness.registration._rw_scoring import build_tables
    from brokenness.registration.random_walk import _walk

    ref = _rooms(60)
    reg = RandomWalkRegistrar(
        rotations=2, start_grid=0, spectral_starts=0, max_iterations=50, patience=5
    )
    prepared = reg.prepare_reference(ref)
    walk = _walk(reg, prepared, build_tables(ref, 6000), [], time.perf_counter())
    assert walk.steps <= 50
    assert walk.restarts > 0  # patience 5: walkers stall and start again from their best
    assert not walk.stopped_by_time


def test_a_time_budget_cuts_the_walk_short_and_still_returns_candidates(building):
    moving, _ = _moved_copy(building, 37.0, (6.0, -4.0))
    reports = []
    reg = RandomWalkRegistrar(
        seed=1, max_iterations=100_000, patience=100_000, time_budget=0.3, progress=reports.append
    )
    t0 = time.perf_counter()
    cands = reg.candidates(reg.prepare_reference(building), moving, 3)
    assert time.perf_counter() - t0 < 10.0
    assert cands and reports[-1].done and reports[-1].step < 100_000


def test_progress_is_reported_while_walking(building):
    from brokenness.registration.random_walk import WalkProgress

    moving, _ = _moved_copy(building, 10.0, (1.0, 1.0))
    reports: list[WalkProgress] = []
    reg = RandomWalkRegistrar(seed=2, progress=reports.append, progress_every=5, **_QUICK)
    prepared = reg.prepare_reference(building)
    reg.candidates(prepared, moving, 2)
    reg.candidates(prepared, moving, 2)
    assert all(isinstance(r, WalkProgress) for r in reports)
    assert [r.call for r in reports if r.done] == [1, 2]
    steps = [r.step for r in reports if r.call == 1]
    assert steps == sorted(steps) and steps[-1] <= _QUICK["max_iterations"]
    assert len(steps) >= 3
    assert all(0.0 <= r.best_acceptance <= 1.0 for r in reports)


def test_candidates_carry_the_acceptance_indicator(building, moved):
    moving, _, cands = moved
    for c in cands:
        d = delta(building, moving, c.transform)
        assert c.acceptance == pytest.approx(d.acceptance, abs=1e-12)
        assert c.confidence == c.acceptance


# --------------------------------------------------------------------------------------------
# Several good alignments: the walk returns the distinct optima
# --------------------------------------------------------------------------------------------
def _motion(degrees: float, pivot: tuple[float, float], shift: tuple[float, float]):
    """The reference -> map motion that turns about ``pivot`` and then shifts."""
    turn = RigidTransform(math.radians(degrees))
    p = np.array([pivot])
    t = p[0] - turn.apply(p)[0] + np.array(shift)
    return RigidTransform(turn.rotation, t[0], t[1])


def test_both_parts_of_a_broken_map_are_among_the_candidates(building):
    """A map in two parts (57 % and 43 % of the walls), each moved its own way: the walk
    returns both alignments among its candidates, not only the nearest optimum."""
    rows, cols = building.shape
    cut = int(cols * 0.45)
    big = np.full_like(building, -1)
    big[:, :cut] = building[:, :cut]
    small = np.full_like(building, -1)
    small[:, cut:] = building[:, cut:]
    # map -> reference transforms; the two parts land side by side, apart, in the map
    a = _motion(20.0, (cut / 2, rows / 2), (30.0, 30.0)).inverse()
    b = _motion(-35.0, ((cut + cols) / 2, rows / 2), (90.0, 30.0)).inverse()
    shape = (rows + 60, cols + 160)
    part_a, part_b = _warp(big, a, shape), _warp(small, b, shape)
    assert not np.any((part_a >= 0) & (part_b >= 0))  # the parts do not overlap
    moving = np.maximum(part_a, part_b)
    assert np.count_nonzero(part_b == 1) > 0.3 * np.count_nonzero(moving == 1)
    for spectral_starts in (6, 0):  # with the spectral start poses, and the pure walk
        reg = RandomWalkRegistrar(seed=4, spectral_starts=spectral_starts)
        cands = reg.candidates(reg.prepare_reference(building), moving, 6)
        err_a = [_errors(c.transform, a, part_a)[1] for c in cands]
        err_b = [_errors(c.transform, b, part_b)[1] for c in cands]
        assert min(err_a) < 2.0 and min(err_b) < 2.0
        assert min(err_a[0], err_b[0]) < 2.0  # the best candidate is one of the two


# --------------------------------------------------------------------------------------------
# The acceptance indicator of a partition
# --------------------------------------------------------------------------------------------
def test_partition_acceptance_is_one_in_place_and_lower_when_moved(building):
    from brokenness.registration.random_walk import partition_acceptance

    labels = np.where(building == 1, 0, -1).astype(np.int16)
    right = labels.copy()
    right[:, : building.shape[1] // 2][right[:, : building.shape[1] // 2] == 0] = 1
    same = partition_acceptance(building, building, right, [RigidTransform()] * 2)
    assert same == [1.0, 1.0]
    off = partition_acceptance(
        building, building, right, [RigidTransform(), RigidTransform(0.0, 3.0, 2.0)]
    )
    assert off[0] == 1.0 and off[1] is not None and off[1] < 0.95
    assert partition_acceptance(building, building, labels, []) == []
