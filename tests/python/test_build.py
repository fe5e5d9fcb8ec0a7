"""Build behaviour: determinism, up-to-date detection, and clean failure."""

import hashlib
import shutil

import numpy as np
import pytest
import zarr

from conftest import PUSHT, run_chunkc, write_spec

PROFILES = """
[profiles.dp]
preset = "diffusion_policy"

[profiles.act]
preset = "act"
fps = 10
chunk = 20
"""


def digests(root):
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*"))
        if p.is_file()
    }


def test_outputs_identical_across_runs_and_thread_counts(tmp_path):
    results = []
    for run, threads in enumerate(["1", "2", "2"]):
        d = tmp_path / f"run{run}"
        d.mkdir()
        run_chunkc("build", "-q", write_spec(d, PROFILES), env={"RAYON_NUM_THREADS": threads})
        results.append(digests(d / "out"))
        assert (d / "chunkc.lock").exists()
    # data, meta, stats, loader, policy, validate, smoke_train, README for both; ACT pickle+JSON; DP normalizer.
    assert len(results[0]) == 20
    assert results[0] == results[1] == results[2]


def test_second_build_does_nothing(tmp_path):
    spec = write_spec(tmp_path, PROFILES)
    run_chunkc("build", "-q", spec)
    before = {p: p.stat().st_mtime_ns for p in (tmp_path / "out").rglob("*") if p.is_file()}
    lock = (tmp_path / "chunkc.lock").read_text()
    second = run_chunkc("build", "-q", spec)
    assert "up to date" in second.stderr
    after = {p: p.stat().st_mtime_ns for p in (tmp_path / "out").rglob("*") if p.is_file()}
    assert before == after
    assert (tmp_path / "chunkc.lock").read_text() == lock
    assert run_chunkc("build", "--locked", spec).returncode == 0


def test_changed_profile_rebuilds_only_that_profile(tmp_path):
    spec = write_spec(tmp_path, PROFILES)
    run_chunkc("build", "-q", spec)
    dp_before = digests(tmp_path / "out" / "dp")
    act_mtime = (tmp_path / "out" / "act" / "data.h5").stat().st_mtime_ns
    write_spec(tmp_path, PROFILES.replace("chunk = 20", "chunk = 25"))
    locked = run_chunkc("build", "--locked", spec, check=False)
    assert locked.returncode == 5 and "act" in locked.stderr
    plan = run_chunkc("plan", spec).stdout
    assert "profile act  [build:" in plan and "profile dp  [up to date]" in plan
    run_chunkc("build", "-q", spec)
    assert digests(tmp_path / "out" / "dp") == dp_before
    assert (tmp_path / "out" / "act" / "data.h5").stat().st_mtime_ns != act_mtime


def test_modified_output_is_rebuilt(tmp_path):
    spec = write_spec(tmp_path, PROFILES)
    run_chunkc("build", "-q", spec)
    good = digests(tmp_path / "out")
    (tmp_path / "out" / "dp" / "stats.json").write_text("{}")
    assert "was modified" in run_chunkc("plan", spec).stdout
    run_chunkc("build", "-q", spec)
    assert digests(tmp_path / "out") == good


def nan_source(tmp_path):
    src = tmp_path / "bad.zarr"
    shutil.copytree(PUSHT, src)
    action = zarr.open(str(src / "data" / "action"), mode="r+")
    values = action[:]
    values[300, 1] = np.nan  # episode 2 (rows 279..420), step 21
    action[:] = values
    return src


def test_bad_data_fails_with_location_and_leaves_no_output(tmp_path):
    spec = write_spec(tmp_path, PROFILES, source=nan_source(tmp_path))
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode == 3
    assert "episode 2" in proc.stderr and "`action`" in proc.stderr and "step 21" in proc.stderr
    assert not (tmp_path / "out").exists()
    assert not (tmp_path / "chunkc.lock").exists()


def test_bad_data_keeps_previous_output(tmp_path):
    spec = write_spec(tmp_path, PROFILES)
    run_chunkc("build", "-q", spec)
    good = digests(tmp_path / "out")
    write_spec(tmp_path, PROFILES, source=nan_source(tmp_path))
    assert run_chunkc("build", "-q", spec, check=False).returncode == 3
    assert digests(tmp_path / "out") == good


@pytest.mark.parametrize(
    "profiles, key",
    [
        ("[profiles.x]\nchunk = 4\nfps = 20\n", "fps"),  # no upsampling
        ("[profiles.x]\npreset = \"act\"\n", "fps"),  # the preset's 50 Hz exceeds the source
    ],
)
def test_impossible_rate_is_a_spec_error(tmp_path, profiles, key):
    spec = write_spec(tmp_path, profiles)
    proc = run_chunkc("build", "-q", spec, check=False)
    assert proc.returncode == 2, proc.stderr
    assert "spec.toml:" in proc.stderr and key in proc.stderr
    assert not (tmp_path / "out").exists()


def test_plan_json_is_versioned_and_sorted(tmp_path):
    import json

    spec = write_spec(tmp_path, PROFILES)
    plan = json.loads(run_chunkc("plan", "--format", "json", spec).stdout)
    assert plan["version"] == 1
    assert [p["name"] for p in plan["profiles"]] == ["act", "dp"]
    # Shared work appears once: one rate job and one statistics job per channel for both.
    assert len(plan["rates"]) == 1 and plan["rates"][0]["profiles"] == ["act", "dp"]
    assert len(plan["statistics"]) == 3
    assert plan == json.loads(run_chunkc("plan", "--format", "json", spec).stdout)
