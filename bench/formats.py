"""Every source layout into every output format: wall time, CPU time and peak RSS of one build.

    .venv/bin/python bench/formats.py [--quick] [--work /tmp/chunkc-bench] [--repeat 1]
                                      [--out bench/results-formats.json] [--bin CHUNKC]

The image dataset of bench/run.py (200 episodes x 300 steps x 2 cameras of 96x96x3, 14-D action
and state, at 50 Hz) written by `chunkc synth` in each layout that carries frames: ALOHA
(one uncompressed HDF5 file per episode), robomimic (one HDF5 file, gzip frames one per chunk, as
robomimic stores them) and Diffusion Policy zarr (Blosc chunks). LeRobot sources keep frames in
mp4 videos, which chunkc does not decode, so they are not here. Each source is built into each
output format with the spec `chunkc synth` wrote (one `act` profile), `format` changed: hdf5
(index, materialized and virtual layouts), zarr, parquet, act_episodes, robomimic_hdf5. Sources are cached under
WORK/formats by their parameters (about 8.5 GB); each output is deleted after its run. With
`--repeat N` the run with the median wall time is reported. `--bin` times another chunkc
binary (an older build, for a before/after table) on the same sources.
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import run  # noqa: E402
from run import REPO, log, timed_once  # noqa: E402

SOURCES = {"aloha": "aloha-hdf5", "robomimic": "robomimic-hdf5", "dp_zarr": "diffusion-policy-zarr"}
FORMATS = ["hdf5", "hdf5/materialized", "hdf5/virtual", "zarr", "parquet", "act_episodes",
           "robomimic_hdf5"]
SIZES = {"full": dict(episodes=200, steps=300), "quick": dict(episodes=10, steps=300)}


def source(work, layout, episodes, steps):
    root = work / "formats" / f"{layout}-e{episodes}-s{steps}"
    if not (root / "spec.toml").exists():
        if root.exists():
            shutil.rmtree(root)
        log(f"generating {root.name}")
        cmd = [run.BIN, "synth", root, "--format", SOURCES[layout], "--episodes", episodes,
               "--steps", steps, "--cameras", 2, "--resolution", "96x96", "--seed", 0]
        subprocess.run([str(c) for c in cmd], check=True, stdout=subprocess.DEVNULL)
    return root


def spec_for(root, fmt, out):
    """The synthesized spec with the profile's format and the output directory changed."""
    lines = []
    for line in (root / "spec.toml").read_text().splitlines():
        if line.startswith('format = "hdf5"'):
            name, _, layout = fmt.partition("/")
            line = f'format = "{name}"' + (f'\nlayout = "{layout}"' if layout else "")
        elif line.startswith("dir = "):
            line = f'dir = "{out}"'
        lines.append(line)
    path = root / f"bench-{fmt.replace('/', '-')}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="10 episodes instead of 200")
    ap.add_argument("--work", type=Path, default=Path("/tmp/chunkc-bench"))
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results-formats.json")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--bin", type=Path, default=run.BIN, help="the chunkc binary to time")
    args = ap.parse_args()
    for b in {run.BIN, args.bin}:
        if not b.exists():
            raise SystemExit(f"{b} is missing: run `cargo build --release` first")
    size = SIZES["quick" if args.quick else "full"]
    results = []
    for layout in SOURCES:
        root = source(args.work, layout, **size)
        # A source just generated is still being written back: wait for the disk, then warm
        # the page cache (every source is read once before it is timed).
        os.sync()
        for p in root.rglob("*"):
            if p.is_file():
                with open(p, "rb") as f:
                    while f.read(8 << 20):
                        pass
        for fmt in FORMATS:
            out = args.work / "formats" / "out"
            spec = spec_for(root, fmt, out)
            runs = []
            for _ in range(args.repeat):
                shutil.rmtree(out, ignore_errors=True)
                (root / "chunkc.lock").unlink(missing_ok=True)
                timed = timed_once([args.bin, "build", "-q", spec])
                timed.pop("stdout")
                runs.append(timed)
            shutil.rmtree(out, ignore_errors=True)
            spec.unlink()
            best = sorted(runs, key=lambda r: r["wall_s"])[len(runs) // 2]
            results.append({"source": layout, "format": fmt, **best, "runs": runs})
            log(f"{layout:>10} -> {fmt:<15} {best['wall_s']:7.2f} s wall "
                f"{best['cpu_s']:7.2f} s cpu {best['peak_rss_mib']:8.1f} MiB")
    print(f"\n| source \\ format | {' | '.join(FORMATS)} |")
    print(f"| --- |{' --- |' * len(FORMATS)}")
    for layout in SOURCES:
        cells = []
        for fmt in FORMATS:
            r = next(r for r in results if r["source"] == layout and r["format"] == fmt)
            cells.append(f"{r['wall_s']:.1f} s, {r['peak_rss_mib']:.0f} MiB")
        print(f"| {layout} | {' | '.join(cells)} |")
    machine = run.machine()
    machine["chunkc"] = subprocess.run([str(args.bin), "--version"], capture_output=True,
                                       text=True).stdout.strip()
    args.out.write_text(json.dumps({"machine": machine, "size": size, "results": results},
                                   indent=1) + "\n")
    log(f"wrote {args.out}")


if __name__ == "__main__":
    main()
