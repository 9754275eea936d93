#!/usr/bin/env python3
"""envrender configurations against each other on bench_cycles.py's scenes and real HDRIs, per region.

Each configuration (envrender options) renders the scene at --spp for --seeds seeds; every render is compared with
a converged reference of the same scene (4096 spp, written once per HDRI and kept in --out), per region (each
sphere, the ground). Efficiency = 1 / (relMSE x envrender's render seconds); the table gives each configuration's
efficiency over the first configuration's (median over the seeds), and in brackets the ratio of relMSE at equal
spp. This is how the strategy and sample-count defaults were chosen (BENCHMARKS.md, "Product tables", "Samples
per shading point"); bench_cycles.sh compares the default with Cycles.

  scripts/bench/bench_strategies.sh --hdris sunrise,forest,interior,city \\
      --config "1+1=--bsdf-samples 1 --light-samples 1" --config "by lobe="
"""
import argparse
import json
import os
import shlex
import statistics
import subprocess

from bench import bench_cycles as bc  # the scenes and the HDRIs
from bench.common import ROOT, exr_attr, read_exr, region_masks, rel_mse


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--hdris", default="sunrise,forest,interior,city")
    p.add_argument("--config", action="append", required=True,
                   help="NAME=OPTIONS (envrender options; the first configuration is the baseline)")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--ref-spp", type=int, default=4096)
    p.add_argument("--size", default="160x90")
    p.add_argument("--threads", default="2")
    p.add_argument("--envrender", default=os.path.join(ROOT, "build", "bin", "envrender"))
    p.add_argument("--out", default=os.path.join(ROOT, "out", "bench_strategies"))
    a = p.parse_args()
    configs = [c.split("=", 1) for c in a.config]
    if any(len(c) != 2 for c in configs):
        p.error("--config takes NAME=OPTIONS")
    size = tuple(int(v) for v in a.size.split("x"))
    os.makedirs(a.out, exist_ok=True)
    spec = bc.SCENE
    regions = list(spec["regions"])
    masks = region_masks(spec, size)
    lines = ["| HDRI | configuration | s | " + " | ".join(regions) + " | geomean |",
             "|---|---|---:|" + "---:|" * (len(regions) + 1)]
    for hdri in a.hdris.split(","):
        scene = os.path.join(a.out, hdri + ".json")
        with open(scene, "w") as f:
            json.dump(bc.envrender_scene(spec, os.path.join(bc.HDRI_DIR, hdri + ".exr"), size), f)
        ref = os.path.join(a.out, "%s_ref_%d.exr" % (hdri, a.ref_spp))
        if not os.path.exists(ref):
            subprocess.run([a.envrender, "--scene", scene, "--spp", str(a.ref_spp), "--seed", "999", "--bake", "-q",
                            "-f", "-o", ref, "--threads", a.threads], check=True)
        R = read_exr(ref)
        runs = {name: [] for name, _ in configs}
        for seed in range(1, a.seeds + 1):  # interleaved: every configuration once per seed
            for name, options in configs:
                out = os.path.join(a.out, "%s_%s_%d.exr" % (hdri, name.replace(" ", "_"), seed))
                subprocess.run([a.envrender, "--scene", scene, "--spp", str(a.spp), "--seed", str(seed), "--bake",
                                "-q", "-f", "-o", out, "--threads", a.threads] + shlex.split(options), check=True)
                seconds = float(exr_attr(out, "envkit:seconds"))
                I = read_exr(out)
                runs[name].append((seconds, [rel_mse(I, R, masks == i) for i in range(len(regions))]))
        base = runs[configs[0][0]]
        for name, _ in configs:
            eff, rel = [], []
            for i in range(len(regions)):
                e = statistics.median(1 / (r[1][i] * r[0]) for r in runs[name])
                e0 = statistics.median(1 / (r[1][i] * r[0]) for r in base)
                eff.append(e / e0)
                rel.append(statistics.median(r[1][i] for r in base) / statistics.median(r[1][i] for r in runs[name]))
            geomean = statistics.geometric_mean(eff)
            seconds = statistics.median(r[0] for r in runs[name])
            line = "| %s | %s | %.3f | %s | %.2f |" % (hdri, name, seconds, " | ".join(
                "%.2f (%.2f)" % (e, r) for e, r in zip(eff, rel)), geomean)
            lines.append(line)
            print(line, flush=True)
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write("envrender, %s, %d spp, %d seeds, references %d spp; efficiency over `%s` (relMSE ratio at equal "
                "spp)\n\n" % (a.size, a.spp, a.seeds, a.ref_spp, configs[0][0]))
        f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
