"""Section 3: sampling strategies. relMSE vs render time (log-log) for every strategy of envrender on a diffuse, a
glossy (roughness 0.1) and a near-mirror (0.01) sphere under a sunny and an overcast probe; efficiency
1/(relMSE x time) and its ratio to power-heuristic MIS at envrender's default sample counts."""
import math
import sys

from report.common import (DEFAULT_STRATEGY, Context, Reference, ToolFailed, commands_block, g, geomean, machine_line,
                           make_probe_images, md_table, plt, scene_with_image)

ctx = Context("strategies")
MODE = ctx.mode

BASE = "mis-power"  # power MIS at envrender's default sample counts (by the material's lobe)
ALL_CONFIGS = [
    ("bsdf", ["--strategy", "bsdf"]),
    ("light cdf", ["--strategy", "light", "--light-method", "cdf"]),
    ("light alias", ["--strategy", "light", "--light-method", "alias"]),
    ("light hierarchical", ["--strategy", "light", "--light-method", "hierarchical"]),
    ("mis-balance", ["--strategy", "mis", "--heuristic", "balance"]),
    (BASE, ["--strategy", "mis", "--heuristic", "power"]),
    ("mis-power 1+1", ["--strategy", "mis", "--heuristic", "power", "--bsdf-samples", "1", "--light-samples", "1"]),
    ("mis-power 1+3", ["--strategy", "mis", "--heuristic", "power", "--bsdf-samples", "1", "--light-samples", "3"]),
    ("mis-power 3+1", ["--strategy", "mis", "--heuristic", "power", "--bsdf-samples", "3", "--light-samples", "1"]),
    ("mis-power 2+2", ["--strategy", "mis", "--heuristic", "power", "--bsdf-samples", "2", "--light-samples", "2"]),
    ("mis-power whole map", ["--strategy", "mis", "--heuristic", "power", "--sun-samples", "0"]),
    ("mis-compensated", ["--strategy", "mis-compensated", "--heuristic", "power"]),
    ("product", ["--strategy", "product"]),
    ("product-mis", ["--strategy", "product-mis"]),
    ("auto", ["--strategy", "auto"]),
    # The samplers of the literature the seed cites (renderer's integrator.h), alone and with MIS.
    ("product-wavelet", ["--strategy", "product-wavelet"]),
    ("product-wavelet-mis", ["--strategy", "product-wavelet-mis"]),
    ("product-steerable", ["--strategy", "product-steerable"]),
    ("product-steerable-mis", ["--strategy", "product-steerable-mis"]),
    ("product-sh", ["--strategy", "product-sh"]),
    ("product-sh-mis", ["--strategy", "product-sh-mis"]),
]
SEED = ["product-wavelet", "product-wavelet-mis", "product-steerable", "product-steerable-mis", "product-sh",
        "product-sh-mis"]
QUICK_SKIP = {"mis-power 3+1", "mis-power 2+2", "product-wavelet", "product-steerable", "product-sh"}
SMOKE_KEEP = {"bsdf", "light hierarchical", BASE, "product-mis", DEFAULT_STRATEGY}
CONFIGS = [c for c in ALL_CONFIGS if MODE == "full" or (MODE == "quick" and c[0] not in QUICK_SKIP)
           or (MODE == "smoke" and c[0] in SMOKE_KEEP)]

RES = ctx.pick(8, 48, 64)
LEVELS = ctx.pick([1], [1, 8], [1, 4, 16, 64, 256])
# The reference's own noise must stay well below what the best strategy reaches at the top of the ladder, or that
# level drops out as unreliable and the best strategy is judged where fixed costs dominate. Rendered with the default
# strategy (less noise per sample than power MIS on most scenes, about the same on the rest) at half the samples that
# power MIS references took, which were most of the section's time; `reliable` below still drops a level whose error
# the reference's noise could blur.
REF_SPP = ctx.pick(16, 1024, 4096)
REF_OPTIONS = ["--strategy", DEFAULT_STRATEGY]
RELIABLE = 3.0  # a level counts when its raw relMSE is at least this many times the reference's own noise
CAP = ctx.pick(2.0, 3.0, 10.0)  # seconds: do not climb to a level predicted (linearly in spp) to take longer
MATERIALS = ctx.pick(["glossy"], ["diffuse", "glossy", "mirror"], ["diffuse", "glossy", "mirror"])
PROBES = ctx.pick(["sunny"], ["sunny", "overcast", "sunrise"], ["sunny", "overcast", "sunrise", "courtyard"])
MAT_LABEL = {"diffuse": "diffuse", "glossy": "glossy (roughness 0.1)", "mirror": "near-mirror (roughness 0.01)"}

ctx.info(f"{len(CONFIGS)} strategies, {len(MATERIALS) * len(PROBES)} scenes, {RES}x{RES} px, spp ladder {LEVELS}, "
         f"reference {REF_SPP} spp")
machine = machine_line()
SKY_SIZE = ctx.pick("256x128", "1024x512", "1024x512")
skies = make_probe_images(ctx, PROBES, SKY_SIZE)
PROBES = [p for p in PROBES if p in skies]

results = {}  # scene -> config -> list of dict(spp, seconds, relmse, relmse_raw)
refs = {}
failures = {}
for probe in PROBES:
    for mat in MATERIALS:
        key = f"{mat}/{probe}"
        template = f"sphere_{mat}_{probe if probe in ('sunny', 'overcast') else 'sunny'}"
        scene = scene_with_image(ctx, template, f"{mat}_{probe}", skies[probe], (RES, RES))
        ctx.info(f"{key}: reference")
        ref = Reference(ctx, scene, REF_SPP, REF_OPTIONS, f"ref_{mat}_{probe}")
        refs[key] = ref
        results[key] = {c[0]: [] for c in CONFIGS}
        active = {c[0] for c in CONFIGS}
        for spp in LEVELS:  # levels outside, strategies inside: load from other users hits all strategies alike
            for name, opts in CONFIGS:
                if name not in active:
                    continue
                r = ctx.render(ctx.path(f"r_{mat}_{probe}.exr"), scene,
                               ["--spp", spp, "--seed", 17 + spp, "--bake"] + opts, check=False)
                if "failed" in r:
                    failures[name] = r["failed"]
                    active.discard(name)
                    ctx.note(f"{name} failed on {key}: {r['failed']}")
                    continue
                raw, corr = ref.error(r["image"])
                results[key][name].append({"spp": r["spp"], "seconds": r["seconds"], "relmse": corr, "relmse_raw": raw,
                                           "reliable": raw >= RELIABLE * ref.noise, "nonfinite": r["nonfinite"]})
                nxt = LEVELS[LEVELS.index(spp) + 1] if spp != LEVELS[-1] else None
                if nxt and r["seconds"] * nxt / spp > CAP:
                    active.discard(name)
        ctx.info(f"{key}: done")


def reliable(points):
    """The levels whose error stands clear of the reference's own noise (raw relMSE >= RELIABLE x that noise): below
    it the noise-corrected relMSE is a small difference of two noisy numbers. At least the first level."""
    return [p for p in points if p["reliable"]] or points[:1]


def efficiency(points):
    """Geometric mean of 1/(relMSE x seconds) over the reliable ladder levels >= 4 spp (all reliable levels when
    none reached 4)."""
    points = reliable(points)
    pts = [p for p in points if p["spp"] >= 4] or points
    effs = [1.0 / (p["relmse"] * p["seconds"]) for p in pts if p["relmse"] > 0 and p["seconds"] > 0]
    return geomean(effs) if effs else float("nan")


eff = {k: {c: efficiency(v) for c, v in d.items() if v} for k, d in results.items()}
ratios = {k: {c: e / d[BASE] for c, e in d.items()} for k, d in eff.items() if BASE in d}

# ---------------------------------------------------------------- plot
p = plt()
keys = list(results)
ncol = len(MATERIALS)
nrow = len(PROBES)
fig, axes = p.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.6 * nrow), squeeze=False)
cmap = p.get_cmap("tab20")
for i, key in enumerate(keys):
    ax = axes[i // ncol][i % ncol]
    for j, (name, _) in enumerate(CONFIGS):
        pts = results[key].get(name) or []
        pts = [q for q in pts if q["relmse"] > 0]
        if not pts:
            continue
        ls = "-" if not name.startswith(("product", "mis-comp")) else "--"
        ax.loglog([q["seconds"] for q in pts], [q["relmse"] for q in pts], ls, marker="o", ms=3, color=cmap(j % 20),
                  label=name, lw=2.2 if name == BASE else 1.1)
    ax.set_title(key.replace("/", " sphere, ") + " probe")
    ax.set_xlabel("render time (s)")
    ax.set_ylabel("relMSE")
axes[0][-1].legend(fontsize=6.5, loc="upper right", ncol=1)
fig.tight_layout()
fig.savefig(f"{ctx.out}/strategies.png")

if keys and BASE in results[keys[0]]:
    fig, ax = p.subplots(figsize=(max(7, 0.55 * len(CONFIGS) + 3.5), 3.8))
    width = 0.8 / len(keys)
    for i, key in enumerate(keys):
        xs = [j + i * width for j in range(len(CONFIGS))]
        ax.bar(xs, [ratios.get(key, {}).get(c[0], float("nan")) for c in CONFIGS], width, label=key)
    ax.set_yscale("log")
    ax.axhline(1, color="k", lw=0.8)
    ax.set_xticks([j + 0.4 - width / 2 for j in range(len(CONFIGS))])
    ax.set_xticklabels([c[0] for c in CONFIGS], rotation=60, ha="right", fontsize=7)
    ax.set_ylabel(f"efficiency / {BASE}")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    fig.tight_layout()
    fig.savefig(f"{ctx.out}/strategies_efficiency.png")

# ---------------------------------------------------------------- tables
hdr = ["strategy"] + keys + ["geo. mean"]
rows = []
for name, _ in CONFIGS:
    vals = [ratios.get(k, {}).get(name) for k in keys]
    rows.append([name] + [v if v is not None else "failed" for v in vals]
                + [geomean([v for v in vals if isinstance(v, float)])])
rows_t = []
for name, _ in CONFIGS:
    row = [name]
    for k in keys:
        pts = reliable(results[k].get(name) or [])
        row.append(f"{g(pts[-1]['relmse'])} @ {pts[-1]['spp']} spp, {g(pts[-1]['seconds'])} s" if pts else "failed")
    rows_t.append(row)
nonfinite = sum(q["nonfinite"] for d in results.values() for v in d.values() for q in v)

text = [f"## 3. Sampling strategies\n",
        f"Scenes in scripts/report/scenes/ ("
        + ", ".join(f"`sphere_{m}_{t}.json`" for m in MATERIALS for t in ("sunny", "overcast")) +
        f"): one sphere filling a "
        f"{RES}x{RES} image (diffuse albedo 0.7; gold conductor, GGX roughness 0.1 and 0.01), lit by the built-in "
        f"default probe (sunny: sun of radius 0.27 deg at 35 deg elevation, seen in the spheres) or the same outdoor "
        f"model with cloud cover 1 and no sun (overcast), as {SKY_SIZE} lat-long images baked in memory (`--bake`), "
        f"and real captures: blender's studio-light HDRIs "
        f"{', '.join(p for p in PROBES if p not in ('sunny', 'overcast')) or '(none in this run)'} (scenes of the "
        f"sunny templates with the image replaced). "
        f"Reference: `{' '.join(REF_OPTIONS)}` at {REF_SPP} spp (its own seed); its own noise (from its variance AOV, "
        f"mean Var/(R^2+0.01)) is subtracted from every relMSE. Time: envrender's render time (scene loading and "
        f"baking excluded), both cores. Each strategy climbs the spp ladder {LEVELS} while the next level is "
        f"predicted (linearly in spp) to take <= {CAP:g} s; all strategies run at one level before the next (interleaved). Efficiency = geometric mean of "
        f"1/(relMSE x time) over the levels >= 4 spp whose raw relMSE is at least {RELIABLE:g}x the reference's own noise "
        f"(below that the corrected relMSE is a small difference of noisy numbers; such levels are left out of the "
        f"efficiencies and of the table of the highest level). Machine: {machine}.\n",
        f"![relMSE vs time](strategies.png)\n",
        f"### Efficiency relative to {BASE} (higher is better)\n",
        md_table(hdr, rows),
        f"\n![efficiency ratios](strategies_efficiency.png)\n",
        "### relMSE at the highest reliable spp reached\n",
        md_table(["strategy"] + keys, rows_t, ["---"] * (len(keys) + 1)),
        f"\nNon-finite estimates reported by envrender over all runs: {nonfinite}.\n"]
if failures:
    text.append("Failed strategies (envrender's message): " + "; ".join(f"{k}: `{v}`" for k, v in failures.items()) + "\n")
ref_noise = ", ".join(f"{k} {g(r.noise)}" for k, r in refs.items())
text.append(f"Reference noise subtracted (relMSE units): {ref_noise}.\n")
for n in ctx.notes:
    text.append(f"- {n}")
text.append("\n" + commands_block(ctx))
ctx.write_md("strategies.md", "\n".join(text))
ctx.save_summary({"configs": [c[0] for c in CONFIGS], "scenes": keys, "results": results, "efficiency": eff,
                  "ratios": ratios, "base": BASE, "failures": failures, "res": RES, "levels": LEVELS, "ref_spp": REF_SPP})
ctx.info("wrote strategies.md")
