"""Opens LeRobot v2.1 datasets with PyPI lerobot 0.3.3 (the last release that reads v2.1; openpi's
pinned lerobot reads v2.1 with the same `LeRobotDataset`) and saves what it gives to .npz files.

Runs in `.venv-lerobot21` (scripts/setup.sh), never in the suite's venv: lerobot 0.3.3's pins
conflict with the suite's lerobot 0.4.4. test_lerobot_v21.py starts it as a subprocess:

    .venv-lerobot21/bin/python lerobot21_read.py JOBS.json

JOBS.json is a list of jobs, each a dict:
    out        the .npz to write
    repo_id    the dataset's repo id
    root       its folder, passed as `root=`; or
    home       HF_LEROBOT_HOME, with no `root=`: openpi's call (`LeRobotDatasetMetadata(repo_id)`,
               then `LeRobotDataset(repo_id, delta_timestamps=...)`), which finds the dataset at
               HF_LEROBOT_HOME / repo_id
    horizon    the action chunk: `delta_timestamps = {"action": [t / fps for t in range(H)]}`,
               as openpi's `create_torch_dataset` builds it from `dataset_meta.fps`
    indices    the samples to read (default: all)
    decode     optional: mp4 files to decode whole with torchcodec (LeRobot's default backend)

Each .npz holds, per sample: every tensor feature of `ds[i]` stacked (frames as uint8 HWC, from
LeRobot's float CHW in [0, 1]), `task` (strings); and `meta`: a JSON string of `fps`,
`video_keys`, `camera_keys`, `num_episodes`, `episodes` (meta/episodes.jsonl as LeRobot read
it), `stats` (the statistics LeRobot aggregated from meta/episodes_stats.jsonl) and `backend`;
`decoded_<k>`: the frames of `decode[k]`.
"""

import json
import os
import sys

import numpy as np


def frames_uint8(t):
    """A LeRobot frame (C, H, W) float in [0, 1] as the HWC uint8 it was decoded from."""
    return np.round(t.numpy().transpose(1, 2, 0) * 255).astype(np.uint8)


def run(job):
    from lerobot.datasets import lerobot_dataset

    horizon = job["horizon"]
    if "home" in job:
        meta = lerobot_dataset.LeRobotDatasetMetadata(job["repo_id"])
        delta = {"action": [t / meta.fps for t in range(horizon)]}
        ds = lerobot_dataset.LeRobotDataset(job["repo_id"], delta_timestamps=delta)
    else:
        meta = lerobot_dataset.LeRobotDatasetMetadata(job["repo_id"], root=job["root"])
        delta = {"action": [t / meta.fps for t in range(horizon)]}
        ds = lerobot_dataset.LeRobotDataset(job["repo_id"], root=job["root"], delta_timestamps=delta)
    cameras = set(ds.meta.camera_keys)
    indices = job.get("indices") or list(range(len(ds)))
    out = {}
    tasks = []
    for i in indices:
        item = ds[i]
        tasks.append(item["task"])
        for k, v in item.items():
            if k == "task":
                continue
            out.setdefault(k, []).append(frames_uint8(v) if k in cameras else v.numpy())
    arrays = {k: np.stack(v) for k, v in out.items()}
    arrays["task"] = np.array(tasks)
    arrays["sample"] = np.array(indices)
    stats = {k: {s: np.asarray(a).tolist() for s, a in v.items()} for k, v in ds.meta.stats.items()}
    arrays["meta"] = np.array(json.dumps({
        "fps": ds.fps,
        "len": len(ds),
        "video_keys": ds.meta.video_keys,
        "camera_keys": ds.meta.camera_keys,
        "num_episodes": ds.num_episodes,
        "episodes": list(ds.meta.episodes.values()),
        "stats": stats,
        "backend": ds.video_backend,
    }))
    for k, path in enumerate(job.get("decode", [])):
        from torchcodec.decoders import VideoDecoder

        decoder = VideoDecoder(path)
        arrays[f"decoded_{k}"] = np.stack([f.numpy().transpose(1, 2, 0) for f in decoder])
    np.savez(job["out"], **arrays)


def main():
    jobs = json.loads(open(sys.argv[1]).read())
    homes = {job.get("home") for job in jobs} - {None}
    # lerobot.constants reads HF_LEROBOT_HOME when it is imported: one home per process.
    assert len(homes) <= 1, "one HF_LEROBOT_HOME per run"
    if homes:
        os.environ["HF_LEROBOT_HOME"] = homes.pop()
    for job in jobs:
        run(job)


if __name__ == "__main__":
    main()
