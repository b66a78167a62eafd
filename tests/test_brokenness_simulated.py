"""compute_brokenness on maps of known degree from the bump-noise simulator (issue 3).

Ground truth: a robot explores a seeded synthetic building; the broken map is drawn with
poses that jumped ``k`` times, the reference with the true poses. The expected degree is the
simulator's honest count (bumps whose partition is too small or not "off" do not count).

Degrees 0..2 must be found exactly, with the true transforms. Degrees 3..5 on these regular
synthetic buildings (rooms of similar sizes, where a piece of one room fits another) are
harder: a small partition whose walls coincide with the reference's under another
partition's transform can be lost. For them we require every map of four seeds to be within
one of its degree; the exact-match rates over many seeds are in the README
(benchmarks/experiment_tables.py).
"""

from __future__ import annotations

import pytest

from brokenness import OccupancyMap, compute_brokenness
from brokenness.masking import cell_points
from brokenness.simulation.synthetic import simulate_broken_map

SEEDS = (0, 1, 2)


def _transform_errors(result, sim) -> list[float]:
    """Per found partition, the mean displacement (cells) to the nearest true transform."""
    truths = [p.transform for p in sim.partitions]
    out = []
    for p in result.partitions:
        pts = cell_points(result.labels == p.index)
        out.append(min(float(p.transform.displacement(t, pts).mean()) for t in truths))
    return out


def test_reference_of_a_simulation_is_degree_zero():
    sim = simulate_broken_map(seed=0, degree=2)
    assert compute_brokenness(sim.reference, sim.reference).degree == 0


@pytest.mark.parametrize("degree", [0, 1, 2])
@pytest.mark.parametrize("seed", SEEDS)
def test_low_degrees_exactly(degree, seed):
    sim = simulate_broken_map(seed=seed, degree=degree)
    assert sim.expected_degree == degree
    result = compute_brokenness(sim.map, sim.reference)
    assert result.degree == degree
    # each partition found is one of the true ones, to within a cell and a half
    assert max(_transform_errors(result, sim)) < 1.5


@pytest.mark.parametrize("degree", [3, 4, 5])
def test_higher_degrees_within_bounds(degree):
    """Of four maps, each measured one is within a partition of its degree; at most one is
    not measured (seed 2 at degree 4 since session 46: its partition in doubt is placed
    elsewhere with the grid turned by a half turn, README step 11)."""
    found = []
    for seed in (0, 1, 2, 3):
        sim = simulate_broken_map(seed=seed, degree=degree)
        assert sim.expected_degree == degree
        found.append(compute_brokenness(sim.map, sim.reference).degree)
    measured = [d for d in found if d is not None]
    assert len(measured) >= 3, found
    assert max(abs(d - degree) for d in measured) <= 1, found


@pytest.mark.parametrize(("degree", "seed"), [(2, 1014), (3, 1012), (3, 1019)])
def test_partitions_that_overlap_in_the_reference_are_found_whole(degree, seed):
    """Partitions of a run overlap in the reference (the robot sees a corridor before and
    after a bump). Registering only with the reference less the walls already matched split
    one true partition of these maps into two or three wrongly placed ones (degree off by one
    or two); with the whole reference every partition comes back with its true transform."""
    sim = simulate_broken_map(seed=seed, degree=degree)
    assert sim.expected_degree == degree
    result = compute_brokenness(sim.map, sim.reference)
    assert result.degree == degree
    assert max(_transform_errors(result, sim)) < 1.5


def test_a_partition_that_lost_cells_to_others_is_recovered(monkeypatch):
    """A small partition of this map (4 % of the cells) loses many of its cells to earlier
    partitions, under whose transforms its walls lie on reference walls; what is left is too
    ambiguous to register alone, and the recursion stops one partition short. The recovery
    finds it among the cells no partition explains coherently, with its true transform (to
    within 4 cells on average: with so few cells of its own, the partition can slide by a
    cell or two along the walls it keeps)."""
    import brokenness.measure.recovery as recovery

    degree, seed = 4, 1018
    sim = simulate_broken_map(seed=seed, degree=degree)
    assert sim.expected_degree == degree
    result = compute_brokenness(sim.map, sim.reference)
    assert result.degree == degree
    assert max(_transform_errors(result, sim)) < 4.0  # every partition is a true one
    monkeypatch.setattr(recovery, "SUPPORT_SHARE", 0.0)  # no suspect: the recursion alone
    assert compute_brokenness(sim.map, sim.reference).degree == degree - 1


def test_a_reference_that_knows_little_free_space_does_not_hide_the_partitions():
    """The chance agreement of the stopping rule is not the share of the reference's known
    area within ``c`` of a wall alone: with the reference's free space known only up to 5
    cells from its walls, that share (``p0``) is 0.49 instead of 0.10, above the agreement of
    every partition of this degree-3 map (17-44 % of its cells), and nothing was found. The
    step's rival hypotheses (other transforms of this map onto this reference) tell what
    chance is here; the four true partitions are found. (Whether the degree is then
    measured is the contradiction test's call, at its limit on this artificial reference:
    it knows free space only near walls, so few free cells of the map can be counted.)"""
    from brokenness.grid import FREE, UNKNOWN
    from brokenness.masking import ReferenceIndex
    from brokenness.masking.distance import manhattan_distance_map

    sim = simulate_broken_map(seed=0, degree=3)
    assert sim.expected_degree == 3
    ref = sim.reference
    states = ref.states.copy()
    states[(states == FREE) & (manhattan_distance_map(ref.occupied) > 5)] = UNKNOWN
    dense = OccupancyMap(states, resolution=ref.resolution, origin=ref.origin)
    assert ReferenceIndex.build(dense).chance_agreement(2) > 0.45
    result = compute_brokenness(sim.map, dense)
    assert len(result.partitions) == 4
    assert max(_transform_errors(result, sim)) < 1.5


def test_a_partition_at_a_twin_takes_a_hypothesis_of_an_earlier_registration(monkeypatch):
    """One partition of this map ends at a twin of its part's place, 115 cells off; its true
    transform was among the hypotheses of an earlier registration of the call, and offered
    again at the end (``measure/pool.py``) it makes more of the map agree: every partition
    is then a true one."""
    import brokenness.measure.recursion as recursion

    degree, seed = 4, 1008
    sim = simulate_broken_map(seed=seed, degree=degree)
    result = compute_brokenness(sim.map, sim.reference)
    assert result.degree == degree
    assert max(_transform_errors(result, sim)) < 1.0
    monkeypatch.setattr(recursion, "offered", lambda *args: [])  # no hypothesis offered again
    alone = compute_brokenness(sim.map, sim.reference)
    assert len(alone.partitions) == degree + 1
    assert max(_transform_errors(alone, sim)) > 50.0
    # and the partition at the twin, in doubt, is not found again with the grid turned by a
    # half turn: since session 46 the map is then not measured (README step 11)
    assert not alone.measured and alone.degree is None
    assert "of the cells of its partitions in doubt placed alike" in (alone.reason or "")
