"""Write a simulated broken map and its ground truth to files.

For ``name`` in ``out_dir``: ``name.yaml`` + ``name.pgm`` (the broken map) and
``name_reference.yaml`` + ``name_reference.pgm`` (ROS ``map_server`` format, via
:func:`brokenness.save_map`), ``name.json`` (seed, parameters, bumps, expected degree, each
partition's transform and share) and ``name_labels.npy`` (int16: the partition that drew
each occupied cell of the broken map, -1 elsewhere). The same simulation gives byte-identical
files.
"""

from __future__ import annotations

import io
import json
import os
from pathlib import Path

import numpy as np

from .._atomic import atomic_write_bytes
from ..errors import MapError, ParameterError
from ..io import save_map
from ..io._files import as_path
from .ground_truth import SimulatedMap

__all__ = ["save_simulation"]

_NAME_OK = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-")


def save_simulation(
    sim: SimulatedMap, out_dir: str | os.PathLike[str], name: str
) -> dict[str, Path]:
    """Write the broken map, the reference, the ground-truth JSON and the label image.

    Parameters
    ----------
    sim : SimulatedMap
    out_dir : path-like
        Created if missing.
    name : str
        File stem: letters, digits, ``.``, ``_``, ``-``.

    Returns
    -------
    dict
        ``{"map", "reference", "truth", "labels"}`` -> path written (YAML for the maps).

    Raises
    ------
    ParameterError
        For an empty name or one with other characters, or an ``out_dir`` that is no path.
    MapError
        If the folder cannot be made (a file of that name, no permission).
    """
    if not name or not set(name) <= _NAME_OK or name.startswith("."):
        raise ParameterError(f"name must be letters, digits, '.', '_', '-', got {name!r}")
    out = as_path(out_dir, "out_dir")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:  # a file where the folder should be, no permission...
        raise MapError(f"{out}: cannot make the folder ({exc.strerror or exc})") from None
    paths = {
        "map": out / f"{name}.yaml",
        "reference": out / f"{name}_reference.yaml",
        "truth": out / f"{name}.json",
        "labels": out / f"{name}_labels.npy",
    }
    save_map(sim.map, paths["map"])
    save_map(sim.reference, paths["reference"])
    truth = sim.to_dict()
    truth["files"] = {k: p.name for k, p in paths.items() if k != "truth"}
    truth["files"]["map_image"] = f"{name}.pgm"
    truth["files"]["reference_image"] = f"{name}_reference.pgm"
    text = json.dumps(truth, indent=2, sort_keys=True, allow_nan=False) + "\n"
    atomic_write_bytes(paths["truth"], text.encode("utf-8"))
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(sim.labels, dtype=np.int16), allow_pickle=False)
    atomic_write_bytes(paths["labels"], buf.getvalue())
    return paths
