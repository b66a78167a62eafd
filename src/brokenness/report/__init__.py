"""Reporting: the partition overlay, the repaired map, result files, comparison tables/plots."""

from .collect import ResultEntry, collect_results
from .overlay import render_overlay
from .plots import comparison_figure, write_plot
from .repair import Repair, repair, repair_map, write_repaired
from .results import ResultFileError, ResultRecord, load_results, save_results
from .tables import GroupTable, group_table, write_table

__all__ = [
    "GroupTable",
    "Repair",
    "ResultEntry",
    "ResultFileError",
    "ResultRecord",
    "collect_results",
    "comparison_figure",
    "group_table",
    "load_results",
    "render_overlay",
    "repair",
    "repair_map",
    "save_results",
    "write_plot",
    "write_repaired",
    "write_table",
]
