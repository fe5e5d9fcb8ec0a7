"""Samples per second of four torch Datasets over the same (episode, t) samples, read through a
`torch.utils.data.DataLoader` (batch 32, shuffled with a fixed seed):

- `chunkc`: the loader chunkc generated for the profile (lazy HDF5 reads);
- `chunkc_mem`: the same with `in_memory=True`;
- `act`: a Dataset that opens the episode's HDF5 file on every item, as ACT's `EpisodicDataset`
  does (reads qpos[t], each camera's frame t and action[t:t+K], pads to K, normalizes);
- `numpy_mem`: plain indexing of materialized in-memory numpy chunks (actions (S, K, A), pad
  masks, per-sample state and frames), the fastest a Python Dataset can be.

    python bench/loader_bench.py MODE PROFILE_DIR SOURCE_DIR --workers 2 --samples 4000

Prints one JSON line: {"mode", "workers", "samples", "seconds", "samples_per_s"}.
"""

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import torch
import torch.utils.data


def load_generated(profile):
    spec = importlib.util.spec_from_file_location("chunkc_bench_loader", profile / "loader.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return mod


class OpenPerItem(torch.utils.data.Dataset):
    """ACT's pattern: every item opens its episode file."""

    def __init__(self, source, samples, ids, chunk, cams, norm):
        self.source, self.samples, self.ids = source, samples, ids
        self.chunk, self.cams, self.norm = chunk, cams, norm

    def __len__(self):
        return len(self.samples)

    def __getitem__(self, i):
        ep, t = self.samples[i]
        with h5py.File(self.source / f"episode_{self.ids[ep]}.hdf5", "r") as f:
            qpos = f["observations/qpos"][t]
            images = {c: f[f"observations/images/{c}"][t] for c in self.cams}
            action = f["action"][t:t + self.chunk]
        k = len(action)
        padded = np.zeros((self.chunk, action.shape[1]), np.float32)
        padded[:k] = action
        is_pad = np.arange(self.chunk) >= k
        (am, as_), (sm, ss) = self.norm["action"], self.norm["observation.state"]
        out = {"action": ((padded - am) / as_).astype(np.float32), "action_is_pad": is_pad,
               "observation.state": ((qpos - sm) / ss).astype(np.float32)[None]}
        for c, img in images.items():
            out[f"observation.{c}"] = img[None]
        return out


class InMemory(torch.utils.data.Dataset):
    """Materialized chunks: every sample's arrays are ready; __getitem__ only indexes."""

    def __init__(self, arrays):
        self.arrays = arrays

    def __len__(self):
        return len(self.arrays["action"])

    def __getitem__(self, i):
        return {k: v[i] for k, v in self.arrays.items()}


def materialize(ds):
    """(S, K, A) actions and everything else per sample, from the generated loader's dataset."""
    f = h5py.File(ds.path, "r")
    data = {n: f["data"][n][:] for n in f["data"]}
    idx = ds.index
    starts, ends = ds.episode_starts[idx[:, 0]], ds.episode_ends[idx[:, 0]]
    rows = starts[:, None] + np.minimum(idx[:, 1:2] + np.arange(ds.chunk_size), (ends - starts - 1)[:, None])
    out = {"action": data["action"][rows],
           "action_is_pad": np.arange(ds.chunk_size)[None] >= idx[:, 2:3]}
    for n, v in data.items():
        if n != "action":
            out[n] = v[starts + idx[:, 1]][:, None]
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["chunkc", "chunkc_mem", "act", "numpy_mem"])
    ap.add_argument("profile", type=Path)
    ap.add_argument("source", type=Path)
    ap.add_argument("--workers", type=int, default=0)
    ap.add_argument("--samples", type=int, default=4000)
    ap.add_argument("--batch", type=int, default=32)
    args = ap.parse_args()
    torch.set_num_threads(1)

    mod = load_generated(args.profile)
    ds = mod.ChunkedDataset(args.profile, "train", in_memory=args.mode == "chunkc_mem")
    if args.mode == "act":
        meta = ds.meta
        cams = [n.split(".", 1)[1] for n, c in meta["channels"].items() if c["kind"] == "image"]
        norm = {n: (np.asarray(p["center"], np.float32), np.asarray(p["scale"], np.float32))
                for n, p in meta["normalization"].items()}
        samples = [(int(e), int(t)) for e, t in ds.index[:, :2]]
        ds = OpenPerItem(args.source, samples, ds.episode_ids.tolist(), ds.chunk_size, cams, norm)
    elif args.mode == "numpy_mem":
        ds = InMemory(materialize(ds))

    gen = torch.Generator().manual_seed(0)
    extra = {"persistent_workers": True, "prefetch_factor": 4} if args.workers else {}
    loader = torch.utils.data.DataLoader(ds, batch_size=args.batch, shuffle=True, generator=gen,
                                         num_workers=args.workers, **extra)
    it = iter(loader)
    next(it)  # workers started, files opened: not part of the rate
    seen, start = 0, time.perf_counter()
    while seen < args.samples:
        try:
            batch = next(it)
        except StopIteration:
            it = iter(loader)
            continue
        seen += len(batch["action"])
    seconds = time.perf_counter() - start
    print(json.dumps({"mode": args.mode, "workers": args.workers, "samples": seen,
                      "seconds": seconds, "samples_per_s": seen / seconds}))


if __name__ == "__main__":
    main()
