"""The chunk writer's fast path writes exactly the bytes of its general path."""

from __future__ import annotations

import numpy as np
import pytest

from impactlab.logs import messages
from impactlab.logs.chunks import Block, _records, _records_dense


def _blocks(rng: np.random.Generator, n: int, subset_times: bool) -> list[Block]:
    t = np.cumsum(rng.integers(1, 5, n)).astype(np.int64) * 500_000
    body = messages.body_state()
    clearance = messages.clearance(2)
    in_contact = rng.random(n) < 0.4
    two = in_contact & (rng.random(n) < 0.3)
    one = in_contact & ~two
    blocks = [
        Block(1, t[:1], rng.integers(0, 256, (1, 37), dtype=np.uint8)),  # a scene, raw bytes
        Block(2, t, rng.normal(size=(n, 13)), body),
        Block(3, t, rng.normal(size=(n, 2)), clearance),
    ]
    for k, mine in ((1, one), (2, two)):
        layout = messages.clearance(13 * k)  # a multi-slot layout, as a step's contacts were
        values = rng.normal(size=(int(mine.sum()), 13 * k))
        blocks.append(Block(4, t[mine], values, layout))
    blocks.append(Block(5, t, rng.normal(size=(n, 3)), messages.energy()))
    blocks.append(Block(6, t, rng.normal(size=(n, 14)), messages.transforms(("A", "B"))))
    if not subset_times:  # times no other block has: the union has to be sorted
        extra = np.sort(rng.choice(np.arange(1, 10 * n), n // 3, replace=False)) * 100_001
        blocks.append(
            Block(7, extra.astype(np.int64), rng.normal(size=(extra.size, 3)), messages.energy())
        )
    return blocks


@pytest.mark.parametrize("subset_times", [True, False])
@pytest.mark.parametrize("n", [1, 2, 50, 777])
def test_dense_records_equal_the_general_path(n, subset_times):
    rng = np.random.default_rng(n)
    blocks = [b for b in _blocks(rng, n, subset_times) if len(b.log_time)]
    fast, fast_index = _records_dense(blocks)
    slow, slow_index = _records(blocks)
    assert fast.tobytes() == slow.tobytes()
    assert fast_index.keys() == slow_index.keys()
    for channel, pairs in slow_index.items():
        assert (fast_index[channel] == pairs).all(), channel
