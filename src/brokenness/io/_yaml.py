"""Strict YAML parsing: PyYAML's safe loader, duplicate keys and aliases refused, every
failure typed.

This is the one YAML reader of the package: map YAMLs, rosbag2 ``metadata.yaml`` files and
batch manifests all go through :func:`parse_yaml`.

PyYAML raises more than :class:`yaml.YAMLError` on hostile documents: an explicitly tagged
empty integer (``!!int``) raises ``IndexError``, ``!!float nen`` a ``ValueError``, deeply
nested flow collections a ``RecursionError``, a ``!!timestamp`` out of range an
``OverflowError``... :func:`parse_yaml` turns all of them into one
:class:`~brokenness.errors.MapFormatError` naming the file, and refuses a mapping that
repeats a key (YAML 1.2 forbids it; PyYAML silently keeps the last value).

Aliases (``*name``, which repeat the node an anchor ``&name`` marks) are refused: none of
these files needs them, and nested aliases make a document of a few hundred bytes stand for
billions of values ("billion laughs"), which any code that walks, prints or copies the value
would expand. The refusal happens while the document is composed, before any value is built.
"""

from __future__ import annotations

from collections.abc import Hashable
from typing import Any

import yaml

from ..errors import BrokennessError, MapFormatError
from ._files import REASON_CHARS, one_line, shown

__all__ = ["AliasError", "DuplicateKeyError", "parse_yaml"]


class DuplicateKeyError(yaml.YAMLError):
    """A YAML mapping names the same key twice."""


class AliasError(yaml.YAMLError):
    """A YAML document uses an alias (``*name``)."""


class _StrictLoader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that refuses aliases and duplicate keys (merge keys ``<<`` still
    override, but need an alias, so are refused in practice)."""

    def compose_node(self, parent: yaml.Node | None, index: int) -> yaml.Node | None:
        if self.check_event(yaml.AliasEvent):  # type: ignore[no-untyped-call]
            event = self.peek_event()  # type: ignore[no-untyped-call]
            mark = event.start_mark
            raise AliasError(
                f"alias *{one_line(event.anchor, 40)} (line {mark.line + 1}, column "
                f"{mark.column + 1}): anchors and aliases are not supported"
            )
        return super().compose_node(parent, index)  # type: ignore[no-untyped-call,no-any-return]

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
                    f"duplicate key {shown(key)} (line {mark.line + 1}, column {mark.column + 1})"
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
        The file, for messages (as :func:`~brokenness.io._files.path_text` shows it).

    Returns
    -------
    object
        Plain Python data (dict, list, str, int, float, bool, None, date...).

    Raises
    ------
    MapFormatError
        Invalid YAML, a duplicate key, an alias (``*name``), a bad explicitly tagged value,
        text that is not UTF-8, nesting too deep. The message is one line of bounded length.

    Examples
    --------
    >>> parse_yaml(b"resolution: 0.05", "m.yaml")
    {'resolution': 0.05}
    >>> parse_yaml(b"a: 1\\na: 2", "m.yaml")
    Traceback (most recent call last):
    ...
    brokenness.errors.MapFormatError: m.yaml: invalid YAML (duplicate key 'a' (line 2, column 1))
    >>> parse_yaml(b"a: &x 1\\nb: *x", "m.yaml")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    brokenness.errors.MapFormatError: m.yaml: invalid YAML (alias *x (line 2, column 4): ...)
    """
    try:
        return yaml.load(data, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except BrokennessError:
        raise
    except RecursionError:
        raise MapFormatError(f"{name}: invalid YAML (nested too deeply)") from None
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise MapFormatError(f"{name}: invalid YAML ({one_line(exc, REASON_CHARS)})") from None
    except Exception as exc:  # PyYAML's constructors raise ValueError, IndexError, ...
        reason = one_line(f"{type(exc).__name__}: {exc}", REASON_CHARS)
        raise MapFormatError(f"{name}: invalid YAML value ({reason})") from None
