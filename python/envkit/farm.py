"""Distributed rendering: envrender's render split into tiles over a dask.distributed cluster (docs/PYTHON.md).

    /usr/bin/python3 -m envkit.farm [SCENE ...] -o OUT.exr [--spp N] [--tiles N | --tile-size WxH]
        [--workers N | --scheduler ADDR] [--rotations YAW,...] [--work DIR] [--force]

Each tile is a window (crop) of the image rendered by envrender's integrator. A pixel's samples do not depend on
the window, the tile order or the threads (Owen-scrambled Sobol seeded per pixel), so the tiles' film sums (sum and
sum of squares of the samples, and their count) copied into one film give exactly the sums of a one-process render
with the same seed and spp; that film is written by envrender's own writer: the two-part EXR ("beauty" R, G, B;
"aov" variance.R/G/B, samples) and its PNG preview.

Finished tiles are written atomically to a work folder (default OUT.farm, next to the output) and recorded in its
manifest.json with the job (scenes and their content hashes, options, tiles). A run that was killed resumes: the
tiles recorded for the same job, whose files still have their hash, are kept and only the others are rendered.
The work folder is removed once every frame is written. Tasks of a worker that dies are re-run on the others
(the scheduler's allowed-failures).

Frame sequences run as one job: several SCENE files (one per frame), or --rotations (one frame per environment
yaw, added to the scene's environment.rotation); OUT then holds one printf integer field, e.g. frame.%04d.exr,
replaced by the frame index from 0.
"""

import argparse
import collections
import contextlib
import hashlib
import io
import json
import os
import re
import sys
import threading
import time

import numpy as np

from ._cluster import OutputError, Parser, UsageError, add_cluster_options, check_out_dir, client_for, completed
from ._cluster import check_out_dirs, count, write_atomic, write_json_atomic

LABEL = "envkit.farm"
MANIFEST_VERSION = 1
MANIFEST = "manifest.json"
DEFAULT_TILE_SIZE = (128, 128)
DEFAULT_SCENE = "built-in default"


class FarmError(Exception):
    """Bad input or a failed tile: one line, exit status 1."""


def default_options(**overrides):
    """The render options of a farm job: envkit.render's (envrender's) names and defaults, and threads = oneTBB
    threads per tile (0: all of the worker's cores)."""
    o = {
        "spp": 16,
        "seed": 0,
        "strategy": None,
        "light_method": "hierarchical",
        "heuristic": "power",
        "bsdf_samples": None,
        "light_samples": None,
        "sun_samples": 1,
        "max_depth": 1,
        "regularize": None,
        "width": 0,
        "height": 0,
        "bake": False,
        "threads": 0,
    }
    unknown = set(overrides) - set(o)
    if unknown:
        raise ValueError("unknown farm options: %s" % ", ".join(sorted(unknown)))
    o.update(overrides)
    return o


def _recorded(options):
    """The options that decide the pixels (what a work folder's manifest must match)."""
    return {k: v for k, v in options.items() if k != "threads"}


# ---------------------------------------------------------------------------------------------------------------
# Frames and tiles


def _new_job(frame, options):
    from . import _envkit

    o = options
    return _envkit._RenderJob(
        frame["path"], frame["text"], frame["base"], o["strategy"], o["light_method"], o["heuristic"],
        o["bsdf_samples"], o["light_samples"], o["sun_samples"], o["max_depth"], o["regularize"], o["width"], o["height"],
        o["bake"])


def frames(scenes=(), rotations=None):
    """The frames of a job: one per scene file (None or no scenes: the built-in default scene), or, with
    rotations (environment yaw angles in degrees), one per angle of the single scene, its environment.rotation's
    yaw plus the angle. Each frame: {"path", "text", "base", "name"} (name: what the EXR's envkit:scene says)."""
    scenes = list(scenes) or [None]
    if rotations is None:
        return [{"path": os.path.abspath(s) if s else None, "text": None, "base": "", "name": s or DEFAULT_SCENE}
                for s in scenes]
    if len(scenes) != 1:
        raise UsageError("--rotations: takes one SCENE (got %d)" % len(scenes))
    from . import _envkit

    path = scenes[0]
    if path is None:
        text, base = _envkit._default_scene_json(), os.path.join(os.getcwd(), "<default scene>")
    else:
        try:
            with open(path) as f:
                text = f.read()
        except OSError as e:
            raise FarmError("%s: cannot read: %s" % (path, e.strerror or e)) from None
        base = os.path.abspath(path)
    try:
        scene = json.loads(_without_comments(text))
        env = scene["environment"]
        yaw, pitch, roll = env.get("rotation", [0, 0, 0])
    except (ValueError, KeyError, TypeError):
        # The loader names the line and key of what is wrong.
        from . import Error

        try:
            _new_job({"path": os.path.abspath(path) if path else None, "text": None, "base": ""}, default_options())
        except Error as e:
            raise FarmError(str(e)) from None
        raise FarmError("%s: environment.rotation: expected [yaw, pitch, roll]" % (path or DEFAULT_SCENE)) from None
    out = []
    for angle in rotations:
        env["rotation"] = [yaw + angle, pitch, roll]
        out.append({"path": None, "text": json.dumps(scene), "base": base,
                    "name": "%s, environment yaw %+g deg" % (path or DEFAULT_SCENE, angle)})
    return out


def _without_comments(text):
    """Scene JSON without the // and /* */ comments the scene loader accepts."""
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"(^|[^:])//[^\n]*", r"\1", text)


def tile_grid(width, height, tiles=None, tile_size=None):
    """Windows (x0, y0, x1, y1) covering a width x height image: `tiles` bands of rows as even as the height allows,
    or a grid of tile_size = (w, h) tiles (the last row and column smaller), row by row."""
    if tiles is not None:
        if tiles > height:
            raise UsageError("--tiles: %d bands do not fit the image's %d rows" % (tiles, height))
        rows = [k * height // tiles for k in range(tiles + 1)]
        return [(0, rows[k], width, rows[k + 1]) for k in range(tiles)]
    tw, th = tile_size or DEFAULT_TILE_SIZE
    return [(x, y, min(x + tw, width), min(y + th, height)) for y in range(0, height, th) for x in range(0, width, tw)]


def tile_name(frame, tile):
    return "f%05d-t%05d.npz" % (frame, tile)


# ---------------------------------------------------------------------------------------------------------------
# The worker's side

_JOBS = collections.OrderedDict()  # scenes loaded by this worker process, most recent last
_JOBS_KEPT = 2
_JOBS_LOCK = threading.Lock()  # a worker may run several tiles at once (threads); they share the scenes


def _cached_job(frame, options):
    """The frame's scene and integrator, loaded once per worker process (a tile pays for neither; rendering is
    thread-safe)."""
    key = json.dumps([frame, _recorded(options)], sort_keys=True)
    with _JOBS_LOCK:
        job = _JOBS.get(key)
        if job is None:
            job = _new_job(frame, options)
            _JOBS[key] = job
            while len(_JOBS) > _JOBS_KEPT:
                _JOBS.popitem(last=False)
        _JOBS.move_to_end(key)
        return job


def _digest(data):
    return hashlib.blake2b(data, digest_size=16).hexdigest()


def content_digest(path):
    """BLAKE2b-128 of a file's bytes (hex), or None when it cannot be read: what the manifest records of the tiles
    and the input files."""
    h = hashlib.blake2b(digest_size=16)
    try:
        with open(path, "rb") as f:
            for chunk in iter(lambda: f.read(1 << 20), b""):
                h.update(chunk)
    except OSError:
        return None
    return h.hexdigest()


def render_tile(frame, options, crop, path):
    """Renders the window crop of the frame and writes its film sums to `path` (atomically, .npz: sum, sum_sq,
    count, crop). Returns {"path", "hash" (content_digest of the file), "seconds"}. Runs on a worker."""
    start = time.monotonic()
    sums = _cached_job(frame, options).render(crop, options["spp"], options["seed"], options["threads"])
    buffer = io.BytesIO()
    np.savez(buffer, sum=sums["sum"], sum_sq=sums["sum_sq"], count=sums["count"], crop=np.asarray(crop, np.int64))
    data = buffer.getvalue()
    # Not synced to disk: a tile is kept only while its file has the hash the manifest records.
    write_atomic(path, lambda f: f.write(data), durable=False)
    return {"path": path, "hash": _digest(data), "seconds": time.monotonic() - start}


# ---------------------------------------------------------------------------------------------------------------
# The client's side


def merge(paths, crops, width, height):
    """The film sums of a width x height image from tile files covering it (render_tile's): sum, sum_sq (H, W, 3)
    float64 and count (H, W) uint64. Each pixel's sums are copied, never added: the merge is exact."""
    sum_ = np.zeros((height, width, 3), np.float64)
    sum_sq = np.zeros((height, width, 3), np.float64)
    count_ = np.zeros((height, width), np.uint64)
    for path, (x0, y0, x1, y1) in zip(paths, crops):
        with np.load(path) as t:
            if tuple(t["crop"]) != (x0, y0, x1, y1):
                raise FarmError("%s: holds window %s, expected %s" % (path, tuple(t["crop"]), (x0, y0, x1, y1)))
            sum_[y0:y1, x0:x1] = t["sum"]
            sum_sq[y0:y1, x0:x1] = t["sum_sq"]
            count_[y0:y1, x0:x1] = t["count"]
    return {"sum": sum_, "sum_sq": sum_sq, "count": count_}


def write_film(path, sums, metadata, preview=True):
    """Writes the film holding `sums` (merge()) with envrender's writer: the two-part EXR at `path` and, with
    preview, its PNG preview next to it; both appear, or neither."""
    from . import _envkit

    h, w = sums["count"].shape
    png = os.path.splitext(path)[0] + ".png" if preview else None
    _envkit._write_film(path, w, h, (0, 0, w, h), sums["sum"], sums["sum_sq"], sums["count"], metadata, png)


def _metadata(frame, job, options, seconds, tiles):
    """envrender's EXR metadata for the frame (envkit:seconds: the tiles' render seconds, summed)."""
    o = options
    return {
        "envkit:renderer": LABEL,
        "envkit:scene": frame["name"],
        "envkit:strategy": job.strategy,
        "envkit:light_method": job.light_method,
        "envkit:heuristic": o["heuristic"],
        "envkit:bsdf_samples": "by lobe" if o["bsdf_samples"] is None else str(o["bsdf_samples"]),
        "envkit:light_samples": "by lobe" if o["light_samples"] is None else str(o["light_samples"]),
        "envkit:sun_samples": str(o["sun_samples"] if job.has_sun_split else 0),
        "envkit:max_depth": str(o["max_depth"]),
        "envkit:regularize": "%g" % job.regularize,
        "envkit:spp": str(o["spp"]),
        "envkit:seed": str(o["seed"]),
        "envkit:seconds": "%.4g" % seconds,
        "envkit:environment": job.environment,
        "envkit:tiles": str(tiles),
    }


class Job:
    """A farm job: frames (frames()), their outputs, the render options and the tiles, checked on the client
    before any work (the scenes are loaded once here: a bad scene or option fails now, with its one-line
    message)."""

    def __init__(self, frame_list, outputs, options, tiles=None, tile_size=None, work_dir=None, preview=True):
        if len(outputs) != len(frame_list):
            raise ValueError("one output per frame")
        self.frames, self.outputs, self.options, self.preview = frame_list, outputs, options, preview
        self.jobs = [None] * len(frame_list)
        first = None
        for i, frame in enumerate(frame_list):
            # Rotated frames differ only in the rotation: the first one checks them all.
            if frame["text"] is None or first is None:
                first = self.jobs[i] = _new_job(frame, options)
            else:
                self.jobs[i] = first
            if (self.jobs[i].width, self.jobs[i].height) != (self.jobs[0].width, self.jobs[0].height):
                raise FarmError("%s: renders %dx%d, the first frame %dx%d (pass --resolution)" % (
                    frame["name"], self.jobs[i].width, self.jobs[i].height, self.jobs[0].width,
                    self.jobs[0].height))
        self.width, self.height = self.jobs[0].width, self.jobs[0].height
        self.crops = tile_grid(self.width, self.height, tiles, tile_size)
        self.work_dir = os.path.abspath(work_dir or outputs[0] + ".farm")
        self._check_outputs()

    def inputs(self):
        files = [f["path"] for f in self.frames if f["path"]]
        files += [f["base"] for f in self.frames if f["text"] is not None and os.path.isfile(f["base"])]
        for job in self.jobs:
            files += [p for p in job.environment_files if os.path.isfile(p)]
        return sorted(set(files))

    def _check_outputs(self):
        inputs = {os.path.realpath(p): p for p in self.inputs()}
        for out in self.outputs:
            if os.path.realpath(out) in inputs:
                raise FarmError("%s: output path is the same as input %s" % (out, inputs[os.path.realpath(out)]))
            if os.path.isdir(out):
                raise FarmError("%s: is a directory" % out)
        if len(set(map(os.path.realpath, self.outputs))) != len(self.outputs):
            raise UsageError("-o: %s names the same file for several frames" % self.outputs[0])

    def identity(self):
        """What the work folder's tiles were rendered from: the frames, the content of every input file, the
        options that decide the pixels, the image size and the tiles."""
        return {
            "version": MANIFEST_VERSION,
            "frames": self.frames,
            "inputs": {p: content_digest(p) for p in self.inputs()},
            "options": _recorded(self.options),
            "size": [self.width, self.height],
            "crops": [list(c) for c in self.crops],
        }

    def tile_path(self, frame, tile):
        return os.path.join(self.work_dir, tile_name(frame, tile))


def _our_files(work_dir):
    pattern = re.compile(r"^(f\d{5}-t\d{5}\.npz|%s)$|^\.(f\d{5}-t\d{5}\.npz|%s)\.tmp-" % (MANIFEST, MANIFEST))
    try:
        return [os.path.join(work_dir, n) for n in os.listdir(work_dir) if pattern.match(n)]
    except FileNotFoundError:
        return []


def clear_work_dir(work_dir, remove=False):
    """Removes the farm's files (tiles, manifest, temporary files) from work_dir, and the folder when remove and it
    is then empty; anything else in it is left alone."""
    for p in _our_files(work_dir):
        try:
            os.unlink(p)
        except FileNotFoundError:
            pass
    if remove:
        try:
            os.rmdir(work_dir)
        except OSError:
            pass


def finished_tiles(job, identity):
    """{tile name: {"hash", "seconds"}} of the tiles the work folder's manifest records for this job (identity:
    job.identity()) whose files still have their hash; a manifest of another job (or none) gives {} and its tiles
    are removed."""
    try:
        with open(os.path.join(job.work_dir, MANIFEST)) as f:
            m = json.load(f)
        if m["job"] != identity:
            raise ValueError("another job")
        return {n: t for n, t in m["tiles"].items()
                if os.path.isfile(os.path.join(job.work_dir, n))
                and content_digest(os.path.join(job.work_dir, n)) == t["hash"]}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        clear_work_dir(job.work_dir)
        return {}


def _rendered_tiles(client, job, pending):
    """Yields (frame, tile, render_tile's result) as the tiles `pending` ([(frame, tile)]) finish on `client`; raises
    FarmError naming the first that failed, the others cancelled."""
    # By reference to the importable module, also when this one runs as __main__ (python3 -m envkit.farm), whose
    # functions cloudpickle would copy by value with their globals.
    from .farm import render_tile as task

    futures = [client.submit(task, job.frames[f], job.options, job.crops[t], job.tile_path(f, t), pure=False,
                             retries=1) for f, t in pending]
    for k, r, e in completed(futures):
        f, t = pending[k]
        if e is not None:
            for other in futures:
                other.cancel()
            raise FarmError("%s tile %d %s: %s" % (job.frames[f]["name"], t, job.crops[t], str(e) or type(e).__name__))
        yield f, t, r


def run(client, job, force=False, keep_work=False, progress=None):
    """Renders every tile of every frame that the work folder does not hold yet on `client`, and writes each frame
    once its tiles are there. progress(event) is called on the client with {"event": "resumed" | "tile" |
    "frame", ...}. Returns {"rendered": [tile paths], "resumed": [tile paths], "merge_seconds": {frame: s},
    "write_seconds": {frame: s}} (merge: reading the tiles and assembling the film; write: the EXR and PNG). Raises
    FarmError naming the first tile that failed (finished tiles stay for a re-run). client: a distributed Client,
    or a function returning a context manager that gives one, called only when a tile is missing (the command
    line starts no cluster for a job whose tiles are all there)."""
    check_out_dir(job.work_dir, "--work")
    if force:
        clear_work_dir(job.work_dir)
    identity = job.identity()
    done = finished_tiles(job, identity)
    manifest_file = os.path.join(job.work_dir, MANIFEST)
    # Not synced to disk either: a manifest cut short by a crash does not parse, and the job starts over.
    write_json_atomic(manifest_file, {"job": identity, "tiles": done}, durable=False)
    n_tiles = len(job.crops)
    tiles = [(f, t) for f in range(len(job.frames)) for t in range(n_tiles)]
    pending = [(f, t) for f, t in tiles if tile_name(f, t) not in done]
    resumed = [job.tile_path(f, t) for f, t in tiles if tile_name(f, t) in done]
    if progress and resumed:
        progress({"event": "resumed", "tiles": len(resumed), "of": len(tiles)})
    missing = collections.Counter(f for f, _ in pending)
    render_seconds = collections.Counter()  # per frame, the resumed tiles' seconds included
    for f, t in tiles:
        render_seconds[f] += done.get(tile_name(f, t), {}).get("seconds", 0.0)
    result = {"rendered": [], "resumed": resumed, "merge_seconds": {}, "write_seconds": {}}

    def finish(f):
        start = time.monotonic()
        paths = [job.tile_path(f, t) for t in range(n_tiles)]
        sums = merge(paths, job.crops, job.width, job.height)
        merged = time.monotonic()
        meta = _metadata(job.frames[f], job.jobs[f], job.options, render_seconds[f], n_tiles)
        write_film(job.outputs[f], sums, meta, job.preview)
        result["merge_seconds"][f] = merged - start
        result["write_seconds"][f] = time.monotonic() - merged
        if progress:
            progress({"event": "frame", "frame": f, "output": job.outputs[f], "seconds": time.monotonic() - start})

    for f in range(len(job.frames)):
        if not missing[f]:
            finish(f)
    if pending:
        with client() if callable(client) else contextlib.nullcontext(client) as c:
            for f, t, r in _rendered_tiles(c, job, pending):
                done[tile_name(f, t)] = {"hash": r["hash"], "seconds": r["seconds"]}
                write_json_atomic(manifest_file, {"job": identity, "tiles": done}, durable=False)
                result["rendered"].append(r["path"])
                render_seconds[f] += r["seconds"]
                missing[f] -= 1
                if progress:
                    progress({"event": "tile", "frame": f, "tile": t, "seconds": r["seconds"],
                              "done": len(resumed) + len(result["rendered"]), "of": len(tiles)})
                if missing[f] == 0:
                    finish(f)
    if not keep_work:
        clear_work_dir(job.work_dir, remove=True)
    return result


# ---------------------------------------------------------------------------------------------------------------
# The command line


def _tile_size(text):
    m = re.fullmatch(r"(\d+)x(\d+)", text)
    if not m or not (1 <= int(m.group(1)) <= 16384 and 1 <= int(m.group(2)) <= 16384):
        raise argparse.ArgumentTypeError("expected WxH, sides in [1, 16384], got '%s'" % text)
    return int(m.group(1)), int(m.group(2))


def _rotations(text):
    try:
        angles = [float(a) for a in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError("expected yaw angles in degrees, e.g. 0,90,180,270, got '%s'" % text) from None
    if not all(np.isfinite(angles)) or not angles:
        raise argparse.ArgumentTypeError("expected finite angles, got '%s'" % text)
    return angles


def _outputs(pattern, n):
    """The output of each of n frames: OUT itself for one frame, else OUT with its printf integer field filled."""
    if not pattern.endswith(".exr"):
        raise UsageError("-o %s: the output must be an .exr file (the PNG preview is written next to it)" % pattern)
    fields = re.findall(r"%[-+ #0]*\d*[di]", pattern)
    if n == 1 and not fields:
        return [pattern]
    if len(fields) != 1 or pattern.count("%") != 1:
        raise UsageError("-o %s: %d frames need one integer field in the name, e.g. frame.%%04d.exr" % (pattern, n))
    return [pattern % i for i in range(n)]


def _parse_args(argv):
    p = Parser(
        label=LABEL,
        prog="python3 -m envkit.farm",
        description="Renders a scene (or a sequence of frames) over a dask.distributed cluster, tile by tile, into "
                    "the EXR envrender writes: bit-identical to a one-process render with the same seed and spp.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="""Examples:
  python3 -m envkit.farm -o out.exr                         the built-in default scene, 2 local workers
  python3 -m envkit.farm scene.json -o out.exr --spp 256 --tile-size 64x64 --workers 4
  python3 -m envkit.farm shot/f*.json -o 'frames/f.%04d.exr' --scheduler tcp://10.0.0.5:8786
  python3 -m envkit.farm scene.json -o 'turn.%03d.exr' --rotations 0,45,90,135,180,225,270,315

Output: per frame, envrender's two-part EXR (part "beauty": R, G, B; part "aov": variance.R/G/B = variance of
each pixel's mean, samples) and its PNG preview. Finished tiles are kept in the work folder (default OUT.farm)
with a manifest: a killed run, run again, renders only the missing tiles. Workers must see the scene and
environment files and the work folder at the same paths. Exit status: 0 done; 1 bad input or a failed tile
(one line on stderr, no output); 2 usage error.""",
    )
    p.add_argument("scenes", nargs="*", metavar="SCENE", help="JSON scene files, one per frame (default: the "
                   "built-in default scene)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.exr",
                   help="output EXR; for several frames a pattern with one integer field, e.g. f.%%04d.exr")
    p.add_argument("--spp", type=count(1, 1 << 24), default=16, metavar="N", help="samples per pixel (default 16)")
    p.add_argument("--seed", type=count(0, 0xFFFFFFFF), default=0, help="sampler seed (default 0)")
    t = p.add_mutually_exclusive_group()
    t.add_argument("--tiles", type=count(1, 1 << 16), metavar="N", help="N bands of rows")
    t.add_argument("--tile-size", type=_tile_size, metavar="WxH", help="tiles of WxH pixels (default 128x128)")
    p.add_argument("--rotations", type=_rotations, metavar="YAW,...",
                   help="one frame per environment yaw (degrees, added to the scene's environment.rotation)")
    p.add_argument("--resolution", type=_tile_size, metavar="WxH", help="override the camera resolution")
    p.add_argument("--strategy", help="envrender's --strategy (default: envrender's)")
    p.add_argument("--light-method", default="hierarchical", help="cdf, alias or hierarchical (default)")
    p.add_argument("--heuristic", default="power", help="balance or power (default)")
    p.add_argument("--bsdf-samples", type=count(0, 1024), metavar="N", help="default: by the material's lobe")
    p.add_argument("--light-samples", type=count(0, 1024), metavar="N", help="default: by the material's lobe")
    p.add_argument("--sun-samples", type=count(0, 1024), default=1, metavar="N", help="default 1")
    p.add_argument("--max-depth", type=count(1, 64), default=1, metavar="N",
                   help="scattering events per path (default 1: direct light only)")
    p.add_argument("--regularize", type=float, default=None, metavar="V",
                   help="envrender's --regularize: widen glossy lobes after rough bounces (BIASED; default: "
                        "envrender's; 0 = unbiased)")
    p.add_argument("--bake", action="store_true", help="bake missing or stale sampling tables in memory")
    add_cluster_options(p)
    p.add_argument("--render-threads", type=count(0, 4096), metavar="R",
                   help="oneTBB threads per tile (0: all of a worker's cores; default: the cores / (workers x "
                        "threads per worker) on a LocalCluster, 0 with --scheduler)")
    p.add_argument("--work", metavar="DIR", help="folder of finished tiles and their manifest (default OUT.farm)")
    p.add_argument("--keep-work", action="store_true", help="keep the work folder after the outputs are written")
    p.add_argument("--force", action="store_true", help="discard the work folder's finished tiles, render all")
    p.add_argument("--no-preview", action="store_true", help="do not write the PNG preview")
    p.add_argument("-q", "--quiet", action="store_true", help="print errors only")
    a = p.parse_args(argv)
    for s in a.scenes:
        if not os.path.isfile(s):
            raise FarmError("%s: no such scene file" % s)
    return a


def _render_threads(a):
    if a.render_threads is not None:
        return a.render_threads
    if a.scheduler:
        return 0
    return max(1, (os.cpu_count() or 1) // (a.workers * a.threads_per_worker))


def main(argv=None):
    from . import Error

    start = time.monotonic()
    try:
        a = _parse_args(sys.argv[1:] if argv is None else argv)
        frame_list = frames(a.scenes, a.rotations)
        outputs = _outputs(a.output, len(frame_list))
        width, height = a.resolution or (0, 0)
        options = default_options(
            spp=a.spp, seed=a.seed, strategy=a.strategy, light_method=a.light_method, heuristic=a.heuristic,
            bsdf_samples=a.bsdf_samples, light_samples=a.light_samples, sun_samples=a.sun_samples,
            max_depth=a.max_depth, regularize=a.regularize, width=width, height=height, bake=a.bake, threads=_render_threads(a))
        try:
            job = Job(frame_list, outputs, options, a.tiles, a.tile_size, a.work, preview=not a.no_preview)
        except (Error, ValueError, TypeError) as e:
            raise FarmError(str(e)) from None
        check_out_dirs([(d, "-o") for d in sorted({os.path.dirname(os.path.abspath(o)) for o in outputs})]
                       + [(job.work_dir, "--work")])
    except UsageError as e:
        print("%s: %s (see --help)" % (LABEL, e), file=sys.stderr)
        return 2
    except (FarmError, OutputError) as e:
        print("%s: %s" % (LABEL, e), file=sys.stderr)
        return 1

    def progress(ev):
        if a.quiet:
            return
        if ev["event"] == "resumed":
            msg = "resuming: %d of %d tiles already rendered in %s" % (ev["tiles"], ev["of"], job.work_dir)
        elif ev["event"] == "tile":
            msg = "[%d/%d] frame %d tile %d (%.2f s)" % (ev["done"], ev["of"], ev["frame"], ev["tile"], ev["seconds"])
        else:
            msg = "wrote %s (%dx%d, %d spp, %d tiles, merged and written in %.2f s)" % (
                ev["output"], job.width, job.height, a.spp, len(job.crops), ev["seconds"])
        print("%s: %s" % (LABEL, msg), file=sys.stderr)

    try:
        run(lambda: client_for(a.scheduler, a.workers, a.threads_per_worker), job, force=a.force,
            keep_work=a.keep_work, progress=progress)
    except (FarmError, OutputError, Error) as e:
        print("%s: %s" % (LABEL, e), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("%s: interrupted; the finished tiles stay in %s for the next run" % (LABEL, job.work_dir),
              file=sys.stderr)
        return 130
    if not a.quiet:
        print("%s: %d frame(s) in %.2f s" % (LABEL, len(frame_list), time.monotonic() - start), file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
