#!/usr/bin/env python3
"""Indirect light: envrender --max-depth D against Blender Cycles at max_bounces D - 1, unbiased and regularized.

The scene is bench_cycles.py's (four spheres on a diffuse ground: one Lambertian, three Fresnel-less GGX reflectors
of alpha 0.05, 0.15, 0.4; or --scene mesh), lit only by a real HDRI of blender-data. For each HDRI and depth:

  references   each renderer's own UNBIASED converged image (--ref-spp): envrender --regularize 0, Cycles with
               Filter Glossy 0 (blur_glossy). Every measured image of a renderer is compared with it, so that the
               bias of a regularized render counts in its error.
  envrender    --regularize V for every V of --regularize (0 = unbiased), at every spp of --spp.
  Cycles       Filter Glossy G for every G of --filter-glossy (0 = unbiased, 1 = Cycles' default), at every spp.
  bias         per regularization value (and Filter Glossy value), one render at --bias-spp: relMSE against the
               unbiased reference (the bias, plus both images' own noise at those spp: an upper bound).

Per region (each sphere, the ground: bench_cycles' analytic masks):
  relMSE = mean over the region's pixels and R, G, B of (img - ref)^2 / (ref^2 + 1e-2) (bench/common.py)
  seconds = envrender: envkit:seconds (the render loop; the product tables of the widened materials are built
            before it); Cycles: wall time of bpy.ops.render.render() after a warm-up (cycles_scene.py)
  efficiency = 1 / (relMSE x seconds); ratio = envrender / Cycles at the same spp
Tables: a summary (per HDRI, depth, spp and value: the efficiency ratio's geometric mean over the regions and its
range), efficiency ratios per region (envrender unbiased vs Cycles Filter Glossy 0; each envrender value vs Cycles'
default), and bias against noise for each regularization value.

  scripts/bench/bench_indirect.sh --quick     reduced run: sunrise, depth 3 only, 64x36, 16/64 spp, references
                                              1024 spp, regularize 0,0.5,1,2 (for a loaded machine)
  scripts/bench/bench_indirect.sh             full run: sunrise, forest, interior; depths 2, 3, 5; 16/64/256 spp;
                                              160x90; references 4096 spp
"""
import argparse
import datetime
import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np

from bench.bench_cycles import (HDRI_DIR, SCENES, cycles_shadowing, envrender_scene, fmt, spec_for_json,
                                write_meshes)
from bench.common import EPS, exr_attr, read_exr, region_masks, rel_mse


def counts_args(counts):
    """envrender's options for a --counts entry: "default" (by the material's lobe) or "N+M" (N BSDF + M light
    samples per shading point for every material)."""
    if counts == "default":
        return []
    n, m = counts.split("+")
    return ["--bsdf-samples", n, "--light-samples", m]


def variant_key(regularize, counts):
    """results.json's key of one envrender variant: the --regularize value, and its counts unless the default."""
    return f"{regularize:g}" + ("" if counts == "default" else f" {counts}")


def is_unbiased(key):
    return float(key.split()[0]) == 0.0


def run_envrender(args, scene_path, depth, regularize, spp, seed, out, counts="default"):
    cmd = [args.envrender, "--scene", scene_path, "--spp", str(spp), "--seed", str(seed), "--bake",
           "--max-depth", str(depth), "--regularize", repr(regularize), "--threads", str(args.threads), "-q", "-f",
           "-o", out] + counts_args(counts)
    if not (args.reuse and os.path.exists(out)):
        subprocess.run(cmd, check=True)
    return float(exr_attr(out, "envkit:seconds"))


def cycles_settings(bounces, filter_glossy):
    return {"max_bounces": bounces, "diffuse_bounces": bounces, "glossy_bounces": bounces,
            "blur_glossy": float(filter_glossy)}


def run_cycles(args, hdri, size, bounces, filter_glossy, renders, stem):
    """Renders `renders` ({spp, seed, output}) in one Blender session; returns their timings."""
    timings = stem + "_timings.json"
    if args.reuse and os.path.exists(timings):
        with open(timings) as fh:
            t = json.load(fh)
        if all(os.path.exists(r["output"]) for r in t["renders"]):
            return t
    spec = spec_for_json(args.spec)
    spec["camera"] = dict(spec["camera"], resolution=list(size))
    job = {"scene": spec, "hdri": hdri, "threads": args.threads, "renders": renders, "timings": timings,
           "cycles_settings": cycles_settings(bounces, filter_glossy)}
    with open(stem + "_job.json", "w") as fh:
        json.dump(job, fh, indent=1)
    here = os.path.dirname(os.path.abspath(__file__))
    with open(stem + ".log", "w") as lf:
        subprocess.run([args.blender, "-b", "--factory-startup", "--python", os.path.join(here, "cycles_scene.py"),
                        "--", stem + "_job.json"], check=True, stdout=lf, stderr=subprocess.STDOUT)
    with open(timings) as fh:
        return json.load(fh)


def region_errors(img, ref, mask, regions):
    return {r: rel_mse(img, ref, mask == i) for i, r in enumerate(regions)}


def measure_depth(args, hdri, d, depth, size, mask, regions):
    """Every render of one HDRI at one depth; returns the figures."""
    scene_path = os.path.join(d, "scene.json")
    bounces = depth - 1
    tag = f"d{depth}"
    R = {"depth": depth, "cycles_max_bounces": bounces, "envrender": {}, "cycles": {}}
    t0 = time.time()
    ref_e_path = os.path.join(d, f"ref_envrender_{tag}.exr")
    R["envrender_ref_seconds"] = run_envrender(args, scene_path, depth, 0.0, args.ref_spp, 9001, ref_e_path)
    ref_c_path = os.path.join(d, f"ref_cycles_{tag}.exr")
    t = run_cycles(args, hdri, size, bounces, 0.0, [{"spp": args.ref_spp, "seed": 9001, "output": ref_c_path}],
                   os.path.join(d, f"ref_cycles_{tag}"))
    R["cycles_ref_seconds"] = t["renders"][0]["seconds"]
    R["blender"] = t["blender"]
    ref = {"envrender": read_exr(ref_e_path), "cycles": read_exr(ref_c_path)}
    le, lc = ref["envrender"].mean(-1), ref["cycles"].mean(-1)
    rel = (lc - le) / np.maximum(le, 1e-8)
    R["agreement_median_abs_rel_diff"] = {r: float(np.median(np.abs(rel[mask == i]))) for i, r in enumerate(regions)}
    print(f"bench_indirect: depth {depth}: references {time.time() - t0:.0f} s", flush=True)
    for v in args.regularize:
        # One bias render per value, at the default counts: the counts do not change what a render converges to.
        bias_path = os.path.join(d, f"envrender_{tag}_reg{v:g}_bias.exr")
        run_envrender(args, scene_path, depth, v, args.bias_spp, 4242, bias_path)
        bias_img = read_exr(bias_path)
        bias = region_errors(bias_img, ref["envrender"], mask, regions)
        for c in args.counts:
            suffix = "" if c == "default" else f"_c{c}"
            runs, noise = {}, {}
            for spp in args.spp:
                reps = []
                for r in range(args.repeats):
                    rep = "" if r == 0 else f"_r{r}"
                    path = os.path.join(d, f"envrender_{tag}_reg{v:g}{suffix}_{spp}spp{rep}.exr")
                    sec = run_envrender(args, scene_path, depth, v, spp, 17 + spp + 1000 * r, path, c)
                    img = read_exr(path)
                    reps.append((sec, region_errors(img, ref["envrender"], mask, regions),
                                 region_errors(img, bias_img, mask, regions)))
                runs[str(spp)] = mean_repeats(reps, regions)
                noise[str(spp)] = {reg: float(np.mean([x[2][reg] for x in reps])) for reg in regions}
            R["envrender"][variant_key(v, c)] = {"runs": runs, "bias": bias, "noise": noise}
            print(f"bench_indirect: depth {depth}: envrender --regularize {v:g} counts {c} done", flush=True)
    for g in args.filter_glossy:
        renders = [{"spp": spp, "seed": 17 + spp + 1000 * r,
                    "output": os.path.join(d, f"cycles_{tag}_fg{g:g}_{spp}spp{'' if r == 0 else f'_r{r}'}.exr")}
                   for spp in args.spp for r in range(args.repeats)]
        renders.append({"spp": args.bias_spp, "seed": 4242, "output": os.path.join(d, f"cycles_{tag}_fg{g:g}_bias.exr")})
        t = run_cycles(args, hdri, size, bounces, g, renders, os.path.join(d, f"cycles_{tag}_fg{g:g}"))
        bias_img = read_exr(renders[-1]["output"])
        runs, noise = {}, {}
        for spp in args.spp:
            reps = []
            for r in t["renders"][:-1]:
                if r["spp"] != spp:
                    continue
                img = read_exr(r["output"])
                reps.append((r["seconds"], region_errors(img, ref["cycles"], mask, regions),
                             region_errors(img, bias_img, mask, regions)))
            runs[str(spp)] = mean_repeats(reps, regions)
            noise[str(spp)] = {reg: float(np.mean([x[2][reg] for x in reps])) for reg in regions}
        R["cycles"][f"{g:g}"] = {"runs": runs, "bias": region_errors(bias_img, ref["cycles"], mask, regions),
                                 "noise": noise}
        print(f"bench_indirect: depth {depth}: Cycles Filter Glossy {g:g} done", flush=True)
    return R


def mean_repeats(reps, regions):
    """The repeats of one render ((seconds, relMSE per region, noise per region) each): mean seconds, mean relMSE."""
    return {"seconds": float(np.mean([x[0] for x in reps])), "repeats": len(reps),
            "relmse": {reg: float(np.mean([x[1][reg] for x in reps])) for reg in regions}}


def efficiency(run, region):
    m = run["relmse"][region]
    return 1.0 / (m * run["seconds"]) if m > 0 else None


def compared_runs(res):
    """(HDRI, depth record, envrender value, Cycles Filter Glossy, spp, envrender run, Cycles run) for every pair the
    tables compare: a biased envrender against unbiased Cycles says little, so it is left out."""
    for h, H in res["hdris"].items():
        for R in H:
            for v, E in R["envrender"].items():
                for g, C in R["cycles"].items():
                    if not is_unbiased(v) and g == "0":
                        continue
                    for spp in map(str, res["spp"]):
                        yield h, R, v, g, spp, E["runs"][spp], C["runs"][spp]


def summary_rows(res):
    """Per HDRI, depth, spp and envrender value: the efficiency ratio against unbiased Cycles (value 0) and against
    Cycles' default, as the geometric mean over the regions and their range."""
    rows = []
    for h, R, v, g, spp, a, b in compared_runs(res):
        r = [efficiency(a, reg) / efficiency(b, reg) for reg in res["regions"]
             if efficiency(a, reg) and efficiency(b, reg)]
        if r:
            rows.append(f"| {h} | {R['depth']} | {spp} | {v} | {g} | "
                        f"**{float(np.exp(np.mean(np.log(r)))):.2f}** | {min(r):.2f}-{max(r):.2f} |")
    return rows


def counts_rows(res):
    """Per HDRI, depth, spp and value: each counts variant's efficiency over the default counts' (same value), as
    the geometric mean over the regions, their range, and the time ratio."""
    rows = []
    for h, H in res["hdris"].items():
        for R in H:
            for key, E in R["envrender"].items():
                if len(key.split()) < 2 or key.split()[0] not in R["envrender"]:
                    continue
                base = R["envrender"][key.split()[0]]
                for spp in map(str, res["spp"]):
                    a, b = E["runs"][spp], base["runs"][spp]
                    r = [efficiency(a, reg) / efficiency(b, reg) for reg in res["regions"]
                         if efficiency(a, reg) and efficiency(b, reg)]
                    if r:
                        rows.append(f"| {h} | {R['depth']} | {spp} | {key.split()[0]} | {key.split()[1]} | "
                                    f"**{float(np.exp(np.mean(np.log(r)))):.2f}** | {min(r):.2f}-{max(r):.2f} | "
                                    f"{a['seconds'] / b['seconds']:.2f} |")
    return rows


def write_markdown(res, out):
    L = [f"envrender --max-depth D vs Cycles max_bounces D - 1, {res['date_utc']} UTC, {res['size'][0]}x"
         f"{res['size'][1]} px, references {res['ref_spp']} spp (each renderer's own, unbiased), bias renders "
         f"{res['bias_spp']} spp, {res['threads']} threads, load average {' '.join(res['load_start'])} at start, "
         f"{' '.join(res['load_end'])} at end, {res['wall_minutes']:.1f} min.", "",
         "Efficiency = 1 / (relMSE x seconds) against the renderer's UNBIASED reference (bias counts); "
         "ratio = envrender / Cycles.", "",
         "Summary: the ratio's geometric mean over the regions, and its range.", "",
         "| HDRI | depth | spp | envrender regularize [counts] | Cycles Filter Glossy | ratio (geo mean) | regions |",
         "|---|---:|---:|---:|---:|---:|---|"] + summary_rows(res) + [""]
    if any(c != "default" for c in res.get("counts", [])):
        L += [f"Sample counts (N BSDF + M light per shading point, every vertex; {res.get('repeats', 1)} repeat(s), "
              "means) against the default counts (by the material's lobe), same --regularize value: efficiency "
              "ratio, geometric mean over the regions, range, and time ratio.", "",
              "| HDRI | depth | spp | regularize | counts | ratio (geo mean) | regions | time |",
              "|---|---:|---:|---:|---|---:|---|---:|"] + counts_rows(res) + [""]
    L += [
         "| HDRI | depth | spp | envrender regularize | Cycles Filter Glossy | region | relMSE envrender | "
         "relMSE Cycles | s envrender | s Cycles | ratio |",
         "|---|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|"]
    for h, R, v, g, spp, a, b in compared_runs(res):
        for reg in res["regions"]:
            ea, eb = efficiency(a, reg), efficiency(b, reg)
            ratio = ea / eb if ea and eb else None
            L.append(f"| {h} | {R['depth']} | {spp} | {v} | {g} | {reg} | {fmt(a['relmse'][reg])} | "
                     f"{fmt(b['relmse'][reg])} | {fmt(a['seconds'])} | {fmt(b['seconds'])} | "
                     f"**{fmt(ratio, 2)}** |")
    L += ["", "Bias against noise per regularization value (relMSE, mean over the regions): bias = the "
          f"{res['bias_spp']}-spp render against the unbiased reference (includes both images' noise: an upper "
          "bound); noise = the spp render against the bias render; total = against the unbiased reference.", "",
          "| HDRI | depth | renderer | value | bias | spp | noise | total | seconds | efficiency |",
          "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    for h, H in res["hdris"].items():
        for R in H:
            for who, label in (("envrender", "envrender --regularize"), ("cycles", "Cycles Filter Glossy")):
                for v, E in R[who].items():
                    bias = float(np.mean(list(E["bias"].values())))
                    for spp in map(str, res["spp"]):
                        run = E["runs"][spp]
                        noise = float(np.mean(list(E["noise"][spp].values())))
                        total = float(np.mean(list(run["relmse"].values())))
                        L.append(f"| {h} | {R['depth']} | {label} | {v} | {fmt(bias)} | {spp} | {fmt(noise)} | "
                                 f"{fmt(total)} | {fmt(run['seconds'])} | {fmt(1.0 / (total * run['seconds']))} |")
    L += ["", "Agreement of the two unbiased references (median |Cycles - envrender| / envrender per region):", ""]
    for h, H in res["hdris"].items():
        for R in H:
            L.append(f"- {h} depth {R['depth']}: " + ", ".join(
                f"{r} {100 * x:.2f}%" for r, x in R["agreement_median_abs_rel_diff"].items()))
    with open(os.path.join(out, "results.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")


def plot(res, out):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cells = [(h, R) for h, H in res["hdris"].items() for R in H]
    fig, axes = plt.subplots(1, len(cells), figsize=(4.2 * len(cells), 3.4), squeeze=False)
    for ax, (h, R) in zip(axes[0], cells):
        for who, marker in (("envrender", "o"), ("cycles", "s")):
            for v, E in R[who].items():
                bias = float(np.mean(list(E["bias"].values())))
                top = str(max(res["spp"]))
                noise = float(np.mean(list(E["noise"][top].values())))
                ax.loglog([max(bias, 1e-8)], [max(noise, 1e-8)], marker, label=f"{who} {v}")
        ax.set_xlabel("bias (relMSE)")
        ax.set_ylabel(f"noise at {max(res['spp'])} spp (relMSE)")
        ax.set_title(f"{h}, depth {R['depth']}", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "bias_noise.png"), dpi=90)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", choices=sorted(SCENES), default="spheres")
    ap.add_argument("--hdris", default="sunrise,forest,interior")
    ap.add_argument("--depths", default="2,3,5", help="envrender --max-depth values (Cycles: max_bounces one less)")
    ap.add_argument("--spp", default="16,64,256")
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--ref-spp", type=int, default=4096)
    ap.add_argument("--bias-spp", type=int, default=None, help="default: --ref-spp / 4")
    ap.add_argument("--regularize", default="0,0.25,0.5,1,2", help="envrender --regularize values")
    ap.add_argument("--counts", default="default",
                    help="envrender sample counts per shading point: default (by the material's lobe) or N+M "
                         "(--bsdf-samples N --light-samples M for every material), comma-separated")
    ap.add_argument("--repeats", type=int, default=1, help="renders per measured setting (seeds 17 + spp + 1000 r); "
                    "relMSE and seconds are their means")
    ap.add_argument("--filter-glossy", default="0,1", help="Cycles Filter Glossy values")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--quick", action="store_true",
                    help="reduced run: sunrise, depth 3, 64x36, 16/64 spp, references 1024 spp, regularize 0,0.5,1,2")
    ap.add_argument("--out", default="out/bench_indirect")
    ap.add_argument("--build", default="build")
    ap.add_argument("--blender", default="blender")
    ap.add_argument("--reuse", action="store_true", help="keep the EXRs already in --out (re-analyse)")
    if ap.parse_known_args()[0].quick:  # the reduced run's values, unless given
        ap.set_defaults(hdris="sunrise", depths="3", spp="16,64", size="64x36", ref_spp=1024, regularize="0,0.5,1,2")
    args = ap.parse_args()
    args.bias_spp = args.bias_spp or max(args.ref_spp // 4, 1)
    args.envrender = os.path.join(args.build, "bin", "envrender")
    for tool in (args.envrender, shutil.which(args.blender) or "", shutil.which("oiiotool") or ""):
        if not tool or not os.path.exists(tool):
            sys.exit("bench_indirect: missing " + (tool or "blender/oiiotool"))
    args.spp = [int(s) for s in args.spp.split(",")]
    args.regularize = [float(v) for v in args.regularize.split(",")]
    args.filter_glossy = [float(v) for v in args.filter_glossy.split(",")]
    args.counts = args.counts.split(",")
    depths = [int(v) for v in args.depths.split(",")]
    size = tuple(int(v) for v in args.size.lower().split("x"))
    os.makedirs(args.out, exist_ok=True)
    out = os.path.abspath(args.out)
    start = datetime.datetime.now(datetime.timezone.utc)
    load_start = open("/proc/loadavg").read().split()[:3]
    args.spec = write_meshes(SCENES[args.scene], out)
    regions = args.spec["regions"]
    mask = region_masks(args.spec, size)
    shadowing = cycles_shadowing(args.blender)
    results = {"date_utc": start.strftime("%Y-%m-%d %H:%M"), "size": list(size), "spp": args.spp,
               "ref_spp": args.ref_spp, "bias_spp": args.bias_spp, "threads": args.threads, "eps": EPS,
               "regions": regions, "scene": spec_for_json(args.spec), "regularize": args.regularize,
               "filter_glossy": args.filter_glossy, "counts": args.counts, "repeats": args.repeats,
               "quick": args.quick, "hdris": {}}
    for hdri_name in args.hdris.split(","):
        hdri = os.path.join(HDRI_DIR, hdri_name + ".exr")
        d = os.path.join(out, hdri_name)
        os.makedirs(d, exist_ok=True)
        with open(os.path.join(d, "scene.json"), "w") as fh:
            json.dump(envrender_scene(args.spec, hdri, size, shadowing), fh, indent=1)
        results["hdris"][hdri_name] = [measure_depth(args, hdri, d, depth, size, mask, regions) for depth in depths]
    results["load_start"] = load_start
    results["load_end"] = open("/proc/loadavg").read().split()[:3]
    results["wall_minutes"] = (datetime.datetime.now(datetime.timezone.utc) - start).total_seconds() / 60
    with open(os.path.join(out, "results.json"), "w") as fh:
        json.dump(results, fh, indent=1)
    write_markdown(results, out)
    plot(results, out)
    print("bench_indirect: wrote", os.path.join(out, "results.md"), flush=True)


if __name__ == "__main__":
    main()
