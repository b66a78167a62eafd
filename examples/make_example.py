"""Make the bundled example: MIT building 31 broken into three partitions on purpose.

Run from the repository root (``python examples/make_example.py``); it rewrites
``examples/broken_building_31.{yaml,png}`` and ``examples/broken_building_31_truth.json``.
The right part of the map is turned by 8 degrees and the right-most part by -15 degrees
more, as if the robot's pose had jumped twice: the expected degree of brokenness is 2.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np

from brokenness import OccupancyMap, RigidTransform, load_map, save_map
from brokenness.grid import FREE, OCCUPIED, UNKNOWN

HERE = Path(__file__).parent


def rotation_about(x: float, y: float, degrees: float, dx: float, dy: float) -> RigidTransform:
    """Rotation by ``degrees`` about cell ``(x, y)`` followed by a shift (reference -> map)."""
    t = np.radians(degrees)
    c, s = np.cos(t), np.sin(t)
    return RigidTransform(t, x - (c * x - s * y) + dx, y - (s * x + c * y) + dy)


def main() -> None:
    ref = load_map(HERE / "building_31.yaml")
    h, w = ref.shape
    pad = 60
    cuts = [0, int(0.45 * w), int(0.75 * w), w]
    motions = [
        RigidTransform(),
        rotation_about(0.6 * w, 0.5 * h, 8.0, 6.0, -10.0),
        rotation_about(0.87 * w, 0.5 * h, -15.0, -12.0, 8.0),
    ]
    shift = RigidTransform(0.0, pad, pad)
    H, W = h + 2 * pad, w + 2 * pad
    occupied = np.zeros((H, W), bool)
    free = np.zeros((H, W), bool)
    for (a, b), motion in zip(zip(cuts[:-1], cuts[1:], strict=True), motions, strict=True):
        piece = np.zeros((h, w), np.uint8)
        piece[:, a:b] = (ref.states[:, a:b] + 2).astype(np.uint8)  # 1 unknown, 2 free, 3 occupied
        moved = cv2.warpAffine(
            piece, shift.compose(motion).matrix[:2], (W, H), flags=cv2.INTER_NEAREST
        )
        occupied |= moved == OCCUPIED + 2
        free |= moved == FREE + 2
    states = np.full((H, W), UNKNOWN, np.int8)
    states[free] = FREE
    states[occupied] = OCCUPIED
    res = ref.resolution
    origin = (ref.origin[0] - pad * res, ref.origin[1] - pad * res, 0.0)
    broken = OccupancyMap(states, res, origin)
    save_map(broken, HERE / "broken_building_31.yaml", image_format="png")
    truth = {
        "expected_degree": 2,
        "note": "transforms map cells of the broken map onto the reference (brokenness convention)",
        "partitions": [
            shift.compose(m).inverse().with_world(broken, ref).to_dict() for m in motions
        ],
    }
    (HERE / "broken_building_31_truth.json").write_text(json.dumps(truth, indent=2) + "\n")


if __name__ == "__main__":
    main()
