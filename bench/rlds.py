"""Reading RLDS: a chunkc build against the independent reader alone, and chunkc's peak RSS
against the number of episodes (issue 20; a note, not a test; results in book/src/rlds.md).

    .venv/bin/python bench/rlds.py [--episodes 250 500 1000 2000] [--steps 100] [--cameras 2]
                                   [--resolution 128x128] [--work /tmp/chunkc-bench-rlds]
                                   [--out bench/results-rlds.json]

For each episode count, `chunkc synth --format rlds` writes a TFDS/RLDS set (64 episodes a
shard, JPEG cameras at quality 95), then it times

- `reader_parse`: the `tfrecord` package's framing and `tf.train.Example` parsing of every
  record, one process (what the tests use as the independent reader), no image decoded;
- `reader_decode`: the same, plus every JPEG decoded to an (H, W, 3) uint8 array with Pillow
  (libjpeg-turbo): the floor for reading the set in Python with one process;
- `chunkc_j1`, `chunkc_j2`: `chunkc build` of the synth spec's `act` profile (HDF5, frames
  uncompressed; every frame decoded with TensorFlow's DCT settings, windows, statistics,
  written), with its peak RSS (getrusage of the child) and its "read episodes" phase
  (CHUNKC_TIMINGS: read, decode, check, statistics partials, frames written).
"""

import argparse
import io
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image
from tfrecord import example_pb2
from tfrecord.reader import tfrecord_iterator

REPO = Path(__file__).resolve().parent.parent
BIN = os.environ.get("CHUNKC_BIN", str(REPO / "target" / "release" / "chunkc"))


def run(cmd, env=None):
    """Wall seconds and the peak RSS (MB) of `cmd`, run in a fresh Python parent so that
    RUSAGE_CHILDREN is this command's alone."""
    measure = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]).returncode; "
               "print('peak_rss_kb', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
               "sys.exit(r)")
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", measure, *map(str, cmd)], capture_output=True, text=True, env=env)
    wall = time.perf_counter() - t0
    if p.returncode:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed:\n{p.stderr[-3000:]}")
    rss = int(next(l for l in p.stderr.splitlines() if l.startswith("peak_rss_kb")).split()[1])
    read = next((l.split(None, 3)[3].strip() for l in p.stderr.splitlines() if "read episodes" in l), "")
    return wall, rss / 1024, read


def read_all(version: Path, decode: bool):
    """Every record of every train shard; with `decode`, every camera frame decoded too."""
    steps = frames = 0
    t0 = time.perf_counter()
    for shard in sorted(version.glob("*.tfrecord-*")):
        for record in tfrecord_iterator(str(shard)):
            ex = example_pb2.Example()
            ex.ParseFromString(record)
            f = ex.features.feature
            steps += len(f["steps/is_first"].int64_list.value)
            for key in f:
                if key.startswith("steps/observation/cam"):
                    if decode:
                        for jpeg in f[key].bytes_list.value:
                            np.asarray(Image.open(io.BytesIO(jpeg)).convert("RGB"))
                    frames += len(f[key].bytes_list.value)
    return time.perf_counter() - t0, steps, frames


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, nargs="+", default=[250, 500, 1000, 2000])
    ap.add_argument("--steps", type=int, default=100)
    ap.add_argument("--cameras", type=int, default=2)
    ap.add_argument("--resolution", default="128x128")
    ap.add_argument("--work", type=Path, default=Path("/tmp/chunkc-bench-rlds"))
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results-rlds.json")
    args = ap.parse_args()
    work = args.work.resolve()
    results = {"steps": args.steps, "cameras": args.cameras, "resolution": args.resolution,
               "cpus": os.cpu_count(), "load_before": os.getloadavg(), "sets": []}
    for n in args.episodes:
        src = work / f"rlds-{n}x{args.steps}-c{args.cameras}-{args.resolution}"
        if not (src / "spec.toml").exists():
            shutil.rmtree(src, ignore_errors=True)
            _ = run([BIN, "synth", src, "--format", "rlds", "--episodes", n, "--steps", args.steps,
                 "--cameras", args.cameras, "--resolution", args.resolution, "--seed", "0"])
        version = src / "rlds" / "1.0.0"
        text = (src / "spec.toml").read_text()
        spec = src / "bench.toml"
        spec.write_text(text.replace('dir = "out"', 'dir = "bench-out"'))
        row = {"episodes": n, "source_bytes": sum(p.stat().st_size for p in version.iterdir())}
        wall, steps, frames = read_all(version, decode=False)
        row["reader_parse"] = {"wall_s": wall, "steps_per_s": steps / wall}
        wall, _, _ = read_all(version, decode=True)
        row["reader_decode"] = {"wall_s": wall, "steps_per_s": steps / wall, "frames_per_s": frames / wall}
        row["steps"], row["frames"] = steps, frames
        for j in (1, 2):
            shutil.rmtree(src / "bench-out", ignore_errors=True)
            (src / "chunkc.lock").unlink(missing_ok=True)
            wall, rss, read = run([BIN, "-j", j, "build", "-q", spec], env={**os.environ, "CHUNKC_TIMINGS": "1"})
            row[f"chunkc_j{j}"] = {"wall_s": wall, "steps_per_s": steps / wall, "peak_rss_mb": rss,
                                   "read_episodes": read}
        row["output_bytes"] = sum(p.stat().st_size for p in (src / "bench-out").rglob("*") if p.is_file())
        shutil.rmtree(src / "bench-out", ignore_errors=True)
        print(f"{n} episodes, {steps} steps, {frames} frames: "
              f"reader parse {row['reader_parse']['wall_s']:.1f} s, +decode {row['reader_decode']['wall_s']:.1f} s; "
              f"chunkc -j1 {row['chunkc_j1']['wall_s']:.1f} s ({row['chunkc_j1']['peak_rss_mb']:.0f} MB; "
              f"read {row['chunkc_j1']['read_episodes']}), "
              f"-j2 {row['chunkc_j2']['wall_s']:.1f} s ({row['chunkc_j2']['peak_rss_mb']:.0f} MB; "
              f"read {row['chunkc_j2']['read_episodes']})", flush=True)
        results["sets"].append(row)
        args.out.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
