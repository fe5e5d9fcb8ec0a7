"""Action transforms (issue 38) end to end, each against an oracle written here from the target
codebase's published definition, never from chunkc's code:

- openpi's `DeltaActions` and `compute_norm_stats` (its `RunningStats`, with the 5000-bin
  histogram quantiles) on the vendored Unitree G1 set, with the `pi0` (z-score) and `pi05`
  (quantile) presets, in HDF5 and parquet; `to_source` gives the source actions back;
- Diffusion Policy's robomimic `abs_action` (pytorch3d's `matrix_to_rotation_6d` of scipy's
  matrices, `robomimic_abs_action_only_normalizer_from_stat`), single and dual arm;
- UMI's `relative` pose representation (`inv(T_base) @ T`, position + 6D rows);
- every rotation kind against scipy (quaternion orders, euler conventions, 6D rows and columns);
- the spec errors `chunkc check` gives, and the build's refusal of a quaternion far from unit norm;
- identical statistics and metadata bytes with 1 or 2 threads and from 2 shards + merge.
"""

import hashlib
import json
import re

import h5py
import numpy as np
import pyarrow.parquet as pq
import pytest
from scipy.spatial.transform import Rotation

from conftest import REPO, load_dataset, make_replay_buffer, run_chunkc

G1 = REPO / "tests" / "data" / "lerobot_g1_subset"


# --- specs and samples ---------------------------------------------------------------------------


def write_spec(directory, fmt, path, channels, profiles, fps=None, split="val_fraction = 0.25\nseed = 0"):
    """A spec in `directory` reading `path` (absolute, so that specs in different directories
    describe the same source) with the `[profiles.*]` TOML text `profiles`."""
    directory.mkdir(parents=True, exist_ok=True)
    lines = ["version = 1", "[source]", f'format = "{fmt}"', f'path = "{path}"']
    if fps is not None:
        lines.append(f"fps = {fps}")
    lines.append("[source.channels]")
    lines += [f"{json.dumps(name)} = {json.dumps(key)}" for name, key in channels.items()]
    lines += ["[split]", split, "[output]", 'dir = "out"', profiles]
    spec = directory / "spec.toml"
    spec.write_text("\n".join(lines) + "\n")
    return spec


def samples(ds, batch=256):
    """Every sample of `ds`, read a batch at a time (the DataLoader's `__getitems__`)."""
    for i in range(0, len(ds), batch):
        yield from ds.__getitems__(list(range(i, min(i + batch, len(ds)))))


def clamped(values, first, k):
    """Rows first .. first+k-1 of one episode, indices clamped into it (LeRobot's clamping, the
    edge padding of every codebase here)."""
    return values[np.clip(np.arange(first, first + k), 0, len(values) - 1)]


def assert_normalized(got, want_raw, center, scale, what, tol=2e-6):
    """`got` (normalized, float32) is `(want_raw - center) / scale` up to float32 rounding: the
    difference, taken back to raw units, is within `tol` of the raw magnitudes."""
    got = np.asarray(got, np.float64)
    want_raw = np.asarray(want_raw, np.float64)
    want = (want_raw - center) / scale
    assert got.shape == want.shape, f"{what}: shape {got.shape}, want {want.shape}"
    err = np.abs(got - want) * np.abs(scale)
    bound = tol * (1 + np.abs(want_raw) + np.abs(center))
    bad = ~(err <= bound)
    if bad.any():
        at = np.unravel_index(np.argmax(np.where(bad, err / bound, 0)), bad.shape)
        raise AssertionError(
            f"{what}: {bad.sum()} of {bad.size} values differ; worst at {at}: got {got[at]!r}, "
            f"want {want[at]!r} (normalized), {err[at]:.3g} in raw units (raw value {want_raw[at]!r})")


def close(got, want, what, rtol=1e-9, atol=1e-12):
    got, want = np.asarray(got, np.float64), np.asarray(want, np.float64)
    assert got.shape == want.shape, f"{what}: shape {got.shape}, want {want.shape}"
    err = np.abs(got - want)
    bad = ~(err <= atol + rtol * np.abs(want))
    if bad.any():
        at = np.unravel_index(np.argmax(np.where(bad, err, 0)), bad.shape)
        raise AssertionError(f"{what}: {bad.sum()} of {bad.size} differ; worst at {at}: got {got[at]!r}, "
                             f"want {want[at]!r} (|diff| {err[at]:.3g}, rel {err[at] / max(abs(want[at]), 1e-300):.3g})")


def sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


# --- openpi, from its published code (transforms.py, shared/normalize.py) -----------------------


def make_bool_mask(*dims):
    """openpi's `make_bool_mask`: 6 -> six True, -1 -> one False."""
    out = []
    for d in dims:
        out.extend([d > 0] * abs(d))
    return tuple(out)


def delta_actions(actions, state, mask):
    """openpi's `DeltaActions`: the sample's one state subtracted from every row of its chunk where
    the mask is true; dimensions past the mask untouched. In the arrays' own dtype, as openpi
    runs it on the float32 arrays its data loader gives."""
    mask = np.asarray(mask)
    d = mask.shape[-1]
    out = np.array(actions, copy=True)
    out[..., :d] -= np.expand_dims(np.where(mask, state[..., :d], 0).astype(out.dtype), axis=-2)
    return out


class RunningStats:
    """openpi's `RunningStats` (shared/normalize.py): running mean and mean of squares, std =
    sqrt(E[x^2] - E[x]^2), and q01/q99 from a 5000-bin histogram per dimension whose bins are
    rebuilt over [min, max] when a batch widens the range; a quantile is the left edge of the
    first bin whose cumulative count reaches q * count."""

    BINS = 5000

    def __init__(self):
        self.count = 0

    def update(self, batch):
        batch = np.asarray(batch, np.float64).reshape(-1, np.shape(batch)[-1])
        n, dims = batch.shape
        if self.count == 0:
            self.mean = batch.mean(axis=0)
            self.mean_sq = (batch ** 2).mean(axis=0)
            self.min = batch.min(axis=0)
            self.max = batch.max(axis=0)
            self.hist = [np.zeros(self.BINS) for _ in range(dims)]
            self.edges = [np.linspace(self.min[i] - 1e-10, self.max[i] + 1e-10, self.BINS + 1) for i in range(dims)]
        else:
            new_max, new_min = batch.max(axis=0), batch.min(axis=0)
            changed = np.any(new_max > self.max) or np.any(new_min < self.min)
            self.max = np.maximum(self.max, new_max)
            self.min = np.minimum(self.min, new_min)
            if changed:
                for i in range(dims):
                    edges = np.linspace(self.min[i], self.max[i], self.BINS + 1)
                    self.hist[i], _ = np.histogram(self.edges[i][:-1], bins=edges, weights=self.hist[i])
                    self.edges[i] = edges
        self.count += n
        self.mean += (batch.mean(axis=0) - self.mean) * (n / self.count)
        self.mean_sq += ((batch ** 2).mean(axis=0) - self.mean_sq) * (n / self.count)
        for i in range(dims):
            h, _ = np.histogram(batch[:, i], bins=self.edges[i])
            self.hist[i] += h

    def std(self):
        return np.sqrt(np.maximum(0, self.mean_sq - self.mean ** 2))

    def quantile_bins(self, q):
        """(left edge, bin index, bin edges) per dimension for quantile q."""
        out = []
        for hist, edges in zip(self.hist, self.edges):
            idx = int(np.searchsorted(np.cumsum(hist), q * self.count))
            out.append((edges[idx], idx, edges))
        return out


def openpi_stats(rows, batch):
    """mean and std as openpi's RunningStats accumulates them batch by batch (`batch` rows at a
    time), and its histogram quantiles from one pass over the whole range (bins over [min, max])."""
    rows = np.asarray(rows, np.float64)
    running = RunningStats()
    for i in range(0, len(rows), batch):
        running.update(rows[i : i + batch])
    whole = RunningStats()
    whole.update(rows)
    return running, whole


def assert_quantile_near_histogram(got, rows, whole, q, what):
    """chunkc's exact quantile against openpi's histogram one. openpi returns the left edge of the
    first bin whose cumulative count reaches q*n; over windows chunkc returns the data value of
    that rank (numpy's `inverted_cdf`), which lies in that bin: at most one bin width above
    openpi's value, never below it. Returns the distance in bins, for the record."""
    apart = []
    for dim, (g, (edge, idx, edges)) in enumerate(zip(got, whole.quantile_bins(q))):
        width = edges[1] - edges[0]
        apart.append((g - edge) / width)
        assert -1e-6 <= apart[-1] <= 1 + 1e-6, (
            f"{what}[{dim}]: chunkc {g!r}; openpi's histogram gives bin {idx} (left edge {edge!r}), "
            f"{apart[-1]:.2f} bins from chunkc's value")
    return np.asarray(apart)


# --- the G1 set ----------------------------------------------------------------------------------


def g1_info():
    return json.loads((G1 / "meta" / "info.json").read_text())


def g1_episode(e):
    """(action, state) of source episode `e`, read with pyarrow, as stored (float32)."""
    table = pq.read_table(G1 / "data" / "chunk-000" / f"episode_{e:06d}.parquet")
    out = []
    for key in ("action", "observation.state"):
        width = g1_info()["features"][key]["shape"][0]
        col = table[key].combine_chunks()
        out.append(np.asarray(col.flatten(), np.float32).reshape(len(col), width))
    return out


# Arms made relative, hands absolute (openpi's ALOHA does the same with its grippers) ...
G1_ARMS_MASK = (14, -12)
# ... and ALOHA's own mask (6, -1, 6, -1), 14 wide: the 12 hand dimensions lie past it.
ALOHA_MASK = (6, -1, 6, -1)

def delta_profile(name, preset, fmt, mask):
    return f"""
[profiles.{name}]
preset = "{preset}"
format = "{fmt}"
[[profiles.{name}.transforms]]
op = "delta"
channel = "action"
reference = "observation.state"
mask = {list(mask)}
"""


G1_PROFILES = (delta_profile("pi0", "pi0", "hdf5", G1_ARMS_MASK)
               + delta_profile("pi0_aloha_mask", "pi0", "parquet", ALOHA_MASK)
               + delta_profile("pi05", "pi05", "hdf5", G1_ARMS_MASK))
G1_MASKS = {"pi0": G1_ARMS_MASK, "pi0_aloha_mask": ALOHA_MASK, "pi05": G1_ARMS_MASK}
G1_CHANNELS = {"action": "action", "observation.state": "observation.state"}
PI0_HORIZON = 50


@pytest.fixture(scope="module")
def g1_built(tmp_path_factory):
    d = tmp_path_factory.mktemp("transforms_g1")
    run_chunkc("build", "-q", write_spec(d, "lerobot", G1, G1_CHANNELS, G1_PROFILES))
    return d / "out"


def openpi_population(meta, mask, horizon=PI0_HORIZON):
    """What openpi's compute_norm_stats feeds RunningStats for this split: every training frame is
    a sample (LeRobot), its H-step action chunk clamped at the episode end and made relative to the
    sample's state (in float32, as openpi computes it); and the sample's state. Returns (keys,
    chunks (N, H, D), states (N, D), source chunks (N, H, D)), float64."""
    keys, chunks, states, sources = [], [], [], []
    for e in meta["split"]["train"]:
        action, state = g1_episode(e)
        for t in range(len(action)):
            chunk = clamped(action, t, horizon)
            keys.append((e, t))
            sources.append(chunk)
            chunks.append(delta_actions(chunk, state[t], make_bool_mask(*mask)))
            states.append(state[t])
    return keys, *(np.stack(x).astype(np.float64) for x in (chunks, states, sources))


@pytest.fixture(scope="module")
def g1_oracle(g1_built):
    meta = json.loads((g1_built / "pi0" / "meta.json").read_text())
    return {name: openpi_population(meta, mask) for name, mask in G1_MASKS.items()}


@pytest.mark.parametrize("profile", ["pi0", "pi0_aloha_mask", "pi05"])
def test_g1_meta_describes_the_delta(g1_built, profile):
    meta = json.loads((g1_built / profile / "meta.json").read_text())
    width = g1_info()["features"]["action"]["shape"][0]
    assert meta["chunk_size"] == PI0_HORIZON and meta["obs_history"] == 1
    assert meta["stats_population"] == "windows"
    assert meta["stored_values"] == "raw"
    assert meta["transforms"] == [{"op": "delta", "channel": "action", "reference": "observation.state",
                                   "mask": list(make_bool_mask(*G1_MASKS[profile]))}]
    assert meta["channels"]["action"]["shape"] == [width]
    assert meta["channels"]["action"]["transformed_shape"] == [width]
    assert meta.get("data_format", "hdf5") == ("parquet" if profile == "pi0_aloha_mask" else "hdf5")


@pytest.mark.parametrize("profile", ["pi0", "pi0_aloha_mask", "pi05"])
def test_g1_norm_stats_are_openpis_running_stats_over_windows(g1_built, g1_oracle, profile):
    keys, chunks, states, _ = g1_oracle[profile]
    width = chunks.shape[-1]
    stats = json.loads((g1_built / profile / "stats.json").read_text())
    norm = json.loads((g1_built / profile / "norm_stats.json").read_text())["norm_stats"]
    assert set(norm) == {"state", "actions"}
    # openpi's loader hands RunningStats batches of 32 samples (it drops the last partial batch;
    # chunkc keeps it, and so does this oracle).
    for key, name, rows, batch in [("actions", "action", chunks.reshape(-1, width), 32 * PI0_HORIZON),
                                   ("state", "observation.state", states, 32)]:
        running, whole = openpi_stats(rows, batch)
        got = norm[key]
        close(got["mean"], running.mean, f"{profile} norm_stats {key}.mean", rtol=1e-4, atol=1e-9)
        close(got["std"], running.std(), f"{profile} norm_stats {key}.std", rtol=1e-4, atol=1e-9)
        for q in ("q01", "q99"):
            apart = assert_quantile_near_histogram(got[q], rows, whole, int(q[1:]) / 100, f"{profile} norm_stats {key}.{q}")
            print(f"{profile} {key}.{q}: chunkc's exact value is {np.abs(apart).max():.1f} bins at most from "
                  f"openpi's histogram value ({(np.abs(apart) <= 1).sum()} of {len(apart)} dimensions within one bin)")
        # chunkc's quantiles are exact over the same population (the data value of rank q*n,
        # numpy's `inverted_cdf`), and stats.json describes that population too.
        for q in (1, 99):
            want = np.percentile(rows, q, axis=0, method="inverted_cdf")
            close(got[f"q{q:02d}"], want, f"{profile} {key}.q{q:02d} exact", rtol=1e-9)
        s = stats[name]
        assert s["count"] == len(rows), f"{profile} stats.json {name}.count {s['count']}, want {len(rows)}"
        close(s["mean"], rows.mean(axis=0), f"{profile} stats.json {name}.mean", rtol=1e-9, atol=1e-12)
        close(s["std"], rows.std(axis=0), f"{profile} stats.json {name}.std", rtol=1e-9, atol=1e-12)
        close(s["min"], rows.min(axis=0), f"{profile} stats.json {name}.min")
        close(s["max"], rows.max(axis=0), f"{profile} stats.json {name}.max")
    assert stats["action"]["count"] == len(keys) * PI0_HORIZON


def normalization(meta, name):
    n = meta["normalization"][name]
    return np.asarray(n["center"], np.float64), np.asarray(n["scale"], np.float64), n


@pytest.mark.parametrize("profile", ["pi0", "pi0_aloha_mask", "pi05"])
def test_g1_windows_are_openpis_delta_chunks_normalized(g1_built, g1_oracle, profile):
    keys, chunks, states, sources = g1_oracle[profile]
    root = g1_built / profile
    ds = load_dataset(root)
    norm = json.loads((root / "norm_stats.json").read_text())["norm_stats"]
    # openpi's Normalize: pi0 z-score with std + 1e-6; pi0.5 and pi0-FAST quantile, unclipped.
    want_params = {}
    for key, name in [("actions", "action"), ("state", "observation.state")]:
        s = {k: np.asarray(v, np.float64) for k, v in norm[key].items()}
        if profile == "pi05":
            want_params[name] = (s["q01"] + (s["q99"] - s["q01"] + 1e-6) / 2, (s["q99"] - s["q01"] + 1e-6) / 2)
        else:
            want_params[name] = (s["mean"], s["std"] + 1e-6)
        center, scale, n = normalization(ds.meta, name)
        assert n["clip"] is False
        close(center, want_params[name][0], f"{profile} meta normalization {name}.center", rtol=1e-12, atol=1e-12)
        close(scale, want_params[name][1], f"{profile} meta normalization {name}.scale", rtol=1e-12, atol=1e-15)

    assert len(ds) == len(keys)
    where = {k: i for i, k in enumerate(keys)}
    lengths = g1_lengths()
    seen = set()
    for s in samples(ds):
        key = (s["episode_index"], s["frame_index"])
        assert key not in seen
        seen.add(key)
        i = where[key]
        what = f"{profile} episode {key[0]} step {key[1]}"
        assert s["action"].shape == chunks[i].shape and s["action"].dtype == np.float32
        assert_normalized(s["action"], chunks[i], *want_params["action"], f"{what} action")
        assert_normalized(s["observation.state"], states[i][None], *want_params["observation.state"],
                          f"{what} observation.state")
        np.testing.assert_array_equal(s["action_is_pad"], key[1] + np.arange(PI0_HORIZON) >= lengths[key[0]],
                                      err_msg=what)
        # The way back: normalization undone, then the delta, with the sample's own state.
        back = ds.to_source("action", s["action"], s)
        assert back.dtype == np.float64 and back.shape == sources[i].shape
        close(back, sources[i], f"{what} to_source", rtol=1e-5, atol=1e-5)
    assert seen == set(keys)


def g1_lengths():
    lines = (G1 / "meta" / "episodes.jsonl").read_text().splitlines()
    return {e["episode_index"]: e["length"] for e in map(json.loads, lines)}


def test_g1_pi05_norm_stats_equal_pi0s(g1_built):
    """Same windows, same transform: the same statistics, whatever the normalization."""
    assert (g1_built / "pi0" / "norm_stats.json").read_bytes() == (g1_built / "pi05" / "norm_stats.json").read_bytes()
    a = json.loads((g1_built / "pi0" / "stats.json").read_text())
    b = json.loads((g1_built / "pi05" / "stats.json").read_text())
    assert a == b


# --- Diffusion Policy, robomimic abs_action ------------------------------------------------------


def rot6d_rows(matrix):
    """pytorch3d's `matrix_to_rotation_6d`: the first two ROWS, flattened."""
    matrix = np.asarray(matrix)
    return matrix[..., :2, :].reshape(matrix.shape[:-2] + (6,))


def rot6d_columns(matrix):
    """Zhou et al.'s 6D: the first two columns, [R00, R10, R20, R01, R11, R21]."""
    return rot6d_rows(np.swapaxes(np.asarray(matrix), -1, -2))


def dp_convert_actions(actions):
    """Diffusion Policy's `_convert_actions` with abs_action: per arm [pos3, axis_angle3, grip1]
    -> [pos3, rotation_6d, grip1] (7 -> 10, dual arm (T, 2, 7) -> 20)."""
    actions = np.asarray(actions, np.float64)
    arms = actions.reshape(len(actions), -1, 7)
    rot = rot6d_rows(Rotation.from_rotvec(arms[..., 3:6].reshape(-1, 3)).as_matrix()).reshape(arms.shape[:2] + (6,))
    out = np.concatenate([arms[..., :3], rot, arms[..., 6:]], axis=-1)
    return out.reshape(len(actions), -1)


def dp_range_normalizer(lo, hi, output_min=-1.0, output_max=1.0, range_eps=1e-7):
    """`get_range_normalizer_from_stat`: scale and offset of `x * scale + offset`."""
    span = hi - lo
    ignore = span < range_eps
    span = np.where(ignore, output_max - output_min, span)
    scale = (output_max - output_min) / span
    offset = np.where(ignore, (output_max + output_min) / 2 - lo, output_min - scale * lo)
    return scale, offset


def dp_abs_action_normalizer(stat):
    """`robomimic_abs_action_only_normalizer_from_stat` (10 wide) and its dual-arm variant (20):
    per arm, the position by its range to [-1, 1], the 6D rotation and the gripper identity."""
    width = len(stat["min"])
    scale, offset = np.ones(width), np.zeros(width)
    for a in range(0, width, width // 2 if width == 20 else width):
        s, o = dp_range_normalizer(stat["min"][a : a + 3], stat["max"][a : a + 3])
        scale[a : a + 3], offset[a : a + 3] = s, o
    return scale, offset


def robomimic_actions(n, arms, rng):
    """Absolute end-effector actions of a robosuite OSC_POSE controller with control_delta off:
    a wandering position, an orientation near the gripper-down pose (so some axis-angle vectors
    have norm near pi), a gripper command that closes once."""
    out = []
    for arm in range(arms):
        pos = np.cumsum(rng.normal(0, 0.01, (n, 3)), axis=0) + [0.1 * arm, 0.0, 1.0]
        if arm == 1:
            pos[:, 2] = 0.8  # a constant dimension: range below 1e-7, scale 1 and offset -min
        base = Rotation.from_euler("xyz", [np.pi - 0.05, 0.02 * (arm + 1), 0.3])
        wobble = Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.03, (n, 3)), axis=0))
        rotvec = (base * wobble).as_rotvec()
        grip = np.where(np.arange(n) < n // 2, -1.0, 1.0)[:, None]
        out.append(np.concatenate([pos, rotvec, grip], axis=1))
    return np.concatenate(out, axis=1)


def write_robomimic(path, episodes):
    with h5py.File(path, "w") as f:
        data = f.create_group("data")
        data.attrs["total"] = int(sum(len(e["actions"]) for e in episodes))
        data.attrs["env_args"] = json.dumps({"env_name": "Lift", "type": 1, "env_kwargs": {}})
        for i, ep in enumerate(episodes):
            g = data.create_group(f"demo_{i}")
            g.attrs["num_samples"] = len(ep["actions"])
            g.create_dataset("actions", data=ep["actions"])
            g.create_dataset("rewards", data=np.zeros(len(ep["actions"])))
            g.create_dataset("dones", data=np.zeros(len(ep["actions"]), np.int64))
            g.create_dataset("obs/robot0_eef_pos", data=ep["eef_pos"])
    return path


@pytest.mark.parametrize("arms", [1, 2], ids=["single_arm_7_to_10", "dual_arm_14_to_20"])
def test_abs_action_is_diffusion_policys_rotation_6d_and_normalizer(tmp_path, arms):
    rng = np.random.default_rng(arms)
    episodes = []
    for n in (40, 55, 31, 47, 60):
        # float32, so that the oracle and the build start from the same numbers.
        actions = robomimic_actions(n, arms, rng).astype(np.float32)
        eef = (actions[:, :3] + rng.normal(0, 1e-3, (n, 3))).astype(np.float32)
        episodes.append({"actions": actions, "eef_pos": eef})
    src = write_robomimic(tmp_path / "robomimic_abs.hdf5", episodes)
    spec = write_spec(tmp_path, "robomimic_hdf5", src,
                      {"action": "actions", "observation.eef_pos": "obs/robot0_eef_pos"},
                      '[profiles.dp]\npreset = "diffusion_policy"\nabs_action = true\n', fps=10,
                      split="val_fraction = 0.2\nseed = 0")
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "dp"
    ds = load_dataset(root)
    meta = ds.meta
    width = 10 * arms
    assert meta["channels"]["action"]["shape"] == [7 * arms]
    assert meta["channels"]["action"]["transformed_shape"] == [width]
    assert meta["stats_population"] == "frames"  # rotation only: every training step once
    assert [(t["op"], t["from"], t["to"], t["layout"]) for t in meta["transforms"]] == \
        [("rotation", "axis_angle", "rotation_6d", "rows")] * arms
    assert meta["normalization"]["action"]["mode"] == "dp_abs_action"

    train = meta["split"]["train"]
    # Converted in float64, then held as float32 like the actions they come from (Diffusion
    # Policy converts float32 actions in float32 torch): chunkc's statistics are over those values.
    converted = {e: dp_convert_actions(episodes[e]["actions"].astype(np.float64)).astype(np.float32).astype(np.float64)
                 for e in range(len(episodes))}
    rows = np.concatenate([converted[e] for e in train])
    # Diffusion Policy's array_to_stats: numpy's min, max, mean and (population) std.
    stat = {"min": rows.min(0), "max": rows.max(0), "mean": rows.mean(0), "std": rows.std(0)}
    scale, offset = dp_abs_action_normalizer(stat)
    if arms == 2:
        assert stat["max"][12] - stat["min"][12] < 1e-7  # the constant z of the second arm
        assert scale[12] == 1.0 and offset[12] == -stat["min"][12]

    params = json.loads((root / "dp_normalizer.json").read_text())["action"]
    close(params["scale"], scale, "dp_normalizer.json action.scale", rtol=1e-9, atol=1e-12)
    close(params["offset"], offset, "dp_normalizer.json action.offset", rtol=1e-9, atol=1e-12)
    for k in ("min", "max", "mean"):
        close(params["input_stats"][k], stat[k], f"dp_normalizer.json action.input_stats.{k}", rtol=1e-9, atol=1e-12)
    unbiased = np.allclose(params["input_stats"]["std"], rows.std(0, ddof=1), rtol=1e-9, atol=1e-12)
    assert not unbiased, (
        "dp_normalizer.json action.input_stats.std is the unbiased std (ddof=1, what LinearNormalizer.fit "
        "stores); robomimic_abs_action_only_normalizer_from_stat's input_stats are array_to_stats', numpy's "
        f"population std (ddof=0): off by sqrt(n/(n-1)) = {np.sqrt(len(rows) / (len(rows) - 1)):.6f} with n = {len(rows)}")
    close(params["input_stats"]["std"], stat["std"], "dp_normalizer.json action.input_stats.std", rtol=1e-9, atol=1e-12)
    # meta's center/scale are the same map: y = x * scale + offset = (x - center) / s.
    center, s, _ = normalization(meta, "action")
    close(1 / s, scale, "meta normalization action: 1/scale", rtol=1e-12)
    close(-center / s, offset, "meta normalization action: -center/scale", rtol=1e-12, atol=1e-12)

    # Diffusion Policy's windows: 16 steps from the first observation (t-1), edge repeated;
    # L - 7 samples per episode.
    k, lead = 16, 1
    want_keys = {(e, t) for e in train for t in range(len(episodes[e]["actions"]) - 7)}
    seen = set()
    for smp in samples(ds):
        e, t = smp["episode_index"], smp["frame_index"]
        seen.add((e, t))
        raw = clamped(converted[e], t - lead, k)
        want = raw * scale + offset
        close(smp["action"], want, f"episode {e} step {t} action", rtol=1e-5, atol=2e-6)
        back = ds.to_source("action", smp["action"], smp)
        src_rows = clamped(episodes[e]["actions"].astype(np.float64), t - lead, k)
        arm_rows = back.reshape(k, arms, 7)
        want_arms = src_rows.reshape(k, arms, 7)
        close(arm_rows[..., [0, 1, 2, 6]], want_arms[..., [0, 1, 2, 6]], f"episode {e} step {t} to_source pos/grip",
              rtol=1e-5, atol=1e-5)
        # Axis-angle is not unique near pi: compare the rotations they describe.
        close(Rotation.from_rotvec(arm_rows[..., 3:6].reshape(-1, 3)).as_matrix(),
              Rotation.from_rotvec(want_arms[..., 3:6].reshape(-1, 3)).as_matrix(),
              f"episode {e} step {t} to_source rotation", rtol=0, atol=1e-5)
    assert seen == want_keys


# --- UMI relative poses ---------------------------------------------------------------------------


def pose_matrix(pos, rotvec):
    T = np.zeros(pos.shape[:-1] + (4, 4))
    T[..., :3, :3] = Rotation.from_rotvec(rotvec.reshape(-1, 3)).as_matrix().reshape(pos.shape[:-1] + (3, 3))
    T[..., :3, 3] = pos
    T[..., 3, 3] = 1
    return T


def umi_relative(pose, base):
    """UMI's `convert_pose_mat_rep(pose, base, 'relative')` then `mat_to_pose10d` without the
    gripper: inv(T_base) @ T as position + rot6d (rows)."""
    rel = np.linalg.inv(base) @ pose
    return np.concatenate([rel[..., :3, 3], rot6d_rows(rel[..., :3, :3])], axis=-1)


def umi_source(rng, lengths=(30, 42, 25, 37, 50)):
    episodes = []
    for n in lengths:
        pos = np.cumsum(rng.normal(0, 0.02, (n, 3)), axis=0) + [0.4, 0.0, 0.3]
        rot = Rotation.from_euler("xyz", [np.pi, 0.1, 0.4]) * Rotation.from_rotvec(np.cumsum(rng.normal(0, 0.05, (n, 3)), axis=0))
        rotvec = rot.as_rotvec()
        eef = np.concatenate([pos, rotvec], axis=1)
        # The commanded pose leads the measured one by a step, as a tracking controller's does.
        target = np.concatenate([eef[1:], eef[-1:]], axis=0) + rng.normal(0, 1e-3, (n, 6))
        grip = np.clip(np.cumsum(rng.normal(0, 0.1, (n, 1)), axis=0), 0, 0.08)
        episodes.append({"action": np.concatenate([target, grip], axis=1).astype(np.float32),
                         "eef": eef.astype(np.float32)})
    return episodes


UMI_PROFILE = """
[profiles.umi]
chunk = 8
obs_history = 2
normalize = { action = "lerobot_mean_std", "observation.eef_pose" = "lerobot_mean_std" }
[[profiles.umi.transforms]]
op = "relative_pose"
channel = "action"
dims = [0, 6]
rotation = "axis_angle"
reference = "observation.eef_pose"
reference_dims = [0, 6]
to = "rotation_6d"
[[profiles.umi.transforms]]
op = "relative_pose"
channel = "observation.eef_pose"
dims = [0, 6]
rotation = "axis_angle"
reference = "observation.eef_pose"
reference_dims = [0, 6]
to = "rotation_6d"
"""


def test_relative_pose_is_umis_relative_representation(tmp_path):
    episodes = umi_source(np.random.default_rng(11))
    src = make_replay_buffer(tmp_path / "umi.zarr", episodes)
    spec = write_spec(tmp_path, "diffusion_policy_zarr", src, {"action": "action", "observation.eef_pose": "eef"},
                      UMI_PROFILE, fps=10, split="val_fraction = 0.2\nseed = 2")
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "umi"
    ds = load_dataset(root)
    meta = ds.meta
    assert meta["stats_population"] == "windows"  # relative_pose forces it
    assert meta["channels"]["action"]["transformed_shape"] == [10]
    assert meta["channels"]["observation.eef_pose"]["transformed_shape"] == [9]
    assert meta["transforms"][0] == {
        "op": "relative_pose", "channel": "action", "dims": [0, 6], "rotation": "axis_angle",
        "reference": "observation.eef_pose", "reference_dims": [0, 6], "reference_rotation": "axis_angle",
        "to": "rotation_6d", "layout": "rows", "convention": None}

    k, h = 8, 2
    train = meta["split"]["train"]
    want = {}
    for e in train:
        act, eef = episodes[e]["action"].astype(np.float64), episodes[e]["eef"].astype(np.float64)
        T_act, T_eef = pose_matrix(act[:, :3], act[:, 3:6]), pose_matrix(eef[:, :3], eef[:, 3:6])
        for t in range(len(act)):
            rows = np.clip(np.arange(t, t + k), 0, len(act) - 1)
            obs_rows = np.clip(np.arange(t - h + 1, t + 1), 0, len(act) - 1)
            a = np.concatenate([umi_relative(T_act[rows], T_eef[t]), act[rows, 6:]], axis=1)
            o = umi_relative(T_eef[obs_rows], T_eef[t])
            want[(e, t)] = (a, o, act[rows])
    actions = np.concatenate([w[0] for w in want.values()])
    obs = np.concatenate([w[1] for w in want.values()])
    stats = json.loads((root / "stats.json").read_text())
    for name, rows in [("action", actions), ("observation.eef_pose", obs)]:
        assert stats[name]["count"] == len(rows)
        close(stats[name]["mean"], rows.mean(0), f"stats.json {name}.mean", rtol=1e-7, atol=1e-9)
        close(stats[name]["std"], rows.std(0), f"stats.json {name}.std", rtol=1e-7, atol=1e-9)
        center, scale, _ = normalization(meta, name)
        close(center, rows.mean(0), f"normalization {name}.center", rtol=1e-7, atol=1e-9)
        close(scale, rows.std(0) + 1e-8, f"normalization {name}.scale", rtol=1e-7, atol=1e-9)

    seen = set()
    for s in samples(ds):
        key = (s["episode_index"], s["frame_index"])
        seen.add(key)
        a, o, source = want[key]
        what = f"episode {key[0]} step {key[1]}"
        assert_normalized(s["action"], a, *normalization(meta, "action")[:2], f"{what} action", tol=1e-5)
        assert_normalized(s["observation.eef_pose"], o, *normalization(meta, "observation.eef_pose")[:2],
                          f"{what} observation.eef_pose", tol=1e-5)
        back = ds.to_source("action", s["action"], s)
        close(back[:, [0, 1, 2, 6]], source[:, [0, 1, 2, 6]], f"{what} to_source pos/grip", rtol=1e-5, atol=1e-5)
        close(Rotation.from_rotvec(back[:, 3:6]).as_matrix(), Rotation.from_rotvec(source[:, 3:6]).as_matrix(),
              f"{what} to_source rotation", rtol=0, atol=1e-5)
    assert seen == set(want)


# --- every rotation kind against scipy ----------------------------------------------------------


def to_matrix(kind, values, convention=None):
    """(N, 3, 3) from a (N, w) slice in `kind`, as the contract defines each kind."""
    v = np.asarray(values, np.float64)
    if kind == "axis_angle":
        return Rotation.from_rotvec(v).as_matrix()
    if kind == "quaternion_xyzw":
        return Rotation.from_quat(v).as_matrix()  # scipy: scalar last; normalizes
    if kind == "quaternion_wxyz":
        return Rotation.from_quat(v[:, [1, 2, 3, 0]]).as_matrix()
    if kind == "euler":
        return Rotation.from_euler(convention, v).as_matrix()
    if kind == "matrix":
        return v.reshape(-1, 3, 3)
    if kind in ("rotation_6d", "rotation_6d_columns"):
        a1, a2 = v[:, :3], v[:, 3:]
        b1 = a1 / np.linalg.norm(a1, axis=1, keepdims=True)
        b2 = a2 - np.sum(b1 * a2, axis=1, keepdims=True) * b1
        b2 /= np.linalg.norm(b2, axis=1, keepdims=True)
        m = np.stack([b1, b2, np.cross(b1, b2)], axis=1)  # rows (pytorch3d)
        return m if kind == "rotation_6d" else np.swapaxes(m, 1, 2)
    raise ValueError(kind)


def from_rotation(kind, rot, convention=None):
    if kind == "axis_angle":
        return rot.as_rotvec()
    if kind == "quaternion_xyzw":
        return rot.as_quat()
    if kind == "quaternion_wxyz":
        return rot.as_quat()[:, [3, 0, 1, 2]]
    if kind == "euler":
        return rot.as_euler(convention)
    if kind == "matrix":
        return rot.as_matrix().reshape(-1, 9)
    if kind == "rotation_6d":
        return rot6d_rows(rot.as_matrix())
    if kind == "rotation_6d_columns":
        return rot6d_columns(rot.as_matrix())
    raise ValueError(kind)


WIDTH = {"axis_angle": 3, "quaternion_xyzw": 4, "quaternion_wxyz": 4, "euler": 3, "matrix": 9,
         "rotation_6d": 6, "rotation_6d_columns": 6}
# (from, to, convention, layout): every kind read and written at least once.
ROTATION_CASES = [
    ("axis_angle", "rotation_6d", None, "rows"),
    ("axis_angle", "rotation_6d", None, "columns"),
    ("quaternion_xyzw", "rotation_6d", None, "rows"),
    ("quaternion_wxyz", "matrix", None, None),
    ("euler", "quaternion_xyzw", "XYZ", None),      # intrinsic
    ("euler", "axis_angle", "xyz", None),           # extrinsic: a different rotation
    ("matrix", "quaternion_wxyz", None, None),
    ("rotation_6d", "axis_angle", None, "rows"),    # not orthonormal: pytorch3d's Gram-Schmidt
    ("rotation_6d", "axis_angle", None, "columns"),
    ("euler", "rotation_6d", "ZYX", "columns"),
]


@pytest.mark.parametrize("case", ROTATION_CASES, ids=lambda c: f"{c[0]}-{c[1]}-{c[2] or c[3] or ''}")
def test_rotation_kinds_equal_scipy(tmp_path, case):
    kind_from, kind_to, convention, layout = case
    src_kind = kind_from + ("_columns" if kind_from == "rotation_6d" and layout == "columns" else "")
    dst_kind = kind_to + ("_columns" if kind_to == "rotation_6d" and layout == "columns" else "")
    rng = np.random.default_rng(5)
    episodes, rots = [], []
    for n in (20, 33, 27):
        rot = Rotation.from_rotvec(rng.normal(0, 1.2, (n, 3)))
        values = from_rotation(src_kind, rot, convention)
        if kind_from.startswith("quaternion"):
            values = values * np.where(np.arange(n) % 5 == 0, 1.005, 1.0)[:, None]  # off by 5e-3: accepted
            values[1::2] *= -1  # q and -q are one rotation
        if kind_from == "rotation_6d":
            # Off unit length and orthogonality by less than the build's 1e-2: Gram-Schmidt matters.
            values = np.concatenate([1.004 * values[:, :3], values[:, 3:] + 0.004 * values[:, :3]], axis=1)
        pos = rng.normal(size=(n, 2))
        episodes.append({"action": np.concatenate([pos, values], axis=1).astype(np.float32)})
        rots.append(values)
    src = make_replay_buffer(tmp_path / "rot.zarr", episodes)
    w = WIDTH[src_kind]
    lines = ["[profiles.r]", "chunk = 3", 'normalize = { action = "none" }', "[[profiles.r.transforms]]",
             'op = "rotation"', 'channel = "action"', f"dims = [2, {2 + w}]", f'from = "{kind_from}"',
             f'to = "{kind_to}"']
    if convention:
        lines.append(f'convention = "{convention}"')
    if layout and "rotation_6d" in (kind_from, kind_to):
        lines.append(f'layout = "{layout}"')
    spec = write_spec(tmp_path, "diffusion_policy_zarr", src, {"action": "action"}, "\n".join(lines) + "\n",
                      fps=10, split="val_fraction = 0.0")
    run_chunkc("build", "-q", spec)
    ds = load_dataset(tmp_path / "out" / "r")
    assert ds.meta["channels"]["action"]["transformed_shape"] == [2 + WIDTH[dst_kind]]
    for s in samples(ds):
        e, t = s["episode_index"], s["frame_index"]
        stored = episodes[e]["action"].astype(np.float64)
        raw = clamped(stored, t, 3)
        want_matrix = to_matrix(src_kind, raw[:, 2:], convention)
        got = np.asarray(s["action"], np.float64)
        what = f"{case} episode {e} step {t}"
        close(got[:, :2], raw[:, :2], f"{what} untouched dims", rtol=0, atol=0)
        if kind_to.startswith("quaternion"):
            q = got[:, 2:]
            close(np.linalg.norm(q, axis=1), np.ones(3), f"{what} quaternion norm", rtol=0, atol=1e-6)
        close(to_matrix(dst_kind, got[:, 2:], convention), want_matrix, f"{what} rotation", rtol=0, atol=2e-6)
        if kind_to in ("rotation_6d", "matrix"):  # unique representations: equal value for value
            close(got[:, 2:], from_rotation(dst_kind, Rotation.from_matrix(want_matrix)), f"{what} values",
                  rtol=0, atol=2e-6)
        back = ds.to_source("action", s["action"], s)
        assert back.shape == raw.shape
        close(to_matrix(src_kind, back[:, 2:], convention), want_matrix, f"{what} to_source", rtol=0, atol=2e-6)
        if kind_to == "rotation_6d":
            # A network's 6D output is not orthonormal: to_source reads it with Gram-Schmidt.
            out = np.array(s["action"], np.float64)
            a1, a2 = out[:, 2:5].copy(), out[:, 5:8].copy()
            out[:, 2:5], out[:, 5:8] = 1.3 * a1, a2 + 0.2 * a1
            back = ds.to_source("action", out, s)
            close(to_matrix(src_kind, back[:, 2:], convention), want_matrix, f"{what} to_source of a skewed 6D",
                  rtol=0, atol=2e-6)


# --- bad specs ----------------------------------------------------------------------------------


def bad_spec_source(directory):
    rng = np.random.default_rng(0)
    eps = [{"action": rng.normal(size=(n, 7)).astype(np.float32),
            "action8": rng.normal(size=(n, 8)).astype(np.float32),
            "state": rng.normal(size=(n, 9)).astype(np.float32),
            "narrow": rng.normal(size=(n, 3)).astype(np.float32),
            "eef": rng.normal(size=(n, 6)).astype(np.float32)} for n in (20, 25)]
    return make_replay_buffer(directory / "bad.zarr", eps)


def transform(**keys):
    return "[[profiles.x.transforms]]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in keys.items())


ROT = dict(op="rotation", channel="action", dims=[3, 6], to="rotation_6d")
DELTA = dict(op="delta", channel="action", reference="observation.state")
REL = dict(op="relative_pose", channel="action", dims=[0, 6], rotation="axis_angle",
           reference="observation.eef", reference_dims=[0, 6], to="rotation_6d")
# (id, profile body, action source key, what stderr must name: each item a string, or a tuple of
# alternatives).
BAD = [
    ("slice_out_of_range", transform(**{**ROT, "dims": [5, 8], "from": "axis_angle"}), "action",
     ["transforms", "dims"]),
    ("slice_reversed", transform(**{**ROT, "dims": [6, 3], "from": "axis_angle"}), "action",
     ["transforms", "dims"]),
    ("from_width_differs_from_slice", transform(**{**ROT, "dims": [3, 7], "from": "axis_angle"}), "action",
     ["transforms", ("dims", "from")]),
    ("quaternion_on_three_dims", transform(**{**ROT, "from": "quaternion_wxyz"}), "action",
     ["transforms", ("dims", "from")]),
    ("delta_reference_missing", transform(**{**DELTA, "reference": "observation.nope", "mask": [6]}), "action",
     ["transforms", "reference"]),
    ("delta_reference_narrower_than_mask", transform(**{**DELTA, "reference": "observation.narrow", "mask": [6]}),
     "action", ["transforms", ("mask", "reference")]),
    ("mask_longer_than_channel", transform(**{**DELTA, "mask": [6, -1, 2]}), "action", ["transforms", "mask"]),
    ("unknown_op", transform(op="rotate", channel="action", dims=[3, 6]), "action",
     ["transforms", ("rotate", "op")]),
    ("unknown_rotation_kind", transform(**{**ROT, "from": "rodrigues"}), "action",
     ["transforms", ("rodrigues", "from")]),
    ("to_euler", transform(**{**ROT, "from": "axis_angle", "to": "euler", "convention": "xyz"}), "action",
     ["transforms", "to"]),
    ("euler_without_convention", transform(**{**ROT, "from": "euler"}), "action", ["transforms", "convention"]),
    ("unknown_channel", transform(**{**ROT, "channel": "observation.nope", "from": "axis_angle"}), "action",
     ["transforms", "channel"]),
    ("relative_pose_slice_not_pose", transform(**{**REL, "dims": [0, 5]}), "action", ["transforms", "dims"]),
    ("relative_pose_reference_dims_out_of_range", transform(**{**REL, "reference_dims": [3, 9]}), "action",
     ["transforms", "reference_dims"]),
    ("frames_with_delta", 'stats_population = "frames"\n' + transform(**{**DELTA, "mask": [6]}), "action",
     ["stats_population"]),
    ("abs_action_on_8_wide_action", "", "action8", ["abs_action"]),
    ("abs_action_without_diffusion_policy", None, "action", ["abs_action"]),
]


@pytest.mark.parametrize("name,body,action_key,needles", BAD, ids=[b[0] for b in BAD])
def test_bad_specs_are_refused_naming_the_key(tmp_path, name, body, action_key, needles):
    src = bad_spec_source(tmp_path)
    if name.startswith("abs_action"):
        preset = "act" if body is None else "diffusion_policy"
        profile = f'[profiles.x]\npreset = "{preset}"\nfps = 10\nchunk = 4\nabs_action = true\n'
    else:
        profile = "[profiles.x]\nchunk = 4\n" + body
    channels = {"action": action_key, "observation.state": "state", "observation.narrow": "narrow",
                "observation.eef": "eef"}
    spec = write_spec(tmp_path, "diffusion_policy_zarr", src, channels, profile, fps=10)
    proc = run_chunkc("check", spec, check=False)
    assert proc.returncode != 0, f"{name}: `chunkc check` accepted\n{spec.read_text()}"
    for needle in needles:
        options = needle if isinstance(needle, tuple) else (needle,)
        assert any(o in proc.stderr for o in options), f"{name}: stderr names none of {options}:\n{proc.stderr}"
    assert "panicked" not in proc.stderr


def test_the_good_spec_of_the_bad_cases_is_accepted(tmp_path):
    """The source of the cases above with valid transforms passes, so their failures are theirs."""
    src = bad_spec_source(tmp_path)
    profile = ("[profiles.x]\nchunk = 4\n" + transform(**{**ROT, "from": "axis_angle"})
               + transform(**{**DELTA, "mask": [3, -4]}))
    channels = {"action": "action", "observation.state": "state", "observation.narrow": "narrow",
                "observation.eef": "eef"}
    run_chunkc("check", write_spec(tmp_path, "diffusion_policy_zarr", src, channels, profile, fps=10))


BAD_ROTATIONS = {
    # kind: (width, a good rotation's values, how the bad step is spoiled)
    "quaternion_xyzw": (4, lambda r: r.as_quat(), lambda v: v * 1.5),
    "matrix": (9, lambda r: r.as_matrix().reshape(-1, 9), lambda v: v * 1.2),
    "rotation_6d": (6, lambda r: rot6d_rows(r.as_matrix()), lambda v: np.concatenate([v[:3], v[3:] + 0.3 * v[:3]])),
}


@pytest.mark.parametrize("kind", list(BAD_ROTATIONS))
def test_a_rotation_far_from_valid_fails_the_build_naming_episode_and_step(tmp_path, kind):
    """A quaternion off unit norm by 0.5, a matrix scaled by 1.2, a 6D rotation whose vectors are
    far from orthogonal: the build stops, names episode 2 and step 17, and writes nothing."""
    width, good, spoil = BAD_ROTATIONS[kind]
    rng = np.random.default_rng(3)
    episodes = []
    for n in (20, 24, 30):
        values = good(Rotation.from_rotvec(rng.normal(0, 1, (n, 3))))
        episodes.append({"action": np.concatenate([rng.normal(size=(n, 3)), values, np.ones((n, 1))], axis=1)
                        .astype(np.float32)})
    episodes[2]["action"][17, 3 : 3 + width] = spoil(episodes[2]["action"][17, 3 : 3 + width])
    src = make_replay_buffer(tmp_path / "q.zarr", episodes)
    to = "axis_angle" if kind == "rotation_6d" else "rotation_6d"
    profile = ("[profiles.x]\nchunk = 4\n"
               + transform(op="rotation", channel="action", dims=[3, 3 + width], to=to, **{"from": kind}))
    spec = write_spec(tmp_path, "diffusion_policy_zarr", src, {"action": "action"}, profile, fps=10,
                      split="val_fraction = 0.0")
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode != 0, f"a spoiled {kind} was accepted"
    assert re.search(r"episode\D{0,12}\b2\b", proc.stderr), proc.stderr
    assert re.search(r"step\D{0,12}\b17\b", proc.stderr), proc.stderr
    assert "panicked" not in proc.stderr
    assert not (tmp_path / "out" / "x" / "meta.json").exists(), "a failed build left an output behind"


# --- determinism ----------------------------------------------------------------------------------


DETERMINISM_FILES = ("stats.json", "norm_stats.json", "meta.json")
DETERMINISM_PROFILES = ("pi0", "pi05")


def test_threads_and_shards_give_the_same_bytes(tmp_path):
    profiles = (delta_profile("pi0", "pi0", "hdf5", G1_ARMS_MASK)
                + delta_profile("pi05", "pi05", "hdf5", G1_ARMS_MASK))
    outs = {}
    for label, threads in (("j1", 1), ("j2", 2)):
        spec = write_spec(tmp_path / label, "lerobot", G1, G1_CHANNELS, profiles)
        run_chunkc("build", "-q", "-j", threads, spec)
        outs[label] = tmp_path / label / "out"
    spec = write_spec(tmp_path / "shards", "lerobot", G1, G1_CHANNELS, profiles)
    parts = tmp_path / "partials"
    for i in range(2):
        run_chunkc("build", "-q", "--shard", f"{i}/2", "--partials", parts, spec)
    run_chunkc("merge", "-q", "--partials", parts, spec)
    outs["shards"] = tmp_path / "shards" / "out"
    for profile in DETERMINISM_PROFILES:
        for f in DETERMINISM_FILES:
            digests = {label: sha(out / profile / f) for label, out in outs.items()}
            assert len(set(digests.values())) == 1, f"{profile}/{f} differs: {digests}"
