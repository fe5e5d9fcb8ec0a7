"""`chunkc synth`: every layout it writes is read by the reference libraries (h5py, zarr-python,
pyarrow) and by chunkc's own adapters with equal values; the bytes depend only on the options;
trajectories are smooth; the timing faults are where faults.json says they are."""

import hashlib
import json
from pathlib import Path

import h5py
import numpy as np
import pyarrow.parquet as pq
import pytest
import zarr

from conftest import run_chunkc

LAYOUTS = ["aloha_hdf5", "robomimic_hdf5", "diffusion_policy_zarr", "lerobot"]


def synth(directory, fmt, *extra, episodes=4, steps=30, cameras=None, seed=3):
    cameras = (0 if fmt == "lerobot" else 1) if cameras is None else cameras
    run_chunkc("synth", directory, "--format", fmt.replace("_", "-"), "--episodes", episodes,
               "--steps", steps, "--action-dim", 5, "--state-dim", 3, "--cameras", cameras,
               "--resolution", "12x16", "--seed", seed, *extra)
    return Path(directory)


def read_reference(root, fmt):
    """Per episode id: {"action", "state", "cam0"?, "timestamps"?} as the reference libraries
    read them."""
    out = {}
    if fmt == "aloha_hdf5":
        for path in (root / "episodes").glob("episode_*.hdf5"):
            with h5py.File(path, "r") as f:
                ep = {"action": f["action"][:], "state": f["observations/qpos"][:]}
                if "images" in f["observations"]:
                    ep["cam0"] = f["observations/images/cam0"][:]
            out[int(path.stem.split("_")[1])] = ep
    elif fmt == "robomimic_hdf5":
        with h5py.File(root / "demos.hdf5", "r") as f:
            for name, g in f["data"].items():
                ep = {"action": g["actions"][:], "timestamps": g["states"][:, 0]}
                if "obs" in g:
                    assert g.attrs["num_samples"] == len(ep["action"])
                    ep["state"] = g["obs/robot0_joint_pos"][:]
                    ep["cam0"] = g["obs/cam0_image"][:]
                else:
                    ep["state"] = g["states"][:, 1:]
                out[int(name.split("_")[1])] = ep
    elif fmt == "diffusion_policy_zarr":
        z = zarr.open(str(root / "replay.zarr"), "r")
        ends = z["meta/episode_ends"][:]
        starts = np.concatenate([[0], ends[:-1]])
        action, state, cam = z["data/action"][:], z["data/state"][:], z["data/cam0"][:]
        for e, (s, t) in enumerate(zip(starts, ends)):
            out[e] = {"action": action[s:t], "state": state[s:t], "cam0": cam[s:t]}
    else:
        table = pq.read_table(root / "lerobot" / "data")
        info = json.loads((root / "lerobot/meta/info.json").read_text())
        assert info["codebase_version"] == "v3.0"
        col = {name: table[name].combine_chunks() for name in table.column_names}
        episode = col["episode_index"].to_numpy()
        for e in np.unique(episode):
            rows = np.flatnonzero(episode == e)
            assert (col["frame_index"].to_numpy()[rows] == np.arange(len(rows))).all()
            out[int(e)] = {
                "action": col["action"].flatten().to_numpy().reshape(len(episode), -1)[rows],
                "state": col["observation.state"].flatten().to_numpy()
                                                .reshape(len(episode), -1)[rows],
                "timestamps": col["timestamp"].to_numpy()[rows]}
    return out


def read_chunkc(root, channels):
    """What chunkc's adapter read: a build of the generated spec with normalize = none."""
    spec = root / "spec.toml"
    lines = ["chunk = 2", "[profiles.act.normalize]"] + [f'"{c}" = "none"' for c in channels
                                                          if c != "observation.cam0"]
    spec.write_text(spec.read_text() + "\n".join(lines) + "\n")
    run_chunkc("build", "-q", spec)
    out = root / "out" / "act"
    meta = json.loads((out / "meta.json").read_text())
    ends = meta["episode_ends"]
    starts = [0] + ends[:-1]
    with h5py.File(out / "data.h5", "r") as f:
        arrays = {c: f["data"][c][:] for c in channels}
    return {e: {c: a[s:t] for c, a in arrays.items()}
            for e, s, t in zip(meta["episodes"], starts, ends)}


@pytest.mark.parametrize("fmt", LAYOUTS)
def test_reference_readers_and_chunkc_read_the_same_values(tmp_path, fmt):
    root = synth(tmp_path / "s", fmt)
    ref = read_reference(root, fmt)
    assert sorted(ref) == [0, 1, 2, 3]
    channels = ["action", "observation.state"] + (["observation.cam0"] if fmt != "lerobot" else [])
    ours = read_chunkc(root, channels)
    assert sorted(ours) == sorted(ref)
    for e, ep in ref.items():
        assert ep["action"].shape == (30, 5) and ep["state"].shape == (30, 3)
        np.testing.assert_array_equal(ours[e]["action"], ep["action"].astype(np.float32))
        np.testing.assert_array_equal(ours[e]["observation.state"], ep["state"].astype(np.float32))
        if "cam0" in ep:
            assert ep["cam0"].shape == (30, 12, 16, 3) and ep["cam0"].dtype == np.uint8
            np.testing.assert_array_equal(ours[e]["observation.cam0"], ep["cam0"])
        if "timestamps" in ep:  # no faults asked for: exactly t / fps
            np.testing.assert_allclose(ep["timestamps"], np.arange(30) / 50, atol=1e-6)


@pytest.mark.parametrize("fmt", LAYOUTS)
def test_same_seed_same_bytes(tmp_path, fmt):
    def digest(root):
        h = hashlib.sha256()
        for p in sorted(root.rglob("*")):
            if p.is_file():
                h.update(str(p.relative_to(root)).encode())
                h.update(p.read_bytes())
        return h.hexdigest()

    a = synth(tmp_path / "a", fmt, "--faults", "drop:0.1", "--fault-fraction", "0.5")
    b = synth(tmp_path / "b", fmt, "--faults", "drop:0.1", "--fault-fraction", "0.5")
    c = synth(tmp_path / "c", fmt, "--faults", "drop:0.1", "--fault-fraction", "0.5", seed=4)
    assert digest(a) == digest(b)
    assert digest(a) != digest(c)


def test_trajectories_are_smooth_and_images_show_motion(tmp_path):
    root = synth(tmp_path / "s", "aloha_hdf5", steps=200, episodes=2)
    for ep in read_reference(root, "aloha_hdf5").values():
        a = ep["action"].astype(np.float64)
        # White noise has std(diff) = sqrt(2) * std; a smooth 50 Hz trajectory far less.
        assert (a.std(axis=0) > 0.01).all()
        assert (np.diff(a, axis=0).std(axis=0) < 0.1 * a.std(axis=0)).all()
        # The state follows the action (correlated), not independent noise.
        for d in range(3):
            assert np.corrcoef(a[:, d], ep["state"][:, d])[0, 1] > 0.9
        frames = ep["cam0"].astype(np.int16)
        assert np.abs(np.diff(frames, axis=0)).mean() > 0.5  # frames change over time
        assert 20 < frames.mean() < 235


def test_faults_are_where_faults_json_says(tmp_path):
    root = synth(tmp_path / "s", "lerobot", "--faults", "drop:0.1,jitter:0.2,dup:0.05",
                 "--fault-fraction", "0.5", episodes=12, steps=100)
    faults = json.loads((root / "faults.json").read_text())
    assert faults["timestamps_in"] == "timestamp"
    ref = read_reference(root, "lerobot")
    faulty = {int(e): {f["fault"]: f for f in v} for e, v in faults["episodes"].items()}
    assert 0 < len(faulty) < 12
    for e, ep in ref.items():
        ts = ep["timestamps"].astype(np.float64)
        if e not in faulty:
            assert len(ts) == 100
            np.testing.assert_allclose(np.diff(ts), 1 / 50, atol=1e-5)
            continue
        f = faulty[e]
        assert len(ts) == 100 - len(f["drop"]["steps"])
        assert 0 not in f["drop"]["steps"]
        # The stored steps' nominal times: the kept original steps over 50 Hz.
        kept = np.setdiff1d(np.arange(100), f["drop"]["steps"])
        dup = np.array(f["duplicate"]["steps"], dtype=int)
        d = np.diff(ts)
        np.testing.assert_array_equal(np.flatnonzero(d == 0) + 1, dup)
        ok = np.setdiff1d(np.arange(1, len(ts)), dup)
        np.testing.assert_array_less(np.abs(ts[ok] - kept[ok] / 50), 0.2 / 50 + 1e-5)


def test_wrong_rate_in_robosuite_states(tmp_path):
    root = synth(tmp_path / "s", "robomimic_hdf5", "--robosuite", "--faults", "rate:25",
                 "--fault-fraction", "1", cameras=0)
    for ep in read_reference(root, "robomimic_hdf5").values():
        np.testing.assert_allclose(np.diff(ep["timestamps"]), 1 / 25)


def test_bad_options_fail_clearly(tmp_path):
    # LeRobot cameras are yuv420p videos (or, without the `video` feature, not writable at all).
    proc = run_chunkc("synth", tmp_path / "x", "--format", "lerobot", "--cameras", "1",
                      "--resolution", "13x16", check=False)
    assert proc.returncode != 0
    assert "13x16" in proc.stderr or "`video` cargo feature" in proc.stderr, proc.stderr
    proc = run_chunkc("synth", tmp_path / "y", "--format", "aloha-hdf5", "--faults", "drop:2",
                      check=False)
    assert proc.returncode != 0 and "drop:2" in proc.stderr
    assert not (tmp_path / "x").exists()
