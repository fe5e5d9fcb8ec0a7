"""bench/frame_storage.py's real-video case (REAL=G1_DIR): chunkc's loader against the decode
floor and LeRobotDataset on real footage as AV1, H.264 and MPEG-4 (see bench/real_video.py for
the sources). Results in bench/results-frame-storage-real.json; the table is in
book/src/video-storage.md."""
import json
import os
from pathlib import Path

import numpy as np

from frame_storage import BIN, REPO, chunkc_loader, dataloader, lerobot, timed
import real_video

EPISODES = int(os.environ.get("EPISODES", "6"))
WORKERS = int(os.environ.get("WORKERS", "2"))
BATCH = int(os.environ.get("BATCH", "32"))
SAMPLES = int(os.environ.get("SAMPLES", "480"))
ROUNDS = int(os.environ.get("ROUNDS", "3"))
FPS = 30


def presets(cams):
    """name: (profile TOML, LeRobot delta_timestamps): ACT (the camera at t, 30 actions) and
    Diffusion Policy (2 observations, 16 actions)."""
    return {
        "act": ('preset = "act"\nfps = 30\nchunk = 30',
                {"observation.state": [0.0], **{k: [0.0] for k in cams},
                 "action": [i / FPS for i in range(30)]}),
        "diffusion_policy": ('preset = "diffusion_policy"\nfps = 30',
                             {"observation.state": [-1 / FPS, 0.0], **{k: [-1 / FPS, 0.0] for k in cams},
                              "action": [(i - 1) / FPS for i in range(16)]}),
    }


def build(root: Path, cams, work: Path, name: str):
    """chunkc's build of a v3.0 root with the default video storage (the packets copied)."""
    profiles = "\n".join(f"[profiles.{p}]\n{toml}\nimage_compression = \"video\"\n"
                         for p, (toml, _) in presets(cams).items())
    return real_video.build_lerobot(BIN, root, cams, work, f"real_{name}", profiles, "-j", str(WORKERS))


class Floor:
    """The decode floor: the frames the chunkc dataset's samples `idx` want (every camera, every
    observation step), decoded by FFmpeg through PyAV from each file's keyframe before them, each
    GOP once a batch up to the last frame wanted from it, the wanted frames converted to RGB;
    decoders and files kept open per worker. Samples hold the frames alone."""

    def __init__(self, ds):
        self.ds = ds
        self.cams = [c for c in ds.channels if c in ds._frames]
        self.files = {}

    def __len__(self):
        return len(self.ds)

    def _open(self, cam, ep):
        import av

        key = (cam, ep, os.getpid())
        got = self.files.get(key)
        if got is None:
            frames = self.ds._frames[cam]
            c = av.open(frames.paths[ep])
            s = c.streams.video[0]
            s.codec_context.thread_count = 1
            keys = np.asarray(sorted(int(round(float(p.pts * s.time_base) * FPS)) for p in c.demux(s)
                                     if p.pts is not None and p.is_keyframe), dtype=np.int64)
            got = self.files[key] = (c, s, keys)
        return got

    def _decode(self, cam, ep, wanted):
        """{frame: RGB array} of episode ep's frames `wanted` (sorted, unique)."""
        c, s, keys = self._open(cam, ep)
        out = {}
        gop = np.searchsorted(keys, wanted, side="right") - 1
        for g in np.unique(gop).tolist():
            mine = wanted[gop == g]
            want, last = set(mine.tolist()), int(mine.max())
            c.seek(int(round(int(keys[g]) / FPS / s.time_base)), stream=s, backward=True)
            for frame in c.decode(s):
                i = int(round(float(frame.pts * s.time_base) * FPS))
                if i in want:
                    out[i] = frame.to_ndarray(format="rgb24")
                if i >= last:
                    break
        return out

    def __getitems__(self, indices):
        ds = self.ds
        ep, t, _, _ = ds.index[np.asarray(indices, dtype=np.int64)].T
        start = ds.episode_starts[ep]
        steps = np.maximum(t[:, None] + np.arange(1 - ds.obs_history, 1), 0)
        rows = (start[:, None] + steps).reshape(-1)
        samples = [{} for _ in indices]
        for cam in self.cams:
            frames = ds._frames[cam]
            eps = np.searchsorted(frames.ends, rows, side="right")
            ks = rows - frames.starts[eps]
            decoded = {e: self._decode(cam, e, np.unique(ks[eps == e])) for e in np.unique(eps).tolist()}
            pixels = np.stack([decoded[e][k] for e, k in zip(eps.tolist(), ks.tolist())])
            pixels = pixels.reshape((len(indices), ds.obs_history) + pixels.shape[1:])
            for j, sample in enumerate(samples):
                sample[cam] = pixels[j]
        # `timed` counts samples by their "action" key: the floor's samples carry their frames'
        # episode steps there.
        for j, sample in enumerate(samples):
            sample["action"] = steps[j]
        return samples


def main_real(work: Path, g1_dir: Path):
    work.mkdir(parents=True, exist_ok=True)
    out = Path(os.environ.get("OUT", REPO / "bench" / "results-frame-storage-real.json"))
    sources = real_video.sources(BIN, g1_dir, work, EPISODES)
    results = {"footage": f"Unitree G1 footage (YifanTian07/G1-policy-train), first {EPISODES} episodes "
                          "with video", "workers": WORKERS, "batch": BATCH, "samples": SAMPLES,
               "rounds": ROUNDS, "cpus": os.cpu_count(), "load_before": os.getloadavg(), "sources": {},
               "loaders": {}}
    runs = {}
    dirs = {}
    for name, (root, cams, frames) in sources.items():
        d, wall = build(root, cams, work, name)
        dirs[name] = (root, cams, d)
        results["sources"][name] = {"frames": frames, "build_s": round(wall, 2),
                                    **real_video.stream_facts(root, cams[0])}
        print(f"{name}: {results['sources'][name]}", flush=True)
    for r in range(ROUNDS):
        for name, (root, cams, d) in dirs.items():
            for preset, (_, deltas) in presets(cams).items():
                loaders = {"chunkc": lambda: chunkc_loader(d / preset),
                           "floor": lambda: Floor(chunkc_loader(d / preset))}
                for backend in ("torchcodec", "pyav"):
                    loaders[f"lerobot_{backend}"] = lambda b=backend: lerobot(root, deltas, b)
                got = runs.setdefault(f"{name}/{preset}", {})
                for loader, make in loaders.items():
                    try:
                        v = timed(dataloader(make()))
                    except Exception as e:  # a backend failing is a result, not fatal
                        if not loader.startswith("lerobot_"):
                            raise
                        got[f"{loader}_error"] = f"{type(e).__name__}: {e}"[:300]
                        print(f"round {r}: {name} {preset} {loader} failed: {got[f'{loader}_error']}", flush=True)
                        continue
                    got.setdefault(loader, []).append(round(v, 1))
                    print(f"round {r}: {name} {preset} {loader} {v:.1f} samples/s", flush=True)
    for key, got in runs.items():
        row = {k: (float(np.median(v)) if isinstance(v, list) else v) for k, v in got.items()}
        lerobots = [v for k, v in row.items() if k.startswith("lerobot_") and isinstance(v, float)]
        row["chunkc_vs_floor"] = round(row["chunkc"] / row["floor"], 2)
        if lerobots:
            row["chunkc_vs_best_lerobot"] = round(row["chunkc"] / max(lerobots), 2)
        row["rounds"] = {k: v for k, v in got.items() if isinstance(v, list)}
        results["loaders"][key] = row
    results["load_after"] = os.getloadavg()
    out.write_text(json.dumps(results, indent=2) + "\n")
    print(json.dumps(results["loaders"], indent=2))
