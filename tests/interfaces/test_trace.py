"""The full-rate trace's containers (humanoid_sim.interfaces.trace): RowBuffer's blocks and slots."""

from __future__ import annotations

import numpy as np

from humanoid_sim.interfaces.trace import RowBuffer


def test_row_buffer_rows_and_slots() -> None:
    """Rows filled through next_row (a view) and next_slot (a block and an index) come back in order, across
    blocks, as one (n, width) array; an empty buffer gives (0, width)."""
    buf = RowBuffer(3, block=4)
    assert buf.array().shape == (0, 3) and len(buf) == 0
    for i in range(10):
        if i % 2:
            buf.next_row()[:] = (i, 2 * i, 3 * i)
        else:
            block, j = buf.next_slot()
            assert block.shape == (4, 3) and j == i % 4
            block[j] = (i, 2 * i, 3 * i)
    out = buf.array()
    assert len(buf) == 10 and out.shape == (10, 3)
    np.testing.assert_array_equal(out, np.arange(10)[:, None] * np.array([1, 2, 3]))
