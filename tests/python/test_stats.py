"""stats.json against numpy on the training split, and the normalize/denormalize round trip."""

import json

import h5py
import numpy as np
import pytest

from conftest import import_loader, run_chunkc, write_spec

PROFILES = """
[profiles.dp]
preset = "diffusion_policy"

[profiles.act]
preset = "act"
fps = 10
chunk = 20

[profiles.half]
fps = 5
chunk = 4
normalize = { action = "zscore" }
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("stats")
    run_chunkc("build", "-q", write_spec(d, PROFILES))
    return d / "out"


def rel_close(got, want, rel=1e-6):
    got, want = np.asarray(got, dtype=np.float64), np.asarray(want, dtype=np.float64)
    assert got.shape == want.shape
    err = np.abs(got - want) / np.maximum(np.abs(want), 1e-12)
    assert np.all((err <= rel) | (np.abs(got - want) <= 1e-12)), (got, want)


@pytest.mark.parametrize("profile", ["dp", "act", "half"])
def test_lowdim_stats_match_numpy(built, raw, profile):
    meta = json.loads((built / profile / "meta.json").read_text())
    stats = json.loads((built / profile / "stats.json").read_text())
    factor = meta["rate"]["factor"]
    train = meta["split"]["train"]
    assert set(train).isdisjoint(meta["split"]["val"])
    for name, key in [("action", "action"), ("observation.state", "state")]:
        x = np.concatenate([raw.episode(key, e, factor) for e in train]).astype(np.float64)
        s = stats[name]
        assert s["count"] == len(x)
        rel_close(s["mean"], x.mean(axis=0))
        rel_close(s["std"], x.std(axis=0, ddof=0))  # documented: population std
        rel_close(s["min"], x.min(axis=0))
        rel_close(s["max"], x.max(axis=0))
        rel_close(s["p001"], np.percentile(x, 0.1, axis=0))
        rel_close(s["p999"], np.percentile(x, 99.9, axis=0))
        rel_close(s["q01"], np.percentile(x, 1, axis=0))
        rel_close(s["q99"], np.percentile(x, 99, axis=0))


def test_image_stats_match_numpy(built, raw):
    meta = json.loads((built / "dp" / "meta.json").read_text())
    s = json.loads((built / "dp" / "stats.json").read_text())["observation.image"]
    imgs = np.concatenate([raw.episode("img", e) for e in meta["split"]["train"]])
    px = imgs.reshape(-1, 3).astype(np.float64)
    assert s["count"] == len(imgs)
    rel_close(s["mean"], px.mean(axis=0))
    rel_close(s["std"], px.std(axis=0))
    rel_close(s["min"], px.min(axis=0))
    rel_close(s["max"], px.max(axis=0))
    rel_close(s["p001"], np.percentile(px, 0.1, axis=0))
    rel_close(s["p999"], np.percentile(px, 99.9, axis=0))


def test_validation_episodes_do_not_leak_into_stats(built, raw):
    meta = json.loads((built / "dp" / "meta.json").read_text())
    s = json.loads((built / "dp" / "stats.json").read_text())["action"]
    every = np.concatenate([raw.episode("action", e) for e in meta["episodes"]]).astype(np.float64)
    assert meta["split"]["val"], "the test needs a validation episode"
    assert s["count"] < len(every)
    assert not np.allclose(s["mean"], every.mean(axis=0), rtol=1e-9, atol=0)


@pytest.mark.parametrize("profile", ["dp", "act"])
def test_normalize_denormalize_round_trip(built, raw, profile):
    root = built / profile
    loader = import_loader(root)
    ds = loader.ChunkedDataset(str(root), "train")
    meta = ds.meta
    for name, key in [("action", "action"), ("observation.state", "state")]:
        x = raw.array(key).astype(np.float64)
        back = ds.denormalize(name, ds.normalize(name, x))
        n = meta["normalization"][name]
        if n["clip"]:
            # Clipping is lossy by design: check the values inside the percentile range.
            center, scale = np.asarray(n["center"]), np.asarray(n["scale"])
            inside = np.all(np.abs((x - center) / scale) <= 1, axis=1)
            x, back = x[inside], back[inside]
        assert np.all(np.abs(back - x) <= 1e-6 * np.maximum(np.abs(x), 1.0))
        # Stored float32 values denormalize back to the source within float32 precision.
        with h5py.File(root / meta["data_file"], "r") as f:
            stored = f["data/" + name][:]
        raw_all = raw.array(key).astype(np.float64)
        recovered = ds.denormalize(name, stored)
        ok = np.ones(len(raw_all), bool) if not n["clip"] else np.all(
            np.abs(ds.normalize(name, raw_all)) < 1, axis=1
        )
        scale = np.asarray(n["scale"])
        assert np.all(np.abs(recovered[ok] - raw_all[ok]) <= 1e-6 * np.maximum(np.abs(raw_all[ok]), scale))
