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

Lanes are compiled with Taichi's `real_matrix_scalarize` off, where Taichi 1.7 gets some
operations on lanes wrong (checked one by one): reading one lane of a vector of booleans
(made by a comparison, & or |), `.any()`, unary minus and `ti.abs`. Hence `lane_ints`
before reading a boolean lane, and `any_lane`, `negate` and `absolute` here. Comparisons,
& and | consumed by ti.select, min, max, sqrt and the four operations are right.
"""

import taichi as ti
from taichi.lang.expr import Expr


def is_lanes(x) -> bool:
    """Whether x (a Taichi expression) is a vector of lanes rather than a scalar."""
    return isinstance(x, Expr) and x.is_tensor()


@ti.func
def lane_ints(cond):
    """cond as 1 or 0 per lane, in i32 lanes: the form to read single lanes from."""
    return ti.select(cond, 1, 0)


@ti.func
def any_lane(cond):
    """Whether cond holds for at least one lane (cond itself for a scalar)."""
    if ti.static(is_lanes(cond)):
        ints = lane_ints(cond)
        result = ints[0]
        for lane in ti.static(range(1, cond.get_shape()[0])):
            result = result | ints[lane]
        return result != 0
    else:
        return cond


@ti.func
def negate(x):
    """-x, lane by lane (x·-1, exactly -x, for lanes)."""
    if ti.static(is_lanes(x)):
        return x * -1.0
    else:
        return -x


@ti.func
def absolute(x):
    """|x|, lane by lane (for lanes max(x, -x), which may differ from |x| in the sign of a zero)."""
    if ti.static(is_lanes(x)):
        return ti.max(x, x * -1.0)
    else:
        return ti.abs(x)


@ti.func
def fill(like, value):
    """value in every lane of `like` (a scalar when `like` is one)."""
    return ti.select(like == like, value, value)


@ti.func
def make3(x, y, z):
    """The point (x, y, z)."""
    if ti.static(is_lanes(x)):
        return ti.Struct(x=x, y=y, z=z)
    else:
        return ti.Vector([x, y, z])


@ti.func
def make2(x, y):
    """The 2-D point (x, y)."""
    if ti.static(is_lanes(x)):
        return ti.Struct(x=x, y=y)
    else:
        return ti.Vector([x, y])


@ti.func
def at(p, i: ti.template()):
    """Component i (0, 1 or 2) of a point."""
    if ti.static(i == 0):
        return p.x
    elif ti.static(i == 1):
        return p.y
    else:
        return p.z


@ti.func
def keep3(cond, new, old):
    """new where cond holds, old elsewhere, lane by lane: ti.select for points."""
    return make3(ti.select(cond, new.x, old.x), ti.select(cond, new.y, old.y), ti.select(cond, new.z, old.z))


@ti.func
def add(p, q):
    """p + q."""
    return make3(p.x + q.x, p.y + q.y, p.z + q.z)


@ti.func
def sub(p, q):
    """p - q."""
    return make3(p.x - q.x, p.y - q.y, p.z - q.z)


@ti.func
def scale(p, s):
    """p·s for a scalar (or lanes) s."""
    return make3(p.x * s, p.y * s, p.z * s)


@ti.func
def dot(p, q):
    """p·q, summed as (x + y) + z like ti.Vector.dot."""
    return p.x * q.x + p.y * q.y + p.z * q.z


@ti.func
def norm_sqr(p):
    """|p|²."""
    return dot(p, p)


@ti.func
def cross(p, q):
    """p × q, term for term as ti.Vector.cross."""
    return make3(p.y * q.z - p.z * q.y, p.z * q.x - p.x * q.z, p.x * q.y - p.y * q.x)


@ti.func
def min3(s):
    """The smallest component of a point."""
    return ti.min(ti.min(s.x, s.y), s.z)


@ti.func
def max3(s):
    """The largest component of a point."""
    return ti.max(ti.max(s.x, s.y), s.z)


@ti.func
def sub2(u, v):
    """u - v for 2-D points."""
    return make2(u.x - v.x, u.y - v.y)


@ti.func
def cross2(u, v):
    """z-component of the 2-D cross product u × v."""
    return u.x * v.y - u.y * v.x


@ti.func
def norm_sqr2(u):
    """|u|² of a 2-D point."""
    return u.x * u.x + u.y * u.y
