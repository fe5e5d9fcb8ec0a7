"""The generated loader and validate.py on training mixtures (issue 40): `ds.source_names`,
`ds.episode_sources`, `ds.window_sources`, each sample's "source", the `<channel>_dim_mask` of
padded channels, per-source normalization (raw stored values normalized here, HDF5's stored
values denormalized with the window's source), `ds.sampler` (balanced source frequencies,
seeded draws, torch Sampler == the numpy fallback, DataLoader workers), validate.py's mixture
report; and a meta.json without "sources" behaving exactly as before.

How the templates are tested: `loader.py` and `validate.py` are "shared scripts" (src/render/
mod.rs `shared_script`): minijinja renders them with `version` alone, and the templates hold no
other template syntax (`render` asserts it), so substituting `{{ version }}` is the render, byte
for byte (checked against the files chunkc wrote before this issue's template edits). Each test
installs this checkout's rendered templates over the ones chunkc wrote, so it exercises the
templates whatever binary built the data.

Most tests run on fake mixtures made from real single-source builds (`fake_mixture`): meta.json
gains "episode_sources" (the first half of the stored episodes source "own", the rest "sim"),
"mixture" and "sources", with normalization tables fitted per source with numpy; HDF5 outputs
(stored normalized) get their arrays rewritten per source, and `pad` rewrites a zarr output's
raw arrays to padded widths. The tests at the end build real mixtures through chunkc (the
contract's [sources.own] + [sources.sim] spec) and are skipped, saying why, while the binary
refuses `[sources.*]`/`[mixture]`.
"""

import importlib.util
import json
import shutil
import subprocess
import sys

import h5py
import numpy as np
import pytest
import zarr

from conftest import PUSHT, REPO, model_tier, run_chunkc, write_mixture_spec, write_spec

NAMES = ["own", "sim"]
WEIGHTS = {"own": 0.7, "sim": 0.3}
DRAWS = 100_000

PROFILES = """
[profiles.zr]
preset = "diffusion_policy"
format = "zarr"

[profiles.pq]
preset = "act"
fps = 10
chunk = 20
format = "parquet"

[profiles.h5]
preset = "diffusion_policy"
format = "hdf5"

[profiles.zero]
chunk = 12
obs_history = 3
padding = "zero"
stride = 2
format = "zarr"
normalize = { action = "zscore", "observation.state" = "zscore" }

[profiles.mask]
chunk = 8
padding = "mask"
stride = 3
format = "zarr"
normalize = { action = "minmax", "observation.state" = "limits" }

[profiles.hier]
chunk = 5
stride = 7
obs_history = 2
padding = "zero"
[profiles.hier.hierarchy]
coarse_seconds = 2.0
"""
RAW_PROFILES = ["zr", "pq", "zero", "mask"]
ALL_PROFILES = RAW_PROFILES + ["h5", "hier"]


def render(template, version):
    """`templates/<template>` as chunkc renders a shared script: `{{ version }}`, the only
    template syntax in it, replaced."""
    text = (REPO / "templates" / template).read_text()
    assert text.count("{{") == text.count("{{ version }}") and "{%" not in text and "{#" not in text, \
        f"{template} holds template syntax beyond {{{{ version }}}}: render it with minijinja"
    return text.replace("{{ version }}", version)


def install_templates(root):
    """Replace the profile directory's loader.py and validate.py by this checkout's templates."""
    version = json.loads((root / "meta.json").read_text())["chunkc_version"]
    for name in ("loader.py", "validate.py"):
        (root / name).write_text(render(name + ".j2", version))
    return root


_MODULES = 0


def loader_module(root):
    """The profile directory's loader.py, imported under a fresh name."""
    global _MODULES
    _MODULES += 1
    spec = importlib.util.spec_from_file_location(f"mixture_loader_{_MODULES}", root / "loader.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def dataset(root, split="train", **kwargs):
    return loader_module(root).ChunkedDataset(str(root), split, **kwargs)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """Single-source Push-T builds (low-dim channels) in several formats and window rules."""
    d = tmp_path_factory.mktemp("mixture_single")
    run_chunkc("build", "-q", write_spec(d, PROFILES, channels={"action": "action", "observation.state": "state"},
                                        split="val_fraction = 0.2\nseed = 0"))
    return d / "out"


# --- the fake mixture ---------------------------------------------------------------------


def stored_rows(root, meta, name):
    """Every stored row of low-dim channel `name` as stored (float32), read without the loader."""
    array = meta["channels"][name].get("array", "data/" + name)
    if meta["data_format"] == "zarr":
        return np.asarray(zarr.open_group(str(root / meta["data_file"]), mode="r")[array][:])
    if meta["data_format"] == "hdf5":
        with h5py.File(root / meta["data_file"], "r") as f:
            return np.asarray(f["data/" + name][...])
    import pyarrow as pa
    import pyarrow.parquet as pq

    values = pq.read_table(root / meta["data_file"]).column(name).combine_chunks()
    while pa.types.is_fixed_size_list(values.type) or pa.types.is_list(values.type):
        values = values.flatten()
    return values.to_numpy(zero_copy_only=False).astype(np.float32).reshape(-1, *meta["channels"][name]["shape"])


def fit(mode, rows, clip):
    """A normalization table of `mode` fitted on `rows` (n, d) with numpy."""
    rows = np.asarray(rows, dtype=np.float64)
    if mode == "none":
        center, scale = np.zeros(rows.shape[1]), np.ones(rows.shape[1])
    elif mode in ("zscore", "lerobot_mean_std"):
        center, scale = rows.mean(axis=0), np.maximum(rows.std(axis=0), 1e-3)
    else:  # limits-like: [min, max] -> [-1, 1]
        center = (rows.max(axis=0) + rows.min(axis=0)) / 2
        scale = np.maximum((rows.max(axis=0) - rows.min(axis=0)) / 2, 1e-3)
    return {"mode": mode, "center": center.tolist(), "scale": scale.tolist(), "clip": bool(clip)}


def widened(table, width, wide):
    """`table` of a source of `width` dims as the mixture's `wide` dims: identity beyond."""
    out = dict(table)
    out["center"] = list(table["center"][:width]) + [0.0] * (wide - width)
    out["scale"] = list(table["scale"][:width]) + [1.0] * (wide - width)
    return out


def stats_of(rows):
    """stats.json's fields for raw rows (n, d)."""
    rows = np.asarray(rows, dtype=np.float64)
    q = {k: np.quantile(rows, v, axis=0).tolist() for k, v in
         {"p001": 0.001, "p999": 0.999, "q01": 0.01, "q99": 0.99, "q10": 0.1, "q50": 0.5, "q90": 0.9}.items()}
    return {"mean": rows.mean(axis=0).tolist(), "std": rows.std(axis=0).tolist(), "min": rows.min(axis=0).tolist(),
            "max": rows.max(axis=0).tolist(), **q, "count": len(rows)}


def oracle_weights(balance, weights, counts):
    """The contract's balanced weights, written out independently of the loader."""
    active = [s for s, n in enumerate(counts) if n > 0]
    p = np.zeros(len(counts))
    for s in active:
        p[s] = {"weights": weights[s], "steps": weights[s] * counts[s], "uniform": 1.0}[balance]
    return (p / p.sum() if p.sum() > 0 else p).tolist()


def fake_mixture(src, dst, balance="weights", stats="per_source", pad=None, sources_of=None):
    """A copy of the single-source profile `src` at `dst` made a 2-source mixture (see the module
    docstring). `sources_of(positions, meta)`: each stored episode's source (default: the first
    half "own"). `pad` {channel: W} (raw formats only): the stored arrays widened to W with zero
    columns, "sim" given one more real dim than "own" in `action` (action[0] - action[1])."""
    shutil.copytree(src, dst)
    install_templates(dst)
    meta = json.loads((dst / "meta.json").read_text())
    raw_values = meta.get("stored_values") == "raw"
    assert raw_values or not pad, "padding is faked on raw-values outputs only"
    ends = np.asarray(meta["episode_ends"], dtype=np.int64)
    starts = np.concatenate([[0], ends[:-1]])
    ids = np.asarray(meta["episodes"], dtype=np.int64)
    e = len(ids)
    episode_sources = np.asarray(sources_of(np.arange(e), meta) if sources_of else
                                 (np.arange(e) >= e // 2).astype(np.int64), dtype=np.int64)
    row_sources = np.repeat(episode_sources, ends - starts)
    train_ids = set(meta["split"]["train"])
    train_rows = np.concatenate([np.arange(starts[p], ends[p]) for p in range(e) if ids[p] in train_ids])
    lowdim = [n for n, c in meta["channels"].items() if c["kind"] == "lowdim"]
    # Raw rows per channel (HDF5: stored normalized with the pooled table, undone here).
    raw = {}
    for name in lowdim:
        rows = stored_rows(dst, meta, name).astype(np.float64).reshape(int(ends[-1]), -1)
        if not raw_values:
            p = meta["normalization"][name]
            rows = rows * np.asarray(p["scale"]) + np.asarray(p["center"])
        raw[name] = rows
    widths = {name: [raw[name].shape[1]] * 2 for name in lowdim}
    if pad:
        for name, wide in pad.items():
            rows = np.zeros((len(raw[name]), wide))
            rows[:, :raw[name].shape[1]] = raw[name]
            if name == "action":
                sim = row_sources == 1
                rows[sim, raw[name].shape[1]] = raw[name][sim, 0] - raw[name][sim, 1]
                widths[name] = [raw[name].shape[1], raw[name].shape[1] + 1]
            rows[row_sources == 0, widths[name][0]:] = 0
            raw[name] = rows
            meta["channels"][name]["shape"] = [wide]
            group = zarr.open_group(str(dst / meta["data_file"]), mode="r+")
            group.array(meta["channels"][name].get("array", "data/" + name), rows.astype(np.float32),
                        chunks=(256, wide), overwrite=True)
    wide = {name: raw[name].shape[1] for name in lowdim}
    tables = {s: {} for s in NAMES}
    source_stats = {s: {} for s in NAMES}
    pooled_stats = {}
    normalization = {}
    for name in lowdim:
        mode, clip = meta["normalization"][name]["mode"], meta["normalization"][name]["clip"]
        own_rows = []
        for s, sname in enumerate(NAMES):
            width = widths[name][s]
            rows = raw[name][train_rows[row_sources[train_rows] == s], :width]
            own_rows.append(rows)
            source_stats[sname][name] = stats_of(rows)
            tables[sname][name] = widened(fit(mode, rows, clip), width, wide[name])
        top = max(widths[name])
        union = np.concatenate([r[:, :top] if r.shape[1] >= top else
                                np.pad(r, ((0, 0), (0, top - r.shape[1])), constant_values=np.nan) for r in own_rows])
        # Pooled: per dimension over the sources that have it.
        per_dim = [stats_of(union[~np.isnan(union[:, d]), d:d + 1]) for d in range(top)]
        pooled = {k: [p[k][0] for p in per_dim] for k in per_dim[0] if k != "count"}
        pooled["count"] = int(max(p["count"] for p in per_dim))
        if len({p["count"] for p in per_dim}) > 1:
            pooled["dim_count"] = [p["count"] for p in per_dim]
        pooled_stats[name] = pooled
        per_dim_fit = [fit(mode, union[~np.isnan(union[:, d]), d:d + 1], clip) for d in range(top)]
        pooled_fit = {"mode": mode, "center": [f["center"][0] for f in per_dim_fit],
                      "scale": [f["scale"][0] for f in per_dim_fit], "clip": bool(clip)}
        normalization[name] = widened(pooled_fit, top, wide[name])
        if stats == "pooled":
            for s, sname in enumerate(NAMES):
                tables[sname][name] = widened(pooled_fit, widths[name][s], wide[name])
    if not raw_values:
        with h5py.File(dst / meta["data_file"], "r+") as f:
            for name in lowdim:
                center = np.stack([np.asarray(tables[s][name]["center"]) for s in NAMES])[row_sources]
                scale = np.stack([np.asarray(tables[s][name]["scale"]) for s in NAMES])[row_sources]
                y = (raw[name] - center) / scale
                f["data/" + name][...] = y.astype(np.float32).reshape(f["data/" + name].shape)
    index = {split: np.asarray(dataset_single(src, split).index) for split in ("train", "val")}
    counts = {split: np.bincount(episode_sources[index[split][:, 0]], minlength=2).tolist() for split in index}
    meta["normalization"] = normalization
    meta["episode_sources"] = episode_sources.tolist()
    meta["mixture"] = {"balance": balance, "stats": stats, "pad_to": dict(pad or {}), "source_names": NAMES,
                       "weights": {split: oracle_weights(balance, [WEIGHTS[n] for n in NAMES], counts[split])
                                   for split in counts}}
    meta["sources"] = {}
    for s, sname in enumerate(NAMES):
        mine = ids[episode_sources == s]
        offset = int(mine.min()) if len(mine) else 0
        meta["sources"][sname] = {
            "index": s, "format": "diffusion_policy_zarr", "path": str(PUSHT), "fingerprint": "fake",
            "weight": WEIGHTS[sname], "fps": 10.0, "id_offset": offset,
            "rate": {"source_fps": 10.0, "factor": 1, "conversion": {"kind": "decimate", "factor": 1}},
            "episodes": (mine - offset).tolist(),
            "split": {split: [int(i) - offset for i in mine if int(i) in set(meta["split"][split])]
                      for split in ("train", "val")},
            "widths": {name: widths[name][s] for name in lowdim},
            "num_samples": {split: counts[split][s] for split in counts},
            "normalization": tables[sname],
        }
        (dst / "sources" / sname).mkdir(parents=True, exist_ok=True)
        (dst / "sources" / sname / "stats.json").write_text(json.dumps(source_stats[sname]))
    (dst / "stats.json").write_text(json.dumps(pooled_stats))
    (dst / "meta.json").write_text(json.dumps(meta, indent=1))
    return dst


def dataset_single(root, split):
    """The single-source dataset of `root` with the loader chunkc wrote there."""
    return dataset(root, split)


def raw_view(src, dst):
    """A copy of a raw-values profile (mixture or not) read as one source with identity
    normalization: its samples are the windows' stored raw rows, through the single-source path
    alone."""
    shutil.copytree(src, dst)
    meta = json.loads((dst / "meta.json").read_text())
    assert meta["stored_values"] == "raw"
    for key in ("sources", "mixture", "episode_sources"):
        meta.pop(key, None)
    for name, p in meta["normalization"].items():
        width = len(np.asarray(p["center"]).reshape(-1))
        meta["normalization"][name] = {"mode": "none", "center": [0.0] * width, "scale": [1.0] * width, "clip": False}
    (dst / "meta.json").write_text(json.dumps(meta))
    return dst


@pytest.fixture(scope="module")
def mixtures(built, tmp_path_factory):
    """Fake mixtures of every built profile (the checkout's templates installed)."""
    d = tmp_path_factory.mktemp("mixtures")
    return {p: fake_mixture(built / p, d / p) for p in ALL_PROFILES}


@pytest.fixture(scope="module")
def padded(built, tmp_path_factory):
    """A fake zarr mixture with `action` padded to 4 (own 2 dims, sim 3) and
    `observation.state` to 6 (both 5)."""
    d = tmp_path_factory.mktemp("padded")
    return fake_mixture(built / "zr", d / "zr", pad={"action": 4, "observation.state": 6})


def table(meta, source, name):
    p = meta["sources"][source]["normalization"][name]
    return np.asarray(p["center"], dtype=np.float64), np.asarray(p["scale"], dtype=np.float64), bool(p["clip"])


def stack(samples, key):
    return np.stack([np.asarray(s[key]) for s in samples])


# --- a meta.json without "sources" --------------------------------------------------------


@pytest.mark.parametrize("profile", ALL_PROFILES)
def test_single_source_outputs_read_as_before(built, tmp_path, profile):
    """The checkout's loader on a single-source output: every sample of both splits bit for bit
    what the loader chunkc wrote gives (the previous template, until the binary is rebuilt with
    this one), no "source" key, the mixture attributes None; the sampler draws windows
    uniformly."""
    mine = install_templates(shutil.copytree(built / profile, tmp_path / profile))
    for split in ("train", "val"):
        before, after = dataset(built / profile, split), dataset(mine, split)
        samples_before = before.__getitems__(np.arange(len(before)))
        samples_after = after.__getitems__(np.arange(len(after)))
        assert len(samples_before) == len(samples_after) > 0
        for a, b in zip(samples_before, samples_after):
            assert list(a) == list(b) and "source" not in b
            for k in a:
                x, y = np.asarray(a[k]), np.asarray(b[k])
                assert x.dtype == y.dtype and np.array_equal(x, y, equal_nan=x.dtype.kind == "f"), k
        for name in ("action", "observation.state"):
            x = stack(samples_after, name)
            assert np.array_equal(before.denormalize(name, x), after.denormalize(name, x))
            assert np.array_equal(before.normalize(name, x), after.normalize(name, x))
        assert after.source_names is None and after.episode_sources is None
        assert after.window_sources is None and after.source_weights is None
        sampler = after.sampler(DRAWS, seed=5)
        assert len(sampler) == DRAWS and np.array_equal(list(sampler), sampler.indices)
        assert np.array_equal(sampler.indices, after.sampler(DRAWS, seed=5).indices)
        counts = np.bincount(sampler.indices, minlength=len(after))
        p = 1 / len(after)
        assert np.abs(counts - DRAWS * p).max() <= 5 * np.sqrt(DRAWS * p * (1 - p))


@pytest.mark.parametrize("profile", ["zr", "pq"])
def test_single_source_validate_prints_as_before(built, tmp_path, profile):
    """validate.py's printout and report on a single-source output are unchanged."""
    model_tier("torch")
    mine = install_templates(shutil.copytree(built / profile, tmp_path / profile))
    outputs = []
    for root, out in ((built / profile, tmp_path / "before"), (mine, tmp_path / "after")):
        proc = subprocess.run([sys.executable, str(root / "validate.py"), "--tiny", "--out", str(out)],
                              capture_output=True, text=True)
        assert proc.returncode in (0, 2), proc.stderr
        outputs.append((proc.returncode, proc.stdout, (out / "validate.json").read_text()))
    assert outputs[0] == outputs[1]
    assert "mixture" not in outputs[1][1]


# --- the loader on a mixture --------------------------------------------------------------


@pytest.mark.parametrize("profile", ALL_PROFILES)
def test_sources_of_episodes_windows_and_samples(mixtures, profile):
    root = mixtures[profile]
    meta = json.loads((root / "meta.json").read_text())
    for split in ("train", "val"):
        ds = dataset(root, split)
        assert ds.source_names == NAMES
        assert ds.episode_sources.dtype == np.int64 and ds.episode_sources.tolist() == meta["episode_sources"]
        assert ds.window_sources.dtype == np.int64 and len(ds.window_sources) == len(ds)
        # Index column 0 is the stored episode's position.
        assert np.array_equal(ds.window_sources, np.asarray(meta["episode_sources"])[ds.index[:, 0]])
        assert set(ds.window_sources.tolist()) == {0, 1}
        idx = np.random.default_rng(0).permutation(len(ds))[:64]
        batch = ds.__getitems__(idx)
        for i, s in zip(idx, batch):
            assert isinstance(s["source"], int) and s["source"] == ds.window_sources[i]
            one = ds[int(i)]
            assert list(one) == list(s)
            for k in s:
                assert np.array_equal(np.asarray(one[k]), np.asarray(s[k])), k
        # The episode ids of a source's windows are its episodes' (mixture ids).
        for s in range(2):
            mine = {e for e, src in zip(meta["episodes"], meta["episode_sources"]) if src == s}
            assert {b["episode_index"] for b in batch if b["source"] == s} <= mine
        assert not any(k.endswith("_dim_mask") for k in batch[0])


@pytest.mark.parametrize("profile", RAW_PROFILES)
def test_raw_values_are_normalized_with_each_windows_source(mixtures, tmp_path, profile):
    """Each window normalized here with its own source's table: (x - center) / scale (clipped
    when the table clips) of the window's raw stored rows (read through the single-source path
    with identity normalization), at every window; zero padding is 0 in the source's raw units,
    mask padding 0 in normalized units."""
    root = mixtures[profile]
    meta = json.loads((root / "meta.json").read_text())
    raw_root = raw_view(root, tmp_path / "raw")
    for split in ("train", "val"):
        ds, raw = dataset(root, split), dataset(raw_root, split)
        samples, raws = ds.__getitems__(np.arange(len(ds))), raw.__getitems__(np.arange(len(ds)))
        src = np.asarray([s["source"] for s in samples])
        assert np.array_equal(src, ds.window_sources)
        for name in ("action", "observation.state"):
            x = stack(raws, name).astype(np.float64)
            centers, scales, clips = zip(*(table(meta, n, name) for n in NAMES))
            center, scale = np.stack(centers)[src][:, None], np.stack(scales)[src][:, None]
            want = (x - center) / scale
            want = np.where(np.asarray(clips)[src][:, None, None], np.clip(want, -1, 1), want).astype(np.float32)
            if name == "action" and ds.padding == "mask":
                want[stack(samples, "action_is_pad")] = 0
            got = stack(samples, name)
            assert got.dtype == np.float32 and np.array_equal(got, want), name
            # Not the pooled table: the sources' tables differ.
            pooled = meta["normalization"][name]
            assert not np.allclose(got, ((x - pooled["center"]) / np.asarray(pooled["scale"])).astype(np.float32))
            # denormalize with each sample's source recovers the raw rows (those not clipped).
            back = ds.denormalize(name, got, src)
            keep = np.ones(got.shape, dtype=bool)
            if name == "action" and ds.padding == "mask":
                keep &= ~stack(samples, "action_is_pad")[..., None]
            keep &= ~(np.asarray(clips)[src][:, None, None] & (np.abs(got) >= 1))
            assert np.allclose(back[keep], x[keep], rtol=1e-6, atol=1e-4)


@pytest.mark.parametrize("profile", ["zr", "zero", "h5"])
def test_rows_read_per_sample_are_normalized_like_cached_ones(mixtures, padded, profile):
    """Low-dim channels read from the file per sample (`cache_lowdim=False`) or all in memory
    (`in_memory=True`) give the cached reading's samples: the rows read pick their sources."""
    root = padded if profile == "zr" else mixtures[profile]
    cached = dataset(root, "val")
    idx = np.random.default_rng(2).permutation(len(cached))[:200]
    want = cached.__getitems__(idx)
    for kwargs in ({"cache_lowdim": False}, {"in_memory": True}):
        got = dataset(root, "val", **kwargs).__getitems__(idx)
        for a, b in zip(want, got):
            assert list(a) == list(b)
            for k in a:
                assert np.array_equal(np.asarray(a[k]), np.asarray(b[k])), (kwargs, k)


@pytest.mark.parametrize("profile", ["h5", "hier"])
def test_hdf5_stored_values_denormalize_with_each_windows_source(built, mixtures, profile):
    """HDF5 stores values normalized per source by the build: read as stored, and
    `denormalize(.., source)` gives the raw values the single-source build denormalizes to."""
    root = mixtures[profile]
    for split in ("train", "val"):
        ds, single = dataset(root, split), dataset(built / profile, split)
        samples = ds.__getitems__(np.arange(len(ds)))
        before = single.__getitems__(np.arange(len(ds)))
        src = np.asarray([s["source"] for s in samples])
        keys = ["action", "observation.state"] + (["coarse_action"] if profile == "hier" else [])
        for key in keys:
            if profile == "hier" and key != "observation.state":
                # Coarse chunks of different lengths: compare sample by sample.
                for s, b in zip(samples, before):
                    pad = np.asarray(s[key + "_is_pad"])
                    got = ds.denormalize("action", s[key], s["source"])[~pad]
                    want = single.denormalize("action", b[key])[~pad]
                    assert np.allclose(got, want, rtol=1e-5, atol=1e-3)
                continue
            name = key
            got = ds.denormalize(name, stack(samples, key), src)
            want = single.denormalize(name, stack(before, key))
            if key == "action" and ds.padding != "edge":
                keep = ~stack(samples, "action_is_pad")
                got, want = got[keep], want[keep]
            assert np.allclose(got, want, rtol=1e-5, atol=1e-3), key


def test_normalize_and_denormalize_take_the_source(mixtures):
    ds = dataset(mixtures["zr"])
    meta = ds.meta
    x = np.random.default_rng(1).uniform(0, 500, size=(7, 16, 2))
    for s, name in enumerate(NAMES):
        center, scale, _ = table(meta, name, "action")
        assert np.allclose(ds.normalize("action", x, s), (x - center) / scale)
        assert np.allclose(ds.denormalize("action", ds.normalize("action", x, s), s), x)
    # One source per leading row (a batch's "source"), as numpy ints, a list or a tensor.
    src = np.array([0, 1, 1, 0, 1, 0, 0])
    per_row = ds.normalize("action", x, src)
    for i, s in enumerate(src):
        assert np.array_equal(per_row[i], ds.normalize("action", x[i], int(s)))
    assert np.array_equal(ds.normalize("action", x, src.tolist()), per_row)
    # Per step too: sources shaped like the leading axes.
    steps = np.broadcast_to(src[:, None], (7, 16))
    assert np.array_equal(ds.normalize("action", x, steps), per_row)
    assert np.allclose(ds.denormalize("action", per_row, src), x)
    with pytest.raises(ValueError, match="pass source="):
        ds.normalize("action", x)
    with pytest.raises(ValueError, match="pass source="):
        ds.denormalize("action", x)
    with pytest.raises(ValueError, match="not one of the 2 sources"):
        ds.normalize("action", x, 2)
    with pytest.raises(ValueError, match="does not lead"):
        ds.normalize("action", x, np.zeros(3, dtype=np.int64))
    # to_source takes the sample's own source.
    sample = ds[len(ds) - 1]
    assert np.array_equal(ds.to_source("action", sample["action"], sample),
                          ds.denormalize("action", sample["action"], sample["source"]))


def test_padded_channels_have_dim_masks_and_zero_pad_dims(padded, tmp_path):
    """`<channel>_dim_mask` (W,) bool per sample, true on the dims the window's source has;
    padding dims stay exactly 0 after normalization; the real dims normalized per source."""
    meta = json.loads((padded / "meta.json").read_text())
    widths = {name: [meta["sources"][n]["widths"][name] for n in NAMES] for name in ("action", "observation.state")}
    assert widths == {"action": [2, 3], "observation.state": [5, 5]}
    raw = dataset(raw_view(padded, tmp_path / "raw"))
    ds = dataset(padded)
    samples = ds.__getitems__(np.arange(len(ds)))
    raws = raw.__getitems__(np.arange(len(ds)))
    src = ds.window_sources
    keys = list(samples[0])
    assert keys[keys.index("frame_index") + 1:] == ["source", "action_dim_mask", "observation.state_dim_mask"]
    for name, wide in (("action", 4), ("observation.state", 6)):
        mask = stack(samples, name + "_dim_mask")
        assert mask.dtype == np.bool_ and mask.shape == (len(ds), wide)
        assert np.array_equal(mask, np.arange(wide)[None, :] < np.asarray(widths[name])[src][:, None])
        values = stack(samples, name)
        assert values.shape[-1] == wide
        assert (values[~np.broadcast_to(mask[:, None, :], values.shape)] == 0).all()
        centers, scales, _ = zip(*(table(meta, n, name) for n in NAMES))
        want = ((stack(raws, name).astype(np.float64) - np.stack(centers)[src][:, None])
                / np.stack(scales)[src][:, None]).astype(np.float32)
        assert np.array_equal(values, want)
    # Every sample's mask is a (W,) array of its own (no memory shared with the dataset).
    assert samples[0]["action_dim_mask"].shape == (4,)
    samples[0]["action_dim_mask"][:] = True
    assert not ds[0]["action_dim_mask"].all() or widths["action"][src[0]] == 4


def test_padded_batches_collate_to_b_w(padded):
    torch = model_tier("torch")
    ds = dataset(padded)
    dl = torch.utils.data.DataLoader(ds, batch_size=32, sampler=ds.sampler(64, seed=0))
    batch = next(iter(dl))
    assert batch["action_dim_mask"].shape == (32, 4) and batch["action_dim_mask"].dtype == torch.bool
    assert batch["observation.state_dim_mask"].shape == (32, 6)
    assert batch["source"].shape == (32,) and batch["source"].dtype == torch.int64


# --- the sampler --------------------------------------------------------------------------


@pytest.mark.parametrize("balance", ["weights", "steps", "uniform"])
def test_sampler_draws_sources_with_the_balanced_weights(built, tmp_path, balance):
    """100,000 draws: each source's count within 4 binomial standard deviations of N p, p the
    contract's balanced weight (== meta.json's, recomputed by the loader from the index); the
    windows of a source uniformly."""
    root = fake_mixture(built / "zr", tmp_path / "mix", balance=balance)
    meta = json.loads((root / "meta.json").read_text())
    for split in ("train", "val"):
        ds = dataset(root, split)
        counts = np.bincount(ds.window_sources, minlength=2)
        want = oracle_weights(balance, [WEIGHTS[n] for n in NAMES], counts.tolist())
        assert ds.source_weights.dtype == np.float64
        assert np.allclose(ds.source_weights, want, rtol=0, atol=1e-12)
        assert np.allclose(ds.source_weights, meta["mixture"]["weights"][split], rtol=0, atol=1e-12)
        sampler = ds.sampler(DRAWS, seed=11)
        drawn = np.bincount(ds.window_sources[sampler.indices], minlength=2)
        assert np.array_equal(drawn, np.bincount(sampler.sources, minlength=2))
        p = np.asarray(want)
        assert (np.abs(drawn - DRAWS * p) <= 4 * np.sqrt(DRAWS * p * (1 - p))).all(), (drawn, DRAWS * p)
        # Within a source, its windows uniformly.
        per_window = np.bincount(sampler.indices, minlength=len(ds))
        for s in range(2):
            mine = per_window[ds.window_sources == s]
            q = 1 / len(mine)
            assert np.abs(mine - drawn[s] * q).max() <= 5 * np.sqrt(drawn[s] * q * (1 - q))


def test_sampler_is_deterministic_per_seed_and_epoch(mixtures):
    ds = dataset(mixtures["zr"])
    a = ds.sampler(5000, seed=3)
    assert len(a) == 5000 and a.indices.dtype == np.int64 and list(a) == a.indices.tolist()
    assert all(isinstance(i, int) for i in list(a)[:10])
    assert np.array_equal(a.indices, ds.sampler(5000, seed=3, epoch=0).indices)
    assert np.array_equal(a.indices, dataset(mixtures["zr"]).sampler(5000, seed=3).indices)
    assert not np.array_equal(a.indices, ds.sampler(5000, seed=4).indices)
    b = ds.sampler(5000, seed=3, epoch=1)
    assert not np.array_equal(a.indices, b.indices)
    # The contract's generator: a source with the weights, then a window uniformly within it.
    rng = np.random.Generator(np.random.PCG64([3, 1]))
    sources = rng.choice(2, size=5000, p=ds.source_weights)
    assert np.array_equal(b.sources, sources)
    assert np.array_equal(ds.window_sources[b.indices], sources)
    # set_epoch redraws as a new sampler of that epoch would.
    a.set_epoch(1)
    assert np.array_equal(a.indices, b.indices) and a.epoch == 1
    assert len(ds.sampler(0, seed=0)) == 0


def test_sampler_gives_no_weight_to_a_source_without_windows(built, tmp_path):
    """Every validation episode in "own": "sim" has p = 0 in val and is never drawn there."""
    def sources_of(positions, meta):
        val = set(meta["split"]["val"])
        return np.array([0 if e in val else int(p % 2) for p, e in zip(positions, meta["episodes"])])

    for balance in ("weights", "steps", "uniform"):
        root = fake_mixture(built / "zr", tmp_path / balance, balance=balance, sources_of=sources_of)
        ds = dataset(root, "val")
        assert ds.source_weights.tolist() == [1.0, 0.0]
        assert ds.source_weights.tolist() == json.loads((root / "meta.json").read_text())["mixture"]["weights"]["val"]
        assert (ds.window_sources[ds.sampler(DRAWS, seed=0).indices] == 0).all()
        train = dataset(root, "train")
        assert (train.source_weights > 0).all() and abs(train.source_weights.sum() - 1) < 1e-12


def test_torch_sampler_equals_the_numpy_fallback(mixtures):
    """With torch the sampler is a torch Sampler (that pickles: its class is module-level once
    defined); without (torch blocked in a fresh process) a plain iterable; the same indices
    either way."""
    torch = model_tier("torch")
    root = mixtures["zr"]
    sampler = dataset(root).sampler(20000, seed=7, epoch=2)
    assert isinstance(sampler, torch.utils.data.Sampler)
    code = (
        "import sys, json, pickle\n"
        "if sys.argv[1] == 'numpy': sys.modules['torch'] = None\n"
        f"sys.path.insert(0, {str(root)!r})\n"
        "import loader\n"
        "ds = loader.ChunkedDataset(split='train')\n"
        "s = ds.sampler(20000, seed=7, epoch=2)\n"
        "assert (type(s) is loader._IndexSampler) == (sys.argv[1] == 'numpy'), type(s)\n"
        "assert (loader._DatasetBase is object) == (sys.argv[1] == 'numpy')\n"
        "assert len(s) == 20000 and list(pickle.loads(pickle.dumps(s))) == list(s)\n"
        "print(json.dumps(list(s)))\n"
    )
    for mode in ("numpy", "torch"):
        out = subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True)
        assert out.returncode == 0, out.stderr
        assert json.loads(out.stdout) == list(sampler), mode


@pytest.mark.parametrize("profile", ["zr", "h5"])
def test_dataloader_with_workers_yields_what_one_process_does(mixtures, padded, profile):
    torch = model_tier("torch")
    root = padded if profile == "zr" else mixtures[profile]
    ds = dataset(root)
    sampler = ds.sampler(600, seed=1)
    batches = []
    for workers in (0, 2):
        dl = torch.utils.data.DataLoader(ds, batch_size=64, sampler=sampler, num_workers=workers)
        batches.append(list(dl))
    assert len(batches[0]) == len(batches[1]) == 10
    for a, b in zip(*batches):
        assert list(a) == list(b)
        for k in a:
            assert torch.equal(a[k], b[k]), k
    sources = torch.cat([b["source"] for b in batches[0]]).numpy()
    assert np.array_equal(sources, ds.window_sources[sampler.indices])
    first = ds.__getitems__(sampler.indices[:64])
    assert np.array_equal(batches[1][0]["action"].numpy(), stack(first, "action"))


# --- validate.py --------------------------------------------------------------------------


def run_validate(root, out, *args):
    return subprocess.run([sys.executable, str(root / "validate.py"), "--tiny", "--out", str(out), *args],
                          capture_output=True, text=True)


@pytest.mark.parametrize("which", ["padded", "pq", "h5"])
def test_validate_reports_source_frequencies(mixtures, padded, tmp_path, which):
    model_tier("torch")
    root = padded if which == "padded" else mixtures[which]
    proc = run_validate(root, tmp_path / "v")
    assert proc.returncode in (0, 2), proc.stdout + proc.stderr
    assert "FAILED" not in proc.stderr, proc.stdout + proc.stderr
    report = json.loads((tmp_path / "v" / "validate.json").read_text())
    assert report["problems"] == []
    meta = json.loads((root / "meta.json").read_text())
    assert "mixture of 2 sources (weights balance)" in proc.stdout
    assert f"source frequencies over {DRAWS} draws" in proc.stdout
    for split in ("train", "val"):
        for s, name in enumerate(NAMES):
            entry = report["mixture"][split][name]
            p = meta["mixture"]["weights"][split][s]
            assert entry["weight"] == pytest.approx(p, abs=1e-12)
            assert abs(entry["frequency"] - p) <= 4 * np.sqrt(p * (1 - p) / DRAWS)
            assert any(line.split()[:2] == [split, name] for line in proc.stdout.splitlines())
    assert "LeRobot's normalizer is not compared" in proc.stdout


@pytest.mark.parametrize("profile", ["zr", "pq"])
def test_validate_passes_a_pooled_fit(built, tmp_path, profile):
    """`stats = "pooled"`: every source normalized with the pooled fit (cut to its width); the
    mode's guarantees then hold per dimension over the sources that have it."""
    model_tier("torch")
    root = fake_mixture(built / profile, tmp_path / "mix", stats="pooled", balance="steps",
                        pad={"action": 4} if profile == "zr" else None)
    meta = json.loads((root / "meta.json").read_text())
    own, sim = (meta["sources"][n]["normalization"]["observation.state"] for n in NAMES)
    assert own["center"] == sim["center"]
    proc = run_validate(root, tmp_path / "v")
    assert proc.returncode in (0, 2), proc.stdout + proc.stderr
    assert json.loads((tmp_path / "v" / "validate.json").read_text())["problems"] == []
    assert "(steps balance)" in proc.stdout


def test_validate_fails_when_the_weights_or_the_draws_are_off(padded, tmp_path):
    model_tier("torch")
    # meta.json's weights against the loader's.
    root = shutil.copytree(padded, tmp_path / "weights")
    meta = json.loads((root / "meta.json").read_text())
    meta["mixture"]["weights"]["train"] = [0.5, 0.5]
    (root / "meta.json").write_text(json.dumps(meta))
    proc = run_validate(root, tmp_path / "v1")
    assert proc.returncode == 1 and "mixture weights [0.5, 0.5] differ" in proc.stderr
    # A sampler whose draws miss the weights: validate's check, in process.
    sys.path.insert(0, str(padded))
    try:
        spec = importlib.util.spec_from_file_location("validate_mixture", padded / "validate.py")
        validate = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(validate)
    finally:
        sys.path.remove(str(padded))
    ds = validate.ChunkedDataset(str(padded), "train")
    problems, report = validate.mixture_checks(ds, 0)
    assert problems == []
    honest = ds.sampler

    def skewed(n, seed, epoch=0):
        s = honest(n, seed, epoch)
        s.indices = np.where(np.arange(n) % 50 == 0, np.flatnonzero(ds.window_sources == 1)[0], s.indices)
        return s

    ds.sampler = skewed
    problems, _ = validate.mixture_checks(ds, 0)
    assert any(p.startswith("train: source") and "+- 4 sd" in p for p in problems), problems


def test_validate_fails_when_a_sources_normalization_is_off(padded, tmp_path):
    """A source's table that is not its fit (the values it normalizes are off): check 1 names
    the source."""
    model_tier("torch")
    root = shutil.copytree(padded, tmp_path / "off")
    meta = json.loads((root / "meta.json").read_text())
    meta["sources"]["sim"]["normalization"]["observation.state"]["scale"][0] *= 0.5
    (root / "meta.json").write_text(json.dumps(meta))
    proc = run_validate(root, tmp_path / "v")
    assert proc.returncode == 1
    assert "observation.state (sim)[0]" in proc.stdout + proc.stderr


@pytest.mark.parametrize("stats_file, name, field, dim, message", [
    ("stats.json", "action", "mean", 2, "action[2]: stats.json mean"),  # sim's own dim, pooled
    ("stats.json", "action", "dim_count", 2, "action: stats.json counts"),
    ("sources/own/stats.json", "observation.state", "max", 1, "observation.state (own)[1]: stats.json max"),
    ("sources/sim/stats.json", "action", "std", 0, "action (sim)[0]: stats.json std"),
])
def test_validate_checks_pooled_and_per_source_stats(padded, tmp_path, stats_file, name, field, dim, message):
    model_tier("torch")
    root = shutil.copytree(padded, tmp_path / "off")
    stats = json.loads((root / stats_file).read_text())
    stats[name][field][dim] += 3 if field == "dim_count" else 5.0
    (root / stats_file).write_text(json.dumps(stats))
    proc = run_validate(root, tmp_path / "v")
    assert proc.returncode == 1 and message in proc.stderr, proc.stdout + proc.stderr


# --- real mixtures, built by chunkc (issue 40's contract) ---------------------------------

LOADER_PROFILES = """
[profiles.dp]
preset = "diffusion_policy"
fps = 10
format = "zarr"
[profiles.h5]
preset = "diffusion_policy"
fps = 10
format = "hdf5"
[profiles.pq]
preset = "diffusion_policy"
fps = 10
format = "parquet"
"""


def build_mixture(directory, balance="weights"):
    """The mixture of conftest.write_mixture_spec (G1 humanoid "own" + Push-T "sim", pad_to 32)
    built by chunkc, with `balance`."""
    mixture = f'balance = "{balance}"\npad_to = {{ action = 32, "observation.state" = 32 }}'
    spec = write_mixture_spec(directory, mixture=mixture, profiles=LOADER_PROFILES,
                              split="val_fraction = 0.2\nseed = 0")
    run_chunkc("build", "-q", spec)
    out = directory / "out"
    for profile in ("dp", "h5", "pq"):
        install_templates(out / profile)
    return out


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    return build_mixture(tmp_path_factory.mktemp("real_mixture"))


@pytest.mark.parametrize("profile", ["dp", "h5", "pq"])
def test_real_mixture_sources_masks_and_weights(real, profile):
    root = real / profile
    meta = json.loads((root / "meta.json").read_text())
    assert meta["mixture"]["source_names"] == NAMES
    widths = {n: meta["sources"][n]["widths"] for n in NAMES}
    assert widths == {"own": {"action": 26, "observation.state": 26}, "sim": {"action": 2, "observation.state": 5}}
    for split in ("train", "val"):
        ds = dataset(root, split)
        assert ds.source_names == NAMES
        # Stored episodes: source 0's, then source 1's.
        assert np.array_equal(ds.episode_sources, np.sort(ds.episode_sources))
        assert np.array_equal(ds.window_sources, ds.episode_sources[ds.index[:, 0]])
        assert np.allclose(ds.source_weights, meta["mixture"]["weights"][split], rtol=0, atol=1e-12)
        counts = np.bincount(ds.window_sources, minlength=2).tolist()
        assert counts == [meta["sources"][n]["num_samples"][split] for n in NAMES]
        assert np.allclose(ds.source_weights, oracle_weights("weights", [0.7, 0.3], counts), rtol=0, atol=1e-12)
        samples = ds.__getitems__(np.arange(len(ds)))
        src = np.asarray([s["source"] for s in samples])
        assert np.array_equal(src, ds.window_sources)
        for name in ("action", "observation.state"):
            mask = stack(samples, name + "_dim_mask")
            assert mask.shape == (len(ds), 32)
            assert np.array_equal(mask, np.arange(32)[None] < np.array([widths[n][name] for n in NAMES])[src][:, None])
            values = stack(samples, name)
            assert values.shape[-1] == 32
            assert (values[~np.broadcast_to(mask[:, None, :], values.shape)] == 0).all()
            assert np.isfinite(values).all()


def test_real_mixture_normalizes_raw_rows_per_source(real, tmp_path):
    """The zarr profile stores raw values: every window normalized with its source's table from
    meta.json; the sim source's raw rows are Push-T's own (10 Hz, no conversion)."""
    root = real / "dp"
    meta = json.loads((root / "meta.json").read_text())
    raw_root = raw_view(root, tmp_path / "raw")
    ds, raw = dataset(root), dataset(raw_root)
    samples, raws = ds.__getitems__(np.arange(len(ds))), raw.__getitems__(np.arange(len(ds)))
    src = ds.window_sources
    for name in ("action", "observation.state"):
        centers, scales, clips = zip(*(table(meta, n, name) for n in NAMES))
        x = stack(raws, name).astype(np.float64)
        want = (x - np.stack(centers)[src][:, None]) / np.stack(scales)[src][:, None]
        want = np.where(np.asarray(clips)[src][:, None, None], np.clip(want, -1, 1), want).astype(np.float32)
        assert np.array_equal(stack(samples, name), want), name
    # sim's first stored episode against the Push-T replay buffer.
    root_zarr = zarr.open(str(PUSHT), mode="r")
    ends = root_zarr["meta/episode_ends"][:]
    first_sim = int(np.flatnonzero(ds.episode_sources == 1)[0])
    local = int(ds.episode_ids[first_sim]) - meta["sources"]["sim"]["id_offset"]
    start = 0 if local == 0 else int(ends[local - 1])
    stored = stored_rows(root, meta, "observation.state")
    rows = stored[ds.episode_starts[first_sim]:ds.episode_ends[first_sim]]
    want = root_zarr["data/state"][start:int(ends[local])]
    assert np.array_equal(rows[:, :5], want) and (rows[:, 5:] == 0).all()


@pytest.mark.parametrize("balance", ["weights", "steps", "uniform"])
def test_real_mixture_sampler_frequencies(tmp_path, balance):
    out = build_mixture(tmp_path, balance)
    meta = json.loads((out / "dp" / "meta.json").read_text())
    for split in ("train", "val"):
        ds = dataset(out / "dp", split)
        p = np.asarray(meta["mixture"]["weights"][split])
        assert np.allclose(ds.source_weights, p, rtol=0, atol=1e-12)
        drawn = np.bincount(ds.window_sources[ds.sampler(DRAWS, seed=0).indices], minlength=2)
        assert (np.abs(drawn - DRAWS * p) <= 4 * np.sqrt(DRAWS * p * (1 - p))).all()


@pytest.mark.parametrize("profile", ["dp", "h5"])
def test_real_mixture_validate_passes(real, tmp_path, profile):
    model_tier("torch")
    proc = run_validate(real / profile, tmp_path / "v")
    assert proc.returncode in (0, 2), proc.stdout + proc.stderr
    report = json.loads((tmp_path / "v" / "validate.json").read_text())
    assert report["problems"] == [], report["problems"]
    assert set(report["mixture"]) == {"train", "val"} and set(report["mixture"]["train"]) == set(NAMES)
