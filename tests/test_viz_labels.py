"""Names on video frames: placed without overlap (each other, the frame counter, the border), legible
at 320x240."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from kinodyn.data import library
from kinodyn.viz import labels, render


def _apart(a, b) -> bool:
    return a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]


def test_labels_at_one_point_stack_without_overlap_inside_the_picture():
    anchors = np.array([[160.0, 60.0]] * 5 + [[5.0, 3.0], [np.nan, np.nan]])
    sizes = np.array([[70, 15]] * 7)
    counter = [2, 2, 120, 18]
    boxes = labels.place_labels(anchors, sizes, 320, 240, [counter])
    shown = boxes[:6]
    assert np.array_equal(boxes[6], [-1, -1, -1, -1])  # behind the camera: no label
    for a, b in itertools.combinations(list(shown) + [counter], 2):
        assert _apart(a, b), f"{a} overlaps {b}"
    assert np.all(shown[:, :2] >= 0) and np.all(shown[:, 2] <= 320) and np.all(shown[:, 3] <= 240)
    assert np.all(shown[:, 2] - shown[:, 0] == 70) and np.all(shown[:, 3] - shown[:, 1] == 15)
    # the lowest first, where it was asked (bottom at the anchor), the others above it, then below
    assert shown[0, 3] == 60


def test_font_grows_with_the_picture():
    assert labels.text_size(240) == 11 and labels.text_size(120) == 9 and labels.text_size(1080) == 16


@pytest.mark.skipif(render.available() is not None, reason="offscreen rendering unavailable")
def test_names_of_characters_in_one_place_do_not_overlap_at_320x240():
    """Three clips in their own coordinates start at the same spot: their names, the frame counter and
    the picture's border stay apart, and each name box holds dark text 11 px high."""
    clips = [library.load(n) for n in ("walk", "run", "punch")]
    world = render.build_world(clips, None, names=["walker", "runner", "boxer"])
    cfg = render.RenderConfig(width=320, height=240, shadows=False)
    with render.Renderer(world, cfg) as r:
        for t in (0.0, 0.6, 1.2):
            img = r.frame(t).copy()
            boxes = r.label_boxes
            assert boxes.shape == (3, 4) and np.all(boxes[:, 0] >= 0)
            assert np.all(boxes[:, 2] <= 320) and np.all(boxes[:, 3] <= 240)
            for a, b in itertools.combinations(boxes, 2):
                assert _apart(a, b), f"labels overlap at {t} s: {a} and {b}"
            for x0, y0, x1, y1 in boxes:
                assert y0 > 18 or x0 > 120  # clear of the frame counter at the top left
                box = img[y0:y1, x0:x1].astype(int)
                dark = box.sum(axis=2) < 450  # darker than mid grey on the light box
                rows = np.nonzero(dark.any(axis=1))[0]
                assert dark.sum() > 25 and rows.max() - rows.min() + 1 >= 6, "legible text (x-height 6 px or more)"
