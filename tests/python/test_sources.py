"""Source adapters: what chunkc reads must be what h5py, pyarrow and Pillow read from the same
files (episode ids, lengths, values, decoded frames), and bad sources fail clearly."""

import io
import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from PIL import Image

import fixtures
from conftest import REPO, run_chunkc

DATA = REPO / "tests" / "data"
PANDA = DATA / "robosuite_panda_lift.hdf5"
SAWYER = DATA / "robosuite_sawyer_lift.hdf5"
G1 = DATA / "lerobot_g1_subset"


def build(tmp_path, fmt, path, channels, fps=None, profile_fps=None, extra_source="",
          split="val_fraction = 0.0", raw=True, check=True):
    """Builds one `act` profile (K=2) at the source rate, storing every channel as read
    (normalize = none)."""
    lines = ["version = 1", "[source]", f'format = "{fmt}"', f'path = "{path}"']
    if fps is not None:
        lines.append(f"fps = {fps}")
    lines += [extra_source, "[source.channels]"]
    lines += [f'"{name}" = {value}' for name, value in channels.items()]
    lines += ["[split]", split, "[output]", 'dir = "out"', "[profiles.act]", 'preset = "act"',
              "chunk = 2"]
    profile_fps = profile_fps or fps or {"lerobot": 30 if Path(path) == G1 else 15}.get(fmt, 50)
    lines.append(f"fps = {profile_fps}")
    if raw:
        lines.append("[profiles.act.normalize]")
        lines += [f'"{name}" = "none"' for name in channels]
    spec = tmp_path / "spec.toml"
    spec.write_text("\n".join(lines) + "\n")
    return run_chunkc("build", "-q", spec, check=check)


def output(tmp_path):
    root = tmp_path / "out" / "act"
    meta = json.loads((root / "meta.json").read_text())
    return meta, h5py.File(root / "data.h5", "r")


def episodes_of(meta, data, name):
    ends = meta["episode_ends"]
    starts = [0] + ends[:-1]
    values = data["data"][name][:]
    return [values[s:e] for s, e in zip(starts, ends)]


def q(key):
    return json.dumps(key)


# robosuite / robomimic -------------------------------------------------------------------------

def test_robosuite_panda_reads_what_h5py_reads(tmp_path):
    build(tmp_path, "robomimic_hdf5", PANDA, {
        "action": q("actions"),
        "observation.state": '{ key = "states", columns = [1, 32] }',
    }, profile_fps=20)
    meta, out = output(tmp_path)
    with h5py.File(PANDA, "r") as f:
        demos = sorted(f["data"], key=lambda n: int(n.split("_")[1]))
        assert meta["episodes"] == [int(d.split("_")[1]) for d in demos]
        assert meta["episode_ends"] == list(np.cumsum([len(f["data"][d]["actions"]) for d in demos]))
        for d, act, state in zip(demos, episodes_of(meta, out, "action"),
                                 episodes_of(meta, out, "observation.state")):
            np.testing.assert_array_equal(act, f["data"][d]["actions"][:].astype(np.float32))
            np.testing.assert_array_equal(state, f["data"][d]["states"][:, 1:32].astype(np.float32))
        # The rate comes from the simulation clock in states[:, 0].
        dt = np.diff(f["data"][demos[0]]["states"][:, 0])
        assert meta["rate"]["source_fps"] == pytest.approx(1 / np.median(dt), rel=1e-3)


def test_robosuite_sawyer_concatenates_and_skips_zero_width(tmp_path):
    proc = build(tmp_path, "robomimic_hdf5", SAWYER, {
        "action": '{ concat = ["joint_velocities", "gripper_actuations", "left_dpos"] }',
        "observation.eef": '{ concat = ["right_dpos", "right_dquat"], columns = [1, 6] }',
    }, fps=100, profile_fps=100,
        # The values as recorded: the audit's re-grid of the irregular clock is test_audit's.
        split="val_fraction = 0.0\n[audit]\nrepair = false")
    assert "left_dpos" in proc.stderr and "zero width" in proc.stderr
    meta, out = output(tmp_path)
    with h5py.File(SAWYER, "r") as f:
        demos = sorted(f["data"], key=lambda n: int(n.split("_")[1]))
        assert meta["episodes"] == [int(d.split("_")[1]) for d in demos]
        lengths = [len(f["data"][d]["states"]) for d in demos]
        assert np.diff([0] + meta["episode_ends"]).tolist() == lengths
        for d, act, eef in zip(demos, episodes_of(meta, out, "action"),
                               episodes_of(meta, out, "observation.eef")):
            g = f["data"][d]
            want = np.concatenate([g["joint_velocities"][:], g["gripper_actuations"][:]], axis=1)
            np.testing.assert_array_equal(act, want.astype(np.float32))
            want = np.concatenate([g["right_dpos"][:], g["right_dquat"][:]], axis=1)[:, 1:6]
            np.testing.assert_array_equal(eef, want.astype(np.float32))


def write_robomimic(path, lengths, masks=True, bad_num_samples=None):
    """A robomimic file with demo_0..demo_{n-1} (so demo_10 sorts after demo_9 only numerically)."""
    rng = np.random.default_rng(1)
    with h5py.File(path, "w") as f:
        data = f.create_group("data")
        data.attrs["total"] = int(sum(lengths))
        data.attrs["env_args"] = json.dumps({"env_name": "Lift", "type": 1})
        for i, n in enumerate(lengths):
            g = data.create_group(f"demo_{i}")
            g.attrs["num_samples"] = n if i != bad_num_samples else n + 1
            g.create_dataset("actions", data=rng.uniform(-1, 1, (n, 7)))
            g.create_dataset("rewards", data=np.zeros(n))
            g.create_dataset("dones", data=np.zeros(n, np.int64))
            g.create_dataset("obs/robot0_eef_pos", data=rng.normal(size=(n, 3)))
            g.create_dataset("obs/robot0_gripper_qpos", data=rng.normal(size=(n, 2)).astype(np.float32))
        if masks:
            names = [f"demo_{i}" for i in range(len(lengths))]
            f.create_dataset("mask/train", data=np.array(names[:-3], dtype="S"))
            f.create_dataset("mask/valid", data=np.array(names[-3:], dtype="S"))


def test_robomimic_order_masks_and_values(tmp_path):
    lengths = [5 + (i * 7) % 11 for i in range(12)]
    src = tmp_path / "robomimic.hdf5"
    write_robomimic(src, lengths)
    build(tmp_path, "robomimic_hdf5", src, {
        "action": q("actions"),
        "observation.state": '{ concat = ["obs/robot0_eef_pos", "obs/robot0_gripper_qpos"] }',
        "observation.done": q("dones"),
    }, fps=20, split='from = "source"')
    meta, out = output(tmp_path)
    assert meta["episodes"] == list(range(12))  # numeric order: demo_10 after demo_9
    assert np.diff([0] + meta["episode_ends"]).tolist() == lengths
    with h5py.File(src, "r") as f:
        valid = sorted(int(n.decode().split("_")[1]) for n in f["mask/valid"][:])
        assert meta["split"]["val"] == valid
        assert meta["split"]["train"] == [i for i in range(12) if i not in valid]
        for i, state in enumerate(episodes_of(meta, out, "observation.state")):
            g = f["data"][f"demo_{i}"]
            want = np.concatenate([g["obs/robot0_eef_pos"][:], g["obs/robot0_gripper_qpos"][:]], axis=1)
            np.testing.assert_array_equal(state, want.astype(np.float32))
        done = np.concatenate(episodes_of(meta, out, "observation.done"))
        assert done.shape == (sum(lengths), 1)


def test_robomimic_num_samples_mismatch_names_file_and_demo(tmp_path):
    src = tmp_path / "robomimic.hdf5"
    write_robomimic(src, [6, 7, 8], bad_num_samples=1)
    proc = build(tmp_path, "robomimic_hdf5", src, {"action": q("actions")}, fps=20, check=False)
    assert proc.returncode == 3
    assert "robomimic.hdf5" in proc.stderr and "data/demo_1" in proc.stderr
    assert "num_samples is 8" in proc.stderr and "`actions` has 7 steps" in proc.stderr


def test_missing_key_lists_the_keys_that_exist(tmp_path):
    proc = build(tmp_path, "robomimic_hdf5", PANDA, {"action": q("action")}, check=False)
    assert proc.returncode == 2
    assert "actions, joint_torques, states" in proc.stderr
    assert "did you mean `actions`?" in proc.stderr


def test_corrupt_hdf5_is_a_clear_error(tmp_path):
    bad = tmp_path / "broken.hdf5"
    bad.write_bytes(PANDA.read_bytes()[:3000])
    proc = build(tmp_path, "robomimic_hdf5", bad, {"action": q("actions")}, check=False)
    assert proc.returncode == 3
    assert "broken.hdf5" in proc.stderr and "cannot open as HDF5" in proc.stderr
    assert "panicked" not in proc.stderr


# LeRobot ---------------------------------------------------------------------------------------

def g1_episodes():
    return [json.loads(line) for line in (G1 / "meta/episodes.jsonl").read_text().splitlines()]


def test_lerobot_g1_reads_what_pyarrow_reads(tmp_path):
    build(tmp_path, "lerobot", G1, {"action": q("action"), "observation.state": q("observation.state")})
    meta, out = output(tmp_path)
    info = json.loads((G1 / "meta/info.json").read_text())
    files = sorted((G1 / "data").rglob("*.parquet"))
    tables = [pq.read_table(p) for p in files]
    assert meta["episodes"] == [t["episode_index"][0].as_py() for t in tables]
    assert np.diff([0] + meta["episode_ends"]).tolist() == [t.num_rows for t in tables]
    assert meta["rate"]["source_fps"] == info["fps"]
    for t, act, state in zip(tables, episodes_of(meta, out, "action"),
                             episodes_of(meta, out, "observation.state")):
        np.testing.assert_array_equal(act, np.stack(t["action"].to_numpy(zero_copy_only=False)))
        np.testing.assert_array_equal(state, np.stack(t["observation.state"].to_numpy(zero_copy_only=False)))


@pytest.mark.parametrize("episode", [e["episode_index"] for e in g1_episodes()])
def test_lerobot_g1_episode_stats_match_lerobots_own(tmp_path, episode):
    """chunkc's statistics of one episode equal meta/episodes_stats.jsonl, LeRobot's numbers."""
    build(tmp_path, "lerobot", G1, {"action": q("action"), "observation.state": q("observation.state")},
          extra_source=f"episodes = [{episode}]")
    stats = json.loads((tmp_path / "out/act/stats.json").read_text())
    theirs = next(json.loads(line)["stats"] for line in (G1 / "meta/episodes_stats.jsonl").open()
                  if json.loads(line)["episode_index"] == episode)
    for feature in ("action", "observation.state"):
        assert stats[feature]["count"] == theirs[feature]["count"][0]
        for stat in ("mean", "std", "min", "max"):  # both population std (ddof = 0)
            np.testing.assert_allclose(stats[feature][stat], theirs[feature][stat], rtol=1e-5, atol=1e-7,
                                       err_msg=f"episode {episode} {feature} {stat}")


def test_lerobot_v3_episode_boundaries(tmp_path):
    src = tmp_path / "v3"
    lengths = (12, 7, 20, 9, 4)
    written = fixtures.write_lerobot_v3(src, lengths=lengths, per_file=3)
    # The fixture really holds several episodes per file, one row group each.
    first = pq.ParquetFile(src / "data/chunk-000/file-000.parquet")
    assert first.metadata.num_row_groups == 3
    assert sorted(set(first.read(columns=["episode_index"])["episode_index"].to_pylist())) == [0, 1, 2]
    build(tmp_path, "lerobot", src, {
        "action": q("action"),
        "observation.state": '{ concat = ["observation.state", "observation.gripper pos"] }',
    })
    meta, out = output(tmp_path)
    assert meta["episodes"] == list(range(len(lengths)))
    assert np.diff([0] + meta["episode_ends"]).tolist() == list(lengths)
    for e, act, state in zip(range(len(lengths)), episodes_of(meta, out, "action"),
                             episodes_of(meta, out, "observation.state")):
        np.testing.assert_array_equal(act, written[e]["action"])
        want = np.concatenate([written[e]["observation.state"],
                               written[e]["observation.gripper pos"][:, None]], axis=1)
        np.testing.assert_array_equal(state, want.astype(np.float32))


def test_lerobot_missing_video_names_the_file(tmp_path):
    proc = build(tmp_path, "lerobot", G1, {
        "action": q("action"), "observation.image": q("observation.images.cam_high")}, check=False)
    assert proc.returncode == 3
    assert ("episode 0, camera `observation.images.cam_high` (channel `observation.image`), "
            "file videos/chunk-000/observation.images.cam_high/episode_000000.mp4: the file is missing") in proc.stderr


def test_changed_source_file_invalidates_the_build(tmp_path):
    src = tmp_path / "v3"
    fixtures.write_lerobot_v3(src)
    channels = {"action": q("action")}
    build(tmp_path, "lerobot", src, channels)
    assert "up to date" in build(tmp_path, "lerobot", src, channels).stderr
    fixtures.write_lerobot_v3(src, seed=1)  # same layout, other values
    proc = build(tmp_path, "lerobot", src, channels)
    assert "built act" in proc.stderr, proc.stderr


# ALOHA -----------------------------------------------------------------------------------------

ALOHA_CHANNELS = {
    "action": q("action"),
    "observation.qpos": q("observations/qpos"),
    "observation.top": q("observations/images/top"),
    "observation.left_wrist": q("observations/images/left_wrist"),
}


def test_aloha_raw_frames_round_trip(tmp_path):
    written = fixtures.write_aloha(tmp_path / "src", lengths=(30, 45, 38))
    build(tmp_path, "aloha_hdf5", tmp_path / "src", ALOHA_CHANNELS)
    meta, out = output(tmp_path)
    assert meta["episodes"] == [0, 1, 2]
    assert meta["rate"]["source_fps"] == 50
    assert np.diff([0] + meta["episode_ends"]).tolist() == [30, 45, 38]
    for cam in fixtures.ALOHA_CAMS:
        for e, frames in enumerate(episodes_of(meta, out, f"observation.{cam}")):
            np.testing.assert_array_equal(frames, written[e][cam])
    for e, qpos in enumerate(episodes_of(meta, out, "observation.qpos")):
        np.testing.assert_array_equal(qpos, written[e]["qpos"])


def test_aloha_jpeg_frames_decode_like_pillow(tmp_path):
    written = fixtures.write_aloha(tmp_path / "src", lengths=(30, 45, 38), compressed=True)
    build(tmp_path, "aloha_hdf5", tmp_path / "src", ALOHA_CHANNELS)
    meta, out = output(tmp_path)
    assert np.diff([0] + meta["episode_ends"]).tolist() == [30, 45, 38]
    for cam in fixtures.ALOHA_CAMS:
        for e, frames in enumerate(episodes_of(meta, out, f"observation.{cam}")):
            with h5py.File(tmp_path / "src" / f"episode_{e}.hdf5", "r") as f:
                rows = f["observations/images"][cam][:]
            assert rows.ndim == 2  # the compressed layout: zero-padded JPEG bytes per step
            pillow = np.stack([np.asarray(Image.open(io.BytesIO(r.tobytes())).convert("RGB")) for r in rows])
            # chunkc decodes with libjpeg-turbo, like Pillow: the frames are identical.
            np.testing.assert_array_equal(frames, pillow)
            # And the same frames Pillow decodes from the bytes the fixture wrote.
            again = np.stack([np.asarray(Image.open(io.BytesIO(b))) for b in written[e][cam]])
            np.testing.assert_array_equal(pillow, again)


def test_aloha_gaps_are_reported(tmp_path):
    fixtures.write_aloha(tmp_path / "src", lengths=(10, 12, 14), ids=(0, 1, 3))
    proc = build(tmp_path, "aloha_hdf5", tmp_path / "src", {"action": q("action")})
    assert "no episode file for ids 2" in proc.stderr
    meta, _ = output(tmp_path)
    assert meta["episodes"] == [0, 1, 3]


def test_variable_list_with_a_wrong_length_names_file_episode_and_step(tmp_path):
    src = tmp_path / "v3"
    fixtures.write_lerobot_v3(src, lengths=(5, 6), per_file=2)
    path = src / "data/chunk-000/file-000.parquet"
    table = pq.read_table(path)
    states = table["observation.state"].to_pylist()
    states[7] = states[7][:3]  # episode 1, step 2: one value short
    table = table.set_column(table.schema.get_field_index("observation.state"), "observation.state",
                             pa.array(states, pa.list_(pa.float32())))
    pq.write_table(table, path)
    proc = build(tmp_path, "lerobot", src, {"action": q("action"), "observation.state": q("observation.state")},
                 check=False)
    assert proc.returncode == 3
    assert "file-000.parquet: episode 1: `observation.state`: step 2 has 3 values, expected 4" in proc.stderr


# Every example spec, built as the golden test builds it, reads the episodes the reference
# libraries see in the same files.

def reference_lengths(fmt, path):
    """{episode id: length} read with zarr-python, h5py or pyarrow, independently of chunkc."""
    if fmt == "diffusion_policy_zarr":
        import zarr
        ends = zarr.open(str(path), mode="r")["meta/episode_ends"][:]
        return dict(enumerate(np.diff(np.concatenate([[0], ends])).tolist()))
    if fmt == "robomimic_hdf5":
        with h5py.File(path, "r") as f:
            return {int(d.split("_")[1]): len(f["data"][d]["actions"] if "actions" in f["data"][d]
                                              else f["data"][d]["states"]) for d in f["data"]}
    if fmt == "aloha_hdf5":
        out = {}
        for p in Path(path).glob("episode_*.hdf5"):
            with h5py.File(p, "r") as f:
                out[int(p.stem.split("_")[1])] = len(f["action"])
        return out
    if fmt == "lerobot":
        rows = np.concatenate([pq.read_table(p, columns=["episode_index"])["episode_index"].to_numpy()
                               for p in sorted((Path(path) / "data").rglob("*.parquet"))])
        ids, counts = np.unique(rows, return_counts=True)
        return dict(zip(ids.tolist(), counts.tolist()))
    if fmt == "rlds":
        # The tfrecord package and protobuf: one Example per episode, ids over the splits in order.
        from tfrecord import example_pb2
        from tfrecord.reader import tfrecord_iterator
        version = Path(path) if (Path(path) / "dataset_info.json").exists() else next(Path(path).iterdir())
        info = json.loads((version / "dataset_info.json").read_text())
        lengths = []
        for split in info["splits"]:
            n = len(split["shardLengths"])
            for x in range(n):
                for rec in tfrecord_iterator(str(version / f"{info['name']}-{split['name']}.tfrecord-{x:05d}-of-{n:05d}")):
                    ex = example_pb2.Example()
                    ex.ParseFromString(rec)
                    lengths.append(len(ex.features.feature["steps/is_first"].int64_list.value))
        return dict(enumerate(lengths))
    raise AssertionError(fmt)


@pytest.mark.parametrize("spec", sorted(p.name for p in (REPO / "specs").glob("*.toml")))
def test_example_spec_episodes_match_reference_readers(tmp_path, spec):
    import tomllib
    (tmp_path / "specs").mkdir()
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "data").symlink_to(DATA)
    shutil.copy(REPO / "specs" / spec, tmp_path / "specs" / spec)
    run_chunkc("build", "-q", tmp_path / "specs" / spec)
    text = tomllib.loads((REPO / "specs" / spec).read_text())
    source = (tmp_path / "specs" / text["source"]["path"]).resolve()
    want = reference_lengths(text["source"]["format"], source)
    out = (tmp_path / "specs" / text["output"]["dir"]).resolve()
    for profile in text["profiles"]:
        meta = json.loads((out / profile / "meta.json").read_text())
        factor = meta["rate"]["factor"]
        assert meta["episodes"] == sorted(want)
        # Episodes the audit re-gridded (robosuite's irregular clock; their lengths are checked
        # against numpy in test_audit.py) start from their repaired length.
        for r in meta["repaired"]:
            assert r["recorded_len"] == want[r["id"]]
            want[r["id"]] = r["len"]
        lengths = np.diff([0] + meta["episode_ends"]).tolist()
        assert lengths == [-(-want[e] // factor) for e in sorted(want)]  # every factor-th step
