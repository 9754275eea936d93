"""Section 8: indirect light. envrender --max-depth 3 on the report's default scene (glossy spheres and a diffuse one
on a diffuse ground), lit by the built-in sunny probe and, where blender's data is installed, real captures. For each
--regularize value (0 = unbiased): the noise of a render at equal spp against the converged image of the same value,
the bias of that converged image against the unbiased reference, the total error against the unbiased reference
(what a user gets), the time, and the efficiency over the unbiased setting. The trade docs/RENDERER-INDIRECT.md
describes, measured in every report run."""
import numpy as np

from bench.common import exr_attr
from report.common import (Context, Reference, ToolFailed, commands_block, g, geomean, machine_line,
                           make_probe_images, md_table, plt, scene_with_image)

ctx = Context("indirect")
DEPTH = 3
VALUES = ctx.pick([0.0, 1.0], [0.0, 0.5, 1.0], [0.0, 0.25, 0.5, 1.0])
PROBES = ctx.pick(["sunny"], ["sunny", "sunrise"], ["sunny", "sunrise", "forest", "interior"])
RES = ctx.pick((32, 16), (96, 48), (160, 80))
SPP = ctx.pick(2, 16, 64)                    # the renders a user looks at
CONVERGED_SPP = ctx.pick(8, 256, 1024)       # each value's converged image (its bias against the reference)
REF_SPP = ctx.pick(16, 512, 2048)            # the unbiased reference (--regularize 0)
SKY = ctx.pick("256x128", "1024x512", "1024x512")
machine = machine_line()
common = ["--max-depth", DEPTH]


def default_value():
    """envrender's --regularize when the option is not given, from the metadata of a tiny render without it (the
    recommendation names it); None when that render fails."""
    out = ctx.path("default_value.exr")
    r = ctx.render(out, None, ["--spp", 1, "--resolution", "8x4", "--max-depth", DEPTH, "-q"], read=False,
                   check=False)
    text = None if "failed" in r else exr_attr(out, "envkit:regularize")
    return float(text) if text else None


DEFAULT = default_value()
images = make_probe_images(ctx, [p for p in PROBES if p != "overcast"], SKY)
results = {}
for probe, image in images.items():
    scene = scene_with_image(ctx, "default", f"indirect_{probe}", image, RES)
    try:
        ref = Reference(ctx, scene, REF_SPP, common + ["--regularize", 0], f"ref_{probe}")
    except ToolFailed as e:
        ctx.note(f"{probe}: the unbiased reference failed ({e}): no row")
        continue
    rows = {}
    for v in VALUES:
        opts = common + ["--regularize", v]
        # Another seed than the reference's: images drawn from the same numbers would share their noise.
        converged = ref if v == 0.0 else Reference(ctx, scene, CONVERGED_SPP, opts, f"converged_{probe}_{v:g}",
                                                   seed=2000003)
        # The converged image against the reference: squared bias plus both images' own noise, which is taken off
        # (Reference.error takes off the reference's; the converged image's is its AOV's mean, converged.noise).
        bias = 0.0 if v == 0.0 else max(ref.error(converged.image)[1] - converged.noise, 0.0)
        r = ctx.render(ctx.path("r.exr"), scene, ["--spp", SPP, "--seed", 7, "--bake"] + opts, check=False)
        if "failed" in r:
            ctx.note(f"{probe} --regularize {v:g} failed: {r['failed']}")
            continue
        noise = converged.error(r["image"])[1]  # against its own converged image: the variance at SPP
        total = ref.error(r["image"])[1]        # against the unbiased reference: what a user gets
        rows[v] = {"seconds": r["seconds"], "noise": noise, "bias": bias, "total": total,
                   "nonfinite": r["nonfinite"], "floor": ref.noise + converged.noise}
    base = rows.get(0.0)
    for v, row in rows.items():
        row["efficiency"] = (base["total"] * base["seconds"] / (row["total"] * row["seconds"])
                             if base and row["total"] > 0 and row["seconds"] > 0 else None)
    results[probe] = rows
    ctx.info(f"{probe} done")

# ---------------------------------------------------------------- plot: bias against noise
if results:
    p = plt()
    fig, ax = p.subplots(figsize=(5.2, 3.6))
    measured = [x for rows in results.values() for row in rows.values() for x in (row["noise"], row["bias"]) if x > 0]
    floor = 0.3 * min(measured) if measured else 1e-6  # where a bias the run could not resolve (0) is drawn
    for probe, rows in results.items():
        vs = [v for v in VALUES if v in rows and v > 0]
        xs = [rows[v]["noise"] for v in vs]
        ys = [rows[v]["bias"] if rows[v]["bias"] > 0 else floor for v in vs]
        line, = ax.plot(xs, ys, "o-", label=probe)
        for v, x, y in zip(vs, xs, ys):
            ax.annotate(f"{v:g}", (x, y), fontsize=7, xytext=(3, 3), textcoords="offset points")
        if 0.0 in rows:
            ax.axvline(rows[0.0]["noise"], color=line.get_color(), ls=":", lw=0.8)
    span = [floor] + measured
    ax.plot([min(span), max(span)], [min(span), max(span)], color="grey", lw=0.6, ls="--", label="bias = noise")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"noise at {SPP} spp (relMSE against the value's converged image)")
    ax.set_ylabel("bias (relMSE of the converged image;\n0, not resolved: drawn at the bottom)", fontsize=8)
    ax.set_title(f"--regularize: bias against noise, depth {DEPTH} (dotted: the unbiased setting's noise)", fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(f"{ctx.out}/indirect.png")

# ---------------------------------------------------------------- tables
text = [f"## 8. Indirect light: regularization's bias against its noise\n",
        f"Scene: scripts/report/scenes/default.json (glossy conductors and plastics of GGX alpha 0.01-0.5 and a "
        f"diffuse sphere on a diffuse ground) at {RES[0]}x{RES[1]}, `--max-depth {DEPTH}` (two bounces), lit by "
        f"{', '.join(images) or '(no probe)'} (the built-in probe rasterized at {SKY}, blender's HDRIs as they are; "
        f"tables baked in memory). For each `--regularize` value: "
        f"**noise** = relMSE of a {SPP}-spp render against that value's own converged image ({CONVERGED_SPP} spp); "
        f"**bias** = relMSE of that converged image against the unbiased reference (`--regularize 0`, {REF_SPP} "
        f"spp), both images' own noise (their variance AOVs) taken off: 0 when the run cannot tell it from noise; "
        f"**total** = relMSE of the {SPP}-spp render against the unbiased reference, its noise taken off (what a user "
        f"gets, bias included); **efficiency** = 1 / (total x seconds) over the unbiased setting's. relMSE is a mean "
        f"over pixels and channels of one render (one seed): on sunny maps the caustics' fireflies make it "
        f"heavy-tailed, so one run ranks values only where they differ by a lot. Machine: {machine}.\n",
        "![bias against noise](indirect.png)\n"]
for probe, rows in results.items():
    text.append(f"### {probe}\n")
    text.append("Bias resolution: a bias below the noise of the two images compared (the reference's and the converged "
                "image's own, " + ", ".join(f"{v:g}: {g(rows[v]['floor'])}" for v in VALUES if v in rows and v > 0)
                + ") is not told apart from it.\n")
    text.append(md_table(["--regularize", "seconds", f"noise ({SPP} spp)", "bias", "total", "efficiency vs 0"],
                         [[f"{v:g}", rows[v]["seconds"], rows[v]["noise"], rows[v]["bias"], rows[v]["total"],
                           rows[v]["efficiency"]] for v in VALUES if v in rows]))
nonfinite = sum(row["nonfinite"] for rows in results.values() for row in rows.values())
text.append(f"\nNon-finite estimates reported by envrender over all runs: {nonfinite}.\n")
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx))
ctx.write_md("indirect.md", "\n".join(text))
ctx.save_summary({"values": VALUES, "probes": list(results), "results": {p: {f"{v:g}": row for v, row in rows.items()}
                                                                        for p, rows in results.items()},
                  "default": DEFAULT, "spp": SPP, "converged_spp": CONVERGED_SPP, "ref_spp": REF_SPP, "depth": DEPTH,
                  "res": RES,
                  "geomean_efficiency": {f"{v:g}": geomean([rows[v]["efficiency"] for rows in results.values()
                                                            if v in rows and rows[v]["efficiency"]])
                                         for v in VALUES}})
ctx.info("wrote indirect.md")
