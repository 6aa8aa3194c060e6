"""Text drawn on video frames: the frame counter and name labels that never overlap each other.

The page moves a name label up where it would cover one placed before it (the lowest on screen first);
:func:`place_labels` does the same for videos, keeps every label inside the picture and off the frame
counter, and goes below its anchor when there is no room above. :func:`text_size` scales the font with
the picture (11 px at 240 rows, 16 px from 350 rows), so names stay legible at 320x240.

Pixels: x right, y down from the top-left corner; boxes are ``(x0, y0, x1, y1)``, ``x1``/``y1`` excluded.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache

import numpy as np

from kinodyn.plotting import style

__all__ = ["MARGIN", "draw_text", "place_labels", "text_size"]

MARGIN = 2  #: pixels kept free between labels and around the picture's border


def text_size(height: int) -> int:
    """Font size (pixels) for a picture ``height`` rows high: 11 at 240 rows, at most 16, at least 9."""
    return int(min(max(round(height / 22), 9), 16))


@cache
def _font(size: int):
    from PIL import ImageFont

    return ImageFont.load_default(size)


def _overlaps(a, b) -> bool:
    return a[0] < b[2] + MARGIN and b[0] < a[2] + MARGIN and a[1] < b[3] + MARGIN and b[1] < a[3] + MARGIN


def _slide(box, blocks, step: int, height: int):
    """Move ``box`` up (``step < 0``) or down past every block it overlaps; ``None`` when it leaves the
    picture."""
    box = list(box)
    for _ in range(len(blocks) + 1):
        hit = [b for b in blocks if _overlaps(box, b)]
        if not hit:
            return box if box[1] >= MARGIN and box[3] <= height - MARGIN else None
        h = box[3] - box[1]
        if step < 0:
            box[3] = min(b[1] for b in hit) - MARGIN
            box[1] = box[3] - h
        else:
            box[1] = max(b[3] for b in hit) + MARGIN
            box[3] = box[1] + h
    return None


def place_labels(anchors, sizes, width: int, height: int, avoid: Sequence = ()) -> np.ndarray:
    """Boxes of labels above their anchors that overlap neither each other nor ``avoid``.

    Each label is centred on its anchor with its bottom there, kept inside the picture; labels are
    placed from the lowest anchor up, each moved up past the boxes already placed (as the page does),
    else down below its anchor, else left where it is (a picture too small for every name).

    Args:
        anchors: ``(N, 2)`` pixel points (NaN: no label, the point is behind the camera).
        sizes: ``(N, 2)`` label width and height in pixels.
        width, height: the picture.
        avoid: boxes ``(x0, y0, x1, y1)`` to keep clear (the frame counter).

    Returns:
        ``(N, 4)`` int boxes; rows of NaN anchors are ``-1``.
    """
    anchors = np.asarray(anchors, dtype=np.float64).reshape(-1, 2)
    sizes = np.asarray(sizes, dtype=np.float64).reshape(-1, 2)
    out = np.full((len(anchors), 4), -1, dtype=np.int64)
    blocks = [list(b) for b in avoid]
    for i in sorted(np.nonzero(np.all(np.isfinite(anchors), axis=1))[0], key=lambda k: -anchors[k, 1]):
        (x, y), (w, h) = anchors[i], sizes[i]
        x0 = int(round(min(max(x - w / 2, MARGIN), max(width - MARGIN - w, MARGIN))))
        y1 = int(round(min(max(y, h + MARGIN), height - MARGIN)))
        box = [x0, y1 - int(h), x0 + int(w), y1]
        placed = _slide(box, blocks, -1, height) or _slide(box, blocks, 1, height) or box
        blocks.append(placed)
        out[i] = placed
    return out


def draw_text(img: np.ndarray, counter: str | None, names: Sequence[str], colors: Sequence[str],
              anchors) -> tuple[np.ndarray, np.ndarray]:
    """Draw the frame ``counter`` at the top left and each name at its anchor (:func:`place_labels`),
    dark text on a light box with a stripe of the character's colour, as the page's labels.

    Args:
        img: ``(H, W, 3)`` uint8 picture (not modified).
        counter: text of the frame counter, or ``None``.
        names, colors: one per label; anchors: ``(N, 2)`` pixel points above the heads.

    Returns:
        the new ``(H, W, 3)`` uint8 picture and the ``(N, 4)`` label boxes.
    """
    from PIL import Image, ImageDraw

    h, w = img.shape[:2]
    font = _font(text_size(h))
    pil = Image.fromarray(np.ascontiguousarray(img))
    draw = ImageDraw.Draw(pil, "RGBA")
    pad = max(2, text_size(h) // 4)
    avoid = []

    def extent(text):
        x0, y0, x1, y1 = draw.textbbox((0, 0), text, font=font)
        return x1 + 2 * pad + 3, y1 + 2 * pad - max(y0 - 1, 0)

    if counter:
        cw, ch = extent(counter)
        avoid.append([MARGIN, MARGIN, MARGIN + cw, MARGIN + ch])
    boxes = place_labels(anchors, [extent(n) for n in names], w, h, avoid)
    items = [(b, n, c) for b, n, c in zip(boxes, names, colors) if b[0] >= 0]
    if counter:
        items.append((avoid[0], counter, None))
    for (x0, y0, x1, y1), text, col in items:
        draw.rectangle((x0, y0, x1 - 1, y1 - 1), fill=(255, 255, 255, 215))
        if col is not None:
            draw.rectangle((x0, y0, x0 + 2, y1 - 1), fill=tuple(int(v * 255) for v in style.rgb(col)))
        ty = y0 + pad - max(draw.textbbox((0, 0), text, font=font)[1] - 1, 0)
        draw.text((x0 + pad + 3, ty), text, fill=(34, 34, 34), font=font)
    return np.array(pil), boxes
