"""Evaluate many maps: manifests, a resumable parallel runner (processes or Dask)."""

from .manifest import Manifest, ManifestError, Pair, read_manifest
from .runner import BatchSummary, PairOptions, RowResult, evaluate_pair, run_batch

__all__ = [
    "BatchSummary",
    "Manifest",
    "ManifestError",
    "Pair",
    "PairOptions",
    "RowResult",
    "evaluate_pair",
    "read_manifest",
    "run_batch",
]
