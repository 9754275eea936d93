"""Section 5: precision. Runs bench_precision (tests/bench/bench_precision.cpp: float vs double accumulation of the
sampling tables and chi-square p-values against the map size) and turns its tab-separated output into a table and
a plot."""
import csv
import io

from report.common import Context, commands_block, g, machine_line, md_table, plt

ctx = Context("precision")
SIZES = ctx.pick("1024", "1024,2048,4096", "1024,2048,4096,8192,16384")
SAMPLES = ctx.pick(100000, 300000, 1000000)
machine = machine_line()
text = ["## 5. Precision\n"]
rows = []
if not ctx.has_tool("bench_precision"):
    ctx.note(f"{ctx.tool('bench_precision')} does not exist (tests/bench/bench_precision.cpp not built): "
             "not measured")
    text.append("**Not measured**: `bench_precision` is not built in this build directory.\n")
else:
    out, err, wall, rc = ctx.run([ctx.tool("bench_precision"), "--sizes", SIZES, "--samples", SAMPLES,
                                  "--cells", "64x32"], check=False)
    if rc != 0:
        text.append(f"**bench_precision failed** (exit {rc}): `{err.strip()[-300:]}`\n")
    else:
        comments = [l[1:].strip() for l in out.splitlines() if l.startswith("#")]
        rows = list(csv.DictReader(io.StringIO("\n".join(l for l in out.splitlines() if l and not l.startswith("#"))),
                                   delimiter="\t"))
        methods = list(dict.fromkeys(r["method"] for r in rows))
        p = plt()
        fig, axes = p.subplots(1, 3, figsize=(12, 3.4))
        for i, m in enumerate(methods):
            rs = [r for r in rows if r["method"] == m]
            ws = [int(r["width"]) for r in rs]
            axes[0].loglog(ws, [max(float(r["max_rel_err"]), 1e-18) for r in rs], "o-", label=m, color=f"C{i}")
            axes[1].semilogx(ws, [int(r["unreachable"]) / int(r["lit_texels"]) for r in rs], "o-", label=m,
                             color=f"C{i}")
            axes[2].semilogx(ws, [float(r["chi2_p"]) for r in rs], "o-", label=m, color=f"C{i}")
        axes[0].set_ylabel("max relative error of texel probability")
        axes[1].set_ylabel("unreachable lit texels (fraction)")
        axes[2].set_ylabel("chi-square p-value")
        axes[2].axhline(0.01, color="k", lw=0.7, ls=":")
        for ax in axes:
            ax.set_xlabel("map width (lat-long W x W/2)")
            ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(f"{ctx.out}/precision.png")
        text.append("`bench_precision --sizes {} --samples {} --cells 64x32` (tests/bench/bench_precision.cpp): "
                    .format(SIZES, SAMPLES) + "; ".join(comments) + ". float-naive = textbook marginal/conditional "
                    "CDF with running float sums; cdf = envkit's CdfDistribution2D (double accumulation, float "
                    "storage); hierarchical = envkit's HierarchicalDistribution2D. Errors are of the probabilities the tables "
                    "draw, relative to the exact w / sum. Machine: " + machine + ".\n")
        text.append("![precision](precision.png)\n")
        text.append(md_table(["map", "method", "max rel err", "mean rel err", "unreachable / lit", "lost mass",
                              "TV distance", "chi2 p (dof)", "build (s)"],
                             [[f"{r['width']}x{r['height']}", r["method"], float(r["max_rel_err"]),
                               float(r["mean_rel_err"]), f"{r['unreachable']} / {r['lit_texels']}",
                               float(r["lost_mass"]), float(r["tv_distance"]), f"{g(float(r['chi2_p']))} ({r['chi2_dof']})",
                               float(r["build_s"])] for r in rows],
                             ["---", "---"] + ["---:"] * 7))
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx))
ctx.write_md("precision.md", "\n".join(text))
ctx.save_summary({"rows": rows, "sizes": SIZES})
ctx.info("wrote precision.md")
