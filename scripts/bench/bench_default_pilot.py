#!/usr/bin/env python3
"""envrender's default (`auto`: a light technique per material chosen by a pilot) against power MIS and product-mis,
per sphere, each sphere rendered and timed alone (`--crop`), on two scenes under every blender-data HDRI.

Scenes: "spheres" (one diffuse sphere and GGX conductors of alpha 0.0225, 0.09 and 0.25 on a diffuse ground: alpha
= Blender roughness 0.15, 0.3, 0.5 squared) and renderer/scenes/glossy.json (conductors and plastics of alpha 0.05,
0.1, 0.3). Per sphere and configuration, --seeds renders at --spp, interleaved. The relative variance comes from
the renders' own variance AOV: mean over the sphere's pixels of var / (mean^2 + 0.01), the mean being the pooled
mean of every render (no reference image needed: every configuration is unbiased). Efficiency = 1 / (relative
variance x render seconds); the table gives each configuration's ratio to the first's (medians over the seeds), and
in brackets the ratio of relative variance at equal spp, which carries no timing noise. The choice the pilot made
is printed by envrender (-v) and repeated in the table.

  scripts/bench/bench_default_pilot.sh                                   (16 scene x HDRI pairs, about 1 h)
  scripts/bench/bench_default_pilot.sh --hdris sunrise,courtyard --scenes spheres --seeds 1   (a quick look)
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys

import numpy as np

from bench import bench_cycles  # where the HDRIs are
from bench.common import ROOT, exr_attr, load_scene, read_exr, sphere_pixels

SPHERES = {
    "camera": {"position": [0.0, 1.6, -7.5], "look_at": [0.0, 0.55, 0.0], "up": [0, 1, 0], "fov": 22,
               "resolution": [200, 80]},
    "materials": {"ground": {"type": "diffuse", "albedo": [0.45, 0.45, 0.42]},
                  "d100": {"type": "diffuse", "albedo": [0.7, 0.7, 0.7]},
                  "c002": {"type": "conductor", "roughness": 0.0225},
                  "c009": {"type": "conductor", "roughness": 0.09},
                  "c025": {"type": "conductor", "roughness": 0.25}},
    "shapes": [{"type": "triangles", "material": "ground",
                "vertices": [[-500, 0, -500], [500, 0, -500], [500, 0, 500], [-500, 0, 500]],
                "triangles": [[0, 2, 1], [0, 3, 2]]},
               {"type": "sphere", "center": [1.95, 0.55, 0.0], "radius": 0.55, "material": "c002"},
               {"type": "sphere", "center": [0.65, 0.55, 0.0], "radius": 0.55, "material": "c009"},
               {"type": "sphere", "center": [-0.65, 0.55, 0.0], "radius": 0.55, "material": "c025"},
               {"type": "sphere", "center": [-1.95, 0.55, 0.0], "radius": 0.55, "material": "d100"}]}
HDRIS = "sunrise,courtyard,city,forest,interior,night,studio,sunset"
CONFIGS = "mis=--strategy mis;product-mis=--strategy product-mis;default="


def scene_file(name, hdri, out):
    scene = json.loads(json.dumps(SPHERES)) if name == "spheres" else load_scene(
        os.path.join(ROOT, "renderer", "scenes", "glossy.json"))
    scene["environment"] = {"image": os.path.join(bench_cycles.HDRI_DIR, hdri + ".exr"), "convention": "blender",
                            "intensity": 1.0}
    path = os.path.join(out, "%s_%s.json" % (name, hdri))
    with open(path, "w") as f:
        json.dump(scene, f)
    return path


def pilot_choices(envrender, scene_path, out):
    """envrender's note of the pilot's choices, as {material: "product table + sun", ...} (one pixel rendered: the
    pilot looks through the whole camera whatever the crop)."""
    err = subprocess.run([envrender, "--scene", scene_path, "-o", os.path.join(out, "pilot.exr"), "--spp", "1",
                          "--bake", "--crop", "0,0,1,1", "-f"], capture_output=True, text=True).stderr
    m = re.search(r"light per material \(pilot\): (.*?)(?: \(built in|$)", err, re.M)
    return dict(item.split(": ", 1) for item in m.group(1).split(", ")) if m else {}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--hdris", default=HDRIS)
    p.add_argument("--scenes", default="spheres,glossy")
    p.add_argument("--configs", default=CONFIGS, help="NAME=OPTIONS;... (the first is the baseline)")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--threads", default="2")
    p.add_argument("--envrender", default=os.path.join(ROOT, "build", "bin", "envrender"))
    p.add_argument("--out", default=os.path.join(ROOT, "out", "bench_default_pilot"))
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    configs = [(c.split("=", 1)[0], c.split("=", 1)[1].split()) for c in a.configs.split(";")]
    base = configs[0][0]
    lines = ["| scene | HDRI | sphere | pilot's choice | " + " | ".join(n for n, _ in configs[1:]) + " |",
             "|---|---|---|---|" + "---:|" * (len(configs) - 1)]
    for name in a.scenes.split(","):
        for hdri in a.hdris.split(","):
            path = scene_file(name, hdri, a.out)
            scene = load_scene(path)
            width, height = scene["camera"]["resolution"]
            choices = pilot_choices(a.envrender, path, a.out)
            for sphere, pix in sphere_pixels(scene, width, height).items():
                xs, ys = np.array([x for x, _ in pix]), np.array([y for _, y in pix])
                crop = (xs.min(), ys.min(), xs.max() + 1, ys.max() + 1)
                runs = {n: [] for n, _ in configs}
                for seed in range(1, a.seeds + 1):
                    for config, options in configs:
                        out = os.path.join(a.out, "%s_%s_%s_%s_%d.exr" % (name, hdri, sphere, config, seed))
                        subprocess.run([a.envrender, "--scene", path, "-o", out, "--spp", str(a.spp), "--seed",
                                        str(seed), "--bake", "-q", "-f", "--threads", a.threads,
                                        "--crop", ",".join(map(str, crop))] + options, check=True)
                        rgb = read_exr(out, "R,G,B", 0)[ys - crop[1], xs - crop[0]]
                        var = read_exr(out, "variance.R,variance.G,variance.B", 1)[ys - crop[1], xs - crop[0]]
                        runs[config].append((rgb, var, float(exr_attr(out, "envkit:seconds"))))
                mean = np.mean([r[0] for v in runs.values() for r in v], axis=0)
                relvar = {n: [float(np.mean(var / (mean ** 2 + 1e-2))) for _, var, _ in v] for n, v in runs.items()}
                eff = {n: statistics.median(1.0 / (r * s) for r, (_, _, s) in zip(relvar[n], runs[n])) for n in runs}
                rv = {n: statistics.median(relvar[n]) for n in runs}
                cells = ["%.2f (%.2f)" % (eff[n] / eff[base], rv[base] / rv[n]) for n, _ in configs[1:]]
                lines.append("| %s | %s | %s | %s | %s |" % (name, hdri, sphere, choices.get(sphere, "-"),
                                                           " | ".join(cells)))
                print(lines[-1], file=sys.stderr, flush=True)
    text = ("Efficiency over `%s` (in brackets: relative variance ratio at equal spp), each sphere alone, %d spp, "
            "%d seed(s)\n\n" % (base, a.spp, a.seeds)) + "\n".join(lines) + "\n"
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
