"""The one place Taichi is initialised, and the numeric settings every kernel reads.

Importing `taichi_dcd` never calls `ti.init`; the first public call that needs a
kernel initialises Taichi with the defaults below unless the user called `init`
first. Calling `init` again with other settings resets Taichi (all fields and
compiled kernels are dropped) and starts it anew.
"""

from __future__ import annotations

import gc
from contextlib import contextmanager

import numpy as np
import taichi as ti
from taichi.lang._ndarray import Ndarray

from . import frontend, kernel_cache, pool, traced_ops

ARCHS = ("cpu", "cuda", "vulkan")
PRECISIONS = ("f32", "f64")

# Geometric decisions treat quantities within TOL_ULPS machine epsilons of zero
# (relative to the size of the triangles involved) as zero. The rounding error of
# a signed distance N·(p - q) is a few epsilons times |p - q|; 32 leaves margin.
TOL_ULPS = 32.0

_settings: dict | None = None

CUDA_POOL_GB = 4.0

# The most a kernel cache folder may hold before Taichi deletes its least recently used
# quarter. Taichi's own default, 100 MB, is less than the kernels of `run all` and the test
# suite together: each folder stayed at 96-98 MB, and the soft scene's frame kernel was
# deleted between runs and compiled again (36 s before its first frame instead of 7).
OFFLINE_CACHE_BYTES = 1 << 30


def init(
    arch: str = "cpu",
    precision: str = "f64",
    debug: bool = False,
    cpu_threads: int | None = None,
    offline_cache: bool = True,
) -> None:
    """Initialise Taichi for taichi_dcd.

    arch: "cpu", "cuda" or "vulkan". precision: "f32" or "f64", the float type of
    every kernel. debug: Taichi's bounds checking (slow; used by the tests).
    cpu_threads: limit the CPU backend's threads (1 makes runs repeatable).
    offline_cache: keep compiled kernels on disk for later processes, in a folder this
    process leases for itself (kernel_cache.leased_folder).
    Calling again with the same settings does nothing.
    """
    global _settings, _chosen
    wanted = _checked_settings(arch, precision, debug, cpu_threads, offline_cache)
    if _settings == wanted:
        return
    reset()
    kwargs = dict(
        arch=getattr(ti, arch),
        default_fp=ti.f64 if precision == "f64" else ti.f32,
        default_ip=ti.i32,
        debug=bool(debug),
        offline_cache=bool(offline_cache),
        log_level=ti.WARN,
        # Fast math lets LLVM reassociate differently in each kernel that inlines
        # a predicate, so a touching pair could be a hit in one kernel and not in
        # another; the narrow phase costs the same without it.
        fast_math=False,
        # Taichi's own IR optimiser takes 40 s on the solver's one-kernel frame (its
        # nested serial loops inline the narrow phase and the rigid-body maths) and
        # 5 s without; LLVM still optimises, and no kernel here ran slower without it.
        advanced_optimization=False,
    )
    if cpu_threads is not None:
        kwargs["cpu_max_num_threads"] = int(cpu_threads)
    if arch == "cuda":
        # Taichi's CUDA backend serves every field from a pool it takes at start (1 GB
        # unless told); the pile's fields and contact rows need about half that on the CPU.
        kwargs["device_memory_GB"] = CUDA_POOL_GB
    if offline_cache:
        kwargs["offline_cache_max_size_of_files"] = OFFLINE_CACHE_BYTES
        if (folder := kernel_cache.leased_folder()) is not None:
            kwargs["offline_cache_file_path"] = folder
    frontend.speed_up()
    traced_ops.install()
    ti.init(**kwargs)
    got = ti.lang.impl.current_cfg().arch
    if got != getattr(ti, arch):
        ti.reset()
        _settings = None
        raise RuntimeError(f"Taichi could not start on arch {arch!r} on this machine")
    _settings = wanted
    _chosen = None


def _checked_settings(arch, precision, debug, cpu_threads, offline_cache) -> dict:
    if arch not in ARCHS:
        raise ValueError(f"unknown arch {arch!r}: choose one of {', '.join(ARCHS)}")
    if precision not in PRECISIONS:
        raise ValueError(f"unknown precision {precision!r}: choose one of {', '.join(PRECISIONS)}")
    if cpu_threads is not None and cpu_threads < 1:
        raise ValueError(f"cpu_threads must be at least 1, got {cpu_threads}")
    return dict(arch=arch, precision=precision, debug=bool(debug),
                cpu_threads=cpu_threads, offline_cache=bool(offline_cache))


# Settings chosen by init_when_needed for the first ensure_init, or None.
_chosen: dict | None = None


def init_when_needed(arch: str = "cpu", precision: str = "f64", debug: bool = False,
                     cpu_threads: int | None = None, offline_cache: bool = True) -> None:
    """`init`'s settings (checked now), applied by the first call that needs Taichi; at once if
    Taichi is running. The command line chooses its settings before it has read the scene's
    meshes, and a scene refused for a bad mesh should not have started Taichi at all."""
    global _chosen
    wanted = _checked_settings(arch, precision, debug, cpu_threads, offline_cache)
    if _settings is not None:
        init(**wanted)
    else:
        _chosen = wanted


# Ndarrays of programs already reset that were still referenced then (see reset).
_stale_ndarrays: list = []


def reset() -> None:
    """Drop the running Taichi program (its fields and compiled kernels); the next call
    that needs Taichi starts it anew. Fields and solvers made before are unusable after."""
    global _settings
    if _settings is not None:
        # Taichi's Ndarray.__del__ hands its pointer to whichever program is current then:
        # an array of this program collected after the next init would free the new
        # program's array that reuses its address (test workers died in JIT code). What
        # can die now dies under its own program; the rest is kept alive for good.
        gc.collect()
        _stale_ndarrays.extend(o for o in gc.get_objects() if isinstance(o, Ndarray))
        pool.clear()
        ti.reset()
        _settings = None


# While a field_block is open: its FieldsBuilder and the fills waiting for finalize.
_block: tuple | None = None


@contextmanager
def field_block():
    """Allocate every field created by model.scalar_field / vec_field / mat_field inside
    the block in one Taichi SNode tree, filled (`fill`) when the block closes. Taichi gives
    each field made after the first kernel launch a tree of its own, and a program holds
    only a few hundred: one tree per field let about twenty scenes be built in one process
    before Taichi crashed. Nested blocks join the outermost."""
    global _block
    if _block is not None:
        yield
        return
    builder, fills, placed = ti.FieldsBuilder(), [], []
    _block = (builder, fills, placed)
    try:
        yield
    finally:
        _block = None
    if placed:
        builder.finalize()
    from .upload import upload  # upload's kernel reads this module's settings
    upload(fills)


def in_field_block() -> bool:
    return _block is not None


def place(fld, shape) -> bool:
    """Place a shapeless field in the open block (True), or do nothing (False)."""
    if _block is None:
        return False
    _block[0].dense(ti.ij if isinstance(shape, tuple) else ti.i, shape).place(fld)
    _block[2].append(fld)
    return True


def fill(fld, data: np.ndarray) -> None:
    """fld.from_numpy(data), at the end of the open block if there is one."""
    if _block is None:
        fld.from_numpy(data)
    else:
        _block[1].append((fld, data))


def ensure_init() -> None:
    """Initialise, with init_when_needed's settings or the defaults, if nobody has yet."""
    if _settings is None:
        init(**(_chosen or {}))


def is_initialized() -> bool:
    return _settings is not None


def settings() -> dict:
    """The settings of the running Taichi instance (initialising it if needed)."""
    ensure_init()
    return dict(_settings)


# Below this many loop iterations a CPU kernel's loops run serially: on these
# machines a parallel loop costs ~120 µs to dispatch to the thread pool, and its
# atomics cost ~5× a serial loop's (Taichi demotes atomics in serial loops).
PARALLEL_MIN_WORK = 200_000


def serial_loops(work: int) -> bool:
    """Whether a kernel whose loops do about `work` iterations should run them serially:
    always on one CPU thread, below PARALLEL_MIN_WORK on CPU, never on a GPU. Loops that append
    (the broad and narrow phases) give the same order either way (core.scan)."""
    ensure_init()
    if _settings["arch"] != "cpu":
        return False
    return _settings["cpu_threads"] == 1 or work < PARALLEL_MIN_WORK


def precision() -> str:
    ensure_init()
    return _settings["precision"]


def arch() -> str:
    """The arch Taichi runs on ("cpu" or "cuda")."""
    ensure_init()
    return _settings["arch"]


def real_type():
    """Taichi float type of the kernels (ti.f64 or ti.f32), for allocating arrays."""
    return ti.f64 if precision() == "f64" else ti.f32


def real_dtype() -> type:
    """NumPy float type matching the kernels' precision."""
    return np.float64 if precision() == "f64" else np.float32


def machine_eps() -> float:
    """Machine epsilon of the kernels' float type."""
    return float(np.finfo(real_dtype()).eps)


def tolerance() -> float:
    """Dimensionless zero threshold used by the geometric predicates: TOL_ULPS·eps."""
    return TOL_ULPS * machine_eps()
