"""Reporting: the partition overlay, the repaired map, result files, comparison tables/plots."""

from .overlay import render_overlay
from .repair import Repair, repair, repair_map, write_repaired
from .results import ResultFileError, ResultRecord, load_results, save_results

__all__ = [
    "Repair",
    "ResultFileError",
    "ResultRecord",
    "load_results",
    "render_overlay",
    "repair",
    "repair_map",
    "save_results",
    "write_repaired",
]
