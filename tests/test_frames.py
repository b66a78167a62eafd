"""``frames``: the measure in several grid frames of the map, the best result kept."""

from __future__ import annotations

import json
import math
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import brokenness
from brokenness import BrokennessOptions, OccupancyMap, compute_brokenness, load_map
from brokenness.cli.main import main
from brokenness.errors import ParameterError
from brokenness.masking import cell_points
from brokenness.measure.evidence import MAP_RATIO, Contradiction, doubtful_bound
from brokenness.measure.frames import (
    FRAMES,
    back_to_own_frame,
    best_of,
    in_doubt,
    in_frame,
    partitions_in_doubt,
    placed_alike,
    to_replicate,
)
from brokenness.transform import RigidTransform

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "broken_building_31.yaml"
REFERENCE = ROOT / "examples" / "building_31.yaml"


@pytest.fixture(scope="module")
def example() -> tuple[OccupancyMap, OccupancyMap]:
    return load_map(EXAMPLE), load_map(REFERENCE)


@pytest.mark.parametrize("frames", [0, 6, 1.5, True, "2"])
def test_frames_out_of_range_are_refused(frames):
    with pytest.raises(ParameterError, match="frames"):
        BrokennessOptions(frames=frames)


@pytest.mark.parametrize("frame", FRAMES)
def test_a_frame_holds_the_same_cells_where_its_transform_puts_them(example, frame):
    m, _ = example
    moved, cells = in_frame(m, frame)
    assert moved.n_occupied == m.n_occupied and moved.resolution == m.resolution
    landed = np.rint(cells.apply(cell_points(m.occupied))).astype(np.intp)
    assert moved.occupied[landed[:, 1], landed[:, 0]].all()


@pytest.mark.parametrize("frame", FRAMES[1:])
def test_a_result_in_another_frame_is_reported_in_the_maps_own_cells(example, frame):
    m, ref = example
    own = compute_brokenness(m, ref)
    moved, cells = in_frame(m, frame)
    back = back_to_own_frame(compute_brokenness(moved, ref), frame, cells, m, ref)
    assert back.labels.shape == m.shape
    np.testing.assert_array_equal(back.labels >= -1, own.labels >= -1)  # the occupied cells
    for p, q in zip(own.partitions, back.partitions, strict=True):
        cells_of_p = cell_points(own.labels == p.index)
        assert np.count_nonzero(back.labels == q.index) == q.cells
        assert float(np.median(p.transform.displacement(q.transform, cells_of_p))) < 0.5
        assert q.transform.world is not None  # metres in the map's own world frame
        assert abs(q.transform.world.rotation_deg - p.transform.world.rotation_deg) < 0.5


def test_the_best_result_leaves_fewest_cells_unexplained_then_crosses_fewest_walls(example):
    m, ref = example
    r = compute_brokenness(m, ref)  # 3 partitions
    results = [
        replace(r, unassigned_cells=5, contradiction=0.1),
        replace(r, unassigned_cells=3, contradiction=0.4),
        replace(r, unassigned_cells=3, contradiction=0.2),
        replace(r, unassigned_cells=3, contradiction=0.2),
        replace(r, unassigned_cells=3, contradiction=None),
    ]
    assert best_of(results) == 2


def test_another_frame_never_changes_the_degree_of_the_maps_own(example):
    m, ref = example
    r = compute_brokenness(m, ref)
    fewer = replace(r, partitions=r.partitions[:-1], degree=1)  # one partition less
    more = replace(r, partitions=(*r.partitions, r.partitions[-1]), degree=3)
    refused = replace(r, measured=False, degree=None)
    own = replace(r, unassigned_cells=400)
    # whatever the others leave unexplained, only a result at the own frame's degree can win
    assert best_of([own, replace(fewer, unassigned_cells=0)]) == 0
    assert best_of([own, replace(more, unassigned_cells=0)]) == 0
    assert best_of([own, replace(refused, unassigned_cells=0)]) == 0
    assert best_of([own, replace(r, unassigned_cells=399)]) == 1


def test_a_map_whose_partitions_all_show_their_place_is_measured_in_its_own_frame(example):
    m, ref = example
    one = compute_brokenness(m, ref)
    assert all(p.contradiction_bound <= MAP_RATIO for p in one.partitions)  # none in doubt
    for p in one.partitions:  # each partition's bound, as the whole map's, over its ratio
        assert p.contradiction < p.contradiction_bound == p.to_dict()["contradiction_bound"]
    three = compute_brokenness(m, ref, frames=3)
    assert three.parameters["frames"] == 3
    assert three.parameters["frame"] == "own" and three.parameters["frame_degrees"] == [2]
    np.testing.assert_array_equal(three.labels, one.labels)
    assert [p.transform for p in three.partitions] == [p.transform for p in one.partitions]


def test_several_frames_keep_the_examples_degree_and_say_which_frame(example, monkeypatch):
    from brokenness.measure import frames

    # every partition in doubt: all frames are tried
    monkeypatch.setattr(frames, "doubtful_bound", lambda bound: True)
    m, ref = example
    one = compute_brokenness(m, ref)
    three = compute_brokenness(m, ref, frames=3)
    assert three.degree == one.degree == 2
    assert three.parameters["frames"] == 3 and three.parameters["frame"] in FRAMES[:3]
    assert three.parameters["frame_degrees"] == [2, 2, 2]
    assert three.unassigned_cells <= one.unassigned_cells
    assert three.labels.shape == m.shape


@pytest.mark.parametrize(
    ("bounds", "doubt"),
    [((0.1, 0.5), False), ((0.1, 0.51), True), ((0.2, None), True), ((), False)],
)
def test_a_partition_is_in_doubt_when_its_free_space_does_not_show_its_place(
    example, bounds, doubt
):
    m, ref = example
    r = compute_brokenness(m, ref)
    parts = tuple(replace(r.partitions[0], contradiction_bound=b) for b in bounds)
    assert in_doubt(replace(r, partitions=parts)) is doubt


def test_a_results_partitions_in_doubt_are_those_the_measure_searched_again(example):
    """One predicate on a bound: the measure's on the counts (``Contradiction.doubtful``) and
    the result's on ``contradiction_bound`` pick the same partitions."""
    m, ref = example
    r = compute_brokenness(m, ref)
    counts = Contradiction(np.array([4000, 50, 0]), np.array([40, 0, 0]), 0.1, 1)
    z = 6.0
    bounds = [counts.upper_ratio(z, i) for i in range(3)]
    parts = tuple(
        replace(r.partitions[0], index=i, contradiction_bound=b if math.isfinite(b) else None)
        for i, b in enumerate(bounds)
    )
    in_doubt_now = [p.index for p in partitions_in_doubt(replace(r, partitions=parts))]
    assert in_doubt_now == counts.doubtful(z) == [1, 2]
    assert doubtful_bound(MAP_RATIO) is False
    assert doubtful_bound(math.nextafter(MAP_RATIO, 1.0)) is True
    assert doubtful_bound(math.inf) is doubtful_bound(None) is doubtful_bound(math.nan) is True


def test_a_pair_not_measured_in_its_own_frame_is_not_measured_in_several():
    walls = np.zeros((300, 300), bool)
    walls[50, 40:260] = walls[250, 40:260] = walls[50:251, 40] = True
    other = np.zeros((300, 300), bool)
    for k in range(0, 300, 7):  # a comb: no room of the walls' shape
        other[k, 10:290] = True
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        result = compute_brokenness(walls, other, frames=2)
    said = [w for w in seen if issubclass(w.category, brokenness.NothingFoundWarning)]
    assert result.measured is False and result.degree is None
    assert len(said) == 1
    # decided in the map's own frame: the other frames are not tried
    assert result.parameters["frame"] == "own" and result.parameters["frame_degrees"] == [None]


def test_cli_says_when_only_the_maps_own_frame_was_tried(capsys):
    assert main(["compute", str(EXAMPLE), str(REFERENCE), "--frames", "3"]) == 0
    out = capsys.readouterr().out
    assert "frames: 3; only the map's own tried (no partition in doubt)" in out
    assert "in doubt:" not in out


def test_cli_names_the_partitions_in_doubt(example, capsys, monkeypatch):
    import brokenness.measure

    m, ref = example
    real = compute_brokenness(m, ref)
    last = replace(real.partitions[-1], contradiction_bound=0.72)
    doubtful = replace(real, partitions=(*real.partitions[:-1], last))
    monkeypatch.setattr(brokenness.measure, "compute_brokenness", lambda *a, **k: doubtful)
    assert main(["compute", str(EXAMPLE), str(REFERENCE)]) == 0
    out = capsys.readouterr().out
    assert "in doubt: partition 2 (at most 72 %): its own free space does not show that it" in out


def test_cli_frames(capsys):
    assert main(["compute", str(EXAMPLE), str(REFERENCE), "--frames", "2", "--json", "-"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["degree"] == 2
    assert record["parameters"]["frames"] == 2 and record["parameters"]["frame"] in FRAMES
    assert main(["compute", str(EXAMPLE), str(REFERENCE), "--frames", "9"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--frames" in err[0]


def test_other_frames_offer_partitionings_of_a_measured_map_never_a_degree(example, monkeypatch):
    from brokenness.measure import recursion

    m, ref = example
    real = compute_brokenness(m, ref)
    doubtful = replace(real.partitions[-1], contradiction_bound=0.7)
    per_frame = iter(
        [
            # own: measured, its last partition in doubt
            replace(real, unassigned_cells=50, partitions=(*real.partitions[:-1], doubtful)),
            # turned 180: measured on the same partitions (so the own frame's verdict is
            # replicated, step 11), with fewer cells left, but at another degree
            replace(_turned(real, m), unassigned_cells=10, degree=3),
            replace(real, unassigned_cells=20),  # turned 90: measured, fewer than own
        ]
    )
    monkeypatch.setattr(recursion, "_compute", lambda *args: next(per_frame))
    result = compute_brokenness(m, ref, frames=3)
    assert result.parameters["frame"] == "turned 90" and result.unassigned_cells == 20
    assert result.parameters["frame_degrees"] == [2, 3, 2]
    assert result.parameters["replication_degree"] == 3
    assert result.measured and result.degree == 2


def test_compare_does_not_split_results_by_the_frame_each_kept(tmp_path):
    from brokenness.report.collect import ResultEntry
    from brokenness.report.tables import run_settings

    def entry(name: str, degree: int, **parameters: object) -> ResultEntry:
        parameters = {"threshold": 2.0, "frames": 3, **parameters}
        return ResultEntry(
            tmp_path / name, degree=degree, measured=True, method="ifmi", parameters=parameters
        )

    entries = [
        entry("a.zip", 2, frame="own", frame_degrees=[2, 2, 2]),
        entry("b.zip", 4, frame="turned 90", frame_degrees=[3, 4, 4]),
    ]
    assert run_settings(entries) == {}  # the same options: one group
    other = entry("c.zip", 4, frames=1)
    assert "parameters" in run_settings([*entries, other])  # other options: apart
    # a map measured again turned (step 11) was run with the same options as the others
    replicated = entry(
        "d.zip",
        3,
        frame="own",
        frame_degrees=[3, 3, 3],
        replication_frame="turned 180",
        replication_degree=3,
        replication_placed_alike=0.93,
    )
    assert run_settings([*entries, replicated]) == {}


def _with_bounds(result, bounds):
    """``result`` with one partition per ``(share of the map's cells, bound)`` in ``bounds``."""
    n = result.occupied_cells
    parts = tuple(
        replace(result.partitions[0], index=i, cells=round(share * n), contradiction_bound=b)
        for i, (share, b) in enumerate(bounds)
    )
    return replace(result, partitions=parts)


@pytest.mark.parametrize(
    ("bounds", "replicate"),
    [
        (((0.6, 0.1), (0.39, 0.5)), False),  # every partition shown in place (0.5: shown)
        (((0.9, 0.1), (0.09, 0.51)), True),  # one partition in doubt, however small
        (((0.45, 0.1), (0.54, 0.9)), True),
        (((0.5, 0.2), (0.49, None)), True),  # no bound counts as in doubt
    ],
)
def test_a_map_with_a_partition_in_doubt_is_to_be_replicated(example, bounds, replicate):
    m, ref = example
    r = _with_bounds(compute_brokenness(m, ref), bounds)
    assert to_replicate(r) is replicate
    assert to_replicate(replace(r, measured=False, degree=None)) is False


@pytest.fixture(scope="module")
def example_result(example) -> brokenness.BrokennessResult:
    return compute_brokenness(*example)


def _turned(
    result: brokenness.BrokennessResult,
    m: OccupancyMap,
    shift: float = 0.0,
    moved: tuple[int, ...] | None = None,
):
    """``result`` of the map ``m`` as the map with its grid turned 180 degrees would report it
    (its labels turned, each transform taking the turned grid's cells), each transform (of
    the partitions ``moved`` only, if given) then moved by ``shift`` reference cells along x."""
    _, cells = in_frame(m, "turned 180")
    back = cells.inverse()
    parts = tuple(
        replace(
            p,
            transform=RigidTransform(
                0.0, shift if moved is None or p.index in moved else 0.0, 0.0
            ).compose(p.transform.compose(back)),
        )
        for p in result.partitions
    )
    labels = np.ascontiguousarray(np.rot90(result.labels, 2))
    return replace(result, partitions=parts, labels=labels)


def _replicated(
    example, real, monkeypatch, again_measured: bool, frames: int = 1, shift=0.0, moved=None
):
    """``compute_brokenness`` whose own frame is the example (its result ``real``) measured
    with partitions in doubt (1 and 2, 41 % of the partitioned cells), and whose map with
    its grid turned 180 degrees is (or is not) measured: on the same partitions, or on
    partitions (those of ``moved``, default all) moved by ``shift`` cells."""
    from brokenness.measure import recursion

    m, ref = example
    own = _with_bounds(real, [(0.3, 0.1), (0.35, 0.7), (0.34, 0.8)])
    again = _turned(own, m, shift, moved)
    if not again_measured:
        again = replace(again, measured=False, degree=None, reason="no")
    calls = []

    def computed(map_, reference, opts):
        calls.append(map_.shape)
        return own if len(calls) == 1 else again

    monkeypatch.setattr(recursion, "_compute", computed)
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        result = compute_brokenness(m, ref, frames=frames)
    said = [w for w in seen if issubclass(w.category, brokenness.NothingFoundWarning)]
    return result, calls, said


def test_a_map_measured_with_partitions_in_doubt_is_measured_again_turned(
    example, example_result, monkeypatch
):
    result, calls, said = _replicated(example, example_result, monkeypatch, True)
    assert len(calls) == 2  # its own frame, then turned 180 (the example is not square)
    assert calls[1] == calls[0][::-1] or calls[1] == calls[0]
    assert result.measured and result.degree == 2 and not said
    assert result.parameters["replication_frame"] == "turned 180"
    assert result.parameters["replication_degree"] == 2
    assert result.parameters["replication_placed_alike"] == 1.0


def test_a_map_measured_again_turned_on_other_partitions_is_not_measured(
    example, example_result, monkeypatch
):
    """Measured in both frames, but the turned frame puts every cell 3 cells from where the
    own frame does (past c = 2): other partitions, not the same ones found again."""
    result, calls, said = _replicated(example, example_result, monkeypatch, True, shift=3.0)
    assert len(calls) == 2
    assert result.measured is False and result.degree is None
    assert result.parameters["replication_degree"] == 2
    assert result.parameters["replication_placed_alike"] == 0.0
    assert "on other partitions: 0% of its partitioned cells placed alike" in result.reason
    assert len(said) == 1
    # 1.9 cells apart: within c, the same placement
    result, _, said = _replicated(example, example_result, monkeypatch, True, shift=1.9)
    assert result.measured and result.parameters["replication_placed_alike"] == 1.0 and not said


def test_a_map_whose_partitions_in_doubt_are_placed_elsewhere_turned_is_not_measured(
    example, example_result, monkeypatch
):
    """The partition shown in place (59 % of the partitioned cells) found again, the two in
    doubt 3 cells away: most of the partitioned cells are placed alike, but none of those
    the replication is asked for (session 46: fresh simulated building 217 against 216,
    50 % and 0 %)."""
    result, calls, said = _replicated(
        example, example_result, monkeypatch, True, shift=3.0, moved=(1, 2)
    )
    assert len(calls) == 2
    assert result.measured is False and result.degree is None
    assert result.parameters["replication_placed_alike"] == pytest.approx(
        np.count_nonzero(example_result.labels == 0) / np.count_nonzero(example_result.labels >= 0)
    )
    assert result.parameters["replication_placed_alike"] > 0.5
    assert result.parameters["replication_placed_alike_in_doubt"] == 0.0
    assert "0% of the cells of its partitions in doubt placed alike, not half" in result.reason
    assert len(said) == 1
    # the partition shown in place moved instead: the partitions in doubt are found again,
    # but not most of the partitioned cells
    result, _, _ = _replicated(example, example_result, monkeypatch, True, shift=3.0, moved=(0,))
    assert result.measured is False
    assert result.parameters["replication_placed_alike_in_doubt"] == 1.0
    assert "of its partitioned cells placed alike, not half" in result.reason
    # both found again
    result, _, said = _replicated(example, example_result, monkeypatch, True, shift=1.0)
    assert result.measured and not said
    assert result.parameters["replication_placed_alike_in_doubt"] == 1.0


def test_a_map_not_measured_again_turned_is_not_measured(example, example_result, monkeypatch):
    result, calls, said = _replicated(example, example_result, monkeypatch, False)
    assert len(calls) == 2
    assert result.measured is False and result.degree is None
    assert "turned 180" in result.reason and "no" in result.reason
    assert "3 partitions, 2 of them in doubt" in result.reason
    assert result.parameters["replication_degree"] is None
    assert len(said) == 1 and "turned 180" in str(said[0].message)
    # with other frames asked for, the same frame decides, computed once
    result, calls, said = _replicated(example, example_result, monkeypatch, False, frames=3)
    assert len(calls) == 3 and result.measured is False and len(said) == 1
    assert result.parameters["frame"] == "own"
    assert result.parameters["frame_degrees"] == [2, None, None]


def test_placed_alike_counts_the_cells_both_results_place_within_the_tolerance(
    example, example_result
):
    m, _ = example
    own = example_result
    assigned = int(np.count_nonzero(own.labels >= 0))
    same = _turned(_turned(own, m), m)  # turned twice: the own frame again
    assert placed_alike(own, own, 0.0) == 1.0
    assert placed_alike(own, same, 1e-6) == 1.0
    moved = replace(
        own,
        partitions=tuple(
            replace(p, transform=RigidTransform(0.0, 0.0, 2.5).compose(p.transform))
            for p in own.partitions
        ),
    )
    assert placed_alike(own, moved, 2.4) == 0.0 and placed_alike(own, moved, 2.6) == 1.0
    # one partition placed elsewhere: its share of the partitioned cells is lost
    first = own.partitions[0]
    one_off = replace(
        own,
        partitions=(
            replace(first, transform=RigidTransform(0.0, 40.0, 0.0).compose(first.transform)),
            *own.partitions[1:],
        ),
    )
    share = 1.0 - np.count_nonzero(own.labels == 0) / assigned
    assert placed_alike(own, one_off, 2.0) == pytest.approx(share)
    # cells the other result leaves unassigned are not placed alike
    unassigned = replace(own, labels=np.where(own.labels == 0, -2, own.labels).astype(np.int16))
    assert placed_alike(own, unassigned, 2.0) == pytest.approx(share)
    nothing = replace(own, labels=np.where(own.labels >= 0, -2, own.labels).astype(np.int16))
    assert placed_alike(nothing, own, 2.0) == 0.0
    # the cells of some partitions only: the one placed elsewhere, the others, none
    assert placed_alike(own, one_off, 2.0, among=[0]) == 0.0
    assert placed_alike(own, one_off, 2.0, among=[1, 2]) == 1.0
    assert placed_alike(own, one_off, 2.0, among=[0, 1, 2]) == pytest.approx(share)
    assert placed_alike(own, own, 2.0, among=[]) == 0.0


def test_a_map_with_its_partitions_shown_in_place_is_computed_once(
    example, example_result, monkeypatch
):
    from brokenness.measure import recursion

    m, ref = example
    real = example_result
    calls = []
    monkeypatch.setattr(recursion, "_compute", lambda *args: calls.append(1) or real)
    assert compute_brokenness(m, ref) is real and len(calls) == 1


def test_cli_says_when_and_where_a_map_was_measured_again(
    example, example_result, capsys, monkeypatch
):
    import brokenness.measure

    replicated = _with_bounds(example_result, [(0.3, 0.1), (0.35, 0.7), (0.34, 0.8)])
    replicated = replace(
        replicated,
        parameters=replicated.parameters
        | {
            "replication_frame": "turned 180",
            "replication_degree": 2,
            "replication_placed_alike": 0.9712,
            "replication_placed_alike_in_doubt": 0.804,
        },
    )
    monkeypatch.setattr(brokenness.measure, "compute_brokenness", lambda *a, **k: replicated)
    assert main(["compute", str(EXAMPLE), str(REFERENCE)]) == 0
    out = capsys.readouterr().out
    assert "measured again with the grid turned 180 degrees" in out
    assert (
        "degree 2 there, 97% of the partitioned cells placed alike (80% of those in doubt)" in out
    )
    monkeypatch.setattr(brokenness.measure, "compute_brokenness", lambda *a, **k: example_result)
    assert main(["compute", str(EXAMPLE), str(REFERENCE)]) == 0
    assert "measured again" not in capsys.readouterr().out


@pytest.mark.parametrize("coarser", ["none", "map", "reference"])
def test_a_true_partitioning_is_found_alike_with_the_grid_turned(coarser, monkeypatch):
    """The bundled broken example (degree 2, every partition true), measured again with its
    grid turned by a half turn (asked here of it): nearly every partitioned cell is placed
    alike, also when the map or the reference is at twice the other's cell (c then counted
    in the reference's cells)."""
    from brokenness.io.resample import resample_to_resolution
    from brokenness.measure import recursion

    m, ref = load_map(EXAMPLE), load_map(REFERENCE)
    if coarser == "map":
        m = resample_to_resolution(m, 2 * m.resolution)
    elif coarser == "reference":
        ref = resample_to_resolution(ref, 2 * ref.resolution)
    monkeypatch.setattr(recursion, "to_replicate", lambda result: True)
    result = compute_brokenness(m, ref)
    assert result.measured and result.degree == 2
    assert result.parameters["replication_degree"] == 2
    assert result.parameters["replication_placed_alike"] > 0.9
