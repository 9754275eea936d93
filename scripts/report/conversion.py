"""Section 1: conversion. envconvert lat-long -> cube for every filter and output size: wall time vs error against
the analytic probe rasterized exactly at the output size by envprobe, measured as a renderer sees it (power, GGX-
prefiltered levels, irradiance: report/seen.py) beside the per-texel relMSE; power error for a sub-texel sun;
envconvert vs exrenvmap through scripts/bench/bench_exrenvmap.sh."""
import json
import os

from report.common import Context, commands_block, g, machine_line, md_table, plt
from report.seen import seen_columns, seen_errors

ctx = Context("conversion")
N = ctx.pick(128, 1024, 2048)  # source lat-long 2N x N
FACES = ctx.pick([32], [64, 128, 256], [128, 256, 512])
FILTERS = ctx.pick(["bilinear", "area"], ["nearest", "bilinear", "bicubic", "area"],
                   ["nearest", "bilinear", "bicubic", "area"])
SUN_FACE = FACES[len(FACES) // 2]
SUN_N = ctx.pick(128, 1024, 2048)
SUN_RADIUS = 0.05  # degrees: below one source texel (180/N degrees) for every N used here
machine = machine_line()

src = ctx.path("src.exr")
ctx.run([ctx.tool("envprobe"), "default", "-o", src, "--size", f"{2 * N}x{N}"])
for F in FACES:
    ctx.run([ctx.tool("envprobe"), "default", "--param", "cube", "--size", F, "-o", ctx.path(f"ref_{F}.exr")])


SEEN = seen_columns()
SEEN_SIZE = ctx.pick(32, 128, 128)  # level 0 of the prefiltered chains that measure what a surface sees


def diff(ref, out):
    d = json.loads(ctx.run([ctx.tool("envdiff"), ref, out, "--json"])[0])
    result = {"rmse": d["rmse"], "relmse": d["relmse"], "max": d["max_abs_error"]["value"],
              "power": d["power_max_relative_difference"]}
    result["seen"] = seen_errors(out, ref, SEEN_SIZE)
    result["seen_worst"] = max(result["seen"][k] for k in SEEN if k.startswith("ggx") or k == "irradiance")
    return result


cmds = {(F, f): [ctx.tool("envconvert"), src, "-o", ctx.path(f"cube_{F}_{f}.exr"), "--to", "cube", "--size", F,
                 "--filter", f, "--quiet"] for F in FACES for f in FILTERS}
ctx.info(f"{len(cmds)} conversions x {ctx.repeats} repeat(s)")
times = ctx.timed_interleaved(cmds)
conv = {}
for (F, f), (t, runs) in times.items():
    conv[(F, f)] = dict(diff(ctx.path(f"ref_{F}.exr"), ctx.path(f"cube_{F}_{f}.exr")), time=t, runs=runs)

# ---------------------------------------------------------------- smooth map (no sun): reconstruction quality
# relMSE of the sunny probe is dominated by where the sun's energy lands (a sun spilled into a dark neighbour texel
# costs far more relMSE than a sun lost altogether), so filters are also compared on the sun-less overcast sky.
osrc = ctx.path("overcast.exr")
ctx.run([ctx.tool("envprobe"), "default", "-o", osrc, "--size", f"{2 * N}x{N}", "--cloud-cover", "1", "--radiance", "0"])
smooth = {}
for F in (FACES if ctx.mode != "smoke" else []):
    oref = ctx.path(f"oref_{F}.exr")
    ctx.run([ctx.tool("envprobe"), "default", "--param", "cube", "--size", F, "-o", oref, "--cloud-cover", "1",
             "--radiance", "0"])
    for f in FILTERS:
        o = ctx.path(f"ocube_{F}_{f}.exr")
        ctx.run([ctx.tool("envconvert"), osrc, "-o", o, "--to", "cube", "--size", F, "--filter", f, "--quiet"])
        smooth[(F, f)] = diff(oref, o)

# ---------------------------------------------------------------- sub-texel sun
sun = ctx.path("sun.exr")
sun_opts = ["--radiance", "1e6", "--sky", "1e-3", "--radius-deg", SUN_RADIUS]
ctx.run([ctx.tool("envprobe"), "sun", "-o", sun, "--size", f"{2 * SUN_N}x{SUN_N}"] + sun_opts)
sun_ref = ctx.path("sun_ref.exr")
ctx.run([ctx.tool("envprobe"), "sun", "-o", sun_ref, "--param", "cube", "--size", SUN_FACE] + sun_opts)
sun_res = {}
for f in FILTERS:
    o = ctx.path(f"sun_{f}.exr")
    ctx.run([ctx.tool("envconvert"), sun, "-o", o, "--to", "cube", "--size", SUN_FACE, "--filter", f, "--quiet"])
    sun_res[f] = diff(sun_ref, o)

# ---------------------------------------------------------------- envconvert vs exrenvmap
bench = None
bench_md = os.path.join(ctx.out, "bench_exrenvmap.md")
if ctx.mode == "smoke":
    ctx.note("smoke mode: scripts/bench/bench_exrenvmap.sh is not run (its smallest case takes longer than the smoke budget)")
else:
    args = [os.path.join(ctx.root, "scripts", "bench", "bench_exrenvmap.sh"), "--workdir", ctx.path("exrenvmap"),
            "--out", bench_md]
    if ctx.mode == "quick":
        args.append("--quick")
    else:
        args += ["--repeats", str(ctx.repeats)]
    env = dict(os.environ, ENVKIT_BIN=ctx.bin)
    ctx.info("scripts/bench/bench_exrenvmap.sh")
    out, err, wall, rc = ctx.run(args, check=False, env=env)
    if rc == 0 and os.path.exists(bench_md):
        bench = open(bench_md).read()
    else:
        ctx.note(f"scripts/bench/bench_exrenvmap.sh failed (exit {rc}): {err.strip()[-300:]}")

# ---------------------------------------------------------------- plots
p = plt()
fig, axes = p.subplots(1, 2, figsize=(10, 3.8))
ax = axes[0]
for i, f in enumerate(FILTERS):
    xs = [conv[(F, f)]["time"] for F in FACES]
    ys = [max(conv[(F, f)]["seen_worst"], 1e-12) for F in FACES]
    ax.loglog(xs, ys, "o-", label=f, color=f"C{i}")
    for F, x, y in zip(FACES, xs, ys):
        ax.annotate(str(F), (x, y), fontsize=6, xytext=(2, 2), textcoords="offset points")
ax.set_xlabel("envconvert wall time (s)")
ax.set_ylabel("worst GGX / irradiance rel. RMS error")
ax.set_title(f"lat-long {2 * N}x{N} -> cube (face size labelled)")
ax.legend(fontsize=7)
ax = axes[1]
vals = [max(sun_res[f]["power"], 1e-12) for f in FILTERS]
ax.bar(FILTERS, vals, color=[f"C{i}" for i in range(len(FILTERS))])
ax.set_yscale("log")
ax.set_ylabel("max relative power error")
ax.set_title(f"sub-texel sun ({SUN_RADIUS} deg, 1e6 over 1e-3) -> cube {SUN_FACE}")
fig.tight_layout()
fig.savefig(f"{ctx.out}/conversion.png")

# ---------------------------------------------------------------- text
rows = []
texel_rows = []
for F in FACES:
    for f in FILTERS:
        c = conv[(F, f)]
        rows.append([f"{F}", f, c["time"]] + [c["seen"][k] for k in SEEN] +
                    [smooth.get((F, f), {}).get("seen_worst", "-")])
        texel_rows.append([f"{F}", f, c["rmse"], c["relmse"], c["max"],
                           smooth.get((F, f), {}).get("relmse", "-")])
sun_rows = [[f] + [sun_res[f]["seen"][k] for k in SEEN] + [sun_res[f]["relmse"], sun_res[f]["max"]] for f in FILTERS]
text = ["## 1. Conversion\n",
        f"Source: `envprobe default` lat-long {2 * N}x{N} (envkit convention, float EXR). Each output: "
        f"`envconvert --to cube --size F --filter X`, wall time including EXR I/O, median of {ctx.repeats} "
        f"interleaved run(s). Reference: the analytic probe rasterized directly at the output size "
        f"(`envprobe default --param cube --size F`: flux-exact texel averages, far more accurate than supersampling "
        f"a converted image). Errors as a renderer sees them (scripts/report/seen.py): `power`, the relative "
        f"difference of total power (worst channel); `ggx A`, the relative RMS of the GGX-prefiltered level of alpha A "
        f"(envkit.prefilter of output and reference, glTF mapping: what a glossy surface of that roughness sees); "
        f"`irradiance`, the relative RMS of the irradiance map (what a diffuse surface sees). `overcast worst` is the "
        f"worst GGX/irradiance error on the sun-less sky (below). Machine: {machine}.\n",
        "![conversion](conversion.png)\n",
        md_table(["face size", "filter", "time (s)"] + SEEN + ["overcast worst"], rows,
                 ["---:", "---", "---:"] + ["---:"] * (len(SEEN) + 1)),
        "\n**Per-texel errors** (`envdiff REF OUT --json`, solid-angle weighted; relMSE = mean((I-R)^2/(R^2+0.01))), "
        "kept for comparison with other tools' reports, with a caveat: they are dominated by the sun. Energy that "
        "the source's own resolution spread into a sky texel next to the sun costs (I - R)^2 / R^2 with R ~ 1, up "
        "to ~1e5 per texel, while a sun lost altogether costs at most 1 per sun texel: relMSE ranks a filter that "
        "loses the sun above one that keeps it. Do not choose a filter by this table; it ranks nothing (no column "
        "compares the filters).\n",
        md_table(["face size", "filter", "RMSE", "relMSE", "max abs err", "overcast relMSE"],
                 texel_rows, ["---:", "---", "---:", "---:", "---:", "---:"]),
        f"\n### Sub-texel sun\n\n`envprobe sun --radiance 1e6 --sky 1e-3 --radius-deg {SUN_RADIUS}` at "
        f"{2 * SUN_N}x{SUN_N} (one texel spans {180 / SUN_N:.3f} deg, the sun's diameter {2 * SUN_RADIUS} deg) converted "
        f"to cube {SUN_FACE}; reference: the same probe rasterized into the cube.\n",
        md_table(["filter"] + SEEN + ["relMSE", "max abs err"], sun_rows),
        "\n### envconvert vs exrenvmap\n"]
if bench:
    body = bench.split("\n", 1)[1] if bench.startswith("## ") else bench
    text.append(f"From `scripts/bench/bench_exrenvmap.sh{' --quick' if ctx.mode == 'quick' else ''}` (run by the report; "
                f"table also in [bench_exrenvmap.md](bench_exrenvmap.md)):\n")
    text.append(body.replace("### ", "#### "))
else:
    text.append("Not measured in this run (see notes).\n")
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx))
ctx.write_md("conversion.md", "\n".join(text))
ctx.save_summary({"faces": FACES, "filters": FILTERS, "conv": {f"{k[0]}|{k[1]}": v for k, v in conv.items()},
                  "smooth": {f"{k[0]}|{k[1]}": v for k, v in smooth.items()},
                  "sun": sun_res, "sun_face": SUN_FACE, "source": [2 * N, N], "bench_exrenvmap": bench is not None})
ctx.info("wrote conversion.md")
