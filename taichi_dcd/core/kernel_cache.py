"""A folder of Taichi's offline kernel cache that no other running process writes to.

Taichi 1.7 writes, when a program ends or resets, the file of every kernel it compiled,
truncating any file of the same kernel first, and reads those files without a lock. Two
processes sharing one cache folder (a sweep's runs, a test suite's workers) that compile the
same kernels can therefore read a half-written one (the first suspect for a CI test
worker's death, which later happened once with separate folders too). Each process here
leases one of several numbered folders with an exclusive file lock held until it exits:
processes that run one after another share a warm folder, processes that run side by side
never share one.
"""

from __future__ import annotations

import os

try:
    import fcntl
except ImportError:  # Windows: no flock; Taichi's own shared folder is used there
    fcntl = None

MAX_SLOTS = 64
ENV_OVERRIDE = "TI_OFFLINE_CACHE_FILE_PATH"
# The folder a process tries first (a slot number), set by `run all` for its workers: the worker
# that runs the soft scene always takes the same folder, so that folder holds the soft frame
# kernels from one run to the next. (Leased in the order processes start, the soft scene's
# worker took either folder, and a warm `run all` compiled its kernels again half the time:
# 37-44 s before its first frame instead of 6 s.)
ENV_PREFERRED_SLOT = "TAICHI_DCD_CACHE_SLOT"

# The open lock file of the leased folder, kept for the life of the process: closing it
# would release the lease.
_lease: tuple[str, int] | None = None


def cache_root() -> str:
    """Where the numbered folders live: $XDG_CACHE_HOME (or ~/.cache)/taichi_dcd/kernels."""
    home = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(home, "taichi_dcd", "kernels")


def leased_folder(root: str | None = None) -> str | None:
    """The folder this process caches compiled kernels in, leased on the first call: the
    first free one, trying $TAICHI_DCD_CACHE_SLOT's first when it is set.

    None leaves the folder to Taichi (its shared default): when the user chose a folder
    themselves ($TI_OFFLINE_CACHE_FILE_PATH), when file locks are unavailable, when the
    cache root cannot be written, or when running processes hold all MAX_SLOTS folders.
    """
    global _lease
    if _lease is not None:
        return _lease[0]
    if os.environ.get(ENV_OVERRIDE) or fcntl is None:
        return None
    root = root or cache_root()
    preferred = os.environ.get(ENV_PREFERRED_SLOT, "")
    first = [int(preferred)] if preferred.isdigit() and int(preferred) < MAX_SLOTS else []
    for slot in first + [s for s in range(MAX_SLOTS) if s not in first]:
        folder = os.path.join(root, f"slot{slot:02d}")
        try:
            os.makedirs(folder, exist_ok=True)
            fd = os.open(os.path.join(folder, "lease.lock"), os.O_CREAT | os.O_RDWR, 0o644)
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        os.set_inheritable(fd, False)
        _lease = (folder, fd)
        return folder
    return None
