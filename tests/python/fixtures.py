"""Source fixtures written with the reference libraries (h5py, Pillow, pyarrow), following the
layouts in TARGETS.md. Used by the tests, and by tests/data/make_synthetic_fixtures.py for the
small fixtures the example specs read."""

import io
import json
from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from PIL import Image

ALOHA_CAMS = ("top", "left_wrist")


def frames(n, height, width, seed):
    """Smooth moving gradients plus a little noise: compressible, but not trivially."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:height, 0:width]
    out = np.empty((n, height, width, 3), np.uint8)
    for t in range(n):
        r = (x * 4 + t * 3) % 256
        g = (y * 5 + t * 2) % 256
        b = ((x + y) * 2 + t * 7) % 256
        img = np.stack([r, g, b], axis=-1).astype(np.int16) + rng.integers(-8, 9, (height, width, 3))
        out[t] = np.clip(img, 0, 255).astype(np.uint8)
    return out


def jpeg(frame, quality=90):
    buf = io.BytesIO()
    Image.fromarray(frame).save(buf, format="JPEG", quality=quality)
    return buf.getvalue()


def write_aloha(directory, lengths=(30, 45, 38), compressed=False, height=48, width=64, seed=0,
                ids=None):
    """ALOHA episodes `episode_<i>.hdf5`; returns {id: {"action", "qpos", cam: frames or bytes}}."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    ids = list(ids) if ids is not None else list(range(len(lengths)))
    rng = np.random.default_rng(seed)
    written = {}
    for e, n in zip(ids, lengths):
        ep = {
            "action": rng.normal(size=(n, 14)).astype(np.float32),
            "qpos": rng.normal(size=(n, 14)).astype(np.float32),
            "qvel": rng.normal(size=(n, 14)).astype(np.float32),
            "effort": rng.normal(size=(n, 14)).astype(np.float32),
        }
        with h5py.File(directory / f"episode_{e}.hdf5", "w") as f:
            f.attrs["sim"] = True
            f.attrs["compress"] = compressed
            f.create_dataset("action", data=ep["action"])
            obs = f.create_group("observations")
            for key in ("qpos", "qvel", "effort"):
                obs.create_dataset(key, data=ep[key])
            images = obs.create_group("images")
            lens = []
            for c, cam in enumerate(ALOHA_CAMS):
                raw = frames(n, height, width, seed=seed * 100 + e * 10 + c)
                if compressed:
                    encoded = [jpeg(fr) for fr in raw]
                    max_len = max(len(b) for b in encoded)
                    padded = np.zeros((n, max_len), np.uint8)
                    for t, b in enumerate(encoded):
                        padded[t, : len(b)] = np.frombuffer(b, np.uint8)
                    images.create_dataset(cam, data=padded, chunks=(1, max_len))
                    lens.append([len(b) for b in encoded])
                    ep[cam] = encoded
                else:
                    images.create_dataset(cam, data=raw, chunks=(1, height, width, 3))
                    ep[cam] = raw
            if compressed:
                f.create_dataset("compress_len", data=np.array(lens, np.float32))
        written[e] = ep
    return written


# The columns every LeRobot frame row has, as info.json declares them.
LEROBOT_INDEX_FEATURES = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}


def write_lerobot_v3(root, lengths=(12, 7, 20, 9), per_file=3, fps=15, seed=0):
    """A LeRobot v3.0 dataset: several episodes per data file (one row group each), episodes
    metadata in meta/episodes/chunk-000/file-000.parquet. `action` is a fixed-size list,
    `observation.state` a variable-size list, `observation.gripper pos` (a non-standard name) a
    scalar. Returns {episode: {column: array}}."""
    root = Path(root)
    rng = np.random.default_rng(seed)
    episodes = {}
    index = 0
    meta_rows = []
    files = [list(range(len(lengths)))[i : i + per_file] for i in range(0, len(lengths), per_file)]
    for file_index, eps in enumerate(files):
        tables = []
        for e in eps:
            n = lengths[e]
            ep = {
                "action": rng.normal(size=(n, 3)).astype(np.float32),
                "observation.state": rng.normal(size=(n, 4)).astype(np.float32),
                "observation.gripper pos": rng.uniform(0, 1, size=n).astype(np.float64),
                "timestamp": (np.arange(n) / fps).astype(np.float32),
            }
            episodes[e] = ep
            tables.append(pa.table({
                "action": pa.FixedSizeListArray.from_arrays(pa.array(ep["action"].ravel()), 3),
                "observation.state": pa.array([list(r) for r in ep["observation.state"]],
                                              pa.list_(pa.float32())),
                "observation.gripper pos": pa.array(ep["observation.gripper pos"]),
                "timestamp": pa.array(ep["timestamp"]),
                "frame_index": pa.array(np.arange(n), pa.int64()),
                "episode_index": pa.array(np.full(n, e), pa.int64()),
                "index": pa.array(np.arange(index, index + n), pa.int64()),
                "task_index": pa.array(np.zeros(n), pa.int64()),
            }))
            meta_rows.append({
                "episode_index": e, "tasks": ["push the block"], "length": n,
                "data/chunk_index": 0, "data/file_index": file_index,
                "dataset_from_index": index, "dataset_to_index": index + n,
                "stats/action/mean": ep["action"].mean(axis=0).tolist(),
            })
            index += n
        path = root / f"data/chunk-000/file-{file_index:03d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        with pq.ParquetWriter(path, tables[0].schema) as w:
            for t in tables:
                w.write_table(t)  # one row group per episode, as LeRobot writes them
    meta = root / "meta/episodes/chunk-000/file-000.parquet"
    meta.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_pylist(meta_rows), meta)
    pq.write_table(pa.table({"task_index": [0], "task": ["push the block"]}), root / "meta/tasks.parquet")
    info = {
        "codebase_version": "v3.0",
        "robot_type": "synthetic",
        "total_episodes": len(lengths),
        "total_frames": int(sum(lengths)),
        "total_tasks": 1,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "fps": fps,
        "splits": {"train": f"0:{len(lengths)}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": {
            "action": {"dtype": "float32", "shape": [3], "names": {"motors": ["x", "y", "z"]}},
            "observation.state": {"dtype": "float32", "shape": [4], "names": ["a", "b", "c", "d"]},
            "observation.gripper pos": {"dtype": "float64", "shape": [1], "names": None},
            **LEROBOT_INDEX_FEATURES,
        },
    }
    (root / "meta/info.json").write_text(json.dumps(info, indent=2))
    return episodes
