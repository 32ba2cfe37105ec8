"""What every benchmark prints first: the machine and the versions it ran with."""

import os
import platform

import numpy as np


def machine_line() -> str:
    """One line naming the CPU, core count, OS and the Python/taichi/numpy versions."""
    model = platform.processor() or "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import taichi as ti

    ti_version = ".".join(map(str, ti.__version__))
    return (f"machine: {model}, {os.cpu_count()} logical cores, {platform.system()} {platform.machine()}; "
            f"Python {platform.python_version()}, taichi {ti_version}, numpy {np.__version__}")
