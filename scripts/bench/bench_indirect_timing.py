#!/usr/bin/env python3
"""Interleaved timing of envrender's sample counts at --max-depth 3, on the scenes a bench_indirect run wrote.

bench_indirect's renders are timed one after the other under whatever load the machine has, and their time ratios
between count settings moved by up to 2x on the shared cores. This driver times the settings alone: for each round,
HDRI and variant, a 1-spp render (the setup: table bake, pilot) and a 256-spp render, interleaved. Per variant it
reports the median of envkit:seconds (the render loop's wall time) and of the process CPU seconds of the 256-spp
render less the 1-spp one's. Efficiency over the default counts = (relMSE ratio per sample, from bench_indirect's
results.json) / (median time ratio).

  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/bench_indirect_timing.py --bench out/bench_indirect \
      --hdris sunrise,forest,interior --rounds 3
"""
import argparse
import json
import os
import resource
import statistics
import subprocess

from bench.common import exr_attr

VARIANTS = [("0", "default"), ("0", "1+1"), ("0", "1+2"), ("0.5", "default"), ("0.5", "1+1")]


def counts_args(counts):
    if counts == "default":
        return []
    n, m = counts.split("+")
    return ["--bsdf-samples", n, "--light-samples", m]


def timed(envrender, scene, spp, seed, regularize, counts, out):
    """CPU seconds of one render (the process and its threads)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([envrender, "--scene", scene, "--spp", str(spp), "--seed", str(seed), "--bake", "--max-depth", "3",
                    "--regularize", regularize, "--threads", "2", "-q", "-f", "-o", out] + counts_args(counts),
                   check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", default="out/bench_indirect", help="a bench_indirect --out (its <hdri>/scene.json)")
    ap.add_argument("--hdris", default="sunrise,forest,interior")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--build", default="build")
    args = ap.parse_args()
    envrender = os.path.join(args.build, "bin", "envrender")
    res = {}
    for r in range(args.rounds):
        for h in args.hdris.split(","):
            scene = os.path.join(args.bench, h, "scene.json")
            out = os.path.join(args.bench, h, "timing.exr")
            for v, c in VARIANTS:
                setup = timed(envrender, scene, 1, 5 + r, v, c, out)
                cpu = timed(envrender, scene, 256, 5 + r, v, c, out) - setup
                res.setdefault(f"{h} {v} {c}", []).append(
                    {"seconds": float(exr_attr(out, "envkit:seconds")), "cpu": cpu, "setup_cpu": setup})
    with open(os.path.join(args.bench, "timing.json"), "w") as fh:
        json.dump(res, fh, indent=1)
    for k, runs in res.items():
        print(f"{k}: median {statistics.median(x['seconds'] for x in runs):.2f} s, "
              f"CPU {statistics.median(x['cpu'] for x in runs):.2f} s")


if __name__ == "__main__":
    main()
