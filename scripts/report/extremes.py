"""Section 6: extremes. The sun's dynamic range (sun radiance over a sky of 1) from 1e2 to 1e9: relMSE and max pixel
error of each strategy at equal spp on a diffuse and a glossy sphere over a ground plane. Then the sizes at the
ends: 1x1, 2x1 and 3x1 lat-long maps and (full run) a 16384x8192 map through envconvert, envbake, envprefilter and
envrender: each tool's exit status, wall time and the conversion's power error."""
import math

import numpy as np

from report.common import (Context, Reference, commands_block, g, machine_line, max_rel_pixel_error, md_table, plt,
                           scene_from_template, scene_with_image)

ctx = Context("extremes")
RANGES = ctx.pick([1e6], [1e2, 1e5, 1e9], [1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9])
RES = ctx.pick((16, 8), (48, 24), (128, 64))
SPP = ctx.pick(1, 4, 16)
REF_SPP = ctx.pick(16, 256, 1024)
SIZE = ctx.pick([256, 128], [1024, 512], [1024, 512])
CONFIGS = [("bsdf", ["--strategy", "bsdf"]),
           ("light hierarchical", ["--strategy", "light", "--light-method", "hierarchical"]),
           ("mis-power", ["--strategy", "mis", "--heuristic", "power"]),
           ("mis-compensated", ["--strategy", "mis-compensated"]),
           ("product", ["--strategy", "product"]),
           ("product-mis", ["--strategy", "product-mis"])]
if ctx.mode == "smoke":
    CONFIGS = [c for c in CONFIGS if c[0] in ("bsdf", "mis-power", "product-mis")]
machine = machine_line()

res = {}
failures = {}
for L in RANGES:
    scene = scene_from_template(ctx, "extremes_sun", f"sun_{L:.0e}", RES,
                                {"radiance": L, "sky": 1.0, "size": SIZE})
    ref = Reference(ctx, scene, REF_SPP, ["--strategy", "mis", "--heuristic", "power"], f"ref_{L:.0e}")
    refmean = float(ref.image.mean())
    for name, opts in CONFIGS:
        r = ctx.render(ctx.path("r.exr"), scene, ["--spp", SPP, "--seed", 3] + opts, check=False)
        if "failed" in r:
            failures[name] = r["failed"]
            ctx.note(f"{name} failed at {L:g}: {r['failed']}")
            continue
        raw, corr = ref.error(r["image"])
        img = r["image"]
        res[(name, L)] = {"relmse": corr, "relmse_raw": raw, "seconds": r["seconds"],
                          "max_rel": max_rel_pixel_error(img, ref.image),
                          "max_abs_over_mean": float(np.max(np.abs(img.astype(np.float64) - ref.image)) / refmean),
                          "nonfinite": r["nonfinite"], "ref_noise": ref.noise,
                          "finite": bool(np.all(np.isfinite(img)))}
    ctx.info(f"dynamic range {L:g} done")

# ---------------------------------------------------------------- sizes at the ends
# (label, how the map is made: an envconvert target of the 2x1 probe, or a special case) per map; the largest lat-long
# depends on the mode.
BIG = ctx.pick(None, "4096x2048", "16384x8192")
MAPS = [("2x1 lat-long", "probe"), ("1x1 octahedral", ["--to", "octahedral", "--size", "1"]),
        ("1x1 mirror ball", ["--to", "mirrorball", "--size", "1"]),
        ("6x1 cube (hstrip, faces of 1)", ["--to", "cube", "--size", "1", "--layout", "hstrip"]),
        ("3x1 (no parameterization has it)", "plain")]
if BIG:
    MAPS.append((f"{BIG} lat-long", "big"))
if ctx.mode == "smoke":
    MAPS = [m for m in MAPS if m[0].startswith(("2x1", "1x1 oct", "3x1"))]


def power(path):
    import envkit  # built beside the tools (report.sh puts BUILD/python on PYTHONPATH)
    return np.asarray(envkit.EnvMap(path).power()[:3], np.float64)


tiny = ctx.path("tiny_2x1.exr")
ctx.run([ctx.tool("envprobe"), "default", "-o", tiny, "--size", "2x1", "-q"])
sizes = {}
for i, (label, how) in enumerate(MAPS):
    src = ctx.path(f"map{i}.exr")
    if how == "probe":
        src = tiny
    elif how == "big":
        ctx.run([ctx.tool("envprobe"), "default", "-o", src, "--size", BIG, "-q"])
    elif how == "plain":
        ctx.run(["oiiotool", "--pattern", "constant:color=1,1,1", "3x1", "3", "-d", "float", "-o", src])
    else:
        ctx.run([ctx.tool("envconvert"), tiny, "-o", src, "-q"] + how)
    face = 2048 if how == "big" else 1
    steps = {
        "envconvert": [ctx.tool("envconvert"), src, "-o", ctx.path(f"map{i}_cube.exr"), "--to", "cube", "--size", face,
                       "-q"],
        "envbake": [ctx.tool("envbake"), src, "-o", ctx.path(f"map{i}.envtbl"), "-q"],
        "envprefilter": [ctx.tool("envprefilter"), src, "-o", ctx.path(f"map{i}.ktx2"), "--size", min(256, face), "-q"],
        "envrender": [ctx.tool("envrender"), "-o", ctx.path(f"map{i}_render.exr"), "--scene",
                      scene_with_image(ctx, "default", f"map{i}", src, (16, 8)), "--bake", "--spp", 4, "-q"],
    }
    row = {}
    for tool, cmd in steps.items():
        out, err, wall, rc = ctx.run(cmd, check=False)
        last = err.strip().splitlines()[-1].replace("|", "/") if rc and err.strip() else ""
        row[tool] = {"exit": rc, "wall": wall, "error": last.replace(ctx.work + "/", "")}
    if row["envconvert"]["exit"] == 0:
        p_in, p_out = power(src), power(ctx.path(f"map{i}_cube.exr"))
        row["power"] = float(np.max(np.abs(p_out - p_in) / np.maximum(p_in, 1e-300)))
    sizes[label] = row
    ctx.info(f"{label} done")

# ---------------------------------------------------------------- plot
p = plt()
fig, axes = p.subplots(1, 2, figsize=(10, 3.8))
for i, (name, _) in enumerate(CONFIGS):
    xs = [L for L in RANGES if (name, L) in res]
    axes[0].loglog(xs, [max(res[(name, L)]["relmse"], 1e-12) for L in xs], "o-", label=name, color=f"C{i}")
    axes[1].loglog(xs, [max(res[(name, L)]["max_abs_over_mean"], 1e-12) for L in xs], "o-", label=name, color=f"C{i}")
axes[0].set_ylabel(f"relMSE at {SPP} spp")
axes[1].set_ylabel("max |I - R| / mean(R)")
for ax in axes:
    ax.set_xlabel("sun radiance / sky radiance")
    ax.legend(fontsize=7)
fig.tight_layout()
fig.savefig(f"{ctx.out}/extremes.png")

# ---------------------------------------------------------------- text
hdr = ["strategy"] + [f"{L:.0e}" for L in RANGES]
t1 = [[n] + [res[(n, L)]["relmse"] if (n, L) in res else "failed" for L in RANGES] for n, _ in CONFIGS]
t2 = [[n] + [res[(n, L)]["max_abs_over_mean"] if (n, L) in res else "failed" for L in RANGES] for n, _ in CONFIGS]
t3 = [[n] + [res[(n, L)]["max_rel"] if (n, L) in res else "failed" for L in RANGES] for n, _ in CONFIGS]
nonfinite = sum(v["nonfinite"] for v in res.values())
text = ["## 6. Extremes: sun dynamic range\n",
        f"Scene `scripts/report/scenes/extremes_sun.json`: a diffuse (albedo 0.7) and a glossy gold (roughness 0.1) "
        f"sphere on a diffuse ground, {RES[0]}x{RES[1]}, lit by `\"probe\": \"sun\"` (radius 0.27 deg, elevation "
        f"35 deg) with sky radiance 1 and sun radiance = the dynamic range, rasterized at {SIZE[0]}x{SIZE[1]}. "
        f"Every strategy at {SPP} spp (equal samples, not equal time) against `--strategy mis` at {REF_SPP} spp "
        f"(its expected noise subtracted from relMSE). Max pixel error: max |I - R| over pixels and channels divided "
        f"by the reference's mean (scale-free), and max |I - R| / (|R| + 0.1). Machine: {machine}.\n",
        "![extremes](extremes.png)\n",
        f"### relMSE at {SPP} spp\n", md_table(hdr, t1),
        "\n### max |I - R| / mean(R)\n", md_table(hdr, t2),
        "\n### max |I - R| / (|R| + 0.1)\n", md_table(hdr, t3),
        f"\nNon-finite estimates reported by envrender over all runs: {nonfinite}; non-finite pixels in the outputs: "
        f"{sum(not v['finite'] for v in res.values())}.\n",
        "\n### Sizes at the ends\n\nThe smallest maps of each kind, made from `envprobe default --size 2x1` by "
        "`envconvert` (so their metadata names their kind), a 3x1 image that fits no parameterization (made by "
        "oiiotool, no metadata: the tools must refuse it with one line)"
        + (f", and `envprobe default --size {BIG}`" if BIG else "") + ". Each goes through `envconvert --to cube "
        "--size F` (F = 1, 2048 for the large map), `envbake`, `envprefilter --size F` (at most 256) and `envrender "
        "--bake` of the default scene lit by the map at 4 spp. Exit status (0 = success; 1 = bad input, with its "
        "message) and wall time of each; power error = the cube's power against the source's (worst channel).\n",
        md_table(["map", "envconvert", "envbake", "envprefilter", "envrender", "power error"],
                 [[size] + [f"exit {r[t]['exit']}, {r[t]['wall']:.2f} s" + (f" ({r[t]['error'][:120]})" if r[t]["error"]
                                                                          else "")
                            for t in ("envconvert", "envbake", "envprefilter", "envrender")] + [r.get("power", "-")]
                  for size, r in sizes.items()])]
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx))
ctx.write_md("extremes.md", "\n".join(text))
ctx.save_summary({"ranges": RANGES, "configs": [c[0] for c in CONFIGS], "spp": SPP,
                  "res": {f"{k[0]}|{k[1]:g}": v for k, v in res.items()}, "failures": failures, "sizes": sizes})
ctx.info("wrote extremes.md")
