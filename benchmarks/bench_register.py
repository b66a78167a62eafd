"""Registration speed and accuracy: brokenness iFMI vs scikit-image's recipe vs imreg_dft.

Each case is a real map cropped/padded to N x N cells (N = 512, 1024), and a copy of it
rotated and shifted by a known rigid transform into a canvas of the same size (so the
corners that turn out of view are lost, as in a real partial map). Every method solves the
same job -- rotation in (-180, 180] and translation, 180-degree twin included -- and we
report the rotation error per case and the median wall-clock time over ``--repeats`` runs
(the machine is shared; medians damp the noise). Peak memory of ``brokenness.register`` is
measured with :mod:`tracemalloc` (numpy, scipy.fft and OpenCV outputs are traced) and
divided by the padded working size of its FFTs.

Run::

    python benchmarks/bench_register.py [--repeats 5] [--sizes 512 1024] [--out FILE.md]

Maps: tests/data (always there); /work/shared/data maps are used when present (bigger real
maps for the 1024 cases), else tests/data maps are upsampled 2x.
"""

from __future__ import annotations

import os

# One thread everywhere (BLAS, OpenMP, OpenCV below): the machine is shared and the
# comparison is per core. ``--threads N`` re-enables OpenCV threads for a second look.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import tracemalloc  # noqa: E402
import warnings  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
import scipy.fft  # noqa: E402

from brokenness.io import load_map  # noqa: E402
from brokenness.registration import IFMIRegistrar, register  # noqa: E402
from brokenness.transform import RigidTransform  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TESTS = ROOT / "tests" / "data"
SHARED = ROOT.parent / "shared" / "data"

# (rotation deg, shift as a fraction of N): moving -> reference
TRANSFORMS = [(23.5, (0.05, -0.03)), (-117.0, (-0.08, 0.1)), (171.3, (0.12, 0.06))]


def _load(path: Path) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.asarray(load_map(path).states)


def _fit(states: np.ndarray, n: int) -> np.ndarray:
    """Centre-crop or pad (unknown) a map to n x n cells."""
    out = np.full((n, n), -1, dtype=np.int8)
    rows, cols = states.shape
    sr, sc = max(0, (rows - n) // 2), max(0, (cols - n) // 2)
    dr, dc = max(0, (n - rows) // 2), max(0, (n - cols) // 2)
    h, w = min(n, rows), min(n, cols)
    out[dr : dr + h, dc : dc + w] = states[sr : sr + h, sc : sc + w]
    return out


def _upsample2(states: np.ndarray) -> np.ndarray:
    up = cv2.resize(
        states.astype(np.int16),
        (states.shape[1] * 2, states.shape[0] * 2),
        interpolation=cv2.INTER_NEAREST,
    )
    return up.astype(np.int8)


def base_maps(n: int) -> list[tuple[str, np.ndarray]]:
    """Two real maps of n x n cells."""
    if n <= 700:
        return [
            ("building_31", _fit(_load(TESTS / "building_31.yaml"), n)),
            ("willow-2010", _fit(_load(TESTS / "willow-2010-02-18-0.10.yaml"), n)),
        ]
    shared = [
        ("aces", SHARED / "slam-benchmark-maps-intel-aces-csail" / "aces.pgm"),
        ("willow-full-0.05", SHARED / "willow-garage-stage-maps" / "willow-full-0.05.pgm"),
    ]
    if all(p.exists() for _, p in shared):
        return [(name, _fit(_load(p), n)) for name, p in shared]
    return [
        ("building_31 x2", _fit(_upsample2(_load(TESTS / "building_31.yaml")), n)),
        ("willow-2010 x2", _fit(_upsample2(_load(TESTS / "willow-2010-02-18-0.10.yaml")), n)),
    ]


def moving_map(ref: np.ndarray, deg: float, shift: tuple[float, float]) -> tuple[np.ndarray, float]:
    """Moving map (same canvas) and the true rotation (deg) of the transform moving -> ref."""
    n = ref.shape[0]
    th = math.radians(deg)
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    c = np.array([(n - 1) / 2, (n - 1) / 2])
    t = c - rot @ c + np.array(shift) * n
    true = RigidTransform(th, t[0], t[1])
    mov = cv2.warpAffine(
        ref.astype(np.int16),
        true.matrix[:2],
        (n, n),
        flags=cv2.INTER_NEAREST | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=-1,
    )
    return mov.astype(np.int8), deg


def angle_error(est_deg: float, true_deg: float) -> float:
    return abs(math.remainder(est_deg - true_deg, 360.0))


# -- the three methods; each returns its estimate of the rotation moving -> reference (deg) ---
def run_ifmi(ref: np.ndarray, mov: np.ndarray) -> float:
    return register(ref, mov).rotation_deg


def run_skimage(ref: np.ndarray, mov: np.ndarray) -> float:
    """scikit-image's documented recipe (gallery: 'Using Polar and Log-Polar Transformations
    for Registration'), with the 180-degree twin decided by the translation error."""
    from skimage.filters import window
    from skimage.registration import phase_cross_correlation
    from skimage.transform import rotate, warp_polar

    a = (ref == 1).astype(float)
    b = (mov == 1).astype(float)
    win = window("hann", a.shape)
    fa = np.abs(scipy.fft.fftshift(scipy.fft.fft2(a * win)))
    fb = np.abs(scipy.fft.fftshift(scipy.fft.fft2(b * win)))
    radius = a.shape[0] // 2
    pa = warp_polar(np.log1p(fa), radius=radius, output_shape=(360, radius))
    pb = warp_polar(np.log1p(fb), radius=radius, output_shape=(360, radius))
    pa, pb = pa[:180, radius // 20 : radius * 8 // 10], pb[:180, radius // 20 : radius * 8 // 10]
    shifts, _, _ = phase_cross_correlation(pa, pb, upsample_factor=10, normalization=None)
    # one polar row per degree; the row shift is the rotation moving -> reference in our
    # convention (checked against known transforms: see the error column)
    angle = float(shifts[0])
    best = None
    for cand in (angle, angle + 180.0):
        # undo the rotation of moving (skimage rotates counter-clockwise for positive angles)
        back = rotate(b, -cand, order=1, preserve_range=True)
        _, err, _ = phase_cross_correlation(a, back, upsample_factor=10, normalization=None)
        if best is None or err < best[0]:
            best = (err, cand)
    assert best is not None
    return math.remainder(best[1], 360.0)


def run_imreg_dft(ref: np.ndarray, mov: np.ndarray) -> float:
    """imreg_dft.similarity with the scale fixed to 1 (it resolves the 180 twin itself)."""
    import imreg_dft

    a = (ref == 1).astype(float)
    b = (mov == 1).astype(float)
    res = imreg_dft.similarity(a, b, numiter=1, constraints={"scale": [1.0, 0.0]})
    return -float(res["angle"])


def timed(
    jobs: dict[str, tuple[Callable[[], float], int]],
) -> dict[str, tuple[float, float, float]]:
    """Per job: (median wall seconds, median CPU seconds of this process, last result).

    The jobs' runs are interleaved (round r runs every job that has more than r repeats),
    so that the drift of a shared virtual machine's speed affects all methods alike. CPU
    time is reported too: under load the wall clock of every method stretches, its CPU time
    much less.
    """
    wall: dict[str, list[float]] = {name: [] for name in jobs}
    cpu: dict[str, list[float]] = {name: [] for name in jobs}
    out: dict[str, float] = {}
    for r in range(max(reps for _, reps in jobs.values())):
        for name, (fn, reps) in jobs.items():
            if r >= reps:
                continue
            w0, c0 = time.perf_counter(), time.process_time()
            out[name] = fn()
            cpu[name].append(time.process_time() - c0)
            wall[name].append(time.perf_counter() - w0)
    return {
        name: (statistics.median(wall[name]), statistics.median(cpu[name]), out[name])
        for name in jobs
    }


def peak_memory(ref: np.ndarray, mov: np.ndarray) -> tuple[int, int]:
    """(peak traced bytes of one register call, padded FFT cells of its spectral stage)."""
    tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    register(ref, mov)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    r = IFMIRegistrar()
    prepared = r.prepare_reference(ref)
    r.candidates(prepared, mov, 4)
    cells = max(p[1] * p[2] for p in prepared.spectra)  # keys: (factor, rows, cols)
    return peak, cells


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--baseline-repeats", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 1024])
    ap.add_argument("--no-imreg-dft", action="store_true")
    ap.add_argument("--out", type=Path, default=None, help="also write the Markdown here")
    ap.add_argument("--threads", type=int, default=1, help="OpenCV threads (default 1)")
    args = ap.parse_args(argv)
    cv2.setNumThreads(args.threads)

    methods: list[tuple[str, Callable[[np.ndarray, np.ndarray], float], int]] = [
        ("ifmi", run_ifmi, args.repeats),
        ("skimage", run_skimage, args.baseline_repeats),
    ]
    if not args.no_imreg_dft:
        try:
            import imreg_dft  # noqa: F401

            methods.append(("imreg_dft", run_imreg_dft, args.baseline_repeats))
        except Exception as exc:  # report precisely why it cannot run
            print(f"imreg_dft unavailable: {type(exc).__name__}: {exc}", file=sys.stderr)

    names = [m for m, _, _ in methods]
    lines = [
        "| size | map | true rot deg | "
        + " | ".join(f"{m} err deg | {m} ms wall | {m} ms CPU" for m in names)
        + " | CPU speed-up vs "
        + " / ".join(names[1:])
        + " |",
        "|" + "---|" * (3 + 3 * len(methods) + 1),
    ]
    summary: dict[str, list[float]] = {m: [] for m in names}
    summary_cpu: dict[str, list[float]] = {m: [] for m in names}
    ratios: dict[str, list[float]] = {m: [] for m in names[1:]}
    worst: dict[str, float] = {m: 0.0 for m in names}
    mem_lines = []
    for n in args.sizes:
        for name, ref in base_maps(n):
            for deg, shift in TRANSFORMS:
                mov, true_deg = moving_map(ref, deg, shift)
                row = [str(n), name, f"{true_deg:.1f}"]
                cpu_of = {}
                results = timed(
                    {
                        mname: (lambda fn=fn, a=ref, b=mov: fn(a, b), reps)
                        for mname, fn, reps in methods
                    }
                )
                for mname, _, _ in methods:
                    sec, cpu, est = results[mname]
                    err = angle_error(est, true_deg)
                    worst[mname] = max(worst[mname], err)
                    cpu_of[mname] = cpu
                    summary[mname].append(sec)
                    summary_cpu[mname].append(cpu)
                    row += [f"{err:.3f}", f"{1000 * sec:.1f}", f"{1000 * cpu:.1f}"]
                for m in names[1:]:
                    ratios[m].append(cpu_of[m] / cpu_of["ifmi"])
                row.append(" / ".join(f"{cpu_of[m] / cpu_of['ifmi']:.0f}x" for m in names[1:]))
                lines.append("| " + " | ".join(row) + " |")
                print(lines[-1], file=sys.stderr, flush=True)
            peak, cells = peak_memory(ref, mov)
            mem_lines.append(
                f"| {n} | {name} | {peak / 2**20:.1f} | {cells} | {peak / cells:.1f} | "
                f"{peak / (n * n):.1f} |"
            )
    out = ["## Registration benchmark", "", *lines, ""]
    out.append(
        "Medians over all cases (wall / CPU): "
        + ", ".join(
            f"{m} {1000 * statistics.median(summary[m]):.1f} / "
            f"{1000 * statistics.median(summary_cpu[m]):.1f} ms"
            for m in names
        )
        + "; CPU speed-up of ifmi (min / median): "
        + ", ".join(
            f"vs {m} {min(v):.0f}x / {statistics.median(v):.0f}x" for m, v in ratios.items()
        )
        + "; worst rotation error: "
        + ", ".join(f"{m} {e:.3f} deg" for m, e in worst.items())
    )
    out += [
        "",
        "### Peak memory of one `register` call (tracemalloc)",
        "",
        "| size | map | peak MiB | padded FFT cells | bytes / padded cell | bytes / map cell |",
        "|---|---|---|---|---|---|",
        *mem_lines,
        "",
    ]
    text = "\n".join(out)
    print(text)
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
