"""Named layouts of the float vectors compiled code reads: a problem's parameters, an integrator's options.

A :class:`Layout` names every slot of a vector: scalars, then fields with one
value per element (per block of a chain), then more scalars. Python packs a
vector by name (:meth:`Layout.pack`); compiled code reads it through the
family's accessors, whose offsets come from the same layout
(:meth:`Layout.head_size`, :meth:`Layout.field`, ...), so no offset is written
as a bare number anywhere.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np


@dataclass(frozen=True)
class Layout:
    """Slots of a float vector: ``head`` scalars, then ``fields`` (one value per element each, field by
    field), then ``tail`` scalars. With ``fields`` empty it is a plain list of named scalars.

    The number of elements is the first head scalar when there are fields (it
    sizes the vector), e.g. ``Layout(head=("n_blocks",), fields=("m", "c"),
    tail=("v0",))`` is ``[n, m_1 .. m_n, c_1 .. c_n, v0]``.
    """

    head: tuple[str, ...] = ()
    fields: tuple[str, ...] = ()
    tail: tuple[str, ...] = ()

    @property
    def head_size(self) -> int:
        return len(self.head)

    def field(self, name: str) -> int:
        """Index of a per-element field (its values start at ``head_size + index * n``)."""
        return self.fields.index(name)

    def scalar(self, name: str) -> int:
        """Index of a tail scalar (at ``head_size + len(fields) * n + index``) or a head scalar."""
        return self.tail.index(name) if name in self.tail else self.head.index(name)

    def size(self, n: int = 0) -> int:
        return len(self.head) + len(self.fields) * n + len(self.tail)

    def offset(self, name: str, n: int = 0, element: int = 0) -> int:
        """Offset of scalar ``name``, or of ``element`` (0-based) of field ``name``, in a vector for ``n`` elements."""
        if name in self.head:
            return self.head.index(name)
        if name in self.fields:
            if not 0 <= element < n:
                raise IndexError(f"element {element} of field {name!r} out of 0..{n - 1}")
            return len(self.head) + self.fields.index(name) * n + element
        if name in self.tail:
            return len(self.head) + len(self.fields) * n + self.tail.index(name)
        raise KeyError(f"no slot {name!r}; slots: {', '.join(self.head + self.fields + self.tail)}")

    def pack(self, values: Mapping[str, Any], n: int = 0) -> np.ndarray:
        """The float64 vector of ``values`` (scalars by name, fields as sequences of ``n`` values)."""
        out = np.zeros(self.size(n))
        for name in self.head + self.tail:
            out[self.offset(name, n)] = float(values[name])
        for name in self.fields:
            seq: Sequence[float] = values[name]
            if len(seq) != n:
                raise ValueError(f"field {name!r} has {len(seq)} values, not {n}")
            start = self.offset(name, n, 0) if n else 0
            out[start : start + n] = np.asarray(seq, dtype=float)
        return out

    def unpack(self, vector: np.ndarray, n: int = 0) -> dict[str, Any]:
        """The values of a packed vector by name (fields as tuples)."""
        v = np.asarray(vector, dtype=float)
        out: dict[str, Any] = {name: float(v[self.offset(name, n)]) for name in self.head + self.tail}
        for name in self.fields:
            start = len(self.head) + self.fields.index(name) * n
            out[name] = tuple(float(x) for x in v[start : start + n])
        return out
