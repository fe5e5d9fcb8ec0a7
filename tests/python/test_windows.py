"""Every training window of a build equals an independent numpy computation from the source."""

import json

import h5py
import numpy as np
import pytest

from conftest import import_loader, run_chunkc, write_spec
from reference import action_window, expected_starts, norm_params, normalize, obs_window

PROFILES = """
[profiles.dp]
preset = "diffusion_policy"

[profiles.act]
preset = "act"
fps = 10
chunk = 20

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
normalize = { action = "minmax", "observation.state" = "minmax" }

[profiles.half]
fps = 5
chunk = 6
obs_history = 2
normalize = { action = "zscore", "observation.state" = "minmax" }
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("windows")
    spec = write_spec(d, PROFILES)
    run_chunkc("build", "-q", spec)
    return d / "out"


@pytest.mark.parametrize("profile", ["dp", "act", "zero", "mask", "trunc", "half"])
def test_every_training_window_matches_numpy(built, raw, profile):
    root = built / profile
    meta = json.loads((root / "meta.json").read_text())
    k, h = meta["chunk_size"], meta["obs_history"]
    padding, stride = meta["padding"], meta["stride"]
    lead, max_pad_after = meta["action_lead"], meta["max_pad_after"]
    factor = meta["rate"]["factor"]
    train_ids = set(meta["split"]["train"])
    episodes = meta["episodes"]
    assert episodes == list(range(len(raw.ends)))

    # Normalization recomputed from the training split of the raw source.
    params = {}
    for name, key in [("action", "action"), ("observation.state", "state")]:
        values = np.concatenate([raw.episode(key, e, factor) for e in sorted(train_ids)])
        params[name] = norm_params(meta["normalization"][name]["mode"], values)

    f = h5py.File(root / "data.h5", "r")
    ends = f["meta/episode_ends"][:]
    starts = np.concatenate([[0], ends[:-1]])
    np.testing.assert_array_equal(ends, meta["episode_ends"])

    # The stored per-step arrays are the normalized source, episode by episode.
    for pos, e in enumerate(episodes):
        for name, key in [("action", "action"), ("observation.state", "state")]:
            stored = f["data/" + name][starts[pos] : ends[pos]]
            want = normalize(raw.episode(key, e, factor), params[name])
            np.testing.assert_allclose(stored, want, rtol=1e-6, atol=1e-6)

    # The training index is exactly the documented windows, and none crosses an episode.
    index = f["index/train"][:]
    want_index = []
    for pos, e in enumerate(episodes):
        if e in train_ids:
            length = ends[pos] - starts[pos]
            starts_ = expected_starts(length, k, h, padding, stride, lead, max_pad_after)
            want_index += [(pos, t, k, 0) for t in starts_]
    np.testing.assert_array_equal(index, np.array(want_index).reshape(-1, 4))
    lengths = ends - starts
    assert np.all(index[:, 1] < lengths[index[:, 0]])
    assert meta["num_samples"]["train"] == len(index)

    # Every training sample the loader returns equals the numpy window.
    loader = import_loader(root)
    ds = loader.ChunkedDataset(str(root), "train")
    assert len(ds) == len(index)
    for i, (pos, t, _, _) in enumerate(index):
        e = episodes[pos]
        s = ds[i]
        assert s["episode_index"] == e and s["frame_index"] == t
        actions = raw.episode("action", e, factor)
        want_a, want_pad = action_window(actions, t, k, padding, params["action"], lead)
        np.testing.assert_array_equal(s["action_is_pad"], want_pad)
        np.testing.assert_allclose(s["action"], want_a, rtol=1e-6, atol=1e-6)
        assert s["action"].shape == (k, 2) and s["action"].dtype == np.float32
        state = normalize(raw.episode("state", e, factor), params["observation.state"])
        np.testing.assert_allclose(s["observation.state"], obs_window(state, t, h), rtol=1e-6, atol=1e-6)
        np.testing.assert_array_equal(s["observation.state_is_pad"], np.arange(t - h + 1, t + 1) < 0)
        if i % 17 == 0:  # images are large: check a regular subset of samples
            img = raw.episode("img", e, factor)
            np.testing.assert_array_equal(s["observation.image"], obs_window(img, t, h).astype(np.uint8))
        if padding == "truncate":
            assert not s["action_is_pad"].any() and t - h + 1 >= 0
