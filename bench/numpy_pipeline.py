"""The baseline the benchmark compares chunkc with: the data preparation the usual guides describe,
written with plain numpy + h5py and kept efficient (whole-array operations, no per-step Python
loops; one Python iteration per episode file, as any reader of an ALOHA directory needs).

It does the work chunkc's `act` profile (index layout) does on an ALOHA source:

1. load every episode's `action` and `observations/qpos` (h5py);
2. audit: `np.diff` of the step times (nominal, ALOHA stores none) and of the episode lengths;
3. split episodes 90/10 with a seeded permutation;
4. statistics of the training split: mean, std (ddof=0), min, max and `np.percentile` at
   0.1/1/10/50/90/99/99.9 per dimension; per colour channel for images (a `np.bincount`
   histogram per episode, so frames are never all in memory);
5. z-score normalize the low-dim channels;
6. edge-padded windows: per sample (episode, t) the K action rows `t..t+K-1`, clipped to the
   episode's last row; stored as chunkc stores them, an index of (episode, t, limit, 0) rows, not
   K copies (materializing K=100 copies would write 100 times the data);
7. write `data.h5` (per-step arrays, image frames one uncompressed chunk per frame as chunkc's
   default `image_compression = "none"` stores them, one h5py write per episode, episode ends,
   index) and `stats.json`, and fsync them (chunkc does too).

    python bench/numpy_pipeline.py SOURCE_DIR OUT_DIR --chunk 100 --fps 50 [--cameras cam0,cam1]

With `--zarr`, SOURCE_DIR is a Diffusion Policy zarr replay buffer instead (low-dim only): step 1
reads `data/action`, `data/state` and `meta/episode_ends` whole with zarr-python (vectorized:
whatever the chunking, each chunk is decoded once) and splits them at the episode ends.
"""

import argparse
import json
import os
from pathlib import Path

import h5py
import numpy as np

PCTS = [0.1, 1, 10, 50, 90, 99, 99.9]


def lowdim_stats(x):
    p = np.percentile(x, PCTS, axis=0)
    return {"mean": x.mean(0).tolist(), "std": x.std(0).tolist(), "min": x.min(0).tolist(),
            "max": x.max(0).tolist(), **{f"p{q}": v.tolist() for q, v in zip(PCTS, p)}}


def histogram_percentiles(hist, q):
    """Exact percentiles (numpy's linear definition) of integer data given as counts per value."""
    cdf = np.cumsum(hist)
    n = cdf[-1]
    pos = np.asarray(q) / 100 * (n - 1)
    lo, hi = np.floor(pos).astype(np.int64), np.ceil(pos).astype(np.int64)
    vlo, vhi = np.searchsorted(cdf, lo, side="right"), np.searchsorted(cdf, hi, side="right")
    return vlo + (vhi - vlo) * (pos - lo)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("source", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--chunk", type=int, default=100)
    ap.add_argument("--fps", type=float, default=50)
    ap.add_argument("--cameras", default="")
    ap.add_argument("--val-fraction", type=float, default=0.1)
    ap.add_argument("--zarr", action="store_true", help="SOURCE_DIR is a zarr replay buffer")
    args = ap.parse_args()
    cams = [c for c in args.cameras.split(",") if c]

    if args.zarr:
        import zarr

        root = zarr.open(str(args.source), mode="r")
        ends = np.asarray(root["meta/episode_ends"][:], np.int64)
        action = np.asarray(root["data/action"][:], np.float32)
        state = np.asarray(root["data/state"][:], np.float32)
        lengths = np.diff(ends, prepend=0)
        files = [None] * len(ends)
        assert not cams, "--zarr reads low-dim sources only"
    else:
        files = sorted(args.source.glob("episode_*.hdf5"), key=lambda p: int(p.stem.split("_")[1]))
        actions, states = [], []
        for p in files:
            with h5py.File(p, "r") as f:
                actions.append(f["action"][:])
                states.append(f["observations/qpos"][:])
        lengths = np.array([len(a) for a in actions])
        action, state = np.concatenate(actions), np.concatenate(states)
        del actions, states
    ends = np.cumsum(lengths)
    starts = ends - lengths

    # Audit: intervals of the (nominal) step times, per episode.
    t = (np.arange(len(action)) - np.repeat(starts, lengths)) / args.fps
    dt = np.diff(t)
    dt = dt[np.diff(np.repeat(np.arange(len(files)), lengths)) == 0]
    audit = {"median_dt": float(np.median(dt)), "max_dt": float(dt.max()),
             "bad": int((np.abs(dt - 1 / args.fps) > 0.5 / args.fps).sum())}

    rng = np.random.default_rng(0)
    n_val = int(round(args.val_fraction * len(files)))
    val = np.zeros(len(files), bool)
    val[rng.permutation(len(files))[:n_val]] = True
    train_rows = np.repeat(~val, lengths)

    stats = {"action": lowdim_stats(action[train_rows]),
             "observation.state": lowdim_stats(state[train_rows])}
    norm = {}
    for name, x in (("action", action), ("observation.state", state)):
        mean, std = np.array(stats[name]["mean"]), np.array(stats[name]["std"])
        norm[name] = ((x - mean) / np.maximum(std, 1e-8)).astype(np.float32)

    # Edge-padded windows: the K rows each sample reads, clipped to its episode's last row.
    ep_of_sample = np.repeat(np.arange(len(files)), lengths)
    t_of_sample = np.arange(len(action)) - starts[ep_of_sample]
    limit = np.minimum(args.chunk, lengths[ep_of_sample] - t_of_sample)
    index = np.stack([ep_of_sample, t_of_sample, limit, np.zeros_like(limit)], 1).astype(np.int64)
    for lo in range(0, len(index), 1 << 16):  # in blocks: (S, K) at once would be S*K*8 bytes
        e, t = ep_of_sample[lo:lo + (1 << 16)], t_of_sample[lo:lo + (1 << 16)]
        rows = starts[e, None] + np.minimum(t[:, None] + np.arange(args.chunk), lengths[e, None] - 1)
        assert (rows < ends[e, None]).all()  # the padded windows never leave their episode

    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "data.h5"
    with h5py.File(path, "w", track_order=False) as out:
        for name, x in norm.items():
            out.create_dataset(f"data/{name}", data=x, chunks=(max(1, 65536 // (4 * x.shape[1])), x.shape[1]))
        out["meta/episode_ends"] = ends
        out["index/train"] = index[~val[ep_of_sample]]
        out["index/val"] = index[val[ep_of_sample]]
        for cam in cams:
            hist = np.zeros((3, 256), np.int64)
            ds = None
            for e, p in enumerate(files):
                with h5py.File(p, "r") as f:
                    frames = f[f"observations/images/{cam}"][:]
                if ds is None:
                    ds = out.create_dataset(f"data/observation.{cam}", (ends[-1],) + frames.shape[1:],
                                            np.uint8, chunks=(1,) + frames.shape[1:])
                ds[starts[e]:ends[e]] = frames
                if not val[e]:
                    flat = frames.reshape(-1, 3)
                    for c in range(3):
                        hist[c] += np.bincount(flat[:, c], minlength=256)
            values = np.arange(256)
            n = hist.sum(1)
            mean = (hist * values).sum(1) / n
            std = np.sqrt((hist * (values - mean[:, None]) ** 2).sum(1) / n)
            stats[f"observation.{cam}"] = {
                "mean": mean.tolist(), "std": std.tolist(),
                "min": [int(np.flatnonzero(h)[0]) for h in hist],
                "max": [int(np.flatnonzero(h)[-1]) for h in hist],
                **{f"p{q}": [float(histogram_percentiles(h, q)) for h in hist] for q in PCTS}}
    (args.out / "stats.json").write_text(json.dumps({"stats": stats, "audit": audit}))
    for p in (path, args.out / "stats.json"):
        with open(p, "rb+") as f:
            os.fsync(f.fileno())


if __name__ == "__main__":
    main()
