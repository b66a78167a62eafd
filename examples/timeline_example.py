"""Worked example of ``brokenness timeline``: a simulated SLAM run recorded in a bag.

Run from the repository root (``python examples/timeline_example.py [--out out/timeline]``).
A robot explores a synthetic 15 m building (seed 0, 262 scans, one scan every 0.5 s); the
"SLAM node" publishes its map on ``/map`` every 10 scans (27 messages). Half-way through,
its pose estimate jumps by 20 degrees (a bump): everything it maps from then on is rigidly
off. At 80 % of the run a loop closure corrects the whole pose chain and the node publishes
the repaired map. The script writes

- ``OUT/run.bag`` (ROS 1; ``--ros 2`` writes a rosbag2 folder ``OUT/run``) and
  ``OUT/reference.yaml`` (the run mapped with the true poses),
- ``OUT/timeline.csv`` and ``OUT/timeline.png`` (also copied to ``examples/timeline.png``
  with ``--update-readme-plot``),

and prints the events. Writing and reading bags needs the optional package ``rosbags``
(``pip install ".[rosbags]"``; without it the script says so in one line). The same from
the command line, once the bag is written::

    brokenness timeline OUT/run.bag OUT/reference.yaml --csv OUT/timeline.csv --plot OUT/t.png
"""

from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

from brokenness import BrokennessError, save_map, timeline
from brokenness.io.rosbag_write import write_bag_maps
from brokenness.simulation.slam_run import simulate_slam_run
from brokenness.timeline import plot_timeline, write_timeline_csv

HERE = Path(__file__).parent


def main() -> None:
    ap = argparse.ArgumentParser(description="brokenness timeline on a simulated SLAM run")
    ap.add_argument("--out", type=Path, default=Path("out/timeline"))
    ap.add_argument("--ros", type=int, choices=(1, 2), default=1)
    ap.add_argument("--update-readme-plot", action="store_true")
    args = ap.parse_args()

    args.out.mkdir(parents=True, exist_ok=True)
    run = simulate_slam_run(seed=0, bump_at=0.5, repair_at=0.8, rotation_deg=20.0)
    bag = args.out / ("run.bag" if args.ros == 1 else "run")
    if bag.is_dir():
        shutil.rmtree(bag)
    bag.unlink(missing_ok=True)
    write_bag_maps(bag, run.maps(), ros=args.ros)
    save_map(run.reference, args.out / "reference.yaml")
    print(
        f"{bag}: {len(run.ends)} maps; bump at scan {run.bump.scan} "
        f"(first shown in message {run.break_message}), repair in message {run.repair_message}"
    )

    tl = timeline(bag, args.out / "reference.yaml", progress=None)
    for f in tl.frames:
        degree = "not measured" if f.degree is None else f"degree {f.degree}"
        shares = ", ".join(f"{p.fraction:.0%}" for p in f.partitions)
        print(f"  message {f.message_index:2d}  t={f.time:5.1f} s  {degree}  [{shares}]")
    for e in tl.events:
        print(e.describe())
    write_timeline_csv(tl, args.out / "timeline.csv")
    t0 = run.ends[0] * run.scan_period  # the plot's time axis starts at the first message
    t_bump = run.bump.scan * run.scan_period - t0
    t_fix = (run.repair_scan or 0) * run.scan_period - t0
    title = f"simulated run: bump at {t_bump:.0f} s, loop closure at {t_fix:.0f} s"
    plot_timeline(tl, args.out / "timeline.png", title=title)
    if args.update_readme_plot:
        shutil.copyfile(args.out / "timeline.png", HERE / "timeline.png")


if __name__ == "__main__":
    try:
        main()
    except BrokennessError as exc:  # a missing optional package, bad input: one line
        sys.exit(f"timeline_example: error: {exc}")
