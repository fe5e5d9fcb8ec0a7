"""Per-shard camera throughput on Ray (issue 48 part 4): the numbers a DROID-scale build is sized
from.

    .venv/bin/python bench/shards_video.py [--episodes 24] [--steps 300] [--cameras 3]
                                           [--resolution 180x320] [--fps 15] [--shards 1,2,4]
                                           [--repeat 2] [--work /tmp/chunkc-bench-shards-video]
                                           [--out bench/results-shards-video.json]

Source: `chunkc synth --format lerobot` (LeRobot v3.0, each camera encoded as LeRobot encodes it:
libsvtav1, yuv420p), DROID's camera shape by default (three 180x320 cameras at 15 Hz, a 7-D
action and a 14-D state). Two specs, one `act` profile each (fps = the source's, HDF5 with
`image_compression = "video"`):

- `copy`: the default, the source's packets copied into one mp4 per episode and camera;
- `encode`: `video_copy = false`, every episode encoded again (the encoder chunkc picks).

Each is built by `scripts/chunkc_ray.py SPEC --num-shards S --num-cpus min(S, cores)` for every
S of `--shards` (one chunkc thread per shard, Ray started on this machine), `--repeat` interleaved
rounds, medians reported. Every chunkc the driver runs goes through a wrapper that records its
peak RSS, wall and CPU seconds (`/usr/bin/time`), so that each shard's and the merge's costs are
known apart from Ray's start-up. The merged outputs are checked byte for byte against a
single-process build of the same spec.

Reported per mode and shard count: the driver's wall time; the shards' CPU seconds (user +
system, summed); frames per shard-CPU-second and source MB per shard-CPU-second ("per core":
one shard is one core's work), the same over the driver's wall time and the cores used; each
shard's peak RSS (the largest); the partials' size (the driver keeps them until the next run);
the merge's wall time and peak RSS; the output's size against the source's videos.
"""

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from shards import hashes, timed as run  # bench/shards.py: the same helpers

REPO = Path(__file__).resolve().parent.parent
BIN = Path(os.environ.get("CHUNKC_BIN", REPO / "target" / "release" / "chunkc")).resolve()
DRIVER = REPO / "scripts" / "chunkc_ray.py"
MODES = {"copy": "", "encode": "video_copy = false\n"}


def size(root, pattern="*"):
    return sum(p.stat().st_size for p in Path(root).rglob(pattern) if p.is_file())


def wrapper(work):
    """A `chunkc` that records each run's arguments, peak RSS (KiB), wall, user and system
    seconds under work/runs/<pid>.*."""
    logs = work / "runs"
    logs.mkdir(parents=True, exist_ok=True)
    path = work / "chunkc-timed"
    path.write_text(f"""#!/bin/sh
echo "$*" > "{logs}/$$.args"
exec /usr/bin/time -f "%M %e %U %S" -o "{logs}/$$.time" "{BIN}" "$@"
""")
    path.chmod(0o755)
    return path, logs


def collected(logs):
    """The runs the wrapper recorded since it was last emptied: (args, rss MiB, wall, cpu)."""
    out = []
    for args in sorted(logs.glob("*.args")):
        timing = args.with_suffix(".time")
        fields = timing.read_text().split()[-4:] if timing.exists() else []
        if len(fields) == 4:
            rss, wall, user, sys_ = map(float, fields)
            out.append({"args": args.read_text().strip(), "rss_mib": rss / 1024, "wall_s": wall,
                        "cpu_s": user + sys_})
    shutil.rmtree(logs)
    logs.mkdir()
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=24)
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--cameras", type=int, default=3)
    ap.add_argument("--resolution", default="180x320")
    ap.add_argument("--fps", type=int, default=15)
    ap.add_argument("--shards", default="1,2,4")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--work", type=Path, default=Path("/tmp/chunkc-bench-shards-video"))
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results-shards-video.json")
    args = ap.parse_args()
    work = args.work.resolve()
    cores = os.cpu_count() or 1
    shard_counts = [int(s) for s in args.shards.split(",")]
    src = work / (f"lerobot-{args.episodes}x{args.steps}-c{args.cameras}-{args.resolution}"
                  f"-{args.fps}hz")
    if not (src / "spec.toml").exists():
        shutil.rmtree(src, ignore_errors=True)
        work.mkdir(parents=True, exist_ok=True)
        print(f"writing the source {src.name} (AV1, once)", file=sys.stderr)
        run([BIN, "synth", src, "--format", "lerobot", "--episodes", args.episodes, "--steps",
             args.steps, "--cameras", args.cameras, "--resolution", args.resolution, "--fps",
             args.fps, "--action-dim", 7, "--state-dim", 14, "--seed", 0])
    text = (src / "spec.toml").read_text()
    base = text[: text.index("[profiles")] if "[profiles" in text else text
    frames = args.episodes * args.steps * args.cameras
    source_mb = size(src / "lerobot" / "videos") / 1e6
    chunkc, logs = wrapper(work)
    env = dict(os.environ, CHUNKC_BIN=str(chunkc), RAY_USAGE_STATS_ENABLED="0")
    specs, want, single = {}, {}, {}
    for mode, keys in MODES.items():
        spec = src / f"bench-{mode}.toml"
        spec.write_text(base.replace('dir = "out"', f'dir = "bench-{mode}"')
                        + f'[profiles.act]\npreset = "act"\nfps = {args.fps}\nchunk = 20\n'
                        + 'format = "hdf5"\nimage_compression = "video"\n' + keys)
        specs[mode] = spec
        clean(src, mode, work)
        single[mode] = run([BIN, "-j", str(cores), "build", "-q", spec])
        want[mode] = hashes(src / f"bench-{mode}")
        print(f"{mode}: one process, -j {cores}: {single[mode]:.1f} s", file=sys.stderr)
    collected(logs)
    runs = {f"{m}_{s}": [] for m in MODES for s in shard_counts}
    for r in range(args.repeat):
        for s in shard_counts:
            for mode, spec in specs.items():
                clean(src, mode, work)
                wall = run([sys.executable, DRIVER, spec, "--num-shards", s, "--num-cpus",
                            min(s, cores), "--partials", work / f"partials-{mode}",
                            "--chunkc", chunkc, "--keep-partials"], env=env)
                partial_bytes = size(work / f"partials-{mode}")
                if hashes(src / f"bench-{mode}") != want[mode]:
                    raise SystemExit(f"{mode}, {s} shards: the merged outputs differ from one build's")
                recorded = collected(logs)
                shards = [x for x in recorded if "--shard" in x["args"]]
                merge = [x for x in recorded if " merge " in f" {x['args']} "]
                runs[f"{mode}_{s}"].append({"wall_s": wall, "shards": shards, "merge": merge,
                                            "partial_bytes": partial_bytes})
                cpu = sum(x["cpu_s"] for x in shards)
                print(f"round {r + 1}: {mode}, {s} shards: {wall:.1f} s wall, shards {cpu:.1f} "
                      f"CPU-s, {frames / cpu:.0f} frames per shard-CPU-second, peak "
                      f"{max(x['rss_mib'] for x in shards):.0f} MiB a shard", file=sys.stderr)
    table = {}
    for key, rounds in runs.items():
        mode, s = key.rsplit("_", 1)
        s = int(s)
        wall = statistics.median(x["wall_s"] for x in rounds)
        cpu = statistics.median(sum(y["cpu_s"] for y in x["shards"]) for x in rounds)
        used = min(s, cores)
        table[key] = {
            "mode": mode, "shards": s, "cores": used, "driver_wall_s": wall, "shard_cpu_s": cpu,
            "frames_per_shard_cpu_s": frames / cpu, "source_mb_per_shard_cpu_s": source_mb / cpu,
            "frames_per_core_s_wall": frames / wall / used,
            "source_mb_per_core_s_wall": source_mb / wall / used,
            "shard_wall_s": statistics.median(y["wall_s"] for x in rounds for y in x["shards"]),
            "peak_rss_mib_per_shard": max(y["rss_mib"] for x in rounds for y in x["shards"]),
            "merge_wall_s": statistics.median(y["wall_s"] for x in rounds for y in x["merge"]),
            "merge_peak_rss_mib": max(y["rss_mib"] for x in rounds for y in x["merge"]),
            "partial_mb": statistics.median(x["partial_bytes"] for x in rounds) / 1e6,
        }
    outputs = {m: size(src / f"bench-{m}") / 1e6 for m in MODES}
    res = {
        "command": "python bench/shards_video.py " + " ".join(sys.argv[1:]),
        "date": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
        "cores": cores, "load_before": os.getloadavg(),
        "source": {"format": "lerobot v3.0 (chunkc synth, libsvtav1)", "episodes": args.episodes,
                   "steps": args.steps, "cameras": args.cameras, "resolution": args.resolution,
                   "fps": args.fps, "frames": frames, "video_mb": source_mb},
        "output_mb": outputs,
        "output_over_source_videos": {m: v / source_mb for m, v in outputs.items()},
        "one_process_s": single, "repeat": args.repeat, "table": table, "runs": runs,
    }
    args.out.write_text(json.dumps(res, indent=2) + "\n")
    print(f"{'mode':8}{'shards':>7}{'wall s':>9}{'CPU s':>8}{'fr/CPU-s':>10}{'MB/CPU-s':>10}"
          f"{'RSS/shard':>11}{'merge s':>9}{'partials MB':>13}")
    for row in table.values():
        print(f"{row['mode']:8}{row['shards']:>7}{row['driver_wall_s']:>9.1f}{row['shard_cpu_s']:>8.1f}"
              f"{row['frames_per_shard_cpu_s']:>10.0f}{row['source_mb_per_shard_cpu_s']:>10.2f}"
              f"{row['peak_rss_mib_per_shard']:>10.0f}M{row['merge_wall_s']:>9.1f}"
              f"{row['partial_mb']:>13.0f}")
    print(f"source videos {source_mb:.1f} MB; outputs "
          + ", ".join(f"{m} {v:.1f} MB ({v / source_mb:.2f}x)" for m, v in outputs.items()))


def clean(src, mode, work):
    shutil.rmtree(src / f"bench-{mode}", ignore_errors=True)
    shutil.rmtree(work / f"partials-{mode}", ignore_errors=True)
    (src / "chunkc.lock").unlink(missing_ok=True)


if __name__ == "__main__":
    main()
