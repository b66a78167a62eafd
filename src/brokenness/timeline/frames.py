"""What a timeline is made of: frames (one per map message), their partitions, events."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..measure.result import BrokennessResult, Partition

__all__ = [
    "EVENT_BREAK",
    "EVENT_REPAIR",
    "TimelineEvent",
    "TimelineFrame",
    "TimelinePartition",
    "TimelineResult",
]

#: A new partition appeared: the degree rose.
EVENT_BREAK = "break"
#: A partition disappeared: the degree fell (a loop closure repaired the map).
EVENT_REPAIR = "repair"


def _pair(value: Any) -> tuple[float, float] | None:
    return None if value is None else (float(value[0]), float(value[1]))


@dataclass(frozen=True)
class TimelinePartition:
    """One partition of one frame (a :class:`~brokenness.Partition` without its step time).

    Attributes
    ----------
    index : int
        0 for the largest.
    cells : int
    fraction : float
        Share of the map's occupied cells.
    rotation_deg : float
        Rotation of its transform (map cell -> reference cell), degrees.
    translation : (float, float)
        Translation of its transform, reference cells.
    translation_m : (float, float) or None
        The world translation, metres (when both maps have geometry).
    rotation_deg_world : float or None
        The world rotation, degrees counter-clockwise.
    confidence : float
    rotation_offset_deg : float
        Rotation relative to the largest partition, degrees.
    displacement : float
        Mean distance of its cells between its transform and the largest's, cells.
    displacement_m : float or None
        The same in metres.
    """

    index: int
    cells: int
    fraction: float
    rotation_deg: float
    translation: tuple[float, float]
    translation_m: tuple[float, float] | None
    rotation_deg_world: float | None
    confidence: float
    rotation_offset_deg: float
    displacement: float
    displacement_m: float | None

    @classmethod
    def from_partition(cls, p: Partition) -> TimelinePartition:
        """From a partition of a :class:`~brokenness.BrokennessResult`."""
        return cls.from_dict(p.to_dict())

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TimelinePartition:
        """From :meth:`Partition.to_dict`, ``stats.json`` or :meth:`to_dict`."""
        t = d.get("transform") or {}
        world = t.get("world") or {}
        return cls(
            index=int(d["index"]),
            cells=int(d["cells"]),
            fraction=float(d["fraction"]),
            rotation_deg=float(t.get("rotation_deg", d.get("rotation_deg", 0.0))),
            translation=_pair(t.get("translation_cells", d.get("translation"))) or (0.0, 0.0),
            translation_m=_pair(world.get("translation_m", d.get("translation_m"))),
            rotation_deg_world=(
                float(world["rotation_deg"])
                if "rotation_deg" in world
                else d.get("rotation_deg_world")
            ),
            confidence=float(d.get("confidence", 0.0)),
            rotation_offset_deg=float(d.get("rotation_offset_deg", 0.0)),
            displacement=float(d.get("displacement_cells", d.get("displacement", 0.0))),
            displacement_m=(
                None if d.get("displacement_m") is None else float(d["displacement_m"])
            ),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "index": self.index,
            "cells": self.cells,
            "fraction": self.fraction,
            "rotation_deg": self.rotation_deg,
            "translation": list(self.translation),
            "translation_m": None if self.translation_m is None else list(self.translation_m),
            "rotation_deg_world": self.rotation_deg_world,
            "confidence": self.confidence,
            "rotation_offset_deg": self.rotation_offset_deg,
            "displacement": self.displacement,
            "displacement_m": self.displacement_m,
        }


@dataclass(frozen=True)
class TimelineFrame:
    """The brokenness of one map message.

    Attributes
    ----------
    message_index : int
        Position of the message on its topic (0-based, counting the thinned-out ones too).
    stamp_ns : int
        Bag time of the message, nanoseconds.
    time : float
        Seconds since the first message on the topic.
    header_stamp : float or None
        ``header.stamp`` of the message, seconds.
    measured : bool
        False when the degree was not measured: too little mapped yet, no part of the map
        agrees with the reference, or an error (``error``). Then ``degree`` is ``None``.
    degree : int or None
    reason : str or None
        Why it was not measured.
    partitions : tuple of TimelinePartition
        Largest first.
    occupied_cells : int
        Occupied cells of the map.
    unassigned_cells : int
    seconds : float
        Time spent on this frame (0 when reused).
    digest : str
        Hash of the map (states, shape, resolution, origin).
    same_as : int or None
        ``message_index`` of the earlier frame whose identical map this one reuses.
    result_file : str or None
        Name of its result zip (``--save-results``), when written.
    resumed : bool
        Read back from a result zip of an earlier run instead of computed.
    error : str or None
        One-line message when computing failed.
    """

    message_index: int
    stamp_ns: int
    time: float
    header_stamp: float | None
    measured: bool
    degree: int | None
    reason: str | None
    partitions: tuple[TimelinePartition, ...]
    occupied_cells: int
    unassigned_cells: int
    seconds: float
    digest: str
    same_as: int | None = None
    result_file: str | None = None
    resumed: bool = False
    error: str | None = None

    @property
    def largest_fraction(self) -> float | None:
        """Share of the largest partition (``None`` when not measured)."""
        if not self.measured or not self.partitions:
            return None
        return self.partitions[0].fraction

    @property
    def unassigned_fraction(self) -> float:
        """Share of the occupied cells in no partition."""
        return self.unassigned_cells / self.occupied_cells if self.occupied_cells else 0.0

    @classmethod
    def from_result(
        cls,
        result: BrokennessResult,
        *,
        message_index: int,
        stamp_ns: int,
        time: float,
        header_stamp: float | None,
        digest: str,
        seconds: float,
        result_file: str | None = None,
    ) -> TimelineFrame:
        """From the result of :func:`brokenness.compute_brokenness` for the message's map."""
        return cls(
            message_index=message_index,
            stamp_ns=stamp_ns,
            time=time,
            header_stamp=header_stamp,
            measured=result.measured,
            degree=result.degree,
            reason=result.reason,
            partitions=tuple(TimelinePartition.from_partition(p) for p in result.partitions),
            occupied_cells=result.occupied_cells,
            unassigned_cells=result.unassigned_cells,
            seconds=seconds,
            digest=digest,
            result_file=result_file,
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "message_index": self.message_index,
            "stamp_ns": self.stamp_ns,
            "time": self.time,
            "header_stamp": self.header_stamp,
            "measured": self.measured,
            "degree": self.degree,
            "reason": self.reason,
            "largest_fraction": self.largest_fraction,
            "partitions": [p.to_dict() for p in self.partitions],
            "occupied_cells": self.occupied_cells,
            "unassigned_cells": self.unassigned_cells,
            "seconds": self.seconds,
            "digest": self.digest,
            "same_as": self.same_as,
            "result_file": self.result_file,
            "resumed": self.resumed,
            "error": self.error,
        }


@dataclass(frozen=True)
class TimelineEvent:
    """A change of the degree between two measured frames.

    Attributes
    ----------
    kind : str
        :data:`EVENT_BREAK` (the degree rose) or :data:`EVENT_REPAIR` (it fell).
    message_index, stamp_ns, time
        Of the frame where the change is first seen.
    after_message_index : int or None
        The last measured frame before it (the change happened in between); ``None`` when
        the first measured frame is already broken.
    degree_before : int or None
    degree_after : int
    partitions : tuple of TimelinePartition
        For a break, the new partitions (as in the frame where they appear: share, rotation
        offset and displacement against the largest partition); for a repair, the
        partitions of the previous frame that are gone.
    settled : tuple of TimelinePartition
        For a break: the new partitions as they stand in the last frame of the same
        degree (before the degree changes again, or at the end). A partition first seen
        small may be registered at a wrong place; with more of it mapped it settles.
        Empty for a repair.
    settled_message_index : int or None
        The frame of ``settled``.
    """

    kind: str
    message_index: int
    stamp_ns: int
    time: float
    after_message_index: int | None
    degree_before: int | None
    degree_after: int
    partitions: tuple[TimelinePartition, ...] = field(default=())
    settled: tuple[TimelinePartition, ...] = field(default=())
    settled_message_index: int | None = None

    def describe(self) -> str:
        """One line for people."""
        before = "?" if self.degree_before is None else str(self.degree_before)
        head = (
            f"t={self.time:.1f} s (message {self.message_index}): {self.kind}, "
            f"degree {before} -> {self.degree_after}"
        )
        text = head + "".join(f"; {_describe(p)}" for p in self.partitions)
        if self.settled and self.settled_message_index != self.message_index:
            later = "; ".join(_describe(p) for p in self.settled)
            text += f" (message {self.settled_message_index}: {later})"
        return text

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "kind": self.kind,
            "message_index": self.message_index,
            "stamp_ns": self.stamp_ns,
            "time": self.time,
            "after_message_index": self.after_message_index,
            "degree_before": self.degree_before,
            "degree_after": self.degree_after,
            "partitions": [p.to_dict() for p in self.partitions],
            "settled": [p.to_dict() for p in self.settled],
            "settled_message_index": self.settled_message_index,
        }


def _describe(p: TimelinePartition) -> str:
    shift = (
        f"{p.displacement_m:.2f} m"
        if p.displacement_m is not None
        else f"{p.displacement:.1f} cells"
    )
    return f"{p.fraction:.1%} of the map, {p.rotation_offset_deg:+.1f} deg, {shift} off"


@dataclass(frozen=True)
class TimelineResult:
    """Brokenness over a run: one frame per map message kept, and the events.

    Attributes
    ----------
    bag, topic, reference : str
    frames : tuple of TimelineFrame
        In message order.
    events : tuple of TimelineEvent
    parameters : dict
        Thinning, the not-measured rule and the ``compute_brokenness`` options.
    seconds : float
        Wall-clock time of the whole timeline.
    """

    bag: str
    topic: str
    reference: str
    frames: tuple[TimelineFrame, ...]
    events: tuple[TimelineEvent, ...]
    parameters: dict[str, Any] = field(default_factory=dict, hash=False)
    seconds: float = 0.0

    @property
    def measured_frames(self) -> tuple[TimelineFrame, ...]:
        """The frames whose degree was measured."""
        return tuple(f for f in self.frames if f.measured)

    @property
    def final_degree(self) -> int | None:
        """Degree of the last frame (``None`` when not measured)."""
        return self.frames[-1].degree if self.frames else None

    @property
    def first_break(self) -> TimelineEvent | None:
        """The first event where the degree rose, if any."""
        return next((e for e in self.events if e.kind == EVENT_BREAK), None)

    def count(self, what: str) -> int:
        """Frames ``"measured"``, ``"not measured"``, ``"reused"``, ``"resumed"``, ``"error"``."""
        tests = {
            "measured": lambda f: f.measured,
            "not measured": lambda f: not f.measured,
            "reused": lambda f: f.same_as is not None,
            "resumed": lambda f: f.resumed,
            "error": lambda f: f.error is not None,
        }
        return sum(1 for f in self.frames if tests[what](f))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dictionary."""
        return {
            "format": "brokenness-timeline",
            "bag": self.bag,
            "topic": self.topic,
            "reference": self.reference,
            "parameters": dict(self.parameters),
            "seconds": self.seconds,
            "final_degree": self.final_degree,
            "events": [e.to_dict() for e in self.events],
            "frames": [f.to_dict() for f in self.frames],
        }
