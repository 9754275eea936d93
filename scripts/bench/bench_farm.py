#!/usr/bin/env python3
"""envkit.farm on 2 workers x 1 thread against one process with 2 threads, and the farm's cost per tile size.

The built-in default scene at --resolution and --spp, rendered
  - in one process: envkit.farm's own scene object rendering the whole image on 2 oneTBB threads, then written with
    envrender's writer (what envrender --threads 2 does once its scene is loaded);
  - on a LocalCluster of 2 worker processes x 1 dask thread, each tile on 1 oneTBB thread (envkit.farm.run: tiles
    written to the work folder, merged, written), the cluster started and the scene loaded on each worker before
    the timed runs (a warm-up run), so the figure is the farm's overhead, not the cluster's start-up.
Runs are interleaved (one-process, then each tile size, --repeats times); the table gives medians, the farm's time
over the one-process time, and the merge (reading the tiles and assembling the film's sums) and the writing of the
EXR and PNG apart. --cli adds one end-to-end pair: `python3 -m envkit.farm --workers 2` against `envrender
--threads 2` (process and cluster start-up included).

  PYTHONPATH=scripts /usr/bin/python3 -m bench.bench_farm                       (480x240, 64 spp, 5 repeats)
  PYTHONPATH=scripts /usr/bin/python3 -m bench.bench_farm --quick               (240x120, 16 spp, 3 repeats)
Needs build/python (envkit with the renderer) and dask.distributed.
"""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

from bench.common import ROOT


def _tile_arg(text):
    if text.startswith("bands"):
        return {"tiles": int(text[len("bands"):])}
    w, h = map(int, text.split("x"))
    return {"tile_size": (w, h)}


def one_process(farm, job, out):
    """The whole image on 2 threads in this process, written as the farm writes it."""
    start = time.perf_counter()
    frame_job = job.jobs[0]
    o = job.options
    sums = frame_job.render((0, 0, job.width, job.height), o["spp"], o["seed"], 2)
    farm.write_film(out, sums, {"envkit:renderer": "bench"}, preview=True)
    return time.perf_counter() - start


def farmed(farm, client, job):
    start = time.perf_counter()
    r = farm.run(client, job, force=True)
    return time.perf_counter() - start, r["merge_seconds"][0], r["write_seconds"][0]


def cli_pair(args, work):
    env = dict(os.environ, PYTHONPATH=os.path.join(args.build, "python"))
    res = ["--resolution", args.resolution, "--spp", str(args.spp)]
    t = {}
    for name, cmd in [("envrender --threads 2", [os.path.join(args.build, "bin", "envrender"), "-q", "--threads", "2",
                                                 "-o", os.path.join(work, "cli_envrender.exr")] + res),
                      ("envkit.farm --workers 2", [sys.executable, "-m", "envkit.farm", "-q", "--workers", "2",
                                                   "--render-threads", "1", "-o",
                                                   os.path.join(work, "cli_farm.exr")] + res)]:
        start = time.perf_counter()
        subprocess.run(cmd, check=True, env=env)
        t[name] = time.perf_counter() - start
    return t


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--resolution", help="default 480x240 (--quick 240x120)")
    p.add_argument("--spp", type=int, help="default 64 (--quick 16)")
    p.add_argument("--repeats", type=int, help="default 5 (--quick 3)")
    p.add_argument("--tiles", default="bands2,128x128,64x64,32x32",
                   help="tilings to time: bandsN (N bands of rows) or WxH tiles")
    p.add_argument("--quick", action="store_true", help="smaller defaults: 240x120, 16 spp, 3 repeats")
    p.add_argument("--cli", action="store_true", help="also one end-to-end pair of command lines")
    p.add_argument("--build", default=os.path.join(ROOT, "build"))
    args = p.parse_args()
    for name, full, quick in (("resolution", "480x240", "240x120"), ("spp", 64, 16), ("repeats", 5, 3)):
        if getattr(args, name) is None:
            setattr(args, name, quick if args.quick else full)
    sys.path.insert(0, os.path.join(args.build, "python"))
    import distributed
    from envkit import farm

    width, height = map(int, args.resolution.split("x"))
    options = farm.default_options(spp=args.spp, width=width, height=height, threads=1)
    print("envkit.farm benchmark: default scene %dx%d, %d spp, %d repeats, %d cores, load average %s" % (
        width, height, args.spp, args.repeats, os.cpu_count(), open("/proc/loadavg").read().split()[0]))
    with tempfile.TemporaryDirectory() as work:
        tilings = [t.strip() for t in args.tiles.split(",") if t.strip()]
        jobs = {t: farm.Job(farm.frames(), [os.path.join(work, "farm_%s.exr" % t)], options, **_tile_arg(t))
                for t in tilings}
        single = jobs[tilings[0]]
        cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
        client = distributed.Client(cluster)
        try:
            for t in tilings:  # warm-up: every worker loads the scene once
                farmed(farm, client, jobs[t])
            one_process(farm, single, os.path.join(work, "one.exr"))
            times = {"one process": []}
            parts = {t: ([], [], []) for t in tilings}
            for _ in range(args.repeats):
                times["one process"].append(one_process(farm, single, os.path.join(work, "one.exr")))
                for t in tilings:
                    for acc, v in zip(parts[t], farmed(farm, client, jobs[t])):
                        acc.append(v)
        finally:
            client.close()
            cluster.close()
        base = statistics.median(times["one process"])
        print("\n| run | tiles | median s | / one process | merge s | write s |")
        print("|---|---:|---:|---:|---:|---:|")
        print("| one process, 2 threads | 1 | %.3f | 1.000 | - | (included) |" % base)
        for t in tilings:
            total, merge, write = (statistics.median(v) for v in parts[t])
            print("| 2 workers x 1 thread, %s | %d | %.3f | %.3f | %.4f | %.4f |" % (
                t, len(jobs[t].crops), total, total / base, merge, write))
        if args.cli:
            t = cli_pair(args, work)
            print("\nend to end (one run each): " + ", ".join("%s %.2f s" % kv for kv in t.items()))


if __name__ == "__main__":
    main()
