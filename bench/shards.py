"""Sharded builds on a local Ray: 1 against 2 workers, and the merge's share of the build.

    .venv/bin/python bench/shards.py [--episodes 40] [--steps 300] [--cameras 2] [--shards 4]
                                     [--repeat 3] [--work /tmp/chunkc-bench-shards]
                                     [--out bench/results-shards.json]

On one synthetic ALOHA source with cameras (`chunkc synth --format aloha-hdf5`, JPEG-free raw
frames, one `act` profile in HDF5 with gzip-compressed frames):

- `single`: `chunkc -j 2 build` (the reference, and its bytes);
- `ray_1` and `ray_2`: `scripts/chunkc_ray.py --num-shards S --num-cpus 1|2` (one chunkc thread per
  shard), end to end: Ray's start, the shards, the merge;
- `shards_seq` and `merge`: the S shards run one after another with the CLI, then the merge alone,
  timed separately (the merge's share of a build without Ray's start-up).

Each is run `--repeat` times in interleaved rounds; medians are reported, every run kept. The
merged outputs are checked byte for byte against the single build's.
"""

import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
BIN = Path(os.environ.get("CHUNKC_BIN", REPO / "target" / "release" / "chunkc"))
DRIVER = REPO / "scripts" / "chunkc_ray.py"
PROFILE = '[profiles.act]\npreset = "act"\nfps = 50\nchunk = 100\nformat = "hdf5"\nimage_compression = "gzip"\n'


def hashes(root):
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def timed(cmd, env=None):
    cmd = [str(c) for c in cmd]
    t = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(map(str, cmd))} failed:\n{proc.stderr[-3000:]}")
    return time.perf_counter() - t


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=40)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--cameras", type=int, default=2)
    ap.add_argument("--shards", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--work", type=Path, default=Path("/tmp/chunkc-bench-shards"))
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results-shards.json")
    args = ap.parse_args()
    work = args.work.resolve()
    src = work / f"aloha-{args.episodes}x{args.steps}-c{args.cameras}"
    if not (src / "spec.toml").exists():
        shutil.rmtree(src, ignore_errors=True)
        work.mkdir(parents=True, exist_ok=True)
        timed([BIN, "synth", src, "--format", "aloha-hdf5", "--episodes", args.episodes,
               "--steps", args.steps, "--cameras", args.cameras, "--seed", "0"])
    text = (src / "spec.toml").read_text()
    base = text[: text.index("[profiles")] if "[profiles" in text else text
    spec = src / "bench.toml"
    spec.write_text(base.replace('dir = "out"', 'dir = "bench-out"') + PROFILE)
    out = src / "bench-out"
    parts = work / "partials"
    env = dict(os.environ, CHUNKC_BIN=str(BIN), RAY_USAGE_STATS_ENABLED="0")

    def clean():
        for d in (out, parts):
            shutil.rmtree(d, ignore_errors=True)
        (src / "chunkc.lock").unlink(missing_ok=True)

    clean()
    timed([BIN, "-j", "2", "build", "-q", spec])
    want = hashes(out)
    runs = {k: [] for k in ("single", "ray_1", "ray_2", "shards_seq", "merge")}
    for r in range(args.repeat):
        clean()
        runs["single"].append(timed([BIN, "-j", "2", "build", "-q", spec]))
        for cpus in (1, 2):
            clean()
            runs[f"ray_{cpus}"].append(timed(
                [sys.executable, DRIVER, spec, "--num-shards", args.shards, "--num-cpus", cpus,
                 "--partials", parts], env=env))
            assert hashes(out) == want, f"ray_{cpus}: outputs differ"
        clean()
        runs["shards_seq"].append(sum(
            timed([BIN, "-j", "1", "build", "-q", "--shard", f"{i}/{args.shards}", "--partials", parts, spec])
            for i in range(args.shards)))
        runs["merge"].append(timed([BIN, "-j", "2", "merge", "-q", "--partials", parts, spec]))
        assert hashes(out) == want, "merge: outputs differ"
        print(f"round {r + 1}: " + ", ".join(f"{k} {v[-1]:.2f} s" for k, v in runs.items()), file=sys.stderr)
    med = {k: statistics.median(v) for k, v in runs.items()}
    partial_bytes = sum(p.stat().st_size for p in parts.glob("*.partial"))
    res = {
        "source": {"episodes": args.episodes, "steps": args.steps, "cameras": args.cameras,
                   "resolution": "96x96", "format": "aloha-hdf5"},
        "shards": args.shards, "repeat": args.repeat, "cpus": os.cpu_count(),
        "load_before": os.getloadavg(), "median_s": med, "runs_s": runs,
        "ray_2_vs_1": med["ray_1"] / med["ray_2"],
        "merge_share_of_single": med["merge"] / med["single"],
        "merge_share_of_sharded": med["merge"] / (med["merge"] + med["shards_seq"]),
        "partial_bytes": partial_bytes,
        "output_bytes": sum(p.stat().st_size for p in out.rglob("*") if p.is_file()),
    }
    args.out.write_text(json.dumps(res, indent=2) + "\n")
    print(json.dumps({k: res[k] for k in ("median_s", "ray_2_vs_1", "merge_share_of_single",
                                          "merge_share_of_sharded", "partial_bytes", "output_bytes")},
                     indent=2))


if __name__ == "__main__":
    main()
