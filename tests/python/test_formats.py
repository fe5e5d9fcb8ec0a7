"""Every output format read back with the reference readers (h5py, zarr-python, numcodecs) and
compared with the `index` layout's windows (bit for bit) and with the raw source."""

import json
import pickle

import h5py
import numpy as np
import pytest
import zarr

from conftest import bits, load_dataset as load, PUSHT, RawSource, run_chunkc, write_spec

DP = 'preset = "diffusion_policy"\n'
PROFILES = f"""
[profiles.index]
{DP}
[profiles.materialized]
{DP}layout = "materialized"
compression = "gzip"

[profiles.virtual]
{DP}layout = "virtual"
compression = "lzf"

[profiles.zarr]
{DP}format = "zarr"

[profiles.zarr3]
{DP}format = "zarr"
zarr_version = 3
compression = "zstd"

[profiles.act]
preset = "act"
fps = 10
chunk = 20
format = "act_episodes"

[profiles.act_zero]
preset = "act"
fps = 10
chunk = 20
padding = "zero"
layout = "virtual"

[profiles.act_zero_mat]
extends = "act_zero"
layout = "materialized"

[profiles.robomimic]
{DP}format = "robomimic_hdf5"

[profiles.parquet]
{DP}format = "parquet"
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("formats")
    # /chunks of the materialized and virtual layouts written a few hundred windows at a time
    # (4 MiB by default: one block for this dataset; the golden test covers that case).
    run_chunkc("build", "-q", write_spec(d, PROFILES), env={"CHUNKC_CHUNKS_BLOCK_BYTES": "4096"})
    return d / "out"


def same(a, b):
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(bits(a[key]), bits(b[key])), key


@pytest.mark.parametrize("profile", ["materialized", "virtual", "zarr", "parquet"])
def test_loader_windows_equal_the_index_layout(built, profile):
    for split in ("train", "val"):
        want, got = load(built / "index", split), load(built / profile, split)
        assert len(want) == len(got) > 0
        np.testing.assert_array_equal(want.index, got.index)
        for i in range(len(want)):
            same(want[i], got[i])


def index_windows(root):
    """Every window of both splits (train then val), as the loader returns them."""
    out = []
    for split in ("train", "val"):
        ds = load(root, split)
        out.extend(ds[i] for i in range(len(ds)))
    return out


@pytest.mark.parametrize("layout,pairs", [
    ("materialized", ("index", "materialized")),
    ("virtual", ("index", "virtual")),
    ("materialized", ("act_zero", "act_zero_mat")),
    ("virtual", ("act_zero", "act_zero")),
])
def test_chunks_group_equals_loader_windows(built, layout, pairs):
    reference, profile = pairs
    windows = index_windows(built / reference)
    meta = json.loads((built / profile / "meta.json").read_text())
    assert meta["layout"] == layout
    with h5py.File(built / profile / "data.h5", "r") as f:
        chunks = f["chunks"]
        assert f.attrs["layout"] == layout
        assert chunks.attrs["num_train"] + chunks.attrs["num_val"] == len(windows)
        if layout == "virtual":
            assert chunks["action"].is_virtual
        action, pad = chunks["action"][()], chunks["action_is_pad"][()]
        assert action.shape == (len(windows), meta["chunk_size"], 2)
        for i, w in enumerate(windows):
            assert np.array_equal(bits(action[i]), bits(w["action"])), i
            assert np.array_equal(pad[i], w["action_is_pad"]), i
            # Plain h5py indexing of one row returns the same chunk.
        assert np.array_equal(bits(chunks["action"][len(windows) - 1]), bits(windows[-1]["action"]))
        if layout == "materialized":
            state = chunks["observation.state"][()]
            for i, w in enumerate(windows):
                assert np.array_equal(bits(state[i]), bits(w["observation.state"]))
                assert np.array_equal(chunks["observation.state_is_pad"][i], w["observation.state_is_pad"])


def test_virtual_layout_is_small_on_lowdim(tmp_path):
    channels = {"action": "action", "observation.state": "state", "observation.keypoint": "keypoint"}
    profiles = f"[profiles.index]\n{DP}\n[profiles.virtual]\n{DP}layout = \"virtual\"\n"
    run_chunkc("build", "-q", write_spec(tmp_path, profiles, channels=channels))
    index = (tmp_path / "out/index/data.h5").stat().st_size
    virtual = (tmp_path / "out/virtual/data.h5").stat().st_size
    assert virtual < 1.1 * index, (virtual, index)


def test_zarr_is_a_replay_buffer_of_raw_values(built, raw):
    root = zarr.open_group(str(built / "zarr" / "data.zarr"), mode="r")
    ends = root["meta/episode_ends"][:]
    np.testing.assert_array_equal(ends, raw.ends)
    # Diffusion Policy's key names (PushTImageDataset reads `img`, `state`, `action`).
    mapping = {"action": "action", "observation.state": "state", "observation.image": "img"}
    for name, key in mapping.items():
        arr = root["data"][key]
        assert arr.shape[0] == ends[-1]
        assert arr.shape == raw.array(key).shape
        want = raw.array(key)
        if name == "observation.image":
            assert arr.dtype == np.uint8
            np.testing.assert_array_equal(arr[:], want.astype(np.uint8))
            assert arr.chunks[0] == 1
        else:
            assert np.array_equal(bits(arr[:]), bits(want.astype(np.float32)))
    assert root["data/action"].compressor.cname == "lz4"
    meta = json.loads((built / "zarr" / "meta.json").read_text())
    assert meta["stored_values"] == "raw" and meta["data_format"] == "zarr"


def test_zarr_v3_layout(built, raw):
    import numcodecs

    base = built / "zarr3" / "data.zarr"
    assert json.loads((base / "zarr.json").read_text())["zarr_format"] == 3
    meta = json.loads((base / "data/action/zarr.json").read_text())
    assert meta["shape"] == list(raw.array("action").shape)
    codec = meta["codecs"][-1]
    assert codec["name"] == "blosc" and codec["configuration"]["cname"] == "zstd"
    rows = meta["chunk_grid"]["configuration"]["chunk_shape"][0]
    chunk = numcodecs.Blosc().decode((base / "data/action/c/0/0").read_bytes())
    got = np.frombuffer(chunk, dtype="<f4").reshape(rows, 2)
    n = min(rows, len(raw.array("action")))
    assert np.array_equal(bits(got[:n]), bits(raw.array("action")[:n]))


def act_episode(path, start_ts):
    """ACT's EpisodicDataset.__getitem__ (imitate_episodes/utils.py), minus normalization."""
    with h5py.File(path, "r") as root:
        is_sim = root.attrs["sim"]
        original_action_shape = root["/action"].shape
        episode_len = original_action_shape[0]
        qpos = root["/observations/qpos"][start_ts]
        root["/observations/qvel"][start_ts]
        image_dict = {cam: root[f"/observations/images/{cam}"][start_ts] for cam in ["img"]}
        if is_sim:
            action = root["/action"][start_ts:]
            action_len = episode_len - start_ts
        else:
            action = root["/action"][max(0, start_ts - 1):]
            action_len = episode_len - max(0, start_ts - 1)
    padded_action = np.zeros(original_action_shape, dtype=np.float32)
    padded_action[:action_len] = action
    is_pad = np.zeros(episode_len)
    is_pad[action_len:] = 1
    return image_dict, qpos, padded_action, is_pad


def test_act_episodes_load_with_act_reader(built, raw):
    out = built / "act"
    files = sorted(out.glob("episode_*.hdf5"))
    assert len(files) == len(raw.ends)
    for e in range(len(raw.ends)):
        path = out / f"episode_{e}.hdf5"
        length = raw.ends[e] - raw.starts[e]
        for start_ts in (0, length // 2, length - 1):
            images, qpos, action, is_pad = act_episode(path, start_ts)
            np.testing.assert_array_equal(qpos, raw.episode("state", e)[start_ts])
            np.testing.assert_array_equal(images["img"], raw.episode("img", e)[start_ts].astype(np.uint8))
            np.testing.assert_array_equal(action[: length - start_ts], raw.episode("action", e)[start_ts:])
            assert is_pad.sum() == start_ts
    with open(out / "dataset_stats.pkl", "rb") as f:
        stats = pickle.load(f)
    for key in ("action_mean", "action_std", "qpos_mean", "qpos_std", "example_qpos"):
        assert key in stats
    assert stats["action_mean"].shape == (2,)


def test_robomimic_export_reads_like_robomimic(built, raw):
    out = built / "robomimic"
    meta = json.loads((out / "meta.json").read_text())
    assert meta["stored_values"] == "raw" and meta["data_format"] == "robomimic_hdf5"
    assert meta["data_file"] == "data.hdf5"
    ids = meta["episodes"]
    with h5py.File(out / "data.hdf5", "r") as f:
        data = f["data"]
        demos = sorted(data.keys(), key=lambda k: int(k[5:]))
        assert demos == [f"demo_{i}" for i in range(len(ids))] == [f"demo_{i}" for i in range(len(raw.ends))]
        assert data.attrs["total"] == raw.ends[-1]
        env = json.loads(data.attrs["env_args"])
        assert env == {"env_name": "", "type": 1, "env_kwargs": {}}
        for e, name in enumerate(demos):
            g = data[name]
            length = raw.ends[e] - raw.starts[e]
            assert g.attrs["num_samples"] == length
            assert g["actions"].dtype == np.float64
            np.testing.assert_array_equal(g["actions"][()], raw.episode("action", e).astype(np.float64))
            np.testing.assert_array_equal(g["obs/state"][()], raw.episode("state", e).astype(np.float32).astype(np.float64))
            assert g["obs/img"].dtype == np.uint8
            np.testing.assert_array_equal(g["obs/img"][()], raw.episode("img", e).astype(np.uint8))
            dones = g["dones"][()]
            assert dones.dtype == np.uint8 and dones.shape == (length,)
            assert dones[-1] == 1 and dones[:-1].sum() == 0
            assert g["rewards"].shape == (length,) and not g["rewards"][()].any()
        # robomimic's get_demos_for_filter_key: byte strings decoded to demo names.
        masks = {k: [elem.decode("utf-8") for elem in np.array(f["mask"][k][:])] for k in ("train", "valid")}
        for key, split in (("train", "train"), ("valid", "val")):
            want = [f"demo_{i}" for i, eid in enumerate(ids) if eid in meta["split"][split]]
            assert masks[key] == want
        assert masks["valid"] and masks["train"]


def test_robomimic_export_is_deterministic(built, tmp_path):
    run_chunkc("build", "-q", write_spec(tmp_path, "[profiles.robomimic]\n" + DP + 'format = "robomimic_hdf5"\n'))
    assert (tmp_path / "out/robomimic/data.hdf5").read_bytes() == (built / "robomimic/data.hdf5").read_bytes()


def test_parquet_is_a_lerobot_v3_dataset_of_raw_values(built, raw):
    import io

    import pyarrow.parquet as pq

    out = built / "parquet"
    meta = json.loads((out / "meta.json").read_text())
    assert meta["stored_values"] == "raw" and meta["data_format"] == "parquet"
    ids = meta["episodes"]
    info = json.loads((out / "meta/info.json").read_text())
    n, total = len(raw.ends), int(raw.ends[-1])
    assert info["codebase_version"] == "v3.0" and info["fps"] == 10
    assert info["total_episodes"] == n and info["total_frames"] == total and info["total_tasks"] == 1
    assert info["chunks_size"] == 1000 and info["splits"] == {"train": f"0:{n}"}
    assert info["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert info["video_path"] is None and info["robot_type"] is None
    assert info["features"]["action"] == {"dtype": "float32", "shape": [2], "names": None}
    assert info["features"]["observation.image"]["dtype"] == "image"
    assert info["features"]["observation.image"]["shape"] == list(raw.array("img").shape[1:])
    for key in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
        assert key in info["features"]

    path = out / "data/chunk-000/file-000.parquet"
    f = pq.ParquetFile(path)
    assert f.metadata.num_row_groups == n
    for e in range(n):
        assert f.metadata.row_group(e).num_rows == raw.ends[e] - raw.starts[e]
    table = pq.read_table(path)
    assert table.num_rows == total
    np.testing.assert_array_equal(table.column("index").to_numpy(), np.arange(total))
    frame = table.column("frame_index").to_numpy()
    episode = table.column("episode_index").to_numpy()
    ts = table.column("timestamp").to_numpy()
    assert ts.dtype == np.float32
    for e in range(n):
        lo, hi = raw.starts[e], raw.ends[e]
        np.testing.assert_array_equal(frame[lo:hi], np.arange(hi - lo))
        assert (episode[lo:hi] == ids[e]).all()
        np.testing.assert_array_equal(ts[lo:hi], (np.arange(hi - lo) / 10).astype(np.float32))
    assert (table.column("task_index").to_numpy() == 0).all()
    for name, key in (("action", "action"), ("observation.state", "state")):
        got = np.stack(table.column(name).to_numpy(zero_copy_only=False))
        assert np.array_equal(bits(got.astype(np.float32)), bits(raw.array(key).astype(np.float32))), name
    images = table.column("observation.image").to_pylist()
    assert images[0]["path"] is None
    try:
        from PIL import Image
    except ImportError:
        Image = None
    want = raw.array("img").astype(np.uint8)
    for i in (0, total // 2, total - 1):
        png = images[i]["bytes"]
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        if Image is not None:
            np.testing.assert_array_equal(np.asarray(Image.open(io.BytesIO(png))), want[i])

    episodes = pq.read_table(out / "meta/episodes/chunk-000/file-000.parquet").to_pydict()
    assert episodes["episode_index"] == ids
    assert episodes["tasks"] == [["chunkc"]] * n
    assert episodes["length"] == list(raw.ends - raw.starts)
    assert episodes["dataset_from_index"] == list(raw.starts)
    assert episodes["dataset_to_index"] == list(raw.ends)
    assert episodes["data/chunk_index"] == [0] * n and episodes["data/file_index"] == [0] * n
    # As LeRobot's writer leaves it: the task strings are pandas' index (LeRobot reads
    # `tasks.iloc[task_index].name`).
    import pandas as pd

    tasks = pd.read_parquet(out / "meta/tasks.parquet")
    assert list(tasks.index) == ["chunkc"] and list(tasks.task_index) == [0]
    stats = json.loads((out / "meta/stats.json").read_text())
    assert set(stats) == {"action", "observation.state", "observation.image"}
    assert len(stats["action"]["mean"]) == 2


def test_parquet_is_deterministic(built, tmp_path):
    run_chunkc("build", "-q", write_spec(tmp_path, "[profiles.parquet]\n" + DP + 'format = "parquet"\n'))
    for rel in ("data/chunk-000/file-000.parquet", "chunkc_index.parquet", "meta/info.json",
                "meta/episodes/chunk-000/file-000.parquet", "meta/tasks.parquet", "meta/stats.json"):
        assert (tmp_path / "out/parquet" / rel).read_bytes() == (built / "parquet" / rel).read_bytes(), rel
