"""envkit.farm: tiles rendered on a dask cluster merge into exactly the one-process render (image and AOVs), a killed
run resumes with only its missing tiles, frame sequences run as one job, bad options are refused before any
work."""
import json
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

import envkit
from conftest import exr_array, run_tool

distributed = pytest.importorskip("distributed")
if not envkit.has_renderer:
    pytest.skip("envkit built without the renderer", allow_module_level=True)

from envkit import farm  # noqa: E402

W, H, SPP, SEED = 40, 20, 4, 7


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def options(**kw):
    o = dict(spp=SPP, seed=SEED, width=W, height=H, threads=1)
    o.update(kw)
    return farm.default_options(**o)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """The default scene with its probe at 128x64 (loading the 1024x512 one costs seconds per process)."""
    s = json.loads(envkit._envkit._default_scene_json())
    s["environment"]["size"] = [128, 64]
    path = tmp_path_factory.mktemp("scene") / "small.json"
    path.write_text(json.dumps(s))
    return str(path)


@pytest.fixture(scope="module")
def reference(scene):
    """The film sums of the whole image rendered in one call, in this process."""
    frame = farm.frames([scene])[0]
    return farm._new_job(frame, options()).render((0, 0, W, H), SPP, SEED, 2)


def tile_paths(job):
    return [job.tile_path(0, t) for t in range(len(job.crops))]


def assert_same_sums(a, b):
    for k in ("sum", "sum_sq", "count"):
        assert a[k].shape == b[k].shape and a[k].dtype == b[k].dtype, k
        assert np.array_equal(a[k], b[k]), k


@pytest.mark.parametrize("tiling", [dict(tiles=1), dict(tiles=3), dict(tiles=7), dict(tile_size=(16, 7))],
                         ids=["1 tile", "3 bands", "7 uneven bands", "16x7 grid"])
def test_merge_is_bit_identical(client, scene, reference, tmp_path, tiling):
    out = str(tmp_path / "farm.exr")
    job = farm.Job(farm.frames([scene]), [out], options(), **tiling)
    if "tiles" in tiling and tiling["tiles"] == 7:
        assert len({y1 - y0 for _, y0, _, y1 in job.crops}) == 2  # really uneven
    r = farm.run(client, job, keep_work=True)
    assert len(r["rendered"]) == len(job.crops) and not r["resumed"]
    merged = farm.merge(tile_paths(job), job.crops, W, H)
    assert_same_sums(merged, reference)
    assert merged["count"].min() == SPP
    # The beauty part is the one-process mean image, to the bit.
    mean = envkit.render(scene, spp=SPP, seed=SEED, width=W, height=H)
    assert np.array_equal(exr_array(out), mean)
    # The whole file, AOV part included, is what the writer makes of the one-process film (same metadata).
    meta = {"envkit:scene": "test"}
    farm.write_film(str(tmp_path / "a.exr"), merged, meta, preview=False)
    farm.write_film(str(tmp_path / "b.exr"), reference, meta, preview=False)
    assert (tmp_path / "a.exr").read_bytes() == (tmp_path / "b.exr").read_bytes()
    assert os.path.isfile(str(tmp_path / "farm.png"))


def test_same_pixels_as_envrender(client, scene, tmp_path):
    out = str(tmp_path / "farm.exr")
    farm.run(client, farm.Job(farm.frames([scene]), [out], options(), tiles=3))
    run_tool("envrender", "--scene", scene, "-o", tmp_path / "envrender.exr", "--resolution", "%dx%d" % (W, H), "--spp", SPP,
             "--seed", SEED, "-q")
    assert np.array_equal(exr_array(out), exr_array(tmp_path / "envrender.exr"))
    assert not os.path.exists(out + ".farm")  # the work folder goes once the output is written


def test_resume_renders_only_missing_tiles(client, scene, reference, tmp_path):
    out = str(tmp_path / "farm.exr")
    job = farm.Job(farm.frames([scene]), [out], options(), tiles=5)
    farm.run(client, job, keep_work=True)
    paths = tile_paths(job)
    # A run killed part-way: two tiles never written, one truncated, the output not yet there.
    os.unlink(paths[1])
    os.unlink(paths[3])
    with open(paths[4], "r+b") as f:
        f.truncate(100)
    os.unlink(out)
    kept = {p: os.stat(p).st_mtime_ns for p in (paths[0], paths[2])}
    r = farm.run(client, job, keep_work=True)
    assert sorted(r["rendered"]) == sorted([paths[1], paths[3], paths[4]])
    assert sorted(r["resumed"]) == sorted(kept)
    assert all(os.stat(p).st_mtime_ns == t for p, t in kept.items())
    assert_same_sums(farm.merge(paths, job.crops, W, H), reference)
    assert np.array_equal(exr_array(out), envkit.render(scene, spp=SPP, seed=SEED, width=W, height=H))
    # Everything finished: a re-run renders nothing; other options (another job) render everything.
    assert farm.run(client, job, keep_work=True)["rendered"] == []
    other = farm.Job(farm.frames([scene]), [out], options(spp=SPP + 1), tiles=5)
    assert len(farm.run(client, other, keep_work=True)["rendered"]) == 5
    assert len(farm.run(client, other, force=True)["rendered"]) == 5
    assert not os.path.exists(job.work_dir)


def test_a_tile_that_fails_is_reported_and_nothing_is_written(client, scene, tmp_path):
    # The scene checked on the client, then gone before the workers load it.
    moved = tmp_path / "scene.json"
    moved.write_text(open(scene).read())
    out = tmp_path / "farm.exr"
    job = farm.Job(farm.frames([str(moved)]), [str(out)], options(spp=SPP + 2), tiles=2)
    moved.unlink()
    with pytest.raises(farm.FarmError, match="scene.json"):
        farm.run(client, job)
    assert not out.exists() and not (tmp_path / "farm.png").exists()


@pytest.fixture(scope="module")
def processes():
    """A LocalCluster of 2 worker processes (with nannies, which restart a worker that dies)."""
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    yield cluster
    cluster.close()


def test_a_worker_that_dies_has_its_tiles_rerun(processes, scene, reference, tmp_path):
    with distributed.Client(processes) as client:
        pids = sorted(client.run(os.getpid).values())
        job = farm.Job(farm.frames([scene]), [str(tmp_path / "farm.exr")], options(), tile_size=(4, 2))
        killed = []

        def progress(event):
            # SIGKILL (no clean-up) one worker process as soon as the first tile is in.
            if event["event"] == "tile" and not killed:
                os.kill(pids[0], signal.SIGKILL)
                killed.append(event["done"])

        r = farm.run(client, job, keep_work=True, progress=progress)
    assert killed and killed[0] < len(job.crops)
    assert sorted(r["rendered"]) == sorted(tile_paths(job))
    assert_same_sums(farm.merge(tile_paths(job), job.crops, W, H), reference)


def run_farm(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "envkit.farm", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout)


def test_rotation_sequence_on_the_command_line(processes, scene, tmp_path):
    out = tmp_path / "frames" / "turn.%02d.exr"
    p = run_farm(scene, "-o", out, "--rotations", "0,90", "--resolution", "%dx%d" % (W, H), "--spp", SPP, "--seed", SEED,
                 "--tiles", "2", "--scheduler", processes.scheduler_address)
    assert p.returncode == 0, p.stderr
    assert "[4/4]" in p.stderr and "wrote" in p.stderr
    frames = [exr_array(tmp_path / "frames" / ("turn.%02d.exr" % i)) for i in range(2)]
    assert (tmp_path / "frames" / "turn.01.png").is_file()
    assert sorted(os.listdir(tmp_path / "frames")) == ["turn.00.exr", "turn.00.png", "turn.01.exr", "turn.01.png"]
    s = json.loads(open(scene).read())
    yaw = s["environment"]["rotation"][0]
    for angle, image in zip((0, 90), frames):
        s["environment"]["rotation"][0] = yaw + angle
        assert np.array_equal(image, envkit.render(s, spp=SPP, seed=SEED, width=W, height=H))
    assert not np.array_equal(frames[0], frames[1])


def one_line_error(p, code, *words):
    assert p.returncode == code, (p.returncode, p.stderr)
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("envkit.farm: ") and "Traceback" not in p.stderr, p.stderr
    for w in words:
        assert w in lines[0], lines[0]


@pytest.mark.parametrize("args,code,words", [
    (["--spp", "0"], 2, ["--spp", "0"]),
    (["--tiles", "0"], 2, ["--tiles"]),
    (["--tiles", "50"], 2, ["--tiles", "50"]),
    (["--tile-size", "0x8"], 2, ["--tile-size", "0x8"]),
    (["--tiles", "2", "--tile-size", "8x8"], 2, ["--tile-size"]),
    (["--workers", "0"], 2, ["--workers"]),
    (["--rotations", "0,x"], 2, ["--rotations"]),
    (["--strategy", "nope"], 1, ["nope"]),
    (["--rotations", "0,90"], 2, ["integer field"]),
    (["missing.json"], 1, ["missing.json"]),
    (["broken.json"], 1, ["broken.json"]),
    (["--work", "broken.json"], 2, ["--work", "broken.json", "not a directory"]),
], ids=lambda v: " ".join(v) if isinstance(v, list) else str(v))
def test_bad_input_is_refused_before_any_work(scene, tmp_path, args, code, words):
    (tmp_path / "broken.json").write_text('{"camera": {"fov": }')
    out = tmp_path / "out" / "x.exr"
    args = [str(tmp_path / a) if a.endswith(".json") else a for a in args]
    if "--work" in args or not any(a.endswith(".json") for a in args):
        args.insert(0, scene)
    p = run_farm(*args, "-o", out, "--resolution", "%dx%d" % (W, H), "--spp" if "--spp" not in args else "--seed",
                 "1", timeout=60)
    one_line_error(p, code, *words)
    assert not (tmp_path / "out").exists()


def test_output_must_be_exr(tmp_path):
    one_line_error(run_farm("-o", tmp_path / "x.png", timeout=60), 2, "x.png", ".exr")
    assert os.listdir(tmp_path) == []
