"""What each stage of the measure buys: the cached benchmark cases with one stage switched off.

The measure is a sequence of stages (README, "How the degree is measured"), each added for
maps it set right. Whether a later stage made an earlier one redundant, and what each costs,
is measured here: the cases of ``realistic.py`` (simulated buildings and real logs, read from
its cache) and of ``drawn_buildings.py`` (buildings no rule was chosen on) are computed
through the public API with one stage switched off, and compared case by case with a run of
the whole pipeline (``--stage none``; give its output to ``--compare``). A stage is switched
off by replacing one function of the package for the run (in this process and its workers);
nothing of the package is changed on disk.

Stages (README step numbers):

- ``second-rounds``: the recovery runs once (step 5 is not repeated after the tests);
- ``first-relocation``: the first recovery round does not register the doubtful partitions'
  own cells alone (step 5's ``relocate``);
- ``relocation``: no step 8 (the settled partitions are not registered alone, nor placed);
- ``piece-rivals``: step 8 without the unions of a doubtful partition and those it touches;
- ``place-every``: step 8 places only the doubtful partitions (not every partition at the
  opposite of its rotation);
- ``all-suspects``: step 5 does not register all the suspects when their regions hold fewer;
- ``groups``: step 5 does not register each group of suspects and the region around it;
- ``region-placement``: step 5's last search (the region around each group of dense
  suspects placed with all its cells) is left out;
- ``rechosen``: step 8's last offers of every hypothesis of the call ("Every hypothesis,
  once more") are left out;
- ``pooled``: step 8's count of every hypothesis of the call as a new partition ("... and
  as new partitions") is left out;
- ``symmetry``: step 10 (pieces at twins that a symmetry of the reference relates made one
  partition) is left out;
- ``replication``: step 11 (a map measured with a partition in doubt must be measured with
  its grid turned by a half turn too) is left out (and with it ``frames``'s other frames,
  tried for the same maps; the stages run with ``frames=1``).

Usage::

    python benchmarks/ablation.py --stage none --out base.json --workers 2
    python benchmarks/ablation.py --stage piece-rivals --compare base.json --workers 2

(cases missing from the caches of ``realistic.py`` and ``drawn_buildings.py`` are drawn
first, as those scripts draw them; with the caches filled, sets 0-10 and the drawn
buildings at 8 seeds take about 6 minutes on 2 cores).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import realistic  # noqa: E402

from brokenness.measure import recovery, recursion  # noqa: E402


def _second_rounds() -> None:
    recursion.RECOVERY_ROUNDS = 1


def _keyword_false(module: Any, name: str, keyword: str) -> None:
    """Replace ``module.name`` by the same function called with ``keyword=False``."""
    function = getattr(module, name)

    def without(*args: Any, **kwargs: Any) -> Any:
        kwargs[keyword] = False
        return function(*args, **kwargs)

    setattr(module, name, without)


def _relocation() -> None:
    recursion._relocated = lambda found, context, registrar, whole, hypotheses: (found, None)  # type: ignore[assignment]


def _rechosen() -> None:
    recursion._rechosen = lambda found, verdict, context, hypotheses: (found, verdict)  # type: ignore[assignment]


def _pooled() -> None:
    recursion._grown = lambda found, verdict, evidence, context, hypotheses: (found, verdict)  # type: ignore[assignment]


def _symmetry() -> None:
    recursion.symmetries = lambda *args: []  # type: ignore[assignment]


def _replication() -> None:
    recursion.to_replicate = lambda result: False  # type: ignore[assignment]


def _piece_rivals() -> None:
    recovery._piece_rivals = lambda *args, **kwargs: []  # type: ignore[assignment]


def _searches_without(drop: Callable[[Any, Any], bool]) -> None:
    searches = recovery._searches

    def without(points: Any, dense: Any, suspect: Any, min_cells: int) -> Iterator[Any]:
        for step in searches(points, dense, suspect, min_cells):
            if not drop(step, suspect):
                yield step

    recovery._searches = without  # type: ignore[assignment]


STAGES: dict[str, Callable[[], None]] = {
    "none": lambda: None,
    "second-rounds": _second_rounds,
    "first-relocation": lambda: _keyword_false(recursion, "recover", "relocate"),
    "relocation": _relocation,
    "piece-rivals": _piece_rivals,
    "place-every": lambda: _keyword_false(recovery, "_relocations", "place_every"),
    "all-suspects": lambda: _searches_without(
        lambda step, suspect: step.cells is suspect and not step.sources and not step.placed
    ),
    "groups": lambda: _searches_without(lambda step, suspect: bool(step.sources)),
    "region-placement": lambda: _searches_without(lambda step, suspect: not step.counted),
    "rechosen": _rechosen,
    "pooled": _pooled,
    "symmetry": _symmetry,
    "replication": _replication,
}


def _switch_off(stage: str) -> None:
    warnings.simplefilter("ignore")
    STAGES[stage]()


def _cases(args: argparse.Namespace) -> list[tuple[Any, str]]:
    """The cases and their caches: realistic sets ``args.sets`` and the drawn buildings."""
    cases: list[tuple[Any, str]] = []
    first, _, last = args.sets.partition("-")
    for s in range(int(first), int(last or first) + 1) if args.sets else ():
        cases += [(c, str(args.cache)) for c in realistic.case_list(first_seed=s)]
    if args.drawn_seeds:
        from drawn_buildings import DRAWN

        drawn = realistic.case_list(logs=("none",), seeds=args.drawn_seeds, plans=tuple(DRAWN))
        cases += [(c, str(args.drawn_cache)) for c in drawn]
    return cases


def table(rows: list[dict[str, Any]]) -> str:
    """Per kind of case: cases, exact degree, all partitions true, not measured, CPU s."""
    out = ["| cases | n | exact | all true | not measured | CPU s |", "|---|---|---|---|---|---|"]
    for kind in ("simulated", "real log", "plan"):
        sel = [r for r in rows if realistic.source_kind(r["source"]) == kind]
        if sel:
            out.append(
                f"| {kind} | {len(sel)} | {sum(bool(r.get('exact')) for r in sel)} "
                f"| {sum(bool(r.get('all_true')) for r in sel)} "
                f"| {sum(not r.get('measured', True) for r in sel)} "
                f"| {sum(r.get('cpu_seconds', 0.0) for r in sel):.0f} |"
            )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--stage", choices=sorted(STAGES), required=True)
    ap.add_argument("--sets", default="0-10", help="realistic sets (first seeds), e.g. 0-10")
    ap.add_argument("--cache", type=Path, default=realistic.CACHE)
    ap.add_argument("--drawn-seeds", type=int, default=8, help="0: no drawn buildings")
    ap.add_argument("--drawn-cache", type=Path, default=realistic.RESULTS / "drawn")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument("--compare", type=Path, default=None, help="a run of --stage none")
    args = ap.parse_args(argv)
    start = time.perf_counter()
    with ProcessPoolExecutor(
        max(1, args.workers), initializer=_switch_off, initargs=(args.stage,)
    ) as pool:
        # the cases missing from the caches drawn first, as realistic.py draws them
        made = pool.map(realistic._generate_job, _cases(args))
        folders = [folder for _, folder, _ in made if folder is not None]
        if not folders:
            print("no case could be drawn")
            return 1
        rows = list(pool.map(realistic._evaluate_job, folders, chunksize=4))
    print(f"stage off: {args.stage}; {len(rows)} cases, {time.perf_counter() - start:.0f} s")
    print(table(rows))
    if args.compare is not None:
        old = json.loads(args.compare.read_text())
        here = {r["case"] for r in rows}
        print(f"\n{args.compare}:")
        print(table([r for r in old["rows"] if r["case"] in here]))
        print(realistic.compare(old, rows, []))
    out = args.out or realistic.RESULTS / f"ablation_{args.stage}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps({"stage": args.stage, "rows": rows}, indent=1))
    print(f"results: {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
