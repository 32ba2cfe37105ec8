"""Taichi's frontend with its pure helpers remembered (core.frontend) gives the same error
messages and kernels as without, every node's position named by file, line and source, and
fields uploaded in batches (core.upload) hold exactly what `from_numpy` puts there."""

import inspect
import sys

import numpy as np
import pytest
import taichi as ti

from taichi_dcd.core import frontend
from taichi_dcd.core.upload import upload


@ti.func
def _scaled(x: ti.f64, k: ti.template()) -> ti.f64:
    out = x
    for _ in ti.static(range(k)):
        out = out * 2.0 + 1.0
    return out


@ti.kernel
def _twice_inlined(a: ti.f64) -> ti.f64:
    total = 0.0
    if a > 0.0:
        total += _scaled(a, 2)
    else:
        total -= _scaled(-a, 3)
    return total + _scaled(a, 1)


def test_every_position_names_its_file_line_function_and_source(f64, monkeypatch):
    """Each node's position, remembered across the inlined calls, is Taichi's own first line
    (file, line, function) and the node's first source line, without Taichi's word-wrapped
    caret lines (its cost: ~0.6 s of a process's first frame kernel)."""
    from taichi.lang.ast import ast_transformer_utils as utils

    assert frontend.speed_up()
    remembered = utils.ASTTransformerContext.get_pos_info
    original = frontend._originals["get_pos_info"]
    seen = []

    def spy(ctx, node):
        text = remembered(ctx, node)
        full = original(ctx, node)
        head = full.split("\n", 1)[0]
        source = ctx.src[node.lineno - 1].rstrip()
        seen.append(text == f"{head}\n{source}\n" and source.strip() in full)
        return text

    monkeypatch.setattr(utils.ASTTransformerContext, "get_pos_info", spy)
    assert _twice_inlined(1.5) == pytest.approx((1.5 * 2 + 1) * 2 + 1 + 1.5 * 2 + 1)
    assert len(seen) > 50 and all(seen)


def _kernel_with_a_bad_call():
    @ti.func
    def bad(x):
        y = x * 2.0
        return y.no_such_member

    @ti.kernel
    def calls_bad() -> ti.f64:
        return bad(1.0) + bad(2.0)

    return calls_bad


def test_an_error_shows_taichis_own_excerpt(f64, monkeypatch):
    """A compile error's message is the one plain Taichi gives, caret lines and all: the
    positions an error reports are Taichi's own."""
    from taichi.lang.ast import ast_transformer_utils as utils

    assert frontend.speed_up()
    with pytest.raises(Exception) as ours:
        _kernel_with_a_bad_call()()
    monkeypatch.setattr(utils.ASTTransformerContext, "get_pos_info", frontend._originals["get_pos_info"])
    with pytest.raises(Exception) as plain:
        _kernel_with_a_bad_call()()
    assert type(ours.value) is type(plain.value)
    assert str(ours.value) == str(plain.value)
    assert "^^^" in str(ours.value) and "y.no_such_member" in str(ours.value)


def test_a_bad_line_is_still_named(f64):
    @ti.func
    def bad(x):
        return x.no_such_member

    @ti.kernel
    def calls_bad() -> ti.f64:
        return bad(1.0) + bad(2.0)

    with pytest.raises(Exception) as err:
        calls_bad()
    text = str(err.value)
    assert "return x.no_such_member" in text and __file__ in text


def test_frame_line_is_inspects():
    frame = sys._getframe()
    assert frontend._frameinfo_from_linecache(frame)[3] == inspect.getframeinfo(frame)[3]
    assert frontend._frameinfo_from_linecache(frame)[:3] == tuple(inspect.getframeinfo(frame)[:3])


def test_frame_of_no_source_file_has_no_context_as_for_inspect():
    """A module's top-level decorators look one frame above the module, into importlib's own
    frozen code, whose source neither linecache nor inspect has: no context either way."""
    scope: dict = {}
    exec(compile("import sys\nframe = sys._getframe()\n", "<no such source>", "exec"), scope)
    frame = scope["frame"]
    assert inspect.getframeinfo(frame)[3] is None
    assert frontend._frameinfo_from_linecache(frame)[3] is None
    assert frontend._frameinfo_from_linecache(frame)[:3] == tuple(inspect.getframeinfo(frame)[:3])


def test_importing_the_kernels_searches_no_module_for_source_lines():
    """Importing Taichi and the solver's kernels (before any `init`) decorates some 400 Taichi
    functions, and Taichi reads the line above each: with the memos installed first (the
    subpackages' __init__) none of them goes to inspect.getframeinfo, which searched every
    loaded module (~300 did)."""
    import os
    import subprocess

    code = (
        "import inspect\n"
        "calls = []\n"
        "original = inspect.getframeinfo\n"
        "inspect.getframeinfo = lambda frame, context=1: calls.append(1) or original(frame, context)\n"
        "import taichi_dcd.solver.kernels, taichi_dcd.output.run\n"
        "print(len(calls))\n")
    env = {k: v for k, v in os.environ.items() if k != frontend.PLAIN_ENV}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-1] == "0"


@pytest.mark.parametrize("precision", ["f64", "f32"])
def test_upload_matches_from_numpy(precision):
    import taichi_dcd

    taichi_dcd.init(arch="cpu", precision=precision, debug=True)
    real = ti.f64 if precision == "f64" else ti.f32
    rng = np.random.default_rng(7)
    shapes = [(ti.field, (real,), (9,), ()), (ti.Vector.field, (3, ti.i32), (5,), (3,)),
              (ti.Matrix.field, (3, 3, real), (4,), (3, 3)), (ti.field, (ti.i32,), (3, 4), ()),
              (ti.Vector.field, (4, real), (2, 3), (4,)), (ti.field, (ti.u8,), (6,), ())]
    ours, theirs, arrays = [], [], []
    for make, args, shape, element in shapes:
        ours.append(make(*args, shape=shape))
        theirs.append(make(*args, shape=shape))
        dtype = args[-1]
        if dtype == real:
            arrays.append(rng.normal(size=shape + element) * 1e3)
        else:
            arrays.append(rng.integers(0, 200, size=shape + element).astype(
                np.uint8 if dtype == ti.u8 else np.int32))
    upload(list(zip(ours, arrays)))
    for mine, other, data in zip(ours, theirs, arrays):
        other.from_numpy(data)
        assert np.array_equal(mine.to_numpy(), other.to_numpy())
    with pytest.raises(ValueError):
        upload([(ours[0], np.zeros(8))])
