"""Events of a timeline: where the degree rises (a break) and where it falls (a repair).

Frames are compared with the last *measured* frame before them (frames not measured are
neither a break nor a repair). When the degree rises, the new partitions are those of the
later frame that match no partition of the earlier one (same rotation within
``rotation_tol`` degrees and translation within ``translation_tol`` metres -- or
``translation_tol / resolution`` cells when the maps have no geometry); the largest
partition is never new. When matching cannot tell (every partition matches one before), the
smallest partitions are taken, as many as the degree rose. A repair reports the partitions of
the earlier frame that match none of the later one, the same way.
"""

from __future__ import annotations

from collections.abc import Sequence

from .frames import EVENT_BREAK, EVENT_REPAIR, TimelineEvent, TimelineFrame, TimelinePartition

__all__ = ["ROTATION_TOL_DEG", "TRANSLATION_TOL_CELLS", "TRANSLATION_TOL_M", "find_events"]

#: Two partitions of consecutive frames are the same part of the map when their transforms
#: differ by less than this rotation ...
ROTATION_TOL_DEG = 4.0
#: ... and this translation (world, metres) ...
TRANSLATION_TOL_M = 0.3
#: ... or this one in cells, when a transform has no world part.
TRANSLATION_TOL_CELLS = 6.0


def _angle_diff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def same_part(a: TimelinePartition, b: TimelinePartition) -> bool:
    """Whether two partitions (of two frames) carry the same transform."""
    if a.translation_m is not None and b.translation_m is not None:
        ra = a.rotation_deg_world if a.rotation_deg_world is not None else -a.rotation_deg
        rb = b.rotation_deg_world if b.rotation_deg_world is not None else -b.rotation_deg
        dx = a.translation_m[0] - b.translation_m[0]
        dy = a.translation_m[1] - b.translation_m[1]
        return (
            _angle_diff(ra, rb) < ROTATION_TOL_DEG
            and (dx * dx + dy * dy) ** 0.5 < TRANSLATION_TOL_M
        )
    dx = a.translation[0] - b.translation[0]
    dy = a.translation[1] - b.translation[1]
    return (
        _angle_diff(a.rotation_deg, b.rotation_deg) < ROTATION_TOL_DEG
        and (dx * dx + dy * dy) ** 0.5 < TRANSLATION_TOL_CELLS
    )


def _unmatched(
    parts: Sequence[TimelinePartition], others: Sequence[TimelinePartition], n: int
) -> tuple[TimelinePartition, ...]:
    """At least ``n`` partitions of ``parts`` (never the largest) that ``others`` lacks."""
    candidates = [p for p in parts[1:] if not any(same_part(p, q) for q in others)]
    if len(candidates) < n:  # matching cannot tell: the smallest ones
        rest = [p for p in reversed(parts[1:]) if p not in candidates]
        candidates += rest[: n - len(candidates)]
    return tuple(sorted(candidates, key=lambda p: p.index))


def find_events(frames: Sequence[TimelineFrame]) -> tuple[TimelineEvent, ...]:
    """The breaks and repairs of a sequence of frames (in message order).

    The first measured frame is a break when it is already broken (``degree_before`` is then
    ``None``: the change happened before anything was measured). A break's ``settled``
    partitions are those of the last frame of the same degree that match no partition of
    the frame before the break.
    """
    measured = [f for f in frames if f.measured and f.degree is not None]
    events: list[TimelineEvent] = []
    for i, f in enumerate(measured):
        assert f.degree is not None
        prev = measured[i - 1] if i else None
        before = None if prev is None else prev.degree
        old = () if prev is None else prev.partitions
        if (before is None and f.degree > 0) or (before is not None and f.degree > before):
            rise = f.degree - (before or 0)
            last = f
            for g in measured[i + 1 :]:
                if g.degree != f.degree:
                    break
                last = g
            new = _unmatched(f.partitions, old, rise)
            settled = _unmatched(last.partitions, old, rise)
            events.append(_event(EVENT_BREAK, f, prev, new, settled, last.message_index))
        elif before is not None and prev is not None and f.degree < before:
            gone = _unmatched(prev.partitions, f.partitions, before - f.degree)
            events.append(_event(EVENT_REPAIR, f, prev, gone))
    return tuple(events)


def _event(
    kind: str,
    f: TimelineFrame,
    prev: TimelineFrame | None,
    parts: tuple[TimelinePartition, ...],
    settled: tuple[TimelinePartition, ...] = (),
    settled_index: int | None = None,
) -> TimelineEvent:
    assert f.degree is not None
    return TimelineEvent(
        kind=kind,
        message_index=f.message_index,
        stamp_ns=f.stamp_ns,
        time=f.time,
        after_message_index=None if prev is None else prev.message_index,
        degree_before=None if prev is None else prev.degree,
        degree_after=f.degree,
        partitions=parts,
        settled=settled,
        settled_message_index=settled_index,
    )
