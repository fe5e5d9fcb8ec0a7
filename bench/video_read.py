"""Decoding LeRobot AV1 video: chunkc (-j1, -j2) against PyAV in one process and against
iterating `LeRobotDataset` (issue 19; a note, not a test; results in book/src/video.md).

    .venv/bin/python bench/video_read.py DIR [EPISODES ...]   (default: 10 20 40)
        env: FRAMES (frames an episode, default 300), FORMAT (the build's output: zarr, the
        default, or hdf5 for uncompressed frames), LEROBOT_MAX (iterate LeRobotDataset over
        every row only on sets of at most this many episodes, default 10; 0: never),
        LEROBOT_SAMPLE (on larger sets, time that many rows spread evenly instead; default 0:
        none), OUT (the JSON results file, default bench/results-video.json)

For each episode count it writes a LeRobot v3.0 dataset under DIR: two cameras of 480x640
frames (ffmpeg's testsrc2 and its mirror), FRAMES frames an episode at 10 fps, all episodes in
one mp4 per camera; one episode encoded as LeRobot encodes (libsvtav1, yuv420p, g=2, crf=30;
needs the `ffmpeg` CLI) and repeated for every episode by stream copy. Then it times
- PyAV alone decoding every frame of both files to rgb24 (`frame.to_ndarray(format="rgb24")`),
  sequentially, in one process: the floor for anything built on PyAV;
- `chunkc build` of one profile (every frame decoded, selected against the parquet timestamps
  and written: Zarr with Blosc lz4, Diffusion Policy's default, or uncompressed HDF5) with -j1
  and -j2, its peak RSS (getrusage of the child) and the "read episodes" phase (CHUNKC_TIMINGS);
- `LeRobotDataset(video_backend="pyav")` indexed over every row (`ds[i]` for all i: both
  cameras' frames, as a training loop without workers reads them).
"""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

REPO = Path(__file__).resolve().parents[1]
BIN = os.environ.get("CHUNKC_BIN", str(REPO / "target/release/chunkc"))
FRAMES = int(os.environ.get("FRAMES", "300"))
FORMAT = os.environ.get("FORMAT", "zarr")
H, W, FPS = 480, 640, 10
KEYS = ["observation.images.top", "observation.images.wrist"]


def encode(out: Path, episodes: int, mirror: bool):
    """One episode's FRAMES frames encoded as LeRobot encodes, then that stream repeated for
    every episode (stream copy, no re-encode): each episode starts on a key frame, as in a
    LeRobot v3.0 file, and encoding 120,000 frames with SVT-AV1 would take an hour on 2 cores."""
    out.parent.mkdir(parents=True, exist_ok=True)
    one = out.with_name("episode.mp4")
    vf = "hflip," if mirror else ""
    subprocess.run(
        ["ffmpeg", "-v", "error", "-y", "-f", "lavfi", "-i",
         f"testsrc2=size={W}x{H}:rate={FPS}", "-frames:v", str(FRAMES), "-vf", f"{vf}format=yuv420p",
         "-c:v", "libsvtav1", "-g", "2", "-crf", "30", "-preset", "10", str(one)],
        check=True, stderr=subprocess.DEVNULL,
    )
    listing = out.with_name("episodes.txt")
    listing.write_text(f"file '{one.name}'\n" * episodes)
    subprocess.run(["ffmpeg", "-v", "error", "-y", "-f", "concat", "-safe", "0", "-i", str(listing),
                    "-c", "copy", str(out)], check=True)
    one.unlink()
    listing.unlink()


def write_tasks(root: Path):
    """meta/tasks.parquet as LeRobot writes it: the task strings are the DataFrame's index
    (`ds[i]["task"]` is `tasks.iloc[task_index].name`); without it LeRobotDataset asks the Hub."""
    import pandas as pd

    pd.DataFrame({"task_index": [0]}, index=["bench"]).to_parquet(root / "meta/tasks.parquet")


def write_dataset(root: Path, episodes: int):
    if (root / "meta/info.json").exists():
        return
    n = episodes * FRAMES
    for i, key in enumerate(KEYS):
        encode(root / f"videos/{key}/chunk-000/file-000.mp4", episodes, mirror=i == 1)
    ep = np.repeat(np.arange(episodes), FRAMES)
    k = np.tile(np.arange(FRAMES), episodes)
    rng = np.random.default_rng(0)
    data = root / "data/chunk-000/file-000.parquet"
    data.parent.mkdir(parents=True, exist_ok=True)
    vec = lambda: pa.array(list(rng.standard_normal((n, 2)).astype(np.float32)), type=pa.list_(pa.float32(), 2))
    pq.write_table(pa.table({
        "observation.state": vec(), "action": vec(),
        "timestamp": pa.array((k / FPS).astype(np.float32)),
        "frame_index": pa.array(k), "episode_index": pa.array(ep), "index": pa.array(np.arange(n)),
        "task_index": pa.array(np.zeros(n, dtype=np.int64)),
    }), data, row_group_size=FRAMES)
    cols = {"episode_index": np.arange(episodes), "length": np.full(episodes, FRAMES),
            "data/chunk_index": np.zeros(episodes, dtype=np.int64),
            "data/file_index": np.zeros(episodes, dtype=np.int64)}
    for key in KEYS:
        cols[f"videos/{key}/chunk_index"] = np.zeros(episodes, dtype=np.int64)
        cols[f"videos/{key}/file_index"] = np.zeros(episodes, dtype=np.int64)
        cols[f"videos/{key}/from_timestamp"] = np.arange(episodes) * FRAMES / FPS
        cols[f"videos/{key}/to_timestamp"] = (np.arange(episodes) + 1) * FRAMES / FPS
    meta = root / "meta/episodes/chunk-000/file-000.parquet"
    meta.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(cols), meta)
    video = {"dtype": "video", "shape": [H, W, 3], "names": ["height", "width", "channels"],
             "info": {"video.codec": "av1", "video.fps": FPS}}
    info = {
        "codebase_version": "v3.0", "fps": FPS, "chunks_size": 1000, "robot_type": None,
        "total_episodes": episodes, "total_frames": n, "total_tasks": 1,
        "splits": {"train": f"0:{episodes}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": {**{k: video for k in KEYS},
                     "observation.state": {"dtype": "float32", "shape": [2]},
                     "action": {"dtype": "float32", "shape": [2]},
                     "timestamp": {"dtype": "float32", "shape": [1]},
                     **{k: {"dtype": "int64", "shape": [1]}
                        for k in ("frame_index", "episode_index", "index", "task_index")}},
    }
    write_tasks(root)
    (root / "meta/info.json").write_text(json.dumps(info))


def pyav_fps(root: Path, threads: int | None) -> float:
    """PyAV decoding every frame to rgb24; `threads` None: PyAV's default (its decoder context
    asks for FFmpeg's automatic thread count, so dav1d uses every core), else that many."""
    import av

    t0, n = time.perf_counter(), 0
    for key in KEYS:
        with av.open(str(root / f"videos/{key}/chunk-000/file-000.mp4")) as c:
            stream = c.streams.video[0]
            if threads is not None:
                stream.codec_context.thread_count = threads
            for frame in c.decode(stream):
                frame.to_ndarray(format="rgb24")
                n += 1
    return n / (time.perf_counter() - t0)


def chunkc(root: Path, work: Path, threads: int):
    spec = work / f"spec_j{threads}.toml"
    spec.write_text(f"""version = 1
[source]
format = "lerobot"
path = "{root}"
[source.channels]
action = "action"
"observation.state" = "observation.state"
"observation.top" = "{KEYS[0]}"
"observation.wrist" = "{KEYS[1]}"
[split]
val_fraction = 0.0
[output]
dir = "{work}/out_j{threads}"
[profiles.h]
preset = "act"
fps = 10
chunk = 10
format = "{FORMAT}"
""")
    subprocess.run(["rm", "-rf", str(work / f"out_j{threads}")], check=True)
    # A fresh Python parent per run, so that its children's peak RSS is this build's alone.
    measure = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]).returncode; "
               "print('peak_rss_kb', resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); "
               "sys.exit(r)")
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", measure, BIN, "build", "-j", str(threads), str(spec)],
                       capture_output=True, text=True, env={**os.environ, "CHUNKC_TIMINGS": "1"})
    wall = time.perf_counter() - t0
    if p.returncode:
        raise SystemExit(p.stderr)
    rss = int(next(l for l in p.stderr.splitlines() if l.startswith("peak_rss_kb")).split()[1])
    read = next((l for l in p.stderr.splitlines() if "read episodes" in l), "").strip()
    subprocess.run(["rm", "-rf", str(work / f"out_j{threads}")], check=True)
    return wall, rss, read


def lerobot_fps(root: Path, sample: int = 0):
    """`ds[i]` for every row, or (`sample` > 0) for that many rows spread evenly over the set."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("bench/av1", root=root, video_backend="pyav")
    rows = range(len(ds)) if sample <= 0 else np.linspace(0, len(ds) - 1, sample).astype(int)
    t0 = time.perf_counter()
    for i in rows:
        item = ds[int(i)]
        assert tuple(item[KEYS[0]].shape) == (3, H, W)
    wall = time.perf_counter() - t0
    return wall, len(rows) * len(KEYS) / wall


def main():
    work = Path(sys.argv[1]).resolve()
    counts = [int(c) for c in sys.argv[2:]] or [10, 20, 40]
    lerobot_max = int(os.environ.get("LEROBOT_MAX", "10"))
    sample = int(os.environ.get("LEROBOT_SAMPLE", "0"))
    out = Path(os.environ.get("OUT", REPO / "bench" / "results-video.json"))
    results = {"frames_per_episode": FRAMES, "cameras": len(KEYS), "resolution": f"{W}x{H}",
               "codec": "libsvtav1 yuv420p g=2 crf=30", "format": FORMAT, "cpus": os.cpu_count(),
               "load_before": os.getloadavg(), "sets": []}
    for e in counts:
        root = work / f"av1_{e}ep_{FRAMES}f"
        write_dataset(root, e)
        frames = e * FRAMES * len(KEYS)
        row = {"episodes": e, "frames": frames}
        print(f"{e} episodes x {FRAMES} frames x {len(KEYS)} cameras at {W}x{H}: {frames} frames")
        row["pyav_fps"] = pyav_fps(root, None)
        print(f"  PyAV, one process, its default threads: {row['pyav_fps']:.0f} frames/s")
        row["pyav_1thread_fps"] = pyav_fps(root, 1)
        print(f"  PyAV, one process, one decoder thread: {row['pyav_1thread_fps']:.0f} frames/s")
        for j in (1, 2):
            wall, rss, read = chunkc(root, work, j)
            row[f"chunkc_j{j}"] = {"wall_s": wall, "fps": frames / wall, "peak_rss_mb": rss / 1024,
                                   "timings": read}
            print(f"  chunkc build -j{j} ({FORMAT}): {wall:.1f} s, {frames / wall:.0f} frames/s, "
                  f"peak RSS {rss / 1024:.0f} MB; {read}")
        if e <= lerobot_max:
            wall, fps = lerobot_fps(root)
            row["lerobot_dataset"] = {"wall_s": wall, "fps": fps}
            print(f"  LeRobotDataset[i] over every row (pyav): {wall:.1f} s, {fps:.0f} frames/s")
        elif sample:
            wall, fps = lerobot_fps(root, sample)
            row["lerobot_dataset_sample"] = {"rows": sample, "wall_s": wall, "fps": fps}
            print(f"  LeRobotDataset[i] over {sample} rows spread over the set (pyav): {wall:.1f} s, "
                  f"{fps:.0f} frames/s")
        results["sets"].append(row)
        out.write_text(json.dumps(results, indent=2) + "\n")
        sys.stdout.flush()


if __name__ == "__main__":
    main()
