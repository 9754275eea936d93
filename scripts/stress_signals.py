#!/usr/bin/env python3
"""Signals a multi-file envkit command at random moments and checks that its outputs are all-or-nothing.

Runs COMMAND once undisturbed (what "all" is, and how long it takes), then N times, each sent SIGTERM after a random
delay in [0, 1.2 x that time]. After each run the scratch directory must hold every output or none, and never a
.tmp- or .bak- file. This is the long form of the test InterruptedWrite.SignalsAtRandomMoments... (which makes
only a few trials per command): a race that shows once in hundreds of runs needs hundreds of runs.

    scripts/stress_signals.py --command info --runs 900
    scripts/stress_signals.py --command faces --runs 200 --bin build-asan/bin

Exit status 0 when no run failed, 1 otherwise. SIGTERM only: a shell's background jobs ignore SIGINT, and the
handler is the same for both.
"""
import argparse
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time

COMMANDS = {
    "info": lambda b, d: [f"{b}/envinfo", f"{d}/t.envtbl", "--export-exr", f"{d}/x"],
    "render": lambda b, d: [f"{b}/envrender", "--resolution", "64x36", "--spp", "2", "--bake", "-q", "-o", f"{d}/r.exr"],
    "faces": lambda b, d: [f"{b}/envconvert", f"{d}/in.exr", "-o", f"{d}/face_%.exr", "--to", "cube", "--size", "128",
                           "-q"],
    "probe": lambda b, d: [f"{b}/envprobe", "gradient", "-o", f"{d}/p.exr", "--preview", f"{d}/p.png", "--size",
                           "256x128"],
}


def run(args):
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--command", choices=sorted(COMMANDS), default="info", help="the multi-file output to try")
    parser.add_argument("--runs", type=int, default=300, help="signalled runs (default 300)")
    parser.add_argument("--bin", default=os.path.join(root, "build", "bin"), help="directory of the tools")
    parser.add_argument("--seed", type=int, default=1, help="seed of the delays (default 1)")
    opt = parser.parse_args()
    if opt.runs < 1:
        parser.error("--runs must be at least 1")
    if not os.path.isfile(os.path.join(opt.bin, "envinfo")):
        sys.exit(f"stress_signals.py: {opt.bin}: no envkit tools there (build first, or pass --bin)")

    work = tempfile.mkdtemp(prefix="envkit_stress_signals_")
    try:
        run([f"{opt.bin}/envprobe", "gradient", "-o", f"{work}/in.exr", "--size", "256x128", "-q"])
        run([f"{opt.bin}/envbake", f"{work}/in.exr", "-o", f"{work}/t.envtbl", "-q"])
        inputs = set(os.listdir(work))
        args = COMMANDS[opt.command](opt.bin, work)

        def outputs():
            return set(os.listdir(work)) - inputs

        def clear(names):
            for name in names:
                os.remove(os.path.join(work, name))

        start = time.monotonic()
        run(args)
        seconds = time.monotonic() - start
        everything = outputs()
        clear(everything)

        rng = random.Random(opt.seed)
        failed = interrupted = 0
        for trial in range(opt.runs):
            delay = rng.uniform(0.0, 1.2 * seconds)
            process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            time.sleep(delay)
            process.send_signal(signal.SIGTERM)
            status = process.wait()
            interrupted += status == -signal.SIGTERM
            produced = outputs()
            left = sorted(n for n in produced if ".tmp-" in n or ".bak-" in n)
            kept = produced - set(left)
            complete = kept == everything
            if left or (kept and not complete) or (status == 0 and not complete):
                failed += 1
                print(f"run {trial}: signal after {delay * 1000:.1f} ms, status {status}: "
                      f"{len(kept)} of {len(everything)} outputs, left {left}", flush=True)
            clear(produced)
        print(f"{opt.command}: {opt.runs} runs ({seconds * 1000:.0f} ms undisturbed), {interrupted} interrupted, "
              f"{failed} failed")
        return 1 if failed else 0
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
