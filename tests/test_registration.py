"""iFMI registration: known rigid transforms of real and synthetic maps are recovered."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from brokenness.errors import MapError, ParameterError
from brokenness.grid import OccupancyMap
from brokenness.io import load_map, resample_to_resolution
from brokenness.registration import IFMIRegistrar, make_registrar, register
from brokenness.transform import RigidTransform

DATA = Path(__file__).parent / "data"

ROT_TOL_DEG = 1.0
DISP_TOL_CELLS = 1.5


@pytest.fixture(scope="module")
def maps() -> dict[str, OccupancyMap]:
    with pytest.warns(Warning):  # depot.yaml triggers the Nav2 grey-205 warning
        depot = load_map(DATA / "depot.yaml")
    return {
        "depot": depot,
        "tb3": load_map(DATA / "tb3_sandbox.yaml"),
        "building": load_map(DATA / "building_31.yaml"),
        "willow": load_map(DATA / "willow-2010-02-18-0.10.yaml"),
    }


def synthetic_map(seed: int = 7, shape: tuple[int, int] = (240, 300)) -> np.ndarray:
    """Rooms with one-cell walls and door gaps, free inside, unknown outside."""
    rng = np.random.default_rng(seed)
    rows, cols = shape
    s = np.full(shape, -1, dtype=np.int8)
    s[10 : rows - 10, 10 : cols - 10] = 0
    occ = np.zeros(shape, dtype=bool)
    occ[10, 10 : cols - 10] = occ[rows - 11, 10 : cols - 10] = True
    occ[10 : rows - 10, 10] = occ[10 : rows - 10, cols - 11] = True
    for _ in range(9):
        if rng.random() < 0.5:
            r = int(rng.integers(30, rows - 30))
            c0, c1 = sorted(rng.integers(10, cols - 10, 2))
            occ[r, c0:c1] = True
            gap = int(rng.integers(c0, max(c0 + 1, c1 - 8)))
            occ[r, gap : gap + 8] = False
        else:
            c = int(rng.integers(30, cols - 30))
            r0, r1 = sorted(rng.integers(10, rows - 10, 2))
            occ[r0:r1, c] = True
    for _ in range(6):  # furniture blobs
        r, c = rng.integers(20, rows - 25), rng.integers(20, cols - 25)
        occ[r : r + 4, c : c + 6] = True
    s[occ] = 1
    return s


def transformed(
    states: np.ndarray,
    deg: float,
    shift: tuple[float, float],
    shape: tuple[int, int] | None = None,
    region: tuple[int, int, int, int] | None = None,
) -> tuple[np.ndarray, RigidTransform]:
    """A moving map: ``states`` (or its ``region``) rotated/shifted into a new canvas.

    Returns the moving states and the true transform moving cells -> ``states`` cells: the
    moving canvas centre goes onto the reference centre (rounded) plus ``shift``, turned by
    ``deg``.
    """
    rows, cols = states.shape
    if shape is None:
        side = math.ceil(math.hypot(rows, cols)) + 4
        shape = (side, side)
    mr, mc = shape
    th = math.radians(deg)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    cm = np.array([(mc - 1) / 2, (mr - 1) / 2])
    cr = np.array([(cols - 1) / 2, (rows - 1) / 2])
    t = np.round(cr - rot @ cm) + np.asarray(shift, dtype=float)
    true = RigidTransform(th, t[0], t[1])
    src = states.astype(np.int16)
    if region is not None:
        r0, r1, c0, c1 = region
        src = np.full_like(src, -1)
        src[r0:r1, c0:c1] = states[r0:r1, c0:c1]
    moving = cv2.warpAffine(
        src,
        true.matrix[:2],
        (mc, mr),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=-1,
    )
    return moving.astype(np.int8), true


def check(est: RigidTransform, true: RigidTransform, moving: np.ndarray) -> tuple[float, float]:
    """Rotation error (deg) and mean displacement (cells) over the moving occupied cells."""
    pts = np.argwhere(moving == 1)[:, ::-1].astype(float)
    disp = float(true.displacement(est, pts).mean())
    rot = abs(math.degrees(math.remainder(est.rotation - true.rotation, 2 * math.pi)))
    assert rot < ROT_TOL_DEG, f"rotation off by {rot:.3f} deg ({est} vs {true})"
    assert disp < DISP_TOL_CELLS, f"mean displacement {disp:.3f} cells ({est} vs {true})"
    return rot, disp


# -- convention ---------------------------------------------------------------------------------
def test_rot90_follows_the_transform_convention() -> None:
    ref = synthetic_map(3, (150, 220))
    moving = np.rot90(ref).copy()  # moving (x, y) shows reference (W - 1 - y, x)
    reg = register(ref, moving)
    rows, cols = ref.shape
    assert reg.rotation_deg == pytest.approx(90.0, abs=1e-6)
    assert reg.transform.tx == pytest.approx(cols - 1, abs=1e-6)
    assert reg.transform.ty == pytest.approx(0.0, abs=1e-6)


def test_pure_shift_sign() -> None:
    ref = synthetic_map(5)
    moving = np.full_like(ref, -1)
    moving[:-20, 13:] = ref[20:, :-13]  # moving (x, y) shows reference (x - 13, y + 20)
    reg = register(ref, moving)
    assert reg.rotation_deg == pytest.approx(0.0, abs=1e-4)
    assert reg.transform.translation == pytest.approx((-13.0, 20.0), abs=1e-3)


def test_self_registration_is_identity(maps: dict[str, OccupancyMap]) -> None:
    for m in maps.values():
        reg = register(m, m)
        assert abs(reg.rotation_deg) < 1e-6
        assert reg.transform.translation == pytest.approx((0.0, 0.0), abs=1e-6)
        assert reg.confidence > 0.9
        assert reg.method == "ifmi"


# -- accuracy -------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("deg", "shift"),
    [
        (0.7, (3, -2)),
        (-17.3, (25, 40)),
        (45.0, (-30, 10)),
        (90.0, (0, 0)),
        (-90.0, (12.0, -5.0)),
        (133.0, (-40, -40)),
        (-150.2, (60, -20)),
        (179.6, (5, 5)),
        (180.0, (-8, 0)),
        (-179.4, (0, 33)),
    ],
)
def test_recovers_rotation_and_shift_tb3(maps: dict[str, OccupancyMap], deg, shift) -> None:
    ref = maps["tb3"].states
    moving, true = transformed(ref, deg, shift)
    check(register(ref, moving).transform, true, moving)


@pytest.mark.parametrize("name", ["depot", "building", "willow"])
@pytest.mark.parametrize("deg", [-123.4, 61.0, 178.8])
def test_recovers_real_maps(maps: dict[str, OccupancyMap], name: str, deg: float) -> None:
    ref = maps[name].states
    moving, true = transformed(ref, deg, (17, -11))
    check(register(ref, moving).transform, true, moving)


@pytest.mark.parametrize("deg", [-100.0, -2.5, 37.0, 171.0])
def test_recovers_synthetic_maps(deg: float) -> None:
    ref = synthetic_map(11)
    moving, true = transformed(ref, deg, (9, 4))
    check(register(ref, moving).transform, true, moving)


def test_shift_of_a_third_of_the_map(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["building"].states
    rows, cols = ref.shape
    # the same canvas size: a third of the map slides out of view, the rest must align
    for deg, shift in [(20.0, (cols / 3, 0)), (-160.0, (-cols / 3, rows / 3))]:
        moving, true = transformed(ref, deg, shift, shape=ref.shape)
        check(register(ref, moving).transform, true, moving)


def test_moving_map_is_a_part_of_the_reference(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["building"].states
    rows, cols = ref.shape
    region = (rows // 4, rows // 4 + rows // 2, cols // 3, cols // 3 + cols // 2)
    for deg in (-75.0, 152.0):
        moving, true = transformed(
            ref, deg, (10, -6), shape=(rows // 2 + 60, cols // 2 + 60), region=region
        )
        check(register(ref, moving).transform, true, moving)


def test_largest_part_of_a_broken_map_is_aligned() -> None:
    ref = synthetic_map(21, (260, 320))
    # 70 % of the map moved by T, the rest by another transform: T must win
    moving, true = transformed(ref, 25.0, (6, -4), shape=ref.shape)
    rest, _ = transformed(ref, -40.0, (30, 15), shape=ref.shape)
    cut = int(0.7 * ref.shape[1])
    moving[:, cut:] = rest[:, cut:]
    pts = np.argwhere(moving[:, :cut] == 1)[:, ::-1].astype(float)
    est = register(ref, moving).transform
    assert abs(est.rotation_deg - 25.0) < ROT_TOL_DEG
    assert float(true.displacement(est, pts).mean()) < DISP_TOL_CELLS


def test_different_shapes_both_ways(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["willow"].states
    big, true = transformed(ref, -63.0, (-4, 9), shape=(900, 700))
    check(register(ref, big).transform, true, big)
    # the reference smaller than the moving map: register the other way round
    est = register(big, ref).transform
    check(est.inverse(), true, big)


def test_twin_is_resolved_and_offered(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["tb3"].states
    moving, true = transformed(ref, 12.0, (4, 4))
    reg = register(ref, moving, max_candidates=4)
    check(reg.transform, true, moving)
    angles = [c.transform.rotation_deg for c in reg.candidates]
    assert any(abs(math.remainder(a - 192.0, 360.0)) < 2.0 for a in angles[1:])
    assert 1 <= len(reg.candidates) <= 4
    assert all(0.0 <= c.confidence <= 1.0 for c in reg.candidates)


def test_large_map_uses_reduced_resolution_and_stays_accurate(
    maps: dict[str, OccupancyMap],
) -> None:
    b = maps["building"].states
    up = cv2.resize(
        b.astype(np.int16), (b.shape[1] * 2, b.shape[0] * 2), interpolation=cv2.INTER_NEAREST
    )
    registrar = IFMIRegistrar(max_size=160)
    prepared = registrar.prepare_reference(up.astype(np.int8))
    assert prepared.factor >= 8
    moving, true = transformed(up.astype(np.int8), -37.0, (40, -25), shape=up.shape)
    check(registrar.candidates(prepared, moving, 3)[0].transform, true, moving)


# -- properties -----------------------------------------------------------------------------------
def test_deterministic(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["willow"].states
    moving, _ = transformed(ref, 77.0, (3, 8))
    a = register(ref, moving).to_dict()
    b = register(ref, moving).to_dict()
    a.pop("seconds")
    b.pop("seconds")
    assert a == b
    r = IFMIRegistrar()
    p = r.prepare_reference(ref)
    first = r.candidates(p, moving, 4)
    again = r.candidates(p, moving, 4)  # cached spectra give the same numbers
    assert first == again


def test_accepts_arrays_and_maps(maps: dict[str, OccupancyMap]) -> None:
    m = maps["tb3"]
    occ_bool = m.states == 1
    reg = register(occ_bool, np.roll(occ_bool, 5, axis=1))
    assert reg.transform.translation == pytest.approx((-5.0, 0.0), abs=1e-3)
    reg2 = register(m, np.roll(m.states, 5, axis=1))
    assert reg2.transform.translation == pytest.approx((-5.0, 0.0), abs=1e-3)


def test_world_transform_attached(maps: dict[str, OccupancyMap]) -> None:
    m = maps["tb3"]
    shifted = OccupancyMap(np.roll(m.states, (4, -6), axis=(0, 1)), m.resolution, m.origin)
    reg = register(m, shifted)
    w = reg.transform.world
    assert w is not None
    # 6 cells right in the image = 6 cells left in the world; 4 rows down = 4 cells up
    assert w.translation == pytest.approx((6 * m.resolution, 4 * m.resolution), abs=1e-6)
    assert reg.transform.rotation_deg_world == pytest.approx(0.0, abs=1e-6)


def test_different_resolution_is_resampled(maps: dict[str, OccupancyMap]) -> None:
    m = maps["tb3"]
    coarse = resample_to_resolution(m, 2 * m.resolution)
    reg = register(m, coarse)
    t = reg.transform
    assert t.scale == pytest.approx(2.0)
    # world frames coincide (same origin), so the world transform is ~ identity
    assert t.world is not None
    assert abs(t.world.rotation_deg) < 0.5
    assert np.hypot(*t.world.translation) < 1.5 * m.resolution * 2
    # the coarse cells land on occupied reference cells
    pts = np.argwhere(coarse.states == 1)[:, ::-1].astype(float)
    q = np.round(t.apply(pts)).astype(int)
    inside = (q[:, 0] >= 0) & (q[:, 0] < m.shape[1]) & (q[:, 1] >= 0) & (q[:, 1] < m.shape[0])
    dist = cv2.distanceTransform(np.where(m.states == 1, 0, 255).astype(np.uint8), cv2.DIST_L2, 5)
    assert np.median(dist[q[inside, 1], q[inside, 0]]) <= 1.5


# -- errors and options -------------------------------------------------------------------------
def test_empty_maps_raise_map_error(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["tb3"].states
    empty = np.zeros((50, 60), dtype=np.int8)
    with pytest.raises(MapError, match="no occupied cell"):
        register(ref, empty)
    with pytest.raises(MapError, match="no occupied cell"):
        register(empty, ref)
    with pytest.raises(MapError):
        register(np.zeros((3, 4, 5)), ref)
    r = IFMIRegistrar()
    with pytest.raises(MapError):
        r.prepare_reference(np.full((10, 10), -1, dtype=np.int8))
    with pytest.raises(MapError):
        r.candidates(r.prepare_reference(ref), empty, 3)


@pytest.mark.parametrize(
    "options",
    [
        {"n_angles": 4},
        {"band": (0.6, 0.2)},
        {"band": "wide"},
        {"max_size": 10},
        {"rotation_peaks": 0},
        {"peak_ratio": 1.5},
        {"rotation_whitening": 1.5},
        {"rotation_whitening": True},
        {"refine": "yes"},
        {"agree_cells": -1.0},
        {"no_such_option": 1},
    ],
)
def test_bad_options_raise_parameter_error(options) -> None:
    with pytest.raises(ParameterError):
        make_registrar("ifmi", **options)


def test_options_and_max_candidates(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["tb3"].states
    moving, true = transformed(ref, -33.0, (2, 7))
    reg = register(ref, moving, n_angles=720, band=(0.1, 0.7), rotation_peaks=3, max_candidates=2)
    assert len(reg.candidates) <= 2
    check(reg.transform, true, moving)
    with pytest.raises(ParameterError):
        register(ref, moving, max_candidates=0)
    with pytest.raises(ParameterError):
        register(ref, moving, method="no-such-method")
    # without the full-resolution refinement the spectral estimate alone is still close
    rough = register(ref, moving, refine=False).transform
    assert abs(math.remainder(rough.rotation_deg + 33.0, 360.0)) < ROT_TOL_DEG


# -- command line --------------------------------------------------------------------------------
def _cli(argv: list[str], monkeypatch: pytest.MonkeyPatch) -> int:
    from brokenness.cli import main as cli_main

    if "register" not in cli_main.SUBCOMMANDS:
        monkeypatch.setattr(cli_main, "SUBCOMMANDS", (*cli_main.SUBCOMMANDS, "register"))
    return cli_main.main(argv)


def test_cli_summary_and_json(tmp_path: Path, monkeypatch, capsys) -> None:
    ref = DATA / "tb3_sandbox.yaml"
    assert _cli(["register", str(ref), str(ref)], monkeypatch) == 0
    out = capsys.readouterr().out
    assert "rotation:" in out and "translation:" in out and "confidence:" in out
    assert "world:" in out  # the YAML gives resolution and origin
    assert _cli(["register", str(ref), str(ref), "--json", "-"], monkeypatch) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["method"] == "ifmi"
    assert record["transform"]["rotation_deg"] == pytest.approx(0.0, abs=1e-6)
    assert record["transform"]["world"]["translation_m"] == pytest.approx([0.0, 0.0], abs=1e-6)
    path = tmp_path / "reg.json"
    assert _cli(["register", str(ref), str(ref), "--json", str(path)], monkeypatch) == 0
    assert json.loads(path.read_text())["moving"] == str(ref)


def test_cli_bad_input_exits_2(tmp_path: Path, monkeypatch, capsys) -> None:
    ref = DATA / "tb3_sandbox.yaml"
    assert _cli(["register", str(ref), str(tmp_path / "missing.pgm")], monkeypatch) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error" in err
    empty = tmp_path / "empty.npy"
    np.save(empty, np.zeros((20, 20), dtype=bool))
    assert _cli(["register", str(ref), str(empty)], monkeypatch) == 2
    assert "no occupied cell" in capsys.readouterr().err


def test_confidence_separates_matches_from_unrelated_maps(maps: dict[str, OccupancyMap]) -> None:
    ref = maps["building"].states
    moving, _ = transformed(ref, 40.0, (5, 5))
    assert register(ref, moving).confidence > 0.9
    assert register(ref, synthetic_map(11)).confidence < 0.5
    assert register(ref, maps["tb3"]).confidence < 0.5


def test_small_reference_large_moving_map_is_pooled_more() -> None:
    ref = synthetic_map(4, (120, 150))
    big = np.full((1500, 1400), -1, dtype=np.int8)
    big[700:820, 600:750] = ref  # the reference is a small part of the moving map
    big[5, 5:1395] = big[1494, 5:1395] = 1  # far walls: the moving map spans 1500 cells
    registrar = IFMIRegistrar()
    prepared = registrar.prepare_reference(ref)
    assert prepared.factor == 1
    found = registrar.candidates(prepared, big, 2)[0].transform
    assert abs(found.rotation_deg) < ROT_TOL_DEG
    assert found.translation == pytest.approx((-600.0, -700.0), abs=1.5)
    assert max(prepared.levels) > 1  # pooled more for the large moving map


def test_translation_peaks_offer_every_copy_of_a_repeated_room():
    """In a row of identical rooms a room fits each of them: with translation_peaks=3 the
    hypotheses include other copies (60 cells apart), with 1 only the best peak."""
    from brokenness.registration import IFMIRegistrar

    ref = np.zeros((60, 200), np.int8)
    for x0 in (10, 70, 130):  # three identical rooms
        ref[10, x0 : x0 + 50] = ref[50, x0 : x0 + 50] = 1
        ref[10:51, x0] = ref[10:51, x0 + 50] = 1
        ref[10:30, x0 + 20] = 1
    moving = ref[:, 60:130].copy()  # the middle room

    def hypotheses(peaks: int) -> list[tuple[float, float, float]]:
        reg = IFMIRegistrar(translation_peaks=peaks)
        cands = reg.candidates(reg.prepare_reference(ref), moving, 12)
        return [(c.transform.rotation_deg, c.transform.tx, c.transform.ty) for c in cands]

    def copies(hyps: list[tuple[float, float, float]]) -> int:
        """Largest number of hypotheses with one rotation and shifts a room apart."""
        best = 0
        for rot, tx, ty in hyps:
            same = [h for h in hyps if abs(h[0] - rot) < 1 and abs(h[2] - ty) < 2]
            apart = [h[1] - tx for h in same]
            shifts = {round(d / 60) for d in apart if min(d % 60, 60 - d % 60) < 2}
            best = max(best, len(shifts))
        return best

    assert copies(hypotheses(1)) == 1
    assert copies(hypotheses(3)) >= 2


def test_translation_peaks_option_is_checked():
    from brokenness import ParameterError
    from brokenness.registration import IFMIRegistrar

    with pytest.raises(ParameterError):
        IFMIRegistrar(translation_peaks=0)


def test_remembered_analysis_is_only_reused_for_the_same_map(
    maps: dict[str, OccupancyMap],
) -> None:
    """A prepared reference remembers the last moving map; a wider second call on it gives
    what a fresh registrar gives, and a changed map (same array object) is analysed anew."""
    ref = maps["building"].states
    moving, true = transformed(ref, -41.0, (5, -7))
    narrow = IFMIRegistrar(rotation_peaks=2)
    wide = IFMIRegistrar(rotation_peaks=6, peak_ratio=0.0)
    prepared = narrow.prepare_reference(ref)
    narrow.candidates(prepared, moving, 4)
    assert wide.candidates(prepared, moving, 8) == wide.candidates(
        wide.prepare_reference(ref), moving, 8
    )
    # mutate the very same array: the remembered analysis must not be used
    other, true_other = transformed(ref, 63.0, (-4, 6), shape=moving.shape)
    moving[...] = other
    check(narrow.candidates(prepared, moving, 4)[0].transform, true_other, moving)


@pytest.mark.parametrize("shape", [(8, 10), (2, 2), (36, 50), (96, 64)])
def test_packed_phase_correlation_matches_numpy(shape) -> None:
    """The translation stage's OpenCV packed spectra give numpy's phase correlation."""
    from brokenness.registration import _spectral

    rng = np.random.default_rng(3)
    a = rng.random((shape[0] // 2, shape[1] // 2)).astype(np.float32)
    b = rng.random((shape[0] // 2, shape[1] // 2)).astype(np.float32)
    fa = _spectral.whiten(np.fft.rfft2(a, s=shape).astype(np.complex64))
    fb = _spectral.whiten(np.fft.rfft2(b, s=shape).astype(np.complex64))
    pa, pb = _spectral.packed_spectrum(a, shape), _spectral.packed_spectrum(b, shape)
    for twin in (False, True):
        expected = np.fft.irfft2(fa * (fb if twin else np.conj(fb)), s=shape)
        got = cv2.idft(cv2.mulSpectrums(pa, pb, 0, conjB=not twin), flags=cv2.DFT_REAL_OUTPUT)
        np.testing.assert_allclose(got / (shape[0] * shape[1]), expected, atol=1e-5)


def test_packed_sizes_are_even_and_fast() -> None:
    from brokenness.registration._spectral import packed_size

    sizes = [packed_size(n) for n in range(1, 400)]
    assert all(m % 2 == 0 and m >= n for n, m in zip(range(1, 400), sizes, strict=True))
    assert all(cv2.getOptimalDFTSize(m) == m for m in sizes)
    assert packed_size(121) == 128 and packed_size(315) == 320


def test_same_placement_test_skips_far_centroids_without_changing_the_answer() -> None:
    # the centroid bound only skips placements the full mean-distance test rejects
    rng = np.random.default_rng(0)
    for _ in range(2000):
        n, k = int(rng.integers(1, 300)), int(rng.integers(0, 8))
        a = rng.uniform(-500, 3000, (n, 2))
        scale = float(rng.choice([0.3, 0.9, 1.0, 1.1, 2.0, 5.0]))
        others = a[None] + rng.normal(0, scale, (k, n, 2)) + rng.normal(0, scale, (k, 1, 2))
        d = (a - others).reshape(-1, 2)
        dist = np.sqrt(np.einsum("ij,ij->i", d, d)).reshape(k, n)
        full = bool((dist.mean(axis=1) < 1.0).any())
        centres = others.mean(axis=1)
        made: list[int] = []

        def placement(i: int, others=others, made=made) -> np.ndarray:
            made.append(i)
            return others[i]

        assert IFMIRegistrar._same_as_any((a, a.mean(axis=0)), centres, placement) == full
        # only the placements whose centroids are within a cell (and the margin) are made
        off = centres - a.mean(axis=0)
        near = off[:, 0] * off[:, 0] + off[:, 1] * off[:, 1] <= (1.0 + 1e-6) ** 2
        assert sorted(made) == [int(i) for i in np.flatnonzero(near)]
