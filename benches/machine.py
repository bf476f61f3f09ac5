"""What the benchmarks report about the machine they ran on (shared by the bench scripts)."""

from __future__ import annotations

import os
import platform


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def load_average() -> str:
    """The 1/5/15-minute load at the end of the run: other work competing for the cores."""
    try:
        return "{:.2f} / {:.2f} / {:.2f} (1 / 5 / 15 min, at the end)".format(*os.getloadavg())
    except OSError:
        return "unknown"
