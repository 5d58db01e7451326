"""dancedata.compute.view_columns: a view's parts side by side, FACT's zero columns filled."""

from __future__ import annotations

import numpy as np
import pytest

from dancedata.compute.view_columns import (
    ZERO_COLUMNS,
    common_length,
    part_widths,
    stack_parts,
)


def test_stack_parts_by_hand() -> None:
    trans = np.arange(12, dtype=np.float32).reshape(4, 3)
    rot = np.arange(100, 108, dtype=np.float32).reshape(4, 2)
    out = stack_parts([None, trans, rot], 1, 3)
    assert out.dtype == np.float32
    expected = np.array(
        [[0, 0, 0, 0, 0, 0, 3, 4, 5, 102, 103], [0, 0, 0, 0, 0, 0, 6, 7, 8, 104, 105]],
        dtype=np.float32,
    )
    np.testing.assert_array_equal(out, expected)


def test_stack_parts_refuses_a_part_too_short_for_the_rows() -> None:
    with pytest.raises(ValueError, match="cannot give rows"):
        stack_parts([np.zeros((3, 2), np.float32)], 1, 4)


def test_common_length_and_widths() -> None:
    parts = [None, np.zeros((5, 3), np.float32), np.zeros((4, 20), np.float32)]
    assert common_length(parts) == 4
    assert part_widths(parts) == [ZERO_COLUMNS, 3, 20]
    with pytest.raises(ValueError, match="at least one part"):
        common_length([None])
