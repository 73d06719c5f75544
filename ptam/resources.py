"""Locate data files that ship with ptam (configs, synthetic scenes).

In a wheel they are copied into ``ptam/_data``; in a source checkout (editable install) they are read
from the repository root.
"""

from __future__ import annotations

from pathlib import Path

_PKG = Path(__file__).resolve().parent


def resource_path(rel: str) -> Path:
    for base in (_PKG / "_data", _PKG.parent):
        p = base / rel
        if p.exists():
            return p
    raise FileNotFoundError(f"ptam resource missing: {rel}")
