"""The allowed values of a numeric config field, in interval notation (see ``sections``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

_ENDS = {"inf": math.inf, "-inf": -math.inf, "pi": math.pi}


@dataclass(frozen=True)
class Range:
    """The allowed values of a numeric config field, e.g. ``Range("(0, inf)")`` or ``Range("[0, 1]")``."""

    interval: str
    length: int | None = None  # list fields: the number of elements, if fixed
    lo: float = field(init=False)
    hi: float = field(init=False)
    lo_closed: bool = field(init=False)
    hi_closed: bool = field(init=False)

    def __post_init__(self) -> None:
        text = self.interval.strip()
        ends = [e.strip() for e in text[1:-1].split(",")]
        if text[:1] not in ("[", "(") or text[-1:] not in ("]", ")") or len(ends) != 2:
            raise ValueError(f"Range: expected an interval like '[0, inf)', got {self.interval!r}")
        lo, hi = (_ENDS[e] if e in _ENDS else float(e) for e in ends)
        if not lo < hi:
            raise ValueError(f"Range: empty interval {self.interval!r}")
        for name, value in (("lo", lo), ("hi", hi), ("lo_closed", text[0] == "["), ("hi_closed", text[-1] == "]")):
            object.__setattr__(self, name, value)

    def __contains__(self, value: float) -> bool:
        above = value >= self.lo if self.lo_closed else value > self.lo
        below = value <= self.hi if self.hi_closed else value < self.hi
        return bool(above and below)  # NaN: both comparisons are false

    def __str__(self) -> str:
        return self.interval
