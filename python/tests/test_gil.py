"""Long calls release the GIL: Python code in another thread runs while they work."""
import threading
import time

import numpy as np

import envkit


def test_convert_releases_the_gil(probe_dir):
    m = envkit.EnvMap(str(probe_dir / "sky.exr"))
    window = {}

    def work():
        window["start"] = time.perf_counter()
        for _ in range(4):
            m.convert("cube", size=256, filter="area")
        window["end"] = time.perf_counter()

    ticks = []
    t = threading.Thread(target=work)
    t.start()
    while t.is_alive():
        ticks.append(time.perf_counter())
        time.sleep(0.001)
    t.join()
    inside = [x for x in ticks if window["start"] < x < window["end"]]
    # With the GIL held the main thread could not run at all during the conversions.
    assert window["end"] - window["start"] > 0.05
    assert len(inside) >= 10


def test_two_threads_overlap(probe_dir):
    t = envkit.bake(envkit.EnvMap(str(probe_dir / "sky.exr")))
    u = np.random.default_rng(0).random((3_000_000, 2))
    spans = []

    def work():
        s = time.perf_counter()
        t.sample(u)
        spans.append((s, time.perf_counter()))

    threads = [threading.Thread(target=work) for _ in range(2)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    (a0, a1), (b0, b1) = sorted(spans)
    assert b0 < a1  # the second call started before the first ended


def test_prefilter_releases_the_gil(probe_dir):
    m = envkit.EnvMap(str(probe_dir / "sky.exr"))
    windows = []

    def work():
        # As many calls as take 0.2 s, each timed apart: a tick inside a call's own window proves that call let
        # the main thread run (between calls it always can).
        first = time.perf_counter()
        while not windows or windows[-1][1] - first < 0.2:
            start = time.perf_counter()
            m.prefilter(size=64, accuracy=0.1)
            windows.append((start, time.perf_counter()))

    ticks = []
    t = threading.Thread(target=work)
    t.start()
    while t.is_alive():
        ticks.append(time.perf_counter())
        time.sleep(0.001)
    t.join()
    inside = [x for x in ticks if any(a < x < b for a, b in windows)]
    assert len(inside) >= 10
