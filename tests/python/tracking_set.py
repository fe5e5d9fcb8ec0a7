"""A realistic low-dim robot dataset with planted faults, written as LeRobot v3.0, independent of
`chunkc synth` (its own trajectories, dynamics and fault injection; nothing shared with chunkc's
generator but the file format).

Each episode: a commanded joint trajectory `cmd` (smooth: cubic interpolation between random
waypoints, plus a slow sinusoid), and a state that tracks it as a first-order system,
`state[t+1] = state[t] + a * (cmd[t] - state[t]) + noise`, with a per-dimension gain `a`, small
process noise and a little sensor noise. The recorded action is `cmd`.

Faults, each in its own share of the episodes (never two in one episode):
- `spike`: three single-step spikes in one action dimension, at least 10 steps apart, each a
  share `k` of that dimension's range over the dataset (k drawn in [spike_min, spike_max],
  10-30% by default: a
  glitch is large against the dimension's motion, not against the noise of its steps, which on
  real still or quantized joints is nothing); the truth records the steps.
- `units`: the episode recorded in degrees where the rest are radians: action and state both
  multiplied by 180/pi.

    python tests/python/tracking_set.py OUT --episodes 200 --seed 0 [--faults spike,units]

writes OUT/meta/..., OUT/data/... and OUT/truth.json ({"episodes": {id: [kind, ...]}})."""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fixtures import LEROBOT_INDEX_FEATURES  # noqa: E402

KINDS = ("spike", "units")


def command(rng, n, dim):
    """Smooth commanded joint positions (radians): cubic through waypoints + a slow sinusoid."""
    knots = max(4, n // 40)
    at = np.linspace(0, n - 1, knots)
    out = np.empty((n, dim))
    t = np.arange(n)
    for d in range(dim):
        way = np.cumsum(rng.normal(0, 0.25, knots)) + rng.uniform(-1, 1)
        # Catmull-Rom-like smoothness through numpy's cubic polyfit per segment is overkill: a
        # natural cubic spline by solving the tridiagonal system keeps this self-contained.
        out[:, d] = natural_cubic(at, way, t)
        out[:, d] += 0.1 * np.sin(2 * np.pi * t / rng.uniform(80, 200) + rng.uniform(0, 6.3))
    return out


def natural_cubic(x, y, xs):
    n = len(x)
    h = np.diff(x)
    a = np.zeros((n, n))
    b = np.zeros(n)
    a[0, 0] = a[-1, -1] = 1
    for i in range(1, n - 1):
        a[i, i - 1], a[i, i], a[i, i + 1] = h[i - 1], 2 * (h[i - 1] + h[i]), h[i]
        b[i] = 3 * ((y[i + 1] - y[i]) / h[i] - (y[i] - y[i - 1]) / h[i - 1])
    c = np.linalg.solve(a, b)
    bb = (np.diff(y) / h) - h * (2 * c[:-1] + c[1:]) / 3
    dd = np.diff(c) / (3 * h)
    i = np.clip(np.searchsorted(x, xs, side="right") - 1, 0, n - 2)
    dx = xs - x[i]
    return y[i] + bb[i] * dx + c[i] * dx**2 + dd[i] * dx**3


def track(rng, cmd, gain):
    n, dim = cmd.shape
    s = np.empty_like(cmd)
    x = cmd[0] + rng.normal(0, 0.01, dim)
    for t in range(n):
        s[t] = x
        x = x + gain * (cmd[t] - x) + rng.normal(0, 0.002, dim)
    return s + rng.normal(0, 0.0005, s.shape)


def generate(episodes=200, seed=0, faults=KINDS, fraction=0.1, dim=6, steps=(150, 250),
             spike_min=0.1, spike_max=0.3):
    """Per episode {"action", "observation.state"} float32 arrays, and the truth per episode."""
    rng = np.random.default_rng(seed)
    gain = rng.uniform(0.2, 0.5, dim)
    order = rng.permutation(episodes)
    share = int(round(fraction * episodes))
    kind_of = {}
    for k, kind in enumerate(faults):
        for e in order[k * share:(k + 1) * share]:
            kind_of[int(e)] = kind
    clean = []
    for e in range(episodes):
        n = int(rng.integers(*steps))
        cmd = command(rng, n, dim)
        clean.append((cmd, track(rng, cmd, gain)))
    # The spikes' sizes are shares of each dimension's range over the dataset.
    every = np.concatenate([c for c, _ in clean])
    span = every.max(0) - every.min(0)
    data, truth = [], {}
    for e, (cmd, state) in enumerate(clean):
        n = len(cmd)
        kind = kind_of.get(e)
        if kind == "spike":
            d = int(rng.integers(dim))
            # Three single glitches, at least 10 steps apart (not one three-step burst).
            at = np.sort(rng.choice(np.arange(10, n - 10, 10), 3, replace=False))
            for t in at:
                cmd[t, d] += rng.choice([-1, 1]) * rng.uniform(spike_min, spike_max) * span[d]
            truth[e] = [{"kind": "spike", "dim": d, "steps": at.tolist()}]
        elif kind == "units":
            cmd, state = cmd * 180 / np.pi, state * 180 / np.pi
            truth[e] = [{"kind": "units", "factor": 180 / np.pi}]
        data.append({"action": cmd.astype(np.float32), "observation.state": state.astype(np.float32)})
    return data, truth


def write_lerobot(root: Path, data, fps=10):
    root = Path(root)
    dim = data[0]["action"].shape[1]
    tables, meta_rows, index = [], [], 0
    for e, ep in enumerate(data):
        n = len(ep["action"])
        tables.append(pa.table({
            "action": pa.FixedSizeListArray.from_arrays(pa.array(ep["action"].ravel()), dim),
            "observation.state": pa.FixedSizeListArray.from_arrays(
                pa.array(ep["observation.state"].ravel()), dim),
            "timestamp": pa.array((np.arange(n) / fps).astype(np.float32)),
            "frame_index": pa.array(np.arange(n), pa.int64()),
            "episode_index": pa.array(np.full(n, e), pa.int64()),
            "index": pa.array(np.arange(index, index + n), pa.int64()),
            "task_index": pa.array(np.zeros(n), pa.int64()),
        }))
        meta_rows.append({"episode_index": e, "tasks": ["reach"], "length": n,
                          "data/chunk_index": 0, "data/file_index": 0,
                          "dataset_from_index": index, "dataset_to_index": index + n})
        index += n
    path = root / "data/chunk-000/file-000.parquet"
    path.parent.mkdir(parents=True, exist_ok=True)
    with pq.ParquetWriter(path, tables[0].schema) as w:
        for t in tables:
            w.write_table(t)
    meta = root / "meta/episodes/chunk-000/file-000.parquet"
    meta.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.Table.from_pylist(meta_rows), meta)
    tasks = pa.table({"task_index": [0], "__index_level_0__": ["reach"]})
    pq.write_table(tasks.replace_schema_metadata({b"pandas": json.dumps({
        "index_columns": ["__index_level_0__"], "column_indexes": [], "columns": []}).encode()}),
        root / "meta/tasks.parquet")
    names = [f"j{d}" for d in range(dim)]
    info = {
        "codebase_version": "v3.0", "robot_type": "tracking", "total_episodes": len(data),
        "total_frames": index, "total_tasks": 1, "chunks_size": 1000,
        "data_files_size_in_mb": 100, "video_files_size_in_mb": 500, "fps": fps,
        "splits": {"train": f"0:{len(data)}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": None,
        "features": {
            "action": {"dtype": "float32", "shape": [dim], "names": names},
            "observation.state": {"dtype": "float32", "shape": [dim], "names": names},
            **LEROBOT_INDEX_FEATURES,
        },
    }
    (root / "meta/info.json").write_text(json.dumps(info, indent=2))


def write(root: Path, episodes=200, seed=0, faults=KINDS, **kw):
    data, truth = generate(episodes, seed, faults, **kw)
    write_lerobot(root, data)
    (Path(root) / "truth.json").write_text(json.dumps({"episodes": truth}, indent=1))
    return truth


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--episodes", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--faults", default=",".join(KINDS))
    a = ap.parse_args()
    write(a.out, a.episodes, a.seed, tuple(f for f in a.faults.split(",") if f))
