"""Assembles REPORT.md (next to the --out directory) from the sections' markdown and JSON summaries, and writes the
recommendations from the numbers. Usage: report.py OUT_DIR MODE SECONDS "FAILED SECTIONS" """
import datetime
import json
import math
import os
import platform
import re
import sys

from report.common import DEFAULT_STRATEGY, commit, g, geomean

out_dir, mode, seconds, failed = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4].split()
base = os.path.basename(out_dir.rstrip("/"))
report_path = os.path.join(os.path.dirname(out_dir.rstrip("/")), "REPORT.md")
SECTIONS = ["conversion", "tables", "strategies", "stratification", "precision", "extremes", "prefilter", "indirect"]


def load(name):
    p = os.path.join(out_dir, name + ".json")
    if not os.path.exists(p):
        return None
    with open(p) as f:
        return json.load(f)


def section_md(name):
    p = os.path.join(out_dir, name + ".md")
    if not os.path.exists(p):
        return f"## {name}\n\nNot run (no {base}/{name}.md).\n"
    text = open(p).read()
    return re.sub(r"\]\((?!https?:)([^)/]+\.(?:png|md))\)", rf"]({base}/\1)", text)


S = {s: load(s) for s in SECTIONS}
rec = []       # recommendation bullets
headline = []  # headline numbers

# ---------------------------------------------------------------- 1. conversion
# Filters are ranked by what a renderer sees (the worst of the GGX-prefiltered and irradiance errors, report/seen.py),
# never by the per-texel relMSE, which rewards losing the sun.
c = S["conversion"]
if c:
    F = c["faces"][-1]
    conv = {k.split("|")[1]: v for k, v in c["conv"].items() if int(k.split("|")[0]) == F}
    fastest = min(conv, key=lambda f: conv[f]["time"])
    best = min(conv, key=lambda f: conv[f]["seen_worst"])
    sun = c["sun"]
    cons = min(sun, key=lambda f: sun[f]["seen"]["power"])
    seen_keys = [k for k in conv[best]["seen"] if k != "power"]
    ok_preview = [f for f in conv if conv[f]["seen_worst"] <= 2 * conv[best]["seen_worst"]]
    prev = min(ok_preview, key=lambda f: conv[f]["time"])
    headline.append(f"Conversion of a {c['source'][0]}x{c['source'][1]} lat-long to cube {F}, error as a surface sees "
                    f"it (worst of {', '.join(seen_keys)}; relative RMS): " +
                    ", ".join(f"`{f}` {g(v['seen_worst'])} in {g(v['time'])} s" for f, v in conv.items()) +
                    f"; lowest `{best}`. Sub-texel sun power error: " +
                    ", ".join(f"{f} {g(v['seen']['power'])}" for f, v in sun.items()) + ".")
    rec.append(f"**Converting maps.** `--filter {best}` for maps that light final frames or are baked into tables: "
               f"the lowest error a glossy or diffuse surface sees at cube {F} ({g(conv[best]['seen_worst'])}, vs "
               + ", ".join(f"{f} {g(v['seen_worst'])}" for f, v in conv.items() if f != best) +
               f") and a sub-texel sun's power kept to {g(sun[best]['seen']['power'])}"
               + (f" (the best at that is `{cons}`, {g(sun[cons]['seen']['power'])})" if cons != best else "")
               + (f"; it is also the fastest. " if best == fastest else
                  f"; it takes {conv[best]['time'] / conv[fastest]['time']:.1f}x the time of the fastest, `{fastest}`. ")
               + (f"For previews, `--filter {prev}` is the fastest within 2x of that error ({g(conv[prev]['time'])} s, "
                  f"{g(conv[prev]['seen_worst'])})." if prev != best else
                  f"No other filter comes within 2x of its error, so it is the choice for previews too."))

# ---------------------------------------------------------------- 2. tables
t = S["tables"]
if t:
    fr = t["fracs"]
    b = t["bake"]
    full, small = b[str(fr[0])], b[str(fr[-1])]
    headline.append(f"Tables of a {t['map'][0]}x{t['map'][1]} map: 1/{fr[-1]} resolution bakes in "
                    f"{g(small['seconds_median'])} s vs {g(full['seconds_median'])} s and takes "
                    f"{small['bytes_total'] / 2**20:.2f} MiB vs {full['bytes_total'] / 2**20:.2f} MiB.")
    if t.get("renders"):
        rr = t["renders"]
        strat = t["strategies"][0]
        fulle = rr[f"{strat}|{fr[0]}|time"]["relmse"]
        good = [f for f in fr if rr[f"{strat}|{f}|time"]["relmse"] <= 1.25 * fulle
                and abs(rr[f"{strat}|{f}|spp"]["mean_ratio"] - 1) < 0.02]
        pick = max(good) if good else fr[0]
        per = ", ".join(f"{'full' if f == 1 else '1/' + str(f)} {g(rr[f'{strat}|{f}|time']['relmse'])}" for f in fr)
        if pick == fr[0]:
            rec.append(f"**Table resolution.** Keep full-resolution tables: with `{strat}` no smaller table stays "
                       f"within 25% of the full table's equal-time relMSE and 2% of its mean brightness (equal-time "
                       f"relMSE {per}); the smaller tables only save memory ({small['bytes_total'] / 2**20:.2f} MiB "
                       f"vs {full['bytes_total'] / 2**20:.2f} MiB at 1/{fr[-1]}).")
        else:
            rec.append(f"**Table resolution.** For previews and interactive work, 1/{pick} resolution tables: with "
                       f"`{strat}` they stay within 25% of the full table's equal-time relMSE and 2% of its mean "
                       f"brightness (equal-time relMSE {per}) at {b[str(pick)]['bytes_total'] / 2**20:.2f} MiB instead "
                       f"of {full['bytes_total'] / 2**20:.2f} MiB; keep full-resolution tables for final frames.")
    else:
        rec.append("**Table resolution.** No render numbers in this run (see section 2: envrender could not load "
                   f"envbake's table files), so only cost is measured: 1/{fr[-1]} tables are "
                   f"{full['bytes_total'] / max(small['bytes_total'], 1):.0f}x smaller and bake in "
                   f"{g(small['seconds_median'])} s vs {g(full['seconds_median'])} s. No recommendation on "
                   f"their render quality until that is measured.")

    pm = t.get("per_method") or {}
    if pm:
        headline.append("Table methods on a real HDRI (sunrise): " + ", ".join(
            f"{m} {g(r['seconds'])} s, {r['bytes'] / 2**20:.2f} MiB, worst pdf error {g(r['worst_pdf'])}, "
            f"chi-square p {g(r['p'])}" for m, r in pm.items()) + ".")
        exact = [m for m, r in pm.items() if r["worst_pdf"] < 1e-4 and r["p"] > 0.01]
        if exact:
            small = min(exact, key=lambda m: pm[m]["bytes"])
            others = [m for m in pm if m not in exact]
            mib = ", ".join(f"{m} {pm[m]['bytes'] / 2**20:.2f} MiB" for m in exact)
            rec.append(f"**Table method.** `{small}`: the smallest of the methods whose density is the ideal "
                       f"importance / total to {g(max(pm[m]['worst_pdf'] for m in exact))} on every texel and whose "
                       f"draws pass chi-square ({mib})"
                       + (f"; {', '.join(f'`{m}`' for m in others)} drew dim texels of the sun's rows at up to "
                          f"{g(max(pm[m]['worst_pdf'] for m in others))} relative error (unbiased, but noisier there)"
                          if others else "") +
                       ". `alias` only for plain random numbers on very large maps (it breaks stratification: "
                       "section 4).")

# ---------------------------------------------------------------- 3. strategies
TIE = 0.95  # efficiency ratio above which the default is recommended over the measured best
s = S["strategies"]
if s and s.get("ratios"):
    ratios, res, basecfg = s["ratios"], s["results"], s["base"]
    scenes = s["scenes"]
    probes = sorted({k.split("/")[1] for k in scenes}, key=lambda p: ["sunny", "overcast"].index(p) if p in
                    ["sunny", "overcast"] else 9)

    def best_for(keys, eff_of):
        scores = {cfg: geomean([eff_of(k, cfg) for k in keys]) for cfg in s["configs"]}
        scores = {k: v for k, v in scores.items() if math.isfinite(v)}
        return max(scores, key=scores.get), scores

    def final_eff(k, cfg):
        return ratios.get(k, {}).get(cfg, float("nan"))

    def preview_eff(k, cfg):  # efficiency at the first ladder level (1 spp), relative to the base strategy there
        a, b0 = res[k].get(cfg), res[k].get(basecfg)
        if not a or not b0 or a[0]["relmse"] <= 0 or b0[0]["relmse"] <= 0:
            return float("nan")
        return (b0[0]["relmse"] * b0[0]["seconds"]) / (a[0]["relmse"] * a[0]["seconds"])

    fb, fscores = best_for(scenes, final_eff)
    pb, pscores = best_for(scenes, preview_eff)
    headline.append(f"Strategies (efficiency = 1/(relMSE x time), geometric mean over {len(scenes)} scenes, relative "
                    f"to {basecfg}): best `{fb}` {fscores[fb]:.2f}x; " +
                    ", ".join(f"{k} {fscores[k]:.2f}x" for k in ("bsdf", "light hierarchical", "mis-compensated",
                                                                 "product", "product-mis", "auto") if k in fscores)
                    + ".")
    rec.append(f"**Previews (1 spp, time-normalised).** `{pb}`: {pscores[pb]:.2f}x the efficiency of {basecfg} at "
               f"1 spp (geometric mean over the scenes).")
    # Within a few percent, a geometric mean over these scenes is a tie: seconds on the shared machine move by more
    # than that between runs. Then the default is the recommendation, since it is what a user gets unasked.
    if fb != DEFAULT_STRATEGY and DEFAULT_STRATEGY in fscores and fscores[DEFAULT_STRATEGY] >= TIE * fscores[fb]:
        rec.append(f"**Final frames.** `{DEFAULT_STRATEGY}` (the default): {fscores[DEFAULT_STRATEGY]:.2f}x the "
                   f"efficiency of {basecfg} over the spp ladder (geometric mean over the scenes); `{fb}` measured "
                   f"{fscores[fb]:.2f}x, a tie within this run's timing noise.")
    else:
        rec.append(f"**Final frames.** `{fb}`: {fscores[fb]:.2f}x the efficiency of {basecfg} over the spp ladder "
                   f"(geometric mean over the scenes)" +
                   ("." if fb == basecfg else f"; {basecfg} itself is the reference at 1.00x."))
    for probe in probes:
        keys = [k for k in scenes if k.endswith("/" + probe)]
        pbest, sc = best_for(keys, final_eff)
        per = "; ".join(f"{k.split('/')[0]}: `{max((c for c in s['configs'] if math.isfinite(final_eff(k, c))), key=lambda c: final_eff(k, c))}` "
                        f"{max(final_eff(k, c) for c in s['configs'] if math.isfinite(final_eff(k, c))):.2f}x" for k in keys)
        rec.append(f"**{probe.capitalize()} probe.** Best overall `{pbest}` ({sc[pbest]:.2f}x {basecfg}); per "
                   f"material: {per}.")
    # The default strategy per scene, and over the glossy scenes, against the base.
    default = DEFAULT_STRATEGY
    per_scene = {k: final_eff(k, default) for k in scenes} if default in s["configs"] else {}
    per_scene = {k: v for k, v in per_scene.items() if math.isfinite(v)}
    if per_scene:
        low = min(per_scene, key=per_scene.get)
        glossy = [per_scene[k] for k in per_scene if k.split("/")[0] == "glossy"]
        headline.append(f"The default strategy (`{default}`) against {basecfg}, equal time: lowest {per_scene[low]:.2f}x "
                        f"({low}), highest {max(per_scene.values()):.2f}x"
                        + (f", geometric mean over the glossy scenes {geomean(glossy):.2f}x" if glossy else "") + ".")
        # The cited samplers against the default, scene by scene: where one wins, say so.
        seed = [c for c in s["configs"] if c.startswith(("product-wavelet", "product-steerable", "product-sh"))]
        wins = [(k, c, final_eff(k, c) / per_scene[k]) for k in per_scene for c in seed
                if math.isfinite(final_eff(k, c)) and final_eff(k, c) > per_scene[k]]
        if seed:
            best_seed = {c: geomean([final_eff(k, c) for k in per_scene if math.isfinite(final_eff(k, c))])
                         for c in seed}
            rec.append("**The cited product samplers** (wavelet, steerable, SH; their precomputation is set-up, "
                       "like the tables', and not in the time): geometric mean efficiency against " + basecfg + ": " +
                       ", ".join(f"`{c}` {v:.2f}x" for c, v in best_seed.items() if math.isfinite(v)) +
                       f"; the default `{default}` {geomean(list(per_scene.values())):.2f}x. " +
                       ("They beat the default on " + "; ".join(f"{k} (`{c}`, {r:.2f}x the default)"
                                                                 for k, c, r in wins) + "."
                        if wins else "None beats the default on any scene."))

# ---------------------------------------------------------------- 4. stratification
st = S["stratification"]
if st:
    avg = st["avg"]
    probe = st["probes"][0]
    gains = {m: avg[f"{probe}|{m}|random"]["64"] / max(avg[f"{probe}|{m}|sobol"]["64"], 1e-300)
             for m in ("cdf", "alias", "hierarchical")}
    bestm = min(("cdf", "alias", "hierarchical"), key=lambda m: avg[f"{probe}|{m}|sobol"]["64"])
    headline.append(f"Stratification ({probe} probe, 64 samples): relMSE random/Sobol = " +
                    ", ".join(f"{m} {v:.2g}x" for m, v in gains.items()) + ".")
    rec.append(f"**Sample sequences.** Draw tables with Sobol points through `{bestm}` (lowest Sobol relMSE at 64 "
               f"samples, {g(avg[f'{probe}|{bestm}|sobol']['64'])}); alias tables gain only {gains['alias']:.2g}x from "
               f"Sobol where cdf gains {gains['cdf']:.2g}x and hierarchical {gains['hierarchical']:.2g}x, so use alias "
               f"only with random sequences or when O(1) sampling matters more than stratification.")

# ---------------------------------------------------------------- 5. precision
pr = S["precision"]
if pr and pr.get("rows"):
    rows = pr["rows"]
    wmax = max(int(r["width"]) for r in rows)
    at = {r["method"]: r for r in rows if int(r["width"]) == wmax}
    fn = at.get("float-naive")
    parts = [f"{m}: max rel. error {g(float(r['max_rel_err']))}, {r['unreachable']} unreachable texels"
             for m, r in at.items()]
    headline.append(f"Precision at {wmax}x{wmax // 2}: " + "; ".join(parts) + ".")
    if fn:
        rec.append(f"**Table precision.** Accumulate in double (envkit's cdf and hierarchical tables): float running sums leave "
                   f"{fn['unreachable']} of {fn['lit_texels']} lit texels unreachable at {wmax}x{wmax // 2} "
                   f"(max relative probability error {g(float(fn['max_rel_err']))}).")

# ---------------------------------------------------------------- 6. extremes
e = S["extremes"]
if e and e.get("res"):
    rng = e["ranges"]
    hi, lo = rng[-1], rng[0]
    r = e["res"]
    at_hi = {cfg: r[f"{cfg}|{hi:g}"]["relmse"] for cfg in e["configs"] if f"{cfg}|{hi:g}" in r}
    if at_hi:
        bh = min(at_hi, key=at_hi.get)
        growth = {cfg: r[f"{cfg}|{hi:g}"]["relmse"] / max(r[f"{cfg}|{lo:g}"]["relmse"], 1e-300)
                  for cfg in e["configs"] if f"{cfg}|{hi:g}" in r and f"{cfg}|{lo:g}" in r}
        headline.append(f"Sun dynamic range {hi:g}: lowest relMSE at {e['spp']} spp `{bh}` ({g(at_hi[bh])}); "
                        + ", ".join(f"{k} {g(v)}" for k, v in at_hi.items() if k != bh) + ".")
        if len(rng) > 1:
            worst = max(growth, key=growth.get)
            ties = [k for k, v in at_hi.items() if v <= 1.1 * at_hi[bh]]
            lead = (f"`{bh}` has the lowest relMSE at equal spp ({g(at_hi[bh])})" if len(ties) == 1 else
                    f"{', '.join(f'`{k}`' for k in ties)} tie within 10% for the lowest relMSE at equal spp "
                    f"({g(at_hi[bh])}; the error they share does not depend on the strategy)")
            worst_txt = (f"`{worst}` degrades most from {lo:g} to {hi:g} (relMSE x{g(growth[worst])}, "
                         f"{g(r[f'{worst}|{lo:g}']['relmse'])} -> {g(at_hi[worst])})")
            rec.append(f"**Very bright suns.** At a dynamic range of {hi:g}, {lead}; {worst_txt}. Strategies whose "
                       f"relMSE at {hi:g} is over 3x the best: " +
                       (", ".join(f"`{k}` ({g(v)})" for k, v in at_hi.items() if v > 3 * at_hi[bh]) or "none") + ".")

if e and e.get("sizes"):
    tools = ("envconvert", "envbake", "envprefilter", "envrender")
    ok = [m for m, r in e["sizes"].items() if all(r[t]["exit"] == 0 for t in tools)]
    refused = [m for m, r in e["sizes"].items() if all(r[t]["exit"] == 1 for t in tools)]
    odd = [m for m in e["sizes"] if m not in ok and m not in refused]
    worst_power = max((r.get("power", 0.0) for m, r in e["sizes"].items() if m in ok), default=0.0)
    headline.append(f"Maps at the ends of the size range: {', '.join(ok) or 'none'} go through every tool (power "
                    f"error of their conversion at most {g(worst_power)}); {', '.join(refused) or 'none'} refused by "
                    f"every tool with one line" + (f"; mixed outcomes: {', '.join(odd)}" if odd else "") + ".")
    rec.append("**Tiny and huge maps.** " + (f"Any tool takes {', '.join(ok)}" if ok else "No map measured passes") +
               (f"; an image no parameterization fits ({', '.join(refused)}) is refused before any work, with "
                f"exit 1 and a message naming the file" if refused else "") +
               (f". Check by hand: {', '.join(odd)} (section 6)." if odd else "."))

# ---------------------------------------------------------------- 7. prefilter
pf = S["prefilter"]
if pf and pf.get("acc"):
    acc, target = pf["acc"], pf["target"]
    sizes = pf["sizes"]
    worst_by_acc = {a: max(acc[f"{s}|{a:g}"]["worst"] for s in sizes if f"{s}|{a:g}" in acc)
                    for a in pf["accuracies"] if any(f"{s}|{a:g}" in acc for s in sizes)}
    big = max(sizes)
    ms = {a: acc[f"{big}|{a:g}"]["ms"] for a in worst_by_acc if f"{big}|{a:g}" in acc}
    meeting = [a for a, w in worst_by_acc.items() if w <= target]
    headline.append(f"Prefiltering, chains {min(sizes)}^2..{big}^2, worst level against the brute-force sum: " +
                    ", ".join(f"accuracy {a:g} {100 * w:.2f}%" + (f" ({g(ms[a])} ms CPU at {big}^2)" if a in ms else "")
                              for a, w in worst_by_acc.items()) + ".")
    d = pf["default_accuracy"]
    if meeting:
        fastest = max(meeting)
        rec.append(f"**Prefiltering.** `--accuracy {fastest:g}` is the fastest setting that keeps every level of every "
                   f"chain from {min(sizes)}^2 to {big}^2 within {100 * target:g}% of the brute-force sum (worst "
                   f"{100 * worst_by_acc[fastest]:.2f}%)" +
                   (f"; the default {d:g} is {'that setting' if fastest == d else 'more exact than needed for that bound (worst ' + format(100 * worst_by_acc[d], '.2f') + '%)'}"
                    if d in worst_by_acc else "") +
                   ". Halve it only for reference renders: each halving costs about 2-4x the time for a few times "
                   "less error.")
    else:
        rec.append(f"**Prefiltering.** No accuracy measured keeps every level within {100 * target:g}% of the "
                   f"brute-force sum (best {100 * min(worst_by_acc.values()):.2f}%): use the smallest.")

# ---------------------------------------------------------------- 8. indirect light
ind = S["indirect"]
if ind and ind.get("results"):
    res = ind["results"]
    values = [f"{v:g}" for v in ind["values"] if f"{v:g}" != "0"]
    eff = ind["geomean_efficiency"]
    headline.append(f"Indirect light (depth {ind['depth']}, {ind['spp']} spp, {', '.join(res)}): efficiency of "
                    "`--regularize` over the unbiased setting, against the unbiased reference (geometric mean over "
                    "the lightings): " + ", ".join(f"{v} {g(eff.get(v))}" for v in values) + " (bias and noise per "
                    "lighting: section 8).")
    # The default is judged as a user meets it: by the total error against the unbiased reference (its bias
    # included) at the section's spp, per unit time, on every lighting.
    default = ind.get("default")
    dv = None if default is None else f"{default:g}"
    wins = [v for v in values if all(v in rows and rows[v]["efficiency"] and rows[v]["efficiency"] > 1.0
                                     for rows in res.values())]
    if dv is None:
        rec.append("**Indirect light.** The section could not read envrender's default `--regularize`.")
    elif dv == "0":
        rec.append("**Indirect light.** " + (f"`--regularize {max(wins, key=lambda v: eff.get(v) or 0.0)}` beats the "
                   "default 0 (unbiased) on every lighting measured." if wins else
                   "Keep the default `--regularize 0` (unbiased): no value measured wins on every lighting."))
    elif dv in wins:
        worst = min(rows[dv]["efficiency"] for rows in res.values())
        bias_max = max(rows[dv]["bias"] for rows in res.values())
        rec.append(f"**Indirect light.** Keep the default `--regularize {dv}`: "
                   f"{g(eff.get(dv))}x the unbiased setting's efficiency here (at least {g(worst)}x on every "
                   "lighting), " + (f"its bias at most {g(bias_max)} relMSE against the unbiased reference" if
                                    bias_max > 0 else "its bias below what the run resolves") + ". It blurs "
                   "caustics seen through a diffuse or rough bounce (docs/RENDERER-INDIRECT.md): render final frames "
                   "that need them exact with `--regularize 0`.")
    else:
        lost = [p for p, rows in res.items() if not (dv in rows and rows[dv]["efficiency"]
                                                     and rows[dv]["efficiency"] > 1.0)]
        rec.append(f"**Indirect light.** The default `--regularize {dv}` does not beat the unbiased setting on "
                   f"{', '.join(lost)} in this run (section 8); `--regularize 0` there.")


# ---------------------------------------------------------------- write
def measured():
    """When (and at which commits, where the sections recorded them) the sections' numbers were measured: a section
    rerun alone, or REPORT.md reassembled later, keeps its own date."""
    runs = [v for v in S.values() if v]
    dates = sorted(v["generated"] for v in runs if v.get("generated"))
    by_commit = {}
    for name, v in S.items():
        if v:
            by_commit.setdefault(v.get("commit") or "a commit they did not record", []).append(name)
    when = (f"sections finished {dates[0]}" + (f" to {dates[-1]}" if dates[-1] != dates[0] else "")) if dates else \
        "sections finished at unknown times"
    if len(by_commit) <= 1:
        return f"{when} at {next(iter(by_commit))}" if by_commit else when
    return when + " (" + "; ".join(f"{', '.join(names)} at {c}" for c, names in by_commit.items()) + ")"


now = datetime.datetime.now(datetime.timezone.utc)
cmd = {"quick": "scripts/report/report.sh --quick", "full": "scripts/report/report.sh --full", "smoke": "scripts/report/report.sh --smoke"}[mode]
L = ["# envkit speed-accuracy report\n",
     f"Generated by `{cmd}`: {measured()}; assembled on {now:%Y-%m-%d %H:%M UTC} at commit {commit()} "
     f"({platform.node()}, {os.cpu_count()} "
     f"cores, load average {os.getloadavg()[0]:.1f} at the end, each section's at its start in its text; shared with "
     f"other users: absolute times wobble, ratios measured side by side in one run are the result); the sections "
     f"ran for {sum(v.get('seconds_total', 0) for v in S.values() if v):.0f} s in total ("
     + ", ".join(f"{k} {v.get('seconds_total', 0):.0f} s" for k, v in S.items() if v) + "). "
     f"Regenerate everything with `scripts/report/report.sh --full` (the real measurement, ~30-60 min on 2 cores) or "
     f"`scripts/report/report.sh --quick` (small sizes, few spp, 1 repeat: a few minutes); both build what they need in "
     f"build-report/. relMSE = mean((I - R)^2 / (R^2 + 0.01)) against a high-sample or exact reference; efficiency "
     f"= 1/(relMSE x time). Raw numbers: `{base}/*.json`; tables: `{base}/*.md`; plots: `{base}/*.png`.\n"]
modes = sorted({v["mode"] for v in S.values() if v})
if modes and modes != [mode]:
    L.append(f"Sections come from runs in modes {', '.join(modes)} (each section says which when it differs from "
             f"`{mode}`).\n")
if mode != "full":
    L.append(f"**This is a `{mode}` run**: small images and few samples; the numbers show the shape of the trade-offs "
             f"and keep the generator honest, the full run gives the figures to quote.\n")
if failed:
    L.append(f"**Sections that failed in this run:** {', '.join(failed)}.\n")
L.append("## Headline numbers\n")
L += [f"- {h}" for h in headline] or ["- (no section produced numbers)"]
L.append("")
for sname in SECTIONS:
    md = section_md(sname)
    if S[sname] and S[sname].get("mode") != mode:
        # a section kept from another invocation (e.g. --sections reran only some): say which
        when = S[sname].get("generated", "?")
        md = re.sub(r"^(## .*)\n", lambda m: m.group(1) + f"\n\n*(This section is from a `--{S[sname]['mode']}` "
                    f"run, {when}.)*\n", md, count=1)
    L.append(md)
L.append("## Recommendations (generated from the numbers above)\n")
L += [f"- {r}" for r in rec] or ["- (no numbers to base recommendations on)"]
L.append("")
with open(report_path, "w") as f:
    f.write("\n".join(L))
print(f"report.py: wrote {report_path}", file=sys.stderr)

# Every section that ran must have produced its table (what the quick CTest checks).
missing = [s for s in SECTIONS if S[s] and "|---" not in section_md(s)]
if missing:
    print(f"report.py: sections without a table: {', '.join(missing)}", file=sys.stderr)
    sys.exit(1)
