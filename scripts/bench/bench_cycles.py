#!/usr/bin/env python3
"""envrender vs Blender Cycles on real HDRIs (driver of scripts/bench/bench_cycles.sh).

One scene (four spheres on a diffuse ground: one Lambertian, three Fresnel-less GGX reflectors of alpha 0.05,
0.15, 0.4), lit only by a real HDRI of blender-data, rendered direct-light-only by envrender (its default
strategy, auto: power-heuristic MIS with each material's light table, product (lobe_product.h) or plain,
chosen by a pilot) and by Cycles (scripts/bench/cycles_scene.py)
in the same run. Each renderer is measured against its OWN converged reference rendered in the same run (another
seed, --ref-spp samples); the two references are compared with each other for agreement.

Per region (each sphere, the ground; pixels whose whole footprint sees one object, from analytic masks):
  relMSE = mean over the region's pixels and R, G, B of (img - ref)^2 / (ref^2 + EPS), EPS = 1e-2
  seconds = envrender: its envkit:seconds metadata (the render loop only: no start-up, scene load, BVH build,
            table bake or EXR write); Cycles: wall time of bpy.ops.render.render() after a 1-spp warm-up with
            persistent data (path tracing plus Cycles' per-render session start and film readback; no Blender
            start-up, scene build, BVH, importance map or EXR write)
  efficiency = 1 / (relMSE x seconds) (seconds of the whole image: the regions share one render)
With --repeats N, relMSE and seconds are the medians over N interleaved repeats (different seeds).

EXRs are read through oiiotool (bench/common.py), so only numpy and matplotlib are needed here.
"""
import argparse
import datetime
import json
import math
import os
import re
import shutil
import subprocess
import sys
import time

import numpy as np

from bench.common import EPS, exr_attr, read_exr, region_masks, rel_mse

HDRI_DIR = "/usr/share/blender/datafiles/studiolights/world"

CAMERA = {"position": [0.0, 1.6, -7.5], "look_at": [0.0, 0.55, 0.0], "up": [0, 1, 0], "fov": 26}
# What every scene has: the camera, the HDRI's intensity, the diffuse ground.
BASE = {"camera": CAMERA, "intensity": 1.0, "ground": {"half_size": 500.0, "material": "ground"},
        "spheres": [], "meshes": []}
GROUND = {"ground": {"type": "diffuse", "albedo": 0.45}}
SCENE = dict(BASE, materials=dict(GROUND, **{
    "diffuse": {"type": "diffuse", "albedo": 0.6},
    "ggx005": {"type": "ggx", "roughness": 0.05},
    "ggx015": {"type": "ggx", "roughness": 0.15},
    "ggx040": {"type": "ggx", "roughness": 0.4},
}), spheres=[
    {"center": [1.95, 0.55, 0.0], "radius": 0.55, "material": "diffuse"},
    {"center": [0.65, 0.55, 0.0], "radius": 0.55, "material": "ggx005"},
    {"center": [-0.65, 0.55, 0.0], "radius": 0.55, "material": "ggx015"},
    {"center": [-1.95, 0.55, 0.0], "radius": 0.55, "material": "ggx040"},
], regions=["diffuse", "ggx005", "ggx015", "ggx040", "ground"])
# The OBJ mesh scene: a diffuse torus and a glossy (GGX alpha 0.15) torus knot, flat-shaded triangle meshes written
# by this script (write_meshes) and read by both renderers from the same OBJ files.
MESH_SCENE = dict(BASE, materials=dict(GROUND, **{
    "torus": {"type": "diffuse", "albedo": 0.6},
    "knot": {"type": "ggx", "roughness": 0.15},
}), meshes=[{"name": "torus", "material": "torus"}, {"name": "knot", "material": "knot"}],
    regions=["torus", "knot", "ground"])
SCENES = {"spheres": SCENE, "mesh": MESH_SCENE}


def torus_mesh(center, major, minor, n_major=48, n_minor=16):
    """An upright torus (ring in the x-y plane) as vertices and triangles."""
    verts, tris = [], []
    for i in range(n_major):
        a = 2 * math.pi * i / n_major
        for j in range(n_minor):
            b = 2 * math.pi * j / n_minor
            r = major + minor * math.cos(b)
            verts.append([center[0] + r * math.cos(a), center[1] + r * math.sin(a), center[2] + minor * math.sin(b)])
    for i in range(n_major):
        for j in range(n_minor):
            a, b = i * n_minor + j, ((i + 1) % n_major) * n_minor + j
            c, d = ((i + 1) % n_major) * n_minor + (j + 1) % n_minor, i * n_minor + (j + 1) % n_minor
            tris += [[a, b, c], [a, c, d]]
    return verts, tris


def knot_mesh(center, scale, tube, p=2, q=3, n_path=192, n_tube=12):
    """A (p, q) torus knot tube, standing in the x-y plane, as vertices and triangles."""
    def path(t):
        r = 2 + math.cos(q * t)
        return np.array([r * math.cos(p * t), r * math.sin(p * t), -math.sin(q * t)]) * scale / 3
    verts, tris = [], []
    for i in range(n_path):
        t = 2 * math.pi * i / n_path
        c, nxt = path(t), path(t + 1e-3)
        tangent = (nxt - c) / np.linalg.norm(nxt - c)
        normal = np.cross(tangent, [0.0, 0.0, 1.0])
        normal /= np.linalg.norm(normal)
        binormal = np.cross(tangent, normal)
        for j in range(n_tube):
            b = 2 * math.pi * j / n_tube
            v = c + tube * (math.cos(b) * normal + math.sin(b) * binormal)
            verts.append([center[0] + v[0], center[1] + v[1], center[2] + v[2]])
    for i in range(n_path):
        for j in range(n_tube):
            a, b = i * n_tube + j, ((i + 1) % n_path) * n_tube + j
            c, d = ((i + 1) % n_path) * n_tube + (j + 1) % n_tube, i * n_tube + (j + 1) % n_tube
            tris += [[a, b, c], [a, c, d]]
    return verts, tris


MESH_BUILDERS = {"torus": lambda: torus_mesh([1.05, 0.68, 0.0], 0.48, 0.19),
                 "knot": lambda: knot_mesh([-1.05, 0.72, 0.0], 0.7, 0.11)}


def write_meshes(spec, folder):
    """Writes each mesh of the spec as an OBJ file in folder; returns the spec with each mesh's "file" set and
    its triangles (for the region masks) under "triangles"."""
    spec = dict(spec)
    meshes = []
    for m in spec.get("meshes", []):
        verts, tris = MESH_BUILDERS[m["name"]]()
        path = os.path.join(folder, m["name"] + ".obj")
        with open(path, "w") as fh:
            fh.write(f"# bench_cycles.py: {m['name']}, {len(tris)} triangles, envkit frame (+Y up)\n")
            fh.writelines(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in verts)
            fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in tris)
        meshes.append(dict(m, file=path, triangles=np.array(verts)[np.array(tris)]))
    spec["meshes"] = meshes
    return spec


def spec_for_json(spec):
    """The spec without the mask-only triangle arrays (for results.json and Cycles' job file)."""
    out = dict(spec)
    out["meshes"] = [{k: v for k, v in m.items() if k != "triangles"} for m in spec.get("meshes", [])]
    return out


def cycles_shadowing(blender):
    """The masking-shadowing of the peer's GGX: Cycles uses the separable G1(wo) G1(wi) up to Blender 3.x (Debian
    12 ships 3.4.1), the height-correlated G2 from Blender 4.0 on."""
    text = subprocess.run([blender, "--version"], check=True, capture_output=True, text=True).stdout
    m = re.search(r"Blender (\d+)\.", text)
    return "separable" if m and int(m.group(1)) < 4 else "height-correlated"


def envrender_scene(spec, hdri, size, shadowing="height-correlated"):
    """The scene in envrender's JSON format. A Fresnel-less GGX reflector is envrender's conductor with
    eta = 0, k = 1: its conductor Fresnel is then exactly 1 at every angle (material_microfacet.h). Its masking-
    shadowing is the peer's (cycles_shadowing()): with Blender 3.x's separable G1(wo) G1(wi), envrender's default
    height-correlated G2 is up to 1% brighter on the GGX 0.4 sphere (BENCHMARKS.md, "Cycles' masking-shadowing")."""
    mats = {}
    for name, m in spec["materials"].items():
        if m["type"] == "diffuse":
            mats[name] = {"type": "diffuse", "albedo": m["albedo"]}
        else:
            mats[name] = {"type": "conductor", "eta": 0.0, "k": 1.0, "roughness": m["roughness"],
                          "shadowing": shadowing}
    s = spec["ground"]["half_size"]
    cam = dict(spec["camera"])
    cam["resolution"] = list(size)
    return {
        "camera": cam,
        "environment": {"image": hdri, "convention": "blender", "intensity": spec["intensity"]},
        "materials": mats,
        "shapes": [{"type": "triangles", "material": spec["ground"]["material"],
                    "vertices": [[-s, 0, -s], [s, 0, -s], [s, 0, s], [-s, 0, s]],
                    "triangles": [[0, 2, 1], [0, 3, 2]]}]
        + [{"type": "sphere", "center": sp["center"], "radius": sp["radius"], "material": sp["material"]}
           for sp in spec["spheres"]]
        + [{"type": "mesh", "file": m["file"], "material": m["material"]} for m in spec.get("meshes", [])],
    }


def run_envrender(args, scene_path, spp, seed, out):
    cmd = [args.envrender, "--scene", scene_path, "--spp", str(spp), "--seed", str(seed), "--bake",
           "--threads", str(args.threads), "-q", "-f", "-o", out]
    if args.crop:
        cmd += ["--crop", ",".join(str(v) for v in args.crop)]
    if not (args.reuse and os.path.exists(out)):
        subprocess.run(cmd, check=True)
    return float(exr_attr(out, "envkit:seconds"))


def run_cycles(args, hdri, size, renders, timings_path, job_path):
    if args.reuse and os.path.exists(timings_path):
        with open(timings_path) as fh:
            t = json.load(fh)
        if all(os.path.exists(r["output"]) for r in t["renders"]):
            return t
    spec = spec_for_json(args.spec)
    spec["camera"] = dict(spec["camera"], resolution=list(size))
    if args.crop:
        spec["crop"] = list(args.crop)
    job = {"scene": spec, "hdri": hdri, "threads": args.threads, "renders": renders, "timings": timings_path}
    with open(job_path, "w") as fh:
        json.dump(job, fh, indent=1)
    here = os.path.dirname(os.path.abspath(__file__))
    log = job_path.replace(".json", ".log")
    with open(log, "w") as lf:
        subprocess.run([args.blender, "-b", "--factory-startup", "--python", os.path.join(here, "cycles_scene.py"),
                        "--", job_path], check=True, stdout=lf, stderr=subprocess.STDOUT)
    with open(timings_path) as fh:
        t = json.load(fh)
    for r in t["renders"]:
        if not os.path.exists(r["output"]):
            sys.exit("bench_cycles: Cycles did not write " + r["output"] + " (see " + log + ")")
    return t


def tonemap(img):
    x = img / (1.0 + img)
    return np.clip(x, 0, 1) ** (1 / 2.2)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=sorted(SCENES), default="spheres",
                    help="spheres: four spheres on a ground; mesh: two OBJ meshes (a diffuse torus, a GGX 0.15 "
                         "torus knot) on a ground")
    ap.add_argument("--hdris", default="sunrise,forest,interior")
    ap.add_argument("--spp", default="16,64,256")
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--ref-spp", type=int, default=2048, help="spp of both converged references")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--crop", default=None,
                    help="x0,y0,x1,y1: render only this window of the frame in both renderers (pixels, row 0 on top, "
                         "x1 and y1 exclusive), e.g. one sphere at a high --ref-spp to see its references converge")
    ap.add_argument("--quick", action="store_true", help="debug run: sunrise only, 64x36, 4/16 spp, ref 256")
    ap.add_argument("--out", default=None, help="default out/bench_cycles (spheres) or out/bench_cycles_mesh")
    ap.add_argument("--build", default="build")
    ap.add_argument("--blender", default="blender")
    ap.add_argument("--reuse", action="store_true",
                    help="re-analyse: keep the EXRs (and their timings) already in --out instead of rendering again")
    args = ap.parse_args()
    if args.quick:
        args.hdris, args.spp, args.size, args.ref_spp, args.repeats = "sunrise", "4,16", "64x36", 256, 1
    args.envrender = os.path.join(args.build, "renderer", "envrender")
    if not os.path.exists(args.envrender):
        cand = os.path.join(args.build, "bin", "envrender")
        args.envrender = cand if os.path.exists(cand) else args.envrender
    for tool in (args.envrender, shutil.which(args.blender) or "", shutil.which("oiiotool") or ""):
        if not tool or not os.path.exists(tool):
            sys.exit("bench_cycles: missing " + (tool or "blender/oiiotool") + " (build envrender; install blender, openimageio-tools)")
    if args.out is None:
        args.out = "out/bench_cycles" + ("" if args.scene == "spheres" else "_" + args.scene)
    hdris = args.hdris.split(",")
    spps = [int(s) for s in args.spp.split(",")]
    size = tuple(int(v) for v in args.size.lower().split("x"))
    if args.crop:
        args.crop = tuple(int(v) for v in args.crop.split(","))
        x0, y0, x1, y1 = args.crop
        if not (len(args.crop) == 4 and 0 <= x0 < x1 <= size[0] and 0 <= y0 < y1 <= size[1]):
            sys.exit(f"bench_cycles: --crop {args.crop} is not a window of the {size[0]}x{size[1]} frame")
    os.makedirs(args.out, exist_ok=True)
    out = os.path.abspath(args.out)
    start = datetime.datetime.now(datetime.timezone.utc)
    previous = None
    if args.reuse and os.path.exists(os.path.join(out, "results.json")):
        with open(os.path.join(out, "results.json")) as fh:
            previous = json.load(fh)
    load_before = open("/proc/loadavg").read().split()[:3]
    args.spec = write_meshes(SCENES[args.scene], out)
    regions = args.spec["regions"]
    mask = region_masks(args.spec, size)
    if args.crop:
        # The window's labels, renumbered over the regions it holds.
        mask = mask[args.crop[1]:args.crop[3], args.crop[0]:args.crop[2]]
        held = [i for i in range(len(regions)) if (mask == i).any()]
        renumber = np.full(len(regions), -2)
        renumber[held] = np.arange(len(held))
        mask = np.where(mask >= 0, renumber[np.maximum(mask, 0)], mask)
        regions = [regions[i] for i in held]
    np.save(os.path.join(out, "regions.npy"), mask)
    shadowing = cycles_shadowing(args.blender)
    results = {"date_utc": start.strftime("%Y-%m-%d %H:%M"), "size": list(size),
               "crop": list(args.crop) if args.crop else None, "spp": spps, "ref_spp": args.ref_spp,
               "repeats": args.repeats, "threads": args.threads, "eps": EPS, "regions": regions,
               "region_pixels": {r: int((mask == i).sum()) for i, r in enumerate(regions)},
               "background_pixels": int((mask == -1).sum()), "scene": spec_for_json(args.spec),
               "envrender_strategy": "default: auto (power-heuristic MIS, each material's light table, product or "
                                     "plain, and the sun apart or not chosen by a pilot), sample counts by lobe, "
                                     "conductors with " + shadowing + " masking-shadowing",
               "hdris": {}}
    for hdri_name in hdris:
        hdri = os.path.join(HDRI_DIR, hdri_name + ".exr")
        d = os.path.join(out, hdri_name)
        os.makedirs(d, exist_ok=True)
        scene_path = os.path.join(d, "scene.json")
        with open(scene_path, "w") as fh:
            json.dump(envrender_scene(args.spec, hdri, size, shadowing), fh, indent=1)
        R = {"envrender": {"runs": []}, "cycles": {"runs": []}}
        # Converged references, each renderer its own, seeds disjoint from the measured runs.
        t0 = time.time()
        ref_e = os.path.join(d, "ref_envrender.exr")
        R["envrender"]["ref_seconds"] = run_envrender(args, scene_path, args.ref_spp, 9001, ref_e)
        ref_c = os.path.join(d, "ref_cycles.exr")
        tc = run_cycles(args, hdri, size, [{"spp": args.ref_spp, "seed": 9001, "output": ref_c}],
                        os.path.join(d, "ref_cycles_timings.json"), os.path.join(d, "ref_cycles_job.json"))
        R["cycles"]["ref_seconds"] = tc["renders"][0]["seconds"]
        R["cycles"]["blender"] = tc["blender"]
        R["cycles"]["sampling_pattern"] = tc["sampling_pattern"]
        print(f"bench_cycles: {hdri_name}: references {time.time() - t0:.0f} s", flush=True)
        ref = {"envrender": read_exr(ref_e), "cycles": read_exr(ref_c)}
        for rep in range(args.repeats):
            order = ["envrender", "cycles"] if rep % 2 == 0 else ["cycles", "envrender"]
            for who in order:
                if who == "envrender":
                    for spp in spps:
                        path = os.path.join(d, f"envrender_{spp}spp_r{rep}.exr")
                        sec = run_envrender(args, scene_path, spp, 100 * rep + spp, path)
                        R["envrender"]["runs"].append({"spp": spp, "rep": rep, "seconds": sec, "path": path})
                else:
                    renders = [{"spp": spp, "seed": 100 * rep + spp, "output": os.path.join(d, f"cycles_{spp}spp_r{rep}.exr")}
                               for spp in spps]
                    t = run_cycles(args, hdri, size, renders, os.path.join(d, f"cycles_r{rep}_timings.json"),
                                   os.path.join(d, f"cycles_r{rep}_job.json"))
                    for r in t["renders"]:
                        R["cycles"]["runs"].append({"spp": r["spp"], "rep": rep, "seconds": r["seconds"],
                                                    "path": r["output"], "warmup_seconds": t["warmup_seconds"]})
            print(f"bench_cycles: {hdri_name}: repeat {rep + 1}/{args.repeats} done", flush=True)
        for who in ("envrender", "cycles"):
            for run in R[who]["runs"]:
                img = read_exr(run["path"])
                run["relmse"] = {r: rel_mse(img, ref[who], mask == i) for i, r in enumerate(regions)}
            summary = {}
            for spp in spps:
                runs = [r for r in R[who]["runs"] if r["spp"] == spp]
                sec = float(np.median([r["seconds"] for r in runs]))
                summary[str(spp)] = {"seconds": sec, "regions": {}}
                for reg in regions:
                    m = float(np.median([r["relmse"][reg] for r in runs]))
                    summary[str(spp)]["regions"][reg] = {"relmse": m, "efficiency": 1.0 / (m * sec) if m > 0 else None}
            R[who]["summary"] = summary
        # Agreement of the two references.
        e, c = ref["envrender"], ref["cycles"]
        le, lc = e.mean(-1), c.mean(-1)
        rel = (lc - le) / np.maximum(le, 1e-8)
        # Noise floor of this pixel-wise comparison: each renderer's two repeats at the highest spp are independent
        # images; the median |rel. diff| between them, scaled by sqrt(2 spp_max / (2 ref_spp)) (two images of
        # ref_spp instead of spp_max), estimates the median a noise-free pair of references would show from their
        # own noise alone (exact for Gaussian pixel errors; heavy-tailed sun samples make it approximate).
        floor = {}
        top = max(spps)
        for who in ("envrender", "cycles"):
            runs = [r for r in R[who]["runs"] if r["spp"] == top]
            if len(runs) >= 2:
                a, b = read_exr(runs[0]["path"]).mean(-1), read_exr(runs[1]["path"]).mean(-1)
                floor[who] = np.abs(a - b) / np.maximum(ref[who].mean(-1), 1e-8) * math.sqrt(top / args.ref_spp)
        agree = {}
        for i, reg in enumerate(regions + ["background"]):
            m = (mask == i) if reg != "background" else (mask == -1)
            if not m.any():  # a window without background
                continue
            agree[reg] = {"median_abs_rel_diff": float(np.median(np.abs(rel[m]))),
                          "median_signed_rel_diff": float(np.median(rel[m])),
                          "mean_ratio_cycles_over_envrender": float(lc[m].sum() / max(le[m].sum(), 1e-30)),
                          "noise_floor_median_abs_rel_diff":
                              float(math.sqrt(0.5 * (np.median(floor["envrender"][m]) ** 2
                                                     + np.median(floor["cycles"][m]) ** 2)))
                              if len(floor) == 2 else None}
        R["agreement"] = agree
        results["hdris"][hdri_name] = R
        # Side-by-side picture of the references and their relative difference.
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(1, 3, figsize=(12, 2.6))
        ax[0].imshow(tonemap(e)); ax[0].set_title(f"envrender ref ({args.ref_spp} spp)")
        ax[1].imshow(tonemap(c)); ax[1].set_title(f"Cycles ref ({args.ref_spp} spp)")
        im = ax[2].imshow(np.clip(rel, -0.1, 0.1), cmap="RdBu_r", vmin=-0.1, vmax=0.1)
        ax[2].set_title("(Cycles - envrender) / envrender")
        fig.colorbar(im, ax=ax[2])
        for a in ax:
            a.axis("off")
        fig.tight_layout()
        fig.savefig(os.path.join(out, f"refs_{hdri_name}.png"), dpi=100)
        plt.close(fig)
    results["uptime_load_start"] = load_before
    results["uptime_load_end"] = open("/proc/loadavg").read().split()[:3]
    results["wall_minutes"] = (datetime.datetime.now(datetime.timezone.utc) - start).total_seconds() / 60
    if args.reuse and previous:  # the date, load and duration are the rendering run's, not this re-analysis's
        for key in ("date_utc", "uptime_load_start", "uptime_load_end", "wall_minutes"):
            results[key] = previous[key]
        results["reanalysed_utc"] = start.strftime("%Y-%m-%d %H:%M")
    with open(os.path.join(out, "results.json"), "w") as fh:
        json.dump(results, fh, indent=1)
    write_markdown(results, out)
    plot(results, out)
    print("bench_cycles: wrote", os.path.join(out, "results.md"), flush=True)


def fmt(x, d=3):
    if x is None:
        return "-"
    if x == 0:
        return "0"
    if abs(x) >= 1e4 or abs(x) < 1e-3:
        return f"{x:.2e}"
    return f"{x:.{d}g}"


def write_markdown(res, out):
    L = []
    crop = res.get("crop")
    window = f" (the window {crop[0]},{crop[1]} to {crop[2]},{crop[3]})" if crop else ""
    L.append(f"envrender vs Cycles, {res['date_utc']} UTC, {res['size'][0]}x{res['size'][1]} px{window}, references "
             f"{res['ref_spp']} spp each, {res['repeats']} interleaved repeat(s) (medians), {res['threads']} threads, "
             f"load average at start {' '.join(res['uptime_load_start'])}, at end {' '.join(res['uptime_load_end'])}.")
    L.append("")
    L.append("Efficiency = 1 / (relMSE x seconds); relMSE against each renderer's own reference, eps = "
             f"{res['eps']}. Ratio = envrender / Cycles efficiency (target >= 2 at 64 and 256 spp).")
    L.append("")
    L.append("| HDRI | spp | region | relMSE envrender | relMSE Cycles | s envrender | s Cycles | eff. envrender | eff. Cycles | ratio |")
    L.append("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|")
    verdict = []
    for h, R in res["hdris"].items():
        for spp in res["spp"]:
            se, sc = R["envrender"]["summary"][str(spp)], R["cycles"]["summary"][str(spp)]
            for reg in res["regions"]:
                a, b = se["regions"][reg], sc["regions"][reg]
                ratio = a["efficiency"] / b["efficiency"] if a["efficiency"] and b["efficiency"] else None
                if spp in (64, 256) and ratio is not None:
                    verdict.append((h, spp, reg, ratio))
                L.append(f"| {h} | {spp} | {reg} | {fmt(a['relmse'])} | {fmt(b['relmse'])} | {fmt(se['seconds'])} | "
                         f"{fmt(sc['seconds'])} | {fmt(a['efficiency'])} | {fmt(b['efficiency'])} | "
                         f"**{fmt(ratio, 2)}** |")
    L.append("")
    L.append("Agreement of the converged references (per pixel: grey mean of R, G, B; relative difference "
             "(Cycles - envrender) / envrender; target: median |diff| <= 0.5%). 'noise floor' = the median |diff| "
             "the references' own noise alone would give, estimated from each renderer's two repeats at the top spp "
             "(their median |diff| scaled by sqrt(spp / ref spp), the two renderers combined in quadrature; "
             "approximate: pixel errors with the sun in view are heavy-tailed). 'region mean' compares the "
             "region's summed radiance (noise mostly averaged out).")
    L.append("")
    L.append("| HDRI | region | median abs rel. diff | median signed | region mean Cycles / envrender | noise floor |")
    L.append("|---|---|---:|---:|---:|---:|")
    agree_ok = []
    for h, R in res["hdris"].items():
        for reg, a in R["agreement"].items():
            if reg != "background":
                agree_ok.append((h, reg, a["median_abs_rel_diff"]))
            L.append(f"| {h} | {reg} | {100 * a['median_abs_rel_diff']:.2f}% | {100 * a['median_signed_rel_diff']:+.2f}% | "
                     f"{a['mean_ratio_cycles_over_envrender']:.4f} | "
                     + ("-" if a["noise_floor_median_abs_rel_diff"] is None else f"{100 * a['noise_floor_median_abs_rel_diff']:.2f}%") + " |")
    L.append("")
    met = [v for v in verdict if v[3] >= 2]
    L.append(f"Efficiency target (>= 2x at 64 and 256 spp): met in {len(met)} of {len(verdict)} (HDRI, spp, region) "
             "cells." + ("" if len(met) == len(verdict) else " Not met: " + ", ".join(
                 f"{h} {s} spp {r} ({fmt(x, 2)}x)" for h, s, r, x in verdict if x < 2) + "."))
    met4 = [v for v in verdict if v[3] >= 4]
    L.append(f"At 4x or more (the product-sampling target): {len(met4)} of {len(verdict)} cells"
             + ("." if len(met4) == len(verdict) else "; below: " + ", ".join(
                 f"{h} {s} spp {r} ({fmt(x, 2)}x)" for h, s, r, x in verdict if x < 4) + "."))
    bad = [a for a in agree_ok if a[2] > 0.005]
    L.append(f"Agreement target (median <= 0.5%): met in {len(agree_ok) - len(bad)} of {len(agree_ok)} (HDRI, region) "
             "cells." + ("" if not bad else " Not met: " + ", ".join(f"{h} {r} ({100 * x:.2f}%)" for h, r, x in bad) + "."))
    with open(os.path.join(out, "results.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")


def plot(res, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    hs = list(res["hdris"])
    regs = res["regions"]
    fig, axes = plt.subplots(len(hs), len(regs), figsize=(3.2 * len(regs), 2.8 * len(hs)), squeeze=False)
    for i, h in enumerate(hs):
        for j, reg in enumerate(regs):
            ax = axes[i][j]
            for who, style in (("envrender", "o-"), ("cycles", "s--")):
                ys = [res["hdris"][h][who]["summary"][str(s)]["regions"][reg]["efficiency"] for s in res["spp"]]
                ax.plot(res["spp"], ys, style, label=who)
            ax.set_xscale("log", base=2)
            ax.set_yscale("log")
            ax.set_title(f"{h}: {reg}", fontsize=9)
            ax.grid(True, which="both", alpha=0.3)
            if i == len(hs) - 1:
                ax.set_xlabel("spp")
            if j == 0:
                ax.set_ylabel("1 / (relMSE x s)")
            if i == 0 and j == 0:
                ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "efficiency.png"), dpi=90)
    plt.close(fig)


if __name__ == "__main__":
    main()
