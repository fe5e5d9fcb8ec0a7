"""Presets reproduce their codebases' sampling and normalization; segments and hierarchies."""

import json

import numpy as np
import pytest

from conftest import model_tier, import_loader, make_replay_buffer, run_chunkc, write_spec
from reference import norm_params, normalize


def load(root, split="train"):
    return import_loader(root).ChunkedDataset(str(root), split)


# --- Diffusion Policy's sampler, reimplemented from its description in TARGETS.md -------------


def dp_create_indices(episode_ends, sequence_length, episode_mask, pad_before, pad_after):
    """One window [idx, idx+sequence_length) per idx in [-pad_before, L - T + pad_after]."""
    indices = []
    for i, end in enumerate(episode_ends):
        if not episode_mask[i]:
            continue
        start = 0 if i == 0 else episode_ends[i - 1]
        length = end - start
        for idx in range(-pad_before, length - sequence_length + pad_after + 1):
            buffer_start = max(idx, 0) + start
            buffer_end = min(idx + sequence_length, length) + start
            sample_start = buffer_start - (idx + start)
            sample_end = sequence_length - ((idx + sequence_length + start) - buffer_end)
            indices.append((buffer_start, buffer_end, sample_start, sample_end))
    return indices


def dp_sample_sequence(array, sequence_length, buffer_start, buffer_end, sample_start, sample_end):
    """The window, with the first/last frame repeated into the padded part (edge padding)."""
    sample = array[buffer_start:buffer_end]
    if sample_start == 0 and sample_end == sequence_length:
        return sample
    out = np.zeros((sequence_length,) + array.shape[1:], dtype=array.dtype)
    out[:sample_start] = sample[0]
    out[sample_end:] = sample[-1]
    out[sample_start:sample_end] = sample
    return out


def test_diffusion_policy_windows_equal_its_sampler_one_for_one(tmp_path, raw):
    spec = write_spec(tmp_path, '[profiles.dp]\npreset = "diffusion_policy"\n')
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "dp"
    ds = load(root)
    meta = ds.meta
    horizon, n_obs, n_action = 16, 2, 8
    assert (meta["chunk_size"], meta["obs_history"], meta["executes"]) == (horizon, n_obs, n_action)
    assert meta["alignment"] == "diffusion_policy"
    train = set(meta["split"]["train"])
    mask = [e in train for e in range(len(raw.ends))]
    windows = dp_create_indices(raw.ends, horizon, mask, n_obs - 1, n_action - 1)
    assert len(windows) == len(ds)

    actions, states, images = raw.array("action"), raw.array("state"), raw.array("img")
    for i, w in enumerate(windows):
        s = ds[i]
        want_action = dp_sample_sequence(actions, horizon, *w)
        np.testing.assert_allclose(ds.denormalize("action", s["action"]), want_action, rtol=1e-5, atol=1e-4)
        want_state = dp_sample_sequence(states, horizon, *w)[:n_obs]
        np.testing.assert_allclose(
            ds.denormalize("observation.state", s["observation.state"]), want_state, rtol=1e-5, atol=1e-4
        )
        if i % 23 == 0:
            want_img = dp_sample_sequence(images, horizon, *w)[:n_obs]
            np.testing.assert_array_equal(s["observation.image"], want_img.astype(np.uint8))


def test_act_stats_match_torch_unbiased_std_with_floor(tmp_path):
    torch = model_tier("torch")
    rng = np.random.default_rng(0)
    episodes = []
    for length in (120, 90, 150, 60):
        t = np.arange(length)[:, None]
        action = np.concatenate(
            [np.sin(t / 7.0) + 0.1 * rng.standard_normal((length, 1)), np.full((length, 1), 0.25)], axis=1
        ).astype(np.float32)
        qpos = np.concatenate([np.cumsum(action[:, :1], axis=0), np.full((length, 1), -3.0)], axis=1)
        episodes.append({"action": action, "qpos": qpos.astype(np.float32)})
    src = make_replay_buffer(tmp_path / "act.zarr", episodes)
    spec = write_spec(
        tmp_path,
        '[profiles.act]\npreset = "act"\n',
        source=src,
        fps=50,
        channels={"action": "action", "observation.qpos": "qpos"},
        split="val_fraction = 0.25\nseed = 3",
    )
    run_chunkc("build", "-q", spec)
    meta = json.loads((tmp_path / "out" / "act" / "meta.json").read_text())
    assert (meta["chunk_size"], meta["fps"], meta["obs_history"]) == (100, 50.0, 1)
    for name, key in [("action", "action"), ("observation.qpos", "qpos")]:
        train = torch.cat([torch.from_numpy(episodes[e][key]).double() for e in meta["split"]["train"]])
        # ACT's get_norm_stats: mean, std (unbiased), clipped to [1e-2, inf).
        mean = train.mean(dim=0)
        std = torch.clip(train.std(dim=0), 1e-2, np.inf)
        n = meta["normalization"][name]
        np.testing.assert_allclose(n["center"], mean.numpy(), rtol=1e-6)
        np.testing.assert_allclose(n["scale"], std.numpy(), rtol=1e-6)
        assert n["scale"][1] == 1e-2  # the constant dimension hit the floor


def test_openpi_and_lerobot_normalization_follow_their_formulas(tmp_path, raw):
    profiles = """
[profiles.openpi]
preset = "openpi"
[profiles.lerobot]
preset = "lerobot_act"
chunk = 10
[profiles.lerobot_dp]
preset = "lerobot_diffusion"
"""
    run_chunkc("build", "-q", write_spec(tmp_path, profiles))
    for profile, mode in [("openpi", "quantile"), ("lerobot", "lerobot_mean_std"), ("lerobot_dp", "lerobot_min_max")]:
        ds = load(tmp_path / "out" / profile)
        train = np.concatenate([raw.episode("action", e) for e in ds.meta["split"]["train"]])
        assert ds.meta["normalization"]["action"]["mode"] == mode
        x = raw.array("action")[:500]
        if profile == "openpi":
            # openpi's population: every training sample's 50-step chunk, indices clamped at the
            # episode end; its quantiles are the data values of rank q*n (openpi's histogram
            # picks the bin holding them).
            assert ds.meta["stats_population"] == "windows"
            chunks = []
            for e in ds.meta["split"]["train"]:
                a = raw.episode("action", e)
                rows = np.clip(np.arange(len(a))[:, None] + np.arange(50), 0, len(a) - 1)
                chunks.append(a[rows].reshape(-1, a.shape[1]))
            windows = np.concatenate(chunks).astype(np.float32)  # the build stores float32
            q01 = np.percentile(windows, 1, axis=0, method="inverted_cdf").astype(np.float64)
            q99 = np.percentile(windows, 99, axis=0, method="inverted_cdf").astype(np.float64)
            r = q99 - q01 + 1e-6  # (x - q01) / r * 2 - 1, as center and half-range
            want = normalize(x, (q01 + r / 2, r / 2, False))
            np.testing.assert_allclose(ds.normalize("action", x), want, rtol=1e-9, atol=1e-9)
            continue
        np.testing.assert_allclose(
            ds.normalize("action", x), normalize(x, norm_params(mode, train)), rtol=1e-9, atol=1e-9
        )
    # LeRobot samples every frame, clamps indices and marks them in `<key>_is_pad`.
    ds = load(tmp_path / "out" / "lerobot_dp")
    assert ds.meta["action_lead"] == 1 and ds.meta["max_pad_after"] is None
    assert len(ds) == sum(len(raw.episode("action", e)) for e in ds.meta["split"]["train"])
    first = ds[0]
    assert first["frame_index"] == 0
    np.testing.assert_array_equal(first["observation.state_is_pad"], [True, False])
    assert first["action_is_pad"][0] and not first["action_is_pad"][1:5].any()
    np.testing.assert_array_equal(first["action"][0], first["action"][1])  # clamped to step 0


def triangle(turns, length):
    """Positions moving +1/-1 per step, reversing direction at each step in `turns`."""
    x, direction, out = 0.0, 1.0, []
    for t in range(length):
        if t in turns:
            direction = -direction
        x += direction
        out.append(x)
    return np.array(out)


def test_segments_cut_at_velocity_zero_crossings(tmp_path):
    lengths, turns = [80, 95], [[20, 45, 60], [30]]
    episodes = []
    for length, tr in zip(lengths, turns):
        pos = triangle(set(tr), length)
        state = np.stack([pos, np.zeros(length)], axis=1).astype(np.float32)
        episodes.append({"action": state.copy(), "state": state})
    src = make_replay_buffer(tmp_path / "seg.zarr", episodes)
    profiles = """
[profiles.seg]
chunk = 40
padding = "mask"
[profiles.seg.segment]
method = "velocity"
channel = "observation.state"
dims = [0]
"""
    spec = write_spec(
        tmp_path, profiles, source=src, fps=10,
        channels={"action": "action", "observation.state": "state"}, split="val_fraction = 0.0",
    )
    run_chunkc("build", "-q", spec)
    ds = load(tmp_path / "out" / "seg")
    segments = ds.meta["sampling"]["segments"]
    # Direction reverses at each turn: the first step moving the other way starts a segment,
    # and a segment longer than max_length (= chunk, 40) is split.
    assert segments[0] == [[0, 20], [20, 45], [45, 60], [60, 80]]
    assert segments[1] == [[0, 30], [30, 70], [70, 95]]
    for i in range(len(ds)):
        s = ds[i]
        ep = s["episode_index"]
        a, b = next(seg for seg in segments[ep] if seg[0] == s["frame_index"])
        n = b - a
        np.testing.assert_array_equal(s["action_is_pad"], np.arange(40) >= n)
        np.testing.assert_allclose(ds.denormalize("action", s["action"][:n]), episodes[ep]["action"][a:b])
        assert not s["action"][n:].any()  # mask padding: zeros in normalized units


def test_hierarchical_samples_nest_fine_chunks_in_coarse_chunks(tmp_path, raw):
    profiles = """
[profiles.h]
chunk = 5
stride = 20
normalize = { action = "none" }
[profiles.h.hierarchy]
coarse_seconds = 2.0
"""
    run_chunkc("build", "-q", write_spec(tmp_path, profiles))
    ds = load(tmp_path / "out" / "h")
    assert ds.meta["sampling"] == {"mode": "hierarchy", "coarse_chunk": 20, "fine_chunk": 5}
    for i in range(len(ds)):
        s = ds[i]
        e, j, t0 = s["episode_index"], s["fine_index"], s["coarse_frame_index"]
        actions = raw.episode("action", e)
        length = len(actions)
        assert s["frame_index"] == t0 + 5 * j < length
        coarse_valid = ~s["coarse_action_is_pad"]
        np.testing.assert_array_equal(s["coarse_action"][coarse_valid], actions[t0 : t0 + 20])
        fine_valid = ~s["action_is_pad"]
        np.testing.assert_array_equal(s["action"][fine_valid], s["coarse_action"][5 * j : 5 * j + 5][fine_valid])
        assert fine_valid.sum() == min(5, length - (t0 + 5 * j))


def test_gripper_command_sign_changes_split_robosuite_lift(tmp_path):
    import h5py

    from conftest import REPO

    source = REPO / "tests" / "data" / "robosuite_panda_lift.hdf5"
    spec = tmp_path / "spec.toml"
    spec.write_text(
        f"""
version = 1
[source]
format = "robomimic_hdf5"
path = "{source}"
[source.channels]
action = "actions"
"observation.state" = {{ key = "states", columns = [1, 32] }}
[split]
val_fraction = 0.0
[output]
dir = "out"
[profiles.phases]
chunk = 1000
padding = "mask"
normalize = {{ action = "limits" }}
[profiles.phases.segment]
method = "sign_change"
channel = "action"
dims = [6]
"""
    )
    run_chunkc("build", "-q", spec)
    ds = load(tmp_path / "out" / "phases")
    with h5py.File(source, "r") as f:
        gripper = f["data/demo_1/actions"][:, 6]
    # numpy: the steps where the gripper command's sign differs from the step before.
    sign = np.sign(gripper)
    cuts = (np.nonzero(sign[1:] != sign[:-1])[0] + 1).tolist()
    assert cuts, "the lift demo closes the gripper at least once"
    bounds = [0, *cuts, len(gripper)]
    assert ds.meta["sampling"]["segments"] == [[[a, b] for a, b in zip(bounds, bounds[1:])]]
    for i in range(len(ds)):
        s = ds[i]
        n = int((~s["action_is_pad"]).sum())
        gripper_seg = ds.denormalize("action", s["action"][:n])[:, 6]
        assert len(set(np.sign(np.round(gripper_seg, 6)))) == 1  # one command sign per segment
