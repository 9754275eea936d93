"""Section 2: tables. Per method (cdf, alias, hierarchical) on a real HDRI: bake time, bytes, the worst relative error
of the density the tables draw from against the ideal importance / total, and a chi-square test of drawn texels.
Then importance-table resolution: envbake --resolution at full, 1/2, 1/4, 1/8 of the map: bake time, bytes, and the
default scene's render relMSE at equal spp and at equal time (envrender reading each table file)."""
import json
import math
import os

import numpy as np

from report.common import (Context, Reference, ToolFailed, commands_block, g, machine_line, md_table, plt, scene_with_image)

ctx = Context("tables")
W, H = ctx.pick((256, 128), (1024, 512), (2048, 1024))
FRACS = ctx.pick([1, 8], [1, 2, 4, 8], [1, 2, 4, 8])
RES = ctx.pick((24, 12), (96, 48), (240, 120))
SPP = ctx.pick(2, 8, 32)
REF_SPP = ctx.pick(16, 256, 1024)
STRATS = ctx.pick([("light hierarchical", ["--strategy", "light", "--light-method", "hierarchical"])],
                  [("light hierarchical", ["--strategy", "light", "--light-method", "hierarchical"]),
                   ("mis-power", ["--strategy", "mis", "--heuristic", "power"])],
                  [("light hierarchical", ["--strategy", "light", "--light-method", "hierarchical"]),
                   ("mis-power", ["--strategy", "mis", "--heuristic", "power"])])
TABLES = "cdf,alias,hierarchical,compensated"
machine = machine_line()

sky = ctx.path("sky.exr")
ctx.run([ctx.tool("envprobe"), "default", "-o", sky, "--size", f"{W}x{H}"])

# ---------------------------------------------------------------- bake (interleaved repeats)
cmds = {f: [ctx.tool("envbake"), sky, "-o", ctx.path(f"t{f}.envtbl"), "--resolution", f"{W // f}x{H // f}",
            "--tables", TABLES, "--json", "--quiet"] for f in FRACS}
bake = {f: {"wall": [], "seconds": []} for f in FRACS}
for _ in range(ctx.repeats):
    for f, c in cmds.items():
        out, _, wall, _ = ctx.run(c)
        d = json.loads(out)
        bake[f]["wall"].append(wall)
        bake[f]["seconds"].append(float(d["seconds"]))
        bake[f]["bytes"] = d["bytes"]
        bake[f]["res"] = (d["width"], d["height"])
for f in FRACS:
    b = bake[f]
    b["seconds_median"] = float(np.median(b["seconds"]))
    b["wall_median"] = float(np.median(b["wall"]))
    b["bytes_total"] = sum(v for k, v in b["bytes"].items())

# ---------------------------------------------------------------- per method
METHODS = ["cdf", "alias", "hierarchical"]
HDRI = "/usr/share/blender/datafiles/studiolights/world/sunrise.exr"
SAMPLES = ctx.pick(100_000, 1_000_000, 4_000_000)


def chi2_p(observed, expected):
    """Pearson chi-square over bins with expected >= 5 (the rest pooled into one bin), and its p-value by the
    Wilson-Hilferty approximation (dof in the thousands here, where it is accurate to ~1e-3)."""
    big = expected >= 5
    obs = np.append(observed[big], observed[~big].sum())
    exp = np.append(expected[big], expected[~big].sum())
    keep = exp > 0
    stat = float(np.sum((obs[keep] - exp[keep]) ** 2 / exp[keep]))
    dof = max(int(keep.sum()) - 1, 1)
    z = ((stat / dof) ** (1 / 3) - (1 - 2 / (9 * dof))) / math.sqrt(2 / (9 * dof))
    return stat, dof, 0.5 * math.erfc(z / math.sqrt(2))


def method_row(method, table_path, seconds):
    import envkit  # built beside the tools (report.sh puts BUILD/python on PYTHONPATH)
    t = envkit.load(table_path)
    imp = np.asarray(t.importance, np.float64)
    grid = envkit.EnvMap.blank(t.height, "latlong")
    omega = np.asarray(grid.solid_angles(), np.float64)
    ideal = imp / t.total_importance  # density per steradian each texel should have
    lit = imp > 0
    dens = np.asarray(t.pdf(np.asarray(grid.directions(), np.float64)[lit], method=method), np.float64)
    worst = float(np.max(np.abs(dens / ideal[lit] - 1.0)))
    u = np.random.default_rng(7).random((SAMPLES, 2))
    _, _, texels = t.sample(u, method=method)
    texels = np.asarray(texels)
    counts = np.bincount(texels[:, 1] * t.width + texels[:, 0], minlength=t.width * t.height).astype(np.float64)
    stat, dof, p = chi2_p(counts, SAMPLES * (ideal * omega).reshape(-1))
    sizes = dict(t.table_bytes)
    return {"bytes": sizes.get(method, 0), "seconds": seconds, "worst_pdf": worst, "chi2": stat, "dof": dof, "p": p}


per_method = {}
if os.path.exists(HDRI):
    cmds = {m: [ctx.tool("envbake"), HDRI, "-o", ctx.path(f"m_{m}.envtbl"), "--tables", m, "--json", "--quiet"]
            + ctx.pick(["--resolution", "256x128"], [], []) for m in METHODS}
    seconds = {m: [] for m in METHODS}
    for _ in range(ctx.repeats):
        for m, c in cmds.items():
            seconds[m].append(float(json.loads(ctx.run(c)[0])["seconds"]))
    for m in METHODS:
        per_method[m] = method_row(m, ctx.path(f"m_{m}.envtbl"), float(np.median(seconds[m])))
    ctx.info("per-method measures done")
else:
    ctx.note(f"{HDRI} is missing (blender's data): no per-method measures")

# ---------------------------------------------------------------- render
renders = {}
problem = None
ref = None
try:
    scenes = {f: scene_with_image(ctx, "default", f"default_t{f}", sky, RES, tables=ctx.path(f"t{f}.envtbl")) for f in FRACS}
    ctx.info("reference")
    full_scene = scene_with_image(ctx, "default", "default_ref", sky, RES)
    ref = Reference(ctx, full_scene, REF_SPP, ["--strategy", "mis", "--heuristic", "power"], "ref")
    for name, opts in STRATS:
        for f in FRACS:  # equal spp
            r = ctx.render(ctx.path(f"r{f}.exr"), scenes[f], ["--spp", SPP, "--seed", 5] + opts, check=False)
            if "failed" in r:
                raise ToolFailed(r["failed"])
            raw, corr = ref.error(r["image"])
            renders[(name, f, "spp")] = {"seconds": r["seconds"], "spp": r["spp"], "relmse": corr,
                                         "mean_ratio": float(r["image"].mean() / ref.image.mean())}
        t_eq = renders[(name, FRACS[0], "spp")]["seconds"]
        for f in FRACS:  # equal time: the full-resolution table's time at SPP
            r = ctx.render(ctx.path(f"q{f}.exr"), scenes[f], ["--time", f"{t_eq:.4f}", "--seed", 9] + opts)
            raw, corr = ref.error(r["image"])
            renders[(name, f, "time")] = {"seconds": r["seconds"], "spp": r["spp"], "relmse": corr,
                                          "mean_ratio": float(r["image"].mean() / ref.image.mean())}
except ToolFailed as e:
    problem = str(e)
    ctx.note(f"rendering with the table files failed: {problem}")

# ---------------------------------------------------------------- plot
p = plt()
fig, axes = p.subplots(1, 2 if renders else 1, figsize=(9 if renders else 4.5, 3.4), squeeze=False)
ax = axes[0][0]
xs = [W // f for f in FRACS]
ax.loglog(xs, [bake[f]["seconds_median"] for f in FRACS], "o-", label="bake time (s)")
ax2 = ax.twinx()
ax2.loglog(xs, [bake[f]["bytes_total"] / 2**20 for f in FRACS], "s--", color="C1", label="table bytes (MiB)")
ax.set_xlabel("importance width (texels)")
ax.set_ylabel("bake time (s)")
ax2.set_ylabel("MiB (all tables)")
ax.set_title(f"envbake {W}x{H} map")
if renders:
    ax = axes[0][1]
    for name, _ in STRATS:
        for kind, ls in (("spp", "o-"), ("time", "s--")):
            ax.loglog(xs, [renders[(name, f, kind)]["relmse"] for f in FRACS], ls,
                      label=f"{name}, equal {'spp' if kind == 'spp' else 'time'}")
    ax.set_xlabel("importance width (texels)")
    ax.set_ylabel("relMSE (default scene)")
    ax.legend(fontsize=7)
import matplotlib.ticker as mticker  # noqa: E402
for a in [x for row in axes for x in row]:
    a.set_xticks(xs)
    a.xaxis.set_major_formatter(mticker.FixedFormatter([str(x) for x in xs]))
    a.xaxis.set_minor_formatter(mticker.NullFormatter())
fig.tight_layout()
fig.savefig(f"{ctx.out}/tables.png")

# ---------------------------------------------------------------- text
rows = []
for f in FRACS:
    b = bake[f]
    row = [f"1/{f}" if f > 1 else "full", f"{b['res'][0]}x{b['res'][1]}", b["seconds_median"], b["wall_median"],
           f"{b['bytes_total'] / 2**20:.2f}"]
    for name, _ in STRATS:
        if renders:
            a, t = renders[(name, f, "spp")], renders[(name, f, "time")]
            row += [a["relmse"], f"{g(t['relmse'])} ({t['spp']} spp)", f"{a['mean_ratio']:.4f}"]
        else:
            row += ["n/a", "n/a", "n/a"]
    rows.append(row)
hdr = ["table", "importance res.", "bake (s, envbake's own)", "envbake wall (s)", "MiB"]
for name, _ in STRATS:
    hdr += [f"{name}: relMSE @ {SPP} spp", f"{name}: relMSE @ equal time", f"{name}: mean / ref mean"]
method_rows = [[m, r["seconds"], f"{r['bytes'] / 2**20:.2f}", r["worst_pdf"], f"{r['chi2']:.0f} / {r['dof']}", r["p"]]
               for m, r in per_method.items()]
text = ["## 2. Tables\n",
        f"### Per method\n\n`envbake {os.path.basename(HDRI)} --tables M` (blender's sunrise HDRI, a real capture with a "
        f"sun) for each method M, envbake's own seconds (median of {ctx.repeats} interleaved run(s)) and the bytes of "
        f"that table. Worst pdf error: max over lit texels of |pdf / (importance / total) - 1|, the density the "
        f"tables draw from (Tables.pdf at the texel's centre) against the ideal. Chi-square: {SAMPLES:,} samples "
        f"(Tables.sample, uniform random u) binned per texel against the ideal probabilities (bins below 5 expected "
        f"pooled); p above 0.01 means the draws match the ideal.\n",
        md_table(["method", "bake (s)", "MiB", "worst pdf error", "chi-square / dof", "p"], method_rows)
        if method_rows else "Not measured in this run (see notes).\n",
        "\n### Importance resolution\n",
        f"`envprobe default` {W}x{H}; `envbake --resolution WxH --tables {TABLES}` at full, 1/2, 1/4, 1/8 of the "
        f"map (median of {ctx.repeats} interleaved run(s); envbake's own `seconds` from `--json` and the wall time "
        f"including file I/O; bytes = all tables in the file). Renders: the built-in default scene "
        f"(`scripts/report/scenes/default.json`, a copy of envrender's) at {RES[0]}x{RES[1]} with the environment "
        f"given as the image plus the baked table file; equal spp = {SPP} spp, equal time = the full-resolution "
        f"table's render time at {SPP} spp (`--time`). Reference: `--strategy mis` at {REF_SPP} spp with the "
        f"full-resolution tables baked in memory. Machine: {machine}.\n",
        md_table(hdr, rows),
        "\n![table resolution](tables.png)\n"]
if problem:
    text.append(f"**The render columns are missing**: envrender cannot load the table files envbake writes. "
                f"envrender's message:\n\n```\n{problem}\n```\n\nThis happens when envbake stamps its tables with a "
                f"hash of the input *file* bytes while envrender checks a hash of the decoded *image* "
                f"(`file_content_hash` in tools/envbake.cpp vs `image_content_hash` in renderer/src/env_light.cpp). "
                f"Once they agree, this section fills in by itself.\n")
elif renders:
    text.append("`mean / ref mean` (image mean over the reference's) is a bias check: a coarser importance table "
                "should only change the noise; a value far from 1 means the smaller table also changed the picture "
                "(e.g. radiance looked up on the coarse grid).\n")
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx))
ctx.write_md("tables.md", "\n".join(text))
ctx.save_summary({"fracs": FRACS, "bake": {str(f): bake[f] for f in FRACS},
                  "renders": {f"{k[0]}|{k[1]}|{k[2]}": v for k, v in renders.items()}, "problem": problem,
                  "spp": SPP, "strategies": [s[0] for s in STRATS], "map": [W, H], "per_method": per_method})
ctx.info("wrote tables.md")
