#!/usr/bin/env bash
# Benchmarks of the Python module envkit (docs/PYTHON.md), each against its peer in the same run:
#  1. call overhead of small calls (Tables.pdf / sample on one vector, EnvMap.width), median of many calls;
#  2. vectorised Tables.sample on an 8192x4096 map (M samples/s per method, GIL released, oneTBB over the cores),
#     batched (the default) against the one-sample path (batched=False), and the C++ loops of the same calls (one
#     thread, bench_env_sampling Sample and SampleBatch) for context;
#  3. batch throughput: envkit.batch (convert + bake) on a LocalCluster of two workers vs envconvert + envbake
#     back to back on the same files; medians of interleaved repeats, ratio reported.
# Usage: scripts/bench/bench_python.sh [--quick] [--sampling] [--build DIR]   (builds nothing; run scripts/build.sh first)
#   --sampling: sections 1 and 2 only.
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build="${ENVKIT_BUILD_DIR:-$root/build}"
quick=0
sampling_only=0
while [ $# -gt 0 ]; do
  case "$1" in
    --quick) quick=1 ;;
    --sampling) sampling_only=1 ;;
    --build) build="$2"; shift ;;
    *) echo "usage: $0 [--quick] [--sampling] [--build DIR]" >&2; exit 2 ;;
  esac
  shift
done
[ -d "$build/python/envkit" ] || { echo "bench_python: $build/python/envkit missing: run scripts/build.sh" >&2; exit 1; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
export PYTHONPATH="$build/python" ENVKIT_BIN="$build/bin" QUICK="$quick" SAMPLING_ONLY="$sampling_only" WORK="$work"
# The LocalCluster's worker processes re-import the main module by path: the script must be a file.
cat > "$work/bench_python.py" <<'EOF'
import os, statistics, subprocess, sys, time
import numpy as np
import envkit
from envkit import batch


def main():

    quick = os.environ["QUICK"] == "1"
    work = os.environ["WORK"]
    bin_dir = os.environ["ENVKIT_BIN"]
    print("envkit Python benchmarks (%s), %d cores, numpy %s, load average %s" % (
        "quick" if quick else "full", os.cpu_count(), np.__version__, open("/proc/loadavg").read().split()[0]))

    # 1. Call overhead.
    small = envkit.EnvMap(np.ones((64, 128, 3), np.float32), parameterization="latlong")
    t_small = envkit.bake(small)
    d1 = np.array([0.3, 0.8, 0.5])
    u1 = np.array([0.25, 0.75])

    def per_call(f, n=20000):
        reps = []
        for _ in range(5):
            s = time.perf_counter()
            for _ in range(n):
                f()
            reps.append((time.perf_counter() - s) / n)
        return statistics.median(reps) * 1e6

    print("\n1. call overhead (median of 5 x 20000 calls)")
    for name, f in [("EnvMap.width (property)", lambda: small.width),
                    ("Tables.pdf(1 direction)", lambda: t_small.pdf(d1)),
                    ("Tables.sample(1 u)", lambda: t_small.sample(u1)),
                    ("EnvMap.texel_of(1 direction)", lambda: small.texel_of(d1))]:
        print("   %-30s %8.2f us/call   (target < 50 us)" % (name, per_call(f)))

    # 2. Vectorised sampling at 8k.
    w, h = (2048, 1024) if quick else (8192, 4096)
    rng = np.random.default_rng(7)
    # bench_env_sampling's map: sky 0.3 + 0.7 max(y, 0) (per row), a ~0.5 degree sun carrying most of the power;
    # written in place through the zero-copy data view of a blank map.
    sky = envkit.EnvMap.blank(h, "latlong")  # envkit's storage, filled in place (no input copy)
    y = np.cos(np.pi * (np.arange(h) + 0.5) / h)
    sky.data[...] = (0.3 + 0.7 * np.maximum(y, 0.0))[:, None, None] * np.array([0.8, 0.9, 1.2], np.float32)
    sun = np.array([0.4, 0.5, -0.7]) / np.linalg.norm([0.4, 0.5, -0.7])
    x0, y0 = sky.texel_of(sun).astype(int)
    r = max(1, int(round(0.0045 / (np.pi / h))))
    sky.data[y0 - r : y0 + r + 1, x0 - r : x0 + r + 1] = 4e5
    # The one copy an array input costs (docs/PYTHON.md, "Arrays in and out"), on this map's pixels.
    arr = np.ascontiguousarray(sky.data)
    copies = []
    for _ in range(3):
        s = time.perf_counter()
        envkit.EnvMap(arr, parameterization="latlong")
        copies.append(time.perf_counter() - s)
    print("\n   EnvMap(array) of %dx%dx3 float32 (borrowed, no copy: the NaN/Inf scan): %.3f s (median of 3)"
          % (w, h, statistics.median(copies)))
    del arr
    s = time.perf_counter()
    t8 = envkit.bake(sky)
    del sky
    print("\n2. vectorised sample on a %dx%d map (bake %.1f s)" % (w, h, time.perf_counter() - s))
    n = 1_000_000 if quick else 5_000_000
    # Method order of bench_env_sampling's second argument: 0 cdf, 1 alias, 2 hierarchical.
    u = rng.random((n, 2))
    out = (np.empty((n, 3)), np.empty(n), np.empty((n, 2), np.int32))
    # Each form runs the batched C++ sample() (the default) and, interleaved with it, the one-sample path
    # (batched=False: the same results, one SphericalDistribution::sample call per element) as "scalar".
    for method in ("cdf", "alias", "hierarchical"):
        t8.sample(u[:100000], method=method)  # warm up
        fresh, reused, scalar = [], [], []
        for _ in range(5):  # interleaved: new result arrays (first touch of fresh memory), out=, scalar with out=
            s = time.perf_counter()
            t8.sample(u, method=method)
            fresh.append(time.perf_counter() - s)
            s = time.perf_counter()
            t8.sample(u, method=method, out=out)
            reused.append(time.perf_counter() - s)
            s = time.perf_counter()
            t8.sample(u, method=method, out=out, batched=False)
            scalar.append(time.perf_counter() - s)
        # One thread through the same binding: calls below parallel_chunks' serial threshold (16384) run on the
        # calling thread, so this is the per-core rate the parallel figure should scale from.
        k = 16000
        small = (out[0][:k], out[1][:k], out[2][:k])
        # (process_time of those calls: CPU ns per sample of one thread, whatever share of a core it got.)
        one, one_scalar, cpu, cpu_scalar = [], [], [], []
        for _ in range(5):
            for batched, times, cpu_times in ((True, one, cpu), (False, one_scalar, cpu_scalar)):
                s, c = time.perf_counter(), time.process_time()
                for i in range(0, 50 * k, k):
                    t8.sample(u[i : i + k], method=method, out=small, batched=batched)
                times.append(time.perf_counter() - s)
                cpu_times.append(time.process_time() - c)
        print("   %-13s %6.1f M samples/s, %6.1f with out= (scalar %5.1f) (%d samples, medians of 5; target >= 20 M/s);"
              " one thread %5.1f M/s (scalar %5.1f), CPU %4.0f ns per sample (scalar %4.0f)" % (
                  method, n / statistics.median(fresh) / 1e6, n / statistics.median(reused) / 1e6,
                  n / statistics.median(scalar) / 1e6, n, 50 * k / statistics.median(one) / 1e6,
                  50 * k / statistics.median(one_scalar) / 1e6, statistics.median(cpu) / (50 * k) * 1e9,
                  statistics.median(cpu_scalar) / (50 * k) * 1e9))
    # CPU time per sample (process_time: every thread of this process, not the other processes' share of the cores),
    # on this map and on a 64x32 map whose tables stay in the caches: the small map's figure bounds what the binding
    # itself costs per sample, the difference is the big tables' memory accesses inside libenv's warps.
    t_small = envkit.bake(envkit.EnvMap(rng.random((32, 64, 3)).astype(np.float32) + 0.1, "latlong"))
    print("   CPU time per sample with out= (median of 5 interleaved; 1e3 / ns = M samples/s per busy core):")
    for label, t in (("%dx%d" % (w, h), t8), ("64x32", t_small)):
        for batched in (True, False):
            cells = []
            for method in ("cdf", "alias", "hierarchical"):
                times = []
                for _ in range(5):
                    c = time.process_time()
                    t.sample(u, method=method, out=out, batched=batched)
                    times.append(time.process_time() - c)
                cells.append("%s %.0f ns" % (method, statistics.median(times) / n * 1e9))
            print("     %-10s %-8s %s" % (label, "batched" if batched else "scalar", ", ".join(cells)))
    # The C++ peer in the same run: one thread, SphericalDistribution::sample in a loop (bench_env_sampling).
    peer = os.path.join(bin_dir, "bench_env_sampling")
    if os.path.exists(peer):
        r = subprocess.run([peer, "--benchmark_filter=Sample(Batch)?/%d/" % (8192 if not quick else 1024),
                            "--benchmark_min_time=0.5"], capture_output=True, text=True)
        for line in r.stdout.splitlines():
            if line.startswith("Sample"):
                f = line.split()
                # Sample: CPU time per call = per sample; SampleBatch: per call of 256 and per_sample (CPU time too).
                print("   C++ one thread: %s CPU %s %s %s" % (f[0], f[3], f[4],
                                                          " ".join(c for c in f if c.startswith("per_sample"))))

    if os.environ["SAMPLING_ONLY"] == "1":
        return

    # 3. Batch throughput vs the CLIs back to back.
    files = 3 if quick else 4
    size = "1024x512" if quick else "2048x1024"
    in_dir = os.path.join(work, "in")
    os.makedirs(in_dir)
    for k in range(files):
        subprocess.run([os.path.join(bin_dir, "envprobe"), "default", "-o", os.path.join(in_dir, "m%d.exr" % k),
                        "--size", size, "--seed", str(k)], check=True, capture_output=True)
    inputs = batch.find_inputs(in_dir)
    opts = batch.default_options(to="cube", size=256, force=True)

    def clis():
        out = os.path.join(work, "cli")
        os.makedirs(out, exist_ok=True)
        s = time.perf_counter()
        for p in inputs:
            stem = os.path.splitext(os.path.basename(p))[0]
            subprocess.run([os.path.join(bin_dir, "envconvert"), p, "-o", os.path.join(out, stem + ".cube.exr"),
                            "--to", "cube", "--size", "256", "-q", "-f"], check=True)
            subprocess.run([os.path.join(bin_dir, "envbake"), p, "-o", os.path.join(out, stem + ".envtbl"), "-q", "-f"],
                           check=True)
        return time.perf_counter() - s

    from distributed import Client, LocalCluster
    s = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    client.run(lambda: __import__("envkit"))
    startup = time.perf_counter() - s

    def batched():
        s = time.perf_counter()
        r = batch.run(inputs, os.path.join(work, "batch"), client, opts)
        assert all(x["status"] == "done" for x in r), r
        return time.perf_counter() - s

    cli_t, batch_t = [], []
    for _ in range(3):  # interleaved
        cli_t.append(clis())
        batch_t.append(batched())
    client.close()
    cluster.close()
    c, b = statistics.median(cli_t), statistics.median(batch_t)
    print("\n3. batch: %d maps %s -> cube 256 + tables (envbake's default: hierarchical), median of 3 interleaved runs" %
          (files, size))
    print("   CLIs back to back      %6.2f s   (%.2f maps/s)" % (c, files / c))
    print("   envkit.batch, 2 workers %6.2f s   (%.2f maps/s); cluster start-up %.1f s once" % (b, files / b, startup))
    print("   ratio batch / CLIs     %6.3f   (target <= 1.10)" % (b / c))
    print("\nload average at the end: %s" % " ".join(open("/proc/loadavg").read().split()[:3]))


if __name__ == "__main__":  # dask's spawned workers import this file as __mp_main__
    main()
EOF
/usr/bin/python3 "$work/bench_python.py"
