"""Training mixtures (`[sources.<name>]`, `[mixture]`) on two real vendored sources of different
rates and action widths: the Unitree G1 LeRobot subset (30 Hz, 26-wide action and state) and the
Push-T zarr subset (10 Hz, action 2, state 5), padded to 32, at 10 Hz.

Oracles: numpy on the sources as pyarrow and zarr-python read them (statistics per source and
over the union, quantiles included), the single-source builds' splits, the bytes of other thread
and shard counts, LeRobot's `LeRobotDataset` on the export. The loader's sampler, masks and
per-source normalization are tested in test_mixture_loader.py."""

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
import zarr

from conftest import G1, PUSHT, import_loader, model_tier, run_chunkc
from conftest import write_mixture_spec as mixture_spec

STATS_KEYS = [("mean", None), ("min", None), ("max", None), ("p001", 0.1), ("p999", 99.9),
              ("q01", 1), ("q10", 10), ("q50", 50), ("q90", 90), ("q99", 99)]



def g1_episodes(key):
    """Each G1 episode's `key` rows at 10 Hz (one step in three), read with pyarrow."""
    out = {}
    for f in sorted((G1 / "data").rglob("*.parquet")):
        t = pq.read_table(f)
        ep = np.asarray(t.column("episode_index").to_pylist())
        rows = np.asarray(t.column(key).to_pylist(), dtype=np.float32)
        for e in np.unique(ep):
            out[int(e)] = rows[ep == e][::3]
    return out


def pusht_episodes(key):
    root = zarr.open(str(PUSHT), mode="r")
    ends = root["meta/episode_ends"][:]
    starts = np.concatenate([[0], ends[:-1]])
    values = root["data"][key][:]
    return {e: values[s:t] for e, (s, t) in enumerate(zip(starts, ends))}


RAW = {"own": {"action": lambda: g1_episodes("action"),
               "observation.state": lambda: g1_episodes("observation.state")},
       "sim": {"action": lambda: pusht_episodes("action"),
               "observation.state": lambda: pusht_episodes("state")}}


def train_rows(meta, source, channel):
    episodes = RAW[source][channel]()
    return np.concatenate([episodes[i] for i in meta["sources"][source]["split"]["train"]]).astype(np.float64)


def assert_stats(got, rows, dims=None):
    dims = range(rows.shape[1]) if dims is None else dims
    for key, q in STATS_KEYS:
        want = rows.mean(0) if key == "mean" else rows.min(0) if key == "min" else \
            rows.max(0) if key == "max" else np.percentile(rows, q, axis=0)
        np.testing.assert_allclose(np.asarray(got[key])[list(dims)], want, rtol=1e-6, atol=1e-6, err_msg=key)
    np.testing.assert_allclose(np.asarray(got["std"])[list(dims)], rows.std(0), rtol=1e-6, atol=1e-6)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    d = tmp_path_factory.mktemp("mixture")
    run_chunkc("build", "-q", "-j", "2", mixture_spec(d))
    return d / "out"


def test_per_source_statistics_equal_numpy_on_each_sources_training_split(built):
    meta = json.loads((built / "dp" / "meta.json").read_text())
    for source in ("own", "sim"):
        own = json.loads((built / "dp" / "sources" / source / "stats.json").read_text())
        for channel in ("action", "observation.state"):
            rows = train_rows(meta, source, channel)
            assert own[channel]["count"] == len(rows)
            assert len(own[channel]["mean"]) == rows.shape[1] == meta["sources"][source]["widths"][channel]
            assert_stats(own[channel], rows)


def test_pooled_statistics_are_exact_over_the_union_per_dimension(built):
    meta = json.loads((built / "dp" / "meta.json").read_text())
    pooled = json.loads((built / "dp" / "stats.json").read_text())
    for channel in ("action", "observation.state"):
        own, sim = train_rows(meta, "own", channel), train_rows(meta, "sim", channel)
        stats = pooled[channel]
        assert len(stats["mean"]) == 32
        counts = []
        for d in range(32):
            cols = [r[:, d] for r in (own, sim) if r.shape[1] > d]
            counts.append(sum(len(c) for c in cols))
            if not cols:
                # No source has the dimension: zeros, counting nothing (padding is not data).
                assert stats["mean"][d] == 0 and stats["q99"][d] == 0
                continue
            assert_stats(stats, np.concatenate(cols)[:, None], dims=[d])
        assert stats["dim_count"] == counts
        assert stats["count"] == len(own) + len(sim)
    # The true union quantile is neither the min / max (LeRobot) nor the mean of the sources'.
    q99 = pooled["action"]["q99"][0]
    per = [json.loads((built / "dp" / "sources" / s / "stats.json").read_text())["action"]["q99"][0]
           for s in ("own", "sim")]
    assert q99 != max(per) and q99 != np.mean(per)


def test_each_source_splits_as_it_would_alone(built, tmp_path):
    meta = json.loads((built / "dp" / "meta.json").read_text())
    alone = tmp_path / "alone"
    alone.mkdir()
    spec = alone / "spec.toml"
    spec.write_text(f"""version = 1
[source]
format = "diffusion_policy_zarr"
path = "{PUSHT}"
fps = 10
[source.channels]
action = "action"
[split]
val_fraction = 0.25
seed = 0
[output]
dir = "out"
[profiles.dp]
preset = "diffusion_policy"
format = "zarr"
""")
    run_chunkc("build", "-q", spec)
    single = json.loads((alone / "out" / "dp" / "meta.json").read_text())
    assert meta["sources"]["sim"]["split"] == single["split"]
    offset = meta["sources"]["sim"]["id_offset"]
    assert offset == 8  # the G1 subset's ids are 0..7
    assert [i + offset for i in single["split"]["train"]] == \
        [i for i in meta["split"]["train"] if i >= offset]


def test_meta_names_each_episodes_source_and_the_balanced_weights(built):
    meta = json.loads((built / "dp" / "meta.json").read_text())
    assert meta["source"]["format"] == "mixture"
    assert meta["mixture"]["source_names"] == ["own", "sim"]
    sources = np.asarray(meta["episode_sources"])
    assert len(sources) == len(meta["episodes"]) == len(meta["episode_ends"])
    assert (sources == (np.asarray(meta["episodes"]) >= 8)).all()
    assert meta["mixture"]["weights"]["train"] == [0.7, 0.3]
    assert meta["sources"]["own"]["rate"]["factor"] == 3 and meta["sources"]["sim"]["rate"]["factor"] == 1
    n = meta["sources"]
    assert n["own"]["num_samples"]["train"] + n["sim"]["num_samples"]["train"] == meta["num_samples"]["train"]
    card = (built / "dp" / "README.md").read_text()
    assert "| format | `mixture` |" in card
    assert f"| `sim` | `diffusion_policy_zarr` | `{PUSHT}` | 10.0 Hz | 0.3 | 8 |" in card


@pytest.mark.parametrize("stats_mode", ["per_source", "pooled"])
def test_hdf5_stores_each_sources_rows_normalized_with_its_own_table_and_padding_zero(tmp_path, stats_mode):
    import h5py

    spec = mixture_spec(tmp_path, mixture=f'stats = "{stats_mode}"\npad_to = {{ action = 32, "observation.state" = 32 }}')
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "act"
    meta = json.loads((root / "meta.json").read_text())
    assert meta["stored_values"] == "normalized"
    with h5py.File(root / "data.h5") as f:
        stored = f["data/action"][...]
    ends = np.asarray(meta["episode_ends"])
    starts = np.concatenate([[0], ends[:-1]])
    pooled = json.loads((root / "stats.json").read_text())["action"]
    for source, s in (("own", 0), ("sim", 1)):
        n = meta["sources"][source]["normalization"]["action"]
        width = meta["sources"][source]["widths"]["action"]
        own_stats = json.loads((root / "sources" / source / "stats.json").read_text())["action"]
        fitted_on = own_stats if stats_mode == "per_source" else pooled
        # ACT's z-score: the unbiased std, floored at 0.01, over the statistics it was fitted on.
        count = np.asarray(fitted_on.get("dim_count", [fitted_on["count"]] * len(fitted_on["mean"])))[:width]
        std = np.asarray(fitted_on["std"])[:width] * np.sqrt(count / np.maximum(count - 1, 1))
        np.testing.assert_allclose(n["center"][:width], fitted_on["mean"][:width], rtol=1e-12)
        np.testing.assert_allclose(n["scale"][:width], np.maximum(std, 0.01), rtol=1e-9)
        assert n["center"][width:] == [0.0] * (32 - width) and n["scale"][width:] == [1.0] * (32 - width)
        raw = RAW[source]["action"]()
        for e, ep in enumerate(meta["episodes"]):
            if meta["episode_sources"][e] != s:
                continue
            rows = stored[starts[e]:ends[e]]
            want = (raw[ep - meta["sources"][source]["id_offset"]] - np.asarray(n["center"][:width])) \
                / np.asarray(n["scale"][:width])
            np.testing.assert_allclose(rows[:, :width], want, rtol=1e-5, atol=1e-5)
            assert (rows[:, width:] == 0).all()


def test_lerobot_export_is_one_dataset_with_a_source_column(built):
    root = built / "lerobot"
    meta = json.loads((root / "meta.json").read_text())
    data = pq.read_table(root / "data" / "chunk-000" / "file-000.parquet")
    tasks = pq.read_table(root / "meta" / "tasks.parquet").to_pydict()
    info = json.loads((root / "meta" / "info.json").read_text())
    assert info["features"]["source_index"] == {"dtype": "int64", "shape": [1], "names": None}
    episode = np.asarray(data.column("episode_index").to_pylist())
    source = np.asarray(data.column("source_index").to_pylist())
    task = np.asarray(data.column("task_index").to_pylist())
    assert sorted(set(episode.tolist())) == meta["episodes"]
    names = dict(zip(tasks["task_index"], tasks["__index_level_0__"]))
    for e, s in zip(meta["episodes"], meta["episode_sources"]):
        assert set(source[episode == e].tolist()) == {s}
        if s == 1:
            # Push-T stores no task: its episodes' task is their source's name.
            assert {names[t] for t in task[episode == e]} == {"sim"}
    assert np.asarray(data.column("action").to_pylist()).shape[1] == 32


def test_hdf5_and_zarr_keep_each_episodes_source(built):
    import h5py

    for profile, read in (("act", lambda p: h5py.File(p / "data.h5")["meta/episode_sources"][...]),
                          ("dp", lambda p: zarr.open(str(p / "data.zarr"), mode="r")["meta/episode_sources"][...])):
        meta = json.loads((built / profile / "meta.json").read_text())
        assert read(built / profile).tolist() == meta["episode_sources"]


def test_lerobot_dataset_opens_the_mixture_export(built):
    dataset = model_tier("lerobot.datasets.lerobot_dataset")
    meta = json.loads((built / "lerobot" / "meta.json").read_text())
    ds = dataset.LeRobotDataset("chunkc/mixture", root=built / "lerobot")
    assert ds.num_episodes == len(meta["episodes"])
    first, last = ds[0], ds[len(ds) - 1]
    assert int(first["source_index"]) == 0 and int(last["source_index"]) == 1
    assert last["task"] == "sim"
    assert tuple(last["action"].shape) == (32,)


def test_audit_writes_each_sources_report(tmp_path):
    spec = mixture_spec(tmp_path)
    proc = run_chunkc("audit", spec)
    assert "source `own`:" in proc.stdout and "source `sim`:" in proc.stdout
    for name, fps in (("own", 30.0), ("sim", 10.0)):
        report = json.loads((tmp_path / "out" / "audit" / name / "audit.json").read_text())
        assert report["source_fps"] == fps
        assert (tmp_path / "out" / "audit" / name / "report.html").exists()


def hashes(root: Path):
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_bytes_are_the_same_for_any_thread_or_shard_count(built, tmp_path):
    want = hashes(built)
    one = tmp_path / "j1"
    one.mkdir()
    run_chunkc("build", "-q", "-j", "1", mixture_spec(one))
    assert hashes(one / "out") == want
    sharded = tmp_path / "sharded"
    sharded.mkdir()
    spec = mixture_spec(sharded)
    for i in range(3):
        run_chunkc("build", "-q", spec, "--shard", f"{i}/3", "--partials", tmp_path / "partials")
    run_chunkc("merge", spec, "--partials", tmp_path / "partials")
    assert hashes(sharded / "out") == want


def test_changing_one_sources_weight_rebuilds_and_says_why(tmp_path):
    spec = mixture_spec(tmp_path)
    run_chunkc("build", "-q", spec)
    spec.write_text(spec.read_text().replace("weight = 0.3", "weight = 0.5"))
    plan = run_chunkc("plan", spec).stdout
    assert "sources.sim.weight" in plan
    run_chunkc("build", "-q", spec)
    meta = json.loads((tmp_path / "out" / "dp" / "meta.json").read_text())
    assert meta["mixture"]["weights"]["train"] == pytest.approx([0.7 / 1.2, 0.5 / 1.2])


BAD = [
    ("sim_extra", "weight = -1", "`sources.sim.weight` must be a finite number at least 0"),
    ("both_zero", None, "every source's weight is 0"),
    ("mixture", 'balance = "random"', "balance"),
    ("mixture", 'stats = "median"', "stats"),
    ("mixture", 'pad_to = { action = 20, "observation.state" = 32 }',
     "`mixture.pad_to.action = 20` is narrower than source `own`'s `action`, which has 26 values"),
    ("mixture", 'pad_to = { "observation.state" = 32 }',
     "`action` has per-step shape [2] in source `sim` but [26] in source `own`"),
    ("mixture", 'pad_to = { action = 32 }',
     "`observation.state` has per-step shape [5] in source `sim` but [26] in source `own`"),
]


@pytest.mark.parametrize("key,value,message", BAD, ids=[m[:30] for _, _, m in BAD])
def test_bad_mixtures_are_refused_naming_the_key(tmp_path, key, value, message):
    kwargs = {"own_extra": "weight = 0", "sim_extra": "weight = 0"} if key == "both_zero" else {key: value}
    spec = mixture_spec(tmp_path, **kwargs)
    proc = run_chunkc("build", spec, check=False)
    assert proc.returncode != 0
    assert message in proc.stderr, proc.stderr
    assert not (tmp_path / "out" / "dp").exists()


def test_two_sources_under_one_name_are_refused(tmp_path):
    spec = mixture_spec(tmp_path)
    text = spec.read_text()
    spec.write_text(text + text[text.index("[sources.sim]"):text.index("[mixture]")])
    proc = run_chunkc("check", spec, check=False)
    assert proc.returncode != 0 and "sim" in proc.stderr and "duplicate" in proc.stderr.lower(), proc.stderr


def test_a_channel_a_source_lacks_is_refused_unless_padded(tmp_path):
    spec = mixture_spec(tmp_path, mixture="")
    text = spec.read_text().replace('"observation.state" = "state"\n', "", 1)
    spec.write_text(text.replace("[mixture]\n", '[mixture]\npad_to = { action = 32 }\n'))
    proc = run_chunkc("build", spec, check=False)
    assert proc.returncode != 0
    assert "source `sim` maps no `observation.state`, which source `own` maps" in proc.stderr, proc.stderr
    spec.write_text(text.replace("[mixture]\n", '[mixture]\npad_to = { action = 32, "observation.state" = 26 }\n'))
    run_chunkc("build", "-q", spec)
    meta = json.loads((tmp_path / "out" / "dp" / "meta.json").read_text())
    assert meta["sources"]["sim"]["widths"]["observation.state"] == 0
    assert meta["sources"]["sim"]["normalization"]["observation.state"]["scale"] == [1.0] * 26


def test_each_sources_codebase_statistics_files_describe_that_source(built):
    import pickle

    meta = json.loads((built / "act" / "meta.json").read_text())
    for source in ("own", "sim"):
        rows = train_rows(meta, source, "action")
        act = pickle.loads((built / "act" / "sources" / source / "dataset_stats.pkl").read_bytes())
        np.testing.assert_allclose(act["action_mean"], rows.mean(0), rtol=1e-6)
        np.testing.assert_allclose(act["action_std"], np.maximum(rows.std(0, ddof=1), 1e-2), rtol=1e-6)
        lerobot = json.loads((built / "act" / "sources" / source / "lerobot_stats.json").read_text())
        np.testing.assert_allclose(lerobot["action"]["q99"], np.percentile(rows, 99, axis=0), rtol=1e-6)
        assert lerobot["action"]["count"] == [len(rows)]


def test_make_dataloader_draws_the_sources_with_their_weights(built):
    pytest.importorskip("torch")
    loader = import_loader(built / "dp")
    dl = loader.make_dataloader(built / "dp", "train", batch_size=256, num_workers=0, seed=3)
    ds = dl.dataset
    assert ds.source_names == ["own", "sim"]
    drawn = np.asarray(dl.sampler.indices)
    assert len(drawn) == len(ds)
    share = np.bincount(ds.window_sources[drawn], minlength=2) / len(drawn)
    # One epoch of draws (every training window once on average) at p = 0.7.
    assert abs(share[0] - 0.7) < 4 * np.sqrt(0.7 * 0.3 / len(drawn))
    batch = next(iter(dl))
    assert batch["action_dim_mask"].shape == (256, 32)
    own = batch["source"] == 0
    assert batch["action_dim_mask"][own].sum(1).eq(26).all() and batch["action_dim_mask"][~own].sum(1).eq(2).all()


def test_a_changed_file_of_one_source_rebuilds_and_names_it(tmp_path):
    sim = shutil.copytree(PUSHT, tmp_path / "pusht.zarr")
    spec = mixture_spec(tmp_path, sim=sim)
    run_chunkc("build", "-q", spec)
    assert "up to date" in run_chunkc("plan", spec).stdout
    chunk = sorted((sim / "data" / "action").glob("[0-9]*"))[0]
    root = zarr.open(str(sim), mode="r+")
    values = root["data/action"][:]
    values[0, 0] += 1.0
    root["data/action"][:] = values
    plan = run_chunkc("plan", spec).stdout
    assert f"sim/data/action/{chunk.name}" in plan and "was modified" in plan, plan
    run_chunkc("build", "-q", spec)
    assert "up to date" in run_chunkc("plan", spec).stdout
