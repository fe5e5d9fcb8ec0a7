"""`chunkc init` and `chunkc inspect` (issue 29): on every source format the tests vendor, the
spec `init` writes is accepted by `chunkc check` and built by `chunkc build` unchanged, and its
windows equal those of the hand-written spec of the same data.

The oracle of "the same windows": the checked-in, hand-written specs in `specs/` (their
`[source]` tables, written by people who read each dataset's documentation), built with the
profiles `init` proposed, and read back with each profile's generated loader; every sample's
action chunk and every observation both specs map from the same source key must be equal, bit
for bit. Malformed inputs must fail naming what is missing, exit non-zero, and write nothing."""

import json
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO, bits, build_with_video, load_dataset, run_chunkc, write_spec

DATA = REPO / "tests" / "data"
SPECS = REPO / "specs"

# (fixture, the hand-written spec of the same data, the format `init` must detect)
CASES = {
    "pusht_zarr": ("pusht_subset.zarr", "pusht.toml", "diffusion_policy_zarr"),
    "aloha_jpeg": ("aloha_sim_jpeg", "aloha_sim.toml", "aloha_hdf5"),
    "robosuite": ("robosuite_panda_lift.hdf5", "robosuite_panda.toml", "robomimic_hdf5"),
    "lerobot_v21": ("lerobot_g1_subset", "lerobot_g1.toml", "lerobot"),
    "lerobot_v30": ("lerobot_v3_synthetic", "lerobot_v3.toml", "lerobot"),
    "rlds_bridge": ("rlds-bridge/bridge_dataset", "bridge.toml", "rlds"),
}


def key_of(mapping):
    """A `[source.channels]` value as (key, columns); `None` for a concatenation."""
    if isinstance(mapping, str):
        return (mapping, None)
    if "concat" in mapping:
        return None
    return (mapping["key"], tuple(mapping.get("columns", ())) or None)


def toml_value(v):
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    return str(v)


def table(name, values):
    lines = [f"[{name}]"]
    lines += [f"{json.dumps(k)} = {toml_value(v)}" for k, v in values.items()]
    return "\n".join(lines)


def hand_spec(directory: Path, hand: dict, generated: dict) -> Path:
    """The hand-written `[source]` (its path made absolute) with `init`'s split and profiles."""
    source = {k: v for k, v in hand["source"].items() if k != "channels"}
    source["path"] = str((SPECS / source["path"]).resolve())
    parts = ["version = 1", table("source", source),
             table("source.channels", hand["source"]["channels"]),
             table("split", generated["split"]), table("output", {"dir": "out"})]
    for name, profile in generated["profiles"].items():
        parts.append(table(f"profiles.{name}", profile))
    path = directory / "hand.toml"
    path.write_text("\n".join(parts) + "\n")
    return path


@pytest.fixture(scope="module", params=sorted(CASES))
def initialized(request, tmp_path_factory):
    fixture, hand_name, fmt = CASES[request.param]
    d = tmp_path_factory.mktemp(f"init_{request.param}")
    spec = d / "spec.toml"
    proc = run_chunkc("init", DATA / fixture, "--out", spec)
    assert f"wrote {spec}" in proc.stderr, proc.stderr
    return request.param, d, spec, tomllib.loads((SPECS / hand_name).read_text()), fmt


def test_init_detects_the_format_and_the_spec_checks_and_builds(initialized):
    name, d, spec, hand, fmt = initialized
    generated = tomllib.loads(spec.read_text())
    assert generated["source"]["format"] == fmt
    channels = generated["source"]["channels"]
    assert channels["action"] == hand["source"]["channels"]["action"]
    # The robot state: the key the hand-written spec reads as the state, under the presets' name.
    for name in ("observation.state", "observation.qpos"):
        state = hand["source"]["channels"].get(name)
        if state is not None and key_of(state) is not None:
            assert key_of(channels["observation.state"]) == key_of(state), name
    assert {"act", "dp"} <= set(generated["profiles"])
    assert ("lerobot" in generated["profiles"]) == (fmt != "lerobot")
    # The rate: the hand-written spec's, where it states one (or the source stores it).
    if "fps" in hand["source"]:
        assert generated["source"]["fps"] == hand["source"]["fps"]
    run_chunkc("check", spec)
    run_chunkc("build", "-q", spec)
    for profile in generated["profiles"]:
        assert (d / generated["output"]["dir"] / profile / "meta.json").exists(), profile


def test_init_windows_equal_the_hand_written_specs(initialized):
    name, d, spec, hand, _ = initialized
    generated = tomllib.loads(spec.read_text())
    hand_dir = d / "hand"
    hand_dir.mkdir(exist_ok=True)
    run_chunkc("build", "-q", hand_spec(hand_dir, hand, generated))
    run_chunkc("build", "-q", spec)
    ours = generated["source"]["channels"]
    theirs = hand["source"]["channels"]
    # Channel pairs that read the same source key (and columns): (init's name, the hand name).
    pairs = [(a, b) for a, va in ours.items() for b, vb in theirs.items()
             if key_of(va) is not None and key_of(va) == key_of(vb)]
    assert ("action", "action") in pairs
    assert len(pairs) >= 2 or name == "lerobot_v30", f"{name}: only {pairs} shared"
    for profile in generated["profiles"]:
        for split in ("train", "val"):
            mine = load_dataset(d / generated["output"]["dir"] / profile, split)
            other = load_dataset(hand_dir / "out" / profile, split)
            assert len(mine) == len(other), (profile, split)
            step = max(1, len(mine) // 60)
            for i in range(0, len(mine), step):
                a, b = mine[i], other[i]
                assert int(a["episode_index"]) == int(b["episode_index"])
                assert int(a["frame_index"]) == int(b["frame_index"])
                for x, y in pairs:
                    np.testing.assert_array_equal(bits(a[x]), bits(b[y]), err_msg=f"{profile} {split} {i} {x}")
                np.testing.assert_array_equal(a["action_is_pad"], b["action_is_pad"])


def test_inspect_prints_the_same_summary_and_writes_nothing(tmp_path):
    before = sorted(p.name for p in tmp_path.iterdir())
    proc = run_chunkc("inspect", DATA / "lerobot_g1_subset")
    assert "format    lerobot" in proc.stdout and "-> observation.state" in proc.stdout
    assert "profile   act" in proc.stdout
    data = json.loads(run_chunkc("inspect", DATA / "pusht_subset.zarr", "--json").stdout)
    assert data["format"] == "diffusion_policy_zarr"
    assert data["rate"]["guessed"] is True and data["rate"]["fps"] == 10
    roles = {k["key"]: (k["role"], k["channel"]) for k in data["keys"]}
    assert roles["action"] == ("action", "action")
    assert roles["state"] == ("state", "observation.state")
    assert roles["img"] == ("image", "observation.image")
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_guessed_rate_is_marked_and_fps_overrides_it(tmp_path):
    spec = tmp_path / "spec.toml"
    run_chunkc("init", DATA / "aloha_sim_jpeg", "--out", spec, "--fps", 25)
    text = spec.read_text()
    assert "fps = 25  # --fps" in text and "GUESS" not in text
    other = tmp_path / "guess.toml"
    run_chunkc("init", DATA / "aloha_sim_jpeg", "--out", other)
    assert "GUESS" in other.read_text()


def test_a_camera_without_any_of_its_videos_is_left_out_with_the_reason(tmp_path):
    source = tmp_path / "set"
    shutil.copytree(DATA / "lerobot_video_v3_av1", source)
    info = json.loads((source / "meta/info.json").read_text())
    cameras = [k for k, f in info["features"].items() if f["dtype"] == "video"]
    assert len(cameras) >= 2
    shutil.rmtree(source / "videos" / cameras[0])
    spec = tmp_path / "spec.toml"
    run_chunkc("init", source, "--out", spec)
    generated = tomllib.loads(spec.read_text())
    assert cameras[0] not in generated["source"]["channels"]
    assert cameras[1] in generated["source"]["channels"]
    text = spec.read_text()
    left = [l for l in text.splitlines() if l.startswith("#") and cameras[0] in l]
    assert left and "left out" in left[0] and "missing" in left[0], text
    assert "exclude_episode" not in text
    run_chunkc("build", "-q", spec)


def test_init_never_overwrites(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text("mine\n")
    proc = run_chunkc("init", DATA / "pusht_subset.zarr", "--out", spec, check=False)
    assert proc.returncode != 0 and "already exists" in proc.stderr
    assert spec.read_text() == "mine\n"


def malformed(tmp_path, case):
    if case == "empty folder":
        (tmp_path / "d").mkdir()
        return tmp_path / "d", "empty directory"
    if case == "not a dataset":
        (tmp_path / "notes.txt").write_text("hello\n")
        return tmp_path / "notes.txt", "not an HDF5 file"
    if case == "folder of other files":
        (tmp_path / "d").mkdir()
        (tmp_path / "d" / "readme.md").write_text("x")
        return tmp_path / "d", "no dataset chunkc reads"
    if case == "lerobot without info.json":
        shutil.copytree(DATA / "lerobot_g1_subset", tmp_path / "d")
        (tmp_path / "d" / "meta" / "info.json").unlink()
        return tmp_path / "d", "no meta/info.json"
    if case == "missing path":
        return tmp_path / "nope", "does not exist"
    if case == "hdf5 without demos":
        import h5py

        with h5py.File(tmp_path / "x.hdf5", "w") as f:
            f["a"] = np.zeros(3)
        return tmp_path / "x.hdf5", "data"
    raise AssertionError(case)


@pytest.mark.parametrize("case", ["empty folder", "not a dataset", "folder of other files",
                                  "lerobot without info.json", "missing path", "hdf5 without demos"])
def test_malformed_inputs_fail_naming_what_is_missing(tmp_path, case):
    path, words = malformed(tmp_path, case)
    out = tmp_path / "spec.toml"
    proc = run_chunkc("init", path, "--out", out, check=False)
    assert proc.returncode != 0, proc.stderr
    assert words in proc.stderr, proc.stderr
    assert not out.exists()
    assert not (tmp_path / "out").exists()
    proc = run_chunkc("inspect", path, check=False)
    assert proc.returncode != 0 and words in proc.stderr


def test_fps_that_contradicts_a_lerobot_dataset_is_refused(tmp_path):
    out = tmp_path / "spec.toml"
    proc = run_chunkc("init", DATA / "lerobot_g1_subset", "--out", out, "--fps", 25, check=False)
    assert proc.returncode != 0 and "--fps 25 disagrees" in proc.stderr and "30" in proc.stderr
    assert not out.exists()


# Issue 37: a spec a policy can train on.


def renamed_lerobot(source: Path, dest: Path, names: dict) -> Path:
    """A copy of the LeRobot set `source` whose keys are renamed (`names`: old -> new) in its
    parquet files (row groups kept: one per episode), `meta/info.json` and the episode stats."""
    import pyarrow.parquet as pq

    shutil.copytree(source, dest)

    def rename(column):
        for old, new in names.items():
            if column == old:
                return new
            if column.startswith(f"stats/{old}/"):
                return f"stats/{new}/" + column[len(f"stats/{old}/"):]
        return column

    for path in sorted(dest.rglob("*.parquet")):
        pf = pq.ParquetFile(path)
        columns = [rename(c) for c in pf.schema_arrow.names]
        groups = [pf.read_row_group(i).rename_columns(columns) for i in range(pf.num_row_groups)]
        schema = groups[0].schema.remove_metadata()
        with pq.ParquetWriter(path, schema) as w:
            for g in groups:
                w.write_table(g.cast(schema))
    info_path = dest / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["features"] = {names.get(k, k): v for k, v in info["features"].items()}
    info_path.write_text(json.dumps(info, indent=2))
    stats = dest / "meta" / "episodes_stats.jsonl"
    if stats.exists():
        rows = [json.loads(l) for l in stats.read_text().splitlines() if l.strip()]
        for row in rows:
            row["stats"] = {names.get(k, k): v for k, v in row["stats"].items()}
        stats.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return dest


ACTIONS_STATE = {"action": "actions", "observation.state": "state"}


@pytest.mark.parametrize("fixture", ["lerobot_g1_subset", "lerobot_v3_synthetic"])
def test_a_lerobot_set_with_actions_and_state_keys_observes_the_state(tmp_path, fixture):
    """The issue's dexterous hand: keys `actions` / `state`, no `observation.` group. The state
    is mapped as `observation.state`, saying it is a guess; the spec checks without a warning and
    builds a dataset whose loader returns the state."""
    source = renamed_lerobot(DATA / fixture, tmp_path / "set", ACTIONS_STATE)
    spec = tmp_path / "spec.toml"
    proc = run_chunkc("init", source, "--out", spec)
    text = spec.read_text()
    channels = tomllib.loads(text)["source"]["channels"]
    assert channels["action"] == "actions"
    assert channels["observation.state"] == "state", text
    line = next(l for l in text.splitlines() if l.startswith('"observation.state"'))
    assert "GUESSED" in line, line
    assert "not in an observation group" not in text
    assert "-> observation.state" in proc.stderr
    checked = run_chunkc("check", spec)
    assert "warning" not in checked.stderr, checked.stderr
    run_chunkc("build", "-q", spec)
    generated = tomllib.loads(text)
    width = json.loads((source / "meta" / "info.json").read_text())["features"]["state"]["shape"][0]
    for profile in generated["profiles"]:
        ds = load_dataset(tmp_path / generated["output"]["dir"] / profile)
        sample = ds[0]
        assert "observation.state" in sample, (profile, sorted(sample))
        assert np.asarray(sample["observation.state"]).shape[-1] == width
        assert np.isfinite(np.asarray(sample["observation.state"], dtype=np.float64)).all()
    # The plan prints the step rounded.
    plan = run_chunkc("plan", spec).stdout
    rate = json.loads((source / "meta" / "info.json").read_text())["fps"]
    assert f"{round(1 / rate, 4):g} s steps" in plan, plan


def test_check_warns_about_a_preset_profile_without_observations(tmp_path):
    profiles = '[profiles.act]\npreset = "act"\nfps = 10\nchunk = 8\n[profiles.dp]\npreset = "diffusion_policy"\n'
    spec = write_spec(tmp_path, profiles, channels={"action": "action"})
    proc = run_chunkc("check", spec)
    assert proc.returncode == 0
    warnings = [l for l in proc.stderr.splitlines() if l.startswith("warning:")]
    assert any("profile `act`" in w and "no observation" in w for w in warnings), proc.stderr
    assert any("profile `dp`" in w and "diffusion_policy" in w for w in warnings), proc.stderr
    assert "ok:" in proc.stderr
    # One observation, low-dim or a camera, and it is quiet.
    for channels in ({"action": "action", "observation.state": "state"},
                     {"action": "action", "observation.image": "img"}):
        d = tmp_path / next(iter(set(channels) - {"action"}))
        d.mkdir()
        quiet = run_chunkc("check", write_spec(d, profiles, channels=channels))
        assert "no observation" not in quiet.stderr, quiet.stderr


def missing_videos_set(tmp_path):
    """lerobot_video_v21 (3 episodes, one mp4 per episode) without episode 1's video."""
    source = tmp_path / "set"
    shutil.copytree(DATA / "lerobot_video_v21", source)
    videos = sorted(source.rglob("*.mp4"))
    assert len(videos) == 3
    gone = [p for p in videos if p.name == "episode_000001.mp4"]
    for p in gone:
        p.unlink()
    return source


def test_a_camera_with_some_videos_missing_is_kept_and_those_episodes_excluded(tmp_path):
    source = missing_videos_set(tmp_path)
    camera = "observation.images.top"
    spec = tmp_path / "spec.toml"
    run_chunkc("init", source, "--out", spec)
    text = spec.read_text()
    generated = tomllib.loads(text)
    assert generated["source"]["channels"][camera] == camera, text
    assert generated["audit"]["video"] == "exclude_episode", text
    line = next(l for l in text.splitlines() if l.startswith(f'"{camera}"'))
    assert "1 of 3 episodes has no video: 1" in line, line
    assert "left out" not in line
    build_with_video(spec)
    for profile in generated["profiles"]:
        meta = json.loads((tmp_path / generated["output"]["dir"] / profile / "meta.json").read_text())
        assert meta["episodes"] == [0, 2], (profile, meta["episodes"])
        assert 1 in [e["id"] if isinstance(e, dict) else e for e in meta["excluded"]], meta["excluded"]
        sample = load_dataset(tmp_path / generated["output"]["dir"] / profile)[0]
        assert camera in sample


def spec_names(text: str):
    """The channel names a spec maps and those its commented lines offer: {name: key}."""
    mapped = tomllib.loads(text)["source"]["channels"]
    names = {k: (v if isinstance(v, str) else v["key"]) for k, v in mapped.items()}
    commented = {}
    for line in text.splitlines():
        if line.startswith('# "') and '" = "' in line:
            name, _, rest = line[2:].partition(" = ")
            commented[json.loads(name)] = json.loads(rest.split("  #")[0])
    return names, commented


@pytest.mark.parametrize("case", ["actions_state", "missing_video", "robosuite", "left_out_camera"])
def test_inspect_prints_the_names_the_spec_uses(tmp_path, case):
    if case == "actions_state":
        source = renamed_lerobot(DATA / "lerobot_g1_subset", tmp_path / "set", ACTIONS_STATE)
    elif case == "missing_video":
        source = missing_videos_set(tmp_path)
    elif case == "left_out_camera":
        # The single camera `image` outside any group: its line and inspect's agree on the name.
        source = renamed_lerobot(DATA / "lerobot_video_v21", tmp_path / "set",
                                 {"observation.images.top": "image"})
        shutil.rmtree(source / "videos")
    else:
        source = DATA / "robosuite_panda_lift.hdf5"
    spec = tmp_path / "spec.toml"
    run_chunkc("init", source, "--out", spec)
    mapped, commented = spec_names(spec.read_text())
    keys = json.loads(run_chunkc("inspect", source, "--json").stdout)["keys"]
    for k in keys:
        if k["channel"] is not None:
            assert mapped.get(k["channel"]) == k["key"], (k, mapped)
        elif k["role"] != "bookkeeping":
            assert commented.get(k["suggested"]) == k["key"], (k, commented)
    printed = run_chunkc("inspect", source).stdout
    assert "(not mapped)" not in printed, printed
    for k in keys:
        name = k["channel"] or k["suggested"]
        if name is not None:
            line = next(l for l in printed.splitlines() if l.strip().startswith(k["key"] + " "))
            assert f"-> {name}" in line, (line, name)
    if case == "left_out_camera":
        assert "observation.image" in commented and "observation.images.image" not in commented
