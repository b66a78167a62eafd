"""Timeline of a long run: a bag of 300 maps of about 1000 x 1000 cells, two workers.

A simulated 38 m x 38 m building at 0.05 m per cell (the maps are about 1000 x 1000 cells:
the canvas also holds the part turned by the bump), explored in about 1700 scans; the "SLAM
node" publishes the map of all scans so far 300 times (every ~6 scans), with a 20 degree
bump half-way through and a repair (loop closure) at 80 % of the run
(:func:`brokenness.simulation.slam_run.simulate_slam_run`). The bag (ROS 1, about 300 MB)
is written once into ``--out`` (reused when there), then
:func:`brokenness.timeline` measures every message against the reference.

Reported: time to write the bag (not part of the target), wall-clock time of the timeline
per number of workers, frames per second, the mean time a worker spends on a frame, the
events found, and the peak resident memory of this process and of the largest worker
(``getrusage``; the target is memory bounded by one map per worker). Target: under 60 s
with two workers on the project machine (2 cores, shared: say what the load was).

Run: ``python benchmarks/bench_timeline.py [--workers 2 [1 ...]] [--messages 300]
[--size 50] [--out DIR]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import threading
import time
from pathlib import Path

import numpy as np

from brokenness import timeline
from brokenness.io.rosbag_write import write_bag_maps
from brokenness.simulation.slam_run import simulate_slam_run


def _mib(kib: int) -> float:
    return kib / 1024.0


class PeakMemory:
    """Peak resident memory of each process below this one (the workers), sampled."""

    def __init__(self, every: float = 0.2) -> None:
        self.peak: dict[int, int] = {}
        self._every, self._stop = every, threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)

    def _sample(self) -> None:
        import psutil

        me = psutil.Process()
        while not self._stop.is_set():
            for child in me.children(recursive=True):
                try:
                    rss = child.memory_info().rss
                except psutil.Error:
                    continue
                self.peak[child.pid] = max(rss, self.peak.get(child.pid, 0))
            self._stop.wait(self._every)

    def __enter__(self) -> PeakMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    def largest_mib(self) -> float:
        return max(self.peak.values(), default=0) / 2**20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--workers", type=int, nargs="+", default=[2])
    ap.add_argument("--messages", type=int, default=300)
    ap.add_argument("--size", type=float, default=38.0, help="building side, metres")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("/tmp/bench_timeline"))
    args = ap.parse_args()

    args.out.mkdir(parents=True, exist_ok=True)
    tag = f"s{args.seed}_{args.size:g}m_{args.messages}"
    bag = args.out / f"run_{tag}.bag"
    t0 = time.perf_counter()
    run = simulate_slam_run(seed=args.seed, size=args.size, publish_every=5)
    n_scans = run.ends[-1]
    ends = np.unique(np.linspace(0, n_scans, args.messages + 1)[1:].round().astype(int))
    run = dataclasses.replace(run, ends=tuple(int(e) for e in ends))
    print(
        f"simulated: {n_scans} scans, map {run.simulation.map.shape[0]} x "
        f"{run.simulation.map.shape[1]} cells, {len(run.ends)} messages, bump at scan "
        f"{run.bump.scan} (message {run.break_message}), repair at scan {run.repair_scan} "
        f"(message {run.repair_message}); {time.perf_counter() - t0:.1f} s"
    )
    if not bag.is_file():
        t0 = time.perf_counter()
        tmp = bag.with_suffix(".tmp.bag")
        tmp.unlink(missing_ok=True)
        write_bag_maps(tmp, run.maps())
        os.replace(tmp, bag)
        print(
            f"bag written: {bag} ({bag.stat().st_size / 1e6:.0f} MB), "
            f"{time.perf_counter() - t0:.1f} s"
        )
    else:
        print(f"bag reused: {bag} ({bag.stat().st_size / 1e6:.0f} MB)")
    print(f"load average before: {os.getloadavg()[0]:.2f}")

    for workers in args.workers:
        with PeakMemory() as mem:
            t0 = time.perf_counter()
            tl = timeline(bag, run.reference, workers=workers)
            wall = time.perf_counter() - t0
        frames = tl.frames
        busy = [f.seconds for f in frames if f.same_as is None]
        print(
            f"workers {workers}: {wall:.1f} s for {len(frames)} frames "
            f"({len(frames) / wall:.2f} frames/s); a frame takes {np.mean(busy):.3f} s "
            f"(median {np.median(busy):.3f}, max {np.max(busy):.3f}) in a worker; "
            f"{tl.count('reused')} unchanged, {tl.count('not measured')} not measured; "
            f"load average {os.getloadavg()[0]:.2f}"
        )
        for e in tl.events:
            print(f"  {e.describe()}")
        print(f"  peak RSS of the largest worker process: {mem.largest_mib():.0f} MiB")
    own = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    print(f"peak RSS of this process (simulation, bag reading, results): {_mib(own):.0f} MiB")


if __name__ == "__main__":
    main()
