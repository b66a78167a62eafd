"""How ``compute_brokenness`` scales with the cells and the degree, and batch throughput (issue 14).

Maps are made as ``bench_compute.py`` makes them (its helpers are imported): the Willow Garage
map (``tests/data/willow-2010-02-18-0.10.yaml``, 608x566 at 0.1 m) rescaled with nearest
neighbours so that it fills a square reference of about 87 % of the map's side, cut into
``degree + 1`` rectangles, every rectangle but the first turned by 10-20 degrees about its
centre and shifted, drawn on a ``size x size`` map. The expected degree counts the rectangles
holding at least ``max(30 cells, 2 %)`` of the occupied cells (the default smallest
partition), less one, so it can be lower than the degree asked for.

Each case runs in a fresh Python process (maps built here, passed as ``.npy`` files): one
small warm-up call (imports, FFT plans), then the timed calls. Memory is the child's
``getrusage(RUSAGE_SELF).ru_maxrss``: "RSS" is the whole process's peak, "bytes/cell" the
peak of the timed calls over what the process holds just before them (maps loaded, warm-up
done), divided by the map's cells: on Linux the peak (``VmHWM``) is reset before the calls
(``/proc/self/clear_refs``), so the transient copies of loading do not hide it; elsewhere
the growth of ``ru_maxrss`` over the calls. The growth exponent is the least-squares slope of
log(time) against log(cells), per degree, over all sizes and over the sizes of 2000² and more.

Batch throughput: a manifest of 12 pairs of 688x646 (the Willow Garage map at its own size,
degrees 0-5, turns of 10-20 and 5-10 degrees) run with ``brokenness batch --workers 1`` and
``--workers 2`` (result zips with their overlay PNG, as a batch writes them): wall time of
the whole command, and the summary's seconds (loading and computing) per pair.

``--batch-only --rounds N`` runs only the batch part, N rounds (the order of the worker
counts alternating), then the fixed costs of a batch and of a pair: the interpreter and
imports of a process, the fork server's first worker, a worker process from the warm fork
server, and per pair loading, computing, repair and stats, the fast overlay, the figure,
and the whole ``save_results``. ``--overlays fast|figure|none`` is passed to ``batch``.
Between the two, the steady-state throughput: each round also runs a batch of 36 pairs (the
12 three times, with a label that makes them distinct) with 1 and 2 workers; the slope
(wall of 36 - wall of 12) / 24 is the time per pair without the start-up (the interpreter,
the imports, the fork server), and its ratio the throughput of a long batch.

Run: ``python benchmarks/bench_scale.py --quick`` (1.5-3 minutes: 1000² at degrees 0, 2,
5, 8; 2000² and 4000² at degrees 2 and 5; the batch once) or without ``--quick`` (5-15
minutes: degrees 0-8 at 1000²; 1000²-8000² at degrees 2 and 5; 10000² at degree 8
once; the batch twice, alternating the worker counts). ``--case SIZE:DEGREE[:RUNS]``
(repeatable) runs only those cases. The load average is printed per row: on a shared
machine, compare ratios within one run.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import cv2
import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from bench_compute import ROOT, broken_case, fit, grid_regions  # noqa: E402

from brokenness import OccupancyMap, compute_brokenness, load_map, save_map  # noqa: E402

WILLOW = ROOT / "tests" / "data" / "willow-2010-02-18-0.10.yaml"
SHARED_WILLOW = (
    ROOT.parent / "shared" / "data" / "willow-garage-2010-slam-map" / "willow-2010-02-18-0.10.yaml"
)
#: rows x cols of the grid cut into degree + 1 rectangles (its poorest cells merged when larger)
GRIDS = {1: (1, 1), 2: (1, 2), 3: (1, 3), 4: (2, 2), 5: (2, 3), 6: (2, 3), 7: (4, 2), 8: (5, 2)}
GRIDS[9] = (5, 2)


def willow() -> OccupancyMap:
    return load_map(SHARED_WILLOW if SHARED_WILLOW.exists() else WILLOW)


def regions_for(ref: OccupancyMap, n: int) -> list[np.ndarray]:
    """``n`` rectangles: the grid of GRIDS[n]; while it has more, the rectangle with the fewest
    occupied cells is merged with its neighbour in the same row."""
    rows, cols = GRIDS[n]
    regs = grid_regions(ref.shape, rows, cols)
    index = [(i, j) for i in range(rows) for j in range(cols)]
    while len(regs) > n:
        k = int(np.argmin([np.count_nonzero(ref.occupied & r) for r in regs]))
        i, j = index[k]
        other = next(
            q for q, (a, b) in enumerate(index) if a == i and b in (j - 1, j + 1) and q != k
        )
        regs[other] = regs[other] | regs[k]
        del regs[k], index[k]
    return regs


def make_case(
    base: OccupancyMap, size: int, degree: int, max_angle: float = 20.0
) -> tuple[OccupancyMap, OccupancyMap, int]:
    """(map, reference, expected degree) of ``size x size`` cells."""
    pad = round(size * 0.065)
    inner = size - 2 * pad
    scale = inner / max(base.shape)
    big = cv2.resize(base.states, None, fx=scale, fy=scale, interpolation=cv2.INTER_NEAREST)
    res = None if base.resolution is None else base.resolution / scale
    ref = fit(OccupancyMap(big, res), inner)
    regions = regions_for(ref, degree + 1)
    m, _ = broken_case(ref, regions, max_angle, pad=pad)
    return m, ref, expected_degree(ref, regions)


def expected_degree(ref: OccupancyMap, regions: list[np.ndarray]) -> int:
    """Rectangles that can be partitions under the default stopping rule's size floor
    (``max(30 cells, 2 %)`` of the occupied cells), less one."""
    floor = max(30, 0.02 * ref.n_occupied)
    return sum(np.count_nonzero(ref.occupied & r) >= floor for r in regions) - 1


# ----------------------------------------------------------------------------- child process


def child(map_npy: str, ref_npy: str, repeat: int, resolution: float) -> None:
    warnings.simplefilter("ignore")
    m = OccupancyMap(np.load(map_npy), resolution)
    ref = OccupancyMap(np.load(ref_npy), resolution)
    w = willow()
    compute_brokenness(w, w)  # warm-up: imports, FFT plans
    # the peak of the calls over what the process holds just before them (Linux: reset the
    # peak, VmHWM, and read it back); else the growth of the whole process's peak
    rss0 = _vm("VmRSS") if _reset_peak() else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    u0 = resource.getrusage(resource.RUSAGE_SELF)
    times, result = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        result = compute_brokenness(m, ref)
        times.append(time.perf_counter() - t0)
    u1 = resource.getrusage(resource.RUSAGE_SELF)
    assert result is not None
    print(
        json.dumps(
            {
                "times": times,
                "degree": result.degree,
                "rss0_kib": rss0,
                "peak_kib": _vm("VmHWM") if _vm("VmHWM") else u1.ru_maxrss,
                "rss_kib": u1.ru_maxrss,
                "user": (u1.ru_utime - u0.ru_utime) / repeat,
                "sys": (u1.ru_stime - u0.ru_stime) / repeat,
            }
        )
    )


def _reset_peak() -> bool:
    """Reset this process's peak resident memory (Linux ``/proc/self/clear_refs``)."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return _vm("VmHWM") > 0


def _vm(field: str) -> int:
    """A ``/proc/self/status`` memory figure in KiB (0 where there is none)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith(field + ":"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0


# ----------------------------------------------------------------------------- parent


def run_case(
    base: OccupancyMap, size: int, degree: int, repeat: int, tmp: Path
) -> dict[str, float | int | None]:
    m, ref, expected = make_case(base, size, degree)
    cells = m.shape[0] * m.shape[1]
    occupied = m.n_occupied
    resolution = m.resolution or 0.1
    np.save(tmp / "m.npy", m.states)
    np.save(tmp / "r.npy", ref.states)
    del m, ref
    load = os.getloadavg()[0]
    out = subprocess.run(
        [
            sys.executable,
            __file__,
            "--child",
            str(tmp / "m.npy"),
            str(tmp / "r.npy"),
            str(repeat),
            str(resolution),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    r = json.loads(out.stdout.strip().splitlines()[-1])
    row = {
        "size": size,
        "cells": cells,
        "occupied": occupied,
        "asked": degree,
        "expected": expected,
        "degree": r["degree"],
        "median": float(np.median(r["times"])),
        "best": min(r["times"]),
        "n": repeat,
        "user": r["user"],
        "sys": r["sys"],
        "cpu": r["user"] + r["sys"],
        "rss_mib": r["rss_kib"] / 1024,
        "bpc": (r["peak_kib"] - r["rss0_kib"]) * 1024 / cells,
        "load": load,
    }
    print(
        f"| {size}² | {degree} | {expected} | {row['degree']} | {occupied} | {row['median']:.3f} "
        f"| {row['best']:.3f} | {repeat} | {row['user']:.2f} + {row['sys']:.2f} "
        f"| {row['rss_mib']:.0f} | {row['bpc']:.1f} | {load:.1f} |",
        flush=True,
    )
    return row


def _slope(rs: list[dict], key: str, min_size: int = 0) -> str:
    pts = [(np.log(r["cells"]), np.log(r[key])) for r in rs if r["size"] >= min_size]
    if len(pts) < 2:
        return "-"
    x, y = zip(*pts, strict=True)
    return f"{np.polyfit(x, y, 1)[0]:.2f}"


def growth(rows: list[dict]) -> None:
    """Least-squares slope of log(time) against log(cells), per degree asked."""
    print(
        "\n| degree asked | sizes | exponent, wall (all sizes) | wall (2000² and up) "
        "| CPU (all sizes) | CPU (2000² and up) |"
    )
    print("|---|---|---|---|---|---|")
    for d in sorted({r["asked"] for r in rows}):
        rs = sorted((r for r in rows if r["asked"] == d), key=lambda r: r["cells"])
        if len(rs) < 2:
            continue
        sizes = ", ".join(str(r["size"]) for r in rs)
        print(
            f"| {d} | {sizes} | {_slope(rs, 'median')} | {_slope(rs, 'median', 2000)} "
            f"| {_slope(rs, 'cpu')} | {_slope(rs, 'cpu', 2000)} |"
        )


def make_manifest(base: OccupancyMap, folder: Path) -> Path:
    """12 pairs: the Willow Garage map at its own size (608x566) as the reference, broken at
    degrees 0-5 with turns of up to 20 and up to 10 degrees, on a map padded by 40 cells.
    Also writes ``manifest36.csv``: the same 12 pairs three times (a label ``copy`` 1-3 makes
    36 distinct pairs), for the steady-state throughput."""
    ref = base
    save_map(ref, folder / "ref.yaml")
    rows = []
    for angle in (20.0, 10.0):
        for degree in range(6):
            regions = regions_for(ref, degree + 1)
            m, _ = broken_case(ref, regions, angle, pad=40)
            expected = expected_degree(ref, regions)
            name = f"m{degree}_{int(angle)}.yaml"
            save_map(m, folder / name)
            rows.append({"map": name, "reference": "ref.yaml", "expected_degree": expected})
    path = folder / "manifest.csv"
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["map", "reference", "expected_degree"])
        w.writeheader()
        w.writerows(rows)
    with (folder / "manifest36.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["map", "reference", "expected_degree", "copy"])
        w.writeheader()
        w.writerows({**row, "copy": str(k)} for k in (1, 2, 3) for row in rows)
    return path


def _command() -> list[str]:
    """The ``brokenness`` command of this interpreter."""
    exe = Path(sys.executable).with_name("brokenness")
    return [str(exe)] if exe.exists() else [sys.executable, "-m", "brokenness"]


def run_batch(
    manifest: Path, workers: int, out: Path, overlays: str = "fast", pairs: int = 12
) -> tuple[float, float, float, int]:
    shutil.rmtree(out, ignore_errors=True)
    cmd = _command()
    load = os.getloadavg()[0]
    t0 = time.perf_counter()
    subprocess.run(
        [
            *cmd,
            "batch",
            str(manifest),
            "--out",
            str(out),
            "--workers",
            str(workers),
            "--overlays",
            overlays,
            "--no-progress",
            "-q",
        ],
        check=True,
    )
    wall = time.perf_counter() - t0
    n = len(list(out.glob("*.zip")))
    if n != pairs:
        raise RuntimeError(f"batch wrote {n} result zips, not {pairs}")
    with (out / "summary.csv").open() as f:
        rows = list(csv.DictReader(f))
    seconds = float(np.mean([float(r["seconds"]) for r in rows]))
    exact = sum(r["degree"] == r["expected_degree"] for r in rows)
    return wall, load, seconds, exact


def batch(base: OccupancyMap, tmp: Path, rounds: int, overlays: str = "fast") -> None:
    folder = tmp / "batch"
    folder.mkdir()
    manifest = make_manifest(base, folder)
    walls: dict[int, list[float]] = {1: [], 2: []}
    print(
        f"\n--overlays {overlays}\n\n| round | workers | wall s | s per pair "
        "| of which loading and computing (summary's seconds) | degree exact | load |"
    )
    print("|---|---|---|---|---|---|---|")
    for k in range(rounds):
        order = (1, 2) if k % 2 == 0 else (2, 1)
        for w in order:
            wall, load, seconds, exact = run_batch(manifest, w, tmp / f"out{w}", overlays)
            walls[w].append(wall)
            print(
                f"| {k + 1} | {w} | {wall:.1f} | {wall / 12:.3f} | {seconds:.3f} | {exact}/12 "
                f"| {load:.1f} |",
                flush=True,
            )
    one, two = np.median(walls[1]), np.median(walls[2])
    ratios = [a / b for a, b in zip(walls[1], walls[2], strict=True)]
    print(
        f"\nthroughput with 2 workers / with 1 (medians): {one / two:.2f}x; per round "
        + ", ".join(f"{r:.2f}x" for r in ratios)
    )
    steady_state(folder, tmp, rounds, overlays)
    fixed_costs(folder)


def steady_state(folder: Path, tmp: Path, rounds: int, overlays: str = "fast") -> None:
    """Throughput without the start-up: the slope between a batch of the 12 pairs and one
    of 36 (the 12 three times), per worker count, each round running the four batches
    (12 and 36 pairs, 1 and 2 workers) in an order that alternates."""
    walls: dict[tuple[int, int], list[float]] = {(w, n): [] for w in (1, 2) for n in (12, 36)}
    print(
        "\nsteady state: seconds per pair beyond the start-up, (wall of 36 pairs - wall of 12) "
        "/ 24\n\n| round | workers | wall 12 pairs | wall 36 pairs | s per pair (slope) "
        "| pairs/s | load |"
    )
    print("|---|---|---|---|---|---|---|")
    for k in range(rounds):
        order = (1, 2) if k % 2 == 0 else (2, 1)
        for w in order:
            sizes = (12, 36) if k % 2 == 0 else (36, 12)
            for n in sizes:
                manifest = folder / ("manifest.csv" if n == 12 else "manifest36.csv")
                wall, load, _, _ = run_batch(manifest, w, tmp / f"out{w}_{n}", overlays, n)
                walls[w, n].append(wall)
            slope = (walls[w, 36][-1] - walls[w, 12][-1]) / 24
            print(
                f"| {k + 1} | {w} | {walls[w, 12][-1]:.2f} | {walls[w, 36][-1]:.2f} "
                f"| {slope:.3f} | {1 / slope:.1f} | {load:.1f} |",
                flush=True,
            )
    slopes = {
        w: [(b - a) / 24 for a, b in zip(walls[w, 12], walls[w, 36], strict=True)] for w in (1, 2)
    }
    ratios = [a / b for a, b in zip(slopes[1], slopes[2], strict=True)]
    one, two = np.median(slopes[1]), np.median(slopes[2])
    start = {w: np.median(walls[w, 12]) - 12 * np.median(slopes[w]) for w in (1, 2)}
    print(
        f"\nsteady-state throughput with 2 workers / with 1 (medians of the slopes): "
        f"{one / two:.2f}x; per round "
        + ", ".join(f"{r:.2f}x" for r in ratios)
        + f"; start-up (wall of 12 pairs less 12 slopes): {start[1]:.2f} s with 1 worker, "
        f"{start[2]:.2f} s with 2"
    )


def _trivial_worker(conn: object, sent: float) -> None:
    conn.send(time.time() - sent)  # type: ignore[attr-defined]
    conn.close()  # type: ignore[attr-defined]


def fixed_costs(folder: Path) -> None:
    """What a pair and a batch cost besides computing: imports, the fork server, a worker
    process, loading, repair and stats, the overlay (fast and figure), the zip."""
    import io

    from brokenness._threads import forkserver_context
    from brokenness.batch.runner import _PRELOAD
    from brokenness.report.fast_overlay import fast_overlay_png
    from brokenness.report.overlay import render_overlay
    from brokenness.report.repair import repair
    from brokenness.report.results import build_stats, save_results

    # what a process evaluating pairs imports (``workers=1``, the fork server), and the
    # command line's own start (the batch process with workers, which imports no pipeline)
    modules = (*_PRELOAD, "brokenness.measure", "brokenness.report.fast_overlay")
    code = f"import importlib\nfor m in {modules!r}: importlib.import_module(m)"
    cli = [*_command(), "batch", "--help"]
    imports, starts_cli = [], []
    for _ in range(3):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-c", code], check=True)
        imports.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        subprocess.run(cli, check=True, stdout=subprocess.DEVNULL)
        starts_cli.append(time.perf_counter() - t0)
    ctx = forkserver_context((*_PRELOAD, "brokenness.report.fast_overlay"))
    starts = []
    for _ in range(13):
        recv, send = ctx.Pipe(duplex=False)
        t0 = time.perf_counter()
        proc = ctx.Process(target=_trivial_worker, args=(send, time.time()))
        proc.start()
        send.close()
        recv.recv()
        proc.join()
        starts.append(time.perf_counter() - t0)
    steps: dict[str, list[float]] = {
        k: [] for k in ("load", "compute", "repair+stats", "fast", "figure", "save fast")
    }
    ref_path = folder / "ref.yaml"
    for path in sorted(folder.glob("m*.yaml")):
        t0 = time.perf_counter()
        m, ref = load_map(path), load_map(ref_path)
        t1 = time.perf_counter()
        result = compute_brokenness(m, ref)
        t2 = time.perf_counter()
        build_stats(result, m, ref, repair(result, m, ref))
        t3 = time.perf_counter()
        fast_overlay_png(result, m, ref)
        t4 = time.perf_counter()
        render_overlay(result, m, ref, io.BytesIO(), dpi=100)
        t5 = time.perf_counter()
        save_results(folder / "x.zip", result, m, ref, overlay="fast")
        t6 = time.perf_counter()
        for key, dt in zip(
            steps, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4, t6 - t5), strict=True
        ):
            steps[key].append(dt)
    spin = "import time\nt = time.perf_counter()\nx = 0\nfor i in range(4_000_000): x += i * i\n"
    spin += "print(time.perf_counter() - t)"
    alone, both = [], []
    for _ in range(3):
        one = subprocess.run([sys.executable, "-c", spin], capture_output=True, text=True)
        alone.append(float(one.stdout))
        two = [
            subprocess.Popen([sys.executable, "-c", spin], stdout=subprocess.PIPE, text=True)
            for _ in range(2)
        ]
        both.append(max(float(p.communicate()[0]) for p in two))
    print(
        "\nthe machine: a CPU-bound loop takes "
        f"{np.median(alone):.2f} s alone and {np.median(both):.2f} s with two at once: two "
        f"processes get {2 * np.median(alone) / np.median(both):.2f}x the CPU of one "
        "(the ceiling of the batch's ratio)"
    )
    print(
        "\nfixed costs (medians): interpreter and imports of a process evaluating pairs "
        f"{np.median(imports):.2f} s (load {os.getloadavg()[0]:.1f}); `brokenness batch "
        f"--help` {np.median(starts_cli):.2f} s; the fork server's "
        f"first worker (its imports) {starts[0]:.2f} s; a worker process from the warm fork "
        f"server {1000 * np.median(starts[1:]):.0f} ms"
    )
    print(
        "per pair, in one process (median ms over the 12 pairs): "
        + ", ".join(f"{k} {1000 * np.median(v):.0f}" for k, v in steps.items())
        + " (save fast = repair, stats, fast overlay, zip and the inputs' SHA-256)"
    )


def _case(text: str) -> tuple[int, int, int]:
    """``SIZE:DEGREE[:RUNS]`` as ``(size, degree, runs)`` (one run unless given)."""
    parts = [int(v) for v in text.split(":")]
    if len(parts) not in (2, 3):
        raise SystemExit(f"--case wants SIZE:DEGREE[:RUNS], got {text!r}")
    return parts[0], parts[1], parts[2] if len(parts) == 3 else 1


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2], sys.argv[3], int(sys.argv[4]), float(sys.argv[5]))
        return
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the subset (about 3 minutes)")
    parser.add_argument("--no-batch", action="store_true", help="skip the batch throughput")
    parser.add_argument(
        "--batch-only", action="store_true", help="only the batch throughput (and fixed costs)"
    )
    parser.add_argument("--rounds", type=int, default=None, help="batch rounds (default 1/2)")
    parser.add_argument(
        "--overlays", choices=("fast", "figure", "none"), default="fast", help="batch --overlays"
    )
    parser.add_argument(
        "--case",
        action="append",
        default=[],
        metavar="SIZE:DEGREE[:RUNS]",
        help="only these cases (repeatable; e.g. --case 8000:5 --case 10000:8); no batch",
    )
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    base = willow()
    if args.quick:
        cases = [(1000, d, 3) for d in (0, 2, 5, 8)]
        cases += [(s, d, 2 if s < 4000 else 1) for s in (2000, 4000) for d in (2, 5)]
        rounds = 1
    else:
        cases = [(1000, d, 3) for d in range(9)]
        cases += [(s, d, {2000: 3, 4000: 2}.get(s, 1)) for s in (2000, 4000, 8000) for d in (2, 5)]
        cases += [(10000, 8, 1)]
        rounds = 2
    if args.rounds is not None:
        rounds = args.rounds
    if args.batch_only:
        cases = []
    if args.case:
        cases = [_case(text) for text in args.case]
        args.no_batch = True
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f} at the start\n")
    print(
        "| cells | degree asked | expected | found | occupied cells | median s | best s | runs "
        "| CPU s (user + sys) | RSS MiB | peak bytes/cell | load |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory(prefix="bench_scale_") as t:
        tmp = Path(t)
        rows = [run_case(base, s, d, n, tmp) for s, d, n in cases]
        if rows:
            growth(rows)
        if not args.no_batch:
            batch(base, tmp, rounds, args.overlays)
    print(f"\nload average at the end: {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
