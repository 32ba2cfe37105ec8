"""Taichi's vector helpers built at trace time (core.traced_ops) compute the same bits as
Taichi's own `ti.func`s: one kernel compiled both ways on seeded random data with signed
zeros, infinities and NaNs among it, compared bit for bit; their errors and Python-scope
behaviour are Taichi's."""

import contextlib

import numpy as np
import pytest
import taichi as ti
from taichi.lang import matrix_ops
from taichi.lang.exception import TaichiCompilationError

from taichi_dcd.core import traced_ops

N = 64
OUTPUTS = 40


@contextlib.contextmanager
def taichi_helpers():
    """Taichi's own helpers in place while a kernel compiles inside the block."""
    traced = {name: getattr(matrix_ops, name) for name in traced_ops.originals}
    for name, original in traced_ops.originals.items():
        setattr(matrix_ops, name, original)
    try:
        yield
    finally:
        for name, helper in traced.items():
            setattr(matrix_ops, name, helper)


def make_kernel(a, b, m, n, out):
    @ti.kernel
    def every_helper():
        for i in range(N):
            u, v = a[i], b[i]
            row = 0
            for value in ti.static([u.dot(v), u.sum(), u.norm(), u.norm_sqr(), u.norm_inv(), u.min(),
                                    u.max(), m[i].sum(), m[i].norm(), m[i].max(), m[i].min(),
                                    a[i].dot(b[(i + 1) % N]), ti.Vector([u[0], u[1]]).cross(ti.Vector([v[1], v[2]])),
                                    u.norm(1e-12)]):
                out[i, row] = value
                row += 1
            for vector in ti.static([u.cross(v), u.normalized(), m[i] @ v, v @ m[i], a[i].cross(b[i]),
                                     ti.Vector([1.0, -0.0, 2.0]).cross(u), u.normalized(1e-9)]):
                for k in ti.static(range(3)):
                    out[i, row + k] = vector[k]
                row += 3
            product = m[i] @ n[i]
            out[i, row] = product[0, 0]
            out[i, row + 1] = product[1, 1]
            out[i, row + 2] = product[2, 0]
            out[i, row + 3] = product[1, 2]
    return every_helper


def random_inputs(seed):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(N, 3)) * 10.0 ** rng.integers(-6, 6, size=(N, 1))
    b = rng.normal(size=(N, 3))
    m = rng.normal(size=(N, 3, 3))
    n = rng.normal(size=(N, 3, 3))
    specials = [0.0, -0.0, np.inf, -np.inf, np.nan, 1e-300, -1e300]
    for row in range(0, N, 5):
        a[row, rng.integers(3)] = specials[row % len(specials)]
        b[row, rng.integers(3)] = specials[(row + 3) % len(specials)]
        m[row, rng.integers(3), rng.integers(3)] = specials[(row + 1) % len(specials)]
    a[1] = [-0.0, -0.0, -0.0]
    m[2] = -0.0
    return a, b, m, n


@pytest.mark.parametrize("seed", [0, 1])
def test_same_bits_as_taichi(f64, seed):
    assert traced_ops.install()
    fields = (ti.Vector.field(3, ti.f64, shape=N), ti.Vector.field(3, ti.f64, shape=N),
              ti.Matrix.field(3, 3, ti.f64, shape=N), ti.Matrix.field(3, 3, ti.f64, shape=N))
    a_np, b_np, m_np, n_np = random_inputs(seed)
    for field, values in zip(fields, (a_np, b_np, m_np, n_np)):
        field.from_numpy(values)
    out_taichi = ti.field(ti.f64, shape=(N, OUTPUTS))
    out_traced = ti.field(ti.f64, shape=(N, OUTPUTS))
    with taichi_helpers():
        make_kernel(*fields, out_taichi)()
    make_kernel(*fields, out_traced)()
    taichi_bits = out_taichi.to_numpy().view(np.int64)
    traced_bits = out_traced.to_numpy().view(np.int64)
    assert np.isnan(out_taichi.to_numpy()).any() and (out_taichi.to_numpy() == 0).any()
    np.testing.assert_array_equal(traced_bits, taichi_bits)
    # and both are the helpers' arithmetic: spot-check against NumPy where the data is finite
    finite = np.isfinite(a_np).all(axis=1) & np.isfinite(b_np).all(axis=1)
    np.testing.assert_allclose(out_traced.to_numpy()[finite, 0], np.einsum("ij,ij->i", a_np[finite], b_np[finite]),
                               rtol=1e-12, atol=1e-300)
    cross_rows = out_traced.to_numpy()[finite, 14:17]
    np.testing.assert_allclose(cross_rows, np.cross(a_np[finite], b_np[finite]), rtol=1e-12, atol=1e-12 * np.abs(a_np[finite]).max())


def test_shape_errors_are_taichis(f64):
    assert traced_ops.install()

    @ti.kernel
    def bad_cross() -> ti.f64:
        return ti.Vector([1.0, 2.0]).cross(ti.Vector([1.0, 2.0, 3.0])).sum()

    with pytest.raises(TaichiCompilationError, match="shape"):
        bad_cross()

    @ti.kernel
    def bad_product() -> ti.f64:
        return (ti.Matrix([[1.0, 2.0], [3.0, 4.0]]) @ ti.Vector([1.0, 2.0, 3.0])).sum()

    with pytest.raises(TaichiCompilationError, match="dimension mismatch"):
        bad_product()


def test_python_scope_is_untouched(f64):
    assert traced_ops.install()
    u, v = ti.Vector([1.0, 2.0, 3.0]), ti.Vector([-2.0, 0.5, 4.0])
    assert u.dot(v) == pytest.approx(11.0)
    assert list(u.cross(v)) == pytest.approx(list(np.cross([1, 2, 3], [-2, 0.5, 4])))
    assert u.norm() == pytest.approx(np.sqrt(14.0))
