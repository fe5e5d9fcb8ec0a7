"""openpi-style co-training: one `pi0` profile over a training mixture of two robots, each with its
own `DeltaActions` mask (`[[profiles.<p>.transforms]] sources = [...]`), statistics over whole
delta chunks (`stats_population = "windows"`, the preset's), per source and pooled, and zero
padding to one width after normalizing.

Sources: the Unitree G1 LeRobot subset (`own`: 30 Hz, action and state 26 wide; mask 25 joints
delta + 1 absolute) and Push-T (`sim`: 10 Hz, action 2, state 5; mask 1 delta + 1 absolute),
padded to 32, at 10 Hz. The oracle is openpi's own `DeltaActions` / `make_bool_mask` /
`RunningStats` as test_transforms.py writes them from openpi's published code, run on each source
as pyarrow and zarr-python read it; numpy for the exact quantiles and the union."""

import hashlib
import json
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import load_dataset, model_tier, run_chunkc
from conftest import write_mixture_spec as mixture_spec
from test_mixture import RAW
from test_transforms import RunningStats, clamped, close, delta_actions, make_bool_mask, samples

HORIZON = 50
MASKS = {"own": (25, -1), "sim": (1, -1)}
WIDTHS = {"own": 26, "sim": 2}
STATE_WIDTHS = {"own": 26, "sim": 5}
PAD = 32


def delta(name, mask, sources):
    return f"""
[[profiles.{name}.transforms]]
op = "delta"
channel = "action"
reference = "observation.state"
mask = {json.dumps(list(mask))}
sources = {json.dumps(sources)}
"""


def pi0_profile(name, fmt="hdf5", masks=MASKS):
    text = f"""
[profiles.{name}]
preset = "pi0"
format = "{fmt}"
fps = 10
"""
    return text + "".join(delta(name, m, [s]) for s, m in masks.items())


PROFILES = pi0_profile("pi") + pi0_profile("pi_parquet", "parquet") + """
[profiles.act]
preset = "act"
format = "hdf5"
fps = 10
chunk = 8

[profiles.act_materialized]
preset = "act"
format = "hdf5"
fps = 10
chunk = 8
layout = "materialized"

[profiles.act_virtual]
preset = "act"
format = "hdf5"
fps = 10
chunk = 8
layout = "virtual"
"""


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("mixture_transforms")
    run_chunkc("build", "-q", "-j", "2", mixture_spec(d, profiles=PROFILES))
    return d


def population(meta, source):
    """What openpi's compute_norm_stats feeds RunningStats for one source's training split: every
    frame a sample, its 50-step chunk clamped at the episode end and made relative to the
    sample's state under the source's mask (float32, as openpi computes it); and the states.
    Returns (keys, delta chunks (N, H, w), states (N, ws), absolute chunks (N, H, w))."""
    actions, states = RAW[source]["action"](), RAW[source]["observation.state"]()
    keys, chunks, state_rows, absolute = [], [], [], []
    for e in meta["sources"][source]["split"]["train"]:
        action, state = actions[e], states[e]
        for t in range(len(action)):
            chunk = clamped(action, t, HORIZON)
            keys.append((e, t))
            absolute.append(chunk)
            chunks.append(delta_actions(chunk, state[t], make_bool_mask(*MASKS[source])))
            state_rows.append(state[t])
    return keys, *(np.stack(x).astype(np.float64) for x in (chunks, state_rows, absolute))


@pytest.fixture(scope="module")
def oracle(built):
    meta = json.loads((built / "out" / "pi" / "meta.json").read_text())
    return {s: population(meta, s) for s in ("own", "sim")}


def test_per_source_norm_stats_are_openpis_over_each_sources_delta_chunks(built, oracle):
    root = built / "out" / "pi"
    for source in ("own", "sim"):
        _, chunks, states, _ = oracle[source]
        norm = json.loads((root / "sources" / source / "norm_stats.json").read_text())["norm_stats"]
        for key, rows in [("actions", chunks.reshape(-1, WIDTHS[source])), ("state", states)]:
            running = RunningStats()
            batch = 32 * HORIZON if key == "actions" else 32
            for i in range(0, len(rows), batch):
                running.update(rows[i:i + batch])
            got = norm[key]
            close(got["mean"], running.mean, f"{source} {key}.mean", rtol=1e-4, atol=1e-9)
            close(got["std"], running.std(), f"{source} {key}.std", rtol=1e-4, atol=1e-9)
            for q in (1, 99):
                want = np.percentile(rows, q, axis=0, method="inverted_cdf")
                close(got[f"q{q:02d}"], want, f"{source} {key}.q{q:02d}", rtol=1e-3, atol=1e-9)


def test_pooled_norm_stats_are_the_union_per_dimension(built, oracle):
    root = built / "out" / "pi"
    norm = json.loads((root / "norm_stats.json").read_text())["norm_stats"]
    stats = json.loads((root / "stats.json").read_text())
    own = oracle["own"][1].reshape(-1, WIDTHS["own"])
    sim = oracle["sim"][1].reshape(-1, WIDTHS["sim"])
    got = norm["actions"]
    assert len(got["mean"]) == PAD
    # Dims 0..1: both robots; 2..25: the G1 only; 26..31: padding, counting nothing.
    for lo, hi, rows in [(0, 2, np.concatenate([own[:, :2], sim])), (2, 26, own[:, 2:26])]:
        close(got["mean"][lo:hi], rows.mean(axis=0), f"pooled mean[{lo}:{hi}]", rtol=1e-6, atol=1e-9)
        close(got["std"][lo:hi], rows.std(axis=0), f"pooled std[{lo}:{hi}]", rtol=1e-6, atol=1e-9)
        for q in (1, 99):
            want = np.percentile(rows, q, axis=0, method="inverted_cdf")
            close(got[f"q{q:02d}"][lo:hi], want, f"pooled q{q:02d}[{lo}:{hi}]", rtol=1e-6, atol=1e-9)
    assert stats["action"]["dim_count"][:2] == [len(own) + len(sim)] * 2
    assert stats["action"]["dim_count"][2:26] == [len(own)] * 24
    assert stats["action"]["dim_count"][26:] == [0] * 6
    assert np.all(np.asarray(got["std"][26:]) == 0)


def test_windows_are_each_sources_zscored_delta_chunk_padded_after(built, oracle):
    root = built / "out" / "pi"
    ds = load_dataset(root)
    meta = ds.meta
    assert meta["stats_population"] == "windows" and meta["stored_values"] == "raw"
    assert [t["sources"] for t in meta["transforms"]] == [["own"], ["sim"]]
    assert meta["channels"]["action"]["transformed_shape"] == [PAD]
    params = {}
    for source in ("own", "sim"):
        # pi0: openpi's z-score with std + 1e-6, from the source's own statistics.
        _, chunks, states, _ = oracle[source]
        rows = chunks.reshape(-1, WIDTHS[source])
        params[source] = {"action": (rows.mean(0), rows.std(0) + 1e-6),
                          "observation.state": (states.mean(0), states.std(0) + 1e-6)}
    where = {s: {k: i for i, k in enumerate(oracle[s][0])} for s in ("own", "sim")}
    seen = {"own": 0, "sim": 0}
    for s in samples(ds):
        source = ds.source_names[s["source"]]
        own_id = s["episode_index"] - meta["sources"][source]["id_offset"]
        i = where[source][(own_id, s["frame_index"])]
        _, chunks, states, absolute = oracle[source]
        w, ws = WIDTHS[source], STATE_WIDTHS[source]
        center, scale = params[source]["action"]
        what = f"{source} episode {own_id} step {s['frame_index']}"
        assert s["action"].shape == (HORIZON, PAD) and s["action"].dtype == np.float32
        close(s["action"][:, :w], (chunks[i] - center) / scale, f"{what} action", rtol=1e-4, atol=1e-4)
        assert np.all(s["action"][:, w:] == 0), f"{what}: the padding is exactly 0"
        np.testing.assert_array_equal(s["action_dim_mask"], np.arange(PAD) < w)
        center, scale = params[source]["observation.state"]
        close(s["observation.state"][0, :ws], (states[i] - center) / scale, f"{what} state", rtol=1e-4, atol=1e-4)
        assert np.all(s["observation.state"][:, ws:] == 0)
        # The way back: the source's absolute actions, at its own width.
        back = ds.to_source("action", s["action"], s)
        assert back.shape == (HORIZON, w)
        close(back, absolute[i], f"{what} to_source", rtol=1e-4, atol=1e-4)
        seen[source] += 1
    assert seen == {s: len(oracle[s][0]) for s in seen}


def test_parquet_export_and_validate(built):
    """The LeRobot export of the same profile opens with the loader's sources; the generated
    validate.py passes on both (per-source and pooled statistics over the window rows)."""
    model_tier("torch")  # validate.py runs the target policy forward
    for profile in ("pi", "pi_parquet"):
        root = built / "out" / profile
        for source in ("own", "sim"):
            assert (root / "sources" / source / "norm_stats.json").exists()
        out = built / f"validate_{profile}"
        done = subprocess.run([sys.executable, str(root / "validate.py"), "--tiny", "--out", str(out)],
                              capture_output=True, text=True)
        assert done.returncode == 0, done.stdout + done.stderr


def test_materialized_and_virtual_layouts_give_the_index_windows(built):
    out = built / "out"
    index = load_dataset(out / "act")
    for layout in ("act_materialized", "act_virtual"):
        other = load_dataset(out / layout)
        assert len(other) == len(index)
        with h5py.File(out / layout / "data.h5") as f:
            chunks = f["chunks"]["action"][...]
            pads = f["chunks"]["action_is_pad"][...]
        train = json.loads((out / layout / "meta.json").read_text())["num_samples"]["train"]
        for a, b in zip(samples(index), samples(other)):
            for key in ("action", "action_is_pad", "observation.state", "source", "episode_index", "frame_index"):
                np.testing.assert_array_equal(a[key], b[key], err_msg=f"{layout} {key}")
        # /chunks/action holds exactly the index layout's normalized windows, train first.
        want = np.stack([s["action"] for s in samples(index)])
        np.testing.assert_array_equal(chunks[:train], want, err_msg=f"{layout} /chunks/action")
        np.testing.assert_array_equal(pads[:train], np.stack([s["action_is_pad"] for s in samples(index)]))


def tree_hashes(root):
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file() and p.name != "chunkc.lock"}


def test_same_bytes_with_one_thread_and_from_shards(built, tmp_path):
    spec = mixture_spec(tmp_path, profiles=PROFILES)
    run_chunkc("build", "-q", "-j", "1", spec)
    want = {p: tree_hashes(built / "out" / p) for p in ("pi", "pi_parquet", "act_materialized")}
    for profile, hashes in want.items():
        assert tree_hashes(tmp_path / "out" / profile) == hashes, profile
    sharded = tmp_path / "sharded"
    sharded.mkdir()
    spec = mixture_spec(sharded, profiles=PROFILES)
    for i in range(3):
        run_chunkc("build", "-q", spec, "--shard", f"{i}/3", "--partials", str(sharded / "partials"))
    run_chunkc("merge", "-q", spec, "--partials", str(sharded / "partials"))
    for profile, hashes in want.items():
        assert tree_hashes(sharded / "out" / profile) == hashes, profile


def test_a_mask_that_does_not_fit_a_source_is_refused_naming_mask_and_source(tmp_path):
    spec = mixture_spec(tmp_path, profiles=pi0_profile("pi", masks={"own": (25, -1)}) + delta("pi", (25, -1), ["sim"]))
    done = run_chunkc("check", spec, check=False)
    assert done.returncode != 0
    assert "transforms[1].mask" in done.stderr and "source `sim`" in done.stderr, done.stderr
    assert "26 dimensions" in done.stderr and "2 values per step" in done.stderr, done.stderr
    # Without `sources`, the same mask applies to every source, and Push-T's action is too narrow.
    text = spec.read_text().replace('sources = ["own"]\n', "")
    spec.write_text(text)
    done = run_chunkc("check", spec, check=False)
    assert done.returncode != 0 and "source `sim`" in done.stderr, done.stderr
    # An unknown source is named, with the known ones.
    spec.write_text(text.replace('sources = ["sim"]', 'sources = ["arm"]'))
    done = run_chunkc("check", spec, check=False)
    assert done.returncode != 0 and "no source `arm`" in done.stderr and "own, sim" in done.stderr, done.stderr
    assert not (tmp_path / "out").exists()


NATIVE = """
[profiles.act_native]
preset = "act"
format = "act_episodes"
fps = 10

[profiles.rm]
preset = "diffusion_policy"
format = "robomimic_hdf5"
fps = 10
"""


def padded(values, width=PAD):
    out = np.zeros((len(values), width), values.dtype)
    out[:, :values.shape[1]] = values
    return out


def test_native_exports_hold_each_source_episode_padded_with_its_dim_mask(tmp_path):
    """ACT episodes and robomimic demos of a mixture: one file / demo per source episode at the
    padded width, raw values as ACT's EpisodicDataset and robomimic's SequenceDataset read them
    (`/action`, `/observations/qpos`; `data/demo_<i>/actions`, `obs/<key>`), the source named
    beside them (`source`) and its own dimensions marked (`dim_mask`)."""
    run_chunkc("build", "-q", mixture_spec(tmp_path, profiles=NATIVE))
    out = tmp_path / "out"
    raw = {s: (RAW[s]["action"](), RAW[s]["observation.state"]()) for s in ("own", "sim")}
    for profile in ("act_native", "rm"):
        meta = json.loads((out / profile / "meta.json").read_text())
        names = meta["mixture"]["source_names"]
        assert sorted(set(meta["episode_sources"])) == [0, 1]
        for e, (episode, s) in enumerate(zip(meta["episodes"], meta["episode_sources"])):
            source = names[s]
            action, state = (v[episode - meta["sources"][source]["id_offset"]] for v in raw[source])
            if profile == "act_native":
                f = h5py.File(out / profile / f"episode_{e}.hdf5", "r")
                group, arrays = f, {"action": "action", "state": "observations/qpos"}
            else:
                f = h5py.File(out / profile / "data.hdf5", "r")
                group = f["data"][f"demo_{e}"]
                arrays = {"action": f"data/demo_{e}/actions", "state": f"data/demo_{e}/obs/observation.state"}
            with f:
                assert group.attrs["source"] == source
                for key, want, width in [("action", action, WIDTHS[source]), ("state", state, STATE_WIDTHS[source])]:
                    got = f[arrays[key]]
                    np.testing.assert_array_equal(got[()], padded(want).astype(got.dtype), err_msg=f"{profile} {e} {key}")
                    np.testing.assert_array_equal(got.attrs["dim_mask"], np.arange(PAD) < width)


SEGMENTS = """
[profiles.seg]
chunk = 40
padding = "mask"
fps = 10
[profiles.seg.segment]
method = "velocity"
channel = "observation.state"
dims = [3, 4]
threshold = 0.0003
"""


def test_segments_are_cut_per_source_episode_as_each_source_alone(tmp_path):
    """Segment sampling over a mixture: each source episode is cut exactly as the same profile
    cuts it when that source is built alone (same rate, same watched dimension)."""
    from conftest import G1, PUSHT
    from conftest import write_spec as pusht_spec
    from test_transforms import write_spec as lerobot_spec

    for d in ("mix", "sim"):
        (tmp_path / d).mkdir()
    run_chunkc("build", "-q", mixture_spec(tmp_path / "mix", profiles=SEGMENTS))
    mixed = json.loads((tmp_path / "mix" / "out" / "seg" / "meta.json").read_text())
    alone = {
        "sim": pusht_spec(tmp_path / "sim", SEGMENTS, source=PUSHT, fps=10,
                          channels={"action": "action", "observation.state": "state"}),
        "own": lerobot_spec(tmp_path / "own", "lerobot", G1, {"action": "action", "observation.state": "observation.state"},
                            SEGMENTS),
    }
    names = mixed["mixture"]["source_names"]
    got = {}
    for e, (episode, s) in enumerate(zip(mixed["episodes"], mixed["episode_sources"])):
        source = names[s]
        got[(source, episode - mixed["sources"][source]["id_offset"])] = mixed["sampling"]["segments"][e]
    for source, spec in alone.items():
        run_chunkc("build", "-q", spec)
        meta = json.loads((spec.parent / "out" / "seg" / "meta.json").read_text())
        for e, episode in enumerate(meta["episodes"]):
            assert got[(source, episode)] == meta["sampling"]["segments"][e], f"{source} episode {episode}"
    assert len(got) == sum(len(json.loads((alone[s].parent / "out" / "seg" / "meta.json").read_text())["episodes"])
                           for s in alone)
    # The watched dimension moves: both sources' episodes are cut at breakpoints, not only at
    # the 40-step maximum.
    ends = np.asarray(mixed["episode_ends"])
    lengths = np.diff(np.concatenate([[0], ends]))
    for s in (0, 1):
        cut = [len(mixed["sampling"]["segments"][e]) > -(-lengths[e] // 40)
               for e in range(len(ends)) if mixed["episode_sources"][e] == s]
        assert any(cut), names[s]
