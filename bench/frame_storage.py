"""Camera frame storage (issue 31): chunkc's loader over `image_compression = "none"`, `"jpeg"`
and `"video"` against LeRobotDataset (torchcodec, its default, and pyav) on the same frames, in
samples/s with shuffled sampling through a torch DataLoader, for the ACT and Diffusion Policy
windows; plus each storage's size and build time. A note, not a test; the table is in
book/src/video-storage.md.

    .venv/bin/python bench/frame_storage.py DIR
        env: EPISODES (default 3), FRAMES (frames an episode, default 100), WORKERS (DataLoader
        workers, default 2), BATCH (default 32), SAMPLES (samples timed per loader, default 480),
        ROUNDS (default 3: every loader is timed once a round, the rounds one after the other,
        and the median is reported), OUT (default bench/results-frame-storage.json)
    REAL=G1_DIR .venv/bin/python bench/frame_storage.py DIR
        the real-video case (issue 48): real 640x480 footage as AV1 (its own packets), H.264
        and MPEG-4 (bench/real_video.py makes the three sources), read by chunkc's loader over
        the default storage (the packets copied), by the decode floor (FFmpeg through PyAV
        decoding exactly the frames the same batches need, decoders kept open, each GOP once a
        batch, nothing else) and by LeRobotDataset with either backend. env as above (EPISODES
        default 6); OUT default bench/results-frame-storage-real.json

The source is a LeRobot v3.0 dataset written by `chunkc synth --format lerobot` (two 480x640
cameras at 10 fps, 14-D state and action, encoded as LeRobot encodes: libsvtav1, yuv420p, g=2,
crf=30; all episodes of a camera in one mp4).
chunkc builds it four times (one spec per storage, each with an `act` profile: 1 observation,
20 actions; and a `diffusion_policy` one: 2 observations, 16 actions), timed. Each loader then
runs with the same DataLoader settings (batch BATCH, WORKERS workers, shuffle with a fixed seed);
the first batch (worker start-up, file opening) is not timed, the next SAMPLES samples are.
LeRobotDataset gets the same windows through `delta_timestamps`.
"""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("HF_HUB_OFFLINE", "1")

REPO = Path(__file__).resolve().parents[1]
BIN = os.environ.get("CHUNKC_BIN", str(REPO / "target/release/chunkc"))
EPISODES = int(os.environ.get("EPISODES", "3"))
FRAMES = int(os.environ.get("FRAMES", "100"))
H, W, FPS = 480, 640, 10
WORKERS = int(os.environ.get("WORKERS", "2"))
BATCH = int(os.environ.get("BATCH", "32"))
SAMPLES = int(os.environ.get("SAMPLES", "480"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
KEYS = ["observation.images.cam0", "observation.images.cam1"]
PRESETS = {
    # name: (profile TOML, LeRobot delta_timestamps)
    "act": ('preset = "act"\nfps = 10\nchunk = 20',
            {"observation.state": [0.0], **{k: [0.0] for k in KEYS}, "action": [i / FPS for i in range(20)]}),
    "diffusion_policy": ('preset = "diffusion_policy"\nfps = 10',
                         {"observation.state": [-0.1, 0.0], **{k: [-0.1, 0.0] for k in KEYS},
                          "action": [(i - 1) / FPS for i in range(16)]}),
}
STORAGES = ["none", "jpeg", "video", "video_encoded"]
# The profile keys of each storage: `video` copies the source's packets where it can (the
# default), `video_encoded` encodes every episode (x264, crf 23, a keyframe every 8 frames).
STORAGE_KEYS = {
    "none": 'image_compression = "none"',
    "jpeg": 'image_compression = "jpeg"',
    "video": 'image_compression = "video"',
    "video_encoded": 'image_compression = "video"\nvideo_copy = false',
}


def build(root: Path, work: Path, storage: str):
    out = work / f"out_{storage}"
    profiles = "\n".join(f"[profiles.{p}]\n{toml}\n{STORAGE_KEYS[storage]}\n"
                         for p, (toml, _) in PRESETS.items())
    spec = work / f"spec_{storage}.toml"
    spec.write_text(f"""version = 1
[source]
format = "lerobot"
path = "{root}"
[source.channels]
action = "action"
"observation.state" = "observation.state"
"{KEYS[0]}" = "{KEYS[0]}"
"{KEYS[1]}" = "{KEYS[1]}"
[split]
val_fraction = 0.0
[output]
dir = "{out}"
{profiles}
""")
    subprocess.run(["rm", "-rf", str(out), str(work / "chunkc.lock")], check=True)
    t0 = time.perf_counter()
    p = subprocess.run([BIN, "build", "-q", "-j", str(WORKERS), str(spec)], capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode:
        raise SystemExit(p.stderr)
    sizes = {}
    for preset in PRESETS:
        d = out / preset
        files = [f for f in d.rglob("*") if f.is_file() and (f.name == "data.h5" or f.suffix == ".mp4")]
        sizes[preset] = sum(f.stat().st_size for f in files)
    return out, wall, sizes


def copied_share(profile_dir: Path):
    """The share of episode files that are the source's packets (`/videos/<cam>/copied`)."""
    import h5py

    with h5py.File(profile_dir / "data.h5", "r") as f:
        if "videos" not in f:
            return None
        flags = [v for cam in f["videos"] for v in f[f"videos/{cam}/copied"][:].tolist()]
    return sum(flags) / len(flags)


def timed(loader):
    """samples/s over SAMPLES samples after the first batch."""
    it = iter(loader)
    next(it)
    n, t0 = 0, time.perf_counter()
    while n < SAMPLES:
        try:
            batch = next(it)
        except StopIteration:
            it = iter(loader)
            continue
        n += len(batch["action"])
    return n / (time.perf_counter() - t0)


def dataloader(ds):
    import torch

    return torch.utils.data.DataLoader(ds, batch_size=BATCH, shuffle=True, num_workers=WORKERS,
                                       generator=torch.Generator().manual_seed(0))


def chunkc_loader(profile_dir: Path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(f"loader_{profile_dir.parent.name}_{profile_dir.name}",
                                                  profile_dir / "loader.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.ChunkedDataset(str(profile_dir))


def lerobot(root: Path, deltas, backend):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    return LeRobotDataset("bench/frames", root=root, delta_timestamps=deltas, video_backend=backend)


def main():
    if os.environ.get("REAL"):
        from frame_storage_real import main_real

        return main_real(Path(sys.argv[1]).resolve(), Path(os.environ["REAL"]).resolve())
    work = Path(sys.argv[1]).resolve()
    work.mkdir(parents=True, exist_ok=True)
    out = Path(os.environ.get("OUT", REPO / "bench" / "results-frame-storage.json"))
    synth = work / f"synth_{EPISODES}ep_{FRAMES}f"
    if not synth.exists():
        subprocess.run([BIN, "synth", "--format", "lerobot", "--episodes", str(EPISODES), "--steps", str(FRAMES),
                        "--cameras", "2", "--resolution", f"{H}x{W}", "--fps", str(FPS), str(synth)], check=True)
    root = synth / "lerobot"
    source_bytes = sum(f.stat().st_size for f in (root / "videos").rglob("*.mp4"))
    results = {"episodes": EPISODES, "frames_per_episode": FRAMES, "cameras": len(KEYS),
               "resolution": f"{W}x{H}", "source": "LeRobot v3.0, libsvtav1 g=2 crf=30",
               "source_video_bytes": source_bytes, "workers": WORKERS, "batch": BATCH, "samples": SAMPLES,
               "rounds": ROUNDS,
               "cpus": os.cpu_count(), "load_before": os.getloadavg(), "builds": {}, "loaders": {}}
    dirs = {}
    for storage in STORAGES:
        d, wall, sizes = build(root, work, storage)
        dirs[storage] = d
        results["builds"][storage] = {"build_s": round(wall, 2), "bytes": sizes,
                                      "copied": copied_share(d / "act")}
        print(f"build {storage}: {wall:.1f} s, {sizes}", flush=True)
    # Every loader once a round, so that a slower spell of the machine hits them all alike.
    runs = {preset: {} for preset in PRESETS}
    for r in range(ROUNDS):
        for preset, (_, deltas) in PRESETS.items():
            loaders = {f"chunkc_{s}": (lambda s=s: chunkc_loader(dirs[s] / preset)) for s in STORAGES}
            for backend in ("torchcodec", "pyav"):
                loaders[f"lerobot_{backend}"] = lambda b=backend: lerobot(root, deltas, b)
            for name, make in loaders.items():
                try:
                    v = timed(dataloader(make()))
                except Exception as e:  # a backend missing on this machine is reported, not fatal
                    if not name.startswith("lerobot_"):
                        raise
                    runs[preset][f"{name}_error"] = f"{type(e).__name__}: {e}"[:300]
                    continue
                runs[preset].setdefault(name, []).append(round(v, 1))
                print(f"round {r}: {preset} {name} {v:.1f} samples/s", flush=True)
    for preset, got in runs.items():
        row = {k: (float(np.median(v)) if isinstance(v, list) else v) for k, v in got.items()}
        lerobots = [v for k, v in row.items() if k.startswith("lerobot_") and isinstance(v, float)]
        if lerobots:
            row["ratio_vs_best_lerobot"] = {s: round(row[f"chunkc_{s}"] / max(lerobots), 2) for s in STORAGES}
        row["rounds"] = {k: v for k, v in got.items() if isinstance(v, list)}
        results["loaders"][preset] = row
    results["load_after"] = os.getloadavg()
    out.write_text(json.dumps(results, indent=2) + "\n")
    print(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
