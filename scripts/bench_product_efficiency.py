#!/usr/bin/env python3
"""Product-sampling efficiency on glossy spheres: relMSE per sphere against a high-spp MIS reference,
time from the EXR metadata (envkit:seconds), efficiency 1/(relMSE x time) and its ratio to power-heuristic MIS.

Driven by scripts/bench_product_efficiency.sh; standard library only (EXRs are read through oiiotool -> FITS).
relMSE = mean((I - R)^2 / (R^2 + 1e-2)) over every channel of the pixels lying entirely on one sphere (the pixel's
four corners and centre hit it: silhouette pixels are left out), minus the reference's own variance of the mean
(the AOV), so that a finite-spp reference does not flatten the ratios. Several seeds; medians.
"""
import argparse
import array
import json
import math
import os
import re
import statistics
import subprocess
import sys
import time


def load_scene(path):
    text = open(path).read()
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"(^|[^:])//[^\n]*", r"\1", text)
    return json.loads(text)


def sub(a, b): return (a[0] - b[0], a[1] - b[1], a[2] - b[2])
def add(a, b): return (a[0] + b[0], a[1] + b[1], a[2] + b[2])
def mul(a, s): return (a[0] * s, a[1] * s, a[2] * s)
def dot(a, b): return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a): return mul(a, 1.0 / math.sqrt(dot(a, a)))


class Camera:  # renderer/src/camera.cpp
    def __init__(self, c, width, height):
        self.pos = tuple(c["position"])
        self.fwd = norm(sub(tuple(c["look_at"]), self.pos))
        self.right = norm(cross(self.fwd, tuple(c.get("up", [0, 1, 0]))))
        self.up = norm(cross(self.right, self.fwd))
        self.tan_half = math.tan(0.5 * c.get("fov", 40) * math.pi / 180)
        self.w, self.h = width, height

    def ray(self, px, py):
        aspect = self.w / self.h
        sx = (2 * px / self.w - 1) * self.tan_half * aspect
        sy = (1 - 2 * py / self.h) * self.tan_half
        return norm(add(add(self.fwd, mul(self.right, sx)), mul(self.up, sy)))


def hits_sphere(o, d, centre, r):
    oc = sub(o, centre)
    b = dot(oc, d)
    c = dot(oc, oc) - r * r
    return b * b - c > 0 and -b - math.sqrt(max(b * b - c, 0)) > 0


def sphere_masks(scene, width, height):
    cam = Camera(scene["camera"], width, height)
    masks = {}
    for s in scene["shapes"]:
        if s["type"] != "sphere":
            continue
        pix = []
        for y in range(height):
            for x in range(width):
                pts = [(x + 0.5, y + 0.5), (x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)]
                if all(hits_sphere(cam.pos, cam.ray(px, py), tuple(s["center"]), s["radius"]) for px, py in pts):
                    pix.append((x, y))
        if pix:
            masks[s["material"]] = pix
    return masks


def read_fits(path):
    data = open(path, "rb").read()
    cards, pos = {}, 0
    while True:
        block = data[pos:pos + 2880]
        pos += 2880
        end = False
        for i in range(0, 2880, 80):
            card = block[i:i + 80].decode("ascii", "replace")
            if card[:8].strip() == "END":
                end = True
                break
            if card[8:10] == "= ":
                cards[card[:8].strip()] = card[10:].split("/")[0].strip()
        if end:
            break
    dims = [int(cards[f"NAXIS{i}"]) for i in range(1, int(cards["NAXIS"]) + 1)]
    n = 1
    for d in dims:
        n *= d
    a = array.array("f")
    a.frombytes(data[pos:pos + 4 * n])
    if sys.byteorder == "little":
        a.byteswap()
    ch, w, h = (dims + [1])[:3] if len(dims) == 3 else (1, dims[0], dims[1])
    return a, ch, w, h


def read_exr(path, subimage, channels):
    fits = path + f".{subimage}.fits"
    subprocess.run(["oiiotool", path, "--subimage", str(subimage), "--ch", channels, "-d", "float", "-o", fits],
                   check=True, capture_output=True)
    img = read_fits(fits)
    os.remove(fits)
    return img


def exr_seconds(path):
    out = subprocess.run(["exrheader", path], check=True, capture_output=True, text=True).stdout
    m = re.search(r'envkit:seconds \(type string\): "([0-9.eE+-]+)"', out)
    return float(m.group(1))


class Image:
    def __init__(self, path, crop):
        self.rgb, ch, w, h = read_exr(path, 0, "R,G,B")
        self.var = read_exr(path, 1, "variance.R,variance.G,variance.B")[0]
        assert ch == 3, (path, ch)
        if w == crop[2] - crop[0] and h == crop[3] - crop[1]:
            self.x0, self.y0, self.w = crop[0], crop[1], w  # data window only
        else:
            self.x0, self.y0, self.w = 0, 0, w  # the full display window (oiiotool fills outside with 0)
        self.seconds = exr_seconds(path)

    def at(self, arr, x, y, c):
        return arr[((y - self.y0) * self.w + (x - self.x0)) * 3 + c]


def relmse(img, ref, pix):
    s = 0.0
    for x, y in pix:
        for c in range(3):
            r = ref.at(ref.rgb, x, y, c)
            d = img.at(img.rgb, x, y, c) - r
            s += (d * d - ref.at(ref.var, x, y, c)) / (r * r + 1e-2)
    return max(s / (3 * len(pix)), 1e-30)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--envrender", required=True)
    ap.add_argument("--scene", action="append", required=True)
    ap.add_argument("--out", required=True, help="work directory for the EXRs")
    ap.add_argument("--md", required=True)
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--config", action="append", required=True,
                    help="label|spp|envrender options (the first config is the baseline, power MIS)")
    ap.add_argument("--threads", default="0")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    configs = []
    for c in args.config:
        label, spp, opts = c.split("|", 2)
        configs.append((label, int(spp), opts.split()))

    def render(scene, out, spp, opts, seed, crop):
        cmd = [args.envrender, "--scene", scene, "-o", out, "--spp", str(spp), "--seed", str(seed), "-q",
               "--threads", args.threads, "--crop", ",".join(map(str, crop))] + opts
        subprocess.run(cmd, check=True)

    md = ["# Product sampling efficiency on glossy spheres", "",
          "Generated by `scripts/bench_product_efficiency.sh` (" + time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()) +
          f", {os.cpu_count()} cores, shared machine). relMSE = mean((I - R)^2 / (R^2 + 1e-2)) over the pixels lying "
          "entirely on each sphere, minus the reference's own variance of the mean; reference: power MIS 1+1 at "
          f"{args.ref_spp} spp; time = envkit:seconds of the render (all passes of one crop); efficiency = "
          f"1/(relMSE x time); median over {args.seeds} seeds (renders interleaved); **ratio** = efficiency / "
          "efficiency of the first row (power MIS, 1 BSDF + 1 light sample) on the same sphere. "
          "Materials: cNNN = GGX conductor, pNNN = rough plastic, alpha = NNN/100.", ""]
    for scene_path in args.scene:
        scene = load_scene(scene_path)
        W, H = scene["camera"]["resolution"]
        masks = sphere_masks(scene, W, H)
        ys = [y for pix in masks.values() for _, y in pix]
        xs = [x for pix in masks.values() for x, _ in pix]
        crop = (min(xs), min(ys), max(xs) + 1, max(ys) + 1)
        name = os.path.splitext(os.path.basename(scene_path))[0]
        ref_path = os.path.join(args.out, f"{name}_ref{args.ref_spp}.exr")
        if not os.path.exists(ref_path):
            t = time.time()
            render(scene_path, ref_path, args.ref_spp, ["--strategy", "mis"], 1000, crop)
            print(f"{name}: reference {args.ref_spp} spp in {time.time() - t:.1f} s", file=sys.stderr)
        ref = Image(ref_path, crop)
        hl = {}
        for m in masks:
            lum = sorted(masks[m], key=lambda p: -sum(ref.at(ref.rgb, p[0], p[1], c) for c in range(3)))
            hl[m] = lum[:max(1, len(lum) // 10)]
        results = {}  # label -> material -> [eff]
        secs = {}
        rel = {}
        for seed in range(1, args.seeds + 1):
            for label, spp, opts in configs:
                out = os.path.join(args.out, f"{name}_{re.sub('[^A-Za-z0-9]+', '_', label)}_{seed}.exr")
                render(scene_path, out, spp, opts, seed, crop)
                img = Image(out, crop)
                secs.setdefault(label, []).append(img.seconds)
                for mat, pix in masks.items():
                    e = relmse(img, ref, pix)
                    rel.setdefault(label, {}).setdefault(mat, []).append(e)
                    results.setdefault(label, {}).setdefault(mat, []).append(1.0 / (e * img.seconds))
                    eh = relmse(img, ref, hl[mat])
                    results.setdefault(label, {}).setdefault(mat + ":hl", []).append(1.0 / (eh * img.seconds))
            print(f"{name}: seed {seed} done", file=sys.stderr)
        mats = list(masks)
        base = configs[0][0]

        md += [f"## {name} ({scene['environment'].get('probe', scene['environment'].get('image'))} probe, "
               f"crop {crop}, {', '.join(f'{m} {len(masks[m])} px' for m in mats)})", "",
               "| config | spp | time s | " + " | ".join(f"{m} relMSE" for m in mats) + " | " +
               " | ".join(f"{m} ratio" for m in mats) + " | geomean ratio |",
               "|---|---:|---:|" + "---:|" * (2 * len(mats) + 1)]
        for label, spp, opts in configs:
            ratios = [statistics.median(results[label][m]) / statistics.median(results[base][m]) for m in mats]
            geo = math.exp(sum(math.log(r) for r in ratios) / len(ratios))
            md.append(f"| `{label}` | {spp} | {statistics.median(secs[label]):.3f} | " +
                      " | ".join(f"{statistics.median(rel[label][m]):.3g}" for m in mats) + " | " +
                      " | ".join(f"{r:.2f}" for r in ratios) + f" | {geo:.2f} |")
        md += ["", "Highlights only (per sphere the 10% of its pixels with the brightest reference, where the sun "
               "or the brightest sky reflects): efficiency ratio vs the first row.", "",
               "| config | " + " | ".join(f"{m} hl ratio" for m in mats) + " | geomean |",
               "|---|" + "---:|" * (len(mats) + 1)]
        for label, spp, opts in configs:
            ratios = [statistics.median(results[label][m + ":hl"]) / statistics.median(results[base][m + ":hl"])
                      for m in mats]
            geo = math.exp(sum(math.log(r) for r in ratios) / len(ratios))
            md.append(f"| `{label}` | " + " | ".join(f"{r:.2f}" for r in ratios) + f" | {geo:.2f} |")
        md += ["", "Options per config: " + "; ".join(f"`{l}`: `{' '.join(o)}`" for l, _, o in configs), ""]
        with open(args.md, "w") as f:
            f.write("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
