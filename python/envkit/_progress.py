"""envkit.batch's progress lines, end-of-run summary and JSON report.

A line per finished map on stderr (failures always, the others unless quiet):

    envkit.batch: [12/100] done sky_012.exr 3.41 s, 880 maps/h, ETA 6 min
    envkit.batch: [13/100] failed broken.exr: cannot read: ...

and at the end, on stdout, the counts, the rate and each failed file with its one-line reason.
"""

import os
import sys
import time

from ._cluster import write_json_atomic
from ._memory import format_bytes

STATUSES = ("done", "skipped", "failed")


def _duration(seconds):
    if seconds < 90:
        return "%.0f s" % seconds
    if seconds < 90 * 60:
        return "%.0f min" % (seconds / 60)
    return "%.1f h" % (seconds / 3600)


def reason(result):
    """The failed file's one-line message, naming the file once."""
    error = result["error"]
    return error if result["input"] in error else "%s: %s" % (result["input"], error)


class Progress:
    """Counts finished maps against `total` and prints a line for each (see the module's doc)."""

    def __init__(self, total, quiet=False, stream=None, clock=time.monotonic):
        self.total = total
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.clock = clock
        self.start = clock()
        self.finished = 0

    def elapsed(self):
        return self.clock() - self.start

    def maps_per_hour(self):
        elapsed = self.elapsed()
        return 3600.0 * self.finished / elapsed if elapsed > 0 else 0.0

    def __call__(self, result):
        self.finished += 1
        head = "envkit.batch: [%d/%d] %s" % (self.finished, self.total, result["status"])
        if result["status"] == "failed":
            print("%s %s" % (head, reason(result)), file=self.stream, flush=True)
            return
        if self.quiet:
            return
        remaining = self.total - self.finished
        eta = ", ETA %s" % _duration(self.elapsed() / self.finished * remaining) if remaining else ""
        name = os.path.basename(result["input"])
        print("%s %s %.2f s, %.0f maps/h%s" % (head, name, result["seconds"], self.maps_per_hour(), eta),
              file=self.stream, flush=True)


def counts(results):
    return {s: sum(r["status"] == s for r in results) for s in STATUSES}


def summary(results, seconds, worker_peaks=None, memory_limit=None):
    """The end-of-run lines: counts, time and rate; the workers' peak memory against the limit; each failed file
    with its reason."""
    c = counts(results)
    rate = 3600.0 * len(results) / seconds if seconds > 0 else 0.0
    lines = ["envkit.batch: %d done, %d skipped, %d failed in %.2f s (%.0f maps/h)" % (
        c["done"], c["skipped"], c["failed"], seconds, rate)]
    if worker_peaks:
        peaks = ", ".join(format_bytes(v) for v in sorted(worker_peaks.values(), reverse=True))
        limit = " (limit %s per worker)" % format_bytes(memory_limit) if memory_limit else ""
        lines.append("envkit.batch: peak memory per worker: %s%s" % (peaks, limit))
    failed = [r for r in results if r["status"] == "failed"]
    if failed:
        lines.append("envkit.batch: failed files:")
        lines.extend("  %s" % reason(r) for r in failed)
    return lines


def write_report(path, results, seconds, worker_peaks=None, memory_limit=None):
    """The JSON report: every file with its status (done, skipped, failed), outputs, error, seconds and predicted
    peak memory; the counts; the workers' peak memory and the limit, in bytes."""
    write_json_atomic(path, {
        "results": results,
        "counts": counts(results),
        "seconds": seconds,
        "maps_per_hour": 3600.0 * len(results) / seconds if seconds > 0 else 0.0,
        "memory_limit_bytes": memory_limit,
        "worker_peak_bytes": worker_peaks or {},
    })
