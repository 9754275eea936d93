#!/usr/bin/env python3
"""Interleaved A/B of envrender builds (or options) at --max-depth D, on the scenes a bench_indirect run wrote.

For each round, HDRI and variant (the order reversed every other round), one render at --spp with seed --seed + round,
timed by envkit:seconds and compared per region with the run's unbiased envrender reference (relMSE, as
bench_indirect). Per variant and HDRI it reports the median time, the median of the per-round time ratios to the
first variant, and the relMSE ratio to the first variant's as the geometric mean over the regions, both from the
mean relMSE over the rounds (what fireflies move) and from the median over the rounds (what they do not), with the
efficiency 1 / (relMSE ratio x time ratio) from each. relMSE x spp is the error of one sample.

  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/bench_indirect_ab.py --bench out/bench_indirect --spp 64 \
      --rounds 16 old=/path/to/old/envrender new=build/bin/envrender "new 1+1=build/bin/envrender:--light-samples 1"
"""
import argparse
import json
import os
import subprocess

import numpy as np

from bench.bench_cycles import SCENES, write_meshes
from bench.common import exr_attr, read_exr, region_masks, rel_mse


def parse_variant(text):
    """"name=binary[:extra options]" -> (name, binary, [options])."""
    name, rest = text.split("=", 1)
    binary, _, extra = rest.partition(":")
    return name, os.path.abspath(binary), extra.split()


def geo_mean(values):
    return float(np.exp(np.mean(np.log(values))))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bench", required=True, help="a bench_indirect --out (its scene.json and references)")
    ap.add_argument("--hdris", default="sunrise,forest,interior")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=16)
    ap.add_argument("--depth", type=int, default=3)
    ap.add_argument("--seed", type=int, default=500, help="the first round's seed")
    ap.add_argument("--regularize", default="0", help="--regularize of the variants that do not set it")
    ap.add_argument("--json", default=None, help="write every round's figures here")
    ap.add_argument("variants", nargs="+", help="name=binary[:options]; ratios are over the first")
    args = ap.parse_args()
    variants = [parse_variant(v) for v in args.variants]
    run = json.load(open(os.path.join(args.bench, "results.json")))
    size = tuple(run["size"])
    tmp = os.path.join(args.bench, "ab")
    os.makedirs(tmp, exist_ok=True)
    # The scene the run rendered: the one of SCENES whose regions it reports (spheres or mesh).
    scene = next(s for s in SCENES.values() if write_meshes(s, tmp)["regions"] == run["regions"])
    spec = write_meshes(scene, tmp)
    regions, mask = spec["regions"], region_masks(spec, size)
    hdris = args.hdris.split(",")
    data = {h: {v[0]: [] for v in variants} for h in hdris}
    for r in range(args.rounds):
        for h in hdris:
            ref = read_exr(os.path.join(args.bench, h, f"ref_envrender_d{args.depth}.exr"))
            for name, binary, extra in variants if r % 2 == 0 else variants[::-1]:
                out = os.path.join(tmp, f"{h}_{len(data[h][name]) % 2}.exr")
                subprocess.run([binary, "--scene", os.path.join(args.bench, h, "scene.json"), "--spp", str(args.spp),
                                "--seed", str(args.seed + r), "--bake", "--max-depth", str(args.depth),
                                "--threads", "2", "-q", "-f", "-o", out] + extra +
                               ([] if "--regularize" in extra else ["--regularize", args.regularize]), check=True)
                img = read_exr(out)
                data[h][name].append((float(exr_attr(out, "envkit:seconds")),
                                      {reg: rel_mse(img, ref, mask == i) for i, reg in enumerate(regions)}))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(data, fh)
    base = variants[0][0]
    print(f"--spp {args.spp}, {args.rounds} rounds, depth {args.depth}; ratios over {base}; per sample = relMSE x spp")
    for h in hdris:
        B = data[h][base]
        for name, _, _ in variants:
            V = data[h][name]
            t = float(np.median([v[0] for v in V]))
            tr = float(np.median([v[0] / b[0] for v, b in zip(V, B)]))
            mean = {reg: np.mean([v[1][reg] for v in V]) for reg in regions}
            er = [mean[reg] / np.mean([b[1][reg] for b in B]) for reg in regions]
            em = [np.median([v[1][reg] for v in V]) / np.median([b[1][reg] for b in B]) for reg in regions]
            print(f"{h} {name}: time {t:.3f} s, ratio {tr:.2f}; relMSE ratio mean-based {geo_mean(er):.2f} "
                  f"({min(er):.2f}-{max(er):.2f}), median-based {geo_mean(em):.2f} ({min(em):.2f}-{max(em):.2f}); "
                  f"efficiency {1 / (geo_mean(er) * tr):.2f} / {1 / (geo_mean(em) * tr):.2f}; per sample "
                  + " ".join(f"{reg} {mean[reg] * args.spp:.3g}" for reg in regions))


if __name__ == "__main__":
    main()
