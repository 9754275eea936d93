#!/usr/bin/env python3
"""How fine must envbake's importance be? Render efficiency against the table resolution, with bake time and file
size, so that the default is chosen by measurement.

For each map and each importance resolution (the map's own grid, then halved, quartered, ...), envbake bakes the
tables envrender's default strategy reads (--tables hierarchical), and envrender renders scripts/bench/bench_cycles.py's
scene (four spheres on a ground) with its default strategy against a reference rendered from the full-resolution
tables at many samples (any tables give the same converged image: rendering stays unbiased).

  efficiency = 1 / (relMSE x seconds), relMSE over the object pixels (spheres + ground), eps = 0.01,
  seconds = envrender's envkit:seconds (the render loop), medians over --repeats seeds.

Maps: blender-data's sunrise, forest and interior (1024 x 512, real), and envprobe's default sky (sharp sun) at
--probe-size (default 8192x4096: the size whose full bake is hundreds of MB).

  scripts/bench/bench_bake_sizing.sh [--spp 64] [--ref-spp 1024] [--repeats 3] [--probe-size 8192x4096] [--out DIR]
Output: DIR/results.json and DIR/results.md (default out/bench_bake_sizing/).
"""
import argparse
import datetime
import json
import os
import subprocess
import time

import numpy as np

from bench import bench_cycles as bc  # the scene and the HDRIs
from bench.common import ROOT, exr_attr, read_exr, region_masks, rel_mse


def run(cmd):
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def bake(args, image, tables, resolution):
    # The scene reads every map with the Blender convention (bench_cycles.envrender_scene): bake in that frame.
    cmd = [f"{args.bin}/envbake", image, "-o", tables, "--tables", "hierarchical", "--from-convention", "blender",
           "-q", "-f"]
    if resolution:
        cmd += ["--resolution", "%dx%d" % resolution]
    t0 = time.perf_counter()
    run(cmd)
    return time.perf_counter() - t0, os.path.getsize(tables)


def render(args, scene, spp, seed, out):
    run([f"{args.bin}/envrender", "--scene", scene, "--spp", str(spp), "--seed", str(seed), "--threads",
         str(args.threads), "-q", "-f", "-o", out])
    return float(exr_attr(out, "envkit:seconds"))


def scene_file(args, work, name, image, tables):
    spec = bc.envrender_scene(bc.SCENE, image, args.size)
    spec["environment"]["tables"] = tables
    path = os.path.join(work, f"{name}_{os.path.basename(tables)}.json")
    with open(path, "w") as f:
        json.dump(spec, f, indent=1)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--probe-size", default="8192x4096")
    ap.add_argument("--levels", type=int, default=4, help="resolutions tried: full, /2, ... (this many)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", default=os.path.join(ROOT, "out", "bench_bake_sizing"))
    ap.add_argument("--bin", default=os.path.join(ROOT, "build", "bin"))
    args = ap.parse_args()
    args.size = (160, 90)
    os.makedirs(args.out, exist_ok=True)
    work = args.out

    probe = os.path.join(work, "probe_default.exr")
    run([f"{args.bin}/envprobe", "default", "-o", probe, "--size", args.probe_size])
    maps = [(h, os.path.join(bc.HDRI_DIR, h + ".exr")) for h in ("sunrise", "forest", "interior")]
    maps.append(("probe " + args.probe_size, probe))

    labels = region_masks(bc.SCENE, args.size)
    mask = labels >= 0
    start = datetime.datetime.now(datetime.timezone.utc)
    load_start = open("/proc/loadavg").read().split()[:3]
    results = {"date_utc": start.strftime("%Y-%m-%d %H:%M"), "spp": args.spp, "ref_spp": args.ref_spp,
               "repeats": args.repeats, "threads": args.threads, "size": list(args.size), "maps": {}}
    for name, image in maps:
        key = name.split()[0]
        info = json.loads(subprocess.run([f"{args.bin}/envinfo", image, "--json"], check=True, capture_output=True,
                                         text=True).stdout)
        w, h = info["width"], info["height"]
        full_tables = os.path.join(work, f"{key}_full.envtbl")
        bake(args, image, full_tables, None)
        ref_path = os.path.join(work, f"{key}_ref.exr")
        render(args, scene_file(args, work, key, image, full_tables), args.ref_spp, 9001, ref_path)
        ref = read_exr(ref_path)
        rows = []
        for level in range(args.levels):
            res = None if level == 0 else (max(w >> level, 2), max(h >> level, 1))
            tables = os.path.join(work, f"{key}_{level}.envtbl")
            bake_s, nbytes = bake(args, image, tables, res)
            scene = scene_file(args, work, key, image, tables)
            runs = []
            for rep in range(args.repeats):
                out = os.path.join(work, f"{key}_{level}_{rep}.exr")
                sec = render(args, scene, args.spp, 100 + rep, out)
                runs.append((rel_mse(read_exr(out), ref, mask), sec))
            relmse = float(np.median([r[0] for r in runs]))
            sec = float(np.median([r[1] for r in runs]))
            rows.append({"resolution": list(res) if res else [w, h], "bake_seconds": bake_s, "bytes": nbytes,
                         "relmse": relmse, "seconds": sec, "efficiency": 1.0 / (relmse * sec)})
            print(f"bench_bake_sizing: {name} {rows[-1]['resolution']}: bake {bake_s:.2f} s, "
                  f"{nbytes / 2**20:.1f} MiB, relMSE {relmse:.3g}, {sec:.3f} s", flush=True)
        results["maps"][name] = rows
    results["load_start"] = load_start
    results["load_end"] = open("/proc/loadavg").read().split()[:3]
    with open(os.path.join(work, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    write_markdown(results, os.path.join(work, "results.md"))
    print(f"bench_bake_sizing: wrote {work}/results.md")


def write_markdown(res, path):
    L = [f"envbake importance resolution vs render efficiency, {res['date_utc']} UTC, scene of bench_cycles.py at "
         f"{res['size'][0]}x{res['size'][1]}, envrender default strategy (product-mis over the hierarchical table), {res['spp']} spp, "
         f"medians of {res['repeats']} seeds, reference {res['ref_spp']} spp from the full tables, "
         f"{res['threads']} threads, load {' '.join(res['load_start'])} -> {' '.join(res['load_end'])}.", "",
         "| map | importance resolution | bake s | file MiB | relMSE | render s | efficiency | vs full |",
         "|---|---|---:|---:|---:|---:|---:|---:|"]
    for name, rows in res["maps"].items():
        full = rows[0]["efficiency"]
        for r in rows:
            L.append(f"| {name} | {r['resolution'][0]}x{r['resolution'][1]} | {r['bake_seconds']:.2f} | "
                     f"{r['bytes'] / 2**20:.1f} | {r['relmse']:.3g} | {r['seconds']:.3f} | {r['efficiency']:.3g} | "
                     f"{r['efficiency'] / full:.2f} |")
    with open(path, "w") as f:
        f.write("\n".join(L) + "\n")


if __name__ == "__main__":
    main()
