"""Shared helpers of the speed-accuracy report (scripts/report/report.sh runs one scripts/report/<section>.py per section,
as the module report.<section>).

Every section gets a Context (tool paths, work directory, output directory, mode) and uses:
  run(...)            run one command, log it (commands.log), return stdout, stderr and wall time
  timed_interleaved   median wall time of several commands over repeats, interleaved so that load hits all alike
  render(...)         one envrender run: parses the render seconds and spp it prints, returns the image as numpy
  read_image(...)     one part of an image (EXR with AOVs included) as a numpy array H x W x C (bench/common.py
                      read_exr: the beauty in process through envkit, other parts through oiiotool)
  rel_mse(I, R)       mean((I - R)^2 / (R^2 + 1e-2)) over pixels and colour channels (bench/common.py)
  md_table / write_md / plot helpers / save_summary (JSON read by the final REPORT.md assembly)
"""
import json
import math
import os
import re
import shlex
import statistics
import subprocess
import sys
import time

import numpy as np

from bench.common import IN_PROCESS_READ, ReadFailed, read_exr, rel_mse

REPORT_DIR = os.path.dirname(os.path.abspath(__file__))
DEFAULT_STRATEGY = "auto"  # envrender's default strategy (what a user gets without --strategy)
SCENE_DIR = os.path.join(REPORT_DIR, "scenes")


class ToolFailed(RuntimeError):
    pass


class Context:
    """Paths and mode shared by all sections; built from the environment set by scripts/report/report.sh."""

    def __init__(self, section):
        self.section = section
        self.mode = os.environ.get("REPORT_MODE", "quick")  # smoke | quick | full
        self.bin = os.environ["REPORT_BIN"]
        self.root = os.environ["REPORT_ROOT"]
        self.out = os.environ["REPORT_OUT"]  # docs/report (png, md, json)
        self.work = os.path.join(os.environ["REPORT_WORK"], section)
        self.repeats = int(os.environ.get("REPORT_REPEATS") or {"smoke": 1, "quick": 1, "full": 3}[self.mode])
        os.makedirs(self.work, exist_ok=True)
        os.makedirs(self.out, exist_ok=True)
        self.log_path = os.path.join(self.work, "commands.log")
        self.commands = []
        self.notes = []
        self.t0 = time.time()
        self.read_note_given = False  # whether the notes say that images are read through oiiotool

    def tool(self, name):
        return os.path.join(self.bin, name)

    def has_tool(self, name):
        return os.access(self.tool(name), os.X_OK)

    def pick(self, smoke, quick, full):
        return {"smoke": smoke, "quick": quick, "full": full}[self.mode]

    def note(self, text):
        self.notes.append(text)
        print(f"[{self.section}] NOTE: {text}", file=sys.stderr)

    def info(self, text):
        print(f"[{self.section}] {time.time() - self.t0:6.1f}s {text}", file=sys.stderr, flush=True)

    def path(self, *names):
        return os.path.join(self.work, *names)

    def short(self, cmd):
        """Command line for the report: tool paths and the work directory stripped."""
        s = " ".join(shlex.quote(str(c)) for c in cmd)
        return s.replace(self.bin + "/", "").replace(self.work + "/", "").replace(self.root + "/", "")

    # ------------------------------------------------------------------ running
    def run(self, cmd, check=True, timeout=None, cwd=None, env=None):
        cmd = [str(c) for c in cmd]
        self.commands.append(self.short(cmd))
        with open(self.log_path, "a") as f:
            f.write(self.short(cmd) + "\n")
        t = time.perf_counter()
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=cwd or self.work, env=env)
        wall = time.perf_counter() - t
        if check and p.returncode != 0:
            raise ToolFailed(f"{self.short(cmd)} -> exit {p.returncode}: {p.stderr.strip()[-600:]}")
        return p.stdout, p.stderr, wall, p.returncode

    def timed_interleaved(self, cmds, repeats=None):
        """cmds: {key: argv}. Runs every command once per repeat, in turn; returns {key: (median, [runs])}."""
        repeats = repeats or self.repeats
        runs = {k: [] for k in cmds}
        for _ in range(repeats):
            for k, c in cmds.items():
                runs[k].append(self.run(c)[2])
        return {k: (statistics.median(v), v) for k, v in runs.items()}

    # ------------------------------------------------------------------ rendering
    RENDER_LINE = re.compile(r"\((\d+)x(\d+), (\d+) spp, [^,]+, ([0-9.eE+-]+) s")

    def render(self, out, scene=None, options=(), read=True, check=True):
        """One envrender run. Returns dict(path, seconds (render only, as printed), wall, spp, image, nonfinite)."""
        cmd = [self.tool("envrender"), "-o", out] + (["--scene", scene] if scene else []) + [str(o) for o in options]
        stdout, stderr, wall, rc = self.run(cmd, check=check)
        if rc != 0:
            return {"path": out, "failed": stderr.strip().splitlines()[-1] if stderr.strip() else f"exit {rc}"}
        m = self.RENDER_LINE.search(stderr)
        res = {"path": out, "wall": wall, "seconds": float(m.group(4)) if m else wall,
               "spp": int(m.group(3)) if m else None, "nonfinite": 0}
        nf = re.search(r"(\d+) non-finite estimates", stderr)
        if nf:
            res["nonfinite"] = int(nf.group(1))
        if read:
            res["image"] = self.read_image(out)
        return res

    def read_image(self, path, channels="R,G,B", subimage="0"):
        """One subimage (EXR part, by index or name) of an image (bench/common.py read_exr: part 0's colour in
        process, checked once against oiiotool); ToolFailed when it cannot be read."""
        try:
            img = read_exr(path, channels, subimage)
        except ReadFailed as e:
            raise ToolFailed(str(e)) from e
        if IN_PROCESS_READ["off_because"] and not self.read_note_given:
            self.read_note_given = True
            self.note(IN_PROCESS_READ["off_because"] + "; every later image is read through oiiotool")
        return img

    # ------------------------------------------------------------------ output
    def write_md(self, name, text):
        p = os.path.join(self.out, name)
        with open(p, "w") as f:
            f.write(text)
        return p

    def save_summary(self, data):
        data = dict(data)
        data.setdefault("section", self.section)
        data["mode"] = self.mode
        data["notes"] = self.notes
        data["commands"] = self.commands[:400]
        data["seconds_total"] = time.time() - self.t0
        data["generated"] = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())
        data["commit"] = commit()
        with open(os.path.join(self.out, f"{self.section}.json"), "w") as f:
            json.dump(data, f, indent=1, default=float)


def commit():
    """The checkout's HEAD (short hash), or a note when this is not a git checkout."""
    try:
        return subprocess.run(["git", "-C", REPORT_DIR, "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"


def max_rel_pixel_error(img, ref):
    """max over pixels of |I - R| / (|R| + 0.1), luminance-free (max over channels)."""
    img = np.asarray(img, dtype=np.float64)
    ref = np.asarray(ref, dtype=np.float64)
    return float(np.max(np.abs(img - ref) / (np.abs(ref) + 0.1)))


def geomean(xs):
    xs = [x for x in xs if x and x > 0 and math.isfinite(x)]
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else float("nan")


def g(x, digits=3):
    """Compact number for tables."""
    if x is None:
        return "-"
    if isinstance(x, str):
        return x
    if not math.isfinite(x):
        return str(x)
    if x == 0:
        return "0"
    a = abs(x)
    if 1e-3 <= a < 1e5:
        s = f"{x:.{digits}g}"
        return s
    return f"{x:.{max(digits - 1, 1)}e}"


def md_table(header, rows, align=None):
    align = align or ["---"] + ["---:"] * (len(header) - 1)
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(align) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(g(c) if not isinstance(c, str) else c for c in r) + " |")
    return "\n".join(lines) + "\n"


def commands_block(ctx, limit=40):
    cmds = []
    for c in ctx.commands:
        if c.startswith("oiiotool") or c in cmds:
            continue
        cmds.append(c)
    more = len(cmds) - limit
    text = "\n".join(cmds[:limit]) + (f"\n... ({more} more, full list in the work directory's commands.log)" if more > 0 else "")
    return "<details><summary>commands</summary>\n\n```\n" + text + "\n```\n</details>\n"


def plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as p
    p.rcParams.update({"figure.dpi": 110, "font.size": 9, "axes.grid": True, "grid.alpha": 0.3})
    return p


def machine_line():
    cpu = "?"
    try:
        cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "?")
    except OSError:
        pass
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return f"{os.cpu_count()} cores, \"{cpu}\", load average {load:.1f} at the start of the section"


def write_scene(path, scene):
    with open(path, "w") as f:
        json.dump(scene, f, indent=1)
    return path


# ---------------------------------------------------------------------- shared rendering setup
HDRI_DIR = "/usr/share/blender/datafiles/studiolights/world"


def make_probe_images(ctx, names=("sunny", "overcast"), size="1024x512"):
    """sky_sunny.exr (the built-in default probe) and sky_overcast.exr (the same outdoor model, cloud cover 1, no
    sun: what the scene format's "probe": "overcast" builds); any other name is one of blender's HDRIs
    (HDRI_DIR/<name>.exr: real captures, e.g. sunrise, courtyard), used as it is and skipped with a note when
    blender's data is not installed. Scenes load these images and bake in memory (--bake), which is faster per run
    than rasterizing the probe in every envrender invocation."""
    out = {}
    for name in names:
        if name in ("sunny", "overcast"):
            continue
        path = os.path.join(HDRI_DIR, name + ".exr")
        if os.path.exists(path):
            out[name] = path
        else:
            ctx.note(f"{path} is missing (blender's data): no {name} scenes in this run")
    for name, extra in (("sunny", []), ("overcast", ["--cloud-cover", "1", "--radiance", "0"])):
        if name not in names:
            continue
        p = ctx.path(f"sky_{name}.exr")
        if not os.path.exists(p):
            ctx.run([ctx.tool("envprobe"), "default", "-o", p, "--size", size] + extra)
        out[name] = p
    return out


def scene_with_image(ctx, template, name, image, resolution=None, tables=None, **env):
    """Copies scripts/report/scenes/<template>.json into the work directory with its environment replaced by an image
    file (and optionally a table file); returns the new scene path."""
    with open(os.path.join(SCENE_DIR, template + ".json")) as f:
        s = json.load(f)
    e = {"image": os.path.abspath(image)}
    if tables:
        e["tables"] = os.path.abspath(tables)
    for k in ("rotation", "intensity"):
        if k in s["environment"]:
            e[k] = s["environment"][k]
    e.update(env)
    s["environment"] = e
    if resolution:
        s["camera"]["resolution"] = list(resolution)
    return write_scene(ctx.path(name + ".json"), s)


def scene_from_template(ctx, template, name, resolution=None, environment=None):
    with open(os.path.join(SCENE_DIR, template + ".json")) as f:
        s = json.load(f)
    if environment:
        s["environment"].update(environment)
    if resolution:
        s["camera"]["resolution"] = list(resolution)
    return write_scene(ctx.path(name + ".json"), s)


class Reference:
    """A high-spp render: image and the per-pixel variance of its mean (from the EXR's variance AOV), so that the
    reference's own noise can be removed from measured errors: E[(I-R)^2] = Var I + Var R + bias^2."""

    def __init__(self, ctx, scene, spp, options, name, extra=(), seed=1000003):
        self.path = ctx.path(name + ".exr")
        r = ctx.render(self.path, scene, ["--spp", spp, "--seed", seed] + list(options) + list(extra) + ["--bake"])
        if "failed" in r:
            raise ToolFailed(r["failed"])
        self.image = r["image"]
        self.seconds = r["seconds"]
        self.spp = spp
        # envrender writes the AOVs into a second EXR part named "aov" (older builds: extra channels of part 0)
        self.variance = None
        for sub in ("aov", "0"):
            try:
                v = ctx.read_image(self.path, "variance.R,variance.G,variance.B", sub)
            except ToolFailed:
                continue
            if v.shape == self.image.shape:
                self.variance = v
                break
        if self.variance is None:
            ctx.note(f"{self.path}: no variance AOV found; the reference's own noise is not subtracted")
            self.variance = np.zeros_like(self.image)
        ref = self.image.astype(np.float64)
        self.noise = float(np.mean(self.variance / (ref ** 2 + 1e-2)))

    def error(self, img):
        """(relMSE against the reference, the same minus the reference's own expected contribution)."""
        e = rel_mse(img, self.image)
        return e, max(e - self.noise, 0.0)
