"""Tests of brokenness.simulation.options: BumpOptions and HonestRule, and how they are used."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from brokenness import OCCUPIED, OccupancyMap
from brokenness.errors import ParameterError
from brokenness.masking import ReferenceIndex
from brokenness.simulation import (
    Bump,
    BumpOptions,
    HonestRule,
    draw_bumps,
    draw_k_bumps,
    simulate_broken_map,
)
from brokenness.simulation.ground_truth import broken_map_from_run, draw_broken_map
from brokenness.simulation.mapper import map_scans, segment_labels


def test_defaults_are_those_of_the_public_functions() -> None:
    options = BumpOptions()
    assert (options.seed, options.degree, options.bumps, options.bump_probability) == (
        0,
        None,
        None,
        None,
    )
    assert (options.bump_radius, options.max_rotation, options.min_rotation) == (1.0, 180.0, 10.0)
    assert options.max_attempts == 30 and options.rule == HonestRule(2.0, 4.0, 0.02, 30)
    assert options.attempts == 1  # one draw unless a degree is asked for
    assert BumpOptions(degree=2).attempts == 30


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"degree": 1, "bumps": 1}, "give at most one of degree, bumps and bump_probability"),
        ({"bumps": 1, "bump_probability": 0.1}, "give at most one of degree"),
        ({"seed": -1}, "seed must be a non-negative integer, got -1"),
        ({"seed": 1.5}, "seed must be a non-negative integer, got 1.5"),
        ({"seed": True}, "seed must be a non-negative integer, got True"),
        ({"degree": -1}, "degree must be a non-negative integer, got -1"),
        ({"degree": 1.0}, "degree must be a non-negative integer, got 1.0"),
        ({"min_rotation": 30.0, "max_rotation": 20.0}, "need 0 <= min_rotation <= max_rotation"),
        ({"max_rotation": 200.0}, "need 0 <= min_rotation <= max_rotation <= 180 degrees"),
        ({"min_rotation": -1.0}, "need 0 <= min_rotation <= max_rotation <= 180 degrees"),
        ({"max_rotation": math.nan}, "need 0 <= min_rotation <= max_rotation <= 180 degrees"),
        ({"max_attempts": 0}, "max_attempts must be a positive integer"),
        ({"max_attempts": 2.0}, "max_attempts must be a positive integer"),
    ],
)
def test_validation_once_with_the_public_messages(kwargs: dict, message: str) -> None:
    with pytest.raises(ParameterError, match=re.escape(message)):
        BumpOptions(**kwargs)
    # the public function says the same, before any building is generated
    with pytest.raises(ParameterError, match=re.escape(message)):
        simulate_broken_map(**kwargs)


def test_values_are_normalised_and_frozen() -> None:
    options = BumpOptions(seed=np.int64(4), bumps=[Bump(3, 0.1, 0.2, 0.3)])
    assert type(options.seed) is int and options.seed == 4
    assert options.bumps == (Bump(3, 0.1, 0.2, 0.3),)  # a tuple: the options cannot change
    with pytest.raises(AttributeError):
        options.degree = 2  # type: ignore[misc]
    assert BumpOptions(bumps=np.int64(2)).bumps == 2  # a count stays a count


def test_draw_follows_the_mode() -> None:
    n = 200
    rng = np.random.default_rng([7, 2, 3])  # draw 3 of seed 7
    spread = draw_k_bumps(
        n, 3, radius=0.5, max_rotation=math.pi / 2, min_rotation=math.radians(10.0), rng=rng
    )
    assert BumpOptions(seed=7, degree=3, bump_radius=0.5, max_rotation=90.0).draw(n, 3) == spread
    rng = np.random.default_rng([7, 2, 0])
    anywhere = draw_k_bumps(
        n,
        2,
        radius=1.0,
        max_rotation=math.pi,
        min_rotation=math.radians(10.0),
        rng=rng,
        spread=False,
    )
    assert BumpOptions(seed=7, bumps=2).draw(n, 0) == anywhere
    rng = np.random.default_rng([7, 2, 0])
    paper = draw_bumps(n, 0.05, radius=1.0, max_rotation=math.pi, rng=rng)
    assert BumpOptions(seed=7, bump_probability=0.05).draw(n, 0) == paper
    given = [Bump(50, 0.3, 0.2, 0.1)]
    assert BumpOptions(seed=7, bumps=given).draw(n, 5) == given
    assert BumpOptions(seed=7).draw(n, 0) == []
    # each draw number gives other bumps, the same ones every time
    options = BumpOptions(seed=1, degree=2)
    assert options.draw(n, 0) == options.draw(n, 0) != options.draw(n, 1)


def test_bump_radius_and_probability_are_checked_when_drawn() -> None:
    BumpOptions(bumps=[], bump_radius=-1.0)  # not used: no error, as before
    with pytest.raises(ParameterError, match="bump radius must be a non-negative number"):
        BumpOptions(degree=1, bump_radius=-1.0).draw(100, 0)
    with pytest.raises(ParameterError, match=re.escape("bump probability must be in [0, 1]")):
        BumpOptions(bump_probability=1.5).draw(100, 0)


def test_parameters_entries() -> None:
    options = BumpOptions(
        seed=3, bumps=[Bump(3, 0.1, 0.2, 0.3)], rule=HonestRule(min_partition_cells=9)
    )
    assert options.parameters() == {
        "seed": 3,
        "degree": None,
        "bumps": "explicit",
        "bump_probability": None,
        "bump_radius": 1.0,
        "max_rotation_deg": 180.0,
        "min_rotation_deg": 10.0,
    }
    assert options.rule.parameters() == {
        "threshold": 2.0,
        "merge_threshold": 4.0,
        "min_partition_fraction": 0.02,
        "min_partition_cells": 9,
    }
    sim = simulate_broken_map(seed=2, degree=1, min_partition_cells=25)
    assert {
        **BumpOptions(seed=2, degree=1).parameters(),
        "attempts": sim.parameters["attempts"],
    }.items() <= sim.parameters.items()
    assert sim.parameters["min_partition_cells"] == 25


def test_draw_broken_map_is_broken_map_from_run_of_the_options_draw() -> None:
    sim = simulate_broken_map(seed=3, degree=1)
    assert sim.run is not None and sim.building is not None
    extent = (0.0, 0.0, sim.building.width, sim.building.height)
    rule = HonestRule(threshold=1.5, min_partition_fraction=0.05)
    options = BumpOptions(seed=3, bumps=2, rule=rule)
    index = ReferenceIndex.build(sim.reference)
    (broken, expected, parts, labels, judged, _), attempts = draw_broken_map(
        sim.run, sim.reference, index, extent, options, hint="-"
    )
    again = broken_map_from_run(
        sim.run,
        sim.reference,
        options.draw(len(sim.run.true_poses), 0),
        extent=extent,
        threshold=1.5,
        min_partition_fraction=0.05,
    )
    assert attempts == 1
    np.testing.assert_array_equal(broken.states, again[0].states)
    np.testing.assert_array_equal(labels, again[3])
    assert (expected, parts, judged) == again[1:3] + again[4:5]
    with pytest.raises(ParameterError, match="could not make a map of degree 9 in 2 draws"):
        draw_broken_map(
            sim.run, sim.reference, index, extent, BumpOptions(degree=9, max_attempts=2), hint="try"
        )


def test_segment_labels_most_hits_first_on_ties() -> None:
    poses = np.array([[0.5, 0.5, 0.0]] * 3)
    ranges = np.full((3, 1), 0.3)
    angles = np.zeros(1)
    drawn = map_scans(poses, ranges, angles, max_range=4.0, resolution=0.1, shape=(10, 10))
    assert int(drawn.states[4, 8]) == OCCUPIED
    labels = segment_labels(poses, ranges, angles, np.array([0, 1, 1]), drawn, max_range=4.0)
    assert labels.dtype == np.int16 and int(labels[4, 8]) == 1  # two hits of segment 1
    assert (labels[drawn.states != OCCUPIED] == -1).all()
    labels = segment_labels(poses, ranges, angles, np.array([0, 1, 0]), drawn, max_range=4.0)
    assert int(labels[4, 8]) == 0
    labels = segment_labels(poses[:2], ranges[:2], angles, np.array([0, 1]), drawn, max_range=4.0)
    assert int(labels[4, 8]) == 0  # a tie: the first segment
    with pytest.raises(ParameterError, match="need a map with a resolution and an origin"):
        segment_labels(
            poses, ranges, angles, np.zeros(3, np.int64), OccupancyMap(drawn.states), max_range=4.0
        )


def test_numpy_integers_become_plain_numbers_so_the_simulation_writes_as_json() -> None:
    import json

    assert type(BumpOptions(degree=np.int64(2)).degree) is int
    assert type(BumpOptions(bumps=np.int32(3)).bumps) is int
    sim = simulate_broken_map(seed=1, degree=np.int64(1), size=8.0)
    assert sim.parameters["degree"] == 1 and type(sim.parameters["degree"]) is int
    assert json.loads(json.dumps(sim.to_dict()))["parameters"]["degree"] == 1


def test_a_building_too_small_for_a_route_is_a_parameter_error() -> None:
    with pytest.raises(ParameterError, match="at least two waypoints"):
        simulate_broken_map(seed=1, degree=1, size=6.0)
