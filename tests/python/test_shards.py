"""Sharded builds end to end: the Ray driver (`scripts/chunkc_ray.py`) on a local Ray, a shard
killed mid-run and retried, and why the merge's statistics are exact where averaging per-shard
quantiles (LeRobot's port scripts) is not."""

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import PUSHT, REPO, chunkc_bin, make_replay_buffer, run_chunkc, write_spec

DRIVER = REPO / "scripts" / "chunkc_ray.py"
PROFILES = """
[profiles.dp]
preset = "diffusion_policy"
format = "zarr"

[profiles.act]
preset = "act"
fps = 10
chunk = 20
format = "hdf5"
"""


def hashes(root: Path):
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def test_ray_builds_pusht_in_four_shards_with_a_killed_shard_retried(tmp_path):
    pytest.importorskip("ray")
    single = tmp_path / "single"
    single.mkdir()
    run_chunkc("build", "-q", write_spec(single, PROFILES, source=PUSHT))
    want = hashes(single / "out")
    assert len(want) > 10

    sharded = tmp_path / "sharded"
    sharded.mkdir()
    spec = write_spec(sharded, PROFILES, source=PUSHT)
    marker = tmp_path / "killed-once"
    env = dict(os.environ, CHUNKC_BIN=chunkc_bin(), CHUNKC_RAY_TEST_KILL=f"2:{marker}",
               RAY_USAGE_STATS_ENABLED="0")
    proc = subprocess.run(
        [sys.executable, str(DRIVER), str(spec), "--num-shards", "4", "--num-cpus", "2",
         "--max-retries", "2", "--partials", str(tmp_path / "partials")],
        capture_output=True, text=True, env=env, timeout=600,
    )
    assert proc.returncode == 0, proc.stderr[-4000:]
    assert marker.exists(), "the test hook never killed shard 2"
    for i in range(4):
        assert f"shard {i} done" in proc.stderr, proc.stderr[-4000:]
    assert hashes(sharded / "out") == want
    assert not list((tmp_path / "partials").glob("*.partial")), "partials kept after the merge"


def test_merged_quantiles_are_the_whole_datasets_not_an_average(tmp_path):
    # Two halves recorded differently: the shards see different distributions.
    rng = np.random.default_rng(7)
    episodes = []
    for e in range(12):
        loc, scale = (0.0, 1.0) if e < 6 else (6.0, 3.0)
        n = 40 + 5 * (e % 3)
        episodes.append({
            "action": rng.normal(loc, scale, (n, 3)).astype(np.float32),
            "state": rng.normal(loc, scale, (n, 2)).astype(np.float32),
        })
    src = make_replay_buffer(tmp_path / "buffer.zarr", episodes)
    spec = write_spec(tmp_path, '[profiles.q]\nchunk = 4\nnormalize = { action = "quantile" }\nformat = "zarr"\n',
                      source=src, channels={"action": "action", "observation.state": "state"},
                      split="val_fraction = 0.2\nseed = 1")
    parts = tmp_path / "partials"
    for i in range(2):
        run_chunkc("build", "-q", "--shard", f"{i}/2", "--partials", parts, spec)
    run_chunkc("merge", "-q", "--partials", parts, spec)
    out = tmp_path / "out" / "q"
    meta = json.loads((out / "meta.json").read_text())
    stats = json.loads((out / "stats.json").read_text())["action"]
    train = meta["split"]["train"]
    plan = json.loads(run_chunkc("plan", "--shards", "2", "--format", "json", spec).stdout)
    cut = plan["shards"]["shards"][1]["episodes"][0]
    rows = np.concatenate([episodes[e]["action"] for e in train]).astype(np.float64)
    whole = {q: np.percentile(rows, p, axis=0) for q, p in [("q01", 1), ("q99", 99)]}
    np.testing.assert_allclose(stats["q01"], whole["q01"], rtol=1e-6)
    np.testing.assert_allclose(stats["q99"], whole["q99"], rtol=1e-6)
    # What averaging the shards' own quantiles gives instead.
    per_shard = [np.concatenate([episodes[e]["action"] for e in train if (e < cut) == first])
                 for first in (True, False)]
    averaged = {q: np.mean([np.percentile(s.astype(np.float64), p, axis=0) for s in per_shard], axis=0)
                for q, p in [("q01", 1), ("q99", 99)]}
    gap = {q: float(np.max(np.abs(averaged[q] - whole[q]))) for q in whole}
    print(f"shard cut at episode {cut}; exact q01 {whole['q01'].round(3)}, averaged {averaged['q01'].round(3)}; "
          f"exact q99 {whole['q99'].round(3)}, averaged {averaged['q99'].round(3)}; max gaps {gap}")
    assert gap["q01"] > 0.5 and gap["q99"] > 0.5, gap
