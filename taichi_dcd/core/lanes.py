"""Arithmetic on points whose components are scalars or vectors of W lanes: W independent
triangle pairs computed at once, lane by lane.

The narrow phase is written once against these functions. The solver runs it on one pair
with scalar components and real branches; the batch API runs it on W pairs at a time with
lane vectors, which LLVM turns into SIMD instructions. There a branch is taken when any
lane needs it (`any_lane`) and its results are kept only for the lanes that do (ti.select,
`keep3`).
A point of scalars is a ti.Vector, a point of lanes a ti.Struct with fields x, y (and z):
both can be reassigned inside Taichi's branches, which a Python tuple cannot. Each
operation keeps the evaluation order of the `ti.Vector` method it stands for (dot =
(x·x' + y·y') + z·z', Taichi's cross and min/max), so a scalar point gives the same bits
as the vector code, and lane l of a batch the same bits as that pair alone.

The functions run in Python while Taichi traces the kernel that calls them (`kernel_code`):
their operations go straight into its IR, as Taichi's own vector helpers do here
(core/traced_ops.py), instead of Taichi's AST transformer inlining their source again at each
of the narrow phase's ~900 call sites. Like an inlined `ti.func` they read their inputs when
called, and their results are kernel locals.

Lanes are compiled with Taichi's `real_matrix_scalarize` off, where Taichi 1.7 gets some
operations on lanes wrong (checked one by one): reading one lane of a vector of booleans
(made by a comparison, & or |), `.any()`, unary minus and `ti.abs`. Hence `lane_ints`
before reading a boolean lane, and `any_lane`, `negate` and `absolute` here. Comparisons,
& and | consumed by ti.select, min, max, sqrt and the four operations are right.
"""

import taichi as ti
from taichi.lang import impl
from taichi.lang.expr import Expr
from taichi.lang.struct import Struct


def kernel_code(fn):
    """Mark fn, a plain Python function, as building kernel code when a kernel calls it, so that
    Taichi's AST transformer neither inlines it nor warns of a "non-taichi function" (it
    reads these attributes of its `ti.func`s)."""
    fn._is_taichi_function = True
    fn.func = fn
    fn.has_print = False
    return fn


def _local(value):
    """value made a local of the kernel being traced (read now, as an inlined call's result)."""
    return impl.expr_init(value)


def _part(p, i: int):
    """Component i of a point: field x, y or z of lanes, entry i of a vector."""
    if isinstance(p, Struct):
        return getattr(p, "xyz"[i])
    return impl.subscript(None, p, i)


def is_lanes(x) -> bool:
    """Whether x (a Taichi expression) is a vector of lanes rather than a scalar."""
    return isinstance(x, Expr) and x.is_tensor()


@kernel_code
def lane_ints(cond):
    """cond as 1 or 0 per lane, in i32 lanes: the form to read single lanes from."""
    return _local(ti.select(cond, 1, 0))


@kernel_code
def any_lane(cond):
    """Whether cond holds for at least one lane (cond itself for a scalar)."""
    if is_lanes(cond):
        ints = lane_ints(cond)
        result = impl.subscript(None, ints, 0)
        for lane in range(1, cond.get_shape()[0]):
            result = result | impl.subscript(None, ints, lane)
        return _local(result != 0)
    return cond


@kernel_code
def negate(x):
    """-x, lane by lane (x·-1, exactly -x, for lanes)."""
    return _local(x * -1.0 if is_lanes(x) else -x)


@kernel_code
def absolute(x):
    """|x|, lane by lane (for lanes max(x, -x), which may differ from |x| in the sign of a zero)."""
    return _local(ti.max(x, x * -1.0) if is_lanes(x) else ti.abs(x))


@kernel_code
def fill(like, value):
    """value in every lane of `like` (a scalar when `like` is one)."""
    return _local(ti.select(like == like, value, value))


@kernel_code
def make3(x, y, z):
    """The point (x, y, z)."""
    if is_lanes(x):
        return _local(ti.Struct(x=x, y=y, z=z))
    return _local(ti.Vector([x, y, z]))


@kernel_code
def make2(x, y):
    """The 2-D point (x, y)."""
    if is_lanes(x):
        return _local(ti.Struct(x=x, y=y))
    return _local(ti.Vector([x, y]))


@kernel_code
def at(p, i: int):
    """Component i (0, 1 or 2) of a point."""
    return _local(_part(p, i))


@kernel_code
def keep3(cond, new, old):
    """new where cond holds, old elsewhere, lane by lane: ti.select for points."""
    return make3(*(ti.select(cond, _part(new, i), _part(old, i)) for i in range(3)))


@kernel_code
def add(p, q):
    """p + q."""
    return make3(*(_part(p, i) + _part(q, i) for i in range(3)))


@kernel_code
def sub(p, q):
    """p - q."""
    return make3(*(_part(p, i) - _part(q, i) for i in range(3)))


@kernel_code
def scale(p, s):
    """p·s for a scalar (or lanes) s."""
    return make3(*(_part(p, i) * s for i in range(3)))


@kernel_code
def dot(p, q):
    """p·q, summed as (x + y) + z like ti.Vector.dot."""
    return _local(_part(p, 0) * _part(q, 0) + _part(p, 1) * _part(q, 1) + _part(p, 2) * _part(q, 2))


@kernel_code
def norm_sqr(p):
    """|p|²."""
    return dot(p, p)


@kernel_code
def cross(p, q):
    """p × q, term for term as ti.Vector.cross."""
    x, y, z = (_part(p, i) for i in range(3))
    u, v, w = (_part(q, i) for i in range(3))
    return make3(y * w - z * v, z * u - x * w, x * v - y * u)


@kernel_code
def min3(s):
    """The smallest component of a point."""
    return _local(ti.min(ti.min(_part(s, 0), _part(s, 1)), _part(s, 2)))


@kernel_code
def max3(s):
    """The largest component of a point."""
    return _local(ti.max(ti.max(_part(s, 0), _part(s, 1)), _part(s, 2)))


@kernel_code
def sub2(u, v):
    """u - v for 2-D points."""
    return make2(_part(u, 0) - _part(v, 0), _part(u, 1) - _part(v, 1))


@kernel_code
def cross2(u, v):
    """z-component of the 2-D cross product u × v."""
    return _local(_part(u, 0) * _part(v, 1) - _part(u, 1) * _part(v, 0))


@kernel_code
def norm_sqr2(u):
    """|u|² of a 2-D point."""
    return _local(_part(u, 0) * _part(u, 0) + _part(u, 1) * _part(u, 1))
