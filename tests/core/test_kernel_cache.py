"""Each running process caches compiled kernels in a folder of its own (kernel_cache).

Taichi rewrites the files of the kernels a program compiled when it ends, and reads them
without a lock, so processes sharing a folder can read half-written kernels. These tests
check that processes running side by side never share a folder, that processes running one
after another do (so later runs start warm), and that Taichi really writes there."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("fcntl")

LEASE_AND_WAIT = (
    "import sys\n"
    "from taichi_dcd.core import kernel_cache\n"
    "print(kernel_cache.leased_folder(sys.argv[1]), flush=True)\n"
    "sys.stdin.readline()\n"
)


def start_leaser(root: Path, preferred_slot: int | None = None) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k not in ("TI_OFFLINE_CACHE_FILE_PATH", "TAICHI_DCD_CACHE_SLOT")}
    if preferred_slot is not None:
        env["TAICHI_DCD_CACHE_SLOT"] = str(preferred_slot)
    return subprocess.Popen([sys.executable, "-c", LEASE_AND_WAIT, str(root)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=env)


def leased(process: subprocess.Popen) -> str:
    return Path(process.stdout.readline().strip()).name


def finish(process: subprocess.Popen) -> None:
    process.communicate("\n", timeout=60)
    assert process.returncode == 0


def test_processes_side_by_side_lease_different_folders_and_later_ones_reuse_them(tmp_path):
    first, second = start_leaser(tmp_path), start_leaser(tmp_path)
    try:
        names = {leased(first), leased(second)}
        assert names == {"slot00", "slot01"}
        third = start_leaser(tmp_path)
        assert leased(third) == "slot02"
        finish(third)
    finally:
        finish(first)
        finish(second)
    # Both leases ended with their processes: the next process gets the first folder again.
    later = start_leaser(tmp_path)
    assert leased(later) == "slot00"
    finish(later)


def test_a_preferred_folder_is_leased_first_while_it_is_free(tmp_path):
    """`run all` has its worker k try folder k first, so that the worker running the same scenes
    finds their kernels in the same folder every run, whichever worker starts first."""
    late_starter = start_leaser(tmp_path, preferred_slot=1)
    try:
        assert leased(late_starter) == "slot01"
        # Its folder taken, a process that prefers it takes the first free one instead.
        second = start_leaser(tmp_path, preferred_slot=1)
        assert leased(second) == "slot00"
        finish(second)
    finally:
        finish(late_starter)


def test_a_folder_the_user_names_is_left_to_taichi(tmp_path):
    code = ("import sys\nfrom taichi_dcd.core import kernel_cache\n"
            "print(kernel_cache.leased_folder(sys.argv[1]))")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True, timeout=60,
                         env=dict(os.environ, TI_OFFLINE_CACHE_FILE_PATH=str(tmp_path / "mine")))
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "None"
    assert not any(tmp_path.iterdir())


def test_taichi_writes_the_compiled_kernels_into_the_leased_folder(tmp_path):
    code = ("import numpy as np, taichi_dcd\n"
            "taichi_dcd.collide_triangle_pairs(np.random.rand(4, 3, 3), np.random.rand(4, 3, 3))\n")
    env = {k: v for k, v in os.environ.items() if k != "TI_OFFLINE_CACHE_FILE_PATH"}
    env["XDG_CACHE_HOME"] = str(tmp_path)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert out.returncode == 0, out.stderr
    folder = tmp_path / "taichi_dcd" / "kernels" / "slot00"
    assert list(folder.glob("*.tic")), sorted(p.name for p in folder.iterdir())
