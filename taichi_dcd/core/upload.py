"""NumPy arrays copied into Taichi fields in a few kernel launches.

`field.from_numpy` compiles a kernel of its own for every field it fills (the field is the
kernel's template argument), and each costs its compile, or its load from Taichi's cache, once
per process: a scene's ~40 fields took most of the second it took to build. `upload` packs
the arrays of up to BATCH fields into one flat array of integers and one of reals and copies
them out in one kernel per batch of fields.
"""

import numpy as np
import taichi as ti
from taichi.lang.matrix import MatrixField

from . import runtime

# Fields per kernel: each is one unrolled loop, and Taichi warns of long compiles past 32.
BATCH = 16


def upload(pairs) -> None:
    """Copy each (field, array) of `pairs` into its field. An array has the field's shape
    followed by its element's shape (as `field.from_numpy` takes it). Fields of i32 or of the
    kernels' float type go in batches of one launch; any other field, and an array of the
    wrong shape (to get Taichi's own error), goes through `from_numpy`."""
    real = runtime.real_type()
    batch = []
    for fld, data in pairs:
        data = np.asarray(data)
        if fld.dtype in (ti.i32, real) and data.shape == tuple(fld.shape) + _element_shape(fld):
            batch.append((fld, data))
        else:
            fld.from_numpy(data)
    for start in range(0, len(batch), BATCH):
        part = batch[start:start + BATCH]
        ints = [d.ravel() for f, d in part if f.dtype == ti.i32]
        reals = [d.ravel() for f, d in part if f.dtype != ti.i32]
        _copy(tuple(f for f, _ in part),
              np.concatenate(ints or [np.zeros(1)]).astype(np.int32),
              np.concatenate(reals or [np.zeros(1)]).astype(runtime.real_dtype()))


def _element_shape(fld) -> tuple:
    if isinstance(fld, MatrixField):
        return (fld.n,) if fld.ndim == 1 else (fld.n, fld.m)
    return ()


def _layout(fields) -> tuple:
    """Per field (at compile time): whether it is an i32 field, where its values start in its
    flat array, its element's shape, and the strides of its index."""
    out, at_int, at_real = [], 0, 0
    for fld in fields:
        element = _element_shape(fld)
        count = int(np.prod(fld.shape)) * int(np.prod(element, dtype=np.int64))
        is_int = fld.dtype == ti.i32
        strides = tuple(int(np.prod(fld.shape[d + 1:], dtype=np.int64)) for d in range(len(fld.shape)))
        out.append((is_int, at_int if is_int else at_real, element, strides))
        if is_int:
            at_int += count
        else:
            at_real += count
    return tuple(out)


@ti.kernel
def _copy(fields: ti.template(), ints: ti.types.ndarray(ndim=1), reals: ti.types.ndarray(ndim=1)):
    """Each field of the tuple `fields` from its run of `ints` or `reals` (row-major, the
    element's components last), as _layout places them."""
    layout = ti.static(_layout(fields))
    for k in ti.static(range(len(fields))):
        is_int, first, element, strides = ti.static(layout[k])
        size = ti.static(int(np.prod(element, dtype=np.int64)))
        values = ti.static(ints if is_int else reals)
        for index in ti.grouped(fields[k]):
            at = first
            for d in ti.static(range(len(strides))):
                at += index[d] * strides[d] * size
            if ti.static(len(element) == 0):
                fields[k][index] = values[at]
            elif ti.static(len(element) == 1):
                for c in ti.static(range(element[0])):
                    fields[k][index][c] = values[at + c]
            else:
                for r, c in ti.static(ti.ndrange(element[0], element[1])):
                    fields[k][index][r, c] = values[at + r * element[1] + c]
