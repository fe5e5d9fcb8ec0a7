"""Samples per second of four torch Datasets over the same (episode, t) samples, read through a
`torch.utils.data.DataLoader` (batch 32, shuffled with a fixed seed):

- `chunkc`: the loader chunkc generated for the profile (lazy HDF5 reads);
- `chunkc_mem`: the same with `in_memory=True`;
- `act`: a Dataset that opens the episode's HDF5 file on every item, as ACT's `EpisodicDataset`
  does (reads qpos[t], each camera's frame t and action[t:t+K], pads to K with zeros as ACT does,
  normalizes);
- `numpy_mem`: plain indexing of materialized in-memory numpy chunks (actions (S, K, A), pad
  masks, per-sample state and frames), the fastest a Python Dataset can be.

`act` and `numpy_mem` return the generated loader's keys, dtypes and shapes (with the
observations' `_is_pad` masks, `episode_index` and `frame_index`), so every mode pays the same
collate cost; that is checked before timing, and for `numpy_mem` the values too.

    python bench/loader_bench.py MODE PROFILE_DIR SOURCE_DIR --workers 2 --samples 4000

It reads at least `--samples` samples and for at least `--min-seconds` (2 s), so that the fast
in-memory modes are not timed over a few tens of milliseconds.

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
    """ACT's pattern: every item opens its episode file. Returns the keys, dtypes and shapes the
    generated loader returns (`check_like` verifies it), so both pay the same collate cost."""

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
        no_pad = np.zeros(1, dtype=bool)
        out = {"action": ((padded - am) / as_).astype(np.float32), "action_is_pad": is_pad,
               "observation.state": ((qpos - sm) / ss).astype(np.float32)[None],
               "observation.state_is_pad": no_pad}
        for c, img in images.items():
            out[f"observation.{c}"] = img[None]
            out[f"observation.{c}_is_pad"] = no_pad.copy()
        out["episode_index"] = self.ids[ep]
        out["frame_index"] = t
        return out


class InMemory(torch.utils.data.Dataset):
    """Materialized chunks: every sample's arrays are ready (the same keys, dtypes and shapes as
    the generated loader's samples; `check_like` verifies values too); __getitem__ only indexes."""

    def __init__(self, arrays):
        self.arrays = arrays

    def __len__(self):
        return len(self.arrays["action"])

    def __getitem__(self, i):
        return {k: v[i] for k, v in self.arrays.items()}


def materialize(ds):
    """(S, K, A) actions and everything else per sample, from the generated loader's dataset (an
    `act`-style profile: one observation frame, actions from the current step, edge padding).
    Integers are Python lists, as the loader returns Python ints."""
    if (ds.obs_history, ds.action_lead, ds.padding, ds.sampling) != (1, 0, "edge", "window"):
        raise SystemExit("numpy_mem materializes act-style profiles only")
    f = h5py.File(ds.path, "r")
    data = {n: f["data"][n][:] for n in f["data"]}
    idx = ds.index
    starts, ends = ds.episode_starts[idx[:, 0]], ds.episode_ends[idx[:, 0]]
    last = np.minimum(idx[:, 1] + idx[:, 2], ends - starts) - 1  # last valid step
    steps = np.minimum(idx[:, 1:2] + np.arange(ds.chunk_size), last[:, None])
    out = {"action": data["action"][starts[:, None] + steps],
           "action_is_pad": idx[:, 1:2] + np.arange(ds.chunk_size) > last[:, None]}
    for n, v in data.items():
        if n != "action":
            out[n] = v[starts + idx[:, 1]][:, None]
            out[n + "_is_pad"] = np.zeros((len(idx), 1), dtype=bool)
    out["episode_index"] = ds.episode_ids[idx[:, 0]].tolist()
    out["frame_index"] = idx[:, 1].tolist()
    return out


def check_like(bench, ds, values):
    """The bench Dataset's samples have the generated loader's keys, dtypes and shapes (and
    values, when `values`), at the first, last and a few random samples."""
    for i in [0, len(ds) - 1, *np.random.default_rng(1).integers(0, len(ds), 5).tolist()]:
        got, want = bench[i], ds[i]
        if set(got) != set(want):
            raise SystemExit(f"sample {i}: keys {sorted(got)} != {sorted(want)}")
        for k, w in want.items():
            g = got[k]
            if type(g) is not type(w) or np.shape(g) != np.shape(w) or \
                    getattr(g, "dtype", None) != getattr(w, "dtype", None):
                raise SystemExit(f"sample {i} {k}: {type(g)} {np.shape(g)} != {type(w)} {np.shape(w)}")
            if values and not np.array_equal(g, w):
                raise SystemExit(f"sample {i} {k}: values differ from the generated loader's")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("mode", choices=["chunkc", "chunkc_mem", "act", "numpy_mem"])
    ap.add_argument("profile", type=Path)
    ap.add_argument("source", type=Path)
    ap.add_argument("--workers", type=int, default=0)
    ap.add_argument("--samples", type=int, default=4000)
    ap.add_argument("--batch", type=int, default=32)
    ap.add_argument("--min-seconds", type=float, default=2.0,
                    help="keep reading past --samples until this long has passed")
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
        bench = OpenPerItem(args.source, samples, ds.episode_ids.tolist(), ds.chunk_size, cams, norm)
        check_like(bench, ds, values=False)
        ds = bench
    elif args.mode == "numpy_mem":
        bench = InMemory(materialize(ds))
        check_like(bench, ds, values=True)
        ds = bench

    gen = torch.Generator().manual_seed(0)
    extra = {"persistent_workers": True, "prefetch_factor": 4} if args.workers else {}
    loader = torch.utils.data.DataLoader(ds, batch_size=args.batch, shuffle=True, generator=gen,
                                         num_workers=args.workers, **extra)
    it = iter(loader)
    next(it)  # workers started, files opened: not part of the rate
    seen, start = 0, time.perf_counter()
    while seen < args.samples or time.perf_counter() - start < args.min_seconds:
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
