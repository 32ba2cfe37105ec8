"""Kernel launches with their array arguments bound once.

Taichi checks and converts every argument of every launch in Python: ~7 µs per
ndarray argument here, ~25 µs per launch besides, so a broad-phase query over a
few thousand triangles spent more time passing its 40-odd arrays than working.
`BoundKernel` resolves a kernel's compiled form and its ndarray and template
arguments once; each call then sets the scalar arguments and launches the
compiled kernel directly (~2 µs per array). Those calls are Taichi 1.7's own
launch path, minus the per-call checks; where that path is missing (another
Taichi version) the bound kernel makes an ordinary call instead.
"""

from __future__ import annotations

import numpy as np
import taichi as ti
from taichi.lang import impl
from taichi.lang.matrix import VectorType
from taichi.types import ndarray_type, primitive_types

_NDARRAY, _FLOAT, _INT, _VECTOR, _EXTERNAL = 0, 1, 2, 3, 4


class BoundKernel:
    """A Taichi kernel bound to its arguments.

    kernel: a function decorated with @ti.kernel; args: all of its arguments, in order.
    Ndarray, vector and template arguments stay bound for the life of the object (bind
    again after reallocating an array); so does a C-contiguous NumPy array, by its memory:
    write new values into that same array between launches. `bound(*scalars)` launches with new values for
    the scalar (int or float) arguments, in order, or the bound ones if none are given,
    and returns what the kernel returns. A method of a @ti.data_oriented object is
    accepted but called the ordinary way: launched through a binding, the solver's frame
    kernel crashed once Taichi had been reset and started again in the same process.
    """

    def __init__(self, kernel, *args):
        self.kernel = kernel
        self.name = getattr(kernel, "__name__", None) or "kernel"
        self.args = list(args)
        self._scalar_positions = [k for k, value in enumerate(self.args) if _is_scalar(value)]
        self._fast = False
        if hasattr(kernel, "_kernel_owner"):
            return
        try:
            self._bind()
        except (AttributeError, TypeError, KeyError, ValueError):
            self._fast = False

    def _bind(self) -> None:
        primal = self.kernel._primal
        slots = []
        scalar_positions = []
        slot = 0
        for position, (value, argument) in enumerate(zip(self.args, primal.arguments, strict=True)):
            annotation = argument.annotation
            if isinstance(annotation, ti.template):
                continue
            if isinstance(annotation, ndarray_type.NdarrayType) and isinstance(value, np.ndarray):
                if not value.flags.c_contiguous:
                    return
                element_dim = getattr(annotation.dtype, "ndim", 0) or 0
                shape = value.shape[: value.ndim - element_dim]
                slots.append((slot, _EXTERNAL, (int(value.ctypes.data), value.nbytes, list(shape))))
            elif isinstance(annotation, ndarray_type.NdarrayType):
                if value.grad is not None:
                    return
                slots.append((slot, _NDARRAY, value.arr))
            elif id(annotation) in primitive_types.real_type_ids:
                slots.append((slot, _FLOAT, position))
                scalar_positions.append(position)
            elif id(annotation) in primitive_types.integer_type_ids and annotation is not bool:
                slots.append((slot, _INT, position))
                scalar_positions.append(position)
            elif isinstance(annotation, VectorType) and annotation.dtype in primitive_types.real_types:
                slots.append((slot, _VECTOR, (annotation, annotation(*(float(x) for x in value)))))
            else:
                return
            slot += 1
        returns = primal.return_type
        if returns is not None and len(returns) != 1:
            return
        if scalar_positions != self._scalar_positions:
            return
        key = primal.ensure_compiled(*self.args)
        self._compiled = primal.compiled_kernels[key]
        self._program = impl.get_runtime().prog
        self._slots = slots
        self._primal = primal
        self._return_type = returns[0] if returns is not None else None
        self._fast = True

    def __call__(self, *scalars):
        if scalars:
            if len(scalars) != len(self._scalar_positions):
                raise TypeError(f"{self.name}: {len(self._scalar_positions)} scalar argument(s) "
                                f"expected, got {len(scalars)}")
            for position, value in zip(self._scalar_positions, scalars):
                self.args[position] = value
        if self._fast and impl.get_runtime().prog is not self._program:
            self._fast = False  # Taichi was reset since the binding: its kernels are gone
            self._bind()
        if not self._fast:
            return self.kernel(*self.args)
        # A launch context is filled once per launch: Taichi copies it to the kernel's
        # argument buffer at the first launch and ignores later changes to it.
        context = self._compiled.make_launch_context()
        for slot, kind, value in self._slots:
            if kind == _NDARRAY:
                context.set_arg_ndarray((slot,), value)
            elif kind == _EXTERNAL:
                context.set_arg_external_array_with_shape((slot,), *value, 0)
            elif kind == _FLOAT:
                context.set_arg_float((slot,), float(self.args[value]))
            elif kind == _INT:
                context.set_arg_int((slot,), int(self.args[value]))
            else:
                annotation, vector = value
                annotation.set_kernel_struct_args(vector, context, (slot,))
        # Fields declared since the last launch are allocated first, and the compiled code
        # is looked up at every launch, as Taichi does (it is a reference into Taichi's
        # cache, which compiling other kernels may move).
        impl.get_runtime().materialize()
        program = self._program
        data = program.compile_kernel(program.config(), program.get_device_caps(), self._compiled)
        program.launch_kernel(data, context)
        if self._return_type is None:
            return None
        ti.sync()
        return self._primal.construct_kernel_ret(context, self._return_type, (0,))


def _is_scalar(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class Launcher:
    """Launches kernels through `BoundKernel`s, one per kernel and set of bound arguments.

    `launcher(kernel, *args)` behaves as `kernel(*args)`. Arrays are told apart by
    identity, which is safe because the cached BoundKernel keeps them alive; only the
    `keep` most recent bindings per kernel are kept (arrays replaced by larger ones are
    released). A vector argument is bound too: pass the same object each time.
    """

    def __init__(self, keep: int = 4):
        self.keep = keep
        self._bound: dict = {}

    def __call__(self, kernel, *args):
        key = tuple(None if _is_scalar(a) else (a if isinstance(a, bool) else id(a)) for a in args)
        entries = self._bound.setdefault(kernel, [])
        for k, (entry_key, bound) in enumerate(entries):
            if entry_key == key:
                if k:
                    entries.insert(0, entries.pop(k))
                return bound(*(a for a in args if _is_scalar(a)))
        bound = BoundKernel(kernel, *args)
        entries.insert(0, (key, bound))
        del entries[self.keep:]
        return bound()
