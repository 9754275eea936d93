#!/usr/bin/env python3
"""Glossy spheres under real HDRIs, each sphere rendered and timed alone: the default strategy against power MIS.

For each HDRI (blender-data's studio lights) the scene of renderer/scenes/glossy.json (GGX conductors cNNN and rough
plastics pNNN of alpha NNN/100) and a variant with alpha 0.02 and 0.2 in place of 0.05 and 0.3 are lit by the map;
every sphere's bounding box is rendered on its own (`--crop`), so a render's seconds are that sphere's. Per sphere:
a `--strategy mis` reference at --ref-spp, then --seeds renders at --spp of each configuration (interleaved);
relMSE over the pixels lying entirely on the sphere (bench_product_efficiency.py's pixels and formula), efficiency =
1 / (relMSE x seconds), medians over the seeds. The table gives the default's efficiency over power MIS with 1 BSDF +
1 light sample and, in brackets, over `--strategy mis` with the same sample counts as the default.

  scripts/bench/bench_spheres_alone.sh                      (4 HDRIs x 10 spheres, about 20 min on 2 cores)
  scripts/bench/bench_spheres_alone.sh --hdris sunrise --seeds 3 --ref-spp 1024   (a quick look)
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys

from bench import bench_cycles  # where the HDRIs are
from bench import bench_product_efficiency as bpe  # its images and relMSE
from bench.common import ROOT, load_scene, sphere_pixels
CONFIGS = [("mis 1+1", ["--strategy", "mis", "--bsdf-samples", "1", "--light-samples", "1"]),
           ("mis", ["--strategy", "mis"]),
           ("default", [])]
# The variant's spheres: the same places and colours, other alphas.
VARIANT = {"c005": ("c002", 0.02), "c030": ("c020", 0.2), "p005": ("p002", 0.02), "p030": ("p020", 0.2)}


def scenes(hdri, out):
    """The two scene files lit by `hdri`, written into `out`."""
    base = load_scene(os.path.join(ROOT, "renderer", "scenes", "glossy.json"))
    base["environment"] = {"image": os.path.join(bench_cycles.HDRI_DIR, hdri + ".exr"), "convention": "blender",
                           "intensity": 1.0}
    variant = json.loads(json.dumps(base))
    for old, (new, alpha) in VARIANT.items():
        variant["materials"][new] = dict(variant["materials"].pop(old), roughness=alpha)
        for shape in variant["shapes"]:
            if shape.get("material") == old:
                shape["material"] = new
    paths = []
    for name, scene in (("glossy", base), ("glossy_a002", variant)):
        paths.append(os.path.join(out, "%s_%s.json" % (name, hdri)))
        with open(paths[-1], "w") as f:
            json.dump(scene, f)
    return paths


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--hdris", default="sunrise,city,forest,interior")
    p.add_argument("--spp", type=int, default=128)
    p.add_argument("--seeds", type=int, default=5)
    p.add_argument("--ref-spp", type=int, default=4096)
    p.add_argument("--threads", default="2")
    p.add_argument("--envrender", default=os.path.join(ROOT, "build", "bin", "envrender"))
    p.add_argument("--out", default=os.path.join(ROOT, "out", "bench_spheres_alone"))
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)

    def render(scene, out, spp, seed, crop, options):
        subprocess.run([a.envrender, "--scene", scene, "-o", out, "--spp", str(spp), "--seed", str(seed), "--bake",
                        "-q", "-f", "--threads", a.threads, "--crop", ",".join(map(str, crop))] + options, check=True)

    rows = {}  # hdri -> sphere -> (ratio over mis 1+1, ratio over mis)
    spheres = []
    for hdri in a.hdris.split(","):
        for scene_path in scenes(hdri, a.out):
            scene = load_scene(scene_path)
            width, height = scene["camera"]["resolution"]
            for sphere, pix in sphere_pixels(scene, width, height).items():
                if sphere in rows.get(hdri, {}):
                    continue  # c010 and p010 are in both scenes
                xs, ys = [x for x, _ in pix], [y for _, y in pix]
                crop = (min(xs), min(ys), max(xs) + 1, max(ys) + 1)
                stem = os.path.join(a.out, "%s_%s" % (hdri, sphere))
                ref_path = "%s_ref%d.exr" % (stem, a.ref_spp)
                if not os.path.exists(ref_path):
                    render(scene_path, ref_path, a.ref_spp, 1000, crop, ["--strategy", "mis"])
                ref = bpe.Image(ref_path, crop)
                eff = {name: [] for name, _ in CONFIGS}
                for seed in range(1, a.seeds + 1):
                    for name, options in CONFIGS:
                        out = "%s_%s_%d.exr" % (stem, re.sub("[^A-Za-z0-9]+", "_", name), seed)
                        render(scene_path, out, a.spp, seed, crop, options)
                        img = bpe.Image(out, crop)
                        eff[name].append(1.0 / (bpe.relmse(img, ref, pix) * img.seconds))
                med = {name: statistics.median(v) for name, v in eff.items()}
                rows.setdefault(hdri, {})[sphere] = (med["default"] / med["mis 1+1"], med["default"] / med["mis"])
                if sphere not in spheres:
                    spheres.append(sphere)
                print("%s %s: %.2f (%.2f)" % ((hdri, sphere) + rows[hdri][sphere]), file=sys.stderr)
    spheres.sort(key=lambda s: (s[0], int(s[1:])))
    lines = ["envrender's default over power MIS 1 + 1 (in brackets: over `--strategy mis` at the same counts), each "
             "sphere rendered alone, %d spp, %d seeds, references %d spp" % (a.spp, a.seeds, a.ref_spp), "",
             "| HDRI | " + " | ".join(spheres) + " |", "|---|" + "---:|" * len(spheres)]
    for hdri, cells in rows.items():
        lines.append("| %s | " % hdri + " | ".join("%.2f (%.2f)" % cells[s] if s in cells else "-" for s in spheres)
                     + " |")
    text = "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
