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

import taichi as ti
from taichi.lang import impl
from taichi.types import ndarray_type, primitive_types

_NDARRAY, _FLOAT, _INT = 0, 1, 2


class BoundKernel:
    """A Taichi kernel bound to its arguments.

    kernel: a function decorated with @ti.kernel; args: all of its arguments, in
    order. Ndarray and template arguments stay bound for the life of the object
    (bind again after reallocating an array); `bound(*scalars)` launches with new
    values for the scalar (int or float) arguments, in order, or the bound ones if
    none are given, and returns what the kernel returns.
    """

    def __init__(self, kernel, *args):
        self.kernel = kernel
        self.args = list(args)
        self._scalar_positions = [k for k, value in enumerate(self.args)
                                  if isinstance(value, (int, float)) and not isinstance(value, bool)]
        self._fast = False
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
            if isinstance(annotation, ndarray_type.NdarrayType):
                if value.grad is not None:
                    return
                slots.append((slot, _NDARRAY, value.arr))
            elif id(annotation) in primitive_types.real_type_ids:
                slots.append((slot, _FLOAT, position))
                scalar_positions.append(position)
            elif id(annotation) in primitive_types.integer_type_ids and annotation is not bool:
                slots.append((slot, _INT, position))
                scalar_positions.append(position)
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
        program = impl.get_runtime().prog
        self._program = program
        self._data = program.compile_kernel(program.config(), program.get_device_caps(), self._compiled)
        self._slots = slots
        self._primal = primal
        self._return_type = returns[0] if returns is not None else None
        self._fast = True

    def __call__(self, *scalars):
        if scalars:
            if len(scalars) != len(self._scalar_positions):
                raise TypeError(f"{self.kernel.__name__}: {len(self._scalar_positions)} scalar argument(s) "
                                f"expected, got {len(scalars)}")
            for position, value in zip(self._scalar_positions, scalars):
                self.args[position] = value
        if not self._fast:
            return self.kernel(*self.args)
        # A launch context is filled once per launch: Taichi copies it to the kernel's
        # argument buffer at the first launch and ignores later changes to it.
        context = self._compiled.make_launch_context()
        for slot, kind, value in self._slots:
            if kind == _NDARRAY:
                context.set_arg_ndarray((slot,), value)
            elif kind == _FLOAT:
                context.set_arg_float((slot,), float(self.args[value]))
            else:
                context.set_arg_int((slot,), int(self.args[value]))
        self._program.launch_kernel(self._data, context)
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
    released).
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
