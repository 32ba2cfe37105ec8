"""The package skeleton: import without Taichi initialisation, one init, a CLI."""

import subprocess
import sys

import pytest

import taichi_dcd


def run_python(code: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)


def test_import_does_not_initialise_taichi():
    out = run_python(
        "import taichi_dcd, taichi as ti\n"
        "assert not taichi_dcd.is_initialized()\n"
        "assert ti.lang.impl.get_runtime().prog is None, 'ti.init ran at import'\n"
        "print('clean')"
    )
    assert out.returncode == 0, out.stderr
    assert "clean" in out.stdout


def test_first_call_initialises_with_defaults():
    out = run_python(
        "import numpy as np, taichi_dcd\n"
        "r = taichi_dcd.collide_triangle_pairs(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)))\n"
        "from taichi_dcd.core import runtime\n"
        "print(runtime.settings()['precision'], runtime.settings()['arch'], r.depth.dtype)"
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1].split() == ["f64", "cpu", "float64"]


def test_init_rejects_unknown_settings():
    with pytest.raises(ValueError, match="precision"):
        taichi_dcd.init(precision="f16")
    with pytest.raises(ValueError, match="arch"):
        taichi_dcd.init(arch="tpu")


def test_arrays_left_from_a_reset_program_leave_the_new_ones_alone():
    """init with other settings restarts Taichi. An ndarray of the old program still held
    then and dropped afterwards must not free the new program's array that took its
    address (Taichi's Ndarray.__del__ asks whichever program is current): the new arrays
    keep their values and the process does not crash."""
    out = run_python(
        "import gc, numpy as np, taichi as ti, taichi_dcd\n"
        "taichi_dcd.init(precision='f64', offline_cache=False)\n"
        "old = [ti.ndarray(ti.f64, shape=100) for _ in range(20)]\n"
        "taichi_dcd.init(precision='f32', offline_cache=False)\n"
        "new = [ti.ndarray(ti.f32, shape=100) for _ in range(20)]\n"
        "for k, a in enumerate(new):\n"
        "    a.from_numpy(np.full(100, k, np.float32))\n"
        "del old\n"
        "gc.collect()\n"
        "print('wrong', sum(not np.all(a.to_numpy() == k) for k, a in enumerate(new)))"
    )
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "wrong 0"


def test_cli_help_lists_commands():
    out = subprocess.run([sys.executable, "-m", "taichi_dcd", "--help"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "collide" in out.stdout


def test_cli_unknown_command_exits_2():
    out = subprocess.run([sys.executable, "-m", "taichi_dcd", "fly"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2
    assert out.stderr.strip().splitlines()[-1].startswith("taichi-dcd: error")
