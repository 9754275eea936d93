"""Batch processing of a folder of environment maps on a dask.distributed cluster (docs/PYTHON.md).

    /usr/bin/python3 -m envkit.batch IN_DIR OUT_DIR [--workers N | --scheduler ADDR] [--to latlong --size 1024]
        [--no-bake] [--tables hierarchical] [--prefilter] [--memory-limit 6GB] [--report FILE] [-q]

Each input IN_DIR/NAME.EXT gives, in OUT_DIR:
  NAME.<to>.exr        the converted map (EnvMap.convert: envconvert IN -o OUT --to ...)
  NAME.envtbl          its sampling tables, baked from the input (Tables.bake: envbake IN -o OUT ...)
  NAME.prefiltered.ktx2 with --prefilter: the GGX mip chain (envkit.prefilter: envprefilter IN -o OUT)
  NAME.manifest.json   written last: the input's content hash, the options and the content hash of every output

A file whose manifest matches (same input hash, same options, every output present with its recorded hash) is
skipped; anything else (no manifest, another input or options, an output missing, truncated or changed) is
redone. Every output is written to a temporary file and renamed into place, and the manifest only after all
outputs, so a run killed at any point leaves either a complete, up-to-date set or one that the next run redoes.
A file that fails is reported with the one-line message the CLIs print and does not stop the others; the exit
status is 1 when any file failed.

Work runs on a dask.distributed Client: a LocalCluster of --workers processes by default, or the scheduler at
--scheduler (workers must see IN_DIR and OUT_DIR at the same paths). Tasks of a worker that dies are re-run on
the others (dask's allowed-failures, 3 by default).

Memory: each map's peak footprint on a worker is predicted from its header (envkit/_memory.py, docs/PYTHON.md).
A map predicted over --memory-limit (per worker; default: the largest map's prediction with a quarter more, at most
the machine's memory over the workers) is refused with one line and not read. A LocalCluster's workers get that
limit as dask's memory limit and as a dask resource that each task claims its prediction of, so the maps running
at once on a worker (--threads-per-worker) fit in it.
"""

import argparse
import fnmatch
import glob
import json
import os
import sys
import time

from . import _memory, _progress
from ._cluster import OutputError, UsageError, client_for, completed, count, worker_peaks, write_json_atomic
from ._cluster import Parser as _ClusterParser
from ._cluster import add_cluster_options
from ._cluster import check_out_dir as _check_out_dir

EXTENSIONS = (".exr", ".hdr", ".pfm", ".tif", ".tiff", ".png", ".jpg", ".jpeg")
MANIFEST_VERSION = 1


def _envkit():
    import envkit  # imported on the worker

    return envkit


def _convert(envkit, env, options, out_dir, stem):
    path = os.path.join(out_dir, "%s.%s.exr" % (stem, options["to"]))
    out = env.convert(
        options["to"],
        size=options["size"],
        filter=options["filter"],
        convention=options["convention"],
        rotate=options["rotate"],
    )
    out.write(path, half=options["half"], compression=options["compression"])
    return path


def _bake(envkit, env, options, out_dir, stem):
    path = os.path.join(out_dir, "%s.envtbl" % stem)
    tables = envkit.bake(
        env,
        importance=options["importance"],
        grid=options["bake_grid"],
        size=options["bake_size"],
        tables=options["tables"],
    )
    tables.save(path)
    return path


def _prefilter(envkit, env, options, out_dir, stem):
    # One KTX2 file holds the whole chain, so the manifest hashes a single output (an .exr chain is a file per
    # level). The chain's write is atomic.
    path = os.path.join(out_dir, "%s.prefiltered.ktx2" % stem)
    envkit.prefilter(env, **options["prefilter_options"]).write(path)
    return path


def prefilter_available():
    """Whether this envkit has a prefilter step (envkit.prefilter(map, **options) -> PrefilteredChain)."""
    try:
        return hasattr(_envkit(), "prefilter")
    except ImportError:
        return False


# The steps applied to every input, in order: name -> (enabled(options), run(envkit, map, options, out_dir, stem)
# -> output path). A new step (prefiltering, SH, ...) is one entry here and one option.
STEPS = {
    "convert": (lambda o: o["convert"], _convert),
    "bake": (lambda o: o["bake"], _bake),
    "prefilter": (lambda o: o["prefilter"], _prefilter),
}


def content_hash(path):
    """XXH3-128 of the file's bytes (what envbake records as the source hash)."""
    return _envkit().file_content_hash(path)


_write_json_atomic = write_json_atomic


def manifest_path(out_dir, stem):
    return os.path.join(out_dir, "%s.manifest.json" % stem)


def up_to_date(manifest_file, input_hash, options):
    """True when the manifest records this input and these options and every output still has its hash."""
    try:
        with open(manifest_file) as f:
            m = json.load(f)
    except (OSError, ValueError):
        return False
    if m.get("version") != MANIFEST_VERSION or m.get("input_hash") != input_hash or m.get("options") != options:
        return False
    outputs = m.get("outputs")
    if not isinstance(outputs, dict) or not outputs:
        return False
    for path, h in outputs.items():
        if not os.path.isfile(path):
            return False
        try:
            if content_hash(path) != h:
                return False
        except Exception:
            return False
    return True


def _remove_stale_temps(out_dir, stem):
    # Temporary files of a writer that was killed (atomic_file.h names them .<name>.tmp-<pid>-<n><ext>).
    for t in glob.glob(os.path.join(out_dir, ".%s.*tmp-*" % glob.escape(stem))):
        try:
            os.unlink(t)
        except OSError:
            pass


def process_file(input_path, out_dir, options, refusal=None):
    """Converts/bakes one input (runs on a worker). Returns a dict: input, status (done | skipped | failed),
    outputs, error (the one-line message), seconds. With `refusal` (a message), an input that is not up to date
    fails with it, unread."""
    start = time.monotonic()
    stem = os.path.splitext(os.path.basename(input_path))[0]
    result = {"input": input_path, "status": "failed", "outputs": [], "error": "", "seconds": 0.0}
    try:
        envkit = _envkit()
        input_hash = content_hash(input_path)
        manifest = manifest_path(out_dir, stem)
        if not options["force"] and up_to_date(manifest, input_hash, _recorded(options)):
            with open(manifest) as f:
                result["outputs"] = sorted(json.load(f)["outputs"])
            result["status"] = "skipped"
            return result
        if refusal:
            result["error"] = refusal
            return result
        # An outdated manifest must not vouch for outputs while they are being replaced.
        try:
            os.unlink(manifest)
        except FileNotFoundError:
            pass
        _remove_stale_temps(out_dir, stem)
        env = envkit.EnvMap(input_path, parameterization=options["from"], convention=options["from_convention"])
        outputs = {}
        for name, (enabled, run) in STEPS.items():
            if enabled(options):
                path = run(envkit, env, options, out_dir, stem)  # the step's result is released on return
                outputs[path] = content_hash(path)
        env = None  # the map is released before the worker takes its next file
        _write_json_atomic(
            manifest,
            {
                "version": MANIFEST_VERSION,
                "input": input_path,
                "input_hash": input_hash,
                "options": _recorded(options),
                "outputs": outputs,
            },
        )
        result["outputs"] = sorted(outputs)
        result["status"] = "done"
    except Exception as e:  # one file's failure is reported, not fatal
        result["error"] = str(e) if str(e) else type(e).__name__
    finally:
        result["seconds"] = time.monotonic() - start
    return result


def _recorded(options):
    """The options that decide the outputs' content (what a manifest must match)."""
    return {k: v for k, v in options.items() if k not in ("force",)}


def output_names(stem, to):
    """File names of every output a run converting to `to` can write for an input named STEM.EXT (with or without
    the optional steps)."""
    return ["%s.%s.exr" % (stem, to), "%s.manifest.json" % stem, "%s.envtbl" % stem, "%s.prefiltered.ktx2" % stem]


def _recorded_outputs(out_dir):
    """Real paths of every output recorded by the manifests in out_dir."""
    recorded = set()
    for m in glob.glob(os.path.join(glob.escape(out_dir), "*.manifest.json")):
        try:
            with open(m) as f:
                outputs = json.load(f).get("outputs", {})
        except (OSError, ValueError, AttributeError):
            continue
        if isinstance(outputs, dict):
            recorded.update(os.path.realpath(p) for p in outputs)
    return recorded


def find_inputs(in_dir, patterns=None, out_dir=None, to="latlong"):
    """The input maps of in_dir (not its subfolders, so an out_dir inside in_dir is never read): files with a map
    extension, or matching `patterns`. With out_dir, outputs of a batch are never inputs, also when out_dir is
    in_dir: files recorded by a manifest of out_dir (earlier runs, any options), and, when out_dir is in_dir, files
    named as this run's outputs of another input (STEM.<to>.exr, STEM.envtbl, ...: a run killed before its
    manifest)."""
    names = sorted(os.listdir(in_dir))
    candidates = []
    for n in names:
        p = os.path.join(in_dir, n)
        if n.startswith(".") or not os.path.isfile(p):
            continue
        if patterns:
            if any(fnmatch.fnmatch(n, pat) for pat in patterns):
                candidates.append(p)
        elif os.path.splitext(n)[1].lower() in EXTENSIONS:
            candidates.append(p)
    if out_dir is None or not os.path.isdir(out_dir):
        return candidates
    recorded = _recorded_outputs(out_dir)
    same_dir = os.path.realpath(in_dir) == os.path.realpath(out_dir)
    stems = {os.path.splitext(os.path.basename(p))[0] for p in candidates}
    outputs = {n for stem in stems for n in output_names(stem, to)} if same_dir else set()
    return [p for p in candidates if os.path.realpath(p) not in recorded and os.path.basename(p) not in outputs]


def default_options(**overrides):
    o = {
        "convert": True,
        "to": "latlong",
        "size": 0,
        "filter": "area",
        "convention": None,
        "rotate": None,
        "half": False,
        "compression": "",
        "from": None,
        "from_convention": None,
        "bake": True,
        "importance": "luminance",
        "bake_grid": "latlong",
        "bake_size": 0,
        "tables": ["hierarchical"],  # envbake's default
        "prefilter": False,
        "prefilter_options": {},
        "force": False,
    }
    unknown = set(overrides) - set(o)
    if unknown:
        raise ValueError("unknown batch options: %s" % ", ".join(sorted(unknown)))
    o.update(overrides)
    return o


def predict(inputs, options):
    """Per input, its predicted peak memory on a worker in bytes (None when its header cannot be read)."""
    predicted = {}
    for p in inputs:
        found = _memory.header(p)
        predicted[p] = _memory.predicted_peak(found[0], found[1], options) if found else None
    return predicted


def refusal(input_path, predicted, memory_limit):
    """The one-line message refusing a map predicted over the limit, or None."""
    if memory_limit is None or predicted is None or predicted <= memory_limit:
        return None
    texels, channels = _memory.header(input_path)
    return "%s: needs about %s of memory (%d texels x %d channels), more than --memory-limit %s per worker" % (
        input_path, _memory.format_bytes(predicted), texels, channels, _memory.format_bytes(memory_limit))


def run(inputs, out_dir, client, options, progress=None, memory_limit=None, claim_memory=False, predicted=None):
    """Maps process_file over `inputs` on `client`; returns the results in input order, each with its predicted
    peak memory (predicted_bytes). A task whose workers all died (dask's KilledWorker) or that raised is reported
    as failed, never raised. Maps predicted over `memory_limit` (bytes) fail with one line, unread. With
    claim_memory, each task claims its prediction of the workers' "memory" resource (a map of unknown size claims
    all of memory_limit); the largest maps start first. `predicted`: predict(inputs, options), when known."""
    os.makedirs(out_dir, exist_ok=True)
    out_dir = os.path.abspath(out_dir)
    inputs = [os.path.abspath(p) for p in inputs]
    predicted = {os.path.abspath(p): v for p, v in (predicted or predict(inputs, options)).items()}
    order = sorted(range(len(inputs)), key=lambda i: -(predicted[inputs[i]] or 0))
    futures = []
    for i in order:
        p = inputs[i]
        refused = refusal(p, predicted[p], memory_limit)
        claim = 0 if refused else (predicted[p] or memory_limit or 0)
        resources = {"memory": claim} if claim_memory else None
        futures.append(client.submit(process_file, p, out_dir, options, refused, pure=False, resources=resources))
    results = [None] * len(inputs)
    for k, r, e in completed(futures):
        i = order[k]
        if e is not None:
            r = {"input": inputs[i], "status": "failed", "outputs": [], "error": "%s: %s" % (type(e).__name__, e),
                 "seconds": 0.0}
        r["predicted_bytes"] = predicted[inputs[i]]
        results[i] = r
        if progress:
            progress(r)
    return results


def _Parser(**kwargs):
    """argparse with one-line usage errors: "envkit.batch: <message> (see --help)", exit status 2."""
    return _ClusterParser(label="envkit.batch", **kwargs)


_count = count


def _memory_size(text):
    """An argparse type: a memory size of at least a worker's base footprint."""
    try:
        v = _memory.parse_bytes(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    if v < _memory.BASE_BYTES:
        raise argparse.ArgumentTypeError("%s is less than a worker's own %s" % (
            text, _memory.format_bytes(_memory.BASE_BYTES)))
    return v


def check_out_dir(out_dir):
    """Refuses, before any work, an OUT_DIR that is not a folder (UsageError) or cannot be created or written
    (OutputError), each with a one-line message."""
    _check_out_dir(out_dir, "OUT_DIR")


def _parse_args(argv):
    p = _Parser(
        prog="python3 -m envkit.batch",
        description="Converts and bakes every environment map of a folder on a dask.distributed cluster.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="""Examples:
  python3 -m envkit.batch hdris/ out/ --workers 2
  python3 -m envkit.batch hdris/ out/ --to cube --size 512 --convention openexr --no-bake
  python3 -m envkit.batch /shared/hdris /shared/out --scheduler tcp://10.0.0.5:8786

A re-run skips inputs whose outputs are up to date (manifest: input content hash, options, output hashes)
and redoes the rest. A map whose predicted memory (docs/PYTHON.md) exceeds --memory-limit is refused.
Exit status: 0 all done or skipped; 1 some file failed; 2 usage error.""",
    )
    p.add_argument("in_dir", metavar="IN_DIR")
    p.add_argument("out_dir", metavar="OUT_DIR")
    add_cluster_options(p, "dask threads per LocalCluster worker (each file still uses oneTBB inside)")
    p.add_argument("--pattern", action="append", metavar="GLOB",
                   help="input file names to take (default: .exr .hdr .pfm .tif .png .jpg)")
    p.add_argument("--to", default="latlong", metavar="KIND", help="output parameterization (default latlong)")
    p.add_argument("--size", type=_count(0, 1 << 18), default=0, metavar="N", help="natural size N (default: the input's density)")
    p.add_argument("--filter", default="area", help="resampling filter (default area)")
    p.add_argument("--convention", metavar="C", help="output convention (default: the input's)")
    p.add_argument("--rotate", metavar="R", help="yaw,pitch,roll in degrees or 9 matrix entries")
    p.add_argument("--half", action="store_true", help="half-float OpenEXR outputs")
    p.add_argument("--compression", default="", metavar="C", help="OpenEXR compression (default zip)")
    p.add_argument("--from", dest="from_", metavar="KIND", help="input parameterization (default: detected)")
    p.add_argument("--from-convention", metavar="C", help="input convention (default: from metadata)")
    p.add_argument("--no-convert", action="store_true", help="do not write converted maps")
    p.add_argument("--no-bake", action="store_true", help="do not bake tables")
    p.add_argument("--importance", default="luminance", help="luminance, average or max")
    p.add_argument("--bake-grid", default="latlong", help="latlong, octahedral or healpix")
    p.add_argument("--bake-size", type=_count(0, 1 << 18), default=0, metavar="N", help="bake grid size N (default natural)")
    p.add_argument("--tables", default="hierarchical", help="any of cdf,alias,hierarchical,compensated,sun (default: as envbake)")
    p.add_argument("--prefilter", action="store_true", help="also prefilter (when this envkit has the step)")
    p.add_argument("--force", action="store_true", help="redo every file, up to date or not")
    p.add_argument("--memory-limit", type=_memory_size, metavar="SIZE",
                   help="memory per worker, e.g. 6GB (default: the largest map's predicted peak + 25%%, at most "
                        "the machine's memory / workers); maps predicted over it are refused")
    p.add_argument("--report", "--json", metavar="FILE",
                   help="write a JSON report: every file with its status, the counts, the workers' peak memory")
    p.add_argument("-q", "--quiet", action="store_true", help="print only failures and the summary")
    a = p.parse_args(argv)
    if a.prefilter and not prefilter_available():
        p.error("--prefilter: this envkit has no prefilter step yet")
    if a.no_convert and a.no_bake and not a.prefilter:
        p.error("nothing to do: --no-convert and --no-bake")
    if not os.path.isdir(a.in_dir):
        p.error("IN_DIR %s: not a directory" % a.in_dir)
    try:
        check_out_dir(a.out_dir)
    except UsageError as e:
        p.error(str(e))
    return a


def main(argv=None):
    try:
        a = _parse_args(sys.argv[1:] if argv is None else argv)
    except OutputError as e:
        print("envkit.batch: %s" % e, file=sys.stderr)
        return 1
    options = default_options(
        convert=not a.no_convert, to=a.to, size=a.size, filter=a.filter, convention=a.convention, rotate=a.rotate,
        half=a.half, compression=a.compression, bake=not a.no_bake, importance=a.importance,
        bake_grid=a.bake_grid, bake_size=a.bake_size, tables=[t for t in a.tables.split(",") if t],
        prefilter=a.prefilter, force=a.force, **{"from": a.from_, "from_convention": a.from_convention})
    inputs = find_inputs(a.in_dir, a.pattern, a.out_dir, a.to)
    if not inputs:
        print("envkit.batch: %s: no input maps" % a.in_dir, file=sys.stderr)
        return 1
    predicted = predict(inputs, options)
    limit = a.memory_limit
    if limit is None and not a.scheduler:
        limit = _memory.default_limit(predicted.values(), a.workers)
    progress = _progress.Progress(len(inputs), quiet=a.quiet)
    resources = {"memory": limit} if not a.scheduler else None
    with client_for(a.scheduler, a.workers, a.threads_per_worker, memory_limit=limit, resources=resources) as client:
        if limit is None:  # a running scheduler: its workers' smallest dask memory limit, if they have one
            limit = min((w.get("memory_limit") or 0 for w in client.scheduler_info()["workers"].values()),
                        default=0) or None
        results = run(inputs, a.out_dir, client, options, progress, memory_limit=limit,
                      claim_memory=resources is not None, predicted=predicted)
        peaks = worker_peaks(client)
    seconds = progress.elapsed()
    for line in _progress.summary(results, seconds, peaks, limit):
        print(line)
    if a.report:
        _progress.write_report(a.report, results, seconds, peaks, limit)
    return 1 if any(r["status"] == "failed" for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
