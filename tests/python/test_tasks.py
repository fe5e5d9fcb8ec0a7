"""Each episode's task reaches the LeRobot export (`format = "parquet"`) as LeRobot stores it, so
that `LeRobotDataset(...)[i]["task"]` is the task string a language-conditioned policy reads.

Oracles: the RLDS records read with `tfrecord` + `example_pb2` (test_rlds's reader) for the
Bridge instructions; LeRobot's own writer's files (the vendored AV1 v3.0 fixture, made with
`LeRobotDataset.create`) read by pandas and by `LeRobotDataset` itself; `meta/episodes.jsonl`
for v2.1; pandas for `meta/tasks.parquet` (LeRobot reads it with `pd.read_parquet` and takes
`tasks.iloc[task_index].name`)."""

import json
import os
from pathlib import Path

import pandas as pd
import pyarrow.parquet as pq
import pytest

import conftest
from conftest import REPO, run_chunkc, write_spec
from test_rlds import BRIDGE, BRIDGE_CHANNELS, VERSION, read_split, rlds_spec

os.environ.setdefault("HF_HUB_OFFLINE", "1")

DATA = REPO / "tests" / "data"
LOWDIM_BRIDGE = {k: v for k, v in BRIDGE_CHANNELS.items() if "images" not in k}


def exported_tasks(root: Path):
    """Per stored row: (episode_index, task string), read the way LeRobot reads them."""
    tasks = pd.read_parquet(root / "meta/tasks.parquet")
    data = pq.read_table(root / "data/chunk-000/file-000.parquet",
                         columns=["episode_index", "task_index"]).to_pandas()
    return [(int(e), tasks.iloc[int(t)].name) for e, t in zip(data.episode_index, data.task_index)]


def lerobot_dataset(root: Path, backend=None):
    return conftest.lerobot_dataset("chunkc/tasks", root, backend)


@pytest.fixture(scope="module")
def bridge_export(tmp_path_factory):
    d = tmp_path_factory.mktemp("tasks_bridge")
    spec = rlds_spec(d, BRIDGE, LOWDIM_BRIDGE, '[profiles.lr]\npreset = "act"\nfps = 5\nformat = "parquet"\n')
    run_chunkc("build", "-q", spec)
    return d / "out" / "lr"


def test_rlds_instructions_are_the_exports_tasks(bridge_export):
    episodes = read_split(VERSION, "train", []) + read_split(VERSION, "val", [])
    want = {e: ep["task"] for e, ep in enumerate(episodes)}
    assert len(set(want.values())) > 1, "the Bridge subset should hold several instructions"
    rows = exported_tasks(bridge_export)
    assert {e for e, _ in rows} == set(want)
    assert all(task == want[e] for e, task in rows)
    # Each distinct task once, numbered by first appearance; total_tasks and meta/episodes agree.
    tasks = pd.read_parquet(bridge_export / "meta/tasks.parquet")
    assert list(tasks.task_index) == list(range(len(tasks)))
    assert sorted(tasks.index) == sorted(set(want.values()))
    info = json.loads((bridge_export / "meta/info.json").read_text())
    assert info["total_tasks"] == len(tasks)
    meta = pq.read_table(bridge_export / "meta/episodes/chunk-000/file-000.parquet").to_pydict()
    assert {e: t[0] for e, t in zip(meta["episode_index"], meta["tasks"])} == want


def test_lerobot_dataset_gives_the_instruction_as_item_task(bridge_export):
    ds = lerobot_dataset(bridge_export)
    episodes = read_split(VERSION, "train", []) + read_split(VERSION, "val", [])
    for i in range(0, len(ds), 7):
        item = ds[i]
        assert item["task"] == episodes[int(item["episode_index"])]["task"]


@pytest.mark.parametrize("fixture", ["lerobot_video_v3_av1", "lerobot_video_v21"])
def test_a_lerobot_sources_tasks_carry_over(tmp_path, fixture):
    source = DATA / fixture
    if fixture.endswith("v21"):
        lines = (source / "meta/episodes.jsonl").read_text().splitlines()
        want = {json.loads(l)["episode_index"]: json.loads(l)["tasks"][0] for l in lines if l.strip()}
    else:
        meta = pd.read_parquet(source / "meta/episodes/chunk-000/file-000.parquet")
        want = {int(e): t[0] for e, t in zip(meta.episode_index, meta.tasks)}
    spec = tmp_path / "spec.toml"
    spec.write_text("\n".join([
        "version = 1", "[source]", 'format = "lerobot"', f'path = "{source}"',
        "[source.channels]", 'action = "action"', '"observation.state" = "observation.state"',
        "[split]", "val_fraction = 0.0", "[output]", 'dir = "out"',
        "[profiles.lr]", 'preset = "act"', "fps = 10", "chunk = 5", 'format = "parquet"',
        "[profiles.h]", 'preset = "act"', "fps = 10", "chunk = 5", 'format = "hdf5"', ""]))
    run_chunkc("build", "-q", spec)
    rows = exported_tasks(tmp_path / "out" / "lr")
    assert rows and all(task == want[e] for e, task in rows)
    # meta.json of every profile maps each episode to it.
    meta_json = json.loads((tmp_path / "out" / "h" / "meta.json").read_text())
    assert meta_json["tasks"] == {str(e): t for e, t in want.items()}
    if fixture.endswith("av1"):
        # LeRobot on both sides, with each video backend (its default first): the source's
        # item["task"] is the export's.
        for backend in (None, "pyav"):
            src = lerobot_dataset(source, backend)
            out = lerobot_dataset(tmp_path / "out" / "lr", backend)
            assert [src[i]["task"] for i in range(len(src))] == [out[i]["task"] for i in range(len(out))]


def test_a_source_without_tasks_gets_the_default_task_as_a_string(tmp_path):
    spec = write_spec(tmp_path, '[profiles.lr]\npreset = "act"\nfps = 10\nformat = "parquet"\n',
                      channels={"action": "action", "observation.state": "state"})
    run_chunkc("build", "-q", spec)
    root = tmp_path / "out" / "lr"
    assert {t for _, t in exported_tasks(root)} == {"chunkc"}
    assert lerobot_dataset(root)[0]["task"] == "chunkc"
