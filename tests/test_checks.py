"""``vpr_core.checks``: each one-line check returns the parsed value or raises one clear line."""

from __future__ import annotations

import numpy as np
import pytest

from vpr_core.checks import (
    check_boxes,
    check_choice,
    check_image,
    check_image_size,
    check_int,
    check_range,
    check_shape,
)


def test_checks_return_the_parsed_value():
    assert check_boxes([]).shape == (0, 4)
    b = check_boxes([[1, 2, 3, 4]])
    assert b.dtype == np.float64 and b.tolist() == [[1.0, 2.0, 3.0, 4.0]]
    assert check_boxes(b) is b  # already parsed: no copy
    img = np.zeros((4, 5, 3), np.uint8)
    assert check_image(img) is img
    assert check_image_size(img.shape) == (4, 5) and check_image_size((4.0, 5)) == (4, 5)
    assert check_shape(np.zeros((2, 3, 3)), "N 3 3").shape == (2, 3, 3)
    assert check_shape([[1, 2]], "P 2", dtype=np.int64).dtype == np.int64
    assert check_int(3.0) == 3 and isinstance(check_int(np.int64(2)), int)
    assert check_range("0.5", "t", 0, 1) == 0.5 and check_range(1, "t", 0, 1) == 1.0
    assert check_choice("b", "mode", ("a", "b")) == "b"


GRAY = np.zeros((4, 5), np.uint8)

#: id -> (call, exception, message)
BAD_CHECK_CALLS = {
    "boxes: shape": (
        lambda: check_boxes(np.zeros((2, 5)), "cand"),
        ValueError,
        r"cand must have shape \(K, 4\) as \(x, y, w, h\), got \(2, 5\)",
    ),
    "boxes: NaN": (
        lambda: check_boxes([[0, 0, np.nan, 1]]),
        ValueError,
        "boxes contains NaN or inf",
    ),
    "boxes: negative": (
        lambda: check_boxes([[0, 0, -1, 1]]),
        ValueError,
        "boxes has negative width or height",
    ),
    "boxes: empty box": (
        lambda: check_boxes([[0, 0, 0, 1]], positive=True),
        ValueError,
        r"positive width and height; bad rows: \[0\]",
    ),
    "boxes: rows": (
        lambda: check_boxes([[0, 0, 1, 1]], k=2),
        ValueError,
        "boxes has 1 boxes but the descriptors have 2 rows",
    ),
    "image: type": (
        lambda: check_image([[0]]),
        TypeError,
        r"image must be a numpy array \(H, W, 3\) uint8 RGB, got list",
    ),
    "image: dtype": (lambda: check_image(np.zeros((4, 5, 3))), ValueError, "got dtype float64"),
    "image: gray": (
        lambda: check_image(GRAY),
        ValueError,
        r"image must have shape \(H, W, 3\) uint8 RGB, got \(4, 5\)",
    ),
    "image: small": (
        lambda: check_image(GRAY, allow_gray=True, min_size=5),
        ValueError,
        "image is too small: shape .* need at least 5 x 5 pixels",
    ),
    "size: array": (lambda: check_image_size(GRAY), ValueError, r"pass image.shape\[:2\]"),
    "size: scalar": (
        lambda: check_image_size(7),
        ValueError,
        r"image_size must be a \(H, W\) pair, got 7",
    ),
    "size: text": (lambda: check_image_size(("a", "b")), ValueError, "must hold integers"),
    "size: zero": (
        lambda: check_image_size((0, 5), "size"),
        ValueError,
        r"size must be positive integers \(H, W\)",
    ),
    "shape": (
        lambda: check_shape(np.zeros((3, 2)), "N 3 3", "homography"),
        ValueError,
        r"homography must have shape \(N, 3, 3\), got \(3, 2\)",
    ),
    "int: fraction": (
        lambda: check_int(2.5, "n"),
        ValueError,
        "n must be a non-negative integer, got 2.5",
    ),
    "int: bool": (lambda: check_int(True, "n"), ValueError, "got True"),
    "int: minimum": (
        lambda: check_int(0, "k", minimum=1),
        ValueError,
        "k must be a positive integer, got 0",
    ),
    "int: text": (
        lambda: check_int("x", "k", minimum=2),
        ValueError,
        "k must be an integer >= 2, got 'x'",
    ),
    "range: closed": (
        lambda: check_range(1.5, "t", 0, 1),
        ValueError,
        r"t must be in \[0, 1\], got 1.5",
    ),
    "range: open": (
        lambda: check_range(0, "sigma", 0, low_open=True),
        ValueError,
        r"sigma must be in \(0, inf\], got 0",
    ),
    "range: NaN": (lambda: check_range(float("nan"), "t", 0, 1), ValueError, "got nan"),
    "range: text": (lambda: check_range("x", "t", 0, 1), ValueError, "got 'x'"),
    "choice": (
        lambda: check_choice("c", "mode", ("a", "b")),
        ValueError,
        "unknown mode 'c'; valid: a, b",
    ),
}


@pytest.mark.parametrize("case", BAD_CHECK_CALLS)
def test_bad_inputs_raise_one_clear_line(case):
    call, exc, match = BAD_CHECK_CALLS[case]
    with pytest.raises(exc, match=match) as info:
        call()
    assert "\n" not in str(info.value)
