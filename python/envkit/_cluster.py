"""What envkit's dask.distributed runners (envkit.batch, envkit.farm) share: one-line usage errors, checked counts,
atomic files, output folder checks, the client (a LocalCluster or a running scheduler) and the loop over finished
tasks."""

import argparse
import contextlib
import json
import os
import sys
import tempfile
import warnings


class Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors: "<label>: <message> (see --help)", exit status 2 (label: the module,
    e.g. envkit.batch)."""

    def __init__(self, *args, label, **kwargs):
        super().__init__(*args, **kwargs)
        self.label = label

    def error(self, message):
        sys.stderr.write("%s: %s (see --help)\n" % (self.label, message))
        sys.exit(2)


def count(lo, hi):
    """An argparse type: an integer in [lo, hi], refused with the range otherwise."""

    def parse(text):
        try:
            v = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError("'%s' is not an integer" % text) from None
        if not lo <= v <= hi:
            raise argparse.ArgumentTypeError("%d is outside [%d, %d]" % (v, lo, hi))
        return v

    parse.__name__ = "integer"
    return parse


class UsageError(Exception):
    """A problem with the command line found after parsing (exit status 2)."""


class OutputError(Exception):
    """An output folder cannot be created or written (exit status 1)."""


def write_atomic(path, write, mode="wb", durable=True):
    """Calls write(f) on a temporary file next to `path`, flushes it (to disk when durable) and renames it to `path`:
    a reader (or a process killed at any point) sees the old file or the complete new one, never a part. Without
    durable, a crash of the machine may leave an empty or partial file: for files whose content is checked when
    read (a hash recorded elsewhere). The temporary file has the permissions of a new file (mkstemp's 0600 would
    hide it from other users)."""
    d = os.path.dirname(path) or "."
    fd, tmp = tempfile.mkstemp(prefix="." + os.path.basename(path) + ".tmp-", dir=d)
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        with os.fdopen(fd, mode) as f:
            write(f)
            f.flush()
            if durable:
                os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def write_json_atomic(path, data, durable=True):
    write_atomic(path, lambda f: json.dump(data, f, indent=1, sort_keys=True), mode="w", durable=durable)


def check_out_dirs(folders):
    """check_out_dir of every (folder, what) pair; a path that is not a folder is refused before any folder is
    made."""
    for out_dir, what in folders:
        _refuse_non_directory(out_dir, what)
    for out_dir, what in folders:
        check_out_dir(out_dir, what)


def _refuse_non_directory(out_dir, what):
    if os.path.exists(out_dir) and not os.path.isdir(out_dir):
        raise UsageError("%s %s: exists and is not a directory" % (what, out_dir))


def check_out_dir(out_dir, what="OUT_DIR"):
    """Refuses, before any work, an output folder that is not a folder (UsageError) or cannot be created or written
    (OutputError), each with a one-line message naming it as `what`."""
    _refuse_non_directory(out_dir, what)
    try:
        os.makedirs(out_dir, exist_ok=True)
        # A probe file: permissions alone do not tell (root ignores them, a read-only mount does not show).
        fd, probe = tempfile.mkstemp(prefix=".envkit-probe-", dir=out_dir)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise OutputError("%s %s: cannot write: %s" % (what, out_dir, e.strerror or e)) from None


def add_cluster_options(parser, threads_help="dask threads per LocalCluster worker"):
    """--scheduler ADDR | --workers N, and --threads-per-worker T."""
    g = parser.add_mutually_exclusive_group()
    g.add_argument("--scheduler", metavar="ADDR", help="address of a running dask scheduler")
    g.add_argument("--workers", type=count(1, 1024), default=2, metavar="N",
                   help="LocalCluster worker processes, 1 to 1024 (default 2)")
    parser.add_argument("--threads-per-worker", type=count(1, 1024), default=1, metavar="T", help=threads_help)


@contextlib.contextmanager
def client_for(scheduler=None, workers=2, threads_per_worker=1, memory_limit=None, resources=None):
    """A dask.distributed Client of the scheduler at `scheduler`, or of a LocalCluster of `workers` processes
    (closed on exit). Tasks of a worker that dies are re-run on the others (the scheduler's allowed-failures).
    A LocalCluster's workers get `resources` (dask worker resources) and, with `memory_limit` (bytes per worker),
    dask's limit: a worker is restarted only when its memory passes the limit itself, and never paused or spilled
    (tasks hold no data to spill, and a pause would wait on memory the running task owns)."""
    import dask
    from distributed import Client, LocalCluster

    if scheduler:
        cluster = None
        client = Client(scheduler)
    else:
        memory = {"distributed.worker.memory.target": False, "distributed.worker.memory.spill": False,
                  "distributed.worker.memory.pause": False, "distributed.worker.memory.terminate": 1.0}
        with dask.config.set(memory if memory_limit else {}), warnings.catch_warnings():
            # The scheduler's HTTP server takes another port when 8787 is taken (another cluster): no news.
            warnings.filterwarnings("ignore", message="Port 8787 is already in use")
            cluster = LocalCluster(n_workers=workers, threads_per_worker=threads_per_worker, processes=True,
                                   dashboard_address=None, memory_limit=memory_limit or "auto", resources=resources)
        client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def peak_rss():
    """This process's peak resident memory in bytes (VmHWM: since its exec; ru_maxrss where /proc is missing)."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def worker_peaks(client):
    """Peak resident memory of every worker process of `client`, in bytes, by worker address."""
    return client.run(peak_rss)


def completed(futures):
    """Yields (index in futures, result, exception) as the futures finish; exception is None, or what the task
    raised, or dask's KilledWorker when every worker that ran it died: never raised."""
    from distributed import as_completed

    index = {f.key: i for i, f in enumerate(futures)}
    for future in as_completed(futures):
        try:
            yield index[future.key], future.result(), None
        except Exception as e:
            yield index[future.key], None, e
