"""Run a command and report its wall time and peak memory (whole process tree)."""

from __future__ import annotations

import subprocess
import time

import psutil


def run_measured(cmd: list[str], poll_s: float = 0.1) -> dict:
    """Wall time, peak resident memory summed over the process and its children, and exit code."""
    start = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    peak = 0
    ps = psutil.Process(proc.pid)
    while proc.poll() is None:
        try:
            tree = [ps, *ps.children(recursive=True)]
            peak = max(peak, sum(p.memory_info().rss for p in tree if p.is_running()))
        except psutil.Error:
            pass
        time.sleep(poll_s)
    out, err = proc.communicate()
    return {
        "seconds": time.perf_counter() - start,
        "peak_gb": peak / 1e9,
        "returncode": proc.returncode,
        "stdout": out,
        "stderr": err,
    }
