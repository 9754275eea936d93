"""Section 7: prefiltering. Every level of GGX chains from 8^2 to 256^2 against the brute-force sum, per accuracy
setting (build/bin/prefilter_accuracy: a smooth sky, a textured one, one with a 1e4 sun and a blender-data HDRI),
and envprefilter's wall time per output size on a real HDRI. cmft, the peer users would otherwise run, is not
packaged in Debian 12 (BENCHMARKS.md), so there is no peer ratio here."""
import os
import re
import statistics

from report.common import Context, commands_block, g, machine_line, md_table, plt

ctx = Context("prefilter")
SIZES = ctx.pick([8], [8, 16, 32, 64], [8, 16, 32, 64, 128, 256])
ACCURACIES = ctx.pick([0.2], [0.4, 0.2, 0.1], [0.4, 0.2, 0.1, 0.05])
OUT_SIZES = ctx.pick([16], [64, 128, 256], [128, 256, 512])
SOURCE = ctx.pick("256x128", "2048x1024", "4096x2048")
HDRI = "/usr/share/blender/datafiles/studiolights/world/courtyard.exr"
TARGET = 0.005  # relative RMS per level that the default accuracy is meant to keep (docs/PREFILTER.md)
DEFAULT_ACCURACY = 0.2
machine = machine_line()
LINE = re.compile(r"^\s*(\d+)\^2 accuracy ([0-9.]+) (\S+)\s+source\s+(\d+)\s+([0-9.]+) ms CPU:(.*)$")

# ---------------------------------------------------------------- accuracy per level (prefilter_accuracy)
acc = {}  # "size|accuracy" -> {"worst": max level error over maps, "ms": mean CPU ms, "levels": worst per level}
if not ctx.has_tool("prefilter_accuracy"):
    ctx.note("prefilter_accuracy is not built (tests/bench): no accuracy table in this run")
else:
    cmd = [ctx.tool("prefilter_accuracy"), "--sizes", ",".join(map(str, SIZES)),
           "--accuracies", ",".join(map(str, ACCURACIES))] + ([HDRI] if os.path.exists(HDRI) else [])
    ctx.info("prefilter_accuracy " + " ".join(cmd[1:]))
    out = ctx.run(cmd)[0]
    for line in out.splitlines():
        m = LINE.match(line)
        if not m:
            continue
        key = f"{int(m.group(1))}|{float(m.group(2)):g}"
        levels = [float(x.rstrip("%")) / 100.0 for x in m.group(6).split()]
        a = acc.setdefault(key, {"worst": 0.0, "ms": [], "levels": [0.0] * len(levels), "maps": []})
        a["worst"] = max([a["worst"]] + levels)
        a["ms"].append(float(m.group(5)))
        a["levels"] = [max(x, y) for x, y in zip(a["levels"], levels)]
        a["maps"].append(m.group(3))
    for a in acc.values():
        a["ms"] = statistics.mean(a["ms"])

# ---------------------------------------------------------------- envprefilter wall time on a real map
src = ctx.path("src.exr")
ctx.run([ctx.tool("envprobe"), "default", "-o", src, "--size", SOURCE])
cmds = {n: [ctx.tool("envprefilter"), src, "-o", ctx.path(f"chain_{n}.ktx2"), "--size", n, "--quiet"]
        for n in OUT_SIZES}
if ctx.has_tool("envinfo"):
    cmds["floor"] = [ctx.tool("envinfo"), src, "--json"]
ctx.info(f"envprefilter: {len(OUT_SIZES)} sizes x {ctx.repeats} repeat(s), interleaved with the floor")
times = {n: t for n, (t, _) in ctx.timed_interleaved(cmds).items()}
floor = times.pop("floor", None)

# ---------------------------------------------------------------- plot
p = plt()
fig, ax = p.subplots(figsize=(6, 3.8))
for i, a_set in enumerate(ACCURACIES):
    xs = [s for s in SIZES if f"{s}|{a_set:g}" in acc]
    ax.semilogy(xs, [max(acc[f"{s}|{a_set:g}"]["worst"], 1e-6) for s in xs], "o-", color=f"C{i}",
                label=f"accuracy {a_set:g}" + (" (default)" if a_set == DEFAULT_ACCURACY else ""))
ax.axhline(TARGET, color="k", lw=0.6, ls="--")
ax.set_xscale("log", base=2)
ax.set_xlabel("chain size (level 0 face)")
ax.set_ylabel("worst level: rel. RMS vs brute force")
ax.legend(fontsize=7)
fig.tight_layout()
fig.savefig(f"{ctx.out}/prefilter.png")

# ---------------------------------------------------------------- text
rows = [[f"{s}^2", f"{a_set:g}", f"{100 * acc[f'{s}|{a_set:g}']['worst']:.2f}%", acc[f"{s}|{a_set:g}"]["ms"],
         " ".join(f"{100 * x:.2f}%" for x in acc[f"{s}|{a_set:g}"]["levels"])]
        for s in SIZES for a_set in ACCURACIES if f"{s}|{a_set:g}" in acc]
maps = sorted({m for a in acc.values() for m in a["maps"]})
text = ["## 7. Prefiltering\n",
        f"Accuracy: `prefilter_accuracy` (tests/bench) prefilters {', '.join(maps) or 'no maps'} "
        f"(256x128 lat-long each; `hdri` is {os.path.basename(HDRI)} area-resampled) into GGX chains of each size "
        f"(glTF mapping, cube) and compares every level >= 1 with the brute-force sum over every source texel "
        f"(`GgxReference`, exact solid angles). Relative RMS, worst colour channel; the table gives the worst map per "
        f"level and overall, and the mean CPU time of a chain (all threads). Machine: {machine}.\n",
        "![prefilter](prefilter.png)\n",
        md_table(["chain", "accuracy", "worst level", "CPU ms", "levels 1..n (worst map)"], rows,
                 ["---:", "---:", "---:", "---:", "---"]),
        f"\n### envprefilter wall time\n\n`envprefilter SRC -o chain.ktx2 --size N` on `envprobe default` {SOURCE} "
        f"(float EXR), median of {ctx.repeats} interleaved run(s); the floor is `envinfo SRC --json` (reading the map and its statistics, "
        f"no more).\n",
        md_table(["size", "wall (s)", "x floor"],
                 [[n, times[n], f"{times[n] / floor:.1f}x" if floor else "-"] for n in OUT_SIZES]),
        "\nNo peer ratio: cmft is not packaged in Debian 12, and glTF-IBL-Sampler needs a GPU (Vulkan).\n"]
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx))
ctx.write_md("prefilter.md", "\n".join(text))
ctx.save_summary({"sizes": SIZES, "accuracies": ACCURACIES, "acc": acc, "target": TARGET,
                  "default_accuracy": DEFAULT_ACCURACY, "times": {str(k): v for k, v in times.items()},
                  "floor": floor, "source": SOURCE})
ctx.info("wrote prefilter.md")
