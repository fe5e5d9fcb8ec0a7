"""The generated loader's batch path: `__getitems__` returns exactly `[ds[i] for i in indices]` in
every sampling, padding and data format the loader supports, the frames it reads straight from the
HDF5 file equal h5py's reads in every storage layout, and DataLoader batches (0 and 2 workers)
equal manual collation of per-item samples."""

import shutil
import zlib

import h5py
import numpy as np
import pytest

from conftest import model_tier, import_loader, run_chunkc, write_spec

PROFILES = """
[profiles.act]
preset = "act"
fps = 10
chunk = 20

[profiles.dp]
preset = "diffusion_policy"

[profiles.zero]
chunk = 12
obs_history = 3
padding = "zero"
stride = 2
normalize = { action = "zscore", "observation.state" = "zscore" }

[profiles.mask]
chunk = 8
padding = "mask"
stride = 3
normalize = { action = "minmax", "observation.state" = "none" }

[profiles.trunc]
chunk = 10
obs_history = 2
padding = "truncate"

[profiles.hier]
chunk = 5
stride = 7
obs_history = 2
padding = "zero"
[profiles.hier.hierarchy]
coarse_seconds = 2.0

[profiles.seg]
chunk = 40
padding = "mask"
[profiles.seg.segment]
method = "velocity"
channel = "observation.state"
dims = [0]

[profiles.dp_zarr]
extends = "dp"
format = "zarr"

[profiles.zero_zarr]
extends = "zero"
format = "zarr"

[profiles.act_parquet]
extends = "act"
format = "parquet"
"""

HDF5 = ["act", "dp", "zero", "mask", "trunc", "hier", "seg"]
ALL = HDF5 + ["dp_zarr", "zero_zarr", "act_parquet"]
# Dataset options: lazy reads (low-dim held in memory), everything in memory, nothing cached.
MODES = {
    "lazy": {},
    "memory": {"in_memory": True},
    "uncached": {"cache_lowdim": False},
    "float": {"image_dtype": "float32"},
}


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("batches")
    run_chunkc("build", "-q", write_spec(d, PROFILES))
    return d / "out"


def assert_same_sample(got, want):
    assert list(got) == list(want)
    for key, w in want.items():
        g = got[key]
        assert type(g) is type(w), key
        if isinstance(w, np.ndarray):
            assert (g.dtype, g.shape) == (w.dtype, w.shape), key
            np.testing.assert_array_equal(g, w, err_msg=key)
        else:
            assert g == w, key


def batch_indices(ds, seed=0):
    """Random indices with repeats, the first and last samples, negative indices, and every
    sample whose actions or observations are padded (near an episode's start or end)."""
    n = len(ds)
    rng = np.random.default_rng(seed)
    ep, t, limit = ds.index[:, 0], ds.index[:, 1], ds.index[:, 2]
    length = ds.episode_ends[ep] - ds.episode_starts[ep]
    edge = np.flatnonzero((t < ds.obs_history + ds.action_lead) | (t + max(ds.chunk_size, *limit) >= length))
    picks = [*rng.integers(0, n, 200).tolist(), 0, n - 1, -1, -n, *edge.tolist()]
    picks += rng.choice(picks, 30).tolist()  # repeats
    rng.shuffle(picks)
    return picks


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("profile", ALL)
def test_getitems_equals_getitem(built, profile, mode):
    if mode == "float" and profile not in ("dp", "hier", "dp_zarr"):
        pytest.skip("float images: a few profiles are enough")
    loader = import_loader(built / profile)
    ds = loader.ChunkedDataset(str(built / profile), "train", **MODES[mode])
    picks = batch_indices(ds)
    if ds.padding in ("zero", "mask", "edge"):
        assert any(ds[i]["action_is_pad"].any() for i in picks), "the indices include padded windows"
    if ds.obs_history > 1 and ds.padding != "truncate":
        assert any(ds[i]["observation.state_is_pad"].any() for i in picks)
    for lo in range(0, len(picks), 64):
        chunk = picks[lo : lo + 64]
        got = ds.__getitems__(chunk)
        assert len(got) == len(chunk)
        for i, sample in zip(chunk, got):
            assert_same_sample(sample, ds[i])
    # A numpy array of indices, a single index and an empty batch.
    assert_same_sample(ds.__getitems__(np.array([len(ds) - 1]))[0], ds[len(ds) - 1])
    assert ds.__getitems__([]) == []
    with pytest.raises(IndexError):
        ds.__getitems__([0, len(ds)])
    with pytest.raises(IndexError):
        ds[-len(ds) - 1]


def test_lowdim_channels_are_held_in_memory_up_to_the_threshold(built, monkeypatch):
    loader = import_loader(built / "dp")
    ds = loader.ChunkedDataset(str(built / "dp"), "train")
    with h5py.File(built / "dp" / "data.h5", "r") as f:
        lowdim = {n for n, d in f["data"].items() if d.ndim == 2}
        assert set(ds._cache) == lowdim
        for name in lowdim:
            np.testing.assert_array_equal(ds._cache[name], f["data"][name][...])
        nbytes = sum(f["data"][n].size * f["data"][n].dtype.itemsize for n in lowdim)
    monkeypatch.setattr(loader, "LOWDIM_CACHE_BYTES", nbytes)
    assert set(loader.ChunkedDataset(str(built / "dp"), "train")._cache) == lowdim
    monkeypatch.setattr(loader, "LOWDIM_CACHE_BYTES", nbytes - 1)
    small = loader.ChunkedDataset(str(built / "dp"), "train")
    assert small._cache == {}
    assert set(loader.ChunkedDataset(str(built / "dp"), "train", cache_lowdim=True)._cache) == lowdim
    for i in (0, len(ds) // 2, len(ds) - 1):
        assert_same_sample(small[i], ds[i])


def test_samples_do_not_share_memory_with_the_dataset(built):
    loader = import_loader(built / "act")
    for options in ({}, {"in_memory": True}):
        ds = loader.ChunkedDataset(str(built / "act"), "train", **options)
        first = ds[0]
        for sample in (ds[0], ds.__getitems__([0, 1])[0]):
            for key, value in sample.items():
                if isinstance(value, np.ndarray):
                    value[...] = 0  # writable, and writing must not reach the dataset
        assert_same_sample(ds[0], first)


def rewrite_images(src, dst, write):
    """A copy of profile directory `src` whose image datasets `write(group, name, frames)` stores
    anew (the low-dim datasets and the index copied as they are)."""
    shutil.copytree(src, dst)
    (dst / "data.h5").unlink()
    with h5py.File(src / "data.h5", "r") as fin, h5py.File(dst / "data.h5", "w") as fout:
        for group in ("index", "meta"):
            fin.copy(fin[group], fout, group)
        data = fout.create_group("data")
        for name, d in fin["data"].items():
            if d.ndim == 4:
                write(data, name, d[...])
            else:
                fin.copy(d, data, name)
    return dst


def deflate_some_chunks(group, name, frames):
    """Deflated frame chunks written directly, every third one stored raw with the filter's bit
    set in its filter mask (as HDF5 does when deflate would not shrink a chunk)."""
    d = group.create_dataset(name, shape=frames.shape, dtype=frames.dtype,
                             chunks=(1,) + frames.shape[1:], compression="gzip")
    for r, frame in enumerate(frames):
        raw = frame.tobytes()
        if r % 3:
            d.id.write_direct_chunk((r, 0, 0, 0), zlib.compress(raw, 1), filter_mask=0)
        else:
            d.id.write_direct_chunk((r, 0, 0, 0), raw, filter_mask=1)


STORAGE = {
    # name: (writer, read with one pread per frame)
    "contiguous": (lambda g, n, x: g.create_dataset(n, data=x), True),
    "frame_chunks": (lambda g, n, x: g.create_dataset(n, data=x, chunks=(1,) + x.shape[1:]), True),
    "deflate_mask": (deflate_some_chunks, True),
    "shuffled": (lambda g, n, x: g.create_dataset(n, data=x, chunks=(1,) + x.shape[1:],
                                                  compression="gzip", shuffle=True), False),
    "many_frames": (lambda g, n, x: g.create_dataset(n, data=x, chunks=(7,) + x.shape[1:],
                                                     compression="gzip"), False),
}


@pytest.mark.parametrize("storage", STORAGE)
def test_frames_read_from_file_offsets_equal_h5py(built, tmp_path, storage):
    write, direct = STORAGE[storage]
    root = rewrite_images(built / "dp", tmp_path / "dp", write)
    loader = import_loader(root)
    ds = loader.ChunkedDataset(str(root), "train")
    assert ("observation.image" in ds._frames) == direct
    with h5py.File(root / "data.h5", "r") as f:
        frames = f["data/observation.image"][...]
    picks = batch_indices(ds, seed=1)
    reference = loader.ChunkedDataset(str(built / "dp"), "train")
    for i, sample in zip(picks, ds.__getitems__(picks)):
        want = reference[i]
        assert_same_sample(sample, want)
        assert_same_sample(ds[i], want)
        ep, t = ds.index[i, 0], ds.index[i, 1]
        steps = np.maximum(np.arange(t - ds.obs_history + 1, t + 1), 0)
        np.testing.assert_array_equal(sample["observation.image"], frames[ds.episode_starts[ep] + steps])


@pytest.mark.parametrize("workers", [0, 2])
@pytest.mark.parametrize("profile,options", [("hier", {}), ("dp", {"in_memory": True}), ("zero_zarr", {})])
def test_dataloader_batches_equal_manual_collation(built, profile, options, workers):
    torch = model_tier("torch")
    from torch.utils.data import DataLoader, default_collate

    loader = import_loader(built / profile)
    ds = loader.ChunkedDataset(str(built / profile), "train", **options)
    order = np.random.default_rng(2).permutation(len(ds))[:300].tolist()
    extra = {"persistent_workers": False} if workers else {}
    dl = DataLoader(ds, batch_size=32, sampler=order, num_workers=workers, **extra)
    batches = list(dl)
    assert len(batches) == (len(order) + 31) // 32
    for b, batch in enumerate(batches):
        want = default_collate([ds[i] for i in order[32 * b : 32 * (b + 1)]])
        assert list(batch) == list(want)
        for key in want:
            assert batch[key].dtype == want[key].dtype
            torch.testing.assert_close(batch[key], want[key], rtol=0, atol=0)


def test_make_dataloader_default_workers_fit_the_machine(built):
    model_tier("torch")
    import os

    loader = import_loader(built / "act")
    dl = loader.make_dataloader(str(built / "act"), "val", batch_size=8)
    cpus = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    assert dl.num_workers == min(4, cpus)
    assert dl.num_workers <= cpus
