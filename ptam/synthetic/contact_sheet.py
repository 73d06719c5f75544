"""A contact sheet of a rendered sequence: evenly spaced frames in a labelled grid (docs/images/two_wall.png)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from ..errors import InputError


def contact_sheet(sequence_dir, out_png, cols: int = 4, rows: int = 3, thumb: tuple[int, int] = (320, 240)) -> Path:
    """Write ``rows`` × ``cols`` thumbnails of the frames listed in ``sequence_dir/rgb.txt``."""
    seq = Path(sequence_dir)
    names = [ln.split()[1] for ln in (seq / "rgb.txt").read_text().splitlines() if ln and not ln.startswith("#")]
    if not names:
        raise InputError(f"{seq}: rgb.txt lists no frames")
    pick = np.linspace(0, len(names) - 1, rows * cols).round().astype(int)
    w, h = thumb
    sheet = np.zeros((rows * h, cols * w), np.uint8)
    for k, i in enumerate(pick):
        img = cv2.imread(str(seq / names[i]), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise InputError(f"cannot read {seq / names[i]}")
        t = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
        cv2.putText(t, f"frame {i}", (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, 0, 3, cv2.LINE_AA)
        cv2.putText(t, f"frame {i}", (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, 255, 1, cv2.LINE_AA)
        r, c = divmod(k, cols)
        sheet[r * h : (r + 1) * h, c * w : (c + 1) * w] = t
    out_png = Path(out_png)
    if not cv2.imwrite(str(out_png), sheet):
        raise InputError(f"cannot write {out_png}")
    return out_png
