"""The random-walk (BCMM) registration baseline: Delta, the walk, determinism, robustness."""

from __future__ import annotations

import math
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


def test_candidates_are_ranked_by_delta_and_distinct(building, moved):
    moving, _, cands = moved
    values = [delta(building, moving, c.transform).value for c in cands]
    # The walk ranks on at most 20000 sampled free cells, delta() uses all of them.
    assert values[0] == min(values)
    assert all(a <= b + 0.1 for a, b in zip(values, values[1:], strict=False))
    for i, a in enumerate(cands):
        for b in cands[:i]:
            corners = np.array([[0, 0], [moving.shape[1], moving.shape[0]]], float)
            assert a.transform.displacement(b.transform, corners).max() >= 3.0


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
