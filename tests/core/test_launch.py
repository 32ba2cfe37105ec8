"""Bound kernel launches do what an ordinary call does: same results, new scalars each
call, new arrays when the caller passes new ones, bounds checks in debug mode."""

import numpy as np
import pytest
import taichi as ti

from taichi_dcd.core.launch import BoundKernel, Launcher

vec3 = ti.types.vector(3, ti.f64)


@ti.kernel
def _scaled_sum(x: ti.types.ndarray(dtype=vec3, ndim=1), out: ti.types.ndarray(dtype=ti.f64, ndim=2),
                scale: float, row: ti.i32, negate: ti.template()) -> ti.i32:
    """out[row, k] = ±scale · Σ_i x[i][k]; returns the number of rows of x."""
    for k in ti.static(range(3)):
        out[row, k] = 0.0
    for i in range(x.shape[0]):
        for k in ti.static(range(3)):
            out[row, k] += (-scale if ti.static(negate) else scale) * x[i][k]
    return x.shape[0]


@ti.kernel
def _vector_result(x: ti.types.ndarray(dtype=vec3, ndim=1)) -> vec3:
    return x[0] * 2.0


@ti.kernel
def _read_at(x: ti.types.ndarray(dtype=vec3, ndim=1), i: ti.i32) -> ti.i32:
    return ti.cast(x[i][0], ti.i32)


def _vectors(values: np.ndarray):
    x = ti.ndarray(vec3, shape=len(values))
    x.from_numpy(values)
    return x


def test_bound_kernel_matches_plain_call_with_new_scalars_each_time(f64):
    rng = np.random.default_rng(0)
    values = rng.normal(size=(50, 3))
    x = _vectors(values)
    out = ti.ndarray(ti.f64, shape=(4, 3))
    bound = BoundKernel(_scaled_sum, x, out, 1.0, 0, False)
    assert bound._fast, "Taichi 1.7's launch path was not found: the fast path is off"
    for row, scale in enumerate([1.0, 2.5, -0.5]):
        assert bound(scale, row) == 50
    _scaled_sum(x, out, 3.0, 3, True)
    got = out.to_numpy()
    total = values.sum(axis=0)
    np.testing.assert_allclose(got[0], total, rtol=1e-12)
    np.testing.assert_allclose(got[1], 2.5 * total, rtol=1e-12)
    np.testing.assert_allclose(got[2], -0.5 * total, rtol=1e-12)
    np.testing.assert_allclose(got[3], -3.0 * total, rtol=1e-12)
    with pytest.raises(TypeError, match="2 scalar argument"):
        bound(1.0)


def test_launcher_rebinds_when_an_array_or_template_changes(f64):
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(10, 3)), rng.normal(size=(30, 3))
    xa, xb = _vectors(a), _vectors(b)
    out = ti.ndarray(ti.f64, shape=(2, 3))
    launch = Launcher(keep=2)
    assert launch(_scaled_sum, xa, out, 1.0, 0, False) == 10
    assert launch(_scaled_sum, xb, out, 2.0, 1, False) == 30
    np.testing.assert_allclose(out.to_numpy(), [a.sum(axis=0), 2.0 * b.sum(axis=0)], rtol=1e-12)
    assert launch(_scaled_sum, xa, out, 1.0, 1, True) == 10
    np.testing.assert_allclose(out.to_numpy()[1], -a.sum(axis=0), rtol=1e-12)
    # Only the two most recent bindings are kept; a dropped one is bound again.
    assert launch(_scaled_sum, xa, out, 1.0, 0, False) == 10
    assert len(launch._bound[_scaled_sum]) == 2


def test_vector_results_and_the_plain_fallback(f64):
    x = _vectors(np.array([[1.0, 2.0, 3.0]]))
    bound = BoundKernel(_vector_result, x)
    assert bound._fast
    np.testing.assert_allclose(bound().to_numpy(), [2.0, 4.0, 6.0])
    # Arguments the fast path does not know (here a numpy array in Fortran order, which
    # Taichi copies at each call) make an ordinary call.
    fortran = np.asfortranarray([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    plain = BoundKernel(_vector_result, fortran)
    assert not plain._fast
    np.testing.assert_allclose(plain().to_numpy(), [2.0, 4.0, 6.0])


def test_a_numpy_array_is_bound_by_its_memory(f64):
    values = np.array([[1.0, 2.0, 3.0]])
    bound = BoundKernel(_vector_result, values)
    assert bound._fast
    np.testing.assert_allclose(bound().to_numpy(), [2.0, 4.0, 6.0])
    # New values written into the same array reach the next launch.
    values[0] = [-1.0, 0.5, 10.0]
    np.testing.assert_allclose(bound().to_numpy(), [-2.0, 1.0, 20.0])


def test_bounds_are_still_checked_in_debug_mode(f64):
    x = _vectors(np.array([[7.0, 0.0, 0.0]]))
    bound = BoundKernel(_read_at, x, 0)
    assert bound() == 7
    with pytest.raises(Exception, match="(?i)out of bound"):
        bound(5)


@ti.kernel
def _add_steps(step: vec3, times: ti.i32, out: ti.types.ndarray(dtype=vec3, ndim=1)) -> ti.i32:
    total = vec3(0.0)
    ti.loop_config(serialize=True)
    for i in range(times):
        total += step
    out[0] = total
    return times


@ti.data_oriented
class _Accumulator:
    def __init__(self):
        self.total = ti.Vector.field(3, ti.f64, shape=())

    @ti.kernel
    def add(self, step: vec3, times: ti.i32, out: ti.types.ndarray(dtype=vec3, ndim=1)) -> ti.i32:
        ti.loop_config(serialize=True)
        for i in range(times):
            self.total[None] += step
        out[0] = self.total[None]
        return times


def test_vector_arguments_and_methods_of_data_oriented_objects(f64):
    """A vector argument is bound like an array; a method of a data-oriented object (the
    solver's kernels) is called the ordinary way and gives the same results."""
    out = ti.ndarray(vec3, shape=1)
    step = ti.Vector([1.0, -2.0, 0.5])
    bound = BoundKernel(_add_steps, step, 3, out)
    assert bound._fast
    assert bound(4) == 4
    np.testing.assert_allclose(out.to_numpy()[0], [4.0, -8.0, 2.0])
    acc = _Accumulator()
    method = BoundKernel(acc.add, step, 3, out)
    assert not method._fast
    assert method(2) == 2 and Launcher()(acc.add, step, 1, out) == 1
    np.testing.assert_allclose(out.to_numpy()[0], [3.0, -6.0, 1.5])
