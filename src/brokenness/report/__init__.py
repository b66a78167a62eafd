"""Reporting: the partition overlay, the repaired map, result files, comparison tables/plots.

The matplotlib parts (:func:`render_overlay`, :func:`comparison_figure`,
:func:`write_plot`) are imported on first use, so that writing result files (a batch's
workers, with the fast overlay) never loads matplotlib.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .collect import ResultEntry, collect_results
from .repair import Repair, repair, repair_map, write_repaired
from .results import ResultFileError, ResultRecord, load_results, save_results
from .tables import GroupTable, group_table, write_table

if TYPE_CHECKING:
    from .overlay import render_overlay
    from .plots import comparison_figure, write_plot

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

_LAZY = {"render_overlay": "overlay", "comparison_figure": "plots", "write_plot": "plots"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        from importlib import import_module

        return getattr(import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
