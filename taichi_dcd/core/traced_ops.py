"""Taichi's small vector and matrix helpers built straight into a kernel's IR.

`a.dot(b)`, `a.cross(b)`, `m @ v`, `.sum()`, `.norm()`, `.norm_sqr()`, `.norm_inv()`,
`.normalized()`, `.min()` and `.max()` are `ti.func`s of Taichi's own (`taichi.lang.matrix_ops`,
1.7). Each call is inlined by running Taichi's AST transformer over that function's source
again, statically unrolled loops and all: on the solver's frame kernel that was ~44% of the
~109,000 AST nodes the frontend visits before the kernel can be looked up in the offline cache
(about 0.8 s of every process's first step).

`install()` swaps those helpers for plain Python functions that Taichi calls while it traces
the kernel, so their operations go into the IR directly. Each one copies its inputs to locals
(as an inlined `ti.func` does with its arguments), keeps the original's checks, and performs
the same arithmetic in the same order (the sums from the left, `m @ v` from a zero of the
original's making), so kernels compute the same bits; they only reach the offline cache under
a new key, once. Outside a kernel the originals run. `TAICHI_DCD_PLAIN_FRONTEND=1` leaves
Taichi as it is.
"""

from __future__ import annotations

from .frontend import left_plain

_installed = False
# The helpers replaced, for tests that compare against them.
originals: dict = {}


def install() -> bool:
    """Replace Taichi's helpers once per process (idempotent). Returns whether they are
    replaced: False when switched off or on a Taichi without the helpers this expects."""
    global _installed
    if _installed:
        return True
    if left_plain():
        return False
    try:
        from taichi.lang import impl, matrix_ops
        from taichi.lang import ops as ops_mod
        from taichi.lang.matrix import Matrix, Vector
        from taichi.lang.matrix_ops_utils import (arg_at, assert_tensor, assert_vector, check_matmul,
                                                  dim_lt, preconditions, same_shapes)
        found = {name: getattr(matrix_ops, name) for name in _REPLACED}
        add, min_impl, max_impl = ops_mod.add, ops_mod.min_impl, ops_mod.max_impl
        sqrt, rsqrt = ops_mod.sqrt, ops_mod.rsqrt
        subscript, expr_init = impl.subscript, impl.expr_init
    except (ImportError, AttributeError):
        return False

    def at(value, *index):
        return subscript(None, value, *index)

    def reduce(mat, combine):
        # Taichi's _reduce: from the first element, left to right, row by row.
        shape = mat.get_shape()
        if len(shape) == 1:
            result = at(mat, 0)
            for i in range(1, shape[0]):
                result = combine(result, at(mat, i))
            return result
        result = at(mat, 0, 0)
        for i in range(shape[0]):
            for j in range(shape[1]):
                if i != 0 or j != 0:
                    result = combine(result, at(mat, i, j))
        return result

    @preconditions(arg_at(0, assert_tensor))
    def traced_sum(mat):
        return reduce(expr_init(mat), add)

    @preconditions(assert_tensor)
    def traced_norm_sqr(mat):
        mat = expr_init(mat)
        return traced_sum(mat * mat)

    @preconditions(arg_at(0, assert_tensor))
    def traced_norm(mat, eps=0.0):
        return sqrt(traced_norm_sqr(mat) + eps)

    @preconditions(arg_at(0, assert_tensor))
    def traced_norm_inv(mat, eps=0.0):
        return rsqrt(traced_norm_sqr(mat) + eps)

    @preconditions(arg_at(0, assert_vector()))
    def traced_normalized(vec, eps=0.0):
        vec = expr_init(vec)
        inverse_length = expr_init(1 / (traced_norm(vec) + eps))
        return expr_init(inverse_length * vec)

    @preconditions(arg_at(0, assert_vector("lhs for dot is not a vector")),
                   arg_at(1, assert_vector("rhs for dot is not a vector")))
    def traced_dot(vec_x, vec_y):
        return traced_sum(expr_init(vec_x) * expr_init(vec_y))

    @preconditions(arg_at(0, assert_vector("lhs for cross is not a vector")),
                   arg_at(1, assert_vector("rhs for cross is not a vector")),
                   same_shapes, arg_at(0, dim_lt(0, 4)))
    def traced_cross(vec_x, vec_y):
        x, y = expr_init(vec_x), expr_init(vec_y)
        if x.get_shape()[0] == 2:
            return at(x, 0) * at(y, 1) - at(x, 1) * at(y, 0)
        return expr_init(Vector([at(x, 1) * at(y, 2) - at(x, 2) * at(y, 1),
                                 at(x, 2) * at(y, 0) - at(x, 0) * at(y, 2),
                                 at(x, 0) * at(y, 1) - at(x, 1) * at(y, 0)]))

    @preconditions(assert_tensor)
    def traced_min(mat):
        return reduce(expr_init(mat), min_impl)

    @preconditions(assert_tensor)
    def traced_max(mat):
        return reduce(expr_init(mat), max_impl)

    def product(x, y, transposed):
        # Taichi's _matmul_helper: each entry summed from a zero made as x[0,0]·y[0]·0 (which
        # carries the sign and the NaN of that product), left to right. `transposed` reads x
        # as its transpose (Taichi transposes first for vector @ matrix).
        if transposed:
            n_rows, n_inner = x.get_shape()[1], x.get_shape()[0]
            entry = lambda i, k: at(x, k, i)  # noqa: E731
        else:
            n_rows, n_inner = x.get_shape()
            entry = lambda i, k: at(x, i, k)  # noqa: E731
        if len(y.get_shape()) == 1:
            zero = entry(0, 0) * at(y, 0) * 0
            sums = []
            for i in range(n_rows):
                total = zero
                for k in range(n_inner):
                    total = total + entry(i, k) * at(y, k)
                sums.append(total)
            return expr_init(Vector(sums))
        zero = entry(0, 0) * at(y, 0, 0) * 0
        rows = []
        for i in range(n_rows):
            row = []
            for j in range(y.get_shape()[1]):
                total = zero
                for k in range(n_inner):
                    total = total + entry(i, k) * at(y, k, j)
                row.append(total)
            rows.append(row)
        return expr_init(Matrix(rows))

    @preconditions(check_matmul)
    def traced_matmul(mat_x, mat_y):
        x, y = expr_init(mat_x), expr_init(mat_y)
        shape_x, shape_y = x.get_shape(), y.get_shape()
        if len(shape_x) == 1 and len(shape_y) == 1:
            return traced_dot(x, y)
        if len(shape_x) == 1:
            return product(y, x, True)
        return product(x, y, False)

    traced = dict(sum=traced_sum, norm_sqr=traced_norm_sqr, norm=traced_norm, norm_inv=traced_norm_inv,
                  normalized=traced_normalized, dot=traced_dot,
                  cross=traced_cross, min=traced_min, max=traced_max, matmul=traced_matmul)
    originals.update(found)
    for name, replacement in traced.items():
        setattr(matrix_ops, name, _in_kernels(replacement, found[name], impl.inside_kernel))
    _installed = True
    return True


_REPLACED = ("sum", "norm_sqr", "norm", "norm_inv", "normalized", "dot", "cross", "min", "max", "matmul")


def _in_kernels(traced, original, inside_kernel):
    """`traced` while Taichi compiles a kernel, `original` in Python scope."""
    def chosen(*args, **kwargs):
        if inside_kernel():
            return traced(*args, **kwargs)
        return original(*args, **kwargs)
    chosen.__name__ = original.__name__
    chosen.__doc__ = original.__doc__
    return chosen
