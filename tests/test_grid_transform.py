"""The map container and the transform convention."""

from __future__ import annotations

import math

import numpy as np
import pytest

from brokenness import FREE, OCCUPIED, UNKNOWN, MapError, MapSizeError, OccupancyMap, RigidTransform
from brokenness.transform import wrap_angle


def test_from_array_bool_and_nav_values():
    m = OccupancyMap.from_array(np.array([[True, False]]))
    assert m.states.tolist() == [[OCCUPIED, FREE]]
    nav = np.array([[-1, 0, 19, 20, 64, 65, 100]], dtype=np.int8)
    assert OccupancyMap.from_array(nav).states.tolist() == [
        [UNKNOWN, FREE, FREE, UNKNOWN, UNKNOWN, OCCUPIED, OCCUPIED]
    ]


def test_states_are_read_only_and_copied():
    arr = np.zeros((3, 3), np.int8)
    m = OccupancyMap(arr)
    arr[0, 0] = 1
    assert m.states[0, 0] == 0
    with pytest.raises(ValueError):
        m.states[0, 0] = 1


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros(5),
        np.array([[101]], np.int16),
        np.array([[np.nan]]),
        np.array([[1.5]]),
        np.zeros((0, 4)),
    ],
)
def test_bad_arrays_raise_map_error(bad):
    with pytest.raises(MapError):
        OccupancyMap.from_array(bad)


def test_absurd_size_is_refused_before_allocation(monkeypatch):
    monkeypatch.setenv("BROKENNESS_MAX_CELLS", "100")  # the documented override
    with pytest.raises(MapSizeError, match="BROKENNESS_MAX_CELLS"):
        OccupancyMap(np.zeros((11, 10), np.int8))


@pytest.mark.parametrize("res", [0.0, -1.0, float("nan")])
def test_bad_resolution(res):
    with pytest.raises(MapError):
        OccupancyMap(np.zeros((2, 2), np.int8), resolution=res)


def test_wrap_angle_range():
    assert wrap_angle(math.pi) == pytest.approx(math.pi)
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_transform_formula_compose_inverse():
    t = RigidTransform(math.radians(30), 5.0, -2.0)
    p = np.array([[1.0, 2.0], [10.0, -3.0]])
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    expected = np.column_stack([c * p[:, 0] - s * p[:, 1] + 5, s * p[:, 0] + c * p[:, 1] - 2])
    np.testing.assert_allclose(t.apply(p), expected)
    u = RigidTransform(-1.0, 3.0, 4.0)
    np.testing.assert_allclose(t.compose(u).apply(p), t.apply(u.apply(p)))
    np.testing.assert_allclose(t.inverse().apply(t.apply(p)), p, atol=1e-12)
    assert t.rotation_deg == pytest.approx(30.0)
    assert t.translation == (5.0, -2.0)


def test_world_transform_of_a_shifted_crop_is_identity():
    """A crop of a map, with its origin moved accordingly, is the same world: identity."""
    ref = OccupancyMap(np.zeros((50, 80), np.int8), resolution=0.1, origin=(-2.0, 1.0, 0.0))
    # crop rows 10.. and columns 20..: lower-left corner unchanged in y (same bottom), x moves.
    crop = OccupancyMap(np.zeros((40, 60), np.int8), resolution=0.1, origin=(0.0, 1.0, 0.0))
    t = RigidTransform(0.0, 20.0, 10.0).with_world(crop, ref)
    assert t.world is not None
    assert t.world.rotation_deg == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(t.world.translation, (0.0, 0.0), atol=1e-9)


def test_world_rotation_sign_is_counter_clockwise():
    """Rows point down, so a positive cell rotation is a negative (clockwise) world rotation."""
    m = OccupancyMap(np.zeros((10, 10), np.int8), resolution=0.05, origin=(0.0, 0.0, 0.0))
    t = RigidTransform(math.radians(90), 0.0, 0.0).with_world(m, m)
    assert t.rotation_deg_world == pytest.approx(-90.0)
    # check on a point: the world image of a cell centre equals the cell image's world centre
    cell = np.array([[3.0, 7.0]])
    w_before = (m.cell_to_world_matrix() @ np.array([3.0, 7.0, 1.0]))[:2]
    w_after = (m.cell_to_world_matrix() @ np.append(t.apply(cell)[0], 1.0))[:2]
    np.testing.assert_allclose(t.world.apply(w_before[None])[0], w_after, atol=1e-12)


def test_world_frame_needs_geometry():
    m = OccupancyMap(np.zeros((10, 10), np.int8))
    assert RigidTransform(0.1, 1, 2).with_world(m, m).world is None
    with pytest.raises(MapError):
        m.cell_to_world_matrix()
