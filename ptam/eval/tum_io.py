"""TUM trajectory files: one pose per line, ``t tx ty tz qx qy qz qw``, camera-to-world (T_wc), ``#`` comments.

Written with every digit a float64 holds (timestamps to the nanosecond), so a write/read round trip is exact
to float precision.
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import InputError
from ..geometry import so3

_FIELDS = 8


def read_tum(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Timestamps (N,) in seconds and camera-to-world poses T_wc (N, 4, 4), in file order.

    Fields may be separated by spaces, tabs or commas (as TUM's own tools accept).
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise InputError(f"trajectory file not found: {path}")
    try:
        with open(path) as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError) as e:
        raise InputError(f"cannot read trajectory {path}: {e}") from None
    rows, linenos = [], []
    for lineno, line in enumerate(lines, 1):
        text = line.split("#", 1)[0].replace(",", " ").strip()
        if not text:
            continue
        try:
            row = [float(v) for v in text.split()]
        except ValueError:
            row = []
        if len(row) != _FIELDS or not np.all(np.isfinite(row)):
            raise InputError(f"{path}:{lineno}: expected 't tx ty tz qx qy qz qw', got {line.strip()!r}")
        if not np.any(row[4:]):
            raise InputError(f"{path}:{lineno}: zero quaternion")
        rows.append(row)
        linenos.append(lineno)
    data = np.array(rows, dtype=np.float64).reshape(-1, _FIELDS)
    back = np.flatnonzero(np.diff(data[:, 0]) <= 0)
    if back.size:
        i = back[0] + 1
        raise InputError(
            f"{path}:{linenos[i]}: timestamp {data[i, 0]:.9f} is not after the previous pose's "
            f"{data[i - 1, 0]:.9f} (timestamps must increase strictly)"
        )
    T = np.zeros((len(data), 4, 4))
    T[:, :3, :3] = so3.from_quaternion(data[:, 4:])
    T[:, :3, 3] = data[:, 1:4]
    T[:, 3, 3] = 1.0
    return data[:, 0], T


def write_tum(path: str | os.PathLike, timestamps: np.ndarray, T_wc: np.ndarray, header: str | None = None) -> None:
    """Write camera-to-world poses T_wc (N, 4, 4) stamped ``timestamps`` (N,) seconds."""
    t = np.asarray(timestamps, dtype=np.float64).reshape(-1)
    T_wc = np.asarray(T_wc, dtype=np.float64).reshape(-1, 4, 4)
    if len(t) != len(T_wc):
        raise ValueError(f"write_tum: {len(t)} timestamps for {len(T_wc)} poses")
    values = np.concatenate([T_wc[:, :3, 3], so3.to_quaternion(T_wc[:, :3, :3])], axis=1)
    lines = [f"# {h}\n" for h in (header or "").splitlines()]
    lines.append("# timestamp tx ty tz qx qy qz qw (camera-to-world)\n")
    # repr() is the shortest text that reads back as the same float64.
    lines.extend(f"{ti:.9f} " + " ".join(repr(float(v)) for v in row) + "\n" for ti, row in zip(t, values))
    with open(path, "w") as f:
        f.writelines(lines)
