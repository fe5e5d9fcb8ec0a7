"""Regenerate the vendored robosuite and LeRobot subsets in tests/data from the public datasets.

Usage: python tests/data/make_source_subsets.py PATH/TO/shared/data

- robosuite_panda_lift.hdf5: robosuite 1.0 `lift/panda/demo.hdf5`, copied whole (1 episode,
  412 steps; `states[:, 0]` is simulation time at 0.05 s steps).
- robosuite_sawyer_lift.hdf5: robosuite 0.3 `SawyerLift/demo.hdf5`, copied whole (2 episodes,
  1058 and 837 steps; irregular 0.010 / 0.012 s steps; zero-width `left_dpos`, `left_dquat`).
- robosuite_baxter_peg_in_hole.hdf5: robosuite 0.3 `BaxterPegInHole/demo.hdf5`, copied whole
  (2 episodes, 1382 and 1138 steps; `states` only, no actions; repeated timestamps, dt = 0).
- lerobot_g1_subset/: the first N_EPISODES episodes of the LeRobot v2.1 Unitree G1 dataset. The
  parquet files are copied byte for byte; meta/info.json totals and splits, episodes.jsonl and
  episodes_stats.jsonl are trimmed to the same episodes. The mp4 videos are absent upstream too.

Each keeps its upstream LICENSE next to it (`<name>.LICENSE`).
"""
import json
import os
import shutil
import sys
from pathlib import Path

N_EPISODES = int(os.environ.get("N_EPISODES", "8"))
HERE = Path(__file__).resolve().parent


def lerobot(src: Path, dst: Path) -> None:
    if dst.exists():
        shutil.rmtree(dst)
    (dst / "meta").mkdir(parents=True)
    info = json.loads((src / "meta/info.json").read_text())
    lines = (src / "meta/episodes.jsonl").read_text().splitlines()[:N_EPISODES]
    episodes = [json.loads(line) for line in lines]
    info["total_episodes"] = len(episodes)
    info["total_frames"] = sum(e["length"] for e in episodes)
    info["total_videos"] = len(episodes) * sum(f["dtype"] == "video" for f in info["features"].values())
    info["splits"] = {"train": f"0:{len(episodes)}"}
    (dst / "meta/info.json").write_text(json.dumps(info, indent=4))
    (dst / "meta/episodes.jsonl").write_text("\n".join(lines) + "\n")
    stats = (src / "meta/episodes_stats.jsonl").read_text().splitlines()[:N_EPISODES]
    (dst / "meta/episodes_stats.jsonl").write_text("\n".join(stats) + "\n")
    shutil.copy(src / "meta/tasks.jsonl", dst / "meta/tasks.jsonl")
    for e in episodes:
        idx = e["episode_index"]
        rel = info["data_path"].format(episode_chunk=idx // info["chunks_size"], episode_index=idx)
        (dst / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(src / rel, dst / rel)


def main(shared: str) -> None:
    data = Path(shared)
    shutil.copy(data / "robosuite-panda/lift/panda/demo.hdf5", HERE / "robosuite_panda_lift.hdf5")
    shutil.copy(data / "robosuite-panda/LICENSE", HERE / "robosuite_panda_lift.LICENSE")
    shutil.copy(data / "robosuite-sawyer/SawyerLift/demo.hdf5", HERE / "robosuite_sawyer_lift.hdf5")
    shutil.copy(data / "robosuite-sawyer/LICENSE", HERE / "robosuite_sawyer_lift.LICENSE")
    shutil.copy(data / "robosuite-sawyer/BaxterPegInHole/demo.hdf5",
                HERE / "robosuite_baxter_peg_in_hole.hdf5")
    shutil.copy(data / "robosuite-sawyer/LICENSE", HERE / "robosuite_baxter_peg_in_hole.LICENSE")
    lerobot(data / "lerobot-g1", HERE / "lerobot_g1_subset")
    shutil.copy(data / "lerobot-g1/LICENSE", HERE / "lerobot_g1_subset.LICENSE")
    for p in sorted(HERE.iterdir()):
        print(p.name)


if __name__ == "__main__":
    main(sys.argv[1])
