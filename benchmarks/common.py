"""What every benchmark prints first: the machine and the versions it ran with."""

import os
import platform

import numpy as np


def machine_line() -> str:
    """One line naming the CPU (and its widest SIMD, which the batch narrow phase uses), core
    count, OS and the Python/taichi/numpy versions."""
    model = platform.processor() or "unknown CPU"
    flags: set[str] = set()
    try:
        with open("/proc/cpuinfo") as f:
            first_cpu = f.read().split("\n\n")[0]
        fields = {key.strip(): value.strip() for key, value in
                  (line.split(":", 1) for line in first_cpu.splitlines() if ":" in line)}
        model = fields.get("model name", model)
        flags = set(fields.get("flags", "").split())
    except OSError:
        pass
    simd = next((name for flag, name in (("avx512f", "AVX-512"), ("avx2", "AVX2"), ("sse2", "SSE2"))
                 if flag in flags), None)
    if simd:
        model += f" ({simd})"
    import taichi as ti

    ti_version = ".".join(map(str, ti.__version__))
    return (f"machine: {model}, {os.cpu_count()} logical cores, {platform.system()} {platform.machine()}; "
            f"Python {platform.python_version()}, taichi {ti_version}, numpy {np.__version__}")
