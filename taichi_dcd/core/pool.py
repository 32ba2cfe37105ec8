"""Field sets that one scene after another reuses, so that scenes share compiled kernels.

Taichi compiles a kernel once for each set of fields it reads, and the solver's frame
kernel takes ~7 s to compile even with Taichi's offline cache warm (most of it turning its
inlined functions into IR, which the cache does not save). A scene with fields of its own
paid that again; a process that builds several scenes (`run all`, a sweep, the tests) paid
it for each. Here a scene gets a `FieldSet` at least as large as it needs: one left free by
a scene that is gone, or a new one with room to spare. Kernels read the scene's own counts
at run time, so whatever a set held before is never read.

A set is in use from `acquire` until every owner given to `hold` has been garbage collected;
`runtime.reset` drops every set (their fields die with the Taichi program).
"""

from __future__ import annotations

import gc
import weakref
from typing import Callable

import numpy as np

# A count gets room for at least this many rows, and the next power of two above it: most
# scenes of a process then fit a set that an earlier one left.
ROWS_FLOOR = 64


def rows_for(count: int, floor: int = ROWS_FLOOR) -> int:
    """The rows a set allocates for `count` items: the next power of two ≥ max(count, floor)."""
    rows = max(int(count), int(floor), 1)
    return 1 << (rows - 1).bit_length()


class FieldSet:
    """Taichi fields with fixed row counts (`capacity`: count name → rows), reused by scene
    after scene. `parts` holds what is built on the set once and kept with it (the solver's
    own fields and its per-variant views), so that kernels specialised on them are reused."""

    def __init__(self, key: tuple, capacity: dict[str, int], fields: dict):
        self.key = key
        self.capacity = dict(capacity)
        self.fields = fields
        self.parts: dict = {}
        self.owners = 0
        self.in_use = True

    def fits(self, counts: dict[str, int]) -> bool:
        return all(self.capacity.get(name, 0) >= max(n, 1) for name, n in counts.items())

    def _release(self) -> None:
        self.owners -= 1
        if self.owners <= 0:
            self.in_use = False


_sets: list[FieldSet] = []


def acquire(key: tuple, counts: dict[str, int], layout: Callable[[dict[str, int]], dict]) -> FieldSet:
    """A free field set made for `key` whose rows hold `counts` (count name → items), or a new
    one: layout(capacity) allocates its fields (name → field) for capacity = rows_for of each
    count. Pass the set to `hold` with the objects that use it, or `give_back` on failure."""
    found = _free(key, counts)
    if found is None:
        gc.collect()  # scenes in reference cycles are gone only once collected
        found = _free(key, counts)
    if found is None:
        capacity = {name: rows_for(n) for name, n in counts.items()}
        found = FieldSet(key, capacity, layout(capacity))
        _sets.append(found)
    found.in_use = True
    found.owners = 0
    return found


def _free(key: tuple, counts: dict[str, int]) -> FieldSet | None:
    fitting = [s for s in _sets if not s.in_use and s.key == key and s.fits(counts)]
    return min(fitting, key=lambda s: sum(s.capacity.values()), default=None)


def hold(field_set: FieldSet, *owners) -> None:
    """Keep the set in use until every one of `owners` has been collected."""
    for owner in owners:
        field_set.owners += 1
        weakref.finalize(owner, field_set._release)


def give_back(field_set: FieldSet) -> None:
    """Free a set whose build failed before `hold`."""
    field_set.in_use = False


def clear() -> None:
    """Forget every set (runtime.reset: the Taichi program that held their fields is gone)."""
    _sets.clear()


def padded(data: np.ndarray, rows: int) -> np.ndarray:
    """`data` (n, ...) followed by zero rows up to `rows`."""
    data = np.asarray(data)
    if len(data) == rows:
        return data
    out = np.zeros((rows,) + data.shape[1:], dtype=data.dtype)
    out[: len(data)] = data
    return out
