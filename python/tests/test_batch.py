"""envkit.batch on a LocalCluster of two workers: outputs equal the CLIs', failures are per file, a worker killed
mid-run loses nothing, re-runs skip up-to-date files and redo partial ones."""
import json
import os
import signal
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import envkit
from envkit import _memory as memory
from envkit import batch
from conftest import exr_array, run_tool

distributed = pytest.importorskip("distributed")

N_INPUTS = 5


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("batch_in")
    for k in range(N_INPUTS):
        run_tool("envprobe", "default", "-o", d / ("map%d.exr" % k), "--size", "384x192", "--seed", str(k),
                 "--elevation-deg", str(10 + 5 * k))
    (d / "broken.exr").write_bytes(b"\x76\x2f\x31\x01 truncated")
    return d


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def options():
    return batch.default_options(to="cube", size=64, tables=["cdf", "hierarchical"])


def check_complete(out, names):
    for n in names:
        m = json.load(open(os.path.join(out, n + ".manifest.json")))
        assert set(m["outputs"]) == {os.path.join(out, n + ".cube.exr"), os.path.join(out, n + ".envtbl")}
        for path, h in m["outputs"].items():
            assert envkit.file_content_hash(path) == h


def test_batch_kill_rerun_and_partial(inputs, tmp_path, client):
    out = str(tmp_path / "out")
    files = batch.find_inputs(str(inputs))
    names = ["map%d" % k for k in range(N_INPUTS)]
    assert len(files) == N_INPUTS + 1

    # Kill one worker process (SIGKILL, no clean-up) as soon as the first file is finished.
    pids = client.run(os.getpid)
    killed = []

    def killer():
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            if any(n.endswith(".manifest.json") for n in os.listdir(out)) if os.path.isdir(out) else False:
                pid = sorted(pids.values())[0]
                os.kill(pid, signal.SIGKILL)
                killed.append(pid)
                return
            time.sleep(0.01)

    k = threading.Thread(target=killer)
    k.start()
    results = batch.run(files, out, client, options())
    k.join()
    assert killed, "the run ended before a worker could be killed"
    status = {os.path.basename(r["input"]): r for r in results}
    assert status["broken.exr"]["status"] == "failed"
    assert "broken.exr" in status["broken.exr"]["error"]
    # Nothing lost: every good file was finished by a surviving (or restarted) worker. A file whose task finished
    # on the killed worker after writing its manifest but before reporting is re-run and found up to date.
    assert all(status[n + ".exr"]["status"] in ("done", "skipped") for n in names), results
    check_complete(out, names)

    # The outputs are what the CLIs write.
    cli = tmp_path / "cli.exr"
    run_tool("envconvert", inputs / "map3.exr", "-o", cli, "--to", "cube", "--size", "64", "-q")
    assert np.array_equal(exr_array(os.path.join(out, "map3.cube.exr")), exr_array(cli))
    cli_t = tmp_path / "cli.envtbl"
    run_tool("envbake", inputs / "map3.exr", "-o", cli_t, "--tables", "cdf,hierarchical", "-q")
    u = np.random.default_rng(0).random((1000, 2))
    a, b = envkit.load(os.path.join(out, "map3.envtbl")), envkit.load(str(cli_t))
    assert a.source_hash == b.source_hash
    assert np.array_equal(a.sample(u)[0], b.sample(u)[0])

    # Re-run: everything up to date is skipped.
    again = batch.run(files, out, client, options())
    assert sorted(r["status"] for r in again) == ["failed"] + ["skipped"] * N_INPUTS

    # A truncated output, a missing one and a changed option are redone; the rest stays skipped.
    with open(os.path.join(out, "map1.envtbl"), "r+b") as f:
        f.truncate(100)
    os.unlink(os.path.join(out, "map2.cube.exr"))
    redo = {os.path.basename(r["input"]): r["status"] for r in batch.run(files, out, client, options())}
    assert redo["map1.exr"] == "done" and redo["map2.exr"] == "done"
    assert [redo["map%d.exr" % k] for k in (0, 3, 4)] == ["skipped"] * 3
    check_complete(out, names)
    changed = batch.default_options(to="cube", size=32, tables=["cdf", "hierarchical"])
    assert batch.run([os.path.join(str(inputs), "map0.exr")], out, client, changed)[0]["status"] == "done"


def test_command_line(inputs, tmp_path):
    out = tmp_path / "cli_out"
    cmd = [sys.executable, "-m", "envkit.batch", str(inputs), str(out), "--workers", "2", "--to", "octahedral",
           "--size", "32", "--no-bake", "--pattern", "map[01].exr", "--pattern", "broken.exr",
           "--json", str(tmp_path / "r.json")]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert p.returncode == 1, p.stderr  # one file failed, the others are done
    assert "2 done, 0 skipped, 1 failed" in p.stdout
    assert "broken.exr: " in p.stderr
    assert sorted(os.listdir(out)) == ["map0.manifest.json", "map0.octahedral.exr", "map1.manifest.json",
                                       "map1.octahedral.exr"]
    report = json.load(open(tmp_path / "r.json"))
    assert report["counts"] == {"done": 2, "skipped": 0, "failed": 1}
    assert sorted((os.path.basename(r["input"]), r["status"]) for r in report["results"]) == [
        ("broken.exr", "failed"), ("map0.exr", "done"), ("map1.exr", "done")]
    p = subprocess.run([sys.executable, "-m", "envkit.batch", str(inputs), str(out), "--no-convert", "--no-bake"],
                       capture_output=True, text=True, timeout=60)
    assert p.returncode == 2 and "nothing to do" in p.stderr


def test_prefilter_step_equals_envprefilter(inputs, tmp_path, client):
    src = str(inputs / "map0.exr")
    out = tmp_path / "out"
    opts = batch.default_options(convert=False, bake=False, prefilter=True, prefilter_options={"size": 8})
    r = batch.run([src], str(out), client, opts)
    assert r[0]["status"] == "done", r
    assert r[0]["outputs"] == [str(out / "map0.prefiltered.ktx2")]
    run_tool("envprefilter", src, "-o", tmp_path / "cli.ktx2", "--size", "8", "-q")
    assert open(out / "map0.prefiltered.ktx2", "rb").read() == open(tmp_path / "cli.ktx2", "rb").read()
    assert batch.prefilter_available()


def run_batch(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "envkit.batch", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def one_line_error(p, code, *words):
    """A usage or output error: exit `code`, exactly one line on stderr naming `words`, no traceback."""
    assert p.returncode == code, (p.returncode, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert lines[0].startswith("envkit.batch: ") and "Traceback" not in p.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.parametrize("option,value", [("--workers", "0"), ("--workers", "-3"), ("--workers", "1.5"),
                                          ("--threads-per-worker", "0"), ("--size", "-1"), ("--bake-size", "x"),
                                          ("--memory-limit", "lots"), ("--memory-limit", "0"),
                                          ("--memory-limit", "2XB"), ("--memory-limit", "1MB")])
def test_counts_are_checked_before_any_work(inputs, tmp_path, option, value):
    # --workers 0 used to start a cluster without workers and wait for ever.
    p = run_batch(inputs, tmp_path / "out", option, value, timeout=30)
    one_line_error(p, 2, option, value)
    assert not (tmp_path / "out").exists()


def test_output_folder_that_is_a_file(inputs, tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    one_line_error(run_batch(inputs, f, timeout=30), 2, str(f), "not a directory")
    assert f.read_text() == "x"


def test_output_folder_that_cannot_be_written(inputs, tmp_path):
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    one_line_error(run_batch(inputs, blocker / "out", timeout=30), 1, str(blocker / "out"), "cannot write")
    ro = tmp_path / "ro"
    ro.mkdir()
    os.chmod(ro, 0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("permission bits do not bind this user (root)")
        one_line_error(run_batch(inputs, ro, timeout=30), 1, str(ro), "cannot write")
        one_line_error(run_batch(inputs, ro / "out", timeout=30), 1, str(ro / "out"), "cannot write")
    finally:
        os.chmod(ro, 0o700)


@pytest.mark.parametrize("inside", [False, True], ids=["same folder", "folder inside"])
def test_outputs_are_never_inputs(tmp_path, inside):
    d = tmp_path / "maps"
    d.mkdir()
    run_tool("envprobe", "default", "-o", d / "sky.exr", "--size", "64x32")
    out = d / "out" if inside else d
    for status in ("1 done, 0 skipped, 0 failed", "0 done, 1 skipped, 0 failed"):
        p = run_batch(d, out, "--workers", "1", "--size", "8", "--no-bake")
        assert p.returncode == 0, p.stderr
        assert status in p.stdout, (p.stdout, p.stderr)
    assert sorted(n for n in os.listdir(out) if n != "out") == sorted(
        (["sky.exr"] if out == d else []) + ["sky.latlong.exr", "sky.manifest.json"])
    # A converted map whose manifest is gone (a run killed before writing it) is not an input either.
    os.unlink(out / "sky.manifest.json")
    assert batch.find_inputs(str(d), out_dir=str(out)) == [str(d / "sky.exr")]


def test_progress_summary_and_report(inputs, tmp_path):
    out, report = tmp_path / "out", tmp_path / "report.json"
    p = run_batch(inputs, out, "--workers", "2", "--to", "cube", "--size", "16", "--bake-size", "16", "--pattern",
                  "map[012].exr", "--pattern", "broken.exr", "--report", report)
    assert p.returncode == 1, p.stderr
    # A line per finished map: count, status, name, seconds, rate, and an ETA until the last.
    lines = [ln for ln in p.stderr.splitlines() if ln.startswith("envkit.batch: [")]
    assert [ln.split("]")[0] for ln in lines] == ["envkit.batch: [%d/4" % k for k in range(1, 5)], p.stderr
    done = [ln for ln in lines if "] done " in ln]
    assert len(done) == 3 and all(" s, " in ln and " maps/h" in ln for ln in done), lines
    assert all("ETA" in ln for ln in lines[:-1] if "] done " in ln) and "ETA" not in lines[-1]
    failed = [ln for ln in lines if "] failed " in ln]
    assert len(failed) == 1 and "broken.exr: " in failed[0]
    # The summary: counts, the workers' peak memory, each failed file with its reason.
    summary = p.stdout.splitlines()
    assert summary[0].startswith("envkit.batch: 3 done, 0 skipped, 1 failed in ") and "maps/h" in summary[0]
    assert summary[1].startswith("envkit.batch: peak memory per worker: ") and "limit" in summary[1]
    assert summary[2:] == ["envkit.batch: failed files:", "  " + failed[0].split("] failed ")[1]]
    r = json.load(open(report))
    status = {os.path.basename(x["input"]): x["status"] for x in r["results"]}
    assert status == {"map0.exr": "done", "map1.exr": "done", "map2.exr": "done", "broken.exr": "failed"}
    assert r["counts"] == {"done": 3, "skipped": 0, "failed": 1}
    # Every worker stayed under the stated bound (the default limit: the largest prediction + 25%).
    assert len(r["worker_peak_bytes"]) == 2
    assert all(0 < v <= r["memory_limit_bytes"] for v in r["worker_peak_bytes"].values()), r
    # A re-run skips; -q prints no progress lines.
    p = run_batch(inputs, out, "--workers", "1", "--to", "cube", "--size", "16", "--bake-size", "16", "--pattern",
                  "map[012].exr", "-q")
    assert p.returncode == 0 and p.stderr == "", p.stderr
    assert p.stdout.startswith("envkit.batch: 0 done, 3 skipped, 0 failed in ")


def exr_header_only(path, width, height, channels="BGR"):
    """An OpenEXR file with a scan-line header of width x height and no pixels: a map's size as a header states
    it."""
    def attr(name, kind, value):
        return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(value)) + value

    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", 2, 0, 1, 1) for c in channels) + b"\0"
    box = struct.pack("<4i", 0, 0, width - 1, height - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<I", 2) + attr("channels", "chlist", chlist)
              + attr("compression", "compression", b"\0") + attr("dataWindow", "box2i", box)
              + attr("displayWindow", "box2i", box) + attr("lineOrder", "lineOrder", b"\0")
              + attr("pixelAspectRatio", "float", struct.pack("<f", 1)) + b"\0")
    path.write_bytes(header + b"\0" * 64)


def test_memory_limit_refuses_a_map_predicted_too_big(inputs, tmp_path):
    d = tmp_path / "in"
    d.mkdir()
    exr_header_only(d / "huge.exr", 16384, 8192, "ABGR")
    assert memory.header(str(d / "huge.exr")) == (16384 * 8192, 4)
    os.symlink(inputs / "map0.exr", d / "map0.exr")
    p = run_batch(d, tmp_path / "out", "--workers", "1", "--memory-limit", "1GB", "--size", "16", "-q")
    assert p.returncode == 1
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert "huge.exr: needs about " in lines[0] and "more than --memory-limit 1.00 GB per worker" in lines[0]
    predicted = memory.predicted_peak(16384 * 8192, 4, batch.default_options(size=16))
    assert memory.format_bytes(predicted) in lines[0]
    assert "1 done, 0 skipped, 1 failed" in p.stdout
    assert sorted(os.listdir(tmp_path / "out")) == ["map0.envtbl", "map0.latlong.exr", "map0.manifest.json"]


def test_headers_give_texels_and_channels(inputs, tmp_path):
    m = envkit.EnvMap(str(inputs / "map0.exr"))
    assert memory.header(str(inputs / "map0.exr")) == (384 * 192, len(m.channels))
    for ext in (".hdr", ".pfm", ".png", ".tif"):
        path = str(tmp_path / ("map" + ext))
        run_tool("envconvert", inputs / "map0.exr", "-o", path, "--to", "cube", "--size", "8", "-q")
        texels, channels = memory.header(path)
        assert texels == 6 * 8 * 8 and channels in (3, 4), (ext, channels)
    assert memory.header(str(inputs / "broken.exr")) is None


def test_memory_sizes_and_default_limit():
    assert [memory.parse_bytes(t) for t in ("6GB", "6G", "6gib", "512MB", "1.5GB", "4096")] == [
        6 << 30, 6 << 30, 6 << 30, 512 << 20, 3 << 29, 4096]
    for bad in ("", "GB", "6 XB", "0", "0.0001KB", "-1GB", "1e9"):
        with pytest.raises(ValueError):
            memory.parse_bytes(bad)
    # The largest known prediction plus a quarter; an unknown one (None) does not count.
    assert memory.default_limit([400 << 20, None, 800 << 20], 2) == 1000 << 20
    # At most the machine's memory shared by the workers.
    assert memory.default_limit([1 << 50], 4) == distributed.system.MEMORY_LIMIT // 4


def overlapping(task_stream):
    """Whether any two process_file tasks of a dask task stream ran at the same time."""
    spans = sorted((s["start"], s["stop"]) for t in task_stream if t["key"].startswith("process_file")
                   for s in t["startstops"] if s["action"] == "compute")
    return any(b[0] < a[1] for a, b in zip(spans, spans[1:]))


def test_memory_claims_keep_a_worker_threads_within_its_limit(inputs, tmp_path):
    # One worker with 2 threads and a memory resource that holds one map's prediction and not two: the maps run
    # one after another; without the claims they run two at a time.
    files = [str(inputs / ("map%d.exr" % k)) for k in range(4)]
    opts = batch.default_options(to="cube", size=16, bake_size=16, force=True)
    one_map = max(batch.predict(files, opts).values())
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=True, dashboard_address=None,
                                       resources={"memory": one_map * 3 // 2})
    client = distributed.Client(cluster)
    try:
        for claim, expected in ((True, False), (False, True)):
            with distributed.get_task_stream(client) as ts:
                r = batch.run(files, str(tmp_path / ("out%d" % claim)), client, opts, memory_limit=one_map * 3 // 2,
                              claim_memory=claim)
            assert [x["status"] for x in r] == ["done"] * 4, r
            assert overlapping(ts.data) == expected, ts.data
    finally:
        client.close()
        cluster.close()
