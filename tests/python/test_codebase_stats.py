"""Statistics files in each target codebase's format, checked against that codebase's math."""

import json
import pickle
import sys

import numpy as np
import pytest

from conftest import model_tier, run_chunkc, write_spec

PROFILES = """
[profiles.act]
preset = "act"
fps = 10
chunk = 20
[profiles.dp]
preset = "diffusion_policy"
[profiles.all]
chunk = 8
stats_formats = ["lerobot", "openpi", "robomimic"]
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("codebase")
    run_chunkc("build", "-q", write_spec(d, PROFILES))
    return d / "out"


def train_values(raw, built, profile, key):
    meta = json.loads((built / profile / "meta.json").read_text())
    return np.concatenate([raw.episode(key, e) for e in meta["split"]["train"]]).astype(np.float64), meta


def test_act_pickle_is_numpy_and_matches_json_and_act_math(built, raw):
    torch = model_tier("torch")
    with open(built / "act" / "dataset_stats.pkl", "rb") as f:
        stats = pickle.load(f)
    as_json = json.loads((built / "act" / "dataset_stats.json").read_text())
    assert set(stats) == {"action_mean", "action_std", "action_min", "action_max", "qpos_mean", "qpos_std", "example_qpos"}
    for k, v in stats.items():
        assert isinstance(v, np.ndarray) and v.dtype == np.float64
        np.testing.assert_array_equal(v, np.asarray(as_json[k]))
    for prefix, key in [("action", "action"), ("qpos", "state")]:
        x, meta = train_values(raw, built, "act", key)
        t = torch.from_numpy(x)
        np.testing.assert_allclose(stats[f"{prefix}_mean"], t.mean(0).numpy(), rtol=1e-9)
        np.testing.assert_allclose(stats[f"{prefix}_std"], torch.clip(t.std(0), 1e-2, np.inf).numpy(), rtol=1e-9)
    x, meta = train_values(raw, built, "act", "action")
    np.testing.assert_allclose(stats["action_min"], x.min(0) - 1e-4)
    np.testing.assert_allclose(stats["action_max"], x.max(0) + 1e-4)
    first_train = meta["split"]["train"][0]
    np.testing.assert_array_equal(stats["example_qpos"], raw.episode("state", first_train))


def test_dp_state_dict_maps_training_actions_into_unit_range(built, raw):
    torch = model_tier("torch")
    sys.path.insert(0, str(built / "dp"))
    try:
        import dp_normalizer
    finally:
        sys.path.pop(0)
    state = dp_normalizer.load_state_dict()
    scale = state["normalizer.params_dict.action.scale"].double().numpy()
    offset = state["normalizer.params_dict.action.offset"].double().numpy()
    assert state["normalizer.params_dict.action.scale"].dtype == torch.float32
    x, _ = train_values(raw, built, "dp", "action")
    y = x * scale + offset
    assert y.min() >= -1 - 1e-6 and y.max() <= 1 + 1e-6
    np.testing.assert_allclose(y.min(0), -1, atol=1e-6)
    np.testing.assert_allclose(y.max(0), 1, atol=1e-6)
    np.testing.assert_allclose(state["normalizer.params_dict.action.input_stats.max"].numpy(), x.max(0), rtol=1e-6)
    assert state["normalizer.params_dict.image.scale"].tolist() == [2.0]
    assert state["normalizer.params_dict.image.offset"].tolist() == [-1.0]


def linear_normalizer_fit(torch, data, range_eps=1e-4, output_min=-1.0, output_max=1.0):
    """What Diffusion Policy's `LinearNormalizer.fit(data, mode="limits")` stores for one key
    (`diffusion_policy/model/common/normalizer.py::_fit`, default arguments: float32,
    last_n_dims=1, fit_offset=True), written out here from its published definition."""
    x = torch.from_numpy(np.ascontiguousarray(data)).type(torch.float32)
    x = x.reshape(-1, x.shape[-1])
    lo, hi = x.min(axis=0).values, x.max(axis=0).values
    mean, std = x.mean(axis=0), x.std(axis=0)  # torch's std: unbiased
    span = hi - lo
    ignore = span < range_eps
    span[ignore] = output_max - output_min
    scale = (output_max - output_min) / span
    offset = output_min - scale * lo
    offset[ignore] = (output_max + output_min) / 2 - lo[ignore]
    return {"scale": scale, "offset": offset, "input_stats": {"min": lo, "max": hi, "mean": mean, "std": std}}


def test_dp_normalizer_json_is_what_linear_normalizer_fit_stores(built, raw):
    torch = model_tier("torch")
    params = json.loads((built / "dp" / "dp_normalizer.json").read_text())
    for key, source_key in (("action", "action"), ("state", "state")):
        x, _ = train_values(raw, built, "dp", source_key)
        want = linear_normalizer_fit(torch, x)
        got = params[key]
        # float32 in `fit` against chunkc's float64: equal to float32 precision.
        for name in ("scale", "offset"):
            np.testing.assert_allclose(got[name], want[name].numpy(), rtol=2e-6, atol=1e-6, err_msg=f"{key}.{name}")
        for stat in ("min", "max", "mean", "std"):
            np.testing.assert_allclose(got["input_stats"][stat], want["input_stats"][stat].numpy(), rtol=2e-6,
                                       err_msg=f"{key}.input_stats.{stat}")
        # The population std (ddof 0) is measurably different: the check above can fail.
        n = len(x)
        assert not np.allclose(got["input_stats"]["std"], x.std(0) * 1.0, rtol=0.1 / n)
        np.testing.assert_allclose(got["input_stats"]["std"], x.std(0, ddof=1), rtol=1e-12)


def test_lerobot_openpi_robomimic_files(built, raw):
    x, meta = train_values(raw, built, "all", "action")
    s = json.loads((built / "all" / "lerobot_stats.json").read_text())
    for q in (1, 10, 50, 90, 99):
        np.testing.assert_allclose(s["action"][f"q{q:02d}"], np.percentile(x, q, axis=0), rtol=1e-9)
    np.testing.assert_allclose(s["action"]["std"], x.std(0), rtol=1e-9)
    assert s["action"]["count"] == [len(x)]
    img = np.asarray(s["observation.image"]["mean"])
    assert img.shape == (3, 1, 1) and 0 <= img.min() and img.max() <= 1

    o = json.loads((built / "all" / "norm_stats.json").read_text())["norm_stats"]
    st, _ = train_values(raw, built, "all", "state")
    np.testing.assert_allclose(o["state"]["q99"], np.percentile(st, 99, axis=0), rtol=1e-9)
    np.testing.assert_allclose(o["actions"]["mean"], x.mean(0), rtol=1e-9)

    r = json.loads((built / "all" / "robomimic_stats.json").read_text())
    a = r["v0.5"]["action_normalization_stats"]["actions"]
    y = (x - np.asarray(a["offset"])) / np.asarray(a["scale"])
    np.testing.assert_allclose(y.min(0), -0.999999, atol=1e-9)
    np.testing.assert_allclose(y.max(0), 0.999999, atol=1e-9)
    obs = r["v0.5"]["obs_normalization_stats"]["state"]
    np.testing.assert_allclose(obs["scale"], [st.std(0) + 1e-3], rtol=1e-9)
