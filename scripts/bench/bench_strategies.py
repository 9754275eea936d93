#!/usr/bin/env python3
"""envrender configurations against each other on bench_cycles.py's scenes and real HDRIs, per region.

Each configuration (envrender options) renders the scene at --spp for --seeds seeds; every render is compared with
a converged reference of the same scene (`--strategy mis` at --ref-spp, written once per lighting and kept in
--out), per region (each sphere, mesh, the ground): relMSE minus the reference's own variance of the mean (its AOV;
region_error).
Efficiency = 1 / (relMSE x seconds), over the first configuration's (mean relMSE over the seeds, median seconds),
with two measures of seconds. Per region (the target's): the sum over the region's pixels of the time envrender spent
on each pixel's samples (`--pixel-seconds`, the rendering thread's CPU time around them), i.e. what the region cost whatever the other
regions' materials cost. Whole image: envrender's render seconds, the same for every region (a material that draws
from costlier tables slows every region's figure down). A cell reads "per-region / whole-image (relMSE ratio at
equal spp, no timing noise)"; renders without the seconds channel (--reuse of older ones) show "-" per region. Seeds are interleaved: every configuration once per seed. This is how the strategy and
sample-count defaults were chosen (BENCHMARKS.md, "envrender: strategies and sample counts"); bench_cycles.sh
compares the default with Cycles.

Scenes (--scene): `spheres` and `mesh` are bench_cycles.py's; `full` is the product-sampling benchmark's set in one
row: GGX conductors of alpha 0.01, 0.0225, 0.05, 0.09, 0.25 and 0.5 (cNNN, Fresnel 1), rough plastics of alpha
0.05 and 0.3 (pNNN), a measured material (a MERL-format file this script writes from an analytic BRDF: a blue
Lambertian base and a GGX alpha 0.08 lobe), a diffuse sphere, a GGX 0.15 torus knot (an OBJ mesh) and the
ground. Lighting (--hdris): blender-data's HDRIs by name, `all` (every HDRI there and both skies), or `skyNN`:
envprobe's built-in outdoor sky with its sun at NN degrees elevation.

  scripts/bench/bench_strategies.sh --hdris sunrise,forest,interior,city \\
      --config "1+1=--bsdf-samples 1 --light-samples 1" --config "by lobe="
  scripts/bench/bench_strategies.sh --scene full --hdris all --config "mis=--strategy mis" --config "default=" \\
      --spp 32 --seeds 3 --ref-spp 512 --size 216x48 --out out/bench_strategies_full
                                        (the product-sampling set: the default against power MIS; about 30 min)
"""
import argparse
import json
import math
import os
import re
import shlex
import statistics
import subprocess

import numpy as np

from bench import bench_cycles as bc  # the scenes and the HDRIs
from bench.common import EPS, ROOT, exr_attr, read_exr, region_masks, rel_mse

# The `full` scene: one row of objects on the ground, seen from far enough that each is a region of a few hundred
# pixels at 288x64 (150 at 216x48). Materials in envrender's format ("ggx": Fresnel-less conductor, as bench_cycles writes them).
FULL_ROW = [("diffuse", {"type": "diffuse", "albedo": 0.6}),
            ("c001", {"type": "ggx", "roughness": 0.01}),
            ("c002", {"type": "ggx", "roughness": 0.0225}),
            ("c005", {"type": "ggx", "roughness": 0.05}),
            ("c009", {"type": "ggx", "roughness": 0.09}),
            ("c025", {"type": "ggx", "roughness": 0.25}),
            ("c050", {"type": "ggx", "roughness": 0.5}),
            ("p005", {"type": "plastic", "diffuse": [0.1, 0.25, 0.6], "roughness": 0.05}),
            ("p030", {"type": "plastic", "diffuse": [0.2, 0.5, 0.15], "roughness": 0.3}),
            ("measured", {"type": "measured", "file": "measured.binary"})]
FULL_SPACING, FULL_RADIUS, FULL_LEFT = 1.0, 0.42, -5.2  # the spheres' x: FULL_LEFT + i x FULL_SPACING
bc.MESH_BUILDERS["knot_small"] = lambda: bc.knot_mesh([5.0, 0.62, 0.0], 0.5, 0.1)  # right of the last sphere
FULL = dict(bc.BASE, camera={"position": [0.0, 2.4, -13.0], "look_at": [0.0, 0.45, 0.0], "up": [0, 1, 0],
                             "fov": 11.5},
            materials=dict(bc.GROUND, knot={"type": "ggx", "roughness": 0.15}, **dict(FULL_ROW)),
            spheres=[{"center": [FULL_LEFT + i * FULL_SPACING, FULL_RADIUS, 0.0],
                      "radius": FULL_RADIUS, "material": name} for i, (name, _) in enumerate(FULL_ROW)],
            meshes=[{"name": "knot_small", "material": "knot"}],
            regions=[name for name, _ in FULL_ROW] + ["knot", "ground"],
            glossy=[name for name, m in FULL_ROW if m["type"] != "diffuse"] + ["knot"])
SCENES = dict(bc.SCENES, full=FULL)
SKY = re.compile(r"sky(\d+)$")


def write_merl(path, kd=(0.1, 0.2, 0.5), ks=0.6, alpha=0.08):
    """A MERL-format BRDF file (renderer/src/merl.h) of f = kd / pi + ks D G2 / (4 cos_o cos_i), GGX D of `alpha` and
    its height-correlated Smith G2, Fresnel 1; cells whose directions leave the upper hemisphere hold -1 (missing), as
    the measured data's do. The cell centres and the (half, difference) to (wo, wi) map are merl.cpp's."""
    th = ((np.arange(90) + 0.5) / 90) ** 2 * (math.pi / 2)
    td = (np.arange(90) + 0.5) / 90 * (math.pi / 2)
    pd = (np.arange(180) + 0.5) / 180 * math.pi
    th, td, pd = np.meshgrid(th, td, pd, indexing="ij")
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], -1)
    ct, st = np.cos(th), np.sin(th)
    wi = np.stack([ct * d[..., 0] + st * d[..., 2], d[..., 1], -st * d[..., 0] + ct * d[..., 2]], -1)
    h = np.stack([st, np.zeros_like(st), ct], -1)
    wo = h * (2 * (wi * h).sum(-1, keepdims=True)) - wi
    co, ci = wo[..., 2], wi[..., 2]
    up = (co > 0) & (ci > 0)
    a2 = alpha * alpha
    D = a2 / (math.pi * (ct ** 2 * (a2 - 1) + 1) ** 2)

    def lam(c):
        c = np.clip(c, 1e-9, 1.0)
        return 0.5 * (np.sqrt(1 + a2 * (1 - c * c) / (c * c)) - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        spec = ks * D / (1 + lam(co) + lam(ci)) / (4 * np.maximum(co, 1e-9) * np.maximum(ci, 1e-9))
    scale = (1 / 1500, 1.15 / 1500, 1.66 / 1500)
    blocks = [np.where(up, (k / math.pi + spec) / s, -1.0) for k, s in zip(kd, scale)]
    with open(path + ".tmp", "wb") as f:
        np.array([90, 90, 180], "<i4").tofile(f)
        np.concatenate([b.ravel() for b in blocks]).astype("<f8").tofile(f)
    os.replace(path + ".tmp", path)


def lighting(name, out):
    """The environment entry of a scene file for `name`: a blender-data HDRI, or skyNN (envprobe's default sky with its
    sun at NN degrees elevation, written into `out` once)."""
    m = SKY.match(name)
    if not m:
        return {"image": os.path.join(bc.HDRI_DIR, name + ".exr"), "convention": "blender", "intensity": 1.0}
    path = os.path.join(out, name + ".exr")
    if not os.path.exists(path):
        subprocess.run([os.path.join(ROOT, "build", "bin", "envprobe"), "default", "-o", path, "-q",
                        "--elevation-deg", m.group(1)], check=True)
    return {"image": path, "convention": "envkit", "intensity": 1.0}


def scene_file(spec, name, size, out):
    """The scene lit by `name`, written into `out`; returns its path."""
    written = {k: m for k, m in spec["materials"].items() if m["type"] in ("diffuse", "ggx")}
    scene = bc.envrender_scene(dict(spec, materials=written), "", size)
    scene["environment"] = lighting(name, out)
    for mat, m in spec["materials"].items():  # the types envrender_scene does not write
        if m["type"] in ("plastic", "measured"):
            scene["materials"][mat] = dict(m)
            if m["type"] == "measured":
                scene["materials"][mat]["file"] = os.path.join(out, m["file"])
                if not os.path.exists(os.path.join(out, m["file"])):
                    write_merl(os.path.join(out, m["file"]))
    path = os.path.join(out, name + ".json")
    with open(path, "w") as f:
        json.dump(scene, f)
    return path


def loadavg():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scene", choices=sorted(SCENES), default="spheres")
    p.add_argument("--hdris", default="sunrise,forest,interior,city",
                   help="blender-data HDRI names, skyNN (built-in sky, sun at NN deg), or all")
    p.add_argument("--config", action="append", required=True,
                   help="NAME=OPTIONS (envrender options; the first configuration is the baseline)")
    p.add_argument("--spp", type=int, default=64)
    p.add_argument("--seeds", type=int, default=3)
    p.add_argument("--ref-spp", type=int, default=4096)
    p.add_argument("--size", default="160x90")
    p.add_argument("--threads", default="2")
    p.add_argument("--envrender", default=os.path.join(ROOT, "build", "bin", "envrender"))
    p.add_argument("--out", default=os.path.join(ROOT, "out", "bench_strategies"))
    p.add_argument("--reuse", action="store_true",
                   help="re-analyse: keep the EXRs already in --out instead of rendering them again")
    a = p.parse_args()
    configs = [c.split("=", 1) for c in a.config]
    if any(len(c) != 2 for c in configs):
        p.error("--config takes NAME=OPTIONS")
    hdris = a.hdris.split(",")
    if hdris == ["all"]:
        hdris = sorted(f[:-4] for f in os.listdir(bc.HDRI_DIR) if f.endswith(".exr")) + ["sky35", "sky8"]
    size = tuple(int(v) for v in a.size.split("x"))
    a.out = os.path.abspath(a.out)  # the scene files name their MERL and mesh files by absolute path
    os.makedirs(a.out, exist_ok=True)
    spec = bc.write_meshes(SCENES[a.scene], a.out)
    regions = list(spec["regions"])
    masks = region_masks(spec, size)
    load_start = loadavg()
    lines = ["| lighting | configuration | s | " + " | ".join(regions) + " | geomean |",
             "|---|---|---:|" + "---:|" * (len(regions) + 1)]
    results = {}  # lighting -> configuration -> [(seconds, relMSE per region)] over the seeds
    choices = {}  # lighting -> the pilot's choices (envrender's note), when a configuration runs auto
    for hdri in hdris:
        scene = scene_file(spec, hdri, size, a.out)
        ref = os.path.join(a.out, "%s_ref_%d.exr" % (hdri, a.ref_spp))
        if not os.path.exists(ref):
            subprocess.run([a.envrender, "--scene", scene, "--spp", str(a.ref_spp), "--seed", "999", "--bake", "-q",
                            "-f", "-o", ref, "--threads", a.threads, "--strategy", "mis"], check=True)
        R = read_exr(ref)
        RV = read_exr(ref, "variance.R,variance.G,variance.B", 1)
        runs = results[hdri] = {name: [] for name, _ in configs}
        for seed in range(1, a.seeds + 1):  # interleaved: every configuration once per seed
            for name, options in configs:
                out = os.path.join(a.out, "%s_%s_%d.exr" % (hdri, re.sub("[^A-Za-z0-9+.-]+", "_", name), seed))
                if not (a.reuse and os.path.exists(out)):
                    r = subprocess.run([a.envrender, "--scene", scene, "--spp", str(a.spp), "--seed", str(seed),
                                        "--bake", "-f", "-o", out, "--threads", a.threads, "--pixel-seconds"] +
                                       shlex.split(options),
                                       check=True, capture_output=True, text=True)
                    with open(out + ".log", "w") as f:
                        f.write(r.stderr)
                if os.path.exists(out + ".log"):
                    for note in open(out + ".log").read().splitlines():
                        if "light per material (pilot)" in note:
                            choices[hdri] = note.split("(pilot): ", 1)[1].split(" (built in")[0]
                I = read_exr(out)
                runs[name].append((float(exr_attr(out, "envkit:seconds")),
                                   [region_error(I, R, RV, masks == i) for i in range(len(regions))],
                                   region_seconds(out, masks, len(regions))))
        for name, _ in configs:
            eff, rel = ratios(runs[name], runs[configs[0][0]], len(regions))
            local = ratios(runs[name], runs[configs[0][0]], len(regions), per_region=True)[0]
            line = "| %s | %s | %.3f | %s | %s |" % (
                hdri, name, statistics.median(r[0] for r in runs[name]),
                " | ".join(("%.2f" % lo if lo == lo else "-") + " / %.2f (%.2f)" % er
                           for lo, er in zip(local, zip(eff, rel))),
                ("%.2f" % statistics.geometric_mean(local) if all(lo == lo for lo in local) else "-") +
                " / %.2f" % statistics.geometric_mean(eff))
            lines.append(line)
            print(line, flush=True)
    summary = [summarize(results, name, configs[0][0], regions, spec.get("glossy", [])) for name, _ in configs[1:]]
    with open(os.path.join(a.out, "results.json"), "w") as f:
        json.dump({"scene": a.scene, "size": a.size, "spp": a.spp, "seeds": a.seeds, "ref_spp": a.ref_spp,
                   "regions": regions, "configs": dict(configs), "runs": results, "choices": choices,
                   "load": [load_start, loadavg()]}, f, indent=1)
    with open(os.path.join(a.out, "results.md"), "w") as f:
        f.write("envrender, scene `%s`, %s, %d spp, %d seeds (mean relMSE, median seconds), references `--strategy mis` at %d spp; "
                "efficiency over `%s`, per cell: with each region's own seconds (the sum of its pixels' times) / "
                "with each render's whole-image seconds (in brackets: relMSE ratio at equal spp); %s threads; load average %s at start, %s at end%s\n\n" % (
                    a.scene, a.size, a.spp, a.seeds, a.ref_spp, configs[0][0], a.threads, load_start, loadavg(),
                    " (of this re-analysis, --reuse: not of the renders)" if a.reuse else ""))
        f.write("\n".join(lines) + "\n\n" + "\n".join("- " + s for s in summary) + "\n")
        if choices:
            f.write("\nThe pilot's choices (auto):\n\n" + "\n".join("- %s: %s" % kv for kv in choices.items()) + "\n")
    print("\n".join(summary))


def region_error(img, ref, ref_variance, mask):
    """relMSE over the region against the converged image: minus the reference's own relative variance of the mean,
    and never below a tenth of it (an error that small is not resolved by the reference: a region where both
    configurations are that close reads as a ratio near 1, not as an unbounded one)."""
    own = float((np.asarray(ref_variance) / (np.asarray(ref) ** 2 + EPS))[mask].mean())
    return max(rel_mse(img, ref, mask) - own, 0.1 * own)


def region_seconds(path, masks, count):
    """Per region, the sum of the render's per-pixel seconds (envrender --pixel-seconds) over its pixels; NaN when
    the render has no seconds channel (oiiotool reads a missing channel as zeros; a timed pixel is never 0)."""
    T = read_exr(path, "seconds", 1)[..., 0]
    if not (T > 0).any():
        return [float("nan")] * count
    return [float(T[masks == i].sum()) for i in range(count)]


def ratios(runs, base, count, per_region=False):
    """Per region: efficiency over the baseline, 1 / (relMSE x seconds) with the mean relMSE over the seeds and the
    median seconds (the whole image's, or with per_region the region's own: region_seconds), and the relMSE ratio at
    equal spp (baseline over this). The mean, not the median: relMSE is an expectation, and a region's error over
    seeds is heavy-tailed (a sun's rare hits), more so for some techniques than others, so medians would favour the
    technique of the heavier tail."""
    eff, rel = [], []
    t, t0 = statistics.median(r[0] for r in runs), statistics.median(r[0] for r in base)
    for i in range(count):
        m, m0 = statistics.fmean(r[1][i] for r in runs), statistics.fmean(r[1][i] for r in base)
        if per_region:
            t, t0 = (statistics.median(r[2][i] if len(r) > 2 else float("nan") for r in rs) for rs in (runs, base))
        rel.append(m0 / m)
        eff.append(m0 * t0 / (m * t))
    return eff, rel


def interval(runs, base, i, draws=2000):
    """The 95% bootstrap interval of region i's per-region efficiency ratio (ratios(per_region=True)): seeds drawn
    with replacement, the same seeds for both configurations. A region's relMSE over seeds is heavy-tailed (a sun's
    rare hits), so a ratio from a few seeds can be far from its expectation: the interval says whether a cell below
    0.95x is resolved."""
    rng = np.random.default_rng(20261206)
    n = min(len(runs), len(base))
    out = []
    for _ in range(draws):
        k = rng.integers(0, n, n)
        m, m0 = (statistics.fmean(rs[j][1][i] for j in k) for rs in (runs, base))
        t, t0 = (statistics.median(rs[j][2][i] for j in k) for rs in (runs, base))
        out.append(m0 * t0 / (m * t))
    return tuple(np.percentile(out, [2.5, 97.5]))


def summarize(results, name, base, regions, glossy):
    """One line on `name` over `base` across every lighting: the lowest region, those below 0.95x, the geometric
    means (with each region's own seconds, the 95% bootstrap interval over the seeds of each region below 0.95x, and
    how many of them lie wholly below); first with each region's own seconds (the target's measure), then with each lighting's own whole-image
    seconds, then with the whole-image seconds ratio pooled over the lightings (the median of the per-lighting
    ratios: the systematic cost of the configuration without each lighting's timing noise, over the relMSE ratio at
    equal spp)."""
    times = {h: statistics.median(r[0] for r in runs[name]) / statistics.median(r[0] for r in runs[base])
             for h, runs in results.items()}
    pooled = statistics.median(times.values())
    text = []
    for label, cells in (
            ("each region's own seconds", [(h, regions[i], e) for h, runs in results.items() for i, e in
                                           enumerate(ratios(runs[name], runs[base], len(regions), True)[0])]),
            ("whole-image seconds", [(h, regions[i], e) for h, runs in results.items()
                                     for i, e in enumerate(ratios(runs[name], runs[base], len(regions))[0])]),
            ("seconds ratio pooled over lightings (%.3f)" % pooled,
             [(h, regions[i], r / pooled) for h, runs in results.items()
              for i, r in enumerate(ratios(runs[name], runs[base], len(regions))[1])])):
        if any(c[2] != c[2] for c in cells):
            text.append("with %s: not measured (renders without a seconds channel)" % label)
            continue
        worst = min(cells, key=lambda c: c[2])
        gl = [c[2] for c in cells if c[1] in glossy]
        below = [c for c in cells if c[2] < 0.95]
        listed = ["%s %s %.2f" % c for c in below]
        resolved = ""
        if label.startswith("each region"):
            ci = [interval(results[h][name], results[h][base], regions.index(r)) for h, r, _ in below]
            listed = ["%s [%.2f-%.2f]" % (t, lo, hi) for t, (lo, hi) in zip(listed, ci)]
            resolved = ", %d of them with the whole 95%% interval below 0.95x" % sum(hi < 0.95 for _, hi in ci)
        text.append("with %s: lowest %.2fx (%s, %s); %d of %d regions below 0.95x%s%s; geometric mean %.2fx over "
                    "every region%s" % (label, worst[2], worst[0], worst[1], len(below), len(cells),
                                        " (" + ", ".join(listed) + ")" if below else "", resolved,
                                  statistics.geometric_mean([c[2] for c in cells]),
                                  ", %.2fx over the glossy ones (%s)" % (statistics.geometric_mean(gl), ", ".join(
                                      glossy)) if gl else ""))
    return "`%s` over `%s` (seconds ratio per lighting %s): " % (name, base, ", ".join(
        "%s %.3f" % kv for kv in times.items())) + "; ".join(text)


if __name__ == "__main__":
    main()
