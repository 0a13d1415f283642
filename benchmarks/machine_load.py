"""How busy the machine was while a benchmark ran: its timings are clean only when other processes took ~0 CPU.

    start = (time.perf_counter(), busy_cpu_s(), own_cpu_s()); ...; print(other_load_line(start))
"""
from __future__ import annotations

import json
import os
import resource
import time
from pathlib import Path


def busy_cpu_s() -> float:
    """CPU seconds all processes of the machine have used since boot (/proc/stat), 0 where there is none."""
    try:
        fields = Path("/proc/stat").read_text().splitlines()[0].split()
    except OSError:
        return 0.0
    user, nice, system, _idle, _iowait, irq, softirq, steal = (int(v) for v in fields[1:9])
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def own_cpu_s() -> float:
    """CPU seconds of this process and of every child it has waited for (their compilers included)."""
    return sum(u.ru_utime + u.ru_stime for u in (resource.getrusage(resource.RUSAGE_SELF),
                                                  resource.getrusage(resource.RUSAGE_CHILDREN)))


def other_load_line(start: tuple[float, float, float]) -> str:
    """How much CPU other processes took while the benchmark ran: its numbers are clean only near 0."""
    wall = time.perf_counter() - start[0]
    other = max(0.0, (busy_cpu_s() - start[1]) - (own_cpu_s() - start[2]))
    return (f"other processes used {other:.0f} CPU-s during the benchmark's {wall:.0f} s "
            f"({100 * other / wall:.0f} % of one of {os.cpu_count()} CPUs; near 0 on a quiet machine)")


def measured_at(command: str) -> dict:
    """When and from what a benchmark's record was measured: the command, the date and the commit."""
    import datetime
    import subprocess

    root = Path(__file__).resolve().parents[1]
    done = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True, text=True)
    return {"command": command, "date": datetime.date.today().isoformat(), "commit": done.stdout.strip() or "unknown"}


def provenance(command: str) -> dict:
    """Where and when a benchmark's record was measured: `measured_at` and the machine (for timings)."""
    import platform

    return {**measured_at(command),
            "machine": f"{platform.machine()}, {os.cpu_count()} CPUs, Python {platform.python_version()}"}


def write_record(path, record: dict) -> None:
    """A benchmark's record as docs/numbers keeps it: JSON, one-space indent, sorted keys, a final newline."""
    Path(path).write_text(json.dumps(record, indent=1, sort_keys=True) + "\n", encoding="utf-8")
