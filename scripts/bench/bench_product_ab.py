#!/usr/bin/env python3
"""Interleaved A/B of two envrender builds on the product-sampling scene (bench_strategies' `--scene full`): time only.

For a change meant to make rendering faster and nothing else (its images are the same bits: check that apart), the
render seconds (envkit:seconds) of each build, interleaved: every round renders each cell with both builds, the order
reversed every other round, with seed = round. A cell is HDRI:REGION; with --crop (the default) the render is the
region's bounding box on one thread, so that the figure is that region's cost and one thread's CPU share is steadier
on a shared machine than two; with --whole the whole image on --threads threads, with each region's CPU seconds
(--pixel-seconds) beside the image's. Reports per cell the median seconds of each build, the ratio of the medians
(new / old), the median of the per-round ratios (each round's pair ran back to back: the steadier figure) and the
sorted per-round ratios, and the load average at each round.

  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/bench_product_ab.py --old /path/to/old/envrender \\
      --new build/bin/envrender --cells city:p005,night:c050,sunrise:p005 --rounds 9 --spp 512
  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/bench_product_ab.py --old ... --new ... --whole --spp 64 \\
      --cells city:p005+c050,night:c050,sunrise:p005
"""
import argparse
import os
import statistics
import subprocess

import numpy as np

from bench import bench_cycles as bc
from bench import bench_strategies as bs
from bench.common import ROOT, exr_attr, read_exr, region_masks


def loadavg():
    with open("/proc/loadavg") as f:
        return f.read().split()[0]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--old", required=True)
    ap.add_argument("--new", required=True)
    ap.add_argument("--cells", default="city:p005,night:c050,sunrise:p005",
                    help="HDRI:REGION[+REGION...] (regions of bench_strategies' full scene)")
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--spp", type=int, default=512)
    ap.add_argument("--size", default="216x48")
    ap.add_argument("--whole", action="store_true", help="whole image on --threads threads instead of crops")
    ap.add_argument("--threads", default="2")
    ap.add_argument("--extra", default="", help="envrender options for both builds")
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench_product_ab"))
    a = ap.parse_args()
    size = tuple(int(v) for v in a.size.split("x"))
    os.makedirs(a.out, exist_ok=True)
    spec = bc.write_meshes(bs.SCENES["full"], a.out)
    regions = list(spec["regions"])
    masks = region_masks(spec, size)
    cells = [c.split(":") for c in a.cells.split(",")]
    scenes = {h: bs.scene_file(spec, h, size, a.out) for h in {h for h, _ in cells}}
    builds = (("old", os.path.abspath(a.old)), ("new", os.path.abspath(a.new)))
    times = {}  # (hdri, regions) -> build -> [(seconds, {region: seconds})]
    loads = []
    for r in range(a.rounds):
        loads.append(loadavg())
        for h, names in cells:
            first = names.split("+")[0]
            ys, xs = np.nonzero(masks == regions.index(first))
            crop = ["--crop", "%d,%d,%d,%d" % (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1), "--threads", "1"]
            where = ["--threads", a.threads, "--pixel-seconds"] if a.whole else crop
            for tag, binary in builds if r % 2 == 0 else builds[::-1]:
                out = os.path.join(a.out, "%s_%s_%s.exr" % (h, names, tag))
                subprocess.run([binary, "--scene", scenes[h], "--spp", str(a.spp), "--seed", str(r + 1), "--bake", "-q",
                                "-f", "-o", out] + where + a.extra.split(), check=True)
                per_region = {}
                if a.whole:
                    T = read_exr(out, "seconds", 1)[..., 0]
                    per_region = {g: float(T[masks == regions.index(g)].sum()) for g in names.split("+")}
                times.setdefault((h, names), {}).setdefault(tag, []).append(
                    (float(exr_attr(out, "envkit:seconds")), per_region))
    loads.append(loadavg())
    print("load average (1 min) at each round: " + " ".join(loads))
    for (h, names), d in times.items():
        o, n = d["old"], d["new"]
        mo, mn = statistics.median(x[0] for x in o), statistics.median(x[0] for x in n)
        rounds = sorted(y[0] / x[0] for x, y in zip(o, n))
        line = "%s:%s %s: old %.3f s, new %.3f s, new/old %.3f, median round %.3f (rounds %s)" % (
            h, names, "image" if a.whole else "crop", mo, mn, mn / mo, statistics.median(rounds),
            " ".join("%.2f" % v for v in rounds))
        for g in (names.split("+") if a.whole else []):
            ro, rn = statistics.median(x[1][g] for x in o), statistics.median(x[1][g] for x in n)
            line += "; %s CPU %.4f / %.4f s, %.3f" % (g, ro, rn, rn / ro)
        print(line)


if __name__ == "__main__":
    main()
