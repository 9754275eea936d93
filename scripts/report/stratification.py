"""Section 4: stratification. envrender has no switch for its sample sequence, so this is measured with envsample:
irradiance estimates E(n) = (1/N) sum L(w) max(0, n.w) / pdf(w) at a few normals n from N = 1..64 samples drawn by
each table (cdf, alias, hierarchical) with random and Owen-scrambled Sobol sequences; relMSE over many trials."""
import json

import numpy as np

from report.common import Context, commands_block, g, geomean, machine_line, md_table, plt

ctx = Context("stratification")
W, H = ctx.pick((256, 128), (1024, 512), (1024, 512))
SEEDS = ctx.pick(1, 4, 16)
BLOCKS = ctx.pick(16, 64, 128)  # consecutive 64-sample blocks per seed
NS = [1, 2, 4, 8, 16, 32, 64]
NMAX = 64
REF_N = ctx.pick(1 << 14, 1 << 18, 1 << 20)
METHODS = ["cdf", "alias", "hierarchical"]
SEQS = ["random", "sobol"]
PROBES = ctx.pick(["sunny"], ["sunny", "overcast"], ["sunny", "overcast"])
el, az = np.radians(35.0), np.radians(40.0)
NORMALS = {"up (+Y)": (0.0, 1.0, 0.0),
           "towards the sun": (np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)),
           "horizontal (+X)": (1.0, 0.0, 0.0),
           "down (-Y)": (0.0, -1.0, 0.0)}
machine = machine_line()


def load_csv(path):
    a = np.loadtxt(path, delimiter=",", skiprows=1, usecols=(2, 3, 4, 5), dtype=np.float64, ndmin=2)
    return a[:, :3], a[:, 3]


res = {}   # probe -> (method, seq) -> normal -> {N: relmse}
refs = {}
for probe in PROBES:
    sky = ctx.path(f"sky_{probe}.exr")
    extra = [] if probe == "sunny" else ["--cloud-cover", "1", "--radiance", "0"]
    ctx.run([ctx.tool("envprobe"), "default", "-o", sky, "--size", f"{W}x{H}"] + extra)
    tbl = ctx.path(f"{probe}.envtbl")
    d = json.loads(ctx.run([ctx.tool("envbake"), sky, "-o", tbl, "--tables", "cdf,alias,hierarchical", "--json", "--quiet"])[0])
    total = float(d["total_importance"])
    # With luminance importance, pdf(w) = L(w) / total for the table's piecewise-constant L, so each sample's
    # L cos / pdf = total * max(0, n.w): the integrand is the map's luminance (at table resolution) times the cosine.
    ref_csv = ctx.path("ref.csv")
    ctx.run([ctx.tool("envsample"), tbl, "-n", REF_N, "--method", "cdf", "--sequence", "sobol", "--seed", 999,
             "-o", ref_csv, "--quiet"])
    dirs, _ = load_csv(ref_csv)
    refs[probe] = {k: total * float(np.mean(np.maximum(dirs @ np.array(n), 0.0))) for k, n in NORMALS.items()}
    res[probe] = {}
    for m in METHODS:
        for s in SEQS:
            sq = {k: {N: [] for N in NS} for k in NORMALS}
            for seed in range(SEEDS):
                csv = ctx.path("s.csv")
                ctx.run([ctx.tool("envsample"), tbl, "-n", NMAX * BLOCKS, "--method", m, "--sequence", s,
                         "--seed", seed, "-o", csv, "--quiet"])
                dirs, pdf = load_csv(csv)
                for k, n in NORMALS.items():
                    f = total * np.maximum(dirs @ np.array(n), 0.0)
                    f = f.reshape(BLOCKS, NMAX)  # each block starts at a multiple of 64: a (0,6,2)-net for Sobol
                    E = refs[probe][k]
                    for N in NS:
                        est = f[:, :N].mean(axis=1)
                        sq[k][N].extend(((est - E) ** 2 / (E * E + 1e-2)).tolist())
            res[probe][(m, s)] = {k: {N: float(np.mean(v)) for N, v in d2.items()} for k, d2 in sq.items()}
    ctx.info(f"{probe} done")

# ---------------------------------------------------------------- plot
p = plt()
fig, axes = p.subplots(len(PROBES), len(NORMALS), figsize=(3.2 * len(NORMALS), 3.0 * len(PROBES)), squeeze=False)
for i, probe in enumerate(PROBES):
    for j, k in enumerate(NORMALS):
        ax = axes[i][j]
        for a, m in enumerate(METHODS):
            for s in SEQS:
                ys = [max(res[probe][(m, s)][k][N], 1e-16) for N in NS]
                ax.loglog(NS, ys, "-" if s == "sobol" else ":", marker="o", ms=3, color=f"C{a}", label=f"{m} {s}")
        ax.loglog(NS, [res[probe][("cdf", "random")][k][1] / N for N in NS], color="0.6", lw=0.8, label="1/N")
        ax.set_title(f"{probe}, n {k}", fontsize=8)
        ax.set_xlabel("samples N")
        if j == 0:
            ax.set_ylabel("relMSE of E(n)")
axes[0][-1].legend(fontsize=6)
fig.tight_layout()
fig.savefig(f"{ctx.out}/stratification.png")

# ---------------------------------------------------------------- tables
text = ["## 4. Stratification\n",
        "envrender has no switch for its sample sequence (it always uses its own low-discrepancy sampler), so this "
        "section measures the tables directly with `envsample` (`--sequence random|sobol`): irradiance "
        "E(n) = integral of L max(0, n.w) dw estimated as (1/N) sum L cos / pdf from N samples of each table. L is the "
        "luminance the tables were baked from (`envbake`, luminance importance, so L/pdf = total importance). "
        f"Trials: {SEEDS} seed(s) x {BLOCKS} consecutive 64-sample blocks (each block of an Owen-scrambled Sobol "
        f"sequence starting at a multiple of 64 is itself a stratified (0,6,2)-net; its first N points a (0,log2 N,2)-net). "
        f"Reference E(n): {REF_N} Sobol cdf samples (seed 999). Probes: `envprobe default` {W}x{H} (sunny) and the same with "
        f"`--cloud-cover 1 --radiance 0` (overcast). relMSE = mean((E_N - E)^2/(E^2 + 0.01)). Machine: {machine}.\n",
        "![stratification](stratification.png)\n"]
summary = {}
for probe in PROBES:
    text.append(f"### {probe}: relMSE, geometric mean over the {len(NORMALS)} normals\n")
    rows = []
    for m in METHODS:
        for s in SEQS:
            avg = {N: geomean([res[probe][(m, s)][k][N] for k in NORMALS]) for N in NS}
            summary[f"{probe}|{m}|{s}"] = avg
            rows.append([f"{m}", s] + [avg[N] for N in NS])
    gain = []
    for m in METHODS:
        r = summary[f"{probe}|{m}|random"][64] / max(summary[f"{probe}|{m}|sobol"][64], 1e-300)
        gain.append(f"{m} {r:.2g}x")
    text.append(md_table(["table", "sequence"] + [f"N={N}" for N in NS], rows, ["---", "---"] + ["---:"] * len(NS)))
    text.append(f"\nrelMSE random / Sobol at N = 64: {', '.join(gain)}.\n")
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx, limit=12))
ctx.write_md("stratification.md", "\n".join(text))
ctx.save_summary({"ns": NS, "avg": summary, "probes": PROBES, "refs": refs,
                  "per_normal": {f"{p}|{m}|{s}": v for p, d in res.items() for (m, s), v in d.items()}})
ctx.info("wrote stratification.md")
