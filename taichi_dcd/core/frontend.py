"""Taichi's Python frontend made cheaper to repeat, with the same output.

Before Taichi can look a kernel up in its offline cache it turns the kernel's Python source into
its own IR again, in every process, inlining each `ti.func` at every call. Pure helpers of that
pass took more than half of it on the solver's frame kernel (Taichi 1.7):

- the source position of every AST node, formatted as an error-message excerpt (word-wrapped
  with `textwrap`) whether or not an error ever comes: ~120,000 times per frame kernel;
- the source lines of every inlined function, read, tokenised and re-filled line by line
  (`textwrap.fill`) again at each call;
- and, when a module of kernels is imported, the line above each decorated function, for
  which Python searches every loaded module for the function's file.

`speed_up()` memoises the source lines and the decorators' lines: each memo returns the very
lines the original returns for the same inputs. The subpackages that hold kernels run it when
they are imported, before their kernels and functions are decorated. A node's position, while
no error is being reported, is no longer Taichi's excerpt but its first line (file, line,
function) and the node's source line, without the word-wrapped caret lines (~0.6 s of a first
frame kernel's 2.6 s in the frontend). The position goes into the IR only as a message for
checks made after the transform (debug mode's bounds checks); it is not part of a kernel's
cache key, so compiled kernels and their cache keys are unchanged, and an error found while
transforming gets Taichi's own excerpt. It patches nothing it does not recognise.
"""

from __future__ import annotations

import functools
import os
import inspect
import linecache
import sys
import textwrap

_patched = False
# Set to 1 to leave Taichi's frontend as it is (to compare, or if a Taichi release breaks a memo).
PLAIN_ENV = "TAICHI_DCD_PLAIN_FRONTEND"
# The helpers replaced, for tests that compare against them.
_originals: dict = {}
_INSPECT_FRAMEINFO = inspect.getframeinfo


def left_plain() -> bool:
    """Whether the user asked for Taichi's frontend as it is (PLAIN_ENV=1)."""
    return os.environ.get(PLAIN_ENV) == "1"


def speed_up() -> bool:
    """Install the memos once per process (idempotent). Returns whether they are installed:
    False on a Taichi whose frontend does not have the helpers they wrap."""
    global _patched
    if _patched:
        return True
    if left_plain():
        return False
    # Taichi decorates its own library's functions as it is imported: inspect's own
    # getframeinfo is the memo's for that while (and only then).
    importing_taichi = "taichi" not in sys.modules
    if importing_taichi:
        inspect.getframeinfo = _frameinfo_from_linecache
    try:
        from taichi.lang import kernel_impl
        from taichi.lang.ast import ast_transformer_utils as utils
        context = utils.ASTTransformerContext
        original_pos_info = context.get_pos_info
        original_lines = kernel_impl.getsourcelines
        original_file = kernel_impl.getsourcefile
    except (ImportError, AttributeError):
        return False
    finally:
        if importing_taichi:
            inspect.getframeinfo = _INSPECT_FRAMEINFO

    _originals.update(get_pos_info=original_pos_info)

    def get_pos_info(ctx, node):
        if getattr(ctx, "raised", True):  # an error being reported: Taichi's own excerpt
            return original_pos_info(ctx, node)
        try:
            return _short_position(ctx, node)
        except (AttributeError, IndexError):
            return original_pos_info(ctx, node)

    context.get_pos_info = get_pos_info
    kernel_impl.getsourcelines = _memo_by_function(original_lines)
    kernel_impl.getsourcefile = _memo_by_function(original_file)
    if getattr(kernel_impl, "textwrap", None) is textwrap:
        kernel_impl.textwrap = _ModuleView(textwrap, fill=_remembered_fill())
    if getattr(kernel_impl, "inspect", None) is inspect:
        kernel_impl.inspect = _ModuleView(inspect, getframeinfo=_frameinfo_from_linecache)
    _patched = True
    return True


def _short_position(ctx, node) -> str:
    """A node's position as the IR keeps it for messages raised after the transform (debug
    checks, later type errors): Taichi's first line (file, line, function) and the node's
    first source line, not word-wrapped and without the caret line under it."""
    line = ctx.src[node.lineno - 1].rstrip()
    return (f'File "{ctx.file}", line {node.lineno + ctx.lineno_offset}, in {ctx.func.func.__name__}:\n'
            f"{line}\n")


class _ModuleView:
    """A module as Taichi's kernel_impl sees it: `module` with some functions replaced."""

    def __init__(self, module, **replaced):
        self._module = module
        self.__dict__.update(replaced)

    def __getattr__(self, name):
        return getattr(self._module, name)


def _remembered_fill():
    """textwrap.fill remembered per line and settings (Taichi re-fills every source line of a
    function at each inlined call)."""
    filled: dict = {}

    def fill(text, **settings):
        key = (text, tuple(sorted(settings.items())))
        out = filled.get(key)
        if out is None:
            out = filled[key] = textwrap.fill(text, **settings)
        return out

    return fill


def _frameinfo_from_linecache(frame, context=1):
    """inspect.getframeinfo for one line of context, its source line read from `linecache`
    by the frame's file name. Taichi's decorators read the line above each kernel and
    function (is it inside a class?), and inspect searched every loaded module for the
    frame's file at each one. A frame of no source file whose line linecache cannot find
    either (importlib's own, one level above a module's top-level decorators while it is
    imported) has no context, as inspect finds after its search. Other requests go to inspect."""
    if context == 1:
        filename, lineno, name = frame.f_code.co_filename, frame.f_lineno, frame.f_code.co_name
        line = linecache.getline(filename, lineno, frame.f_globals)
        if line:
            return (filename, lineno, name, [line], 0)
        if filename.startswith("<") and filename.endswith(">"):
            return (filename, lineno, name, None, None)
    getframeinfo = inspect.getframeinfo
    if getframeinfo is _frameinfo_from_linecache:  # inspect's own, while taichi is imported
        getframeinfo = _INSPECT_FRAMEINFO
    return getframeinfo(frame, context)


def _memo_by_function(read):
    """`read(func)` remembered per function object: a module's functions do not change
    their source while the process runs."""
    cache: dict = {}

    @functools.wraps(read)
    def remembered(func):
        try:
            return cache[func]
        except KeyError:
            pass
        except TypeError:
            return read(func)
        value = cache[func] = read(func)
        return value

    return remembered

