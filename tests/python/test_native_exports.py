"""Native exports opened the way their codebases open them, by the names their configurations use.

- Diffusion Policy: a reimplementation of `ReplayBuffer.copy_from_path` + `SequenceSampler`
  (`diffusion_policy/common/replay_buffer.py`, `sampler.py`: `create_indices` with
  `pad_before = n_obs_steps - 1`, `pad_after = n_action_steps - 1`, edge padding from
  `sample_start_idx` / `sample_end_idx`) reads `data/img`, `data/state`, `data/action`, as
  `PushTImageDataset` does, and gets the windows of chunkc's own loader.
- robomimic: `next_obs`, `rewards`, `dones` beside `obs`, as `hdf5_load_next_obs = true` needs.
- ACT: an ALOHA source keeps its names (`observations/qpos`, `observations/qvel`,
  `observations/images/<cam>`).
- `[profiles.<name>.export_keys]` renames.
"""

import io
import json

import h5py
import numpy as np
import pytest
import zarr
from PIL import Image

from conftest import PUSHT, REPO, import_loader, run_chunkc, write_spec

ALOHA = REPO / "tests" / "data" / "aloha_sim_jpeg"
HORIZON, N_OBS, N_ACTION = 16, 2, 8  # the diffusion_policy preset (TARGETS.md)


# ---- Diffusion Policy's ReplayBuffer and SequenceSampler, reimplemented ----------------------


def dp_copy_from_path(path, keys):
    """`ReplayBuffer.copy_from_path(path, keys=keys)` with the numpy backend: every `meta` array,
    and `data/<key>` for each key (a missing key is the KeyError users hit)."""
    src = zarr.open_group(str(path), mode="r")
    meta = {}
    for key, value in src["meta"].arrays():
        meta[key] = np.array(value) if len(value.shape) == 0 else value[:]
    data = {key: src["data"][key][:] for key in keys}
    return {"meta": meta, "data": data}


def dp_create_indices(episode_ends, sequence_length, episode_mask, pad_before=0, pad_after=0):
    pad_before = min(max(pad_before, 0), sequence_length - 1)
    pad_after = min(max(pad_after, 0), sequence_length - 1)
    indices = []
    for i in range(len(episode_ends)):
        if not episode_mask[i]:
            continue
        start_idx = 0 if i == 0 else episode_ends[i - 1]
        end_idx = episode_ends[i]
        episode_length = end_idx - start_idx
        min_start = -pad_before
        max_start = episode_length - sequence_length + pad_after
        for idx in range(min_start, max_start + 1):
            buffer_start_idx = max(idx, 0) + start_idx
            buffer_end_idx = min(idx + sequence_length, episode_length) + start_idx
            start_offset = buffer_start_idx - (idx + start_idx)
            end_offset = (idx + sequence_length + start_idx) - buffer_end_idx
            sample_start_idx = 0 + start_offset
            sample_end_idx = sequence_length - end_offset
            assert sample_end_idx - sample_start_idx == buffer_end_idx - buffer_start_idx
            indices.append([buffer_start_idx, buffer_end_idx, sample_start_idx, sample_end_idx])
    return np.array(indices, dtype=np.int64).reshape(-1, 4)


class DpSequenceSampler:
    def __init__(self, buffer, sequence_length, pad_before, pad_after, keys, episode_mask):
        self.buffer = buffer
        self.keys = list(keys)
        self.sequence_length = sequence_length
        self.indices = dp_create_indices(buffer["meta"]["episode_ends"], sequence_length, episode_mask,
                                         pad_before=pad_before, pad_after=pad_after)

    def __len__(self):
        return len(self.indices)

    def sample_sequence(self, idx):
        buffer_start_idx, buffer_end_idx, sample_start_idx, sample_end_idx = self.indices[idx]
        result = {}
        for key in self.keys:
            input_arr = self.buffer["data"][key]
            sample = input_arr[buffer_start_idx:buffer_end_idx]
            data = sample
            if sample_start_idx > 0 or sample_end_idx < self.sequence_length:
                data = np.zeros((self.sequence_length,) + input_arr.shape[1:], dtype=input_arr.dtype)
                if sample_start_idx > 0:
                    data[:sample_start_idx] = sample[0]
                if sample_end_idx < self.sequence_length:
                    data[sample_end_idx:] = sample[-1]
                data[sample_start_idx:sample_end_idx] = sample
            result[key] = data
        return result


@pytest.fixture(scope="module")
def dp_zarr(tmp_path_factory):
    d = tmp_path_factory.mktemp("dp_zarr")
    run_chunkc("build", "-q", write_spec(d, '[profiles.dp]\npreset = "diffusion_policy"\nformat = "zarr"\n'))
    return d / "out" / "dp"


def test_pusht_image_dataset_keys_open_the_zarr_export(dp_zarr):
    root = zarr.open_group(str(dp_zarr / "data.zarr"), mode="r")
    assert sorted(root["data"].array_keys()) == ["action", "img", "state"]
    assert not list(root["data"].group_keys())  # ReplayBuffer walks `data/` expecting arrays
    meta = json.loads((dp_zarr / "meta.json").read_text())
    assert {n: c["array"] for n, c in meta["channels"].items()} == {
        "action": "data/action", "observation.state": "data/state", "observation.image": "data/img"}


def test_dp_sequence_sampler_matches_the_loader_on_every_train_sample(dp_zarr):
    meta = json.loads((dp_zarr / "meta.json").read_text())
    # PushTImageDataset: ReplayBuffer.copy_from_path(zarr_path, keys=['img', 'state', 'action']).
    buffer = dp_copy_from_path(dp_zarr / "data.zarr", ["img", "state", "action"])
    train = set(meta["split"]["train"])
    mask = np.array([eid in train for eid in meta["episodes"]])
    sampler = DpSequenceSampler(buffer, HORIZON, N_OBS - 1, N_ACTION - 1, ["img", "state", "action"], mask)
    ds = import_loader(dp_zarr).ChunkedDataset(str(dp_zarr), "train", in_memory=True)
    assert len(ds) == len(sampler) == meta["num_samples"]["train"]
    ends = buffer["meta"]["episode_ends"]
    for i in range(len(sampler)):
        want = sampler.sample_sequence(i)
        got = ds[i]
        # The same episode: the buffer rows of DP's window lie in the loader's episode.
        episode = int(np.searchsorted(ends, sampler.indices[i][0], side="right"))
        assert got["episode_index"] == meta["episodes"][episode]
        np.testing.assert_array_equal(got["observation.image"], want["img"][:N_OBS])
        np.testing.assert_allclose(ds.denormalize("observation.state", got["observation.state"]),
                                   want["state"][:N_OBS], rtol=0, atol=1e-3)
        np.testing.assert_allclose(ds.denormalize("action", got["action"]), want["action"],
                                   rtol=0, atol=1e-3)


def test_lowdim_pusht_keys(tmp_path):
    """Low-dim Push-T (`PushTLowdimDataset`) reads `keypoint`, `state`, `action`."""
    channels = {"action": "action", "observation.state": "state", "observation.keypoint": "keypoint"}
    run_chunkc("build", "-q", write_spec(tmp_path, '[profiles.dp]\npreset = "diffusion_policy"\nformat = "zarr"\n',
                                         channels=channels))
    buffer = dp_copy_from_path(tmp_path / "out/dp/data.zarr", ["keypoint", "state", "action"])
    src = zarr.open_group(str(PUSHT), mode="r")
    for key in ("keypoint", "state", "action"):
        np.testing.assert_array_equal(buffer["data"][key], src["data"][key][:].astype(np.float32))


# ---- robomimic: next_obs, rewards, dones -----------------------------------------------------


def test_robomimic_has_next_obs_rewards_and_dones(tmp_path):
    run_chunkc("build", "-q", write_spec(tmp_path, '[profiles.rm]\npreset = "diffusion_policy"\nformat = "robomimic_hdf5"\n'))
    with h5py.File(tmp_path / "out/rm/data.hdf5", "r") as f:
        demos = sorted(f["data"].keys(), key=lambda k: int(k[5:]))
        assert demos
        for name in demos:
            g = f["data"][name]
            n = g.attrs["num_samples"]
            assert sorted(g["obs"].keys()) == sorted(g["next_obs"].keys()) == ["img", "state"]
            for key in g["obs"]:
                obs, nxt = g["obs"][key][()], g["next_obs"][key][()]
                assert nxt.dtype == obs.dtype and nxt.shape == obs.shape and len(obs) == n
                np.testing.assert_array_equal(nxt[:-1], obs[1:])
                np.testing.assert_array_equal(nxt[-1], obs[-1])
            dones = g["dones"][()]
            np.testing.assert_array_equal(dones, (np.arange(n) == n - 1).astype(np.uint8))
            rewards = g["rewards"][()]
            assert rewards.shape == (n,) and not rewards.any()
            assert g["actions"].shape[0] == n


# ---- ACT on an ALOHA source --------------------------------------------------------------------

ALOHA_SPEC = """version = 1
[source]
format = "aloha_hdf5"
path = "{path}"
[source.channels]
action = "action"
"observation.qpos" = "observations/qpos"
"observation.qvel" = "observations/qvel"
"observation.images.top" = "observations/images/top"
"observation.images.left_wrist" = {{ key = "observations/images/left_wrist", kind = "image" }}
[split]
val_fraction = 0.34
seed = 0
[output]
dir = "out"
[profiles.act]
preset = "act"
chunk = 20
format = "act_episodes"
{extra}"""


def jpeg_frames(rows):
    return np.stack([np.asarray(Image.open(io.BytesIO(r.tobytes())).convert("RGB")) for r in rows])


def test_act_export_keeps_aloha_names(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(ALOHA_SPEC.format(path=ALOHA, extra=""))
    run_chunkc("build", "-q", spec)
    out = tmp_path / "out/act"
    meta = json.loads((out / "meta.json").read_text())
    sources = sorted(ALOHA.glob("episode_*.hdf5"), key=lambda p: int(p.stem.split("_")[1]))
    assert [int(p.stem.split("_")[1]) for p in sources] == meta["episodes"]
    for i, src_path in enumerate(sources):
        with h5py.File(out / f"episode_{i}.hdf5", "r") as got, h5py.File(src_path, "r") as src:
            names = []
            got.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
            assert sorted(names) == ["action", "observations/images/left_wrist", "observations/images/top",
                                     "observations/qpos", "observations/qvel"]
            for key in ("action", "observations/qpos", "observations/qvel"):
                np.testing.assert_array_equal(got[key][()], src[key][()])
            for cam in ("top", "left_wrist"):
                np.testing.assert_array_equal(got[f"observations/images/{cam}"][()],
                                              jpeg_frames(src[f"observations/images/{cam}"][()]))


# ---- export_keys -------------------------------------------------------------------------------

RENAMED = """
[profiles.plain]
preset = "diffusion_policy"
format = "zarr"

[profiles.zarr]
extends = "plain"

[profiles.zarr.export_keys]
"observation.image" = "camera_0"
"observation.state" = "robot_eef_pose"
action = "actions"

[profiles.rm]
preset = "diffusion_policy"
format = "robomimic_hdf5"

[profiles.rm.export_keys]
"observation.image" = "agentview_image"

[profiles.act]
preset = "act"
fps = 10
chunk = 20
format = "act_episodes"

[profiles.act.export_keys]
"observation.image" = "cam_high"
"""


def test_export_keys_rename_arrays(tmp_path):
    run_chunkc("build", "-q", write_spec(tmp_path, RENAMED))
    out = tmp_path / "out"
    src = zarr.open_group(str(PUSHT), mode="r")
    root = zarr.open_group(str(out / "zarr/data.zarr"), mode="r")
    assert sorted(root["data"].array_keys()) == ["actions", "camera_0", "robot_eef_pose"]
    np.testing.assert_array_equal(root["data/camera_0"][:], src["data/img"][:].astype(np.uint8))
    np.testing.assert_array_equal(root["data/actions"][:], src["data/action"][:].astype(np.float32))
    # chunkc's loader follows meta.json to the renamed arrays: the same samples as without names.
    renamed = import_loader(out / "zarr").ChunkedDataset(str(out / "zarr"), "train")
    plain = import_loader(out / "plain").ChunkedDataset(str(out / "plain"), "train")
    assert len(renamed) == len(plain)
    for i in (0, len(plain) // 2, len(plain) - 1):
        a, b = renamed[i], plain[i]
        assert a.keys() == b.keys()
        for key in a:
            np.testing.assert_array_equal(a[key], b[key])
    with h5py.File(out / "rm/data.hdf5", "r") as f:
        g = f["data/demo_0"]
        assert sorted(g["obs"].keys()) == sorted(g["next_obs"].keys()) == ["agentview_image", "state"]
    with h5py.File(out / "act/episode_0.hdf5", "r") as f:
        assert list(f["observations/images"].keys()) == ["cam_high"]
        assert "observations/qpos" in f and "observations/qvel" in f


def test_act_names_that_collide_once_the_state_channel_is_known(tmp_path):
    """ACT reads its state channel as `qpos`: which channel that is depends on the source's
    kinds, so this collision is found when the plan is resolved, still at the spec's line."""
    spec = tmp_path / "spec.toml"
    text = ALOHA_SPEC.format(path=ALOHA, extra="")
    text = text.replace('"observation.qpos" = "observations/qpos"\n"observation.qvel" = "observations/qvel"\n',
                        '"observation.a" = "observations/effort"\n"observation.b" = "observations/qpos"\n')
    spec.write_text(text)
    proc = run_chunkc("plan", spec, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "observations/qpos" in proc.stderr and "observation.a" in proc.stderr
    assert "observation.b" in proc.stderr and "spec.toml:" in proc.stderr
    assert not (tmp_path / "out").exists()
