"""The generated scripts run the TARGET models: LeRobot's ACTPolicy and DiffusionPolicy forward on
our loader's batches, smoke training whose loss falls, the K sweep, and a Push-T rollout.

Tiny settings throughout (small dims, 32x32 images, a few dozen steps, one CPU thread each) so
that the file stays within a few minutes on two cores."""

import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from conftest import model_tier, REPO, run_chunkc

model_tier("torch")
model_tier("lerobot")

# One thread per script: on a shared 2-core machine torch's own threads only contend.
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def example(tmp_path_factory, stem):
    """specs/<stem>.toml built inside a scratch copy of the layout it expects."""
    d = tmp_path_factory.mktemp(stem)
    (d / "specs").mkdir()
    shutil.copy(REPO / "specs" / f"{stem}.toml", d / "specs")
    (d / "tests" / "data").mkdir(parents=True)
    os.symlink(REPO / "tests" / "data" / "pusht_subset.zarr", d / "tests" / "data" / "pusht_subset.zarr")
    run_chunkc("build", "-q", d / "specs" / f"{stem}.toml")
    return d / "out" / stem


@pytest.fixture(scope="module")
def pusht(tmp_path_factory):
    return example(tmp_path_factory, "pusht")


@pytest.fixture(scope="module")
def rollout_ready(tmp_path_factory):
    return example(tmp_path_factory, "pusht_rollout")


def script(profile, name, *args, env=ENV):
    return subprocess.run([sys.executable, str(profile / name), *map(str, args)], capture_output=True, text=True,
                          env=env)


def smoke(profile, out, *extra):
    proc = script(profile, "smoke_train.py", "--out", out, "--tiny", "--batch-size", 16, "--eval-samples", 32,
                  "--eval-steps", 3, *extra)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads((out / "metrics.json").read_text())


@pytest.mark.parametrize("name,policy", [("act", "LeRobot ACTPolicy"), ("dp", "LeRobot DiffusionPolicy")])
def test_validate_runs_the_target_policy_on_a_loader_batch(tmp_path, pusht, name, policy):
    profile = pusht / name
    meta = json.loads((profile / "meta.json").read_text())
    out = tmp_path / "v"
    proc = script(profile, "validate.py", "--out", out, "--tiny", "--episodes", 1, "--batch-size", 4)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads((out / "validate.json").read_text())
    assert report["policy"] == policy and f"forward pass of {policy}" in proc.stdout
    assert np.isfinite(report["loss"])
    assert report["output_shape"] == [4, meta["chunk_size"], meta["channels"]["action"]["shape"][0]]
    assert report["round_trip_error"] <= 1e-6
    # LeRobot's own normalizer fed with our stats.json agrees with the loader: exactly for
    # limits (MIN_MAX); for z-score within ACT's unbiased-vs-biased std (a relative 1/(2n)).
    diffs = report["lerobot_normalizer"]
    assert set(diffs) == {"action", "observation.state"}
    tolerance = 1e-6 if name == "dp" else 1e-3
    assert max(diffs.values()) <= tolerance, diffs
    # One episode: its action plot and its animation (chunk drawn as waypoints: Push-T's
    # pixel actions), and a histogram per low-dim channel.
    assert "waypoints on the frames (512x512 workspace)" in proc.stdout
    files = set(report["files"])
    assert {"hist_action.png", "hist_observation.state.png"} <= files
    gifs = [f for f in files if f.endswith(".gif")]
    assert len(gifs) == 1 and (out / gifs[0]).read_bytes()[:6] == b"GIF89a"
    assert isinstance(report["strays"], list)


def test_histograms_name_the_dimensions_that_stray(tmp_path, pusht):
    """The strays printed are those an independent numpy reading of the data file finds."""
    import h5py

    profile = pusht / "act"
    out = tmp_path / "v"
    # The policy part is covered above; the histograms are what this test reads.
    proc = script(profile, "validate.py", "--out", out, "--tiny", "--episodes", 0, "--batch-size", 2)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads((out / "validate.json").read_text())
    meta = json.loads((profile / "meta.json").read_text())
    train = set(meta["split"]["train"])
    ends = np.asarray(meta["episode_ends"])
    starts = np.concatenate([[0], ends[:-1]])
    rows = np.concatenate([np.arange(s, e) for s, e, i in zip(starts, ends, meta["episodes"]) if i in train])
    expected = []
    with h5py.File(profile / "data.h5") as f:
        for name in ("action", "observation.state"):
            x = f[f"data/{name}"][...][rows].astype(np.float64)
            for d in range(x.shape[1]):
                tail = np.mean(np.abs(x[:, d]) > 3)
                if tail > 0.01 or abs(x[:, d].mean()) > 0.5:
                    expected.append(f"{name}[{d}]")
    assert [s.split(" ")[0] for s in report["strays"]] == expected
    for name in expected:
        assert name in proc.stdout


def test_missing_lerobot_says_how_to_install_it(tmp_path, pusht):
    code = (
        "import sys, runpy; sys.modules['lerobot'] = None; "
        f"sys.argv = ['validate.py', '--out', {str(tmp_path / 'v')!r}, '--episodes', '0', '--batch-size', '2']; "
        f"runpy.run_path({str(pusht / 'dp' / 'validate.py')!r}, run_name='__main__')"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV)
    assert proc.returncode == 2
    assert 'pip install "lerobot==0.4.4"' in proc.stderr
    assert "forward pass" not in proc.stdout  # no silent stand-in model


@pytest.mark.parametrize("name", ["act", "dp"])
def test_smoke_training_of_the_target_policy_lowers_its_loss(tmp_path, pusht, name):
    m = smoke(pusht / name, tmp_path / "smoke", "--max-steps", 30, "--episodes", 6)
    assert m["policy"] == ("LeRobot ACTPolicy" if name == "act" else "LeRobot DiffusionPolicy")
    assert m["steps"] == 30 and m["episodes"] == 6
    # The same batch, noise and dropout before and after: the loss fell.
    assert m["fixed_batch_loss_after"] < 0.7 * m["fixed_batch_loss_before"], m
    assert m["final_loss"] < m["initial_loss"]
    meta = json.loads((pusht / name / "meta.json").read_text())
    assert len(m["per_step_error"]) == meta["chunk_size"] and np.all(np.isfinite(m["per_step_error"]))
    for png in ("loss.png", "horizon_error.png"):
        assert (tmp_path / "smoke" / png).read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "smoke" / "policy" / "config.json").exists()


def test_k_sweep_writes_its_plot_and_per_k_metrics(tmp_path, pusht):
    profile = pusht / "act"
    out = tmp_path / "sweep"
    proc = script(profile, "smoke_train.py", "--sweep", "--out", out, "--max-steps", 8, "--episodes", 4,
                  "--batch-size", 8, "--eval-samples", 16)
    assert proc.returncode == 0, proc.stderr[-3000:]
    sweep = json.loads((out / "sweep.json").read_text())
    assert sweep["profile_chunk"] == 20
    assert sorted(int(k) for k in sweep["results"]) == [10, 20, 40]
    for k, r in sweep["results"].items():
        assert len(r["val_error_per_step"]) == int(k) and np.isfinite(r["val_error_mean"])
    assert (out / "sweep.png").read_bytes()[:4] == b"\x89PNG"


def test_rollout_of_the_smoke_trained_diffusion_policy_in_pusht(tmp_path, rollout_ready):
    profile = rollout_ready / "dp"
    meta = json.loads((profile / "meta.json").read_text())
    assert meta["env"] == "gym_pusht/PushT-v0" and meta["channels"]["observation.state"]["shape"] == [2]
    smoke(profile, tmp_path / "smoke", "--max-steps", 10, "--episodes", 4)
    out = tmp_path / "rollout"
    proc = script(profile, "rollout.py", "--checkpoint", tmp_path / "smoke" / "policy", "--out", out,
                  "--episodes", 2, "--max-steps", 24, "--ddim-steps", 3)
    assert proc.returncode == 0, proc.stderr[-3000:]
    m = json.loads((out / "metrics.json").read_text())
    assert m["env"] == "gym_pusht/PushT-v0" and m["episodes"] == 2 and m["executes"] == meta["executes"]
    assert 0.0 <= m["success_rate"] <= 1.0
    for e in m["per_episode"]:
        assert e["steps"] == 24 or e["success"]
        # gym-pusht's reward is clip(coverage / 0.95, 0, 1).
        assert e["max_reward"] == pytest.approx(min(1.0, e["max_coverage"] / 0.95), abs=1e-9)
    assert m["mean_max_reward"] == pytest.approx(np.mean([e["max_reward"] for e in m["per_episode"]]))
    for gif in m["videos"]:
        assert (out / gif).read_bytes()[:6] == b"GIF89a"


def test_rollout_names_the_observations_the_env_cannot_provide(tmp_path):
    """specs/pusht.toml's 5-D state (agent and block pose) is no observation gym-pusht gives."""
    spec = (REPO / "specs" / "pusht.toml").read_text()
    spec = spec.replace('"../tests/data/pusht_subset.zarr"', f'"{REPO / "tests" / "data" / "pusht_subset.zarr"}"')
    spec = spec.replace('"../out/pusht"', '"out"').replace('preset = "diffusion_policy"',
                                                          'preset = "diffusion_policy"\nenv = "gym_pusht/PushT-v0"')
    (tmp_path / "spec.toml").write_text(spec)
    run_chunkc("build", "-q", tmp_path / "spec.toml")
    assert not (tmp_path / "out" / "act" / "rollout.py").exists()  # no env, no rollout script
    proc = script(tmp_path / "out" / "dp", "rollout.py", "--checkpoint", tmp_path / "none")
    assert proc.returncode != 0
    assert "cannot provide the observation keys the policy needs: observation.state (lowdim (5,))" in proc.stderr
    assert 'columns = [0, 2]' in proc.stderr


def test_env_must_be_a_gymnasium_id(tmp_path):
    spec = (REPO / "specs" / "pusht_rollout.toml").read_text()
    spec = spec.replace('"../tests/data/pusht_subset.zarr"', f'"{REPO / "tests" / "data" / "pusht_subset.zarr"}"')
    spec = spec.replace('env = "gym_pusht/PushT-v0"\nformat', 'env = "gym_pusht/PushT"\nformat', 1)
    (tmp_path / "spec.toml").write_text(spec)
    proc = run_chunkc("check", tmp_path / "spec.toml", check=False)
    assert proc.returncode != 0
    line = next(i for i, s in enumerate(spec.splitlines(), 1) if s == 'env = "gym_pusht/PushT"')
    assert "profiles.dp.env" in proc.stderr or "gym_pusht/PushT" in proc.stderr
    assert f":{line}:" in proc.stderr, proc.stderr
