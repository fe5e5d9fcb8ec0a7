"""Channels of any per-step rank ((T, D), (T, a, b), (T, N, 3)) in every format, layout and
normalization mode: every window equals the `hdf5` index layout's, and that layout's windows
equal numpy's over the source (a replay buffer written here with zarr-python)."""

import json

import numpy as np
import pytest
import pyarrow.parquet as pq

import reference
from conftest import bits, load_dataset as load, make_replay_buffer, run_chunkc, write_spec

MODES = ["zscore", "limits", "minmax", "quantile", "lerobot_mean_std", "lerobot_min_max", "none"]
# format keys of each profile beside the reference (`hdf5`, layout `index`)
FORMATS = {
    "index": 'format = "hdf5"',
    "materialized": 'format = "hdf5"\nlayout = "materialized"',
    "virtual": 'format = "hdf5"\nlayout = "virtual"',
    "zarr": 'format = "zarr"',
    "parquet": 'format = "parquet"',
}
CHANNELS = {
    "action": "action",
    "observation.state": "state",  # (T, 4)
    "observation.pose": "pose",  # (T, 3, 2)
    "observation.cloud": "cloud",  # (T, 16, 3): a point cloud
}
SHAPES = {"action": (3,), "state": (4,), "pose": (3, 2), "cloud": (16, 3)}


def episodes(seed=0, lengths=(23, 9, 31, 17, 26, 12)):
    rng = np.random.default_rng(seed)
    out = []
    for n in lengths:
        ep = {}
        for key, shape in SHAPES.items():
            # Per-dimension offsets and scales, so that a statistic laid out in the wrong order
            # (or broadcast over the wrong axis) gives other windows.
            dims = int(np.prod(shape))
            base = np.arange(dims, dtype=np.float64).reshape(shape) * 3.0 - 7.0
            scale = 1.0 + np.arange(dims).reshape(shape) % 5
            ep[key] = (base + scale * rng.standard_normal((n,) + shape)).astype(np.float32)
        out.append(ep)
    return out


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("ranks")
    source = make_replay_buffer(d / "ranks.zarr", episodes())
    profiles = []
    for mode in MODES:
        norm = ", ".join(f'"{name}" = "{mode}"' for name in CHANNELS)
        for fmt, keys in FORMATS.items():
            profiles.append(f'[profiles.{mode}_{fmt}]\npreset = "diffusion_policy"\nchunk = 5\n{keys}\n'
                            f"normalize = {{ {norm} }}\n")
    spec = write_spec(d, "\n".join(profiles), source=source, channels=CHANNELS,
                      split="val_fraction = 0.34\nseed = 3")
    run_chunkc("build", "-q", spec)
    return d / "out", source


def raw_arrays(source):
    import zarr

    root = zarr.open(str(source), mode="r")
    ends = root["meta/episode_ends"][:]
    starts = np.concatenate([[0], ends[:-1]])
    return {k: root["data"][k][:] for k in SHAPES}, starts, ends


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("fmt", [f for f in FORMATS if f != "index"])
def test_windows_equal_the_index_layout(built, mode, fmt):
    out, _ = built
    for split in ("train", "val"):
        want, got = load(out / f"{mode}_index", split), load(out / f"{mode}_{fmt}", split)
        assert len(want) == len(got) > 0
        for i in range(len(want)):
            a, b = want[i], got[i]
            assert a.keys() == b.keys()
            for key in a:
                assert np.array_equal(bits(a[key]), bits(b[key])), (split, i, key)
        # The batched path returns the same samples.
        idx = list(range(0, len(got), 3))
        for i, s in zip(idx, got.__getitems__(idx)):
            for key in s:
                assert np.array_equal(bits(s[key]), bits(got[i][key])), (split, i, key)


@pytest.mark.parametrize("mode", MODES)
def test_index_layout_windows_and_statistics_match_numpy(built, mode):
    out, source = built
    data, starts, ends = raw_arrays(source)
    root = out / f"{mode}_index"
    meta = json.loads((root / "meta.json").read_text())
    stats = json.loads((root / "stats.json").read_text())
    train = meta["split"]["train"]
    for name, key in CHANNELS.items():
        shape = SHAPES[key]
        assert tuple(meta["channels"][name]["shape"]) == shape
        rows = np.concatenate([data[key][starts[e]:ends[e]] for e in train]).astype(np.float64)
        # Statistics keep the channel's shape: what numpy's reductions over time give.
        np.testing.assert_allclose(stats[name]["mean"], rows.mean(axis=0), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(stats[name]["std"], rows.std(axis=0), rtol=1e-9)
        np.testing.assert_array_equal(stats[name]["min"], rows.min(axis=0))
        np.testing.assert_allclose(stats[name]["q99"], np.percentile(rows, 99, axis=0), rtol=1e-9)
        # The normalization of every mode, from numpy over the flattened steps (reference.py).
        center, scale, clip = reference.norm_params(mode, rows.reshape(len(rows), -1))
        params = meta["normalization"][name]
        assert np.asarray(params["center"]).shape == shape
        np.testing.assert_allclose(np.asarray(params["center"]).reshape(-1), center, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(np.asarray(params["scale"]).reshape(-1), scale, rtol=1e-9)
        assert params["clip"] == clip
    ds = load(root)
    assert len(ds) > 0
    for i in range(len(ds)):
        s = ds[i]
        e = int(s["episode_index"])
        t = int(s["frame_index"])
        lo = starts[e]
        for name, key in CHANNELS.items():
            if name == "action":
                continue
            steps = np.maximum(np.arange(t - 1, t + 1), 0)  # diffusion_policy: 2 observations
            want = data[key][lo + steps].astype(np.float64)
            assert s[name].shape == (2,) + SHAPES[key]
            params = meta["normalization"][name]
            center = np.asarray(params["center"], dtype=np.float64).reshape(-1)
            scale = np.asarray(params["scale"], dtype=np.float64).reshape(-1)
            expected = (want.reshape(2, -1) - center) / scale
            if params["clip"]:
                expected = np.clip(expected, -1, 1)
            np.testing.assert_allclose(s[name].reshape(2, -1), expected, rtol=1e-5, atol=1e-5)
            if not params["clip"]:
                np.testing.assert_allclose(ds.denormalize(name, s[name]), want, rtol=1e-5,
                                           atol=1e-5 * (1 + np.abs(want)).max())
            # normalize(denormalize(x)) == x: the round trip the guide asks for.
            back = ds.normalize(name, ds.denormalize(name, s[name]))
            np.testing.assert_allclose(back, s[name], atol=1e-6)


def test_lerobot_export_keeps_the_feature_shape(built):
    out, source = built
    root = out / "zscore_parquet"
    info = json.loads((root / "meta" / "info.json").read_text())
    stats = json.loads((root / "meta" / "stats.json").read_text())
    table = pq.read_table(next((root / "data").rglob("*.parquet")))
    data, starts, ends = raw_arrays(source)
    for name, key in CHANNELS.items():
        shape = SHAPES[key]
        assert tuple(info["features"][name]["shape"]) == shape
        assert np.asarray(stats[name]["mean"]).shape == shape
        # Nested lists, one level per axis, as LeRobot's Array2D features are stored.
        values = np.asarray(table.column(name).to_pylist(), dtype=np.float32)
        assert values.shape == (len(data[key]),) + shape
        np.testing.assert_array_equal(values, data[key])


def test_dp_normalizer_flattens_and_robomimic_stats_keep_the_shape(tmp_path):
    source = make_replay_buffer(tmp_path / "ranks.zarr", episodes(seed=1))
    profiles = '[profiles.dp]\npreset = "diffusion_policy"\nchunk = 4\nstats_formats = ["diffusion_policy", "robomimic", "lerobot"]\n'
    run_chunkc("build", "-q", write_spec(tmp_path, profiles, source=source, channels=CHANNELS))
    root = tmp_path / "out" / "dp"
    dp = json.loads((root / "dp_normalizer.json").read_text())
    assert np.asarray(dp["pose"]["scale"]).shape == (6,)
    assert np.asarray(dp["cloud"]["input_stats"]["mean"]).shape == (48,)
    rm = json.loads((root / "robomimic_stats.json").read_text())
    obs = rm["v0.5"]["obs_normalization_stats"]
    assert np.asarray(obs["cloud"]["offset"]).shape == (1, 16, 3)
    assert np.asarray(obs["state"]["offset"]).shape == (1, 4)
    le = json.loads((root / "lerobot_stats.json").read_text())
    assert np.asarray(le["observation.pose"]["q01"]).shape == (3, 2)


@pytest.mark.parametrize("fmt", ["hdf5", "zarr", "parquet"])
def test_pusht_keypoint_with_the_diffusion_policy_preset(tmp_path, fmt):
    """Diffusion Policy's own low-dim Push-T observes `keypoint` (T, 9, 2)."""
    channels = {"action": "action", "observation.state": "state", "observation.keypoint": "keypoint"}
    profiles = f'[profiles.ref]\npreset = "diffusion_policy"\n[profiles.dp]\npreset = "diffusion_policy"\nformat = "{fmt}"\n'
    run_chunkc("build", "-q", write_spec(tmp_path, profiles, channels=channels))
    want, got = load(tmp_path / "out" / "ref"), load(tmp_path / "out" / "dp")
    assert len(got) == len(want) > 0
    for i in range(0, len(got), 7):
        s = got[i]
        assert s["observation.keypoint"].shape == (2, 9, 2)
        for key in s:
            assert np.array_equal(bits(s[key]), bits(want[i][key])), (i, key)
        raw = got.denormalize("observation.keypoint", s["observation.keypoint"])
        assert raw.shape == (2, 9, 2) and 0 <= raw.min() and raw.max() <= 512
