"""The interface shared by every frame source: an iterable of :class:`Frame` with ``fps``, ``size`` and
``length`` (None for a live camera), closed explicitly or by a ``with`` block."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterator

from .frame import Frame


class FrameSource(ABC):
    name: str
    fps: float
    size: tuple[int, int]
    length: int | None

    @abstractmethod
    def __iter__(self) -> Iterator[Frame]:
        """Frames in order, read lazily one per step."""

    @abstractmethod
    def close(self) -> None:
        """Release the underlying file or device."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        w, h = self.size
        n = "live" if self.length is None else f"{self.length} frames"
        return f"{type(self).__name__}({self.name!r}, {w}x{h}, {self.fps:g} fps, {n})"
