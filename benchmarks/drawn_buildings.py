"""Buildings drawn for a held-out check: shapes unlike any map the rules were chosen on.

Every rule of the measure was chosen on the simulated buildings of
:func:`brokenness.simulation.building.generate_building` (rooms and corridors at right
angles) and the real logs, and checked on six more buildings known as maps
(``realistic.py --plans``). The maps users bring will be of other buildings again. This
script draws three floor plans in code (deterministic, nothing downloaded, no
``../shared`` needed) whose geometry none of those has:

- ``wings``: a corridor with five rooms, a slanted wing, a round room, pillars and a
  slanted wall across the corridor's end;
- ``atrium``: a round atrium with a ring of six columns and five corridors at 72 degrees to
  each other, each to a room of its own size, turned with the corridor (a building nearly
  symmetric under a fifth of a turn);
- ``office``: an open-plan office in an irregular hexagon, with free-standing partitions and
  desks at random angles.

Each is toured and scanned as ``realistic.py --plans`` does for the six buildings of
``tests/data`` and ``../shared/data`` (``simulation.plan_run``; the map in its own frame,
three-state, a third of the cases at another resolution than the reference, degrees 0-8,
seeds 0 and 1, or ``--seeds N --first-seed S``), measured through the public API from the
YAML files, and judged the same way (exact degree; all partitions true within 3 reference
cells). Then the negative controls of these buildings: each broken map at degrees 0, 3
and 6 against the reference of each other drawn building (its run at degree 0 and the first
seed) and against four references of the repository (building 31, the Nav2 depot, the
Willow Garage SLAM map and a simulated building), which must get no degree.

Usage::

    python benchmarks/drawn_buildings.py --workers 2   # 4 min on 2 cores, 3 more to draw the maps
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from brokenness import OccupancyMap
from brokenness.grid import FREE, OCCUPIED, UNKNOWN

sys.path.insert(0, str(Path(__file__).resolve().parent))

#: Metres per cell of the drawn plans.
RESOLUTION = 0.05
#: Wall thickness drawn around the free space (cells each side: 0.2 m).
WALL = 4
#: Degrees of the broken maps that are also negative controls.
CONTROL_DEGREES = (0, 3, 6)
#: References of the repository the drawn maps are controls against (``cases.py`` names).
CONTROL_REFERENCES = ("building_31", "depot", "willow_slam", "sim_ref_201")


def _cells(metres: float) -> int:
    return int(round(metres / RESOLUTION))


def _walled(inside: NDArray[np.uint8], disc: bool = False) -> NDArray[np.int8]:
    """States of a plan whose free space is ``inside`` (nonzero), walls ``WALL`` cells thick
    around it, unknown beyond."""
    size = 2 * WALL + 1
    kernel = (
        cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
        if disc
        else np.ones((size, size), np.uint8)
    )
    walls = cv2.dilate(inside, kernel) > 0
    states = np.full(inside.shape, UNKNOWN, np.int8)
    states[walls] = OCCUPIED
    states[inside > 0] = FREE
    return states


def _plan(states: NDArray[np.int8], name: str) -> OccupancyMap:
    return OccupancyMap(states, RESOLUTION, (0.0, 0.0, 0.0), source=f"drawn:{name}")


def wings() -> OccupancyMap:
    """A corridor with five rooms off it (doors 1 m wide), a wing slanted 36 degrees from
    the corridor's normal, a round room, three pillars, a slanted wall across the corridor's
    end and a table in the wing."""
    c = _cells
    inside = np.zeros((c(36), c(40)), np.uint8)
    cv2.rectangle(inside, (c(2), c(14)), (c(38), c(20)), 1, -1)  # the corridor
    for i in range(5):  # the rooms, 0.6 m of wall between them
        x0 = c(2 + 7.2 * i)
        cv2.rectangle(inside, (x0, c(4)), (x0 + c(6.6), c(13.6)), 1, -1)
    wing = np.array([[c(20), c(20)], [c(26), c(20)], [c(36), c(34)], [c(30), c(34)]], np.int32)
    cv2.fillPoly(inside, [wing], 1)
    cv2.circle(inside, (c(10), c(27)), c(5), 1, -1)  # the round room and its passage
    cv2.rectangle(inside, (c(9), c(20)), (c(11), c(23)), 1, -1)
    states = _walled(inside)
    for i in range(5):  # the doors
        xc = c(2 + 7.2 * i + 3.3)
        states[c(13.6) - 1 : c(14) + 1, xc - c(0.5) : xc + c(0.5)] = FREE
    occupied = np.zeros(states.shape, np.uint8)
    cv2.line(occupied, (c(33), c(14.5)), (c(37), c(19.5)), 1, 3)
    for x in (6, 16, 24):
        cv2.circle(occupied, (c(x), c(17)), c(0.25), 1, -1)
    cv2.rectangle(occupied, (c(29), c(28)), (c(30.5), c(29)), 1, -1)
    states[occupied > 0] = OCCUPIED
    return _plan(states, "wings")


def atrium() -> OccupancyMap:
    """A round atrium (6 m radius) with a ring of six columns and five corridors 72 degrees
    apart, each 14 m to a room of its own size (7 m by 5-9 m) turned with it."""
    c = _cells
    n = c(44)
    centre = n // 2
    inside = np.zeros((n, n), np.uint8)
    cv2.circle(inside, (centre, centre), c(6), 1, -1)
    for k in range(5):
        a = math.radians(18 + 72 * k)
        ex, ey = centre + c(14) * math.cos(a), centre + c(14) * math.sin(a)
        cv2.line(inside, (centre, centre), (int(ex), int(ey)), 1, c(2.2))
        room = ((ex + c(3) * math.cos(a), ey + c(3) * math.sin(a)), (c(7), c(5 + k)), 18 + 72 * k)
        cv2.fillPoly(inside, [cv2.boxPoints(room).astype(np.int32)], 1)
    states = _walled(inside, disc=True)
    occupied = np.zeros(states.shape, np.uint8)
    for k in range(6):
        a = math.radians(60 * k)
        at = (int(centre + c(3.5) * math.cos(a)), int(centre + c(3.5) * math.sin(a)))
        cv2.circle(occupied, at, c(0.3), 1, -1)
    states[occupied > 0] = OCCUPIED
    return _plan(states, "atrium")


def office() -> OccupancyMap:
    """An open-plan office in an irregular hexagon (30 m by 26 m), with nine free-standing
    partitions (3-7 m) and fourteen desks (1.6 m by 0.8 m) at random angles (seed 7)."""
    c = _cells
    rng = np.random.default_rng(7)
    inside = np.zeros((c(30), c(34)), np.uint8)
    outline = [(2, 2), (24, 2), (32, 9), (32, 28), (12, 28), (2, 18)]
    cv2.fillPoly(inside, [np.array([(c(x), c(y)) for x, y in outline], np.int32)], 1)
    states = _walled(inside)
    occupied = np.zeros(states.shape, np.uint8)
    for _ in range(9):
        x, y = rng.uniform(6, 28), rng.uniform(6, 24)
        a, length = rng.uniform(0, math.pi), rng.uniform(3, 7)
        end = (c(x + length * math.cos(a)), c(y + length * math.sin(a)))
        cv2.line(occupied, (c(x), c(y)), end, 1, 3)
    for _ in range(14):
        x, y = rng.uniform(5, 29), rng.uniform(5, 25)
        desk = ((c(x), c(y)), (c(1.6), c(0.8)), rng.uniform(0, 180))
        cv2.fillPoly(occupied, [cv2.boxPoints(desk).astype(np.int32)], 1)
    states[(occupied > 0) & (inside > 0)] = OCCUPIED  # nothing drawn outside the walls
    return _plan(states, "office")


#: The drawn buildings: name -> function that draws its plan.
DRAWN: dict[str, Callable[[], OccupancyMap]] = {"wings": wings, "atrium": atrium, "office": office}


def _control_jobs(made: list[tuple[Any, str]]) -> list[tuple[str, str, str, str, str]]:
    """Jobs of :func:`negative_controls.run_pair`: each broken drawn map (its case and case
    folder) at :data:`CONTROL_DEGREES` against the true-run reference of every other drawn
    building and the references of :data:`CONTROL_REFERENCES`."""
    import negative_controls as nc
    from cases import control_sources, save_control_maps

    available = [n for n in CONTROL_REFERENCES if n in control_sources()]
    refs = {str(k): str(v) for k, v in save_control_maps(available, nc.CACHE).items()}
    first = min((case.seed for case, _ in made), default=0)
    for case, folder in made:  # a drawn building's reference: its run at degree 0, first seed
        if case.degree == 0 and case.seed == first:
            refs[case.source[len("plan-") :]] = str(Path(folder) / "reference.yaml")
    jobs = []
    for case, folder in sorted(made, key=lambda cf: cf[0].name):
        if case.degree not in CONTROL_DEGREES:
            continue
        building, map_path = case.source[len("plan-") :], str(Path(folder) / "map.yaml")
        jobs += [("control", case.name, r, map_path, p) for r, p in refs.items() if r != building]
    return jobs


def _controls_table(rows: list[dict[str, Any]]) -> str:
    claims = [r for r in rows if r.get("measured")]
    errors = [r for r in rows if "error" in r]
    bounds = sorted(
        (r["contradiction_bound"], r["map"], r["reference"])
        for r in rows
        if r.get("contradiction_bound") is not None
    )
    out = [
        f"\nnegative controls: {len(rows)} pairs, {len(claims)} with a degree claimed"
        + "".join(f"\n  CLAIM {r['pair']}: degree {r['degree']}" for r in claims)
        + "".join(f"\n  ERROR {r['pair']}: {r['error']}" for r in errors)
    ]
    if bounds:
        out.append(
            "smallest upper bounds of the free-space ratio: "
            + ", ".join(f"{b:.3f} ({m} vs {r})" for b, m, r in bounds[:3])
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    import realistic

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seeds", type=int, default=2, help="seeds per building and degree")
    ap.add_argument(
        "--first-seed",
        type=int,
        default=0,
        help="seeds FIRST.. (0-7: the rules were checked on them; 8-9 first run in session 46)",
    )
    ap.add_argument("--cache", type=Path, default=realistic.RESULTS / "drawn")
    ap.add_argument("--out", type=Path, default=realistic.RESULTS / "drawn_buildings.json")
    ap.add_argument("--no-controls", action="store_true", help="only the broken maps")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    cases = realistic.case_list(
        logs=("none",), seeds=args.seeds, first_seed=args.first_seed, plans=tuple(DRAWN)
    )
    workers = max(1, args.workers)
    t0 = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        made = list(pool.map(realistic._generate_job, [(c, str(args.cache)) for c in cases]))
    failed = [c.name for c, f, _ in made if f is None]
    drawn = [(c, f) for c, f, _ in made if f is not None]
    print(
        f"{len(cases)} cases ({len(failed)} could not be drawn: {', '.join(failed) or '-'}); "
        f"generation {time.perf_counter() - t0:.0f} s (cache {args.cache})",
        flush=True,
    )
    with ProcessPoolExecutor(workers) as pool:
        rows = list(pool.map(realistic._evaluate_job, [f for _, f in drawn]))
        controls: list[dict[str, Any]] = []
        if not args.no_controls:
            import negative_controls as nc

            controls = list(pool.map(nc.run_pair, _control_jobs(drawn)))
    print(realistic.tables(rows))
    print(realistic.failures(rows))
    if controls:
        print(_controls_table(controls))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"rows": rows, "controls": controls}, indent=1))
    print(f"results: {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
