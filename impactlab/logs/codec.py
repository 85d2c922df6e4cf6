"""Fixed-layout protobuf encoding and decoding of whole arrays of messages at once.

A message whose only varying fields are doubles, all always written, has the same bytes in
every instance but for those doubles. `Template` learns that layout from the protobuf
library itself (it serialises one message with distinct sentinel values and finds where
each lands), then encodes an (n, k) array into n payloads, or decodes n payloads back,
with numpy alone. Decoding checks every fixed byte against the template, so a payload of
another layout is never misread: the caller falls back to the protobuf library.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import TypeVar

import numpy as np
from google.protobuf.message import Message
from numpy.lib.stride_tricks import as_strided

M = TypeVar("M", bound=Message)
Setter = Callable[[M, Sequence[float]], None]
CHECK_BLOCK_BYTES = 32 << 10
"""Fixed bytes are compared in blocks of this many (fresh memory costs a page fault per
4 KiB page; a freed block's is reused)."""


@dataclass(frozen=True)
class Template:
    """The byte layout of one fixed-shape message.

    Attributes:
        template: the serialised message with zeros in the double slots, (size,) uint8.
        slots: byte offset of each double, in value order, (k,) int64.
        fixed: mask of bytes that must equal the template, (size,) bool.
    """

    template: np.ndarray
    slots: np.ndarray
    fixed: np.ndarray

    @property
    def size(self) -> int:
        """Payload length in bytes."""
        return int(self.template.size)

    @classmethod
    def learn(cls, make: Callable[[], M], setter: Setter[M], k: int) -> Template:
        """Learn the layout of `make()` with its k doubles set by `setter(msg, values)`."""
        sentinels = [1.0 + (i + 1) * 2.0**-20 + 2.0**-40 for i in range(k)]
        msg = make()
        setter(msg, sentinels)
        raw = msg.SerializeToString()
        slots = []
        for value in sentinels:
            needle = struct.pack("<d", value)
            at = raw.find(needle)
            if at < 0 or raw.find(needle, at + 1) >= 0:
                raise ValueError("message layout is not fixed: a double is missing or repeated")
            slots.append(at)
        template = np.frombuffer(raw, dtype=np.uint8).copy()
        fixed = np.ones(template.size, dtype=bool)
        for at in slots:
            template[at : at + 8] = 0
            fixed[at : at + 8] = False
        return cls(template, np.asarray(slots, dtype=np.int64), fixed)

    @cached_property
    def record_dtype(self) -> np.dtype:
        """A structured dtype viewing one payload: field v<j> is the j-th double."""
        return np.dtype(
            {
                "names": [f"v{j}" for j in range(self.slots.size)],
                "formats": ["<f8"] * self.slots.size,
                "offsets": self.slots.tolist(),
                "itemsize": self.size,
            }
        )

    def encode(self, values: np.ndarray) -> np.ndarray:
        """Payloads for rows of doubles: (n, k) float64 -> (n, size) uint8."""
        out = np.tile(self.template, (values.shape[0], 1))
        fields = out.view(self.record_dtype).reshape(-1)
        for j in range(self.slots.size):
            fields[f"v{j}"] = values[:, j]
        return out

    def decode(self, payloads: np.ndarray) -> np.ndarray | None:
        """Doubles from payloads: (n, size) uint8 -> (n, k) float64; None if any differs.

        The result is the transpose of a C-ordered (k, n) array: each value's column is
        contiguous.
        """
        if payloads.ndim != 2 or payloads.shape[1] != self.size:
            return None
        out = np.empty((self.slots.size, payloads.shape[0]), dtype=np.float64)
        return out.T if self.decode_into(payloads, out) else None

    def decode_into(self, payloads: np.ndarray, out: np.ndarray) -> bool:
        """Decode payloads (n, size) uint8 (rows may be strided, as views into a chunk) into
        `out`, (k, n) float64; False, `out` untouched, if any payload is of another layout."""
        if payloads.ndim != 2 or payloads.shape[1] != self.size:
            return False
        if payloads.strides[1] != 1:
            payloads = np.ascontiguousarray(payloads)
        n = payloads.shape[0]
        if not n:
            return True
        fixed, expected = self._fixed_at, self.template[self._fixed_at]
        step = max(1, CHECK_BLOCK_BYTES // max(fixed.size, 1))
        for at in range(0, n, step):  # blocks: each one's bytes reuse the last one's memory
            if not (payloads[at : at + step, fixed] == expected).all():
                return False
        fields = payloads.view(self.record_dtype)[:, 0]
        for j, count, spacing in self._runs:  # evenly spaced doubles: one strided copy each
            first = fields[f"v{j}"]
            if count == 1:
                out[j] = first
            else:
                shape, strides = (count, n), (spacing, first.strides[0])
                out[j : j + count] = as_strided(first, shape, strides, writeable=False)
        return True

    @cached_property
    def _fixed_at(self) -> np.ndarray:
        return np.flatnonzero(self.fixed)

    @cached_property
    def _runs(self) -> list[tuple[int, int, int]]:
        """The doubles in runs of even spacing: (first value, count, spacing in bytes)."""
        runs: list[tuple[int, int, int]] = []
        slots = self.slots.tolist()
        j = 0
        while j < len(slots):
            count = 1
            spacing = slots[j + 1] - slots[j] if j + 1 < len(slots) else 8
            while j + count < len(slots) and slots[j + count] - slots[j + count - 1] == spacing:
                count += 1
            runs.append((j, count, spacing))
            j += count
        return runs
