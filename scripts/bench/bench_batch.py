#!/usr/bin/env python3
"""envkit.batch on 2 workers against loops of the CLIs, in maps per hour, and each worker's peak memory against the
stated bound (docs/PYTHON.md, python/envkit/_memory.py).

A synthetic library of lat-long EXR maps (zip), widths cycling through --widths, is written to a temporary folder
(numpy, written by envkit). Each repeat times, interleaved, end to end (process and cluster start-up included):
  - `python3 -m envkit.batch IN OUT --workers 2 --force -q --report R` (convert to lat-long at the input's density,
    bake hierarchical tables: the defaults);
  - a shell loop: `envconvert MAP -o OUT --to latlong -q; envbake MAP -o OUT -q` for each map, one after another
    (each CLI on both cores through oneTBB);
  - the same pairs two at a time (`xargs -P 2`).
The workers' peak resident memory (VmHWM) comes from batch's report; the bound is the prediction for the largest
map. --huge adds one run of a single 16384 x 8192 map on 1 worker: its peak against its prediction.

  PYTHONPATH=scripts /usr/bin/python3 -m bench.bench_batch                 (24 maps 512..2048 wide, 3 repeats)
  PYTHONPATH=scripts /usr/bin/python3 -m bench.bench_batch --full          (100 maps 512..4096 wide, 2 repeats)
  PYTHONPATH=scripts /usr/bin/python3 -m bench.bench_batch --huge          (also the 16k map: about 8 min more)
Needs build/python (envkit), build/bin (envconvert, envbake) and dask.distributed.
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

from bench.common import ROOT


def write_map(envkit, np, path, width, seed):
    """A sky-like lat-long map: a vertical gradient with noise and a small bright sun."""
    height = width // 2
    rng = np.random.default_rng(seed)
    y = np.linspace(1.0, 0.1, height, dtype=np.float32)[:, None, None]
    a = y * np.array([0.6, 0.8, 1.0], np.float32) * (1 + 0.2 * rng.random((height, width, 1), dtype=np.float32))
    s = max(2, height // 90)
    r, c = int(rng.integers(s, height // 2)), int(rng.integers(0, width - s))
    a[r:r + s, c:c + s] = 20000.0
    envkit.EnvMap(a, parameterization="latlong").write(path)


def library(envkit, np, folder, count, widths):
    os.makedirs(folder)
    for k in range(count):
        write_map(envkit, np, os.path.join(folder, "sky_%03d.exr" % k), widths[k % len(widths)], k)


def timed(cmd, env):
    start = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def run_batch(in_dir, out_dir, report, env, workers=2):
    t = timed([sys.executable, "-m", "envkit.batch", in_dir, out_dir, "--workers", str(workers), "--force", "-q",
               "--report", report], env)
    with open(report) as f:
        return t, json.load(f)


def cli_pair(build, in_path, out_dir):
    stem = os.path.splitext(os.path.basename(in_path))[0]
    return "%s %s -o %s --to latlong -q && %s %s -o %s -q" % (
        shlex.quote(os.path.join(build, "bin", "envconvert")), shlex.quote(in_path),
        shlex.quote(os.path.join(out_dir, stem + ".latlong.exr")), shlex.quote(os.path.join(build, "bin", "envbake")),
        shlex.quote(in_path), shlex.quote(os.path.join(out_dir, stem + ".envtbl")))


def run_loop(build, in_dir, out_dir, parallel, env):
    os.makedirs(out_dir, exist_ok=True)
    maps = sorted(os.path.join(in_dir, n) for n in os.listdir(in_dir))
    if parallel == 1:
        script = "\n".join(cli_pair(build, m, out_dir) for m in maps)
        return timed(["bash", "-ec", script], env)
    lines = "".join(cli_pair(build, m, out_dir) + "\n" for m in maps)
    start = time.perf_counter()
    subprocess.run(["xargs", "-P", str(parallel), "-d", "\n", "-I", "{}", "bash", "-ec", "{}"], input=lines,
                   text=True, check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def gb(n):
    return n / (1 << 30)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--maps", type=int, help="maps in the library (default 24; --full 100)")
    p.add_argument("--widths", help="lat-long widths, cycled (default 512,1024,2048; --full 512,1024,2048,4096)")
    p.add_argument("--repeats", type=int, help="interleaved repeats (default 3; --full 2)")
    p.add_argument("--full", action="store_true", help="100 maps 512..4096 wide, 2 repeats")
    p.add_argument("--huge", action="store_true", help="also a run of one 16384 x 8192 map on 1 worker")
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    args = p.parse_args()
    for name, default, full in (("maps", 24, 100), ("widths", "512,1024,2048", "512,1024,2048,4096"),
                                ("repeats", 3, 2)):
        if getattr(args, name) is None:
            setattr(args, name, full if args.full else default)
    widths = [int(w) for w in args.widths.split(",")]
    sys.path.insert(0, os.path.join(args.build, "python"))
    import numpy as np

    import envkit
    from envkit import _memory, batch

    env = dict(os.environ, PYTHONPATH=os.path.join(args.build, "python"))
    print("envkit.batch benchmark: %d maps, widths %s, %d repeats, %d cores, load average %s" % (
        args.maps, args.widths, args.repeats, os.cpu_count(), open("/proc/loadavg").read().split()[0]), flush=True)
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as work:
        in_dir = os.path.join(work, "in")
        start = time.perf_counter()
        library(envkit, np, in_dir, args.maps, widths)
        print("library written in %.1f s" % (time.perf_counter() - start), flush=True)
        options = batch.default_options()
        largest = max(_memory.predicted_peak(*_memory.header(os.path.join(in_dir, n)), options)
                      for n in os.listdir(in_dir))
        times = {"envkit.batch, 2 workers": [], "shell loop": [], "xargs -P 2": []}
        peaks = []
        for r in range(args.repeats):
            t, report = run_batch(in_dir, os.path.join(work, "batch"), os.path.join(work, "r.json"), env)
            assert report["counts"]["done"] == args.maps, report["counts"]
            times["envkit.batch, 2 workers"].append(t)
            peaks.append(report["worker_peak_bytes"])
            times["shell loop"].append(run_loop(args.build, in_dir, os.path.join(work, "loop"), 1, env))
            times["xargs -P 2"].append(run_loop(args.build, in_dir, os.path.join(work, "xargs"), 2, env))
            print("repeat %d: %s" % (r + 1, ", ".join("%s %.1f s" % (k, v[-1]) for k, v in times.items())),
                  flush=True)
        base = statistics.median(times["shell loop"])
        print("\n| run | median s | maps/h | / shell loop time |")
        print("|---|---:|---:|---:|")
        for k, v in times.items():
            m = statistics.median(v)
            print("| %s | %.1f | %.0f | %.3f |" % (k, m, 3600 * args.maps / m, m / base))
        worst = max(max(p.values()) for p in peaks)
        print("\npeak memory per worker (each repeat): %s GB; bound for the largest map %.2f GB (limit %.2f GB)" % (
            "; ".join(", ".join("%.2f" % gb(v) for v in sorted(p.values(), reverse=True)) for p in peaks),
            gb(largest), gb(report["memory_limit_bytes"])))
        print("largest worker peak / bound: %.3f" % (worst / largest))
        if args.huge:
            huge = os.path.join(work, "huge")
            os.makedirs(huge)
            write_map(envkit, np, os.path.join(huge, "sky_16k.exr"), 16384, 0)
            t, report = run_batch(huge, os.path.join(work, "huge_out"), os.path.join(work, "h.json"), env, workers=1)
            bound = report["results"][0]["predicted_bytes"]
            peak = max(report["worker_peak_bytes"].values())
            print("\n16384 x 8192 on 1 worker: %.1f s, peak %.2f GB, bound %.2f GB (peak / bound %.3f)" % (
                t, gb(peak), gb(bound), peak / bound))


if __name__ == "__main__":
    main()
