"""Running the real command line in a subprocess, and checking what it left behind."""

import hashlib
import os
import subprocess
import sys
from pathlib import Path


def snapshot(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def run_cli(*args, cwd: Path, timeout: float = 300, env: dict | None = None) -> subprocess.CompletedProcess:
    env = dict(os.environ, ENABLE_TAICHI_HEADER_PRINT="False", **(env or {}))
    return subprocess.run([sys.executable, "-m", "taichi_dcd", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env=env)


def assert_one_line_error(result, status: int, *culprits: str):
    assert result.returncode == status, f"exit status {result.returncode}: {result.stderr}"
    assert "Traceback" not in result.stderr
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("taichi-dcd: error: "), last
    for culprit in culprits:
        assert culprit in last, f"{culprit!r} not in {last!r}"
