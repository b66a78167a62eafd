"""Strict YAML parsing: PyYAML's safe loader, duplicate keys refused, every failure typed.

PyYAML raises more than :class:`yaml.YAMLError` on hostile documents: an explicitly tagged
empty integer (``!!int``) raises ``IndexError``, ``!!float nen`` a ``ValueError``, deeply
nested flow collections a ``RecursionError``, a ``!!timestamp`` out of range an
``OverflowError``... :func:`parse_yaml` turns all of them into one
:class:`~brokenness.errors.MapFormatError` naming the file, and refuses a mapping that
repeats a key (YAML 1.2 forbids it; PyYAML silently keeps the last value).
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any

import yaml

from ..errors import BrokennessError, MapFormatError
from ._files import one_line

__all__ = ["DuplicateKeyError", "parse_yaml"]


class DuplicateKeyError(yaml.YAMLError):
    """A YAML mapping names the same key twice."""


class _StrictLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses duplicate keys (merge keys ``<<`` still override)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Hashable] = set()
        for key_node, _value in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue
            key = self.construct_object(key_node, deep=False)  # type: ignore[no-untyped-call]
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: construct_mapping reports it
                continue
            if duplicate:
                mark = key_node.start_mark
                raise DuplicateKeyError(
                    f"duplicate key {key!r} (line {mark.line + 1}, column {mark.column + 1})"
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


def parse_yaml(data: bytes | str, name: str) -> Any:
    """Parse one YAML document with the safe loader; every failure is a MapFormatError.

    Parameters
    ----------
    data : bytes or str
        The document.
    name : str
        The file, for messages.

    Returns
    -------
    object
        Plain Python data (dict, list, str, int, float, bool, None, date...).

    Raises
    ------
    MapFormatError
        Invalid YAML, a duplicate key, a bad explicitly tagged value, text that is not UTF-8,
        nesting too deep.

    Examples
    --------
    >>> parse_yaml(b"resolution: 0.05", "m.yaml")
    {'resolution': 0.05}
    >>> parse_yaml(b"a: 1\\na: 2", "m.yaml")
    Traceback (most recent call last):
    ...
    brokenness.errors.MapFormatError: m.yaml: invalid YAML (duplicate key 'a' (line 2, column 1))
    """
    try:
        return yaml.load(data, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except BrokennessError:
        raise
    except RecursionError:
        raise MapFormatError(f"{name}: invalid YAML (nested too deeply)") from None
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise MapFormatError(f"{name}: invalid YAML ({one_line(exc)})") from None
    except Exception as exc:  # PyYAML's constructors raise ValueError, IndexError, ...
        reason = f"{type(exc).__name__}: {one_line(exc)}"
        raise MapFormatError(f"{name}: invalid YAML value ({reason})") from None
